//! Scene descriptions as loaded from files (glTF, OBJ), before acceleration structures and
//! light samplers are built. Everything is in world space, y up, scene units.

use crate::{Error, Result, Rgb};
use glam::{Mat3, Mat4, Vec2, Vec3, Vec4};
use std::path::{Path, PathBuf};

pub mod binding;
pub mod gltf;
pub mod obj;
pub mod texture;

pub use binding::{Binding, Varying, VaryingForm, BINDING_FORMS, MAX_MIX_PARTS};
pub use texture::{Texture, TextureRef};

/// All triangles of a scene: those placed once, in world space, followed by the
/// [`Mesh`]es that [`Instance`]s place, each in its own object space.
#[derive(Clone, Debug, Default)]
pub struct Geometry {
    /// Vertex positions, world space.
    pub positions: Vec<Vec3>,
    /// Unit shading normals per vertex, world space (computed from faces where a file has none).
    pub normals: Vec<Vec3>,
    /// Texture coordinates per vertex (glTF convention: v down), zero where a file has none.
    pub uvs: Vec<Vec2>,
    /// A second set of texture coordinates (glTF TEXCOORD_1), one per vertex, or empty when
    /// no mesh has one; a vertex whose mesh has none repeats its first set here.
    pub uvs1: Vec<Vec2>,
    /// Unit tangents per vertex, world space, with the handedness w = ±1 in the fourth
    /// component (glTF TANGENT: bitangent = w · normal × tangent, pointing up the normal
    /// map's image); empty when no material has a normal map. A vertex of a mesh without
    /// a normal-mapped material, or whose tangent could not be computed, holds zero.
    pub tangents: Vec<Vec4>,
    /// Vertex indices per triangle, counter-clockwise seen from the front side.
    pub triangles: Vec<[u32; 3]>,
    /// Index into [`SceneDescription::materials`] per triangle.
    pub material_ids: Vec<u32>,
}

impl Geometry {
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// World-space corners of triangle `i`.
    #[inline]
    pub fn triangle_positions(&self, i: usize) -> [Vec3; 3] {
        let [a, b, c] = self.triangles[i];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }

    /// Axis-aligned bounds `(min, max)` of all vertex positions; `None` when there are no
    /// vertices.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let first = *self.positions.first()?;
        Some(
            self.positions
                .iter()
                .fold((first, first), |(lo, hi), &p| (lo.min(p), hi.max(p))),
        )
    }

    /// Moves every vertex by `object_to_world`: positions; normals by the inverse transpose
    /// (normals that cannot be normalised afterwards become area-weighted smooth normals of
    /// the moved triangles); tangents by the linear part, their handedness w flipped under a
    /// mirroring transform (zero tangents stay zero); and triangles' winding flipped under a
    /// mirroring transform, so they stay counter-clockwise seen from the front (glTF: the
    /// determinant's sign decides the winding).
    pub fn transform(&mut self, object_to_world: Mat4) {
        for p in &mut self.positions {
            *p = object_to_world.transform_point3(*p);
        }
        let linear = Mat3::from_mat4(object_to_world);
        let handedness = linear.determinant().signum();
        if handedness < 0.0 {
            for t in &mut self.triangles {
                t.swap(1, 2);
            }
        }
        let normal_matrix = linear.inverse().transpose();
        let normals: Vec<Option<Vec3>> = self.normals.iter().map(|&n| (normal_matrix * n).try_normalize()).collect();
        self.normals = if normals.iter().all(Option::is_some) {
            normals.into_iter().flatten().collect()
        } else {
            let smooth = smooth_vertex_normals(&self.positions, &self.triangles);
            normals.into_iter().zip(smooth).map(|(n, s)| n.unwrap_or(s)).collect()
        };
        for t in &mut self.tangents {
            *t = match (linear * t.truncate()).try_normalize() {
                Some(xyz) if *t != Vec4::ZERO => xyz.extend(t.w * handedness),
                _ => Vec4::ZERO,
            };
        }
    }

    /// Appends `other`, offsetting its vertex indices; its material ids are kept as they are.
    ///
    /// Fails, naming `source`, when the vertex count would no longer fit the `u32` indices.
    pub fn append(&mut self, other: &Geometry, source: &Path) -> Result<()> {
        let total = self.positions.len() + other.positions.len();
        let offset = u32::try_from(self.positions.len())
            .ok()
            .filter(|_| u32::try_from(total).is_ok())
            .ok_or_else(|| Error::invalid_file(source, "more than 2^32 - 1 vertices in all"))?;
        self.positions.extend_from_slice(&other.positions);
        self.normals.extend_from_slice(&other.normals);
        if self.uvs1.is_empty() && !other.uvs1.is_empty() {
            self.uvs1 = self.uvs.clone();
        }
        if !self.uvs1.is_empty() {
            self.uvs1.extend_from_slice(if other.uvs1.is_empty() { &other.uvs } else { &other.uvs1 });
        }
        self.uvs.extend_from_slice(&other.uvs);
        if !self.tangents.is_empty() || !other.tangents.is_empty() {
            self.tangents.resize(self.positions.len() - other.positions.len(), Vec4::ZERO);
            match other.tangents.is_empty() {
                true => self.tangents.resize(self.positions.len(), Vec4::ZERO),
                false => self.tangents.extend_from_slice(&other.tangents),
            }
        }
        self.triangles.extend(
            other
                .triangles
                .iter()
                .map(|t| [t[0] + offset, t[1] + offset, t[2] + offset]),
        );
        self.material_ids.extend_from_slice(&other.material_ids);
        Ok(())
    }
}

