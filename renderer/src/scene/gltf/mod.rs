//! glTF 2.0 loader (`.gltf` with external or `data:` buffers, and binary `.glb`).
//!
//! What is read:
//! - The default scene (or the first scene): its node hierarchy, with each node's `matrix`
//!   or translation/rotation/scale accumulated from the root.
//! - Mesh primitives of mode TRIANGLES, TRIANGLE_STRIP and TRIANGLE_FAN (strips and fans are
//!   converted to triangle lists as the glTF specification orders them); POINTS and LINES*
//!   are errors. POSITION, NORMAL (transformed by the inverse transpose of the node's world
//!   matrix), TEXCOORD_0 and TEXCOORD_1 (a primitive without set 1 repeats set 0 there),
//!   indices or
//!   none. Primitives without normals get area-weighted smooth vertex normals computed
//!   from their triangles ([`super::smooth_vertex_normals`]); normals that cannot be
//!   normalised are replaced the same way. Under a transform with a negative determinant
//!   the winding is flipped so triangles stay counter-clockwise seen from the front.
//! - Materials: `pbrMetallicRoughness.baseColorFactor` (linear) times `baseColorTexture`
//!   (sRGB-decoded to linear at load), `metallicFactor` and `roughnessFactor` times the blue
//!   and green channels of `metallicRoughnessTexture` (linear data), `emissiveFactor` times
//!   `emissiveTexture` (sRGB) times `KHR_materials_emissive_strength` as
//!   [`Material::emission`] and [`Material::emissive_texture`], `normalTexture` (linear, with
//!   its `scale`) as [`Material::normal_texture`], `alphaMode` and `alphaCutoff` with the
//!   base colour's alpha ([`AlphaMode`]), `KHR_materials_ior` and `KHR_materials_specular`'s
//!   factors ([`Material::dielectric_fresnel`]; its textures are ignored with a warning),
//!   `KHR_materials_transmission`'s factor times its texture's red channel
//!   ([`Material::transmission`]: that part of the dielectric base is glass, tinted by the
//!   base colour) and `KHR_materials_volume` ([`Material::volume`]: with a thickness factor
//!   greater than 0 the surfaces enclose an absorbing volume, σa from the attenuation colour and
//!   distance; without it, or with thickness 0, transmitting surfaces are thin-walled, as
//!   the specification says; the thickness texture, a rasteriser's approximation, is not
//!   needed by a path tracer and ignored).
//!   Textures: PNG or JPEG (8/16-bit; EXR and HDR as linear), each image decoded once per
//!   encoding and shared; the sampler's `wrapS`/`wrapT` (repeat, clamp, mirrored repeat) and
//!   `magFilter` (nearest or bilinear; no mipmaps) and `KHR_texture_transform` (also on
//!   normal textures, read from their JSON) are honoured ([`super::texture::TextureRef`]),
//!   with `texCoord` 0 or 1 (another set reads set 0, with a warning). Occlusion textures
//!   are ignored; `doubleSided` is kept.
//!   Primitives without a material get [`Material::default_diffuse`] (named "default").
//! - Tangents, for primitives whose material has a normal map: TANGENT (xyz turned by the
//!   node's matrix, w flipped under a mirroring transform) or, without it, MikkTSpace
//!   ([`primitives::mikktspace_tangents`]) over the world-space triangles.
//! - Material `extras` choose the [`SurfaceModel`] (at most one of these keys):
//!   - `{"bsdf": "diffuse"}` → [`SurfaceModel::Lambert`]; `{"bsdf": "metallic-roughness"}`
//!     → [`SurfaceModel::MetallicRoughness`] (the default without extras);
//!   - `{"brdf": "BINDING"}` → [`SurfaceModel::Bound`] with the [`Binding`] written there,
//!     e.g. `merl:materials/alum-bronze.binary` or `nbrdf:networks/alum-bronze`, a relative
//!     path resolved against the glTF file's directory; a binding that does not parse is an
//!     error naming the file and the material;
//!   - `{"neural": "NAME"}` → [`SurfaceModel::Bound`]`(`[`Binding::Neural`]`)`, a latent
//!     code of the material file chosen at render time;
//!   - `{"neural": {...}}` → [`SurfaceModel::Varying`], codes varied by textures (TEXTURE
//!     is a textureInfo object `{"index": i, "texCoord": 0|1}` with its sampler and
//!     `KHR_texture_transform`; a code is a latent name or a written [`Binding`]):
//!     `{"mix": [A, B, ...up to 4], "weights": TEXTURE}` (the exact mixture weighted by the
//!     texture's R, G, B, A, linear, normalised per texel), `{"blend": [A, B], "t": TEXTURE,
//!     "channel": 0-3}` (latent codes only: the latent interpolation at t, one channel,
//!     linear; channel 0 when absent), `{"code": A}`; each takes an optional `"tint":
//!     TEXTURE` (sRGB) multiplying f_r. Unknown keys, more than four codes, a blend of
//!     tables, a missing texture or a channel out of range are errors naming the material.
//! - Perspective cameras instanced by nodes (`yfov`, `aspectRatio`); `camera_to_world` is
//!   the node's world transform without its scale. A camera is named after the camera
//!   object, else its node, else `camera<index>`. Orthographic cameras are skipped; a file
//!   whose only cameras are orthographic is an error.
//! - `KHR_lights_punctual` point, spot and directional lights in the specification's
//!   photometric units (candela for point and spot, lux for directional), converted to
//!   radiometric ones as glTF and Blender's exporter do: `intensity / 683 lm/W × color`
//!   ([`super::LUMENS_PER_WATT`]; W/sr, W/m²); positions are the
//!   node's world origin, directions its world -z; spot cone angles become cosines.
//!   `range` is ignored.
//! - The environment, from the scene's `extras` (falling back to the asset's `extras`):
//!   `{"environment": {"image": "studio.exr", "strength": 1.0, "rotation_degrees": 0.0}}`
//!   (image path relative to the glTF file) or `{"environment": {"color": [r, g, b]}}`
//!   (`strength` and `rotation_degrees` optional, defaults 1 and 0). The image itself is
//!   read by the renderer's environment code, not here.
//!
//! - Not read: animations, skins and morph targets (the rest pose is used), sparse
//!   accessors, and extensions other than the seven named above. A file that *requires* another
//!   extension (`extensionsRequired`) is an error naming it; one that only *uses* another
//!   (`extensionsUsed`, e.g. `KHR_materials_clearcoat`) loads
//!   with a warning naming it once ([`SceneDescription::warnings`]), and its materials render
//!   with their core parameters.
//!
//! Errors: a missing scene or buffer file is [`Error::Io`] naming that file; everything else
//! is [`Error::InvalidFile`] naming the glTF file and the problem (the `gltf` crate's message
//! for malformed JSON or invalid references).

