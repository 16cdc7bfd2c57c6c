//! Every emitter of a scene behind one interface for next-event estimation: emissive
//! triangles, punctual lights and the environment, one of which is chosen per shading point.
//!
//! Selection: the emitters form groups (all emissive triangles; each punctual light; the
//! environment). A group is chosen with probability ½ · its share of the estimated power +
//! ½ · uniform over the groups, then a triangle within its group by power. Power alone
//! starves small lights where a distant emitter's power estimate is large (an environment
//! over a vast ground plane), giving fireflies; the uniform half bounds that.

pub mod area;
pub mod environment;
pub mod punctual;

use crate::color::luminance;
use crate::lanes::{Vec3s, LANES};
use crate::sampling::Distribution1D;
use crate::scene::{PunctualLight, Texture};
use crate::Rgb;
use area::{Emitter, TriangleLight};
use std::sync::Arc;
use environment::{Environment, MapPoint};
use glam::{Vec2, Vec3};

/// A light chosen and sampled for a shading point.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// World-space unit direction toward the light.
    pub direction: Vec3,
    /// Distance to the sampled point (∞ for the environment and directional lights).
    pub distance: f32,
    /// Incident radiance (for punctual lights: intensity / distance²).
    pub radiance: Rgb,
    /// Density including the selection probability: solid angle (1/sr) for area lights and
    /// the environment, the bare selection probability for delta lights.
    pub pdf: f32,
    /// True for punctual lights, which BSDF sampling can never hit (no MIS).
    pub is_delta: bool,
    /// Where a shadow ray toward the light must end (`None`: at infinity).
    pub shadow_target: Option<Vec3>,
}

enum Light {
    Triangle(TriangleLight),
    Punctual(PunctualLight),
    Environment,
}

/// The scene's emitters with a power-proportional selection distribution.
pub struct LightSet {
    lights: Vec<Light>,
    selection: Option<Distribution1D>,
    /// Light index of each scene triangle (`u32::MAX` for non-emitters); empty when the scene
    /// has no emissive triangles.
    triangle_to_light: Vec<u32>,
    environment: Option<Environment>,
    environment_light: usize,
    /// The scene's textures (emissive textures of triangle lights read them).
    textures: Arc<[Texture]>,
}

impl LightSet {
    /// Builds the set. `emissive` lists the emitting triangles; `triangle_count` is the
    /// number of scene triangles; `scene_radius` bounds the scene (for the power of distant
    /// lights); `textures` are the scene's, which emissive textures index. A textured
    /// triangle's power is estimated with the texture's mean over the triangle
    /// ([`area::EmissionTexture::mean_over_triangle`]).
    pub fn new(
        emissive: impl IntoIterator<Item = Emitter>,
        triangle_count: usize,
        punctual: &[PunctualLight],
        environment: Option<Environment>,
        scene_radius: f32,
        textures: Arc<[Texture]>,
    ) -> Self {
        let mut lights = Vec::new();
        // Estimated power of each light, and the group each belongs to.
        let mut weights = Vec::new();
        let mut groups = Vec::new();
        let mut triangle_to_light = Vec::new();
        for Emitter { triangle, corners, radiance, texture, coat } in emissive {
            if let Some(mut light) = TriangleLight::new(corners, radiance) {
                if triangle_to_light.is_empty() {
                    triangle_to_light = vec![u32::MAX; triangle_count];
                }
                triangle_to_light[triangle as usize] = lights.len() as u32;
                let mean = texture.as_ref().map_or(Rgb::ONE, |t| t.mean_over_triangle(&textures));
                light.texture = texture;
                light.coat = coat;
                weights.push(light.area * std::f32::consts::PI * luminance(radiance * mean));
                groups.push(0usize);
                lights.push(Light::Triangle(light));
            }
        }
        for (i, p) in punctual.iter().enumerate() {
            weights.push(punctual::power_hint(p, scene_radius));
            groups.push(1 + i);
            lights.push(Light::Punctual(p.clone()));
        }
        let environment_light = lights.len();
        if let Some(env) = &environment {
            weights.push(env.power_hint() * std::f32::consts::PI * scene_radius * scene_radius);
            groups.push(1 + punctual.len());
            lights.push(Light::Environment);
        }
        let selection = (!weights.is_empty()).then(|| Distribution1D::new(&selection_weights(&weights, &groups)));
        LightSet {
            lights,
            selection,
            triangle_to_light,
            environment,
            environment_light,
            textures,
        }
    }