/// Area-weighted smooth vertex normals: each vertex gets the normalised sum of the
/// (unnormalised) cross products of the triangles using it, so larger triangles weigh more
/// and the orientation follows the counter-clockwise winding.
///
/// Vertices that no triangle of non-zero area uses get +y. Triangle indices must be in range.
///
/// # Panics
/// If a triangle index is out of range of `positions`.
pub fn smooth_vertex_normals(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<Vec3> {
    let mut sums = vec![Vec3::ZERO; positions.len()];
    for &[a, b, c] in triangles {
        let (pa, pb, pc) = (
            positions[a as usize],
            positions[b as usize],
            positions[c as usize],
        );
        let n = (pb - pa).cross(pc - pa);
        if n.is_finite() {
            for i in [a, b, c] {
                sums[i as usize] += n;
            }
        }
    }
    sums.into_iter()
        .map(|n| n.try_normalize().unwrap_or(Vec3::Y))
        .collect()
}

/// How a material's surface scatters light.
#[derive(Clone, Debug, PartialEq)]
pub enum SurfaceModel {
    /// Lambertian with albedo = base colour (glTF material with `extras.bsdf == "diffuse"`,
    /// or OBJ materials without a specular term).
    Lambert,
    /// glTF metallic-roughness (GGX specular over a Lambertian base).
    MetallicRoughness,
    /// A BSDF made from data (MERL table, NBRDF network, latent code), opened when the scene
    /// is prepared for rendering ([`crate::material`]).
    Bound(Binding),
    /// BSDFs made from data varied across the surface by textures: a mixture, a latent
    /// blend, a tint ([`Varying`]).
    Varying(Varying),
}

/// A surface material.
#[derive(Clone, Debug)]
pub struct Material {
    pub name: String,
    pub model: SurfaceModel,
    /// Linear base colour (albedo of the diffuse base, F0 tint of metals).
    pub base_color: Rgb,
    /// A base-colour texture (sRGB) multiplying `base_color`.
    pub base_color_texture: Option<TextureRef>,
    /// A metallic-roughness texture (linear): its blue channel multiplies `metallic`, its
    /// green channel `roughness` (glTF's packing).
    pub metallic_roughness_texture: Option<TextureRef>,
    /// glTF metallic factor in [0, 1].
    pub metallic: f32,
    /// glTF perceptual roughness in [0, 1] (GGX α = roughness²).
    pub roughness: f32,
    /// Emitted radiance in W/(m² sr) (emissiveFactor × emissive strength), emitted from
    /// the front side only.
    pub emission: Rgb,
    /// Whether the back side scatters light too (glTF `doubleSided`). A single-sided
    /// material is black seen from behind, as Mitsuba's BSDFs are.
    pub double_sided: bool,
    /// An emissive texture (sRGB) multiplying `emission`.
    pub emissive_texture: Option<TextureRef>,
    /// A tangent-space normal map (glTF `normalTexture`), read with the vertex tangents.
    pub normal_texture: Option<NormalMap>,
    /// How the base colour's alpha (the factor's times the texture's) covers the surface.
    pub alpha_mode: AlphaMode,
    /// The base colour factor's alpha (glTF `baseColorFactor[3]`), in [0, 1].
    pub base_alpha: f32,
    /// The dielectric's index of refraction (`KHR_materials_ior`; 1.5 by default).
    pub ior: f32,
    /// `KHR_materials_specular`'s specular factor (strength of the dielectric's specular
    /// reflection, in [0, 1]; 1 by default) and specular colour (linear, scales its F0).
    pub specular: f32,
    pub specular_color: Rgb,
    /// `KHR_materials_transmission`'s factor in [0, 1]: the fraction of the dielectric base
    /// that transmits (a glass BSDF, tinted by the base colour) instead of scattering
    /// diffusely; 0 by default (opaque).
    pub transmission: f32,
    /// A transmission texture (linear): its red channel multiplies `transmission`.
    pub transmission_texture: Option<TextureRef>,
    /// The volume its surfaces enclose (`KHR_materials_volume` with a thickness > 0); `None`:
    /// the surface is thin-walled (light passes through it without refraction).
    pub volume: Option<Volume>,
    /// A clear coat over the material (`KHR_materials_clearcoat`).
    pub clearcoat: Option<Clearcoat>,
    /// A sheen over the material's base, under any clear coat (`KHR_materials_sheen`).
    pub sheen: Option<SheenLayer>,
}

/// `KHR_materials_clearcoat`: a GGX dielectric coat (index 1.5) over the material.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Clearcoat {
    /// `clearcoatFactor` in [0, 1], times `texture`'s red channel (linear).
    pub factor: f32,
    pub texture: Option<TextureRef>,
    /// `clearcoatRoughnessFactor` (perceptual, α = r²) in [0, 1], times
    /// `roughness_texture`'s green channel (linear).
    pub roughness: f32,
    pub roughness_texture: Option<TextureRef>,
    /// `clearcoatNormalTexture`; without it the coat has the interpolated vertex normal
    /// (the base's normal map does not bend it).
    pub normal_texture: Option<NormalMap>,
}

