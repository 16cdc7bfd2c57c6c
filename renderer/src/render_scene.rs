//! A scene prepared for rendering: the BVH, the lights, the materials with their BSDFs
//! ([`SceneMaterials`]) and everything the integrator looks up per hit. Only what the scene
//! uses is built: BSDFs made from data are opened and latent codes decoded only for materials
//! some triangle uses, and the environment's sampling structures exist only when the scene
//! has an environment.

use crate::accel::{depth_class, gamma, interpolate_point, barycentric_point, Bvh, Hit, InstanceBvh, Ray, TracePolicy, DEPTH_CLASSES, NO_INSTANCE};
use crate::bsdf::Bsdf;
use crate::error::Result;
use crate::frame::Frame;
use crate::lanes::{F32s, Mask, MaskOps, Real, SetLane, Vec2s, Vec3s, V2, V3};
use crate::neural::latent_library::LatentLibrary;
use crate::lights::environment::Environment;
use crate::lights::area::{EmissionCoat, EmissionTexture, Emitter};
use crate::lights::LightSet;
use crate::material::SceneMaterials;
use crate::sampler::hash_float;
use crate::scene::{AlphaMode, Geometry, NormalMap, SceneDescription};
use crate::Rgb;
use glam::{Affine3A, Vec2, Vec3, Vec3A};

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
    /// Whether some triangle's material lets rays through (alpha MASK or BLEND): rays are
    /// then traced with [`Bvh::intersect_filtered`].
    has_alpha: bool,
    /// Meshes placed by instances (two-level acceleration); `None` without instances.
    instances: Option<Instances>,
}

/// The instanced part of a scene: a BVH over the instances and one per mesh, in the mesh's
/// space ([`InstanceBvh`]), and how batches are traced through both levels with the
/// scene's own triangles (per class of depth, see [`DEPTH_CLASSES`]).
struct Instances {
    bvh: InstanceBvh,
    /// Per instance, the transforms a hit on it needs.
    placements: Vec<Placed<f32>>,
    closest_policies: [TracePolicy; DEPTH_CLASSES],
    occluded_policies: [TracePolicy; DEPTH_CLASSES],
}