    /// Probability of choosing light `i` (for tests and diagnostics).
    pub fn selection_probability(&self, i: usize) -> f32 {
        self.selection.as_ref().map_or(0.0, |s| s.pdf_cell(i))
    }

    /// Number of lights (each emissive triangle counts as one).
    pub fn len(&self) -> usize {
        self.lights.len()
    }

    /// True when the scene has no emitter at all.
    pub fn is_empty(&self) -> bool {
        self.lights.is_empty()
    }

    /// Chooses a light with `u_select` and samples it from shading point `p`.
    #[inline]
    pub fn sample(&self, p: Vec3, u_select: f32, u: Vec2) -> Option<LightSample> {
        let (index, select_pdf) = self.choose(u_select)?;
        self.sample_chosen(index, select_pdf, p, u)
    }

    /// Chooses a light with `u_select`: its index and selection probability (> 0); `None`
    /// when the scene has no emitter.
    #[inline]
    pub fn choose(&self, u_select: f32) -> Option<(u32, f32)> {
        let (index, select_pdf) = self.selection.as_ref()?.sample_cell(u_select);
        (select_pdf > 0.0).then_some((index as u32, select_pdf))
    }

    /// The scene's textures, which the triangle lights' emissive textures index.
    #[inline]
    pub fn textures(&self) -> &[Texture] {
        &self.textures
    }

    /// The emissive triangle that light `index` is, if it is one.
    #[inline]
    pub fn triangle(&self, index: u32) -> Option<&TriangleLight> {
        match &self.lights[index as usize] {
            Light::Triangle(t) => Some(t),
            _ => None,
        }
    }

    /// The environment, where light `index` is the environment.
    #[inline]
    pub fn environment_of(&self, index: u32) -> Option<&Environment> {
        match self.lights.get(index as usize) {
            Some(Light::Environment) => self.environment.as_ref(),
            _ => None,
        }
    }

    /// Light `index`, where it is a point, spot or directional light.
    #[inline]
    pub fn punctual(&self, index: u32) -> Option<&PunctualLight> {
        match self.lights.get(index as usize) {
            Some(Light::Punctual(l)) => Some(l),
            _ => None,
        }
    }

    /// Samples light `index`, chosen with probability `select_pdf` by [`Self::choose`], from
    /// shading point `p`.
    #[inline]
    pub fn sample_chosen(&self, index: u32, select_pdf: f32, p: Vec3, u: Vec2) -> Option<LightSample> {
        match &self.lights[index as usize] {
            Light::Triangle(t) => t.sample(p, u, &self.textures).map(|s| s.with_selection(select_pdf)),
            Light::Punctual(l) => punctual::illuminate(l, p).map(|s| LightSample {
                direction: s.direction,
                distance: s.distance,
                radiance: s.value,
                pdf: select_pdf,
                is_delta: true,
                shadow_target: s.distance.is_finite().then(|| p + s.direction * s.distance),
            }),
            Light::Environment => {
                let env = self.environment.as_ref()?;
                env.sample(u).map(|s| s.with_selection(select_pdf))
            }
        }
    }

    /// Density (1/sr, selection included) with which [`Self::sample`] at `p` picks point `q`
    /// on scene triangle `triangle`; zero for non-emitting triangles.
    #[inline]
    pub fn pdf_triangle(&self, triangle: u32, p: Vec3, q: Vec3) -> f32 {
        let Some(&light) = self.triangle_to_light.get(triangle as usize) else {
            return 0.0;
        };
        if light == u32::MAX {
            return 0.0;
        }
        let (Light::Triangle(t), Some(selection)) = (&self.lights[light as usize], &self.selection) else {
            return 0.0;
        };
        t.pdf(p, q) * selection.pdf_cell(light as usize)
    }