impl Clearcoat {
    /// The coat's weight c at a point: its factor times its texture's red channel, as
    /// `lookup` reads the texture there.
    #[inline]
    pub fn weight(&self, lookup: impl Fn(&TextureRef) -> Rgb) -> f32 {
        self.texture.as_ref().map_or(self.factor, |t| self.factor * lookup(t).x)
    }
}

/// `KHR_materials_sheen`: a Charlie sheen over the material's base.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SheenLayer {
    /// `sheenColorFactor` (linear) times `color_texture` (sRGB).
    pub color: Rgb,
    pub color_texture: Option<TextureRef>,
    /// `sheenRoughnessFactor` (perceptual, α = r²) in [0, 1] times `roughness_texture`'s
    /// alpha channel.
    pub roughness: f32,
    pub roughness_texture: Option<TextureRef>,
}

/// A homogeneous absorbing volume inside a closed mesh (glTF `KHR_materials_volume`):
/// light travelling d metres through it keeps exp(−σa d) of its radiance (Beer–Lambert).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Volume {
    /// Absorption coefficient σa in 1/m per channel: −ln(attenuationColor) /
    /// attenuationDistance (zero for the default infinite distance).
    pub sigma_a: Rgb,
}

impl Volume {
    /// The volume whose light keeps `color` (linear, in (0, 1]) of its radiance after
    /// `distance` metres (> 0; infinite: no absorption), as `KHR_materials_volume` states
    /// it; `None` where a value is outside those ranges.
    pub fn from_attenuation(color: Rgb, distance: f32) -> Option<Volume> {
        let valid = color.min_element() > 0.0 && color.max_element() <= 1.0 && distance > 0.0;
        valid.then(|| Volume {
            sigma_a: if distance == f32::INFINITY { Rgb::ZERO } else { -Rgb::new(color.x.ln(), color.y.ln(), color.z.ln()) / distance },
        })
    }
}

/// A tangent-space normal map: texel (r, g, b) ↦ n = normalize((2r − 1) s, (2g − 1) s, 2b − 1)
/// in the frame (tangent, bitangent, normal), with s = `scale` (glTF `normalTexture`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NormalMap {
    pub texture: TextureRef,
    pub scale: f32,
}

/// How alpha covers a surface (glTF `alphaMode`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum AlphaMode {
    /// Fully opaque; alpha is ignored (OPAQUE, the default).
    #[default]
    Opaque,
    /// A cut-out: the surface exists where alpha ≥ `cutoff` and nowhere else (MASK,
    /// `alphaCutoff`, default 0.5), for camera, bounce and shadow rays alike.
    Mask { cutoff: f32 },
    /// Partial coverage (BLEND), rendered as stochastic coverage: a ray passes through with
    /// probability 1 − alpha, decided by a hash of the ray, so the image converges to the
    /// alpha blend.
    Blend,
}

impl Material {
    /// A grey Lambertian material, used where a file gives none.
    pub fn default_diffuse(name: &str) -> Self {
        Material {
            name: name.to_string(),
            model: SurfaceModel::Lambert,
            base_color: Rgb::splat(0.8),
            base_color_texture: None,
            metallic_roughness_texture: None,
            metallic: 0.0,
            roughness: 1.0,
            emission: Rgb::ZERO,
            double_sided: true,
            emissive_texture: None,
            normal_texture: None,
            alpha_mode: AlphaMode::Opaque,
            base_alpha: 1.0,
            ior: 1.5,
            specular: 1.0,
            specular_color: Rgb::ONE,
            transmission: 0.0,
            transmission_texture: None,
            volume: None,
            clearcoat: None,
            sheen: None,
        }
    }

    /// Whether the surface transmits light somewhere (a transmission factor > 0).
    pub fn transmits(&self) -> bool {
        self.transmission > 0.0
    }

    /// The dielectric's Fresnel reflectance at normal and grazing incidence, (f0, f90), as
    /// `KHR_materials_specular` defines them: f0 = min(((ior − 1)/(ior + 1))² · specular
    /// colour, 1) · specular, f90 = specular; (0.04, 1) for the defaults.
    pub fn dielectric_fresnel(&self) -> (Rgb, f32) {
        let r = ((self.ior - 1.0) / (self.ior + 1.0)).powi(2);
        ((r * self.specular_color).min(Rgb::ONE) * self.specular, self.specular)
    }

    /// Whether rays can pass through parts of the surface (a cut-out or partial coverage).
    pub fn has_alpha(&self) -> bool {
        match self.alpha_mode {
            AlphaMode::Opaque => false,
            AlphaMode::Mask { .. } | AlphaMode::Blend => true,
        }
    }