use super::texture::{texture_transform, Encoding, Filter, Wrap};
use super::{
    smooth_vertex_normals, AlphaMode, Binding, Camera, EnvironmentSource, EnvironmentSpec, Geometry, Instance,
    Material, Mesh, NormalMap, PunctualLight, SceneDescription, SurfaceModel, Texture, TextureRef, Varying, VaryingForm, Volume, MAX_MIX_PARTS,
};
use super::{Clearcoat, SheenLayer};
use crate::{Error, Result, Rgb};
use ::gltf::accessor::{DataType, Dimensions};
use ::gltf::camera::Projection;
use ::gltf::khr_lights_punctual::Kind as LightKind;
use ::gltf::mesh::Mode;
use ::gltf::{Accessor, Document, Gltf, Node, Primitive};
use glam::{Mat4, Vec2, Vec3, Vec4};
use serde_json::Value;
use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

mod buffers;
mod extras;
mod primitives;
#[cfg(test)]
mod tests;

use buffers::{load_buffers, parse_and_validate, read_uri};
use extras::environment_from_extras;

/// Loads a `.gltf` or `.glb` file (see the module documentation for what is read).
pub fn load(path: &Path) -> Result<SceneDescription> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    load_from_bytes(&bytes, path)
}

/// Loads a glTF scene from the contents of a `.gltf` or `.glb` file. `path` is where the
/// bytes came from: errors name it, and buffers and images given by relative URIs are read
/// from disk relative to its directory.
pub fn load_from_bytes(bytes: &[u8], path: &Path) -> Result<SceneDescription> {
    load_from_bytes_with(bytes, path, |file| std::fs::read(file))
}

