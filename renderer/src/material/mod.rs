//! Material → BSDF: the one place that decides which BSDF a material's surface gets.
//!
//! A [`Material`] says how it scatters with a [`SurfaceModel`](crate::scene::SurfaceModel):
//! Lambert and glTF metallic-roughness are built per shading point from the material's
//! (textured) parameters; a [`Binding`] names a BSDF made from data (a MERL table, an NBRDF
//! network, a latent code), opened once into a [`SharedBsdf`] that every shading point of
//! the materials bound to it shares. Which of these a material gets — the command line's
//! `--bind`, the scene file's `extras`, a latent code of the same name, or its own
//! parameters — is decided by the precedence in [`binding`]. [`SceneMaterials`] holds a
//! scene's materials prepared this way: it opens only what some triangle uses, each distinct
//! binding once. [`MaterialBsdf`] is one such BSDF on its own, for other renderers (the
//! plugins).

pub mod binding;
pub mod standalone;

pub use crate::scene::{Binding, BINDING_FORMS};
pub use binding::bind_scene;
pub use standalone::MaterialBsdf;

use binding::Surface;

use crate::bsdf::neural::NeuralBsdf;
use crate::bsdf::merl::MerlBsdf;
use crate::bsdf::nbrdf::NbrdfBsdf;
use crate::bsdf::layered::{coat_transmittance, Base, Coat};
use crate::bsdf::sheen::Sheen;
use crate::bsdf::mixture::Part;
use crate::bsdf::{Bsdf, Dielectric, Lambert, Layered, MetallicRoughness, Mixture, Transmission};
use crate::neural::latent_library::LatentLibrary;
use crate::scene::{AlphaMode, Material, NormalMap, Texture, TextureRef, Varying, VaryingForm};
use crate::{Error, Result, Rgb};
use glam::Vec2;
use std::collections::HashMap;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

/// A BSDF made from data, opened once and shared by every shading point of the materials
/// bound to it.
///
/// The NBRDF variant holds its weights inline (≈ 3.5 KB) so evaluation needs no pointer
/// chase; scenes hold a handful of these, by reference.
#[derive(Debug)]
#[allow(clippy::large_enum_variant)]
pub enum SharedBsdf {
    /// A MERL-layout table.
    Merl(MerlBsdf),
    /// An NBRDF network.
    Nbrdf(NbrdfBsdf),
    /// A decoded FreNBRDF/HyperBRDF latent code.
    Neural(NeuralBsdf),
}

impl SharedBsdf {
    /// Opens the BSDF a binding names; a latent code is decoded from `latents` (an unknown
    /// name lists the available ones; an empty library is an error saying a latent file is
    /// needed). Errors name the offending file or name.
    pub fn open(binding: &Binding, latents: &LatentLibrary) -> Result<Self> {
        Ok(match binding {
            Binding::Merl(path) => SharedBsdf::Merl(MerlBsdf::load(resolve_merl_path(path))?),
            Binding::Nbrdf(path) => SharedBsdf::Nbrdf(NbrdfBsdf::load(resolve_nbrdf_prefix(path)?)?),
            Binding::Neural(name) if latents.is_empty() => {
                return Err(Error::InvalidArgument {
                    flag: format!("BRDF binding '{binding}'"),
                    reason: format!("latent code '{name}' needs a latent file (render --material FILE)"),
                })
            }
            Binding::Neural(name) => SharedBsdf::Neural(latents.decode(name)?),
        })
    }

    /// The BSDF as a part of a [`Mixture`].
    #[inline]
    pub fn as_part(&self) -> Part<'_> {
        match self {
            SharedBsdf::Merl(b) => Part::Merl(b),
            SharedBsdf::Nbrdf(b) => Part::Nbrdf(b),
            SharedBsdf::Neural(b) => Part::Neural(b),
        }
    }

    /// Bytes it holds (tables, weights, sampling tables; not a latent file's reference
    /// table, which its codes share).
    pub fn heap_bytes(&self) -> usize {
        match self {
            SharedBsdf::Merl(b) => b.heap_bytes(),
            SharedBsdf::Nbrdf(b) => b.heap_bytes(),
            SharedBsdf::Neural(b) => b.heap_bytes(),
        }
    }

    /// The BSDF for shading.
    #[inline]
    pub fn as_bsdf(&self) -> Bsdf<'_> {
        match self {
            SharedBsdf::Merl(b) => Bsdf::Merl(b),
            SharedBsdf::Nbrdf(b) => Bsdf::Nbrdf(b),
            SharedBsdf::Neural(b) => Bsdf::Neural(b),
        }
    }
}

/// `PATH`, or `PATH.binary` when only that exists.
fn resolve_merl_path(path: &Path) -> PathBuf {
    if path.exists() {
        return path.to_path_buf();
    }
    let mut with_extension = path.as_os_str().to_owned();
    with_extension.push(".binary");
    let with_extension = PathBuf::from(with_extension);
    if with_extension.is_file() {
        with_extension
    } else {
        path.to_path_buf()
    }
}

/// The network prefix an `nbrdf:` path names (see [`binding`]).
fn resolve_nbrdf_prefix(path: &Path) -> Result<PathBuf> {
    let text = path.to_string_lossy();
    for name in crate::neural::nbrdf::TENSOR_NAMES {
        if let Some(prefix) = text.strip_suffix(&format!("_{name}.npy")) {
            return Ok(PathBuf::from(prefix));
        }
    }
    if crate::neural::nbrdf::tensor_paths(path)[0].is_file() {
        return Ok(path.to_path_buf());
    }
    if path.is_dir() {
        let names = crate::neural::nbrdf::list_networks(path)?;
        if let [name] = &names[..] {
            return Ok(path.join(name));
        }
        return Err(Error::invalid_file(path, format!("a directory of {} NBRDF networks: name one as DIR/MATERIAL", names.len())));
    }
    if let Some(dir) = path.parent().filter(|d| d.is_dir()) {
        let available = crate::neural::nbrdf::list_networks(dir)?;
        if !available.is_empty() {
            return Err(Error::UnknownName {
                what: "NBRDF network",
                name: path.display().to_string(),
                available,
            });
        }
    }
    // Loading reports the missing `_fc1.npy` with its path.
    Ok(path.to_path_buf())
}