/// The per-triangle data a hit needs, in one record (60 bytes, aligned to one 64-byte cache
/// line, so a hit's record is one line to fetch).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
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
    /// The clear coat's normal in the local shading frame, turned to the viewer's side:
    /// z, except under a clear coat whose normal differs from the shading normal (the
    /// base's normal map does not bend the coat; the coat's own normal map does).
    pub coat_normal: Vec3,
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
        let (bounds_centre, bounds_radius) = bounding_sphere(description.world_bounds());
        let world_triangles = description.world_triangle_count();
        let instances = (!description.instances.is_empty()).then(|| Instances::build(&description));
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
        let bvh = Bvh::build((0..world_triangles).map(|i| geometry.triangle_positions(i)));
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
        let has_alpha = materials.iter().zip(&used).any(|(m, &u)| u && m.has_alpha());
        let materials = SceneMaterials::prepare(materials, textures, &used, latents)?;
        let environment = environment.as_ref().map(Environment::load).transpose()?;
        let emissive = (0..world_triangles).filter_map(|i| {
            let material = geometry.material_ids[i];
            let radiance = materials.emission(material);
            (radiance.max_element() > 0.0).then(|| {
                let m = &materials.materials()[material as usize];
                let uvs = |tex_coord: Option<u32>| geometry.triangles[i].map(|v| tex_coord.map_or(Vec2::ZERO, |set| vertex_uv(&geometry, v, set)));
                Emitter {
                    triangle: i as u32,
                    corners: geometry.triangle_positions(i),
                    radiance,
                    texture: m.emissive_texture.map(|texture| EmissionTexture { texture, uvs: uvs(Some(texture.tex_coord)) }),
                    coat: m.clearcoat.map(|coat| Box::new(EmissionCoat { coat, uvs: uvs(coat.texture.map(|t| t.tex_coord)) })),
                }
            })
        });
        let lights = LightSet::new(
            emissive,
            geometry.triangle_count(),
            &punctual,
            environment,
            bounds_radius,
            materials.shared_textures(),
        );
        Ok(RenderScene {
            geometry,
            materials,
            bvh,
            hit_records,
            lights,
            bounds_centre,
            bounds_radius,
            has_alpha,
            instances,
        })
    }

    /// The closest surface `ray` stops at within (0, ray.t_max): the closest hit, passing
    /// through cut-outs and, with probability 1 − alpha, partly covering surfaces
    /// ([`AlphaMode`]).
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        let best = if self.has_alpha {
            self.bvh.intersect_filtered(ray, |hit| self.stops(ray, hit))
        } else {
            self.bvh.intersect(ray)
        };
        match &self.instances {
            Some(inst) => inst.bvh.intersect(ray, best, self.has_alpha.then_some(&|r: &Ray, h: &Hit| self.stops(r, h))),
            None => best,
        }
    }

    /// Whether a surface blocks `ray` within (0, ray.t_max) (as [`RenderScene::intersect`]
    /// decides what blocks).
    #[inline]
    pub fn occluded(&self, ray: &Ray) -> bool {
        let world = if self.has_alpha {
            self.bvh.occluded_filtered(ray, |hit| self.stops(ray, hit))
        } else {
            self.bvh.occluded(ray)
        };
        world || self.instances.as_ref().is_some_and(|inst| inst.bvh.occluded(ray, self.has_alpha.then_some(&|r: &Ray, h: &Hit| self.stops(r, h))))
    }

    /// How batches of closest-hit and occlusion rays are traced (true: packets, false: one
    /// ray at a time, `None` before the first measurement): as the policies of the
    /// instances (both levels together) or of the BVH chose.
    pub fn trace_modes(&self) -> [(Option<bool>, Option<bool>); DEPTH_CLASSES] {
        match &self.instances {
            Some(inst) => std::array::from_fn(|c| (inst.closest_policies[c].choice(), inst.occluded_policies[c].choice())),
            None => self.bvh.trace_modes(),
        }
    }

    /// [`RenderScene::intersect`] of many rays at path depth `depth` (0 for camera rays;
    /// batches of each depth choose their trace mode apart, see [`Bvh::intersect_all`]):
    /// `out[i]` for `rays[i]`.
    pub fn intersect_all(&self, rays: &[Ray], out: &mut Vec<Option<Hit>>, depth: usize) {
        if let Some(inst) = &self.instances {
            let stops = |r: &Ray, h: &Hit| self.stops(r, h);
            let accept = self.has_alpha.then_some(&stops as &dyn Fn(&Ray, &Hit) -> bool);
            inst.closest_policies[depth_class(depth)].trace(rays.len(), |packets| {
                match accept {
                    Some(accept) => self.bvh.intersect_all_filtered_with(rays, out, packets, accept),
                    None => self.bvh.intersect_all_with(rays, out, packets),
                }
                inst.bvh.intersect_all_with(rays, out, packets, accept);
            });
        } else if self.has_alpha {
            self.bvh.intersect_all_filtered(rays, out, depth, |ray, hit| self.stops(ray, hit));
        } else {
            self.bvh.intersect_all(rays, out, depth);
        }
    }

    /// [`RenderScene::occluded`] of many rays from vertices at path depth `depth`: `out[i]`
    /// for `rays[i]`.
    pub fn occluded_all(&self, rays: &[Ray], out: &mut Vec<bool>, depth: usize) {
        if let Some(inst) = &self.instances {
            let stops = |r: &Ray, h: &Hit| self.stops(r, h);
            let accept = self.has_alpha.then_some(&stops as &dyn Fn(&Ray, &Hit) -> bool);
            inst.occluded_policies[depth_class(depth)].trace(rays.len(), |packets| {
                match accept {
                    Some(accept) => self.bvh.occluded_all_filtered_with(rays, out, packets, accept),
                    None => self.bvh.occluded_all_with(rays, out, packets),
                }
                inst.bvh.occluded_all_with(rays, out, packets, accept);
            });
        } else if self.has_alpha {
            self.bvh.occluded_all_filtered(rays, out, depth, |ray, hit| self.stops(ray, hit));
        } else {
            self.bvh.occluded_all(rays, out, depth);
        }
    }

    /// Whether `ray` stops at `hit` rather than passing through: always on opaque
    /// materials; on a cut-out (MASK) where alpha ≥ the cutoff; on partial coverage (BLEND)
    /// with probability alpha, decided by a hash of the ray and the triangle, so the same
    /// ray always gets the same answer.
    #[inline]
    fn stops(&self, ray: &Ray, hit: &Hit) -> bool {
        let material = self.geometry.material_ids[hit.triangle as usize];
        let alpha = || self.materials.alpha(material, |set| self.uv_at(hit.triangle, hit.barycentric, set));
        match self.materials.alpha_mode(material) {
            AlphaMode::Opaque => true,
            AlphaMode::Mask { cutoff } => alpha() >= cutoff,
            AlphaMode::Blend => {
                let [ox, oy, oz] = ray.origin.to_array().map(f32::to_bits);
                let [dx, dy, dz] = ray.direction.to_array().map(f32::to_bits);
                hash_float(&[ox, oy, oz, dx, dy, dz, hit.triangle]) < alpha()
            }
        }
    }

    /// Starts fetching what [`RenderScene::surface_point`] of `hit` reads first (the
    /// triangle's record, vertex indices and material), so that the look-ups of many hits
    /// issued after all their prefetches overlap their cache misses. No effect on values.
    #[inline]
    pub fn prefetch_hit(&self, hit: &Hit) {
        let tri = hit.triangle as usize;
        if let (Some(record), Some(vertices), Some(material)) = (self.hit_records.get(tri), self.geometry.triangles.get(tri), self.geometry.material_ids.get(tri)) {
            crate::support::prefetch(record);
            crate::support::prefetch(vertices);
            crate::support::prefetch(material);
        }
    }

    /// What beginning `hit`'s vertex in lanes needs, where its material lets the lane
    /// kernels begin it ([`SceneMaterials::lane_bsdf`]) and its triangle is not degenerate:
    /// the hit with its material ([`LaneHit`], whose triangle [`TriangleLanes::set`] reads
    /// for [`surface_points_lanes`]), the material's BSDF there seen from its front, and
    /// whether it is double-sided; `None` elsewhere.
    #[inline]
    pub(crate) fn lane_hit(&self, hit: &Hit) -> Option<(LaneHit, Bsdf<'_>, bool)> {
        let material = self.geometry.material_ids[hit.triangle as usize];
        let (bsdf, double_sided) = self.materials.lane_bsdf(material, |set| self.uv_at(hit.triangle, hit.barycentric, set))?;
        if self.hit_records[hit.triangle as usize].ng == Vec3::ZERO {
            return None;
        }
        Some((LaneHit { hit: *hit, material }, bsdf, double_sided))
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
        let (mut p, mut p_error) = interpolate_point(corners, hit.barycentric);
        let b = hit.barycentric;
        let mut ns = if flat_normal != Vec3::ZERO {
            flat_normal
        } else {
            let normals = g.triangles[tri].map(|i| V3::from(g.normals[i as usize]));
            smooth_normal(normals, b.into(), ng.into()).into()
        };
        let material = g.material_ids[tri];
        let normal_map = self.materials.normal_map(material);
        // The clear coat's normal where it is not the shading normal: the interpolated
        // normal under a base normal map, or bent by the coat's own normal map.
        let mut coat_normal = match self.materials.clearcoat_normal_map(material) {
            Some(map) => Some(self.mapped_normal(tri, hit.barycentric, ns, map)),
            None => (normal_map.is_some() && self.materials.has_clearcoat(material)).then_some(ns),
        };
        if let Some(map) = normal_map {
            ns = self.mapped_normal(tri, hit.barycentric, ns, map);
        }
        let mut ng = ng;
        if hit.instance != NO_INSTANCE {
            let placed = &self.instances.as_ref()?.placements[hit.instance as usize];
            let world = placed.place(p.into(), p_error.into(), ng.into(), ns.into());
            (p, p_error, ng, ns) = (world.p.into(), world.p_error.into(), world.ng.into(), world.ns.into());
            coat_normal = coat_normal.map(|n| placed.normal_to_world(n.into(), world.ng).into());
            if !world.ok {
                return None;
            }
        }
        let (front_face, ng_facing, mut ns) = facing(direction.into(), ng.into(), ns.into());
        if normal_map.is_some() {
            ns = keep_viewer_above(ns, (-direction).into(), ng_facing);
        }
        let (ng_facing, frame): (Vec3, _) = (ng_facing.into(), Frame::from_normal(ns.into()));
        let coat_normal = match coat_normal {
            Some(n) => {
                let n = if n.dot(ng_facing) < 0.0 { -n } else { n };
                frame.to_local(keep_viewer_above(n.into(), (-direction).into(), ng_facing.into()).into())
            }
            None => Vec3::Z,
        };
        Some(SurfacePoint {
            p,
            p_error,
            ng,
            frame,
            ng_facing,
            triangle: hit.triangle,
            barycentric: b,
            front_face,
            material,
            coat_normal,
        })
    }

    /// The shading normal `n` (interpolated, unit) bent by normal map `map` at barycentric
    /// coordinates `b` of triangle `tri` ([`NormalBend::bend`]); `n` itself where the
    /// vertices carry no tangent.
    fn mapped_normal(&self, tri: usize, b: Vec2, n: Vec3, map: &NormalMap) -> Vec3 {
        match self.normal_bend(tri, b, map) {
            Some(bend) => bend.bend(n.into()).into(),
            None => n,
        }
    }

    /// Normal map `map`'s reading at barycentric coordinates `b` of triangle `tri`: the
    /// tangent and bitangent sign interpolated from its vertices, and the texel's normal;
    /// `None` where the vertices carry no tangent.
    #[inline]
    fn normal_bend(&self, tri: usize, b: Vec2, map: &NormalMap) -> Option<NormalBend<f32>> {
        let g = &self.geometry;
        if g.tangents.is_empty() {
            return None;
        }
        let [i0, i1, i2] = g.triangles[tri].map(|i| g.tangents[i as usize]);
        let tangent = (i0 * (1.0 - b.x - b.y) + i1 * b.x + i2 * b.y).truncate();
        let sign = if i0.w + i1.w + i2.w < 0.0 { -1.0 } else { 1.0 };
        let texel = map.texture.lookup(self.materials.textures(), self.uv_at(tri as u32, b, map.texture.tex_coord));
        let normal = (2.0 * texel - Vec3::ONE) * Vec3::new(map.scale, map.scale, 1.0);
        Some(NormalBend { tangent: tangent.into(), sign, normal: normal.into() })
    }

    /// Texture coordinates of set `set` (0 or 1; set 1 falls back to set 0 where the scene has
    /// none) at a surface point, interpolated from its triangle's vertices.
    #[inline]
    pub fn uv(&self, sp: &SurfacePoint, set: u32) -> Vec2 {
        self.uv_at(sp.triangle, sp.barycentric, set)
    }

    /// Texture coordinates of set `set` at barycentric coordinates `b` of `triangle`.
    #[inline]
    fn uv_at(&self, triangle: u32, b: Vec2, set: u32) -> Vec2 {
        let [i0, i1, i2] = self.geometry.triangles[triangle as usize];
        let uv = |v| vertex_uv(&self.geometry, v, set);
        uv(i0) * (1.0 - b.x - b.y) + uv(i1) * b.x + uv(i2) * b.y
    }

    /// The BSDF at a surface point; `None` where the surface does not scatter (the back of
    /// a single-sided material).
    #[inline]
    pub fn bsdf(&self, sp: &SurfacePoint) -> Option<Bsdf<'_>> {
        self.materials.bsdf(sp.material, sp.front_face, |set| self.uv(sp, set), sp.coat_normal)
    }

    /// Radiance emitted at a surface point toward `wo` (world, unit: back along the ray that
    /// hit it), front side only; under a clear coat darkened by it
    /// ([`SceneMaterials::emission_toward`]).
    #[inline]
    pub fn emission(&self, sp: &SurfacePoint, wo: Vec3) -> Rgb {
        if sp.front_face {
            self.materials.emission_toward(sp.material, |set| self.uv(sp, set), sp.ng.dot(wo))
        } else {
            Rgb::ZERO
        }
    }
}