/// Like [`load_from_bytes`], but the files the glTF file refers to (external buffers and
/// images) are read by `read_file`, given their path (the glTF file's directory joined with
/// the decoded URI), instead of from disk; an error it returns becomes [`Error::Io`] naming
/// that path. Lets a scene and its files come from memory (tests, fuzzing).
pub fn load_from_bytes_with(
    bytes: &[u8],
    path: &Path,
    mut read_file: impl FnMut(&Path) -> std::io::Result<Vec<u8>>,
) -> Result<SceneDescription> {
    let Gltf { document, blob } = parse_and_validate(bytes, path)?;
    let base = path.parent().unwrap_or_else(|| Path::new(""));
    let buffers = load_buffers(path, base, &document, blob, &mut read_file)?;
    let warnings = document
        .extensions_used()
        .filter(|e| !buffers::SUPPORTED_EXTENSIONS.contains(e))
        .map(|e| format!("{}: glTF extension {e} is not supported and is ignored (materials render with their core parameters)", path.display()))
        .collect();
    let mut loader = Loader {
        path,
        base,
        read_file: &mut read_file,
        buffers: &buffers,
        scene: SceneDescription {
            source: path.to_path_buf(),
            warnings,
            ..SceneDescription::default()
        },
        texture_of_image: HashMap::new(),
        default_material: None,
        saw_orthographic: false,
        instanced: HashMap::new(),
        meshes: Geometry::default(),
    };
    for material in document.materials() {
        let material = loader.material(&document, &material)?;
        loader.scene.materials.push(material);
    }
    let gltf_scene = document
        .default_scene()
        .or_else(|| document.scenes().next())
        .ok_or_else(|| Error::invalid_file(path, "defines no scene"))?;
    loader.choose_instanced_meshes(&document, &gltf_scene);
    loader.walk(&gltf_scene)?;
    loader.place_meshes()?;
    if loader.scene.cameras.is_empty() && loader.saw_orthographic {
        return Err(Error::invalid_file(
            path,
            "has only orthographic cameras, which are not supported (use a perspective camera)",
        ));
    }
    let environment = environment_from_extras(gltf_scene.extras(), path, base)?;
    loader.scene.environment = match environment {
        Some(env) => Some(env),
        None => environment_from_extras(&document.as_json().asset.extras, path, base)?,
    };
    loader.scene.validate()?;
    Ok(loader.scene)
}

/// A mesh is instanced when copying it to every node using it would store at least this
/// many extra triangles (the Cornell box's walls, a few triangles on three nodes, are copied).
pub const INSTANCING_MIN_SAVED_TRIANGLES: usize = 1024;

/// The state of one load.
struct Loader<'a> {
    path: &'a Path,
    base: &'a Path,
    /// Reads the files the glTF file refers to (see [`load_from_bytes_with`]).
    read_file: &'a mut dyn FnMut(&Path) -> std::io::Result<Vec<u8>>,
    buffers: &'a [Vec<u8>],
    scene: SceneDescription,
    /// (glTF image index, encoding) → index into `scene.textures`.
    texture_of_image: HashMap<(usize, Encoding), usize>,
    /// Index of the material given to primitives without one, once created.
    default_material: Option<u32>,
    saw_orthographic: bool,
    /// glTF meshes stored once and placed by instances → their index in
    /// `scene.meshes` once stored (see [`Loader::choose_instanced_meshes`]).
    instanced: HashMap<usize, Option<u32>>,
    /// The instanced meshes' triangles, in their own space, appended to the world-space
    /// geometry at the end ([`Loader::place_meshes`]); `scene.meshes` index into it until then.
    meshes: Geometry,
}

