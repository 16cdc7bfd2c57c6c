//! glTF 2.0 loader (`.gltf` with external or `data:` buffers, and binary `.glb`).
//!
//! What is read:
//! - The default scene (or the first scene): its node hierarchy, with each node's `matrix`
//!   or translation/rotation/scale accumulated from the root.
//! - Mesh primitives of mode TRIANGLES, TRIANGLE_STRIP and TRIANGLE_FAN (strips and fans are
//!   converted to triangle lists as the glTF specification orders them); POINTS and LINES*
//!   are errors. POSITION, NORMAL (transformed by the inverse transpose of the node's world
//!   matrix), TEXCOORD_0 (only set 0, whatever `texCoord` a texture names), indices or
//!   none. Primitives without normals get area-weighted smooth vertex normals computed
//!   from their triangles ([`super::smooth_vertex_normals`]); normals that cannot be
//!   normalised are replaced the same way. Under a transform with a negative determinant
//!   the winding is flipped so triangles stay counter-clockwise seen from the front.
//! - Materials: `pbrMetallicRoughness.baseColorFactor` (linear) times `baseColorTexture`
//!   (sRGB-decoded to linear at load, see [`Texture::from_encoded_srgb`]; samplers' wrap
//!   and filter modes are ignored: the renderer repeats and filters bilinearly),
//!   `metallicFactor`, `roughnessFactor`, and `emissiveFactor` times
//!   `KHR_materials_emissive_strength` as [`Material::emission`]. Emissive, normal,
//!   occlusion and metallic-roughness textures are ignored; `doubleSided` is kept. Primitives without a material
//!   get [`Material::default_diffuse`] (named "default").
//! - Material `extras` choose the [`SurfaceModel`] (at most one of these keys):
//!   - `{"bsdf": "diffuse"}` → [`SurfaceModel::Lambert`]; `{"bsdf": "metallic-roughness"}`
//!     → [`SurfaceModel::MetallicRoughness`] (the default without extras);
//!   - `{"brdf": "BINDING"}` → [`SurfaceModel::Bound`] with the [`Binding`] written there,
//!     e.g. `merl:materials/alum-bronze.binary` or `nbrdf:networks/alum-bronze`, a relative
//!     path resolved against the glTF file's directory; a binding that does not parse is an
//!     error naming the file and the material;
//!   - `{"neural": "NAME"}` → [`SurfaceModel::Bound`]`(`[`Binding::Neural`]`)`, a latent
//!     code of the material file chosen at render time.
//! - Perspective cameras instanced by nodes (`yfov`, `aspectRatio`); `camera_to_world` is
//!   the node's world transform without its scale. A camera is named after the camera
//!   object, else its node, else `camera<index>`. Orthographic cameras are skipped; a file
//!   whose only cameras are orthographic is an error.
//! - `KHR_lights_punctual` point, spot and directional lights: radiometric intensity =
//!   `intensity × color` (no 683 lm/W factor, see [`PunctualLight`]); positions are the
//!   node's world origin, directions its world -z; spot cone angles become cosines.
//!   `range` is ignored.
//! - The environment, from the scene's `extras` (falling back to the asset's `extras`):
//!   `{"environment": {"image": "studio.exr", "strength": 1.0, "rotation_degrees": 0.0}}`
//!   (image path relative to the glTF file) or `{"environment": {"color": [r, g, b]}}`
//!   (`strength` and `rotation_degrees` optional, defaults 1 and 0). The image itself is
//!   read by the renderer's environment code, not here.
//!
//! - Not read: animations, skins and morph targets (the rest pose is used), sparse
//!   accessors, and extensions other than the two above (files that *require* another
//!   extension are rejected by the `gltf` crate's validation).
//!
//! Errors: a missing scene or buffer file is [`Error::Io`] naming that file; everything else
//! is [`Error::InvalidFile`] naming the glTF file and the problem (the `gltf` crate's message
//! for malformed JSON or invalid references).

use super::{
    smooth_vertex_normals, Camera, EnvironmentSource, EnvironmentSpec, Geometry, Material,
    PunctualLight, SceneDescription, SurfaceModel, Texture,
};
use crate::material::Binding;
use crate::{Error, Result, Rgb};
use ::gltf::accessor::{DataType, Dimensions};
use ::gltf::camera::Projection;
use ::gltf::khr_lights_punctual::Kind as LightKind;
use ::gltf::mesh::Mode;
use ::gltf::{Accessor, Document, Gltf, Node, Primitive};
use glam::{Mat3, Mat4, Vec2, Vec3};
use serde_json::Value;
use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

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
    let mut loader = Loader {
        path,
        base,
        read_file: &mut read_file,
        buffers: &buffers,
        scene: SceneDescription {
            source: path.to_path_buf(),
            ..SceneDescription::default()
        },
        texture_of_image: HashMap::new(),
        default_material: None,
        saw_orthographic: false,
    };
    for material in document.materials() {
        let material = loader.material(&document, &material)?;
        loader.scene.materials.push(material);
    }
    let gltf_scene = document
        .default_scene()
        .or_else(|| document.scenes().next())
        .ok_or_else(|| Error::invalid_file(path, "defines no scene"))?;
    loader.walk(&gltf_scene)?;
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

/// Parses a `.gltf` or `.glb` file and runs the `gltf` crate's validation, which checks
/// every index into the document's arrays. Two inputs that make the `gltf` crate (1.4)
/// panic are turned into errors first: a GLB header whose total length is below the
/// header's own 12 bytes (an overflowing subtraction in `binary.rs`), and a primitive whose
/// POSITION names a missing accessor (the validation indexes the accessors with it
/// unchecked, `gltf-json` `mesh.rs`).
fn parse_and_validate(bytes: &[u8], path: &Path) -> Result<Gltf> {
    let invalid = |e: &dyn std::fmt::Display| {
        Error::invalid_file(path, format!("not a valid glTF file: {e}"))
    };
    if let Some(header) = bytes.first_chunk::<12>().filter(|h| h.starts_with(b"glTF")) {
        let length = u32::from_le_bytes([header[8], header[9], header[10], header[11]]);
        if length < 12 {
            return Err(invalid(&format!(
                "GLB header gives a total length of {length} bytes, less than the 12-byte header"
            )));
        }
    }
    let Gltf { document, blob } =
        Gltf::from_slice_without_validation(bytes).map_err(|e| invalid(&e))?;
    let json = document.into_json();
    let accessor_count = json.accessors.len();
    for (m, mesh) in json.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let position = ::gltf::json::validation::Checked::Valid(::gltf::Semantic::Positions);
            if let Some(index) = primitive.attributes.get(&position) {
                if index.value() >= accessor_count {
                    return Err(invalid(&format!(
                        "meshes[{m}].primitives[{p}].attributes.POSITION: accessor {} does not exist ({accessor_count} accessors)",
                        index.value()
                    )));
                }
            }
        }
    }
    let document = Document::from_json(json).map_err(|e| invalid(&e))?;
    Ok(Gltf { document, blob })
}

/// Reads every buffer of the document: the GLB binary chunk, `data:` URIs, or files relative
/// to `base`; checks each holds at least its declared `byteLength`.
fn load_buffers(
    path: &Path,
    base: &Path,
    document: &Document,
    mut blob: Option<Vec<u8>>,
    read_file: &mut dyn FnMut(&Path) -> std::io::Result<Vec<u8>>,
) -> Result<Vec<Vec<u8>>> {
    let mut buffers = Vec::new();
    for buffer in document.buffers() {
        let i = buffer.index();
        let (data, origin) = match buffer.source() {
            ::gltf::buffer::Source::Bin => (
                blob.take().ok_or_else(|| {
                    Error::invalid_file(
                        path,
                        format!("buffer {i} refers to a GLB binary chunk the file lacks"),
                    )
                })?,
                "the GLB binary chunk".to_string(),
            ),
            ::gltf::buffer::Source::Uri(uri) => (
                read_uri(path, base, uri, &format!("buffer {i}"), read_file)?,
                describe_uri(uri),
            ),
        };
        if data.len() < buffer.length() {
            return Err(Error::invalid_file(
                path,
                format!(
                    "buffer {i} ({origin}) is truncated: {} bytes, byteLength says {}",
                    data.len(),
                    buffer.length()
                ),
            ));
        }
        buffers.push(data);
    }
    Ok(buffers)
}