/// A hit on a triangle whose surface point can be found in lanes ([`RenderScene::lane_hit`]),
/// and the triangle's material. What finding the point needs (the triangle's corners and
/// normals, an instance's transforms, a normal map's reading) is read from the scene into the
/// lanes themselves ([`TriangleLanes::set`]), not gathered into a value first: returned and
/// moved per vertex, such a value (with its optional parts written in pieces and copied
/// whole) stalled store forwarding for ~5 % of the Cornell box's time.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LaneHit {
    pub hit: Hit,
    pub material: u32,
}

impl LaneHit {
    /// Whether the triangle is flat-shaded (one shading normal over it).
    #[cfg(test)]
    pub fn flat(&self, scene: &RenderScene) -> bool {
        scene.hit_records[self.hit.triangle as usize].flat_normal != Vec3::ZERO
    }

    /// Where the triangle is an instance's, the instance's transforms (the triangle's record
    /// is in its mesh's space).
    #[inline(always)]
    pub fn placed<'s>(&self, scene: &'s RenderScene) -> Option<&'s Placed<f32>> {
        match &scene.instances {
            Some(inst) if self.hit.instance != NO_INSTANCE => Some(&inst.placements[self.hit.instance as usize]),
            _ => None,
        }
    }

    /// The normal map's reading at the hit, where the material has a normal map and the
    /// vertices carry tangents.
    #[cfg(test)]
    pub fn bend(&self, scene: &RenderScene) -> Option<NormalBend<f32>> {
        let map = scene.materials.normal_map(self.material)?;
        scene.normal_bend(self.hit.triangle as usize, self.hit.barycentric, map)
    }
}