/// How a prepared material scatters.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    Lambert,
    MetallicRoughness,
    /// Metallic-roughness with transmission ([`Transmission`]).
    Transmission,
    /// Index into [`SceneMaterials::shared`].
    Shared(usize),
    /// Index into [`SceneMaterials::varying`].
    Varying(usize),
}

/// Networks decoded along a latent interpolation z(t), t = k / (n − 1) for k = 0 … n − 1:
/// a `blend` material's BSDF at t is the mixture of the two entries around it, weighted by
/// where t falls between them (which the integrator estimates by drawing one of the two per
/// vertex, [`Mixture::drawn_per_vertex_of`]). 32 entries: at the midpoints between entries the mixture of the
/// neighbours is within the error target of the exact decode (docs/neural-textures.md).
pub const PALETTE_SIZE: usize = 32;

/// A varying material prepared: its parts as slots of [`SceneMaterials::shared`] and its
/// textures.
#[derive(Clone, Debug)]
struct PreparedVarying {
    parts: PreparedParts,
    tint: Option<TextureRef>,
}

#[derive(Clone, Debug)]
enum PreparedParts {
    One(usize),
    Mix { slots: Vec<usize>, weights: TextureRef },
    /// The palette's entries are the slots `palette`, in order of t.
    Blend { palette: Range<usize>, t: TextureRef, channel: usize },
}

/// What preparing a scene's materials decoded and opened ([`SceneMaterials::stats`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct MaterialStats {
    /// BSDFs made from data opened (tables, networks, decoded codes; palette entries
    /// included).
    pub opened: usize,
    /// Latent codes decoded (palette entries included).
    pub decoded_codes: usize,
    /// Palettes decoded for latent blends ([`PALETTE_SIZE`] codes each).
    pub palettes: usize,
    /// Bytes the opened BSDFs hold ([`SharedBsdf::heap_bytes`]).
    pub bytes: usize,
    /// Bytes of the palettes alone.
    pub palette_bytes: usize,
    /// Bytes the scene's decoded textures hold ([`Texture::heap_bytes`]: 8-bit images as
    /// their RGBA bytes, others as linear `f32`).
    pub texture_bytes: usize,
    /// Wall time spent opening and decoding, seconds.
    pub seconds: f64,
}

/// Opens a scene's bindings, each distinct one once, and decodes the palettes of its latent
/// blends, each pair of ends once.
struct Opener<'l> {
    latents: &'l LatentLibrary,
    shared: Vec<SharedBsdf>,
    opened: HashMap<Binding, usize>,
    palettes: HashMap<[String; 2], Range<usize>>,
    stats: MaterialStats,
}

impl Opener<'_> {
    /// The slot of `binding`'s BSDF, opened now if it was not.
    fn open(&mut self, binding: &Binding) -> Result<usize> {
        if let Some(&slot) = self.opened.get(binding) {
            return Ok(slot);
        }
        self.shared.push(SharedBsdf::open(binding, self.latents)?);
        self.stats.decoded_codes += matches!(binding, Binding::Neural(_)) as usize;
        self.opened.insert(binding.clone(), self.shared.len() - 1);
        Ok(self.shared.len() - 1)
    }

    fn varying(&mut self, v: &Varying) -> Result<PreparedVarying> {
        let parts = match &v.form {
            VaryingForm::One(binding) => PreparedParts::One(self.open(binding)?),
            VaryingForm::Mix { parts, weights } => PreparedParts::Mix {
                slots: parts.iter().map(|b| self.open(b)).collect::<Result<_>>()?,
                weights: *weights,
            },
            VaryingForm::Blend { ends, t, channel } => PreparedParts::Blend { palette: self.palette(ends)?, t: *t, channel: *channel },
        };
        Ok(PreparedVarying { parts, tint: v.tint })
    }

    /// The slots of the palette from `ends[0]` to `ends[1]` ([`PALETTE_SIZE`] codes along
    /// the editing sweep [`LatentLibrary::sweep`](crate::neural::latent_library::LatentLibrary::sweep),
    /// as `render --sweep` decodes them), decoded now if it was not.
    fn palette(&mut self, ends: &[String; 2]) -> Result<Range<usize>> {
        if let Some(range) = self.palettes.get(ends) {
            return Ok(range.clone());
        }
        if self.latents.is_empty() {
            return Err(Error::InvalidArgument {
                flag: format!("blend {} → {}", ends[0], ends[1]),
                reason: "latent codes need a latent file (render --material FILE)".to_string(),
            });
        }
        let (a, b) = (self.latents.latent(&ends[0])?, self.latents.latent(&ends[1])?);
        let sweep = self.latents.sweep(&a, &b)?;
        let start = self.shared.len();
        for k in 0..PALETTE_SIZE {
            let t = k as f32 / (PALETTE_SIZE - 1) as f32;
            let label = format!("{}>{}@{t:.3}", ends[0], ends[1]);
            let bsdf = self.latents.decode_code(&sweep.code(t)?, &label)?;
            self.stats.palette_bytes += bsdf.heap_bytes();
            self.shared.push(SharedBsdf::Neural(bsdf));
        }
        self.stats.decoded_codes += PALETTE_SIZE;
        self.stats.palettes += 1;
        self.palettes.insert(ends.clone(), start..self.shared.len());
        Ok(start..self.shared.len())
    }
}