/// A short description of a URI for messages (data URIs are not quoted in full).
fn describe_uri(uri: &str) -> String {
    if uri.starts_with("data:") {
        "data URI".to_string()
    } else {
        format!("'{uri}'")
    }
}

/// The bytes a URI refers to: a base64 `data:` URI, a `file:` URI, or a percent-encoded
/// path relative to `base`. `what` names the referring object in error messages.
fn read_uri(
    path: &Path,
    base: &Path,
    uri: &str,
    what: &str,
    read_file: &mut dyn FnMut(&Path) -> std::io::Result<Vec<u8>>,
) -> Result<Vec<u8>> {
    if uri.starts_with("data:") {
        let data = ::gltf::buffer::Data::from_source(::gltf::buffer::Source::Uri(uri), None)
            .map_err(|e| Error::invalid_file(path, format!("{what}: bad data URI: {e}")))?;
        return Ok(data.0);
    }
    let file_path = if let Some(rest) = uri
        .strip_prefix("file://")
        .or_else(|| uri.strip_prefix("file:"))
    {
        PathBuf::from(percent_decode(rest, path, what)?)
    } else if uri.contains(':') {
        return Err(Error::invalid_file(
            path,
            format!("{what}: unsupported URI scheme in '{uri}' (only data: and relative paths)"),
        ));
    } else {
        base.join(percent_decode(uri, path, what)?)
    };
    read_file(&file_path).map_err(|e| Error::io(file_path, e))
}

/// Decodes `%XX` escapes of a URI path.
fn percent_decode(uri: &str, path: &Path, what: &str) -> Result<String> {
    let bad = || Error::invalid_file(path, format!("{what}: malformed URI '{uri}'"));
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = bytes.get(i + 1..i + 3).ok_or_else(bad)?;
            let hex = std::str::from_utf8(hex).map_err(|_| bad())?;
            out.push(u8::from_str_radix(hex, 16).map_err(|_| bad())?);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).map_err(|_| bad())
}