/// A vertex's surface point per lane, as the lane kernels read it: position, its absolute
/// error bound, geometric normal on the side of the arriving ray, shading frame (s, t, n),
/// and the direction toward the previous vertex in that frame (the vertex's wo).
#[derive(Clone, Debug, Default)]
pub(crate) struct SurfaceLanes {
    pub p: Vec3s,
    pub p_error: Vec3s,
    pub ng: Vec3s,
    pub s: Vec3s,
    pub t: Vec3s,
    pub n: Vec3s,
    pub wo: Vec3s,
}

impl SurfaceLanes {
    /// World direction `v` in the lanes' shading frames.
    #[inline(always)]
    pub fn to_local(&self, v: Vec3s) -> Vec3s {
        crate::frame::to_local(self.s, self.t, self.n, v)
    }

    /// Local direction `v` in world space.
    #[inline(always)]
    pub fn to_world(&self, v: Vec3s) -> Vec3s {
        crate::frame::to_world(self.s, self.t, self.n, v)
    }
}


/// The triangles of up to [`LANES`] hits whose surface points are found in lanes
/// ([`surface_points_lanes`]): per lane, a [`LaneHit`]'s triangle's corners, geometric
/// normal, vertex normals (where `flat`, the first is the flat shading normal and the others
/// are unused), on an instance its transforms, and on a normal-mapped material the map's
/// reading; whether any lane is smooth-shaded, whether any is on an instance, and whether
/// any is normal-mapped.
#[derive(Clone, Debug, Default)]
pub(crate) struct TriangleLanes {
    corners: [Vec3s; 3],
    ng: Vec3s,
    normals: [Vec3s; 3],
    flat: Mask,
    any_smooth: bool,
    placed: Placed<F32s>,
    instanced: Mask,
    any_instanced: bool,
    bends: NormalBend<F32s>,
    /// The lanes whose material has a normal map, and those of them whose map bends the
    /// normal (their vertices carry tangents).
    mapped: Mask,
    bent: Mask,
    any_mapped: bool,
}

impl TriangleLanes {
    /// Forgets which lanes are smooth-shaded, on instances or normal-mapped (their old values
    /// stay, unused).
    #[inline]
    pub fn clear(&mut self) {
        self.any_smooth = false;
        self.any_instanced = false;
        self.any_mapped = false;
    }