    /// Every texture the material reads.
    pub fn texture_refs(&self) -> impl Iterator<Item = &TextureRef> {
        [
            self.base_color_texture.as_ref(),
            self.metallic_roughness_texture.as_ref(),
            self.emissive_texture.as_ref(),
            self.normal_texture.as_ref().map(|n| &n.texture),
            self.transmission_texture.as_ref(),
            self.clearcoat.as_ref().and_then(|c| c.texture.as_ref()),
            self.clearcoat.as_ref().and_then(|c| c.roughness_texture.as_ref()),
            self.clearcoat.as_ref().and_then(|c| c.normal_texture.as_ref()).map(|n| &n.texture),
            self.sheen.as_ref().and_then(|s| s.color_texture.as_ref()),
            self.sheen.as_ref().and_then(|s| s.roughness_texture.as_ref()),
        ]
        .into_iter()
        .flatten()
        .chain(match &self.model {
            SurfaceModel::Varying(v) => v.texture_refs(),
            _ => Vec::new(),
        })
    }
}

/// A perspective camera.
#[derive(Clone, Debug)]
pub struct Camera {
    pub name: String,
    /// Camera-to-world transform (rigid); the camera looks down its local -z with +y up
    /// (glTF's convention).
    pub camera_to_world: Mat4,
    /// Vertical field of view in radians.
    pub yfov: f32,
    /// Width / height the file asks for, if any; the rendered resolution decides otherwise.
    pub aspect_ratio: Option<f32>,
}

impl Camera {
    /// Vertical field of view of [`Camera::look_at_bounds`], degrees.
    pub const FRAMING_YFOV_DEGREES: f32 = 40.0;

    /// A camera named `name` on the +z side of the box `min`..`max`, looking down -z at its
    /// centre, far enough that the box's bounding sphere fits both the vertical field of view
    /// ([`Camera::FRAMING_YFOV_DEGREES`]) and the horizontal one implied by `aspect_ratio`
    /// (width / height; 1 when `None`). Meant for files without cameras (OBJ).
    pub fn look_at_bounds(name: &str, min: Vec3, max: Vec3, aspect_ratio: Option<f32>) -> Camera {
        let yfov = Self::FRAMING_YFOV_DEGREES.to_radians();
        let aspect = aspect_ratio
            .filter(|a| a.is_finite() && *a > 0.0)
            .unwrap_or(1.0);
        let half_y = 0.5 * yfov;
        let half_x = (aspect * half_y.tan()).atan();
        let centre = 0.5 * (min + max);
        let radius = 0.5 * (max - min).length();
        let radius = if radius.is_finite() && radius > 0.0 {
            radius
        } else {
            1.0
        };
        let distance = radius / half_y.min(half_x).sin();
        let centre = if centre.is_finite() {
            centre
        } else {
            Vec3::ZERO
        };
        Camera {
            name: name.to_string(),
            camera_to_world: Mat4::from_translation(centre + Vec3::new(0.0, 0.0, distance)),
            yfov,
            aspect_ratio,
        }
    }
}

/// Luminous efficacy used to turn glTF's photometric light units into radiometric ones, lm/W:
/// the value `KHR_lights_punctual` and Blender's glTF exporter use (the peak of the photopic
/// curve), so 683 cd is 1 W/sr and 683 lx is 1 W/m².
pub const LUMENS_PER_WATT: f32 = 683.0;

/// A punctual light (KHR_lights_punctual), in radiometric units: W/sr for point and spot
/// lights, W/m² for directional lights (the same scale as emissive radiance). The glTF loader
/// converts the file's photometric units (cd, lx) with [`LUMENS_PER_WATT`].
#[derive(Clone, Debug, PartialEq)]
pub enum PunctualLight {
    Point {
        position: Vec3,
        /// Radiant intensity, W/sr.
        intensity: Rgb,
    },
    Spot {
        position: Vec3,
        /// Unit direction the spot points to.
        direction: Vec3,
        /// Radiant intensity on the axis, W/sr.
        intensity: Rgb,
        /// Cosine of the inner cone angle (full intensity inside).
        cos_inner: f32,
        /// Cosine of the outer cone angle (zero outside).
        cos_outer: f32,
    },
    Directional {
        /// Unit direction the light travels in.
        direction: Vec3,
        /// Irradiance on a surface facing the light, W/m².
        irradiance: Rgb,
    },
}

/// Where an environment's radiance comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum EnvironmentSource {
    /// Equirectangular image file (.exr or .hdr), path resolved relative to the scene file.
    Image(PathBuf),
    /// The same radiance from every direction, W/(m² sr).
    Constant(Rgb),
}

/// The distant environment surrounding a scene.
///
/// glTF scenes name it in the top-level scene's (or the asset's) `extras`:
/// `{"environment": {"image": "studio.exr", "strength": 1.0, "rotation_degrees": 0.0}}` or
/// `{"environment": {"color": [1.0, 1.0, 1.0]}}`.
#[derive(Clone, Debug, PartialEq)]
pub struct EnvironmentSpec {
    pub source: EnvironmentSource,
    /// Multiplier on the image's radiance.
    pub strength: f32,
    /// Rotation about the world +y axis, radians.
    pub rotation: f32,
}