impl Loader<'_> {
    fn invalid(&self, reason: impl Into<String>) -> Error {
        Error::invalid_file(self.path, reason)
    }

    /// Walks the scene's node trees depth first (without recursion), each node visited once.
    fn walk(&mut self, gltf_scene: &::gltf::Scene) -> Result<()> {
        let mut visited = HashSet::new();
        let mut stack: Vec<(Node, Mat4)> =
            gltf_scene.nodes().map(|n| (n, Mat4::IDENTITY)).collect();
        stack.reverse();
        while let Some((node, parent)) = stack.pop() {
            if !visited.insert(node.index()) {
                return Err(self.invalid(format!(
                    "node {} is reached twice in the node hierarchy (a cycle or a shared child)",
                    node_label(&node)
                )));
            }
            let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
            self.visit(&node, world)?;
            let children: Vec<Node> = node.children().collect();
            stack.extend(children.into_iter().rev().map(|c| (c, world)));
        }
        Ok(())
    }

    /// Chooses the meshes to store once and instance: those that nodes of the scene use
    /// often enough that copying them would store [`INSTANCING_MIN_SAVED_TRIANGLES`] or more
    /// extra triangles, unless one of their materials emits light (emissive triangles are
    /// lights, kept in world space). Smaller repeats are copied: a flat BVH traces faster.
    fn choose_instanced_meshes(&mut self, document: &Document, gltf_scene: &::gltf::Scene) {
        let mut uses: HashMap<usize, usize> = HashMap::new();
        let mut visited = HashSet::new();
        let mut stack: Vec<Node> = gltf_scene.nodes().collect();
        while let Some(node) = stack.pop() {
            if !visited.insert(node.index()) {
                continue;
            }
            if let Some(mesh) = node.mesh() {
                *uses.entry(mesh.index()).or_default() += 1;
            }
            stack.extend(node.children());
        }
        let emits = |m: Option<usize>| m.and_then(|m| self.scene.materials.get(m)).is_some_and(|m| m.emission.max_element() > 0.0);
        for mesh in document.meshes() {
            let copies = uses.get(&mesh.index()).map_or(0, |&n| n.saturating_sub(1));
            // Close enough for the choice (a strip of n indices has n − 2 triangles).
            let vertices = |p: &Primitive| p.indices().or_else(|| p.get(&::gltf::Semantic::Positions)).map_or(0, |a| a.count());
            let triangles: usize = mesh.primitives().map(|p| vertices(&p) / 3).sum();
            if copies * triangles >= INSTANCING_MIN_SAVED_TRIANGLES && !mesh.primitives().any(|p| emits(p.material().index())) {
                self.instanced.insert(mesh.index(), None);
            }
        }
    }

    /// Appends the instanced meshes after the world-space triangles and points
    /// `scene.meshes` at them.
    fn place_meshes(&mut self) -> Result<()> {
        let (triangles, vertices) = (self.scene.geometry.triangle_count() as u32, self.scene.geometry.positions.len() as u32);
        let meshes = std::mem::take(&mut self.meshes);
        self.scene.geometry.append(&meshes, self.path)?;
        for m in &mut self.scene.meshes {
            m.first_triangle += triangles;
            m.first_vertex += vertices;
        }
        Ok(())
    }

    fn visit(&mut self, node: &Node, world: Mat4) -> Result<()> {
        if let Some(mesh) = node.mesh() {
            let name = mesh
                .name()
                .map(str::to_string)
                .unwrap_or_else(|| format!("#{}", mesh.index()));
            match self.instanced.get(&mesh.index()).copied() {
                None => {
                    for primitive in mesh.primitives() {
                        let part = self.primitive(&name, &primitive, world)?;
                        self.scene.geometry.append(&part, self.path)?;
                    }
                }
                Some(stored) => {
                    let id = match stored {
                        Some(id) => id,
                        None => self.store_mesh(&mesh, &name)?,
                    };
                    // A transform that cannot be inverted flattens the mesh to nothing
                    // visible (as degenerate triangles would be); such a node is skipped.
                    let invertible = world.is_finite() && world.determinant() != 0.0 && world.inverse().is_finite();
                    if invertible {
                        self.scene.instances.push(Instance { mesh: id, object_to_world: world });
                    }
                }
            }
        }
        if let Some(camera) = node.camera() {
            match camera.projection() {
                Projection::Perspective(p) => {
                    let name = camera
                        .name()
                        .or(node.name())
                        .map(str::to_string)
                        .unwrap_or_else(|| format!("camera{}", camera.index()));
                    let (_, rotation, translation) = world.to_scale_rotation_translation();
                    let camera_to_world =
                        Mat4::from_rotation_translation(rotation.normalize(), translation);
                    if !camera_to_world.is_finite() {
                        return Err(self
                            .invalid(format!("camera '{name}' has a degenerate node transform")));
                    }
                    if !(p.yfov() > 0.0 && p.yfov() < std::f32::consts::PI) {
                        return Err(self.invalid(format!(
                            "camera '{name}' has yfov {} (must be in (0, pi) radians)",
                            p.yfov()
                        )));
                    }
                    self.scene.cameras.push(Camera {
                        name,
                        camera_to_world,
                        yfov: p.yfov(),
                        aspect_ratio: p.aspect_ratio().filter(|a| a.is_finite() && *a > 0.0),
                    });
                }
                Projection::Orthographic(_) => self.saw_orthographic = true,
            }
        }
        if let Some(light) = node.light() {
            // cd → W/sr, lx → W/m² (the division first, so 683 k cd is exactly k W/sr).
            let radiometric = Rgb::from_array(light.color()) * (light.intensity() / super::LUMENS_PER_WATT);
            let position = world.transform_point3(Vec3::ZERO);
            let direction = world.transform_vector3(Vec3::NEG_Z).try_normalize();
            let label = light
                .name()
                .map(str::to_string)
                .unwrap_or_else(|| format!("#{}", light.index()));
            let direction = || {
                direction.ok_or_else(|| {
                    self.invalid(format!("light '{label}' has a degenerate node transform"))
                })
            };
            let light = match light.kind() {
                LightKind::Point => PunctualLight::Point {
                    position,
                    intensity: radiometric,
                },
                LightKind::Spot {
                    inner_cone_angle,
                    outer_cone_angle,
                } => PunctualLight::Spot {
                    position,
                    direction: direction()?,
                    intensity: radiometric,
                    cos_inner: inner_cone_angle.cos(),
                    cos_outer: outer_cone_angle.cos(),
                },
                LightKind::Directional => PunctualLight::Directional {
                    direction: direction()?,
                    irradiance: radiometric,
                },
            };
            if !position.is_finite() || !radiometric.is_finite() {
                return Err(self.invalid(format!("light '{label}' is not finite")));
            }
            self.scene.lights.push(light);
        }
        Ok(())
    }

    /// Stores a glTF mesh once, in its own space, as the next of `scene.meshes`.
    fn store_mesh(&mut self, mesh: &::gltf::Mesh, name: &str) -> Result<u32> {
        let (first_triangle, first_vertex) = (self.meshes.triangle_count() as u32, self.meshes.positions.len() as u32);
        for primitive in mesh.primitives() {
            let part = self.primitive(name, &primitive, Mat4::IDENTITY)?;
            self.meshes.append(&part, self.path)?;
        }
        let id = self.scene.meshes.len() as u32;
        self.scene.meshes.push(Mesh {
            first_triangle,
            triangle_count: self.meshes.triangle_count() as u32 - first_triangle,
            first_vertex,
            vertex_count: self.meshes.positions.len() as u32 - first_vertex,
        });
        self.instanced.insert(mesh.index(), Some(id));
        Ok(id)
    }

    fn default_material_id(&mut self) -> Result<u32> {
        if let Some(id) = self.default_material {
            return Ok(id);
        }
        let id = u32::try_from(self.scene.materials.len())
            .map_err(|_| self.invalid("too many materials"))?;
        self.scene
            .materials
            .push(Material::default_diffuse("default"));
        self.default_material = Some(id);
        Ok(id)
    }

    fn material(&mut self, document: &Document, material: &::gltf::Material) -> Result<Material> {
        use ::gltf::material::AlphaMode as GltfAlpha;
        let name = material
            .name()
            .map(str::to_string)
            .unwrap_or_else(|| format!("material{}", material.index().unwrap_or(0)));
        let pbr = material.pbr_metallic_roughness();
        let [r, g, b, a] = pbr.base_color_factor();
        let base_color_texture = match pbr.base_color_texture() {
            Some(info) => Some(self.texture_ref(document, &TextureUse::info(&info), Encoding::Srgb, &name, "base colour")?),
            None => None,
        };
        let metallic_roughness_texture = match pbr.metallic_roughness_texture() {
            Some(info) => Some(self.texture_ref(document, &TextureUse::info(&info), Encoding::Linear, &name, "metallic-roughness")?),
            None => None,
        };
        let emissive_texture = match material.emissive_texture() {
            Some(info) => Some(self.texture_ref(document, &TextureUse::info(&info), Encoding::Srgb, &name, "emissive")?),
            None => None,
        };
        let normal_texture = match material.normal_texture() {
            Some(normal) => {
                let texture = self.texture_ref(document, &TextureUse::normal(&normal), Encoding::Linear, &name, "normal")?;
                if !normal.scale().is_finite() {
                    return Err(self.invalid(format!("material '{name}' has a non-finite normalTexture scale")));
                }
                Some(NormalMap { texture, scale: normal.scale() })
            }
            None => None,
        };
        let alpha_mode = match material.alpha_mode() {
            GltfAlpha::Opaque => AlphaMode::Opaque,
            GltfAlpha::Mask => {
                let cutoff = material.alpha_cutoff().unwrap_or(0.5);
                if cutoff.is_nan() || cutoff < 0.0 {
                    return Err(self.invalid(format!("material '{name}' has alphaCutoff {cutoff} (must be ≥ 0)")));
                }
                AlphaMode::Mask { cutoff }
            }
            GltfAlpha::Blend => AlphaMode::Blend,
        };
        let emission = Rgb::from_array(material.emissive_factor())
            * material.emissive_strength().unwrap_or(1.0);
        let ior = material.ior().unwrap_or(1.5);
        let (specular, specular_color) = match material.specular() {
            Some(spec) => {
                for (texture, what) in [(spec.specular_texture().is_some(), "specularTexture"), (spec.specular_color_texture().is_some(), "specularColorTexture")] {
                    if texture {
                        let warning = format!("{}: material '{name}': KHR_materials_specular's {what} is not supported and is ignored (its factor is used)", self.path.display());
                        self.scene.warnings.push(warning);
                    }
                }
                (spec.specular_factor(), Rgb::from_array(spec.specular_color_factor()))
            }
            None => (1.0, Rgb::ONE),
        };
        if !(ior == 0.0 || ior >= 1.0) || !specular.is_finite() || !specular_color.is_finite() {
            return Err(self.invalid(format!("material '{name}' has an invalid KHR_materials_ior or KHR_materials_specular (ior {ior}, specular {specular}, colour {specular_color}): ior must be 0 or at least 1 and the factors finite")));
        }
        let (transmission, transmission_texture) = match material.transmission() {
            Some(tr) => {
                let texture = match tr.transmission_texture() {
                    Some(info) => Some(self.texture_ref(document, &TextureUse::info(&info), Encoding::Linear, &name, "transmission")?),
                    None => None,
                };
                (tr.transmission_factor(), texture)
            }
            None => (0.0, None),
        };
        if !(0.0..=1.0).contains(&transmission) {
            return Err(self.invalid(format!("material '{name}' has KHR_materials_transmission factor {transmission} (must be in [0, 1])")));
        }
        let volume = match material.volume() {
            Some(v) if v.thickness_factor() > 0.0 => {
                let color = Rgb::from_array(v.attenuation_color());
                let distance = v.attenuation_distance();
                Some(Volume::from_attenuation(color, distance).ok_or_else(|| {
                    self.invalid(format!("material '{name}' has an invalid KHR_materials_volume (attenuationColor {color}, attenuationDistance {distance}): the colour must be in (0, 1] and the distance > 0"))
                })?)
            }
            Some(v) if v.thickness_factor() < 0.0 || v.thickness_factor().is_nan() => {
                return Err(self.invalid(format!("material '{name}' has KHR_materials_volume thicknessFactor {} (must be ≥ 0)", v.thickness_factor())));
            }
            _ => None,
        };
        let clearcoat = self.clearcoat(document, material, &name)?;
        let sheen = self.sheen(document, material, &name)?;
        let model = self.surface_model(document, material.extras(), &name)?;
        let result = Material {
            model,
            base_color: Rgb::new(r, g, b),
            base_color_texture,
            metallic_roughness_texture,
            metallic: pbr.metallic_factor().clamp(0.0, 1.0),
            roughness: pbr.roughness_factor().clamp(0.0, 1.0),
            emission,
            double_sided: material.double_sided(),
            emissive_texture,
            normal_texture,
            alpha_mode,
            base_alpha: a.clamp(0.0, 1.0),
            ior,
            specular: specular.clamp(0.0, 1.0),
            specular_color: specular_color.max(Rgb::ZERO),
            transmission,
            transmission_texture,
            volume,
            clearcoat,
            sheen,
            name,
        };
        if !result.base_color.is_finite() || !result.emission.is_finite() || !a.is_finite() {
            return Err(self.invalid(format!("material '{}' has non-finite factors", result.name)));
        }
        Ok(result)
    }

    /// A number of an extension's JSON object: `default` where the key is absent, an error
    /// naming the material where it is not a number in [0, 1].
    fn unit_factor(&self, object: &Value, extension: &str, key: &str, default: f32, material: &str) -> Result<f32> {
        match object.get(key) {
            None => Ok(default),
            Some(v) => match v.as_f64() {
                Some(x) if (0.0..=1.0).contains(&x) => Ok(x as f32),
                _ => Err(self.invalid(format!("material '{material}' has {extension} {key} {v} (must be a number in [0, 1])"))),
            },
        }
    }

    /// The texture an extension's JSON names under `key` (a textureInfo object), if any.
    fn json_texture(&mut self, document: &Document, object: &Value, key: &str, encoding: Encoding, material: &str, role: &str) -> Result<Option<TextureRef>> {
        match object.get(key) {
            None => Ok(None),
            Some(info) => {
                let used = TextureUse::json(document, info).map_err(|reason| self.invalid(format!("the {role} texture of material '{material}' {reason}")))?;
                self.texture_ref(document, &used, encoding, material, role).map(Some)
            }
        }
    }

    /// `KHR_materials_clearcoat` (read from the material's JSON: the `gltf` crate does not
    /// parse it); `None` without the extension or with a zero factor.
    fn clearcoat(&mut self, document: &Document, material: &::gltf::Material, name: &str) -> Result<Option<Clearcoat>> {
        const EXT: &str = "KHR_materials_clearcoat";
        let Some(object) = material.extension_value(EXT) else {
            return Ok(None);
        };
        let factor = self.unit_factor(object, EXT, "clearcoatFactor", 0.0, name)?;
        let roughness = self.unit_factor(object, EXT, "clearcoatRoughnessFactor", 0.0, name)?;
        let texture = self.json_texture(document, object, "clearcoatTexture", Encoding::Linear, name, "clearcoat")?;
        let roughness_texture = self.json_texture(document, object, "clearcoatRoughnessTexture", Encoding::Linear, name, "clearcoat roughness")?;
        let normal_texture = match object.get("clearcoatNormalTexture") {
            Some(info) => {
                let texture = self.json_texture(document, object, "clearcoatNormalTexture", Encoding::Linear, name, "clearcoat normal")?.expect("present");
                let scale = match info.get("scale") {
                    None => 1.0,
                    Some(v) => v.as_f64().filter(|s| s.is_finite()).ok_or_else(|| self.invalid(format!("material '{name}' has a clearcoatNormalTexture scale {v} that is not a finite number")))? as f32,
                };
                Some(NormalMap { texture, scale })
            }
            None => None,
        };
        Ok((factor > 0.0).then_some(Clearcoat { factor, texture, roughness, roughness_texture, normal_texture }))
    }

    /// `KHR_materials_sheen` (read from the material's JSON); `None` without the extension
    /// or with a black sheen colour.
    fn sheen(&mut self, document: &Document, material: &::gltf::Material, name: &str) -> Result<Option<SheenLayer>> {
        const EXT: &str = "KHR_materials_sheen";
        let Some(object) = material.extension_value(EXT) else {
            return Ok(None);
        };
        let color = match object.get("sheenColorFactor") {
            None => Rgb::ZERO,
            Some(v) => {
                let parsed: Option<Vec<f64>> = v.as_array().and_then(|a| a.iter().map(Value::as_f64).collect());
                match parsed.as_deref() {
                    Some(&[r, g, b]) if [r, g, b].iter().all(|c| (0.0..=1.0).contains(c)) => Rgb::new(r as f32, g as f32, b as f32),
                    _ => return Err(self.invalid(format!("material '{name}' has {EXT} sheenColorFactor {v} (must be three numbers in [0, 1])"))),
                }
            }
        };
        let roughness = self.unit_factor(object, EXT, "sheenRoughnessFactor", 0.0, name)?;
        let color_texture = self.json_texture(document, object, "sheenColorTexture", Encoding::Srgb, name, "sheen colour")?;
        let roughness_texture = self.json_texture(document, object, "sheenRoughnessTexture", Encoding::Linear, name, "sheen roughness")?;
        Ok((color.max_element() > 0.0).then_some(SheenLayer { color, color_texture, roughness, roughness_texture }))
    }

    /// A material's texture (`role` names it in messages): its image decoded with
    /// `encoding`, its texture-coordinate set, its sampler's wrap and filter modes,
    /// `KHR_texture_transform`. Sets 0 and 1 are read: a `texCoord` ≥ 2 reads set 0, with a
    /// warning.
    fn texture_ref(
        &mut self,
        document: &Document,
        used: &TextureUse,
        encoding: Encoding,
        material: &str,
        role: &str,
    ) -> Result<TextureRef> {
        use ::gltf::texture::{MagFilter, WrappingMode};
        let texture = &used.texture;
        let index = self.texture(document, texture.source().index(), encoding, &format!("{role} of material '{material}'"))?;
        let wrap = |mode: WrappingMode| match mode {
            WrappingMode::ClampToEdge => Wrap::ClampToEdge,
            WrappingMode::MirroredRepeat => Wrap::MirroredRepeat,
            WrappingMode::Repeat => Wrap::Repeat,
        };
        let sampler = texture.sampler();
        let filter = match sampler.mag_filter() {
            Some(MagFilter::Nearest) => Filter::Nearest,
            _ => Filter::Linear,
        };
        let transform = used.transform.as_ref().map(|t| t.parse()).transpose().map_err(|reason| {
            self.invalid(format!("the {role} texture of material '{material}' has an invalid KHR_texture_transform: {reason}"))
        })?;
        let tex_coord = transform.and_then(|t| t.3).unwrap_or(used.tex_coord);
        let tex_coord = if tex_coord > 1 {
            let warning = format!(
                "{}: the {role} texture of material '{material}' uses TEXCOORD_{tex_coord}; only sets 0 and 1 are read, and set 0 is used instead",
                self.path.display()
            );
            self.scene.warnings.push(warning);
            0
        } else {
            tex_coord
        };
        let transform = transform.map(|(offset, rotation, scale, _)| texture_transform(offset, rotation, scale));
        if transform.is_some_and(|m| !m.is_finite()) {
            return Err(self.invalid(format!("the {role} texture of material '{material}' has a non-finite KHR_texture_transform")));
        }
        Ok(TextureRef {
            texture: index,
            tex_coord,
            wrap: [wrap(sampler.wrap_s()), wrap(sampler.wrap_t())],
            filter,
            transform,
        })
    }

    /// The texture index of glTF image `image` decoded with `encoding`, decoding it on first
    /// use (`what` names its use in messages).
    fn texture(&mut self, document: &Document, image: usize, encoding: Encoding, what: &str) -> Result<usize> {
        if let Some(&t) = self.texture_of_image.get(&(image, encoding)) {
            return Ok(t);
        }
        let gltf_image = document.images().nth(image).ok_or_else(|| {
            self.invalid(format!("the {what} uses missing image {image}"))
        })?;
        let what = format!("image {image} ({what})");
        let bytes = match gltf_image.source() {
            ::gltf::image::Source::View { view, .. } => self
                .buffers
                .get(view.buffer().index())
                .and_then(|b| b.get(view.offset()..view.offset().checked_add(view.length())?))
                .ok_or_else(|| {
                    self.invalid(format!(
                        "{what}: bufferView {} is out of range",
                        view.index()
                    ))
                })?
                .to_vec(),
            ::gltf::image::Source::Uri { uri, .. } => {
                read_uri(self.path, self.base, uri, &what, self.read_file)?
            }
        };
        let texture = Texture::from_encoded(&bytes, encoding, self.path, &what)?;
        let t = self.scene.textures.len();
        self.scene.textures.push(texture);
        self.texture_of_image.insert((image, encoding), t);
        Ok(t)
    }
}