    /// Lane `i` holds the triangle of `hit`, a hit in `scene`.
    #[inline(always)]
    pub fn set(&mut self, i: usize, scene: &RenderScene, hit: &LaneHit) {
        let tri = hit.hit.triangle as usize;
        let HitRecord { corners, ng, flat_normal } = scene.hit_records[tri];
        for (lanes, corner) in self.corners.iter_mut().zip(corners) {
            lanes.set(i, corner);
        }
        self.ng.set(i, ng);
        // A flat lane's normal is its first; the others are read only where some lane is
        // smooth, and then not used for the flat lanes.
        let flat = flat_normal != Vec3::ZERO;
        if flat {
            self.normals[0].set(i, flat_normal);
        } else {
            let g = &scene.geometry;
            for (lanes, v) in self.normals.iter_mut().zip(g.triangles[tri]) {
                lanes.set(i, g.normals[v as usize]);
            }
        }
        self.flat.0[i] = flat;
        self.any_smooth |= !flat;
        let placed = hit.placed(scene);
        self.instanced.0[i] = placed.is_some();
        if let Some(placed) = placed {
            self.placed.set(i, placed);
            self.any_instanced = true;
        }
        // Each part written as it is read (no optional value built whole and copied).
        self.bent.0[i] = false;
        let map = scene.materials.normal_map(hit.material);
        self.mapped.0[i] = map.is_some();
        if let Some(map) = map {
            self.any_mapped = true;
            if let Some(bend) = scene.normal_bend(tri, hit.hit.barycentric, map) {
                self.bent.0[i] = true;
                self.bends.set(i, &bend);
            }
        }
    }
}

/// The surface points on `triangles` at barycentric coordinates `barycentric` of rays with
/// directions `direction` (the lanes on instances moved into world space by their
/// transforms, the normal-mapped ones' normals bent), with [`RenderScene::surface_point`]'s
/// operations and wo as `PathTracer::begin` finds it (so the same bits); the lanes hit from
/// the front; and the lanes with a surface point (`surface_point` gives none where an
/// instance's transform leaves no geometric normal).
#[inline(always)]
pub(crate) fn surface_points_lanes(triangles: &TriangleLanes, barycentric: Vec2s, direction: Vec3s) -> (SurfaceLanes, Mask, Mask) {
    let TriangleLanes { corners, ng, normals, flat, any_smooth, .. } = *triangles;
    let (mut p, mut p_error) = barycentric_point(corners, barycentric);
    let mut ns = normals[0];
    if any_smooth {
        ns = flat.select(ns, smooth_normal(normals, barycentric, ng));
    }
    if triangles.any_mapped {
        ns = triangles.bent.select(triangles.bends.bend(ns), ns);
    }
    let (mut ng, mut valid) = (ng, Mask::splat(true));
    if triangles.any_instanced {
        let world = triangles.placed.place(p, p_error, ng, ns);
        let lanes = triangles.instanced;
        ((p, p_error), (ng, ns)) = lanes.select(((world.p, world.p_error), (world.ng, world.ns)), ((p, p_error), (ng, ns)));
        valid = !lanes | world.ok;
    }
    let (front_face, ng_facing, mut n) = facing(direction, ng, ns);
    if triangles.any_mapped {
        n = triangles.mapped.select(keep_viewer_above(n, -direction, ng_facing), n);
    }
    let (s, t) = crate::frame::tangents(n);
    let mut surface = SurfaceLanes { p, p_error, ng: ng_facing, s, t, n, wo: Vec3s::default() };
    surface.wo = surface.to_local(-direction);
    (surface, front_face, valid)
}

/// The unit shading normal interpolated from a triangle's corner normals `normals` at
/// barycentric coordinates `b` (of corners 1 and 2), `ng` where it has no length; over
/// [`Real`] values (one point, or one per lane).
#[inline(always)]
fn smooth_normal<R: Real>(normals: [V3<R>; 3], b: V2<R>, ng: V3<R>) -> V3<R> {
    let b0 = R::splat(1.0) - b.x - b.y;
    let (unit, ok) = (normals[0] * b0 + normals[1] * b.x + normals[2] * b.y).try_normalize();
    ok.select(unit, ng)
}

/// The side a ray of direction `direction` meets a surface of geometric normal `ng` from:
/// whether it is the front (`ng`'s side), the geometric normal facing the ray and the shading
/// normal `ns` turned to that side; over [`Real`] values (one point, or one per lane).
#[inline(always)]
fn facing<R: Real>(direction: V3<R>, ng: V3<R>, ns: V3<R>) -> (R::Mask, V3<R>, V3<R>) {
    let zero = R::splat(0.0);
    let front = direction.dot(ng).lt(zero);
    let ng_facing = front.select(ng, -ng);
    (front, ng_facing, ns.dot(ng_facing).lt(zero).select(-ns, ns))
}

/// A normal-mapped shading normal `ns` tilted toward the viewer direction `wo` (unit, on
/// the side of `ng`) just enough that the viewer stays above its hemisphere: where a bump
/// faces away at grazing view, the BSDF would otherwise see `wo` below its horizon and the
/// path would end black (dark speckles on normal-mapped ground far away). The bound,
/// min(0.9 wo·ng, 0.01), follows Cycles' `ensure_valid_reflection`. Over [`Real`] values
/// (one point, or one per lane).
#[inline(always)]
fn keep_viewer_above<R: Real>(ns: V3<R>, wo: V3<R>, ng: V3<R>) -> V3<R> {
    let least = (wo.dot(ng) * 0.9).min(R::splat(0.01));
    let cos = ns.dot(wo);
    let (tilted, ok) = (ns + wo * (least - cos)).try_normalize();
    cos.ge(least).select(ns, ok.select(tilted, ng))
}