/// The largest vertex coordinate magnitude a scene may have, in scene units: beyond it the
/// BVH builder's surface-area costs (products of extents, summed over millions of nodes)
/// would overflow f32 (a fuzzed file with coordinates near 10³⁵ broke `obvhs`'s build).
pub const MAX_COORDINATE: f32 = 1e12;

/// A mesh stored once, in its own object space, and placed by [`Instance`]s: triangles
/// `first_triangle..first_triangle + triangle_count` and vertices
/// `first_vertex..first_vertex + vertex_count` of the scene's [`Geometry`] (after all
/// world-space triangles and their vertices).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Mesh {
    pub first_triangle: u32,
    pub triangle_count: u32,
    pub first_vertex: u32,
    pub vertex_count: u32,
}

/// A placement of a [`Mesh`] in the world.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Instance {
    /// Index into [`SceneDescription::meshes`].
    pub mesh: u32,
    /// Object-to-world transform (affine, invertible).
    pub object_to_world: Mat4,
}

/// What a scene file describes: triangles in world space, and meshes placed by instances.
#[derive(Clone, Debug, Default)]
pub struct SceneDescription {
    /// The file it was read from (for error messages).
    pub source: PathBuf,
    pub geometry: Geometry,
    /// Meshes stored once (their triangles at the end of `geometry`), placed by `instances`.
    pub meshes: Vec<Mesh>,
    pub instances: Vec<Instance>,
    pub materials: Vec<Material>,
    pub textures: Vec<Texture>,
    pub cameras: Vec<Camera>,
    pub lights: Vec<PunctualLight>,
    pub environment: Option<EnvironmentSpec>,
    /// What the loader could not honour but rendered around (e.g. an unsupported glTF
    /// extension the file uses without requiring it), one line each, to show the user once.
    pub warnings: Vec<String>,
}

impl SceneDescription {
    /// Loads a scene file, choosing the loader by extension (case-insensitive): `.gltf` and
    /// `.glb` with [`gltf::load`], `.obj` with [`obj::load`].
    pub fn load(path: &Path) -> Result<SceneDescription> {
        let extension = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match extension.as_deref() {
            Some("gltf") | Some("glb") => gltf::load(path),
            Some("obj") => obj::load(path),
            _ => Err(Error::invalid_file(
                path,
                "unknown scene format (expected a .gltf, .glb or .obj file)",
            )),
        }
    }

    /// Number of triangles stored in world space (the first ones of the geometry; the rest
    /// belong to instanced meshes).
    pub fn world_triangle_count(&self) -> usize {
        self.meshes.first().map_or(self.geometry.triangle_count(), |m| m.first_triangle as usize)
    }

    /// Number of vertices stored in world space (the first ones; the rest belong to
    /// instanced meshes).
    pub fn world_vertex_count(&self) -> usize {
        self.meshes.first().map_or(self.geometry.positions.len(), |m| m.first_vertex as usize)
    }

    /// Number of triangles in the world: world-space ones plus each instance's mesh.
    pub fn triangle_instance_count(&self) -> u64 {
        let instanced: u64 = self.instances.iter().map(|i| u64::from(self.meshes[i.mesh as usize].triangle_count)).sum();
        self.world_triangle_count() as u64 + instanced
    }