/// The state of one load.
struct Loader<'a> {
    path: &'a Path,
    base: &'a Path,
    /// Reads the files the glTF file refers to (see [`load_from_bytes_with`]).
    read_file: &'a mut dyn FnMut(&Path) -> std::io::Result<Vec<u8>>,
    buffers: &'a [Vec<u8>],
    scene: SceneDescription,
    /// glTF image index → index into `scene.textures`.
    texture_of_image: HashMap<usize, usize>,
    /// Index of the material given to primitives without one, once created.
    default_material: Option<u32>,
    saw_orthographic: bool,
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

    fn visit(&mut self, node: &Node, world: Mat4) -> Result<()> {
        if let Some(mesh) = node.mesh() {
            let name = mesh
                .name()
                .map(str::to_string)
                .unwrap_or_else(|| format!("#{}", mesh.index()));
            for primitive in mesh.primitives() {
                let part = self.primitive(&name, &primitive, world)?;
                self.scene.geometry.append(&part, self.path)?;
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
            let radiometric = Rgb::from_array(light.color()) * light.intensity();
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

    /// One primitive's triangles in world space, with material ids set.
    fn primitive(&mut self, mesh: &str, primitive: &Primitive, world: Mat4) -> Result<Geometry> {
        let index = primitive.index();
        let mode = primitive.mode();
        if !matches!(
            mode,
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            return Err(self.invalid(format!(
                "unsupported primitive mode {} in mesh '{mesh}' (only triangles, strips and fans)",
                mode_name(mode)
            )));
        }
        let what = |attribute: &str| format!("{attribute} of primitive {index} in mesh '{mesh}'");
        let buffers = self.buffers;
        let reader = primitive.reader(|b| buffers.get(b.index()).map(Vec::as_slice));

        let positions_accessor = primitive
            .get(&::gltf::Semantic::Positions)
            .ok_or_else(|| self.invalid(format!("{} is missing", what("POSITION"))))?;
        self.check_accessor(
            &positions_accessor,
            &what("POSITION"),
            &[DataType::F32],
            Dimensions::Vec3,
        )?;
        let local_positions: Vec<Vec3> = reader
            .read_positions()
            .ok_or_else(|| self.invalid(format!("cannot read {}", what("POSITION"))))?
            .map(Vec3::from_array)
            .collect();
        let vertex_count = local_positions.len();

        let local_normals: Option<Vec<Vec3>> = match primitive.get(&::gltf::Semantic::Normals) {
            Some(accessor) => {
                self.check_accessor(
                    &accessor,
                    &what("NORMAL"),
                    &[DataType::F32],
                    Dimensions::Vec3,
                )?;
                let normals: Vec<Vec3> = reader
                    .read_normals()
                    .ok_or_else(|| self.invalid(format!("cannot read {}", what("NORMAL"))))?
                    .map(Vec3::from_array)
                    .collect();
                self.check_count(normals.len(), vertex_count, &what("NORMAL"))?;
                Some(normals)
            }
            None => None,
        };

        let uvs: Vec<Vec2> = match primitive.get(&::gltf::Semantic::TexCoords(0)) {
            Some(accessor) => {
                self.check_accessor(
                    &accessor,
                    &what("TEXCOORD_0"),
                    &[DataType::F32, DataType::U8, DataType::U16],
                    Dimensions::Vec2,
                )?;
                let uvs: Vec<Vec2> = reader
                    .read_tex_coords(0)
                    .ok_or_else(|| self.invalid(format!("cannot read {}", what("TEXCOORD_0"))))?
                    .into_f32()
                    .map(Vec2::from_array)
                    .collect();
                self.check_count(uvs.len(), vertex_count, &what("TEXCOORD_0"))?;
                uvs
            }
            None => vec![Vec2::ZERO; vertex_count],
        };

        let indices: Vec<u32> = match primitive.indices() {
            Some(accessor) => {
                self.check_accessor(
                    &accessor,
                    &what("indices"),
                    &[DataType::U8, DataType::U16, DataType::U32],
                    Dimensions::Scalar,
                )?;
                reader
                    .read_indices()
                    .ok_or_else(|| self.invalid(format!("cannot read {}", what("indices"))))?
                    .into_u32()
                    .collect()
            }
            None => (0..u32::try_from(vertex_count)
                .map_err(|_| self.invalid(format!("too many vertices in {}", what("POSITION"))))?)
                .collect(),
        };
        if let Some(&bad) = indices.iter().find(|&&i| i as usize >= vertex_count) {
            return Err(self.invalid(format!(
                "index {bad} out of range ({vertex_count} vertices) in primitive {index} of mesh '{mesh}'"
            )));
        }
        let mut triangles = assemble_triangles(mode, &indices).ok_or_else(|| {
            self.invalid(format!(
                "{} index count {} is not a multiple of 3 in primitive {index} of mesh '{mesh}'",
                mode_name(mode),
                indices.len()
            ))
        })?;

        let positions: Vec<Vec3> = local_positions
            .iter()
            .map(|&p| world.transform_point3(p))
            .collect();
        if positions.iter().any(|p| !p.is_finite()) {
            return Err(self.invalid(format!("non-finite vertex position in mesh '{mesh}'")));
        }
        let linear = Mat3::from_mat4(world);
        if linear.determinant() < 0.0 {
            for t in &mut triangles {
                t.swap(1, 2);
            }
        }
        let normal_matrix = linear.inverse().transpose();
        let normals = match local_normals {
            Some(local) => {
                let transformed: Vec<Option<Vec3>> = local
                    .iter()
                    .map(|&n| (normal_matrix * n).try_normalize())
                    .collect();
                if transformed.iter().all(Option::is_some) {
                    transformed.into_iter().flatten().collect()
                } else {
                    let smooth = smooth_vertex_normals(&positions, &triangles);
                    transformed
                        .into_iter()
                        .zip(smooth)
                        .map(|(n, s)| n.unwrap_or(s))
                        .collect()
                }
            }
            None => smooth_vertex_normals(&positions, &triangles),
        };

        let material_id = match primitive.material().index() {
            Some(i) => u32::try_from(i).map_err(|_| self.invalid("too many materials"))?,
            None => self.default_material_id()?,
        };
        let material_ids = vec![material_id; triangles.len()];
        Ok(Geometry {
            positions,
            normals,
            uvs,
            triangles,
            material_ids,
        })
    }

    /// Checks what the `gltf` crate's readers assume but do not check, so reading can
    /// neither panic nor silently truncate: component type and dimensions, a non-zero count,
    /// a buffer view (sparse accessors are not supported), a stride at least the element
    /// size, and the accessed range inside the view and the view inside its buffer.
    fn check_accessor(
        &self,
        accessor: &Accessor,
        what: &str,
        types: &[DataType],
        dimensions: Dimensions,
    ) -> Result<()> {
        let i = accessor.index();
        if accessor.sparse().is_some() {
            return Err(self.invalid(format!("{what}: sparse accessor {i} is not supported")));
        }
        if !types.contains(&accessor.data_type()) || accessor.dimensions() != dimensions {
            return Err(self.invalid(format!(
                "{what}: accessor {i} has type {:?} {:?}, expected {dimensions:?} of {types:?}",
                accessor.dimensions(),
                accessor.data_type()
            )));
        }
        if accessor.count() == 0 {
            return Err(self.invalid(format!("{what}: accessor {i} has count 0")));
        }
        let view = accessor
            .view()
            .ok_or_else(|| self.invalid(format!("{what}: accessor {i} has no bufferView")))?;
        let element = accessor.size();
        let stride = view.stride().unwrap_or(element);
        if stride < element {
            return Err(self.invalid(format!(
                "{what}: bufferView {} has byteStride {stride}, smaller than accessor {i}'s {element}-byte elements",
                view.index()
            )));
        }
        let end = stride
            .checked_mul(accessor.count() - 1)
            .and_then(|n| n.checked_add(element))
            .and_then(|n| n.checked_add(accessor.offset()));
        if end.is_none_or(|end| end > view.length()) {
            return Err(self.invalid(format!(
                "{what}: accessor {i} reads past the end of bufferView {}",
                view.index()
            )));
        }
        let buffer_len = self.buffers.get(view.buffer().index()).map_or(0, Vec::len);
        if view
            .offset()
            .checked_add(view.length())
            .is_none_or(|end| end > buffer_len)
        {
            return Err(self.invalid(format!(
                "{what}: bufferView {} reads past the end of buffer {} ({buffer_len} bytes)",
                view.index(),
                view.buffer().index()
            )));
        }
        Ok(())
    }

    fn check_count(&self, count: usize, vertex_count: usize, what: &str) -> Result<()> {
        if count == vertex_count {
            Ok(())
        } else {
            Err(self.invalid(format!(
                "{what} has {count} elements but POSITION has {vertex_count}"
            )))
        }
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
        let name = material
            .name()
            .map(str::to_string)
            .unwrap_or_else(|| format!("material{}", material.index().unwrap_or(0)));
        let pbr = material.pbr_metallic_roughness();
        let [r, g, b, _] = pbr.base_color_factor();
        let base_color_texture = match pbr.base_color_texture() {
            Some(info) => Some(self.texture(document, info.texture().source().index(), &name)?),
            None => None,
        };
        let emission = Rgb::from_array(material.emissive_factor())
            * material.emissive_strength().unwrap_or(1.0);
        let model = surface_model(material.extras(), &name, self.base)
            .map_err(|reason| self.invalid(reason))?;
        let result = Material {
            model,
            base_color: Rgb::new(r, g, b),
            base_color_texture,
            metallic: pbr.metallic_factor().clamp(0.0, 1.0),
            roughness: pbr.roughness_factor().clamp(0.0, 1.0),
            emission,
            double_sided: material.double_sided(),
            name,
        };
        if !result.base_color.is_finite() || !result.emission.is_finite() {
            return Err(self.invalid(format!("material '{}' has non-finite factors", result.name)));
        }
        Ok(result)
    }

    /// The texture index of glTF image `image`, decoding it on first use.
    fn texture(&mut self, document: &Document, image: usize, material: &str) -> Result<usize> {
        if let Some(&t) = self.texture_of_image.get(&image) {
            return Ok(t);
        }
        let gltf_image = document.images().nth(image).ok_or_else(|| {
            self.invalid(format!("material '{material}' uses missing image {image}"))
        })?;
        let what = format!("image {image} (base colour of material '{material}')");
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
        let texture = Texture::from_encoded_srgb(&bytes, self.path, &what)?;
        let t = self.scene.textures.len();
        self.scene.textures.push(texture);
        self.texture_of_image.insert(image, t);
        Ok(t)
    }
}

/// A node's name for messages.
fn node_label(node: &Node) -> String {
    match node.name() {
        Some(name) => format!("'{name}'"),
        None => format!("#{}", node.index()),
    }
}

/// The glTF spelling of a primitive mode.
fn mode_name(mode: Mode) -> &'static str {
    match mode {
        Mode::Points => "POINTS",
        Mode::Lines => "LINES",
        Mode::LineLoop => "LINE_LOOP",
        Mode::LineStrip => "LINE_STRIP",
        Mode::Triangles => "TRIANGLES",
        Mode::TriangleStrip => "TRIANGLE_STRIP",
        Mode::TriangleFan => "TRIANGLE_FAN",
    }
}

/// Triangle list from a triangle mode's index sequence (glTF 2.0 § 3.7.2.1 orders strips as
/// (i, i + 1 + i % 2, i + 2 - i % 2) and fans as (i + 1, i + 2, 0)); `None` when a
/// TRIANGLES list's length is not a multiple of 3.
fn assemble_triangles(mode: Mode, indices: &[u32]) -> Option<Vec<[u32; 3]>> {
    let n = indices.len();
    match mode {
        Mode::TriangleStrip => Some(
            (0..n.saturating_sub(2))
                .map(|i| [indices[i], indices[i + 1 + i % 2], indices[i + 2 - i % 2]])
                .collect(),
        ),
        Mode::TriangleFan => Some(
            (1..n.saturating_sub(1))
                .map(|i| [indices[i], indices[i + 1], indices[0]])
                .collect(),
        ),
        _ => n.is_multiple_of(3).then(|| {
            indices
                .chunks_exact(3)
                .map(|t| [t[0], t[1], t[2]])
                .collect()
        }),
    }
}

/// Parses an `extras` object, or `None` when there are no extras.
fn extras_object(extras: &::gltf::json::Extras) -> Option<serde_json::Map<String, Value>> {
    let raw = extras.as_ref()?;
    match serde_json::from_str(raw.get()) {
        Ok(Value::Object(map)) => Some(map),
        _ => None,
    }
}

/// The surface model a material's extras ask for (see the module documentation).
fn surface_model(
    extras: &::gltf::json::Extras,
    material: &str,
    base: &Path,
) -> Result<SurfaceModel, String> {
    let Some(map) = extras_object(extras) else {
        return Ok(SurfaceModel::MetallicRoughness);
    };
    let keys: Vec<&str> = ["bsdf", "brdf", "neural"]
        .into_iter()
        .filter(|k| map.contains_key(*k))
        .collect();
    if keys.len() > 1 {
        return Err(format!(
            "material '{material}' extras give more than one of {}",
            keys.join(", ")
        ));
    }
    let string = |key: &str| -> Result<&str, String> {
        map[key]
            .as_str()
            .ok_or_else(|| format!("material '{material}' extras: '{key}' must be a string"))
    };
    match keys.first().copied() {
        Some("bsdf") => match string("bsdf")? {
            "diffuse" => Ok(SurfaceModel::Lambert),
            "metallic-roughness" => Ok(SurfaceModel::MetallicRoughness),
            other => Err(format!(
                "material '{material}' extras: unknown bsdf '{other}' (expected diffuse or metallic-roughness)"
            )),
        },
        Some("brdf") => {
            let text = string("brdf")?;
            if text.is_empty() {
                return Err(format!("material '{material}' extras: 'brdf' is empty"));
            }
            Binding::parse(text, base)
                .map(SurfaceModel::Bound)
                .map_err(|e| format!("material '{material}' extras: {e}"))
        }
        Some("neural") => {
            let name = string("neural")?;
            if name.is_empty() {
                return Err(format!("material '{material}' extras: 'neural' is empty"));
            }
            Ok(SurfaceModel::Bound(Binding::Neural(name.to_string())))
        }
        _ => Ok(SurfaceModel::MetallicRoughness),
    }
}

/// The environment named in `extras` (see [`EnvironmentSpec`]), `None` when there is none.
fn environment_from_extras(
    extras: &::gltf::json::Extras,
    path: &Path,
    base: &Path,
) -> Result<Option<EnvironmentSpec>> {
    let Some(map) = extras_object(extras) else {
        return Ok(None);
    };
    let Some(env) = map.get("environment") else {
        return Ok(None);
    };
    let bad = |reason: &str| Error::invalid_file(path, format!("extras.environment: {reason}"));
    let env = env.as_object().ok_or_else(|| bad("must be an object"))?;
    let number = |key: &str, default: f32| -> Result<f32> {
        match env.get(key) {
            None => Ok(default),
            Some(v) => v
                .as_f64()
                .map(|x| x as f32)
                .filter(|x| x.is_finite())
                .ok_or_else(|| bad(&format!("'{key}' must be a number"))),
        }
    };
    let strength = number("strength", 1.0)?;
    if strength < 0.0 {
        return Err(bad("'strength' must not be negative"));
    }
    let rotation = number("rotation_degrees", 0.0)?.to_radians();
    let source = match (env.get("image"), env.get("color")) {
        (Some(image), None) => {
            let image = image
                .as_str()
                .filter(|s| !s.is_empty())
                .ok_or_else(|| bad("'image' must be a file name"))?;
            EnvironmentSource::Image(base.join(image))
        }
        (None, Some(color)) => {
            let rgb: Vec<f32> = color
                .as_array()
                .map(|a| {
                    a.iter()
                        .filter_map(Value::as_f64)
                        .map(|x| x as f32)
                        .collect()
                })
                .unwrap_or_default();
            match rgb[..] {
                [r, g, b] if rgb.iter().all(|c| c.is_finite() && *c >= 0.0) => {
                    EnvironmentSource::Constant(Rgb::new(r, g, b))
                }
                _ => return Err(bad("'color' must be three non-negative numbers")),
            }
        }
        (Some(_), Some(_)) => return Err(bad("give either 'image' or 'color', not both")),
        (None, None) => return Err(bad("needs 'image' or 'color'")),
    };
    Ok(Some(EnvironmentSpec {
        source,
        strength,
        rotation,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;
    use std::f32::consts::FRAC_1_SQRT_2;

    /// Standard base64 with padding (for `data:` URIs written by the tests).
    fn base64(bytes: &[u8]) -> String {
        const ALPHABET: &[u8; 64] =
            b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
        let mut out = String::new();
        for chunk in bytes.chunks(3) {
            let b = [
                chunk[0],
                *chunk.get(1).unwrap_or(&0),
                *chunk.get(2).unwrap_or(&0),
            ];
            let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
            for k in 0..4 {
                if k <= chunk.len() {
                    out.push(ALPHABET[(n >> (18 - 6 * k) & 63) as usize] as char);
                } else {
                    out.push('=');
                }
            }
        }
        out
    }

    /// Accumulates one binary buffer with its buffer views and accessors.
    #[derive(Default)]
    struct Bin {
        bytes: Vec<u8>,
        views: Vec<Value>,
        accessors: Vec<Value>,
    }

    impl Bin {
        fn push(&mut self, data: &[u8], accessor: Value) -> usize {
            while !self.bytes.len().is_multiple_of(4) {
                self.bytes.push(0);
            }
            self.views.push(
                json!({"buffer": 0, "byteOffset": self.bytes.len(), "byteLength": data.len()}),
            );
            self.bytes.extend_from_slice(data);
            let mut accessor = accessor;
            accessor["bufferView"] = json!(self.views.len() - 1);
            self.accessors.push(accessor);
            self.accessors.len() - 1
        }

        fn vec3(&mut self, v: &[[f32; 3]]) -> usize {
            let data: Vec<u8> = v.iter().flatten().flat_map(|x| x.to_le_bytes()).collect();
            // glTF requires POSITION bounds; NaN is left out of them (f32::min ignores it).
            let bound = |f: fn(f32, f32) -> f32, start: f32| {
                (0..3)
                    .map(|k| v.iter().map(|p| p[k]).fold(start, f))
                    .collect::<Vec<f32>>()
            };
            self.push(
                &data,
                json!({"componentType": 5126, "count": v.len(), "type": "VEC3",
                       "min": bound(f32::min, f32::MAX), "max": bound(f32::max, f32::MIN)}),
            )
        }

        fn vec2(&mut self, v: &[[f32; 2]]) -> usize {
            let data: Vec<u8> = v.iter().flatten().flat_map(|x| x.to_le_bytes()).collect();
            self.push(
                &data,
                json!({"componentType": 5126, "count": v.len(), "type": "VEC2"}),
            )
        }

        fn indices(&mut self, v: &[u16]) -> usize {
            let data: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
            self.push(
                &data,
                json!({"componentType": 5123, "count": v.len(), "type": "SCALAR"}),
            )
        }

        /// Adds buffers, views and accessors to `root`; the buffer's uri is `uri` (None for
        /// a GLB binary chunk).
        fn finish(self, mut root: Value, uri: Option<String>) -> (Value, Vec<u8>) {
            let mut buffer = json!({"byteLength": self.bytes.len()});
            if let Some(uri) = uri {
                buffer["uri"] = json!(uri);
            }
            root["buffers"] = json!([buffer]);
            root["bufferViews"] = json!(self.views);
            root["accessors"] = json!(self.accessors);
            (root, self.bytes)
        }

        /// Finishes with the buffer embedded as a data URI.
        fn embed(self, root: Value) -> Value {
            let uri = format!(
                "data:application/octet-stream;base64,{}",
                base64(&self.bytes)
            );
            self.finish(root, Some(uri)).0
        }
    }

    const TRIANGLE: [[f32; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];

    /// A document with one triangle mesh (mesh 0: "tri", with normals +z, uvs, indices,
    /// material 0 if `with_material`), and `extra` merged into the root.
    fn triangle_doc(nodes: Value, scene_nodes: Value, extra: Value) -> Value {
        let mut bin = Bin::default();
        let p = bin.vec3(&TRIANGLE);
        let n = bin.vec3(&[[0.0, 0.0, 1.0]; 3]);
        let t = bin.vec2(&[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]);
        let i = bin.indices(&[0, 1, 2]);
        let mut root = json!({
            "asset": {"version": "2.0"},
            "scene": 0,
            "scenes": [{"nodes": scene_nodes}],
            "nodes": nodes,
            "meshes": [{"name": "tri", "primitives": [{
                "attributes": {"POSITION": p, "NORMAL": n, "TEXCOORD_0": t},
                "indices": i
            }]}]
        });
        if let (Some(root), Some(extra)) = (root.as_object_mut(), extra.as_object()) {
            for (k, v) in extra {
                root.insert(k.clone(), v.clone());
            }
        }
        bin.embed(root)
    }

    fn write(dir: &Path, name: &str, doc: &Value) -> PathBuf {
        let path = dir.join(name);
        std::fs::write(&path, serde_json::to_vec_pretty(doc).expect("serialise")).expect("write");
        path
    }

    fn load_doc(doc: &Value) -> Result<SceneDescription> {
        let dir = tempfile::tempdir().expect("tempdir");
        load(&write(dir.path(), "scene.gltf", doc))
    }

    /// Loads `doc`, expects an error, and checks its message names the file and `problem`.
    fn expect_error(doc: &Value, problem: &str) -> String {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = write(dir.path(), "bad.gltf", doc);
        let message = load(&path).expect_err("load must fail").to_string();
        assert!(message.contains(&path.display().to_string()), "{message}");
        assert!(message.contains(problem), "{message}");
        assert!(!message.contains('\n'), "{message}");
        message
    }

    fn close(a: Vec3, b: Vec3) -> bool {
        (a - b).length() < 1e-5
    }

    #[test]
    fn single_triangle_loads_with_attributes() {
        let doc = triangle_doc(json!([{"mesh": 0}]), json!([0]), json!({}));
        let scene = load_doc(&doc).expect("load");
        let g = &scene.geometry;
        assert_eq!(g.triangles, vec![[0, 1, 2]]);
        assert_eq!(g.positions, TRIANGLE.map(Vec3::from_array).to_vec());
        assert_eq!(g.normals, vec![Vec3::Z; 3]);
        assert_eq!(g.uvs[1], Vec2::new(1.0, 0.0));
        assert_eq!(scene.materials.len(), 1);
        assert_eq!(scene.materials[0].name, "default");
        assert_eq!(scene.materials[0].model, SurfaceModel::Lambert);
        assert!(scene.cameras.is_empty() && scene.lights.is_empty());
        assert!(scene.environment.is_none());
    }

    #[test]
    fn child_under_translated_and_scaled_parent_lands_in_place() {
        let nodes = json!([
            {"name": "parent", "translation": [1.0, 2.0, 3.0], "scale": [2.0, 2.0, 2.0], "children": [1, 2]},
            {"name": "trs-child", "translation": [1.0, 0.0, 0.0], "mesh": 0},
            {"name": "matrix-child", "mesh": 0,
             "matrix": [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, -1.0, 1.0]}
        ]);
        let scene = load_doc(&triangle_doc(nodes, json!([0]), json!({}))).expect("load");
        let g = &scene.geometry;
        assert_eq!(g.triangle_count(), 2);
        // world = T(1,2,3) S(2) T(child): p -> 2 (p + t) + (1, 2, 3).
        let first = g.triangle_positions(0);
        assert!(close(first[0], Vec3::new(3.0, 2.0, 3.0)));
        assert!(close(first[1], Vec3::new(5.0, 2.0, 3.0)));
        assert!(close(first[2], Vec3::new(3.0, 4.0, 3.0)));
        let second = g.triangle_positions(1);
        assert!(close(second[0], Vec3::new(1.0, 2.0, 1.0)));
        assert!(close(second[2], Vec3::new(1.0, 4.0, 1.0)));
        assert!(g.normals.iter().all(|&n| close(n, Vec3::Z)));
    }

    #[test]
    fn normals_use_the_inverse_transpose() {
        let mut bin = Bin::default();
        // The plane x + y = 1 with its normal (1, 1, 0) / sqrt 2.
        let p = bin.vec3(&[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 0.0, 1.0]]);
        let s = FRAC_1_SQRT_2;
        let n = bin.vec3(&[[s, s, 0.0]; 3]);
        let doc = bin.embed(json!({
            "asset": {"version": "2.0"},
            "scenes": [{"nodes": [0]}],
            "nodes": [{"mesh": 0, "scale": [2.0, 1.0, 1.0]}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": p, "NORMAL": n}}]}]
        }));
        let scene = load_doc(&doc).expect("load");
        // Stretched plane x/2 + y = 1: normal (1/2, 1, 0) normalised.
        let expected = Vec3::new(0.5, 1.0, 0.0).normalize();
        assert!(scene.geometry.normals.iter().all(|&n| close(n, expected)));
        let [a, b, c] = scene.geometry.triangle_positions(0);
        assert!(close((b - a).cross(c - a).normalize(), expected));
    }

    #[test]
    fn missing_normals_are_computed_smooth_and_area_weighted() {
        let mut bin = Bin::default();
        // Two faces sharing the edge 0-1: a large one facing +z and a small one facing +x.
        let p = bin.vec3(&[
            [0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [-3.0, 0.0, 0.0],
            [0.0, 0.0, -1.0],
        ]);
        let i = bin.indices(&[0, 1, 2, 0, 3, 1]);
        let doc = bin.embed(json!({
            "asset": {"version": "2.0"},
            "scenes": [{"nodes": [0]}],
            "nodes": [{"mesh": 0}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": p}, "indices": i}]}]
        }));
        let g = load_doc(&doc).expect("load").geometry;
        let shared = Vec3::new(1.0, 0.0, 3.0).normalize();
        assert!(close(g.normals[0], shared), "{:?}", g.normals);
        assert!(close(g.normals[1], shared));
        assert!(close(g.normals[2], Vec3::Z));
        assert!(close(g.normals[3], Vec3::X));
    }

    #[test]
    fn mirroring_transform_keeps_fronts_counter_clockwise() {
        let doc = triangle_doc(
            json!([{"mesh": 0, "scale": [-1.0, 1.0, 1.0]}]),
            json!([0]),
            json!({}),
        );
        let g = load_doc(&doc).expect("load").geometry;
        let [a, b, c] = g.triangle_positions(0);
        let face = (b - a).cross(c - a).normalize();
        assert!(close(face, Vec3::Z), "{face}");
        assert!(g.normals.iter().all(|&n| close(n, Vec3::Z)));
    }

    #[test]
    fn strips_and_fans_become_triangle_lists() {
        let mut bin = Bin::default();
        let p = bin.vec3(&[
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [1.0, 1.0, 0.0],
        ]);
        let fan_p = bin.vec3(&[
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ]);
        let doc = bin.embed(json!({
            "asset": {"version": "2.0"},
            "scenes": [{"nodes": [0]}],
            "nodes": [{"mesh": 0}],
            "meshes": [{"primitives": [
                {"attributes": {"POSITION": p}, "mode": 5},
                {"attributes": {"POSITION": fan_p}, "mode": 6}
            ]}]
        }));
        let g = load_doc(&doc).expect("load").geometry;
        assert_eq!(
            g.triangles,
            vec![[0, 1, 2], [1, 3, 2], [5, 6, 4], [6, 7, 4]]
        );
        for t in 0..4 {
            let [a, b, c] = g.triangle_positions(t);
            assert!((b - a).cross(c - a).z > 0.0, "triangle {t} is clockwise");
        }
    }

    #[test]
    fn cameras_are_found_by_name_and_unknown_names_list_the_cameras() {
        let nodes = json!([
            {"mesh": 0},
            {"camera": 0, "translation": [0.0, 1.0, 5.0], "scale": [3.0, 3.0, 3.0]},
            {"name": "side", "camera": 1, "translation": [5.0, 0.0, 0.0],
             "rotation": [0.0, FRAC_1_SQRT_2, 0.0, FRAC_1_SQRT_2]},
            {"camera": 2}
        ]);
        let cameras = json!({"cameras": [
            {"name": "main", "type": "perspective", "perspective": {"yfov": 0.5, "aspectRatio": 1.5, "znear": 0.1}},
            {"type": "perspective", "perspective": {"yfov": 0.7, "znear": 0.1}},
            {"name": "ortho", "type": "orthographic", "orthographic": {"xmag": 1.0, "ymag": 1.0, "znear": 0.1, "zfar": 10.0}}
        ]});
        let scene = load_doc(&triangle_doc(nodes, json!([0, 1, 2, 3]), cameras)).expect("load");
        assert_eq!(scene.cameras.len(), 2, "the orthographic camera is skipped");
        let main = scene.camera(None).expect("first camera");
        assert_eq!(main.name, "main");
        assert_eq!(main.aspect_ratio, Some(1.5));
        assert!((main.yfov - 0.5).abs() < 1e-6);
        assert!(close(
            main.camera_to_world.transform_point3(Vec3::ZERO),
            Vec3::new(0.0, 1.0, 5.0)
        ));
        assert!(
            close(main.camera_to_world.transform_vector3(Vec3::X), Vec3::X),
            "scale removed"
        );
        let side = scene.camera(Some("side")).expect("named camera");
        assert_eq!(side.aspect_ratio, None);
        // +90° about y: the camera's -z looks toward -x, back at the origin.
        assert!(close(
            side.camera_to_world.transform_vector3(Vec3::NEG_Z),
            Vec3::NEG_X
        ));
        let message = scene.camera(Some("top")).expect_err("unknown").to_string();
        assert!(message.contains("camera 'top' not found"), "{message}");
        assert!(message.contains("main, side"), "{message}");
    }

    #[test]
    fn degenerate_camera_and_light_transforms_are_errors() {
        let cameras = json!({"cameras": [
            {"name": "flat", "type": "perspective", "perspective": {"yfov": 0.5, "znear": 0.1}}
        ]});
        let doc = triangle_doc(
            json!([{"mesh": 0}, {"camera": 0, "scale": [0.0, 0.0, 0.0]}]),
            json!([0, 1]),
            cameras,
        );
        expect_error(&doc, "camera 'flat' has a degenerate node transform");
        let lights = json!({
            "extensionsUsed": ["KHR_lights_punctual"],
            "extensions": {"KHR_lights_punctual": {"lights": [{"name": "sun", "type": "directional"}]}}
        });
        let doc = triangle_doc(
            json!([{"mesh": 0}, {"scale": [1.0, 1.0, 0.0], "extensions": {"KHR_lights_punctual": {"light": 0}}}]),
            json!([0, 1]),
            lights,
        );
        expect_error(&doc, "light 'sun' has a degenerate node transform");
    }

    #[test]
    fn only_orthographic_cameras_is_an_error() {
        let cameras = json!({"cameras": [
            {"type": "orthographic", "orthographic": {"xmag": 1.0, "ymag": 1.0, "znear": 0.1, "zfar": 10.0}}
        ]});
        let doc = triangle_doc(json!([{"mesh": 0}, {"camera": 0}]), json!([0, 1]), cameras);
        expect_error(&doc, "only orthographic cameras");
    }

    #[test]
    fn punctual_lights_of_all_three_kinds() {
        let s = FRAC_1_SQRT_2;
        let nodes = json!([
            {"mesh": 0},
            {"translation": [1.0, 2.0, 3.0], "extensions": {"KHR_lights_punctual": {"light": 0}}},
            {"translation": [0.0, 4.0, 0.0], "rotation": [-s, 0.0, 0.0, s],
             "extensions": {"KHR_lights_punctual": {"light": 1}}},
            {"rotation": [0.0, s, 0.0, s], "extensions": {"KHR_lights_punctual": {"light": 2}}}
        ]);
        let lights = json!({
            "extensionsUsed": ["KHR_lights_punctual"],
            "extensions": {"KHR_lights_punctual": {"lights": [
                {"type": "point", "color": [1.0, 0.5, 0.25], "intensity": 4.0},
                {"type": "spot", "intensity": 10.0, "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.5}},
                {"type": "directional", "color": [0.5, 0.5, 0.5], "intensity": 3.0}
            ]}}
        });
        let scene = load_doc(&triangle_doc(nodes, json!([0, 1, 2, 3]), lights)).expect("load");
        assert_eq!(scene.lights.len(), 3);
        assert_eq!(
            scene.lights[0],
            PunctualLight::Point {
                position: Vec3::new(1.0, 2.0, 3.0),
                intensity: Rgb::new(4.0, 2.0, 1.0)
            }
        );
        let PunctualLight::Spot {
            position,
            direction,
            intensity,
            cos_inner,
            cos_outer,
        } = scene.lights[1]
        else {
            panic!("expected a spot light, got {:?}", scene.lights[1]);
        };
        assert!(close(position, Vec3::new(0.0, 4.0, 0.0)));
        assert!(close(direction, Vec3::NEG_Y), "{direction}");
        assert_eq!(intensity, Rgb::splat(10.0));
        assert!((cos_inner - 0.2f32.cos()).abs() < 1e-6);
        assert!((cos_outer - 0.5f32.cos()).abs() < 1e-6);
        let PunctualLight::Directional {
            direction,
            irradiance,
        } = scene.lights[2]
        else {
            panic!("expected a directional light, got {:?}", scene.lights[2]);
        };
        assert!(close(direction, Vec3::NEG_X), "{direction}");
        assert_eq!(irradiance, Rgb::splat(1.5));
    }

    fn material_doc(materials: Value) -> Value {
        let mut doc = triangle_doc(
            json!([{"mesh": 0}]),
            json!([0]),
            json!({"materials": materials}),
        );
        doc["meshes"][0]["primitives"][0]["material"] = json!(0);
        doc
    }

    #[test]
    fn emissive_strength_multiplies_the_emissive_factor() {
        let doc = material_doc(json!([{
            "name": "lamp",
            "emissiveFactor": [1.0, 0.5, 0.25],
            "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 8.0}},
            "pbrMetallicRoughness": {"baseColorFactor": [0.2, 0.3, 0.4, 1.0], "metallicFactor": 0.25, "roughnessFactor": 0.75}
        }]));
        let scene = load_doc(&doc).expect("load");
        let m = &scene.materials[0];
        assert_eq!(scene.materials.len(), 1, "no default material needed");
        assert_eq!(m.name, "lamp");
        assert_eq!(m.emission, Rgb::new(8.0, 4.0, 2.0));
        assert_eq!(m.base_color, Rgb::new(0.2, 0.3, 0.4));
        assert_eq!((m.metallic, m.roughness), (0.25, 0.75));
        assert_eq!(m.model, SurfaceModel::MetallicRoughness);
        assert!(!m.double_sided);
        assert_eq!(scene.geometry.material_ids, vec![0]);
    }

    #[test]
    fn material_extras_choose_the_surface_model() {
        let dir = tempfile::tempdir().expect("tempdir");
        let mut doc = material_doc(json!([
            {"name": "a", "extras": {"bsdf": "diffuse"}},
            {"name": "b", "extras": {"brdf": "merl:tables/alum-bronze.binary"}},
            {"name": "c", "extras": {"brdf": "nbrdf:/abs/net"}},
            {"name": "d", "extras": {"neural": "gold-paint"}},
            {"name": "e", "extras": {"note": "unrelated"}},
            {"name": "f", "extras": {"brdf": "neural:blue-fabric"}}
        ]));
        let prims: Vec<Value> = (0..6)
            .map(|m| json!({"attributes": {"POSITION": 0}, "material": m}))
            .collect();
        doc["meshes"][0]["primitives"] = json!(prims);
        let path = write(dir.path(), "scene.gltf", &doc);
        let scene = load(&path).expect("load");
        let models: Vec<&SurfaceModel> = scene.materials.iter().map(|m| &m.model).collect();
        let table = dir.path().join("tables/alum-bronze.binary");
        assert_eq!(
            models,
            vec![
                &SurfaceModel::Lambert,
                &SurfaceModel::Bound(Binding::Merl(table)),
                &SurfaceModel::Bound(Binding::Nbrdf("/abs/net".into())),
                &SurfaceModel::Bound(Binding::Neural("gold-paint".into())),
                &SurfaceModel::MetallicRoughness,
                &SurfaceModel::Bound(Binding::Neural("blue-fabric".into())),
            ]
        );
        assert_eq!(scene.geometry.material_ids, vec![0, 1, 2, 3, 4, 5]);
        let both =
            material_doc(json!([{"name": "x", "extras": {"bsdf": "diffuse", "neural": "n"}}]));
        expect_error(
            &both,
            "material 'x' extras give more than one of bsdf, neural",
        );
        let unknown = material_doc(json!([{"name": "y", "extras": {"bsdf": "glass"}}]));
        expect_error(&unknown, "unknown bsdf 'glass'");
        let bad = material_doc(json!([{"name": "z", "extras": {"brdf": "phong:x"}}]));
        expect_error(&bad, "material 'z' extras: BRDF binding kind 'phong:x' not found");
    }

    #[test]
    fn base_color_texture_is_decoded_from_srgb() {
        let mut png = Vec::new();
        image::RgbImage::from_raw(2, 1, vec![255, 128, 0, 10, 20, 30])
            .expect("image")
            .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .expect("encode png");
        let mut doc = material_doc(
            json!([{"name": "tex", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]),
        );
        doc["textures"] = json!([{"source": 0}]);
        doc["images"] = json!([{"uri": format!("data:image/png;base64,{}", base64(&png))}]);
        let scene = load_doc(&doc).expect("load");
        assert_eq!(scene.materials[0].base_color_texture, Some(0));
        let t = &scene.textures[0];
        assert_eq!((t.width, t.height), (2, 1));
        assert!((t.texels[0].x - 1.0).abs() < 1e-5 && t.texels[0].z == 0.0);
        assert!((t.texels[0].y - 0.215_861).abs() < 1e-4, "{}", t.texels[0]);
        assert!((t.texels[1].x - 0.003_035).abs() < 1e-5, "{}", t.texels[1]);
    }

    #[test]
    fn environment_from_scene_extras_then_asset_extras() {
        let dir = tempfile::tempdir().expect("tempdir");
        let mut doc = triangle_doc(json!([{"mesh": 0}]), json!([0]), json!({}));
        doc["scenes"][0]["extras"] = json!({"environment": {"image": "studio.exr", "strength": 2.0, "rotation_degrees": 90.0}});
        let scene = load(&write(dir.path(), "scene.gltf", &doc)).expect("load");
        let env = scene.environment.expect("environment");
        assert_eq!(
            env.source,
            EnvironmentSource::Image(dir.path().join("studio.exr"))
        );
        assert_eq!(env.strength, 2.0);
        assert!((env.rotation - std::f32::consts::FRAC_PI_2).abs() < 1e-6);

        doc["scenes"][0]["extras"] = json!({"other": 1});
        doc["asset"]["extras"] = json!({"environment": {"color": [0.1, 0.2, 0.3]}});
        let scene = load_doc(&doc).expect("load");
        assert_eq!(
            scene.environment,
            Some(EnvironmentSpec {
                source: EnvironmentSource::Constant(Rgb::new(0.1, 0.2, 0.3)),
                strength: 1.0,
                rotation: 0.0
            })
        );

        doc["asset"]["extras"] = json!({"environment": {"color": [1.0, 2.0]}});
        expect_error(
            &doc,
            "extras.environment: 'color' must be three non-negative numbers",
        );
        doc["asset"]["extras"] =
            json!({"environment": {"image": "a.exr", "color": [1.0, 1.0, 1.0]}});
        expect_error(&doc, "either 'image' or 'color'");
    }

    #[test]
    fn glb_with_binary_chunk_loads() {
        let mut bin = Bin::default();
        let p = bin.vec3(&TRIANGLE);
        let root = json!({
            "asset": {"version": "2.0"},
            "scenes": [{"nodes": [0]}],
            "nodes": [{"mesh": 0, "translation": [0.0, 0.0, -2.0]}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": p}}]}]
        });
        let (root, mut bin_chunk) = bin.finish(root, None);
        let mut json_chunk = serde_json::to_vec(&root).expect("serialise");
        while !json_chunk.len().is_multiple_of(4) {
            json_chunk.push(b' ');
        }
        while !bin_chunk.len().is_multiple_of(4) {
            bin_chunk.push(0);
        }
        let total = 12 + 8 + json_chunk.len() + 8 + bin_chunk.len();
        let mut glb = Vec::new();
        glb.extend_from_slice(b"glTF");
        glb.extend_from_slice(&2u32.to_le_bytes());
        glb.extend_from_slice(&(total as u32).to_le_bytes());
        glb.extend_from_slice(&(json_chunk.len() as u32).to_le_bytes());
        glb.extend_from_slice(b"JSON");
        glb.extend_from_slice(&json_chunk);
        glb.extend_from_slice(&(bin_chunk.len() as u32).to_le_bytes());
        glb.extend_from_slice(b"BIN\0");
        glb.extend_from_slice(&bin_chunk);
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("scene.glb");
        std::fs::write(&path, &glb).expect("write");
        let scene = SceneDescription::load(&path).expect("load");
        assert_eq!(scene.geometry.triangle_count(), 1);
        assert!(close(
            scene.geometry.positions[1],
            Vec3::new(1.0, 0.0, -2.0)
        ));
    }

    /// A triangle document whose buffer lives in `scene.bin` next to it.
    fn external_bin(dir: &Path, truncate_to: Option<usize>) -> PathBuf {
        let mut bin = Bin::default();
        let p = bin.vec3(&TRIANGLE);
        let (doc, mut bytes) = bin.finish(
            json!({
                "asset": {"version": "2.0"},
                "scenes": [{"nodes": [0]}],
                "nodes": [{"mesh": 0}],
                "meshes": [{"primitives": [{"attributes": {"POSITION": p}}]}]
            }),
            Some("scene%20data.bin".into()),
        );
        if let Some(n) = truncate_to {
            bytes.truncate(n);
        }
        std::fs::write(dir.join("scene data.bin"), bytes).expect("write bin");
        write(dir, "scene.gltf", &doc)
    }

    #[test]
    fn external_bin_loads_and_truncated_bin_is_an_error() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = external_bin(dir.path(), None);
        assert_eq!(load(&path).expect("load").geometry.triangle_count(), 1);
        let path = external_bin(dir.path(), Some(20));
        let message = load(&path).expect_err("truncated").to_string();
        assert!(message.contains(&path.display().to_string()), "{message}");
        assert!(
            message.contains(
                "buffer 0 ('scene%20data.bin') is truncated: 20 bytes, byteLength says 36"
            ),
            "{message}"
        );
    }

    #[test]
    fn missing_files_are_io_errors_naming_them() {
        let dir = tempfile::tempdir().expect("tempdir");
        let missing = dir.path().join("nowhere.gltf");
        let error = load(&missing).expect_err("missing");
        assert!(
            matches!(error, Error::Io { ref path, .. } if path == &missing),
            "{error}"
        );
        let path = external_bin(dir.path(), None);
        std::fs::remove_file(dir.path().join("scene data.bin")).expect("remove");
        let error = load(&path).expect_err("missing bin");
        assert!(
            matches!(error, Error::Io { ref path, .. } if path.ends_with("scene data.bin")),
            "{error}"
        );
    }

    #[test]
    fn malformed_json_is_an_invalid_file() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("broken.gltf");
        std::fs::write(&path, b"{\"asset\": {\"version\": \"2.0\"}, \"nodes\": [").expect("write");
        let error = load(&path).expect_err("malformed");
        let message = error.to_string();
        assert!(matches!(error, Error::InvalidFile { .. }));
        assert!(
            message.starts_with(&path.display().to_string()),
            "{message}"
        );
        assert!(message.contains("not a valid glTF file"), "{message}");
        let doc = json!({"asset": {"version": "2.0"}, "scenes": [{"nodes": [7]}]});
        expect_error(&doc, "not a valid glTF file");
    }

    #[test]
    fn bad_accessors_are_invalid_files() {
        let mut doc = triangle_doc(json!([{"mesh": 0}]), json!([0]), json!({}));
        doc["accessors"][0]["count"] = json!(4);
        expect_error(
            &doc,
            "POSITION of primitive 0 in mesh 'tri': accessor 0 reads past the end of bufferView 0",
        );
        let mut doc = triangle_doc(json!([{"mesh": 0}]), json!([0]), json!({}));
        doc["accessors"][0]["type"] = json!("VEC2");
        expect_error(&doc, "accessor 0 has type Vec2 F32, expected Vec3");
        let mut doc = triangle_doc(json!([{"mesh": 0}]), json!([0]), json!({}));
        doc["bufferViews"][0]["byteLength"] = json!(1000);
        expect_error(&doc, "bufferView 0 reads past the end of buffer 0");
        let mut doc = triangle_doc(json!([{"mesh": 0}]), json!([0]), json!({}));
        doc["bufferViews"][3]["byteLength"] = json!(6);
        doc["accessors"][3]["count"] = json!(3);
        doc["bufferViews"][0]["byteStride"] = json!(4);
        expect_error(
            &doc,
            "byteStride 4, smaller than accessor 0's 12-byte elements",
        );
    }

    #[test]
    fn out_of_range_index_is_an_invalid_file() {
        let mut bin = Bin::default();
        let p = bin.vec3(&TRIANGLE);
        let i = bin.indices(&[0, 1, 3]);
        let doc = bin.embed(json!({
            "asset": {"version": "2.0"},
            "scenes": [{"nodes": [0]}],
            "nodes": [{"mesh": 0}],
            "meshes": [{"name": "m", "primitives": [{"attributes": {"POSITION": p}, "indices": i}]}]
        }));
        expect_error(
            &doc,
            "index 3 out of range (3 vertices) in primitive 0 of mesh 'm'",
        );
    }

    #[test]
    fn lines_are_an_unsupported_primitive_mode() {
        let mut doc = triangle_doc(json!([{"mesh": 0}]), json!([0]), json!({}));
        doc["meshes"][0]["primitives"][0]["mode"] = json!(1);
        expect_error(&doc, "unsupported primitive mode LINES in mesh 'tri'");
        doc["meshes"][0]["primitives"][0]["mode"] = json!(0);
        expect_error(&doc, "unsupported primitive mode POINTS in mesh 'tri'");
    }

    #[test]
    fn a_scene_without_triangles_is_an_error() {
        let doc = triangle_doc(json!([{"name": "empty"}]), json!([0]), json!({}));
        expect_error(&doc, "contains no triangles");
        let mut doc = triangle_doc(json!([{"mesh": 0}]), json!([0]), json!({}));
        doc["meshes"][0]["primitives"][0]["mode"] = json!(5);
        doc["accessors"][3]["count"] = json!(2);
        expect_error(&doc, "contains no triangles");
    }

    #[test]
    fn non_finite_positions_are_an_error() {
        let mut bin = Bin::default();
        let p = bin.vec3(&[[0.0, 0.0, 0.0], [f32::NAN, 0.0, 0.0], [0.0, 1.0, 0.0]]);
        let doc = bin.embed(json!({
            "asset": {"version": "2.0"},
            "scenes": [{"nodes": [0]}],
            "nodes": [{"mesh": 0}],
            "meshes": [{"name": "bad", "primitives": [{"attributes": {"POSITION": p}}]}]
        }));
        expect_error(&doc, "non-finite vertex position in mesh 'bad'");
        let overflow = triangle_doc(
            json!([{"mesh": 0, "scale": [3e38, 3e38, 3e38], "translation": [3e38, 0.0, 0.0]}]),
            json!([0]),
            json!({}),
        );
        expect_error(&overflow, "non-finite vertex position in mesh 'tri'");
    }

    #[test]
    fn node_cycles_are_an_error() {
        let doc = triangle_doc(
            json!([{"name": "a", "mesh": 0, "children": [1]}, {"name": "b", "children": [0]}]),
            json!([0]),
            json!({}),
        );
        expect_error(&doc, "node 'a' is reached twice");
    }

    fn shipped(relative: &str) -> Option<PathBuf> {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("..")
            .join(relative);
        path.exists().then_some(path)
    }

    #[test]
    fn shipped_material_preview_loads() {
        let Some(path) = shipped("scenes/material-preview/scene.gltf") else {
            panic!("scenes/material-preview/scene.gltf is missing (run assets-scripts/make_material_preview.py)");
        };
        let scene = load(&path).expect("load");
        let camera = scene.camera(Some("camera")).expect("camera");
        assert!((camera.yfov - 30f32.to_radians()).abs() < 1e-5);
        assert_eq!(camera.aspect_ratio, Some(1.0));
        let eye = camera.camera_to_world.transform_point3(Vec3::ZERO);
        assert!(
            (eye.length() - 2.0).abs() < 1e-4,
            "camera at distance {}",
            eye.length()
        );
        let forward = camera.camera_to_world.transform_vector3(Vec3::NEG_Z);
        assert!(
            close(forward, -eye.normalize()),
            "camera looks at the sphere"
        );
        let preview = scene
            .materials
            .iter()
            .position(|m| m.name == "preview")
            .expect("preview material");
        assert_eq!(
            scene.materials[preview].model,
            SurfaceModel::Bound(Binding::Neural("alum-bronze".to_string())),
            "the preview binds the shipped latent code by its extras"
        );
        assert!(
            scene
                .materials
                .iter()
                .any(|m| m.model == SurfaceModel::Lambert),
            "diffuse ground"
        );
        assert!(!scene.lights.is_empty());
        let Some(EnvironmentSpec {
            source: EnvironmentSource::Image(image),
            ..
        }) = &scene.environment
        else {
            panic!("expected an image environment, got {:?}", scene.environment);
        };
        let envmap = image::open(image).expect("studio.exr decodes");
        assert_eq!((envmap.width(), envmap.height()), (512, 256));
        let sphere: Vec<usize> = (0..scene.geometry.triangle_count())
            .filter(|&t| scene.geometry.material_ids[t] as usize == preview)
            .collect();
        assert!(sphere.len() > 10_000);
        for &t in &sphere {
            let [a, b, c] = scene.geometry.triangle_positions(t);
            let face = (b - a).cross(c - a);
            let centre = (a + b + c) / 3.0;
            assert!(face.dot(centre) >= 0.0, "sphere triangle {t} faces inward");
        }
    }

    #[test]
    fn shipped_cornell_box_loads() {
        let Some(path) = shipped("scenes/cornell-box/scene.gltf") else {
            return;
        };
        let scene = load(&path).expect("load");
        assert!(scene.geometry.triangle_count() >= 30);
        assert!(scene.camera(None).is_ok());
        assert!(scene
            .materials
            .iter()
            .any(|m| m.emission.max_element() > 0.0));
    }
}
