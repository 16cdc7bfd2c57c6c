//! Wavefront OBJ/MTL loader (via `tobj`: faces triangulated, one index per vertex).
//!
//! OBJ files are taken as world space, y up, counter-clockwise fronts; texture coordinates
//! are flipped to glTF's convention (v down). Objects without normals get area-weighted
//! smooth vertex normals ([`super::smooth_vertex_normals`]). OBJ has no cameras or lights:
//! `cameras` and `lights` stay empty (see [`SceneDescription::camera_or_default`]).
//!
//! MTL materials become:
//! - `Kd` → [`Material::base_color`] (0.8 grey when absent), `map_Kd` →
//!   [`Material::base_color_texture`] (path relative to the OBJ file's directory, decoded
//!   from sRGB as for glTF);
//! - [`SurfaceModel::Lambert`] when `Ks` is absent or zero; otherwise
//!   [`SurfaceModel::MetallicRoughness`] (metallic 0) with the Phong exponent `Ns` mapped to
//!   the GGX width by Walter et al. 2007's Phong–Beckmann relation α = sqrt(2 / (Ns + 2)),
//!   so the perceptual roughness is sqrt(α) (α = roughness², see [`Material::roughness`]);
//!   `Ks`'s colour itself is not used (the dielectric F0 is the model's 0.04);
//! - `Ke` → [`Material::emission`];
//! - every material double-sided (OBJ cannot say otherwise).
//!
//! Faces without a material get [`Material::default_diffuse`] (named "default"). A missing
//! OBJ or MTL file is [`Error::Io`] naming it; a malformed one is [`Error::InvalidFile`].

use super::{smooth_vertex_normals, Geometry, Material, SceneDescription, SurfaceModel, Texture};
use crate::{Error, Result, Rgb};
use glam::{Vec2, Vec3};
use std::cell::RefCell;
use std::io::Cursor;
use std::path::Path;

/// Loads an OBJ file and the MTL libraries it names (see the module documentation).
pub fn load(path: &Path) -> Result<SceneDescription> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let base = path.parent().unwrap_or_else(|| Path::new(""));
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ..tobj::LoadOptions::default()
    };
    let mtl_error: RefCell<Option<Error>> = RefCell::new(None);
    let parsed = tobj::load_obj_buf(&mut Cursor::new(bytes), &options, |mtl: &Path| {
        let mtl_path = base.join(mtl);
        let result = match std::fs::read(&mtl_path) {
            Ok(mtl_bytes) => tobj::load_mtl_buf(&mut Cursor::new(mtl_bytes)).map_err(|e| {
                Error::invalid_file(&mtl_path, format!("cannot parse material library: {e}"))
            }),
            Err(e) => Err(Error::io(&mtl_path, e)),
        };
        result.map_err(|error| {
            mtl_error.replace(Some(error));
            tobj::LoadError::OpenFileFailed
        })
    });
    if let Some(error) = mtl_error.into_inner() {
        return Err(error);
    }
    let (models, obj_materials) =
        parsed.map_err(|e| Error::invalid_file(path, format!("cannot parse OBJ: {e}")))?;
    let obj_materials = obj_materials
        .map_err(|e| Error::invalid_file(path, format!("cannot load its materials: {e}")))?;

    let mut scene = SceneDescription {
        source: path.to_path_buf(),
        ..SceneDescription::default()
    };
    for m in &obj_materials {
        let material = convert_material(m, path, base, &mut scene.textures)?;
        scene.materials.push(material);
    }
    let mut default_material = None;
    for model in &models {
        let mesh = &model.mesh;
        let material_id = match mesh.material_id {
            Some(id) if id < scene.materials.len() => id,
            Some(id) => {
                return Err(Error::invalid_file(
                    path,
                    format!(
                        "object '{}' uses material {id}, which is not defined",
                        model.name
                    ),
                ))
            }
            None => *default_material.get_or_insert_with(|| {
                scene.materials.push(Material::default_diffuse("default"));
                scene.materials.len() - 1
            }),
        };
        let part = convert_mesh(&model.name, mesh, material_id, path)?;
        scene.geometry.append(&part, path)?;
    }
    scene.validate()?;
    Ok(scene)
}