    /// Object-space bounds `(min, max)` of each mesh's vertices (empty meshes: an empty box,
    /// min = +∞, max = −∞), computed once for all instances of a mesh.
    pub fn mesh_bounds(&self) -> Vec<(Vec3, Vec3)> {
        self.meshes
            .iter()
            .map(|m| {
                let vertices = &self.geometry.positions[m.first_vertex as usize..(m.first_vertex + m.vertex_count) as usize];
                vertices.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| (lo.min(p), hi.max(p)))
            })
            .collect()
    }

    /// World-space bounds of instance `instance` given [`SceneDescription::mesh_bounds`]: the
    /// transformed box of its mesh's object-space bounds.
    pub fn instance_bounds(mesh_bounds: &[(Vec3, Vec3)], instance: &Instance) -> (Vec3, Vec3) {
        let (lo, hi) = mesh_bounds[instance.mesh as usize];
        (0..8u32)
            .map(|c| Vec3::new([lo.x, hi.x][(c & 1) as usize], [lo.y, hi.y][(c >> 1 & 1) as usize], [lo.z, hi.z][(c >> 2) as usize]))
            .map(|corner| instance.object_to_world.transform_point3(corner))
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| (lo.min(p), hi.max(p)))
    }

    /// Bounds of everything in the world: world-space vertices and instances; `None` when
    /// there is nothing.
    pub fn world_bounds(&self) -> Option<(Vec3, Vec3)> {
        let world_vertices = self.world_vertex_count();
        let mut bounds = self.geometry.positions[..world_vertices]
            .iter()
            .fold(None, |b: Option<(Vec3, Vec3)>, &p| Some(b.map_or((p, p), |(lo, hi)| (lo.min(p), hi.max(p)))));
        let mesh_bounds = self.mesh_bounds();
        for instance in &self.instances {
            let (lo, hi) = Self::instance_bounds(&mesh_bounds, instance);
            if lo.cmple(hi).all() {
                bounds = Some(bounds.map_or((lo, hi), |(a, b)| (a.min(lo), b.max(hi))));
            }
        }
        bounds
    }

    /// The same scene with every instance's mesh copied into world space (memory grows with
    /// the instances): for comparing instancing against its absence.
    pub fn flatten_instances(mut self) -> Result<SceneDescription> {
        let world_triangles = self.world_triangle_count();
        let world_vertices = self.world_vertex_count();
        let g = &self.geometry;
        let part = |m: &Mesh| {
            let vertices = m.first_vertex as usize..(m.first_vertex + m.vertex_count) as usize;
            let triangles = m.first_triangle as usize..(m.first_triangle + m.triangle_count) as usize;
            Geometry {
                positions: g.positions[vertices.clone()].to_vec(),
                normals: g.normals[vertices.clone()].to_vec(),
                uvs: g.uvs[vertices.clone()].to_vec(),
                uvs1: if g.uvs1.is_empty() { Vec::new() } else { g.uvs1[vertices.clone()].to_vec() },
                tangents: if g.tangents.is_empty() { Vec::new() } else { g.tangents[vertices].to_vec() },
                triangles: g.triangles[triangles.clone()].iter().map(|t| t.map(|v| v - m.first_vertex)).collect(),
                material_ids: g.material_ids[triangles].to_vec(),
            }
        };
        let parts: Vec<Geometry> = self.meshes.iter().map(part).collect();
        let mut world = Geometry {
            positions: g.positions[..world_vertices].to_vec(),
            normals: g.normals[..world_vertices].to_vec(),
            uvs: g.uvs[..world_vertices].to_vec(),
            uvs1: if g.uvs1.is_empty() { Vec::new() } else { g.uvs1[..world_vertices].to_vec() },
            tangents: if g.tangents.is_empty() { Vec::new() } else { g.tangents[..world_vertices].to_vec() },
            triangles: g.triangles[..world_triangles].to_vec(),
            material_ids: g.material_ids[..world_triangles].to_vec(),
        };
        for instance in &self.instances {
            let mut placed = parts[instance.mesh as usize].clone();
            placed.transform(instance.object_to_world);
            world.append(&placed, &self.source)?;
        }
        self.geometry = world;
        self.meshes.clear();
        self.instances.clear();
        Ok(self)
    }

    /// The camera named `name`, or the file's first camera when `name` is `None`.
    ///
    /// Fails with [`Error::UnknownName`] (listing the cameras there are) when no camera has
    /// that name, and with [`Error::InvalidFile`] when `name` is `None` and the file has no
    /// camera (see [`SceneDescription::camera_or_default`]).
    pub fn camera(&self, name: Option<&str>) -> Result<&Camera> {
        match name {
            Some(name) => {
                self.cameras
                    .iter()
                    .find(|c| c.name == name)
                    .ok_or_else(|| Error::UnknownName {
                        what: "camera",
                        name: name.to_string(),
                        available: self.cameras.iter().map(|c| c.name.clone()).collect(),
                    })
            }
            None => self
                .cameras
                .first()
                .ok_or_else(|| Error::invalid_file(&self.source, "contains no perspective camera")),
        }
    }

    /// Like [`SceneDescription::camera`], but when `name` is `None` and the file has no
    /// camera, a camera named "default" framing the geometry's bounds
    /// ([`Camera::look_at_bounds`]).
    pub fn camera_or_default(
        &self,
        name: Option<&str>,
        aspect_ratio: Option<f32>,
    ) -> Result<Camera> {
        if name.is_none() && self.cameras.is_empty() {
            let (min, max) = self.world_bounds().unwrap_or((Vec3::ZERO, Vec3::ZERO));
            return Ok(Camera::look_at_bounds("default", min, max, aspect_ratio));
        }
        self.camera(name).cloned()
    }

    /// Checks what the renderer relies on: at least one triangle, finite vertex positions,
    /// one normal and one texture coordinate per vertex, vertex indices in range, one
    /// material id per triangle naming an existing material, texture indices in range and
    /// cameras with a field of view in (0, π). Errors name [`SceneDescription::source`].
    /// Degenerate (zero-area) triangles are allowed.
    pub fn validate(&self) -> Result<()> {
        let fail = |reason: String| Err(Error::invalid_file(&self.source, reason));
        let g = &self.geometry;
        if g.triangles.is_empty() {
            return fail("contains no triangles".into());
        }
        if let Some(i) = g.positions.iter().position(|p| !p.is_finite()) {
            return fail(format!("non-finite vertex position (vertex {i})"));
        }
        if let Some(i) = g.positions.iter().position(|p| p.abs().max_element() > MAX_COORDINATE) {
            return fail(format!(
                "vertex {i} lies {:e} scene units from the origin (at most {MAX_COORDINATE:e} are supported)",
                g.positions[i].abs().max_element()
            ));
        }
        let n = g.positions.len();
        if g.normals.len() != n || g.uvs.len() != n {
            return fail(format!(
                "{} positions but {} normals and {} texture coordinates",
                n,
                g.normals.len(),
                g.uvs.len()
            ));
        }
        if let Some(i) = g.normals.iter().position(|v| !v.is_finite()) {
            return fail(format!("non-finite vertex normal (vertex {i})"));
        }
        if !g.uvs1.is_empty() && g.uvs1.len() != n {
            return fail(format!("{n} positions but {} second texture coordinates", g.uvs1.len()));
        }
        if !g.tangents.is_empty() && g.tangents.len() != n {
            return fail(format!("{n} positions but {} tangents", g.tangents.len()));
        }
        if let Some(i) = g.tangents.iter().position(|v| !v.is_finite()) {
            return fail(format!("non-finite vertex tangent (vertex {i})"));
        }
        if let Some(i) = g.uvs.iter().chain(&g.uvs1).position(|v| !v.is_finite()) {
            return fail(format!("non-finite texture coordinate (vertex {})", i % n.max(1)));
        }
        if let Some(t) = g
            .triangles
            .iter()
            .position(|t| t.iter().any(|&v| v as usize >= n))
        {
            return fail(format!(
                "triangle {t} has a vertex index out of range ({n} vertices)"
            ));
        }
        if g.material_ids.len() != g.triangles.len() {
            return fail(format!(
                "{} triangles but {} material ids",
                g.triangles.len(),
                g.material_ids.len()
            ));
        }
        if let Some(t) = g
            .material_ids
            .iter()
            .position(|&m| m as usize >= self.materials.len())
        {
            return fail(format!(
                "triangle {t} uses material {} of {}",
                g.material_ids[t],
                self.materials.len()
            ));
        }
        for m in &self.materials {
            if m.texture_refs().any(|t| t.texture >= self.textures.len())
            {
                return fail(format!("material '{}' uses a missing texture", m.name));
            }
        }
        let (world_triangles, world_vertices) = (self.world_triangle_count(), self.world_vertex_count());
        let (mut next_triangle, mut next_vertex) = (world_triangles, world_vertices);
        for (k, m) in self.meshes.iter().enumerate() {
            let contiguous = m.first_triangle as usize == next_triangle && m.first_vertex as usize == next_vertex;
            next_triangle += m.triangle_count as usize;
            next_vertex += m.vertex_count as usize;
            if !contiguous || next_triangle > g.triangles.len() || next_vertex > n {
                return fail(format!("mesh {k} does not follow the world-space triangles and the meshes before it"));
            }
            let vertices = m.first_vertex..m.first_vertex + m.vertex_count;
            let triangles = m.first_triangle as usize..next_triangle;
            if g.triangles[triangles].iter().flatten().any(|v| !vertices.contains(v)) {
                return fail(format!("mesh {k} has a triangle using a vertex outside it"));
            }
        }
        if next_triangle != g.triangles.len() || next_vertex != n {
            return fail("triangles or vertices after the last mesh".into());
        }
        if g.triangles[..world_triangles].iter().flatten().any(|&v| v as usize >= world_vertices) {
            return fail("a world-space triangle uses a vertex of an instanced mesh".into());
        }
        let mesh_bounds = self.mesh_bounds();
        for (k, instance) in self.instances.iter().enumerate() {
            let m = instance.object_to_world;
            if instance.mesh as usize >= self.meshes.len() {
                return fail(format!("instance {k} places mesh {} of {}", instance.mesh, self.meshes.len()));
            }
            if !m.is_finite() || m.determinant().abs().partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) || !m.inverse().is_finite() || m.row(3) != glam::Vec4::W {
                return fail(format!("instance {k} has a transform that is not affine and invertible"));
            }
            let (lo, hi) = Self::instance_bounds(&mesh_bounds, instance);
            if lo.abs().max(hi.abs()).max_element() > MAX_COORDINATE && lo.cmple(hi).all() {
                return fail(format!("instance {k} reaches {:e} scene units from the origin (at most {MAX_COORDINATE:e} are supported)", lo.abs().max(hi.abs()).max_element()));
            }
        }
        for c in &self.cameras {
            let fov_ok = c.yfov > 0.0 && c.yfov < std::f32::consts::PI;
            if !fov_ok || !c.camera_to_world.is_finite() {
                return fail(format!(
                    "camera '{}' has an invalid field of view or transform",
                    c.name
                ));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One unit right triangle in the xy plane, facing +z, with a grey material.
    fn triangle_scene() -> SceneDescription {
        let positions = vec![Vec3::ZERO, Vec3::X, Vec3::Y];
        SceneDescription {
            source: PathBuf::from("mem.gltf"),
            geometry: Geometry {
                normals: vec![Vec3::Z; 3],
                uvs: vec![Vec2::ZERO; 3],
                uvs1: Vec::new(),
                tangents: Vec::new(),
                triangles: vec![[0, 1, 2]],
                material_ids: vec![0],
                positions,
            },
            materials: vec![Material::default_diffuse("grey")],
            ..SceneDescription::default()
        }
    }

    #[test]
    fn smooth_normals_weigh_by_area_and_tolerate_degenerate_triangles() {
        let positions = [
            Vec3::ZERO,
            Vec3::Y,
            Vec3::new(-3.0, 0.0, 0.0),
            Vec3::NEG_Z,
            Vec3::splat(7.0),
        ];
        let normals = smooth_vertex_normals(&positions, &[[0, 1, 2], [0, 3, 1], [4, 4, 4]]);
        assert!(normals[0].abs_diff_eq(Vec3::new(1.0, 0.0, 3.0).normalize(), 1e-6));
        assert_eq!(normals[2], Vec3::Z);
        assert_eq!(normals[3], Vec3::X);
        assert_eq!(
            normals[4],
            Vec3::Y,
            "only a degenerate triangle: fallback +y"
        );
    }

    #[test]
    fn append_offsets_indices() {
        let mut g = triangle_scene().geometry;
        let other = g.clone();
        g.append(&other, Path::new("x.obj")).expect("append");
        assert_eq!(g.triangles, vec![[0, 1, 2], [3, 4, 5]]);
        assert!(g.tangents.is_empty(), "no tangents stored when neither part has any");
        let mut bumpy = other.clone();
        bumpy.tangents = vec![Vec4::X; 3];
        g.append(&bumpy, Path::new("x.obj")).expect("append");
        g.append(&other, Path::new("x.obj")).expect("append");
        let mut expected = vec![Vec4::ZERO; 6];
        expected.extend([Vec4::X; 3]);
        expected.extend([Vec4::ZERO; 3]);
        assert_eq!(g.tangents, expected, "parts without tangents are padded with zeros");
        assert_eq!(g.bounds(), Some((Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0))));
        assert_eq!(Geometry::default().bounds(), None);
    }

    #[test]
    fn validate_rejects_what_the_renderer_cannot_use() {
        assert!(triangle_scene().validate().is_ok());
        type Breakage = (fn(&mut SceneDescription), &'static str);
        let cases: [Breakage; 6] = [
            (
                |s| s.geometry = Geometry::default(),
                "mem.gltf: contains no triangles",
            ),
            (
                |s| s.geometry.positions[1].x = f32::NAN,
                "mem.gltf: non-finite vertex position (vertex 1)",
            ),
            (
                |s| s.geometry.triangles[0][2] = 3,
                "vertex index out of range",
            ),
            (
                |s| s.geometry.positions[2].y = -1e35,
                "mem.gltf: vertex 2 lies 1e35 scene units from the origin (at most 1e12 are supported)",
            ),
            (|s| s.geometry.material_ids[0] = 1, "uses material 1 of 1"),
            (
                |s| {
                    s.geometry.normals.pop();
                },
                "3 positions but 2 normals",
            ),
        ];
        for (break_it, problem) in cases {
            let mut scene = triangle_scene();
            break_it(&mut scene);
            let message = scene.validate().expect_err(problem).to_string();
            assert!(message.contains(problem), "{message}");
        }
    }

    #[test]
    fn camera_lookup_and_default_framing() {
        let mut scene = triangle_scene();
        let message = scene.camera(None).expect_err("no camera").to_string();
        assert_eq!(message, "mem.gltf: contains no perspective camera");
        let framed = scene
            .camera_or_default(None, Some(2.0))
            .expect("default camera");
        assert_eq!(framed.name, "default");
        let eye = framed.camera_to_world.transform_point3(Vec3::ZERO);
        let centre = Vec3::new(0.5, 0.5, 0.0);
        assert!((eye - centre).normalize().abs_diff_eq(Vec3::Z, 1e-6));
        let radius = 0.5 * 2f32.sqrt();
        let half = 0.5 * Camera::FRAMING_YFOV_DEGREES.to_radians();
        assert!(((eye - centre).length() - radius / half.sin()).abs() < 1e-5);

        scene.cameras.push(framed.clone());
        scene.cameras.push(Camera {
            name: "top".into(),
            ..framed
        });
        assert_eq!(scene.camera(Some("top")).expect("top").name, "top");
        assert_eq!(scene.camera(None).expect("first").name, "default");
        let message = scene.camera(Some("side")).expect_err("unknown").to_string();
        assert_eq!(message, "camera 'side' not found (available: default, top)");
    }

    #[test]
    fn load_dispatches_on_the_extension() {
        let message = SceneDescription::load(Path::new("scene.fbx"))
            .expect_err("unknown format")
            .to_string();
        assert_eq!(
            message,
            "scene.fbx: unknown scene format (expected a .gltf, .glb or .obj file)"
        );
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("TRI.OBJ");
        std::fs::write(&path, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").expect("write");
        let scene = SceneDescription::load(&path).expect("load OBJ by upper-case extension");
        assert_eq!(scene.geometry.triangle_count(), 1);
    }

    #[test]
    fn srgb_textures_are_decoded_to_linear() {
        let mut png = Vec::new();
        image::RgbImage::from_raw(1, 1, vec![0, 188, 255])
            .expect("image")
            .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .expect("encode");
        let t = Texture::from_encoded_srgb(&png, Path::new("a.gltf"), "image 0").expect("decode");
        assert!(
            t.texel(0).abs_diff_eq(Rgb::new(0.0, 0.502_886, 1.0), 1e-4),
            "{}",
            t.texel(0)
        );
        assert_eq!(t.lookup(Vec2::new(0.3, 0.9)), t.texel(0));
        let message = Texture::from_encoded_srgb(b"not an image", Path::new("a.gltf"), "image 0")
            .expect_err("garbage")
            .to_string();
        assert!(
            message.starts_with("a.gltf: cannot decode image 0"),
            "{message}"
        );
    }
}