/// A normal map's reading at a point, over [`Real`] values (one point's, or one per lane):
/// the tangent interpolated from the triangle's vertices (not unit, in the mesh's space),
/// the bitangent's sign w (±1), and the texel's tangent-space normal (2 texel − 1, its x and
/// y times the map's scale).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct NormalBend<R> {
    tangent: V3<R>,
    sign: R,
    normal: V3<R>,
}

impl<R: Real> NormalBend<R> {
    /// The unit shading normal `n` bent by the map: the texel's normal in the frame of the
    /// tangent made orthogonal to `n`, the bitangent w n × t, and `n`; `n` itself where the
    /// tangent has no length orthogonal to `n` or the bent normal has none.
    #[inline(always)]
    fn bend(&self, n: V3<R>) -> V3<R> {
        let (t, ok) = (self.tangent - n * n.dot(self.tangent)).try_normalize();
        let v = self.normal;
        let (bent, bent_ok) = (t * v.x + n.cross(t) * self.sign * v.y + n * v.z).try_normalize();
        (ok & bent_ok).select(bent, n)
    }
}

impl NormalBend<F32s> {
    /// Lane `i` holds `bend`.
    #[inline(always)]
    fn set(&mut self, i: usize, bend: &NormalBend<f32>) {
        self.tangent.set_lane(i, bend.tangent);
        self.sign.set_lane(i, bend.sign);
        self.normal.set_lane(i, bend.normal);
    }
}

/// Texture coordinates of set `set` (0 or 1; set 1 falls back to set 0 where the geometry
/// has none) at vertex `v`.
#[inline]
fn vertex_uv(g: &Geometry, v: u32, set: u32) -> Vec2 {
    let uvs = if set == 1 && !g.uvs1.is_empty() { &g.uvs1 } else { &g.uvs };
    uvs[v as usize]
}

impl Instances {
    fn build(description: &SceneDescription) -> Instances {
        let g = &description.geometry;
        let meshes = description
            .meshes
            .iter()
            .map(|m| {
                let triangles = m.first_triangle as usize..(m.first_triangle + m.triangle_count) as usize;
                (Bvh::build(triangles.map(|i| g.triangle_positions(i))), m.first_triangle)
            })
            .collect();
        let mesh_bounds = description.mesh_bounds();
        let to_world: Vec<Affine3A> = description.instances.iter().map(|i| Affine3A::from_mat4(i.object_to_world)).collect();
        let placements = to_world.iter().map(Placed::of).collect();
        let bvh = InstanceBvh::build(
            description.instances.iter().zip(&to_world).map(|(i, m)| (SceneDescription::instance_bounds(&mesh_bounds, i), m.inverse(), i.mesh)),
            meshes,
        );
        let policies = || std::array::from_fn(|_| TracePolicy::new(Bvh::packet_width().is_some()));
        Instances { bvh, placements, closest_policies: policies(), occluded_policies: policies() }
    }
}

/// An instance's transforms over [`Real`] values (one instance's, or one per lane): the
/// object-to-world matrix's columns and translation, and the inverse transpose of its linear
/// part (for normals).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Placed<R> {
    cols: [V3<R>; 3],
    translation: V3<R>,
    normal: [V3<R>; 3],
}

/// A surface point placed in world space by [`Placed::place`]: position, its absolute error
/// bound, unit geometric and shading normals, and whether the geometric normal exists.
struct PlacedPoint<R: Real> {
    p: V3<R>,
    p_error: V3<R>,
    ng: V3<R>,
    ns: V3<R>,
    ok: R::Mask,
}

impl Placed<f32> {
    /// The transforms of an instance placed by `object_to_world`.
    fn of(object_to_world: &Affine3A) -> Self {
        let v = |a: Vec3A| V3::from(Vec3::from(a));
        let m = &object_to_world.matrix3;
        let n = m.inverse().transpose();
        Placed {
            cols: [v(m.x_axis), v(m.y_axis), v(m.z_axis)],
            translation: v(object_to_world.translation),
            normal: [v(n.x_axis), v(n.y_axis), v(n.z_axis)],
        }
    }
}

impl Placed<F32s> {
    /// Lane `i` holds `placed`.
    #[inline(always)]
    pub(crate) fn set(&mut self, i: usize, placed: &Placed<f32>) {
        for (lanes, &one) in self.cols.iter_mut().chain(self.normal.iter_mut()).zip(placed.cols.iter().chain(&placed.normal)) {
            lanes.set_lane(i, one);
        }
        self.translation.set_lane(i, placed.translation);
    }
}

impl<R: Real> Placed<R> {
    /// Linear part applied to `v`, summed as glam's `Mat3A * Vec3A`.
    #[inline(always)]
    fn apply(cols: &[V3<R>; 3], v: V3<R>) -> V3<R> {
        cols[0] * v.x + cols[1] * v.y + cols[2] * v.z
    }

