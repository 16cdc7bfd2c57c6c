//! A scene prepared for rendering: the BVH, the lights, the materials with their BSDFs
//! ([`SceneMaterials`]) and everything the integrator looks up per hit. Only what the scene
//! uses is built: BSDFs made from data are opened and latent codes decoded only for materials
//! some triangle uses, and the environment's sampling structures exist only when the scene
//! has an environment.

use crate::accel::{interpolate_point, Bvh, Hit};
use crate::bsdf::Bsdf;
use crate::error::Result;
use crate::frame::Frame;
use crate::neural::latent_library::LatentLibrary;
use crate::lights::environment::Environment;
use crate::lights::LightSet;
use crate::material::SceneMaterials;
use crate::scene::{Geometry, SceneDescription};
use crate::Rgb;
use glam::{Vec2, Vec3};

/// Everything the integrator needs, built once from a [`SceneDescription`].
pub struct RenderScene {
    pub geometry: Geometry,
    /// The materials and their BSDFs.
    pub materials: SceneMaterials,
    pub bvh: Bvh,
    /// What a hit reads of its triangle, gathered once per triangle.
    hit_records: Vec<HitRecord>,
    pub lights: LightSet,
    /// Centre and radius of a sphere bounding the geometry.
    pub bounds_centre: Vec3,
    pub bounds_radius: f32,
}

/// The per-triangle data a hit needs, in one record.
#[derive(Clone, Copy, Debug)]
struct HitRecord {
    corners: [Vec3; 3],
    /// Unit geometric normal from the winding; zero for a degenerate triangle.
    ng: Vec3,
    /// The unit shading normal where all three vertex normals are equal (flat shading: no
    /// interpolation needed); zero where it varies over the triangle.
    flat_normal: Vec3,
}

/// The local description of a surface hit.
#[derive(Clone, Copy, Debug)]
pub struct SurfacePoint {
    /// World position and its absolute error bound per axis.
    pub p: Vec3,
    pub p_error: Vec3,
    /// Unit geometric normal from the triangle's winding (the emitting side of lights).
    pub ng: Vec3,
    /// Shading frame (interpolated normal), flipped to the side the ray arrived from.
    pub frame: Frame,
    /// Geometric normal flipped to the side the ray arrived from.
    pub ng_facing: Vec3,
    /// The triangle hit and the barycentric coordinates (b1, b2) of the point on it (for
    /// attributes looked up only where needed, such as texture coordinates).
    pub triangle: u32,
    pub barycentric: Vec2,
    /// True when the ray hit the front (counter-clockwise) side.
    pub front_face: bool,
    pub material: u32,
}

impl RenderScene {
    /// Builds the BVH, opens the bound BSDFs (each distinct binding once), loads the
    /// environment and builds the light set. Without latent files, materials bound to a
    /// latent code fall back to their glTF parameters
    /// ([`SceneMaterials::unbound_neural`]).
    pub fn new(description: SceneDescription) -> Result<Self> {
        Self::with_latents(description, &LatentLibrary::default())
    }

    /// As [`RenderScene::new`], decoding the latent codes that used materials bind from
    /// `latents` (each distinct code once); an unknown latent name is an error listing the
    /// available ones.
    pub fn with_latents(description: SceneDescription, latents: &LatentLibrary) -> Result<Self> {
        let SceneDescription {
            geometry,
            materials,
            textures,
            lights: punctual,
            environment,
            ..
        } = description;
        let mut used = vec![false; materials.len()];
        for &m in &geometry.material_ids {
            used[m as usize] = true;
        }
        let bvh = Bvh::build((0..geometry.triangle_count()).map(|i| geometry.triangle_positions(i)));
        let hit_records = (0..geometry.triangle_count())
            .map(|i| {
                let corners = geometry.triangle_positions(i);
                let ng = (corners[1] - corners[0]).cross(corners[2] - corners[0]).normalize_or_zero();
                let n = geometry.triangles[i].map(|v| geometry.normals[v as usize]);
                let flat_normal = if n[0] == n[1] && n[1] == n[2] {
                    n[0].try_normalize().unwrap_or(ng)
                } else {
                    Vec3::ZERO
                };
                HitRecord {
                    corners,
                    ng,
                    flat_normal,
                }
            })
            .collect();
        let materials = SceneMaterials::prepare(materials, textures, &used, latents)?;
        let (bounds_centre, bounds_radius) = bounding_sphere(&geometry);
        let environment = environment.as_ref().map(Environment::load).transpose()?;
        let emissive = (0..geometry.triangle_count()).filter_map(|i| {
            let e = materials.emission(geometry.material_ids[i]);
            (e.max_element() > 0.0).then(|| (i as u32, geometry.triangle_positions(i), e))
        });
        let lights = LightSet::new(
            emissive,
            geometry.triangle_count(),
            &punctual,
            environment,
            bounds_radius,
        );
        Ok(RenderScene {
            geometry,
            materials,
            bvh,
            hit_records,
            lights,
            bounds_centre,
            bounds_radius,
        })
    }