    /// Where world direction `d` (unit) falls in the environment ([`Environment::locate`],
    /// which prefetches what [`Self::environment_radiance_pdf_at`] reads); `None` without one.
    #[inline]
    pub fn locate_environment(&self, d: Vec3) -> Option<MapPoint> {
        Some(self.environment.as_ref()?.locate(d))
    }

    /// [`Self::locate_environment`] of each lane's world direction (unit).
    #[inline(always)]
    pub fn locate_environment_lanes(&self, d: Vec3s) -> Option<[MapPoint; LANES]> {
        Some(self.environment.as_ref()?.locate_lanes(d))
    }

    /// The environment's radiance in the direction [`Self::locate_environment`] found at
    /// `at`, and the density (1/sr, selection included) with which [`Self::sample`] picks the
    /// environment in that direction; `None` without an environment.
    #[inline]
    pub fn environment_radiance_pdf_at(&self, at: MapPoint) -> Option<(Rgb, f32)> {
        let env = self.environment.as_ref()?;
        let (radiance, pdf) = env.radiance_pdf_at(at);
        let select = self.selection.as_ref().map_or(0.0, |s| s.pdf_cell(self.environment_light));
        Some((radiance, pdf * select))
    }
}

/// Selection weights from per-light power estimates and group indices (see the module doc).
fn selection_weights(power: &[f32], groups: &[usize]) -> Vec<f32> {
    let clean = |w: f32| if w.is_finite() && w > 0.0 { w } else { 0.0 };
    let group_count = groups.iter().max().map_or(0, |g| g + 1);
    let mut group_power = vec![0.0f64; group_count];
    let mut group_size = vec![0usize; group_count];
    for (&w, &g) in power.iter().zip(groups) {
        group_power[g] += clean(w) as f64;
        group_size[g] += 1;
    }
    let present = group_size.iter().filter(|&&n| n > 0).count() as f64;
    let total: f64 = group_power.iter().sum();
    power
        .iter()
        .zip(groups)
        .map(|(&w, &g)| {
            let share = if total > 0.0 { group_power[g] / total } else { 0.0 };
            let p_group = if total > 0.0 { 0.5 * share + 0.5 / present } else { 1.0 / present };
            let within = if group_power[g] > 0.0 {
                clean(w) as f64 / group_power[g]
            } else {
                1.0 / group_size[g] as f64
            };
            (p_group * within) as f32
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn selection_gives_every_group_half_a_uniform_share() {
        let point = PunctualLight::Point {
            position: Vec3::Y,
            intensity: Rgb::splat(1.0),
        };
        let env = Environment::constant(Rgb::splat(1.0));
        let tri = [Vec3::ZERO, Vec3::X, Vec3::Z];
        let set = LightSet::new(
            [(0, tri), (1, tri.map(|v| v * 2.0))].map(|(triangle, corners)| Emitter { triangle, corners, radiance: Rgb::splat(5.0), texture: None, coat: None }),
            2,
            std::slice::from_ref(&point),
            Some(env),
            1000.0,
            Arc::from([]),
        );
        assert_eq!(set.len(), 4);
        let p: Vec<f32> = (0..4).map(|i| set.selection_probability(i)).collect();
        assert!((p.iter().sum::<f32>() - 1.0).abs() < 1e-5);
        // Three groups: each gets at least half of a uniform share.
        assert!(p[0] + p[1] >= 1.0 / 6.0 - 1e-6 && p[2] >= 1.0 / 6.0 - 1e-6 && p[3] >= 1.0 / 6.0 - 1e-6, "{p:?}");
        // Within the triangles, by power: the second has four times the area.
        assert!((p[1] / p[0] - 4.0).abs() < 1e-3, "{p:?}");
    }
}