    /// A point of the instance's mesh with its absolute error bound, and its geometric and
    /// shading normals, placed in world space: the transformed point, the transformed bound
    /// plus the rounding of the transform itself (pbrt-v4's bound for applying a transform to
    /// a point with error), the normals through the normal matrix made unit (the geometric one
    /// zero, and `ok` unset, where it cannot be; the shading one falling back to the geometric).
    #[inline(always)]
    fn place(&self, p: V3<R>, p_error: V3<R>, ng: V3<R>, ns: V3<R>) -> PlacedPoint<R> {
        let abs = self.cols.map(V3::abs);
        let g = gamma(3.0);
        let world = Self::apply(&self.cols, p) + self.translation;
        let error = Self::apply(&abs, p_error) * R::splat(g + 1.0) + (Self::apply(&abs, p.abs()) + self.translation.abs()) * R::splat(g);
        let (ng_unit, ok) = Self::apply(&self.normal, ng).try_normalize();
        let ng = ok.select(ng_unit, V3::splat(Vec3::ZERO));
        let (ns_unit, ns_ok) = Self::apply(&self.normal, ns).try_normalize();
        PlacedPoint { p: world, p_error: error, ng, ns: ns_ok.select(ns_unit, ng), ok }
    }

    /// A normal `n` in world space, made unit (`fallback` where it cannot be).
    #[inline(always)]
    fn normal_to_world(&self, n: V3<R>, fallback: V3<R>) -> V3<R> {
        let (unit, ok) = Self::apply(&self.normal, n).try_normalize();
        ok.select(unit, fallback)
    }
}