    /// The surface point of a hit of a ray with direction `direction`; `None` for a
    /// degenerate triangle.
    #[inline]
    pub fn surface_point(&self, hit: &Hit, direction: Vec3) -> Option<SurfacePoint> {
        let g = &self.geometry;
        let tri = hit.triangle as usize;
        let HitRecord { corners, ng, flat_normal } = self.hit_records[tri];
        if ng == Vec3::ZERO {
            return None;
        }
        let (p, p_error) = interpolate_point(corners, hit.barycentric);
        let front_face = direction.dot(ng) < 0.0;
        let ng_facing = if front_face { ng } else { -ng };
        let b = hit.barycentric;
        let b0 = 1.0 - b.x - b.y;
        let mut ns = if flat_normal != Vec3::ZERO {
            flat_normal
        } else {
            let [i0, i1, i2] = g.triangles[tri];
            let ns = g.normals[i0 as usize] * b0 + g.normals[i1 as usize] * b.x + g.normals[i2 as usize] * b.y;
            ns.try_normalize().unwrap_or(ng)
        };
        if ns.dot(ng_facing) < 0.0 {
            ns = -ns;
        }
        Some(SurfacePoint {
            p,
            p_error,
            ng,
            frame: Frame::from_normal(ns),
            ng_facing,
            triangle: hit.triangle,
            barycentric: b,
            front_face,
            material: g.material_ids[tri],
        })
    }

    /// Texture coordinates of set `set` (0 or 1; set 1 falls back to set 0 where the scene has
    /// none) at a surface point, interpolated from its triangle's vertices.
    #[inline]
    pub fn uv(&self, sp: &SurfacePoint, set: u32) -> Vec2 {
        let g = &self.geometry;
        let uvs = if set == 1 && !g.uvs1.is_empty() { &g.uvs1 } else { &g.uvs };
        let [i0, i1, i2] = g.triangles[sp.triangle as usize];
        let b = sp.barycentric;
        let b0 = 1.0 - b.x - b.y;
        uvs[i0 as usize] * b0 + uvs[i1 as usize] * b.x + uvs[i2 as usize] * b.y
    }

    /// The BSDF at a surface point; `None` where the surface does not scatter (the back of
    /// a single-sided material).
    #[inline]
    pub fn bsdf(&self, sp: &SurfacePoint) -> Option<Bsdf<'_>> {
        self.materials.bsdf(sp.material, sp.front_face, |set| self.uv(sp, set))
    }

    /// Radiance emitted at a surface point toward the ray that hit it (front side only).
    #[inline]
    pub fn emission(&self, sp: &SurfacePoint) -> Rgb {
        if sp.front_face {
            self.materials.emission(sp.material)
        } else {
            Rgb::ZERO
        }
    }
}

/// A sphere bounding all vertices (the box's centre and half-diagonal).
fn bounding_sphere(g: &Geometry) -> (Vec3, f32) {
    if g.positions.is_empty() {
        return (Vec3::ZERO, 1.0);
    }
    let (lo, hi) = g.positions.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), &p| (lo.min(p), hi.max(p)),
    );
    let centre = 0.5 * (lo + hi);
    (centre, (0.5 * (hi - lo).length()).max(1e-3))
}