/// How the lane kernels begin a material's vertices ([`SceneMaterials::lane_bsdf`]).
#[derive(Clone, Copy, Debug)]
enum LaneBegin {
    /// With this BSDF, the same at every point seen from the front.
    Uniform(Bsdf<'static>),
    /// With the BSDF its textures give at the point (Lambertian or metallic-roughness).
    Textured,
}

/// A scene's materials prepared for shading (see the module documentation).
pub struct SceneMaterials {
    materials: Vec<Material>,
    /// Shared with the light set (emissive textures).
    textures: Arc<[Texture]>,
    kinds: Vec<Kind>,
    /// Per material, how the lane kernels begin its vertices ([`SceneMaterials::lane_bsdf`])
    /// and whether it is double-sided; `None` where they cannot.
    lanes: Vec<Option<(LaneBegin, bool)>>,
    /// Per glass material that begins in lanes, its [`SceneMaterials::glass_back`].
    glass_backs: Vec<Option<Dielectric>>,
    shared: Vec<SharedBsdf>,
    varying: Vec<PreparedVarying>,
    stats: MaterialStats,
    /// Materials that bind a latent code while no latent file was given: (material, latent
    /// name); they render with their glTF parameters.
    unbound_neural: Vec<(String, String)>,
}

/// The BSDF of transmitting material `m` at a point seen from its front (`front_face`) or
/// back, with base colour `base`, metallic factor and perceptual roughness
/// `(metallic, roughness)` and transmission factor `transmission` there: glass (its index
/// across the surface from the side the path arrives on; thin-walled without a volume, the
/// same from either side) mixed with an opaque part.
#[inline]
fn transmission_bsdf(m: &Material, front_face: bool, base: Rgb, (metallic, roughness): (f32, f32), transmission: f32) -> Bsdf<'static> {
    let ior = m.ior.max(1.0);
    let eta = if front_face || m.volume.is_none() { ior } else { 1.0 / ior };
    let glass = Dielectric::new(eta, roughness).with_tint(base);
    let glass = if m.volume.is_none() { glass.thin() } else { glass };
    Bsdf::Transmission(Transmission::new(base, metallic, roughness, transmission, m.dielectric_fresnel(), glass))
}

impl SceneMaterials {
    /// Opens the bindings of the materials marked `used` (each distinct binding once, latent
    /// codes from `latents`). Without latent files a material bound to a latent code falls
    /// back to its glTF metallic-roughness parameters ([`binding`]'s rule 4,
    /// [`SceneMaterials::unbound_neural`]); unused bound materials get nothing opened.
    pub fn prepare(materials: Vec<Material>, textures: Vec<Texture>, used: &[bool], latents: &LatentLibrary) -> Result<Self> {
        let started = Instant::now();
        let mut opener = Opener { latents, shared: Vec::new(), opened: HashMap::new(), palettes: HashMap::new(), stats: MaterialStats::default() };
        let mut varying = Vec::new();
        let mut unbound_neural = Vec::new();
        let mut kinds = Vec::with_capacity(materials.len());
        for (material, &is_used) in materials.iter().zip(used) {
            kinds.push(match binding::surface(&material.model, latents) {
                Surface::Lambert => Kind::Lambert,
                Surface::MetallicRoughness if material.transmits() => Kind::Transmission,
                Surface::MetallicRoughness => Kind::MetallicRoughness,
                Surface::Bound(_) | Surface::Varying(_) | Surface::LatentWithoutFile(_) if !is_used => Kind::Lambert,
                Surface::LatentWithoutFile(name) => {
                    unbound_neural.push((material.name.clone(), name.to_string()));
                    Kind::MetallicRoughness
                }
                Surface::Bound(binding) => Kind::Shared(opener.open(binding)?),
                Surface::Varying(v) => {
                    let prepared = opener.varying(v).map_err(|e| Error::InvalidArgument { flag: format!("material '{}'", material.name), reason: e.to_string() })?;
                    varying.push(prepared);
                    Kind::Varying(varying.len() - 1)
                }
            });
        }
        let Opener { shared, mut stats, .. } = opener;
        stats.opened = shared.len();
        stats.bytes = shared.iter().map(SharedBsdf::heap_bytes).sum();
        stats.texture_bytes = textures.iter().map(Texture::heap_bytes).sum();
        stats.seconds = started.elapsed().as_secs_f64();
        let lanes = materials
            .iter()
            .zip(&kinds)
            .map(|(m, &kind)| {
                // No layers over its base (emission, which only a coat darkens, is added when
                // the vertex is pushed: `SceneMaterials::emits`).
                let bare = m.clearcoat.is_none() && m.sheen.is_none();
                let uniform = m.base_color_texture.is_none()
                    && (kind == Kind::Lambert || m.metallic_roughness_texture.is_none())
                    && m.transmission_texture.is_none()
                    && m.normal_texture.is_none();
                let begin = match kind {
                    _ if !bare => return None,
                    Kind::Lambert | Kind::MetallicRoughness if !uniform => LaneBegin::Textured,
                    Kind::Lambert => LaneBegin::Uniform(Bsdf::Lambert(Lambert { albedo: m.base_color })),
                    Kind::MetallicRoughness => {
                        let (f0, f90) = m.dielectric_fresnel();
                        LaneBegin::Uniform(Bsdf::MetallicRoughness(MetallicRoughness::new(m.base_color, m.metallic, m.roughness).with_dielectric(f0, f90)))
                    }
                    // Glass alone (no opaque part), untextured: seen from its front
                    // (`glass_back` has its back), scattering on both sides.
                    Kind::Transmission if uniform => match transmission_bsdf(m, true, m.base_color, (m.metallic, m.roughness), m.transmission) {
                        Bsdf::Transmission(t) if t.glass_alone().is_some() => return Some((LaneBegin::Uniform(Bsdf::Transmission(t)), true)),
                        _ => return None,
                    },
                    Kind::Transmission | Kind::Shared(_) | Kind::Varying(_) => return None,
                };
                Some((begin, m.double_sided))
            })
            .collect::<Vec<_>>();
        let glass_backs = materials
            .iter()
            .zip(&lanes)
            .map(|(m, lanes)| match lanes {
                Some((LaneBegin::Uniform(Bsdf::Transmission(_)), _)) => match transmission_bsdf(m, false, m.base_color, (m.metallic, m.roughness), m.transmission) {
                    Bsdf::Transmission(t) => t.glass_alone().copied(),
                    _ => None,
                },
                _ => None,
            })
            .collect();
        Ok(SceneMaterials {
            materials,
            textures: textures.into(),
            kinds,
            lanes,
            glass_backs,
            shared,
            varying,
            stats,
            unbound_neural,
        })
    }