/// A sphere bounding the world bounds `(min, max)` (the box's centre and half-diagonal).
fn bounding_sphere(bounds: Option<(Vec3, Vec3)>) -> (Vec3, f32) {
    let Some((lo, hi)) = bounds else {
        return (Vec3::ZERO, 1.0);
    };
    let centre = 0.5 * (lo + hi);
    (centre, (0.5 * (hi - lo).length()).max(1e-3))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Material, Texture, TextureRef};
    use crate::scene::texture::Filter;
    use glam::Vec4;

    /// Axis-aligned unit quads facing +z at the given depths (x, y ∈ [0, 1], texture
    /// coordinates u = x, v = 1 − y), quad k with material k.
    fn quads(depths: &[f32], materials: Vec<Material>, textures: Vec<Texture>) -> SceneDescription {
        let mut g = Geometry::default();
        for (k, &z) in depths.iter().enumerate() {
            let base = g.positions.len() as u32;
            for (x, y) in [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)] {
                g.positions.push(Vec3::new(x, y, z));
                g.normals.push(Vec3::Z);
                g.uvs.push(Vec2::new(x, 1.0 - y));
                g.tangents.push(Vec4::new(1.0, 0.0, 0.0, 1.0));
            }
            g.triangles.extend([[base, base + 1, base + 2], [base, base + 2, base + 3]]);
            g.material_ids.extend([k as u32; 2]);
        }
        SceneDescription { source: "quads".into(), geometry: g, materials, textures, ..SceneDescription::default() }
    }

    /// A 2 × 1 texture: left texel `left`, right texel `right` (RGB and alpha).
    fn two_texels(left: (Rgb, f32), right: (Rgb, f32)) -> Texture {
        Texture::from_linear(2, 1, vec![left.0, right.0], vec![left.1, right.1])
    }

    fn nearest(texture: usize) -> TextureRef {
        TextureRef { filter: Filter::Nearest, ..TextureRef::new(texture) }
    }

    fn down_at(x: f32) -> Ray {
        Ray::new(Vec3::new(x, 0.5, 5.0), Vec3::NEG_Z)
    }

    /// A cut-out (alpha 0 on its left half) lets camera and shadow rays through there and
    /// stops them on its right half.
    #[test]
    fn masked_surfaces_pass_rays_where_alpha_is_below_the_cutoff() {
        let cutout = Material {
            base_color_texture: Some(nearest(0)),
            alpha_mode: AlphaMode::Mask { cutoff: 0.5 },
            ..Material::default_diffuse("cutout")
        };
        let scene = quads(&[1.0, 0.0], vec![cutout, Material::default_diffuse("back")], vec![two_texels((Rgb::ONE, 0.0), (Rgb::ONE, 1.0))]);
        let scene = RenderScene::new(scene).unwrap();
        let left = scene.intersect(&down_at(0.25)).expect("the back quad");
        assert_eq!(scene.geometry.material_ids[left.triangle as usize], 1);
        assert!((left.t - 5.0).abs() < 1e-5);
        let right = scene.intersect(&down_at(0.75)).expect("the cut-out");
        assert_eq!(scene.geometry.material_ids[right.triangle as usize], 0);
        let segment = |x: f32| Ray { t_max: 4.5, ..down_at(x) };
        assert!(!scene.occluded(&segment(0.25)), "shadow rays pass through the hole");
        assert!(scene.occluded(&segment(0.75)));
        let mut hits = Vec::new();
        scene.intersect_all(&[down_at(0.25), down_at(0.75)], &mut hits, 0);
        assert_eq!(hits, vec![Some(left), Some(right)]);
        let mut blocked = Vec::new();
        scene.occluded_all(&[segment(0.25), segment(0.75)], &mut blocked, 0);
        assert_eq!(blocked, vec![false, true]);
    }

    /// Partial coverage stops a fraction alpha of rays, the same ray always the same way.
    #[test]
    fn blended_surfaces_stop_a_fraction_alpha_of_rays() {
        let glass = Material { base_alpha: 0.25, alpha_mode: AlphaMode::Blend, ..Material::default_diffuse("veil") };
        let scene = RenderScene::new(quads(&[1.0], vec![glass], Vec::new())).unwrap();
        let n = 20_000;
        let rays: Vec<Ray> = (0..n).map(|i| down_at((i as f32 + 0.5) / n as f32)).collect();
        let stopped = rays.iter().filter(|r| scene.intersect(r).is_some()).count();
        let fraction = stopped as f64 / n as f64;
        assert!((fraction - 0.25).abs() < 0.015, "{fraction}");
        assert!(rays.iter().all(|r| scene.intersect(r).is_some() == scene.occluded(r)), "one decision per ray");
    }

    /// A normal map bends the shading normal in the tangent frame, scaled in x and y by
    /// its scale; without one the interpolated normal is kept.
    #[test]
    fn normal_maps_bend_the_shading_normal() {
        // Texel (0.8, 0.5, 0.9) encodes the tangent-space normal (0.6, 0, 0.8).
        let texture = Texture::from_linear(1, 1, vec![Rgb::new(0.8, 0.5, 0.9)], Vec::new());
        let material = |scale| Material { normal_texture: Some(NormalMap { texture: TextureRef::new(0), scale }), ..Material::default_diffuse("bumpy") };
        let scene = quads(&[0.0, -1.0, -2.0], vec![material(1.0), material(0.5), Material::default_diffuse("flat")], vec![texture]);
        let scene = RenderScene::new(scene).unwrap();
        let ray = down_at(0.3);
        let expected = [Vec3::new(0.6, 0.0, 0.8), Vec3::new(0.3, 0.0, 0.8).normalize(), Vec3::Z];
        for (k, n) in expected.into_iter().enumerate() {
            let hit = Hit { t: 5.0 + k as f32, triangle: 2 * k as u32, barycentric: Vec2::new(0.3, 0.3), instance: NO_INSTANCE };
            let sp = scene.surface_point(&hit, ray.direction).unwrap();
            assert!(sp.frame.n.abs_diff_eq(n, 1e-5), "quad {k}: {} vs {n}", sp.frame.n);
            assert_eq!(sp.ng, Vec3::Z);
        }
        // Seen from behind (double-sided), the bent normal turns to the viewer's side.
        let sp = scene.surface_point(&Hit { t: 5.0, triangle: 0, barycentric: Vec2::new(0.3, 0.3), instance: NO_INSTANCE }, Vec3::Z).unwrap();
        assert!(sp.frame.n.abs_diff_eq(-Vec3::new(0.6, 0.0, 0.8), 1e-5), "{}", sp.frame.n);
    }

    /// A bump facing away from a grazing viewer is tilted so the viewer stays above it.
    #[test]
    fn normal_maps_keep_the_viewer_above_the_shading_normal() {
        let n = Vec3::new(-0.6, 0.0, 0.8);
        let wo = Vec3::new(0.99, 0.0, 0.141).normalize();
        assert!(n.dot(wo) < 0.0);
        let keep = |n: Vec3| Vec3::from(keep_viewer_above::<f32>(n.into(), wo.into(), Vec3::Z.into()));
        let tilted = keep(n);
        assert!((0.01..0.02).contains(&tilted.dot(wo)) && (tilted.length() - 1.0).abs() < 1e-6, "{tilted}");
        assert_eq!(keep(Vec3::Z), Vec3::Z, "a normal the viewer sees is kept");
    }

    /// An emissive texture scales the emission seen by rays and sampled by lights, and
    /// the light's selection weight follows its mean.
    #[test]
    fn emissive_textures_vary_emission_over_the_surface() {
        let red_blue = Texture::from_linear(2, 1, vec![Rgb::new(1.0, 0.0, 0.0), Rgb::new(0.0, 0.0, 1.0)], Vec::new());
        let lamp = Material { emission: Rgb::splat(2.0), emissive_texture: Some(nearest(0)), ..Material::default_diffuse("lamp") };
        let scene = RenderScene::new(quads(&[0.0], vec![lamp], vec![red_blue])).unwrap();
        let at = |x: f32| {
            let hit = scene.intersect(&down_at(x)).unwrap();
            scene.emission(&scene.surface_point(&hit, Vec3::NEG_Z).unwrap(), Vec3::Z)
        };
        assert_eq!(at(0.25), Rgb::new(2.0, 0.0, 0.0));
        assert_eq!(at(0.75), Rgb::new(0.0, 0.0, 2.0));
        // Light samples from a point above the lamp carry the texel where they land.
        let p = Vec3::new(0.5, 0.5, 1.0);
        let (mut red, mut blue) = (0, 0);
        for i in 0..64 {
            for j in 0..64 {
                let u = Vec2::new((i as f32 + 0.5) / 64.0, (j as f32 + 0.5) / 64.0);
                let s = scene.lights.sample(p, 0.5, u).expect("lamp sample");
                let q = p + s.direction * s.distance;
                let expected = if q.x < 0.5 { Rgb::new(2.0, 0.0, 0.0) } else { Rgb::new(0.0, 0.0, 2.0) };
                assert_eq!(s.radiance, expected, "at {q}");
                if q.x < 0.5 { red += 1 } else { blue += 1 }
            }
        }
        assert!(red > 1000 && blue > 1000, "{red} {blue}");
    }
}