/// A texture as one material slot uses it: the texture, its `texCoord` and its
/// `KHR_texture_transform` (as the `gltf` crate parses it for texture infos, as JSON for
/// normal textures, whose extensions it leaves unparsed).
struct TextureUse<'a> {
    texture: ::gltf::Texture<'a>,
    tex_coord: u32,
    transform: Option<TransformSource<'a>>,
}

enum TransformSource<'a> {
    Parsed(::gltf::texture::TextureTransform<'a>),
    Json(&'a Value),
}

/// offset, rotation (radians), scale and the texCoord override of a `KHR_texture_transform`.
type TransformParts = (Vec2, f32, Vec2, Option<u32>);

impl<'a> TextureUse<'a> {
    fn info(info: &::gltf::texture::Info<'a>) -> Self {
        TextureUse {
            texture: info.texture(),
            tex_coord: info.tex_coord(),
            transform: info.texture_transform().map(TransformSource::Parsed),
        }
    }

    fn normal(normal: &'a ::gltf::material::NormalTexture<'a>) -> Self {
        TextureUse {
            texture: normal.texture(),
            tex_coord: normal.tex_coord(),
            transform: normal.extension_value("KHR_texture_transform").map(TransformSource::Json),
        }
    }

    /// A textureInfo object of an extension the `gltf` crate does not parse:
    /// `{"index": i, "texCoord": n, "extensions": {"KHR_texture_transform": {...}}}`; the
    /// error says what is wrong with it.
    fn json(document: &'a Document, info: &'a Value) -> std::result::Result<Self, String> {
        let index = info.get("index").and_then(Value::as_u64).ok_or_else(|| format!("has no valid index ({info})"))?;
        let texture = document.textures().nth(index as usize).ok_or_else(|| format!("names texture {index}, which does not exist"))?;
        let tex_coord = match info.get("texCoord") {
            None => 0,
            Some(v) => v.as_u64().and_then(|n| u32::try_from(n).ok()).ok_or_else(|| format!("has an invalid texCoord {v}"))?,
        };
        let transform = info.get("extensions").and_then(|e| e.get("KHR_texture_transform")).map(TransformSource::Json);
        Ok(TextureUse { texture, tex_coord, transform })
    }
}

impl TransformSource<'_> {
    fn parse(&self) -> std::result::Result<TransformParts, String> {
        match self {
            TransformSource::Parsed(t) => Ok((Vec2::from(t.offset()), t.rotation(), Vec2::from(t.scale()), t.tex_coord())),
            TransformSource::Json(value) => {
                let pair = |key: &str, default: Vec2| -> std::result::Result<Vec2, String> {
                    match value.get(key) {
                        None => Ok(default),
                        Some(v) => match v.as_array().map(|a| a.iter().map(Value::as_f64).collect::<Option<Vec<_>>>()) {
                            Some(Some(a)) if a.len() == 2 => Ok(Vec2::new(a[0] as f32, a[1] as f32)),
                            _ => Err(format!("'{key}' must be an array of two numbers")),
                        },
                    }
                };
                let rotation = match value.get("rotation") {
                    None => 0.0,
                    Some(v) => v.as_f64().ok_or("'rotation' must be a number")? as f32,
                };
                let tex_coord = match value.get("texCoord") {
                    None => None,
                    Some(v) => Some(v.as_u64().and_then(|t| u32::try_from(t).ok()).ok_or("'texCoord' must be a non-negative integer")?),
                };
                Ok((pair("offset", Vec2::ZERO)?, rotation, pair("scale", Vec2::ONE)?, tex_coord))
            }
        }
    }
}

/// A node's name for messages.
fn node_label(node: &Node) -> String {
    match node.name() {
        Some(name) => format!("'{name}'"),
        None => format!("#{}", node.index()),
    }
}