    /// What preparing decoded and opened, with its memory and time.
    pub fn stats(&self) -> MaterialStats {
        self.stats
    }

    /// The materials, in scene order.
    pub fn materials(&self) -> &[Material] {
        &self.materials
    }

    /// The textures the materials index.
    pub fn textures(&self) -> &[Texture] {
        &self.textures
    }

    /// The textures, shared (for the light set's emissive textures).
    pub fn shared_textures(&self) -> Arc<[Texture]> {
        Arc::clone(&self.textures)
    }

    /// The BSDF of `material` at a point seen from its front (`front_face`) or back, with
    /// texture coordinates of a set from `uv(set)` (called only when the material's BSDF
    /// reads a texture: base colour, metallic-roughness, transmission, clear coat, sheen)
    /// and its clear coat's normal `coat_normal` in the local shading frame (z where it is
    /// the shading normal; [`crate::render_scene::SurfacePoint::coat_normal`]); `None` where
    /// the surface does not scatter (the back of a single-sided opaque material;
    /// transmitting materials scatter on both sides, since light inside them leaves through
    /// their back). A sheen or clear coat wraps the material's BSDF in [`Layered`].
    #[inline]
    pub fn bsdf(&self, material: u32, front_face: bool, uv: impl Fn(u32) -> Vec2, coat_normal: glam::Vec3) -> Option<Bsdf<'_>> {
        let bsdf = self.base_bsdf(material, front_face, &uv)?;
        let m = &self.materials[material as usize];
        if m.clearcoat.is_none() && m.sheen.is_none() {
            return Some(bsdf);
        }
        let lookup = |t: &TextureRef| t.lookup(&self.textures, uv(t.tex_coord));
        let sheen = m.sheen.map(|s| {
            let color = s.color_texture.as_ref().map_or(s.color, |t| s.color * lookup(t));
            let roughness = s.roughness_texture.as_ref().map_or(s.roughness, |t| s.roughness * t.lookup_alpha(&self.textures, uv(t.tex_coord)));
            Sheen::new(color, roughness)
        });
        let coat = m.clearcoat.map(|c| {
            let weight = c.weight(lookup);
            let roughness = c.roughness_texture.as_ref().map_or(c.roughness, |t| c.roughness * lookup(t).y);
            Coat::new(weight, roughness, coat_normal)
        });
        Some(Bsdf::Layered(Layered::new(Base::of(bsdf)?, sheen, coat)))
    }

    /// [`Self::bsdf`] without the layers.
    #[inline]
    fn base_bsdf(&self, material: u32, front_face: bool, uv: &impl Fn(u32) -> Vec2) -> Option<Bsdf<'_>> {
        let m = &self.materials[material as usize];
        let kind = self.kinds[material as usize];
        if !front_face && !m.double_sided && kind != Kind::Transmission {
            return None;
        }
        let lookup = |t: &TextureRef| t.lookup(&self.textures, uv(t.tex_coord));
        let base = || match &m.base_color_texture {
            Some(t) => m.base_color * lookup(t),
            None => m.base_color,
        };
        let metallic_roughness = || match &m.metallic_roughness_texture {
            Some(t) => {
                let texel = lookup(t);
                (m.metallic * texel.z, m.roughness * texel.y)
            }
            None => (m.metallic, m.roughness),
        };
        Some(match kind {
            Kind::Lambert => Bsdf::Lambert(Lambert { albedo: base() }),
            Kind::MetallicRoughness => {
                let (metallic, roughness) = metallic_roughness();
                let (f0, f90) = m.dielectric_fresnel();
                Bsdf::MetallicRoughness(MetallicRoughness::new(base(), metallic, roughness).with_dielectric(f0, f90))
            }
            Kind::Transmission => {
                let transmission = match &m.transmission_texture {
                    Some(t) => m.transmission * lookup(t).x,
                    None => m.transmission,
                };
                transmission_bsdf(m, front_face, base(), metallic_roughness(), transmission)
            }
            Kind::Shared(i) => self.shared[i].as_bsdf(),
            Kind::Varying(i) => Bsdf::Mixture(self.mixture(&self.varying[i], uv)),
        })
    }

    /// The mixture a varying material gives at a point whose texture coordinates of a set
    /// are `uv(set)`.
    #[inline]
    fn mixture(&self, v: &PreparedVarying, uv: &impl Fn(u32) -> Vec2) -> Mixture<'_> {
        let part = |slot: usize| self.shared[slot].as_part();
        // RGBA at the point.
        let lookup = |t: &TextureRef| {
            let at = uv(t.tex_coord);
            let rgb = t.lookup(&self.textures, at);
            [rgb.x, rgb.y, rgb.z, t.lookup_alpha(&self.textures, at)]
        };
        let tint = v.tint.as_ref().map_or(Rgb::ONE, |t| Rgb::from_slice(&lookup(t)[..3]));
        match &v.parts {
            PreparedParts::One(slot) => Mixture::new(&[(part(*slot), 1.0)], tint),
            PreparedParts::Mix { slots, weights } => {
                let w = lookup(weights);
                let parts: [(Part<'_>, f32); 4] = std::array::from_fn(|k| (part(slots[k.min(slots.len() - 1)]), if k < slots.len() { w[k] } else { 0.0 }));
                Mixture::new(&parts[..slots.len()], tint)
            }
            PreparedParts::Blend { palette, t, channel } => {
                // NaN → 0.
                let t = lookup(t)[*channel];
                let s = if t > 0.0 { t.min(1.0) } else { 0.0 } * (palette.len() - 1) as f32;
                let k = (s as usize).min(palette.len() - 2);
                let a = s - k as f32;
                Mixture::drawn_per_vertex_of(&[(part(palette.start + k), 1.0 - a), (part(palette.start + k + 1), a)], tint)
            }
        }
    }

    /// The BSDF of `material` seen from its front at a point whose texture coordinates of a
    /// set are `uv(set)` (what [`SceneMaterials::bsdf`] gives there), and whether it is
    /// double-sided, where the lane kernels can begin its vertices from their hits: a
    /// material that emits nothing and has no clear coat or sheen, Lambertian or
    /// metallic-roughness (textured and normal-mapped or not), or untextured glass alone
    /// (transmission with no opaque part; its back is [`SceneMaterials::glass_back`]);
    /// `None` elsewhere. `uv` is asked only for textured materials.
    #[inline]
    pub fn lane_bsdf(&self, material: u32, uv: impl Fn(u32) -> Vec2) -> Option<(Bsdf<'_>, bool)> {
        match self.lanes[material as usize] {
            Some((LaneBegin::Uniform(bsdf), double_sided)) => Some((bsdf, double_sided)),
            Some((LaneBegin::Textured, double_sided)) => Some((self.base_bsdf(material, true, &uv)?, double_sided)),
            None => None,
        }
    }

    /// The glass of a glass `material` that begins in lanes ([`SceneMaterials::lane_bsdf`]) seen from its
    /// back: what [`SceneMaterials::bsdf`] gives there.
    #[inline]
    pub fn glass_back(&self, material: u32) -> Option<&Dielectric> {
        self.glass_backs[material as usize].as_ref()
    }

    /// Radiance `material` emits from its front side, W/(m² sr): its emissive factor, times
    /// its emissive texture when it has one (not applied here: see
    /// [`SceneMaterials::emission_at`]).
    #[inline]
    pub fn emission(&self, material: u32) -> Rgb {
        self.materials[material as usize].emission
    }

    /// Whether `material` may emit: some channel of its emissive factor is > 0 (elsewhere
    /// [`Self::emission_at`] is zero or NaN, which the integrator adds as nothing).
    #[inline]
    pub fn emits(&self, material: u32) -> bool {
        self.materials[material as usize].emission.max_element() > 0.0
    }

    /// Radiance `material` emits from its front side at a point whose texture coordinates of
    /// a set are `uv(set)` (asked only for an emissive texture), W/(m² sr).
    #[inline]
    pub fn emission_at(&self, material: u32, uv: impl Fn(u32) -> Vec2) -> Rgb {
        let m = &self.materials[material as usize];
        match &m.emissive_texture {
            Some(t) if m.emission.max_element() > 0.0 => m.emission * t.lookup(&self.textures, uv(t.tex_coord)),
            _ => m.emission,
        }
    }

    /// Radiance `material` emits from its front side toward a direction at cosine `cos` to
    /// the surface's geometric normal, at a point whose texture coordinates of a set are
    /// `uv(set)`, W/(m² sr): [`Self::emission_at`], under a clear coat darkened by the coat's
    /// reflectance, 1 − c F_c(|cos|) ([`crate::bsdf::layered::coat_transmittance`]). The coat's
    /// angle is taken to the geometric normal, as the light set's samples take it (exact for
    /// flat emitters; the coat's normal maps do not bend it).
    #[inline]
    pub fn emission_toward(&self, material: u32, uv: impl Fn(u32) -> Vec2, cos: f32) -> Rgb {
        let le = self.emission_at(material, &uv);
        match &self.materials[material as usize].clearcoat {
            Some(c) if le.max_element() > 0.0 => le * coat_transmittance(c.weight(|t| t.lookup(&self.textures, uv(t.tex_coord))), cos),
            _ => le,
        }
    }

    /// The absorption coefficient σa (1/m) of the medium a path transmitted through
    /// `material` from its front (`front_face`) or back enters: the material's volume
    /// through the front, vacuum (zero) through the back; `None` where its surfaces are
    /// thin-walled or do not transmit (no volume: the path stays in its medium;
    /// [`crate::scene::Material::volume`]).
    #[inline]
    pub fn entered_volume(&self, material: u32, front_face: bool) -> Option<Rgb> {
        self.materials[material as usize].volume.map(|v| if front_face { v.sigma_a } else { Rgb::ZERO })
    }

    /// Whether `material` has a clear coat.
    #[inline]
    pub fn has_clearcoat(&self, material: u32) -> bool {
        self.materials[material as usize].clearcoat.is_some()
    }

    /// The normal map of `material`'s clear coat, if it has one.
    #[inline]
    pub fn clearcoat_normal_map(&self, material: u32) -> Option<&NormalMap> {
        self.materials[material as usize].clearcoat.as_ref()?.normal_texture.as_ref()
    }

    /// `material`'s normal map, if it has one.
    #[inline]
    pub fn normal_map(&self, material: u32) -> Option<&NormalMap> {
        self.materials[material as usize].normal_texture.as_ref()
    }

    /// How `material` covers its surface.
    #[inline]
    pub fn alpha_mode(&self, material: u32) -> AlphaMode {
        self.materials[material as usize].alpha_mode
    }

    /// `material`'s alpha (coverage in [0, 1]: the base colour factor's alpha times its
    /// texture's) at a point whose texture coordinates of a set are `uv(set)`.
    #[inline]
    pub fn alpha(&self, material: u32, uv: impl Fn(u32) -> Vec2) -> f32 {
        let m = &self.materials[material as usize];
        match &m.base_color_texture {
            Some(t) => m.base_alpha * t.lookup_alpha(&self.textures, uv(t.tex_coord)),
            None => m.base_alpha,
        }
    }

    /// The distinct shared BSDFs in use.
    pub fn shared(&self) -> &[SharedBsdf] {
        &self.shared
    }

    /// The slot (index into [`SceneMaterials::shared`]) of the BSDF the material called
    /// `name` is bound to; `None` when there is no such material or it has none (not bound,
    /// or on no triangle).
    pub fn shared_slot(&self, name: &str) -> Option<usize> {
        let i = self.materials.iter().position(|m| m.name == name)?;
        match self.kinds[i] {
            Kind::Shared(slot) => Some(slot),
            _ => None,
        }
    }

    /// Slots of the decoded latent codes that materials are bound to (not the parts of
    /// varying materials).
    pub fn neural_slots(&self) -> Vec<usize> {
        let mut slots: Vec<usize> = self
            .kinds
            .iter()
            .filter_map(|k| match k {
                Kind::Shared(i) if matches!(self.shared[*i], SharedBsdf::Neural(_)) => Some(*i),
                _ => None,
            })
            .collect();
        slots.sort_unstable();
        slots.dedup();
        slots
    }

    /// Replaces the BSDF at `slot` (e.g. by another latent code in an editing sweep); every
    /// material bound to it follows.
    ///
    /// # Panics
    /// If `slot` is out of range.
    pub fn set_shared(&mut self, slot: usize, bsdf: SharedBsdf) {
        self.shared[slot] = bsdf;
    }

    /// Materials that bind a latent code without a latent file: (material, latent).
    pub fn unbound_neural(&self) -> &[(String, String)] {
        &self.unbound_neural
    }

    /// Evaluations of the decoded latent codes whose value was clamped to 0 (see
    /// [`NeuralBsdf::clamped_count`]).
    pub fn clamped_bsdf_values(&self) -> u64 {
        self.shared
            .iter()
            .map(|m| match m {
                SharedBsdf::Neural(b) => b.clamped_count(),
                _ => 0,
            })
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::Bxdf;
    use crate::formats::merl::MerlTable;
    use crate::testing::data::data_dir;
    use glam::Vec3;

    fn open(text: &str, base: &Path) -> Result<SharedBsdf> {
        SharedBsdf::open(&Binding::parse(text, base)?, &LatentLibrary::default())
    }

    fn unit(theta: f32, phi: f32) -> Vec3 {
        Vec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos())
    }

    /// A metallic-roughness texture scales metallic by its blue and roughness by its green
    /// channel at the point's texture coordinates; a material without textures never asks
    /// for them.
    #[test]
    fn metallic_roughness_textures_scale_the_factors() {
        use crate::bsdf::metallic_roughness::MetallicRoughness;
        use crate::scene::{Material, SurfaceModel, Texture, TextureRef};
        // Texel 0: metallic 1, roughness 0.5; texel 1: metallic 0, roughness 1.
        let texture = Texture::from_linear(2, 1, vec![Rgb::new(0.0, 0.5, 1.0), Rgb::new(0.0, 1.0, 0.0)], Vec::new());
        let textured = Material {
            model: SurfaceModel::MetallicRoughness,
            metallic: 1.0,
            roughness: 0.8,
            metallic_roughness_texture: Some(TextureRef { filter: crate::scene::texture::Filter::Nearest, ..TextureRef::new(0) }),
            ..Material::default_diffuse("textured")
        };
        let plain = Material { model: SurfaceModel::MetallicRoughness, ..Material::default_diffuse("plain") };
        let materials = SceneMaterials::prepare(vec![textured.clone(), plain.clone()], vec![texture], &[true, true], &LatentLibrary::default()).unwrap();
        let (wo, wi) = (unit(0.4, 0.0), unit(0.5, 2.0));
        for (u, metallic, roughness) in [(0.25, 1.0, 0.4), (0.75, 0.0, 0.8)] {
            let bsdf = materials.bsdf(0, true, |_| glam::Vec2::new(u, 0.5), Vec3::Z).unwrap();
            let expected = MetallicRoughness::new(textured.base_color, metallic, roughness);
            assert_eq!(bsdf.eval(wo, wi), expected.eval(wo, wi), "u = {u}");
        }
        let bsdf = materials.bsdf(1, true, |_| panic!("no texture, no texture coordinates"), Vec3::Z).unwrap();
        assert_eq!(bsdf.eval(wo, wi), MetallicRoughness::new(plain.base_color, plain.metallic, plain.roughness).eval(wo, wi));
    }

    /// A neural paint under a clear coat: a material bound to a latent code with
    /// `KHR_materials_clearcoat` shades as the decoded network under the coat (its value
    /// away from the coat's lobe is the network's times 1 − c F_c), and the coat adds its
    /// highlight in the mirror direction.
    #[test]
    fn a_neural_material_can_sit_under_a_clear_coat() {
        use crate::bsdf::layered::{Base, Coat};
        use crate::scene::{Clearcoat, Material, SurfaceModel};
        let latents = crate::testing::data::shipped_latents();
        let name = latents.names()[0].to_string();
        let coated = Material {
            model: SurfaceModel::Bound(Binding::Neural(name.clone())),
            clearcoat: Some(Clearcoat { factor: 1.0, texture: None, roughness: 0.05, roughness_texture: None, normal_texture: None }),
            ..Material::default_diffuse("varnished")
        };
        let materials = SceneMaterials::prepare(vec![coated], Vec::new(), &[true], latents).unwrap();
        let bsdf = materials.bsdf(0, true, |_| glam::Vec2::ZERO, Vec3::Z).unwrap();
        let Bsdf::Layered(layered) = bsdf else { panic!("expected a layered BSDF, got {bsdf:?}") };
        let Base::Neural(neural) = layered.base() else { panic!("expected a neural base") };
        let coat = Coat::new(1.0, 0.05, Vec3::Z);
        let (wo, wi) = (unit(0.5, 0.0), unit(0.9, 2.0));
        let expected = neural.eval(wo, wi) * (1.0 - coat.reflectance(wo));
        assert!((bsdf.eval(wo, wi) - expected).abs().max_element() <= 1e-5 * expected.max_element().max(1.0), "{} vs {expected}", bsdf.eval(wo, wi));
        let mirror = Vec3::new(-wo.x, -wo.y, wo.z);
        assert!(bsdf.eval(wo, mirror).min_element() > neural.eval(wo, mirror).max_element(), "the coat's highlight");
    }

    /// A varying material: a mix weighted by a texture shades each texel as its codes'
    /// mixture (a texel naming one code, as that code alone); a blend's t = 0 and t = 1 ends
    /// are its two codes bit for bit, its middle the mixture of the palette's neighbours; a
    /// tint multiplies. Only what is used is decoded: shared codes once, one palette.
    #[test]
    fn varying_materials_mix_blend_and_tint_codes() {
        use crate::scene::texture::Filter;
        use crate::scene::{Material, SurfaceModel, Varying, VaryingForm};
        let latents = crate::testing::data::shipped_latents();
        let names = latents.names();
        let (a, b) = (names[0].clone(), names[1].clone());
        // Texel 0: (1, 0, 0), alpha 1; texel 1: (0, 1, 0.5), alpha 0.25 (linear).
        let texture = Texture::from_linear(2, 1, vec![Rgb::new(1.0, 0.0, 0.0), Rgb::new(0.0, 1.0, 0.5)], vec![1.0, 0.25]);
        let at = |u: f32| move |_: u32| glam::Vec2::new(u, 0.5);
        let texel = TextureRef { filter: Filter::Nearest, ..TextureRef::new(0) };
        let material = |name: &str, form: VaryingForm, tint: Option<TextureRef>| Material {
            model: SurfaceModel::Varying(Varying { form, tint }),
            ..Material::default_diffuse(name)
        };
        let mix = material("mix", VaryingForm::Mix { parts: vec![Binding::Neural(a.clone()), Binding::Neural(b.clone())], weights: texel }, None);
        let blend = material("blend", VaryingForm::Blend { ends: [a.clone(), b.clone()], t: texel, channel: 1 }, None);
        let tinted = material("tinted", VaryingForm::One(Binding::Neural(b.clone())), Some(texel));
        let four = material("four", VaryingForm::Mix { parts: [&a, &b, &a, &b].map(|n| Binding::Neural(n.clone())).to_vec(), weights: texel }, None);
        let materials = SceneMaterials::prepare(vec![mix, blend, tinted, four], vec![texture], &[true; 4], latents).unwrap();
        let stats = materials.stats();
        assert_eq!(stats.texture_bytes, 2 * 12 + 2 * 4, "two linear RGB texels and their alphas");
        assert_eq!((stats.decoded_codes, stats.palettes, stats.opened), (2 + PALETTE_SIZE, 1, 2 + PALETTE_SIZE), "{stats:?}");
        assert!(stats.palette_bytes > 0 && stats.bytes > stats.palette_bytes, "{stats:?}");
        let (code_a, code_b) = (latents.decode(&a).unwrap(), latents.decode(&b).unwrap());
        let (wo, wi) = (unit(0.4, 0.0), unit(0.6, 2.5));
        let (fa, fb) = (code_a.eval(wo, wi), code_b.eval(wo, wi));
        let f = |m: u32, u: f32| materials.bsdf(m, true, at(u), Vec3::Z).unwrap().eval(wo, wi);
        assert_eq!(f(0, 0.25), fa, "mix, texel (1, 0): A alone");
        assert_eq!(f(0, 0.75), fb, "mix, texel (0, 1): B alone");
        assert_eq!(f(1, 0.25), fa, "blend t = 0: A");
        assert_eq!(f(1, 0.75), fb, "blend t = 1: B");
        assert_eq!(f(2, 0.25), Rgb::new(1.0, 0.0, 0.0) * fb, "tint (1, 0, 0)");
        // Four codes: texel 1 weighs (0, 1, 0.5, 0.25) → B with 1.25, A with 0.5 of 1.75.
        let expected = (0.5 * fa + 1.25 * fb) / 1.75;
        assert!((f(3, 0.75) - expected).abs().max_element() <= 1e-5 * expected.max_element(), "{} vs {expected}", f(3, 0.75));
        // A blend between palette entries mixes its two neighbours.
        let texture = Texture::from_linear(1, 1, vec![Rgb::splat(0.5)], Vec::new());
        let half = material("half", VaryingForm::Blend { ends: [a.clone(), b.clone()], t: TextureRef::new(0), channel: 0 }, None);
        let materials = SceneMaterials::prepare(vec![half], vec![texture], &[true], latents).unwrap();
        let Some(Bsdf::Mixture(m)) = materials.bsdf(0, true, at(0.5), Vec3::Z) else { panic!("a mixture") };
        let parts: Vec<f32> = m.parts().map(|(_, w)| w).collect();
        assert_eq!(parts, [0.5, 0.5], "t = 0.5 lies between entries 15 and 16 of 32");
        assert_eq!(materials.neural_slots(), Vec::<usize>::new(), "palette entries are not bound codes");
    }

    /// Unused varying materials decode nothing; bad codes are errors naming the material.
    #[test]
    fn varying_materials_decode_only_what_is_used_and_name_bad_codes() {
        use crate::scene::{Material, SurfaceModel, Varying, VaryingForm};
        let latents = crate::testing::data::shipped_latents();
        let a = latents.names()[0].clone();
        let blend = |ends: [String; 2]| Material {
            model: SurfaceModel::Varying(Varying { form: VaryingForm::Blend { ends, t: TextureRef::new(0), channel: 0 }, tint: None }),
            ..Material::default_diffuse("ramp")
        };
        let texture = || vec![Texture::from_linear(1, 1, vec![Rgb::ONE], Vec::new())];
        let unused = SceneMaterials::prepare(vec![blend([a.clone(), a.clone()])], texture(), &[false], latents).unwrap();
        assert_eq!(unused.stats().decoded_codes, 0);
        let msg = SceneMaterials::prepare(vec![blend([a.clone(), "no-such-code".into()])], texture(), &[true], latents).err().unwrap().to_string();
        assert!(msg.contains("material 'ramp'") && msg.contains("no-such-code") && msg.contains(&a) && !msg.contains('\n'), "{msg}");
        // Without a latent file the material falls back to its own parameters (rule 4).
        let fallback = SceneMaterials::prepare(vec![blend([a.clone(), a.clone()])], texture(), &[true], &LatentLibrary::default()).unwrap();
        assert_eq!(fallback.unbound_neural(), &[("ramp".to_string(), a.clone())]);
    }

    #[test]
    fn bindings_open_tables_and_networks() {
        let dir = data_dir().join("merl");
        for name in ["alum-bronze", "alum-bronze_fc3.npy"] {
            let text = format!("nbrdf:{}", dir.join(name).display());
            assert!(matches!(open(&text, Path::new("")).unwrap(), SharedBsdf::Nbrdf(_)), "{text}");
        }
        assert!(matches!(open("nbrdf:merl/chrome", &data_dir()).unwrap(), SharedBsdf::Nbrdf(_)));

        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("grey.binary");
        MerlTable::from_fn(|_, _, _| Rgb::splat(0.1)).write(&path).unwrap();
        assert!(matches!(open(&format!("merl:{}", path.display()), Path::new("")).unwrap(), SharedBsdf::Merl(_)));
        let b = open("merl:grey", tmp.path()).unwrap();
        let f = b.as_bsdf().eval(Vec3::Z, Vec3::new(0.6, 0.0, 0.8));
        assert!((f - Rgb::splat(0.1)).abs().max_element() < 1e-6, "{f}");
    }

    #[test]
    fn bad_bindings_name_the_file_or_name() {
        let msg = open("merl:/nonexistent/x.binary", Path::new("")).unwrap_err().to_string();
        assert!(msg.contains("/nonexistent/x.binary"), "{msg}");

        let e = open(&format!("nbrdf:{}", data_dir().join("merl/alum-bronz").display()), Path::new("")).unwrap_err();
        let msg = e.to_string();
        assert!(matches!(e, Error::UnknownName { .. }) && msg.contains("alum-bronz'") && msg.contains("alum-bronze,"), "{msg}");

        let msg = open(&format!("nbrdf:{}", data_dir().join("merl").display()), Path::new("")).unwrap_err().to_string();
        assert!(msg.contains("100 NBRDF networks"), "{msg}");

        let msg = open("nbrdf:/nonexistent/dir/x", Path::new("")).unwrap_err().to_string();
        assert!(msg.contains("/nonexistent/dir/x_fc1.npy"), "{msg}");

        let msg = open("neural:gold", Path::new("")).unwrap_err().to_string();
        assert!(msg.contains("neural:gold") && msg.contains("needs a latent file"), "{msg}");

        let tmp = tempfile::tempdir().unwrap();
        let bad = tmp.path().join("short.binary");
        let mut bytes: Vec<u8> = [90i32, 90, 180].iter().flat_map(|d| d.to_le_bytes()).collect();
        bytes.extend_from_slice(&[0u8; 88]);
        std::fs::write(&bad, bytes).unwrap();
        let msg = open(&format!("merl:{}", bad.display()), Path::new("")).unwrap_err().to_string();
        assert!(msg.contains("short.binary") && msg.contains("truncated"), "{msg}");
    }

    #[test]
    fn the_shared_bsdf_is_the_inner_bsdf() {
        let b = open(&format!("nbrdf:{}", data_dir().join("merl/alum-bronze").display()), Path::new("")).unwrap();
        let SharedBsdf::Nbrdf(inner) = &b else {
            panic!("expected an NBRDF");
        };
        let (wo, wi) = (unit(0.5, 0.2), unit(0.7, 2.5));
        let u = glam::Vec2::new(0.3, 0.6);
        assert_eq!(b.as_bsdf().eval(wo, wi), inner.eval(wo, wi));
        assert_eq!(b.as_bsdf().pdf(wo, wi), inner.pdf(wo, wi));
        assert_eq!(b.as_bsdf().eval_pdf(wo, wi), (inner.eval(wo, wi), inner.pdf(wo, wi)));
        assert_eq!(b.as_bsdf().sample(wo, u, 0.7), inner.sample(wo, u, 0.7));
    }
}