/// One `tobj` mesh as geometry with its own vertex indices.
fn convert_mesh(
    name: &str,
    mesh: &tobj::Mesh,
    material_id: usize,
    path: &Path,
) -> Result<Geometry> {
    let invalid = |reason: String| Error::invalid_file(path, reason);
    let positions: Vec<Vec3> = mesh
        .positions
        .chunks_exact(3)
        .map(|p| Vec3::new(p[0], p[1], p[2]))
        .collect();
    if positions.iter().any(|p| !p.is_finite()) {
        return Err(invalid(format!(
            "non-finite vertex position in object '{name}'"
        )));
    }
    let n = positions.len();
    if !mesh.indices.len().is_multiple_of(3) {
        return Err(invalid(format!(
            "object '{name}' has a face that is not a triangle"
        )));
    }
    if let Some(&bad) = mesh.indices.iter().find(|&&i| i as usize >= n) {
        return Err(invalid(format!(
            "object '{name}' has vertex index {bad} of {n}"
        )));
    }
    let triangles: Vec<[u32; 3]> = mesh
        .indices
        .chunks_exact(3)
        .map(|t| [t[0], t[1], t[2]])
        .collect();
    let smooth = || smooth_vertex_normals(&positions, &triangles);
    let normals: Vec<Vec3> = if mesh.normals.len() == 3 * n {
        let given: Vec<Option<Vec3>> = mesh
            .normals
            .chunks_exact(3)
            .map(|v| Vec3::new(v[0], v[1], v[2]).try_normalize())
            .collect();
        if given.iter().all(Option::is_some) {
            given.into_iter().flatten().collect()
        } else {
            given
                .into_iter()
                .zip(smooth())
                .map(|(g, s)| g.unwrap_or(s))
                .collect()
        }
    } else {
        smooth()
    };
    let uvs: Vec<Vec2> = if mesh.texcoords.len() == 2 * n {
        mesh.texcoords
            .chunks_exact(2)
            .map(|t| Vec2::new(t[0], 1.0 - t[1]))
            .collect()
    } else {
        vec![Vec2::ZERO; n]
    };
    let material_id =
        u32::try_from(material_id).map_err(|_| invalid("too many materials".into()))?;
    Ok(Geometry {
        material_ids: vec![material_id; triangles.len()],
        positions,
        normals,
        uvs,
        triangles,
    })
}

/// One MTL material (see the module documentation for the mapping); its `map_Kd` texture is
/// decoded and pushed onto `textures`.
fn convert_material(
    m: &tobj::Material,
    path: &Path,
    base: &Path,
    textures: &mut Vec<Texture>,
) -> Result<Material> {
    let base_color = m.diffuse.map_or(Rgb::splat(0.8), Rgb::from_array);
    let specular = m.specular.is_some_and(|ks| ks.iter().any(|&c| c > 0.0));
    let (model, roughness) = if specular {
        let ns = m.shininess.unwrap_or(0.0).max(0.0);
        (
            SurfaceModel::MetallicRoughness,
            phong_exponent_to_roughness(ns),
        )
    } else {
        (SurfaceModel::Lambert, 1.0)
    };
    let base_color_texture = match m.diffuse_texture.as_deref() {
        Some(file) if !file.is_empty() => {
            let texture_path = base.join(file);
            let bytes = std::fs::read(&texture_path).map_err(|e| Error::io(&texture_path, e))?;
            let what = format!("texture '{file}' of material '{}'", m.name);
            textures.push(Texture::from_encoded_srgb(&bytes, &texture_path, &what)?);
            Some(textures.len() - 1)
        }
        _ => None,
    };
    let emission = m.emissive.map_or(Rgb::ZERO, Rgb::from_array);
    if !base_color.is_finite() || !emission.is_finite() {
        return Err(Error::invalid_file(
            path,
            format!("material '{}' has non-finite colours", m.name),
        ));
    }
    Ok(Material {
        name: m.name.clone(),
        model,
        base_color,
        base_color_texture,
        metallic: 0.0,
        roughness,
        emission,
        double_sided: true,
    })
}

/// Perceptual GGX roughness for a Phong exponent: α = sqrt(2 / (Ns + 2)) (Walter et al.
/// 2007), roughness = sqrt(α), in (0, 1].
fn phong_exponent_to_roughness(ns: f32) -> f32 {
    (2.0 / (ns + 2.0)).sqrt().sqrt().clamp(0.0, 1.0)
}
