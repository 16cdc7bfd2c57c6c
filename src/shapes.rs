//! Procedural triangle meshes for test scenes.

use glam::{Vec2, Vec3};
use renderer::scene::{EnvironmentSource, EnvironmentSpec, Geometry, Material, SceneDescription};
use renderer::Rgb;
use std::f32::consts::PI;

/// Appends a UV sphere to `geometry` with every triangle using `material`. With `inward`
/// the front faces (counter-clockwise) and normals point toward the centre.
pub fn add_sphere(geometry: &mut Geometry, centre: Vec3, radius: f32, stacks: u32, slices: u32, inward: bool, material: u32) {
    let base = geometry.positions.len() as u32;
    for i in 0..=stacks {
        let theta = PI * i as f32 / stacks as f32;
        for j in 0..=slices {
            let phi = 2.0 * PI * j as f32 / slices as f32;
            // Exact poles, so the collapsed triangles there are exactly degenerate.
            let (st, ct) = if i == 0 || i == stacks { (0.0, theta.cos().signum()) } else { theta.sin_cos() };
            let n = Vec3::new(st * phi.cos(), ct, st * phi.sin());
            geometry.positions.push(centre + radius * n);
            geometry.normals.push(if inward { -n } else { n });
            geometry.uvs.push(Vec2::new(j as f32 / slices as f32, i as f32 / stacks as f32));
        }
    }
    let row = slices + 1;
    for i in 0..stacks {
        for j in 0..slices {
            let (a, b, c, d) = (base + i * row + j, base + i * row + j + 1, base + (i + 1) * row + j, base + (i + 1) * row + j + 1);
            // Outward-facing counter-clockwise order is (a, b, c), (b, d, c).
            let quads = [[a, b, c], [b, d, c]];
            for [x, y, z] in quads {
                let p = |k: u32| geometry.positions[k as usize];
                if (p(y) - p(x)).cross(p(z) - p(x)).length_squared() == 0.0 {
                    continue; // the collapsed triangles at the poles
                }
                geometry.triangles.push(if inward { [x, z, y] } else { [x, y, z] });
                geometry.material_ids.push(material);
            }
        }
    }
}

/// Appends an axis-aligned square in the plane y = `height`, of half-size `half`, facing +y.
pub fn add_floor(geometry: &mut Geometry, height: f32, half: f32, material: u32) {
    let base = geometry.positions.len() as u32;
    for (x, z) in [(-half, -half), (half, -half), (half, half), (-half, half)] {
        geometry.positions.push(Vec3::new(x, height, z));
        geometry.normals.push(Vec3::Y);
        geometry.uvs.push(Vec2::ZERO);
    }
    geometry.triangles.push([base, base + 2, base + 1]);
    geometry.triangles.push([base, base + 3, base + 2]);
    geometry.material_ids.extend([material, material]);
}

/// A furnace: a unit sphere at the origin (`stacks` × `slices`, outward) made of `material`
/// under a uniform environment of radiance 1.
pub fn sphere_in_furnace(material: Material, stacks: u32, slices: u32) -> SceneDescription {
    let mut geometry = Geometry::default();
    add_sphere(&mut geometry, Vec3::ZERO, 1.0, stacks, slices, false, 0);
    SceneDescription {
        geometry,
        materials: vec![material],
        environment: Some(EnvironmentSpec {
            source: EnvironmentSource::Constant(Rgb::ONE),
            strength: 1.0,
            rotation: 0.0,
        }),
        ..SceneDescription::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sphere_winding_matches_normals() {
        for inward in [false, true] {
            let mut g = Geometry::default();
            add_sphere(&mut g, Vec3::ZERO, 2.0, 8, 16, inward, 0);
            for i in 0..g.triangle_count() {
                let [a, b, c] = g.triangle_positions(i);
                let n = (b - a).cross(c - a);
                let centroid = (a + b + c) / 3.0;
                let outward = n.dot(centroid) > 0.0;
                assert_eq!(outward, !inward, "triangle {i}");
            }
        }
    }
}
