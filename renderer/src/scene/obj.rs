//! Wavefront OBJ/MTL loader (via `tobj`: faces triangulated, one index per vertex; point
//! and line elements skipped).
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

use super::{smooth_vertex_normals, Geometry, Material, SceneDescription, SurfaceModel, Texture, TextureRef};
use crate::{Error, Result, Rgb};
use glam::{Vec2, Vec3};
use std::cell::RefCell;
use std::io::Cursor;
use std::path::Path;

/// Loads an OBJ file and the MTL libraries it names (see the module documentation).
pub fn load(path: &Path) -> Result<SceneDescription> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    load_from_bytes(&bytes, path)
}

/// Loads an OBJ scene from the contents of an OBJ file. `path` is where the bytes came from:
/// errors name it, and the MTL libraries and textures it names are read from disk relative
/// to its directory.
pub fn load_from_bytes(bytes: &[u8], path: &Path) -> Result<SceneDescription> {
    load_from_bytes_with(bytes, path, |file| std::fs::read(file))
}

/// Like [`load_from_bytes`], but the files the OBJ file refers to (MTL libraries and their
/// textures) are read by `read_file`, given their path (the OBJ file's directory joined with
/// the name in the file), instead of from disk; an error it returns becomes [`Error::Io`]
/// naming that path. Lets a scene and its files come from memory (tests, fuzzing).
pub fn load_from_bytes_with(
    bytes: &[u8],
    path: &Path,
    read_file: impl FnMut(&Path) -> std::io::Result<Vec<u8>>,
) -> Result<SceneDescription> {
    let base = path.parent().unwrap_or_else(|| Path::new(""));
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ignore_points: true,
        ignore_lines: true,
    };
    check_face_indices(bytes, path)?;
    let mtl_error: RefCell<Option<Error>> = RefCell::new(None);
    // tobj asks for a `Fn` material loader.
    let read_cell = RefCell::new(read_file);
    let parsed = tobj::load_obj_buf(&mut Cursor::new(bytes), &options, |mtl: &Path| {
        let mtl_path = base.join(mtl);
        let result = match (read_cell.borrow_mut())(&mtl_path) {
            Ok(mtl_bytes) => check_mtl_colours(&mtl_bytes, &mtl_path).and_then(|()| {
                tobj::load_mtl_buf(&mut Cursor::new(mtl_bytes)).map_err(|e| {
                    Error::invalid_file(&mtl_path, format!("cannot parse material library: {e}"))
                })
            }),
            Err(e) => Err(Error::io(&mtl_path, e)),
        };
        result.map_err(|error| {
            mtl_error.replace(Some(error));
            tobj::LoadError::OpenFileFailed
        })
    });
    let mut read_file = read_cell.into_inner();
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
        let material = convert_material(m, path, base, &mut scene.textures, &mut read_file)?;
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

/// Rejects face (`f`) and line (`l`) elements whose indices `tobj` 4.0 would turn into
/// absurd `usize` values: a relative (negative) index reaching before the first vertex,
/// texture coordinate or normal, and an index larger than the file could hold. `tobj`
/// computes such indices with wrapping casts and then multiplies them (an overflow panic
/// in debug builds, a wrong look-up or an out-of-bounds panic otherwise).
fn check_face_indices(obj: &[u8], path: &Path) -> Result<()> {
    const KINDS: [&str; 3] = ["vertex", "texture coordinate", "normal"];
    let largest = obj.len() as i128;
    let mut counts = [0i128; 3];
    for (number, line) in obj.split(|&b| b == b'\n').enumerate() {
        let line = String::from_utf8_lossy(line);
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => counts[0] += 1,
            Some("vt") => counts[1] += 1,
            Some("vn") => counts[2] += 1,
            Some("f" | "l") => {
                for element in words {
                    for (k, part) in element.split('/').take(3).enumerate() {
                        // Unparsable parts are left to tobj, which reports them.
                        let Ok(index) = part.parse::<isize>() else {
                            continue;
                        };
                        let index = index as i128;
                        if index > largest || counts[k] + index < 0 {
                            return Err(Error::invalid_file(
                                path,
                                format!(
                                    "cannot parse OBJ: line {}: {} index {index} out of range ({} defined before it)",
                                    number + 1,
                                    KINDS[k],
                                    counts[k]
                                ),
                            ));
                        }
                    }
                }
            }
            _ => {}
        }
    }
    Ok(())
}

/// Rejects MTL colour lines (`Ka`, `Kd`, `Ks`, `Ke`) with fewer than three values, which
/// make `tobj` 4.0 panic (an unwrap in its `parse_float3`) instead of returning an error.
fn check_mtl_colours(mtl: &[u8], mtl_path: &Path) -> Result<()> {
    for (number, line) in mtl.split(|&b| b == b'\n').enumerate() {
        let line = String::from_utf8_lossy(line);
        let mut words = line.split_whitespace();
        if let Some(key @ ("Ka" | "Kd" | "Ks" | "Ke")) = words.next() {
            if words.count() < 3 {
                return Err(Error::invalid_file(
                    mtl_path,
                    format!(
                        "cannot parse material library: line {}: '{key}' needs three numbers",
                        number + 1
                    ),
                ));
            }
        }
    }
    Ok(())
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
        uvs1: Vec::new(),
        tangents: Vec::new(),
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
    read_file: &mut dyn FnMut(&Path) -> std::io::Result<Vec<u8>>,
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
            let bytes = read_file(&texture_path).map_err(|e| Error::io(&texture_path, e))?;
            let what = format!("texture '{file}' of material '{}'", m.name);
            textures.push(Texture::from_encoded_srgb(&bytes, &texture_path, &what)?);
            Some(TextureRef::new(textures.len() - 1))
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
        metallic_roughness_texture: None,
        metallic: 0.0,
        roughness,
        emission,
        double_sided: true,
        ..Material::default_diffuse("")
    })
}

/// Perceptual GGX roughness for a Phong exponent: α = sqrt(2 / (Ns + 2)) (Walter et al.
/// 2007), roughness = sqrt(α), in (0, 1].
fn phong_exponent_to_roughness(ns: f32) -> f32 {
    (2.0 / (ns + 2.0)).sqrt().sqrt().clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    const OBJ: &str = "mtllib scene.mtl
o plain
v 0 0 5
v 1 0 5
v 0 1 5
f 1 2 3
o floor
v -1 0 -1
v 1 0 -1
v 1 0 1
v -1 0 1
vt 0 0
vt 1 0
vt 1 1
vt 0 1
usemtl matte
f 7/4 6/3 5/2 4/1
o lamp
v 0 2 0
v 1 2 0
v 0 2 1
vn 0 -1 0
usemtl light
f 8//1 10//1 9//1
o shiny
v 0 1 0
v 1 1 0
v 0 1.5 0
usemtl glossy
f 11 12 13
";

    const MTL: &str = "newmtl matte
Kd 0.5 0.25 0.125
Ks 0 0 0
newmtl light
Kd 0 0 0
Ke 10 9 8
newmtl glossy
Kd 0.1 0.2 0.3
Ks 0.5 0.5 0.5
Ns 98
";

    fn write_files(dir: &Path, obj: &str, mtl: Option<&str>) -> std::path::PathBuf {
        let path = dir.join("scene.obj");
        std::fs::write(&path, obj).expect("write obj");
        if let Some(mtl) = mtl {
            std::fs::write(dir.join("scene.mtl"), mtl).expect("write mtl");
        }
        path
    }

    #[test]
    fn obj_with_mtl_loads() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = write_files(dir.path(), OBJ, Some(MTL));
        let scene = SceneDescription::load(&path).expect("load");
        let g = &scene.geometry;
        assert_eq!(g.triangle_count(), 5);
        assert!(scene.cameras.is_empty() && scene.lights.is_empty());
        let by_name = |name: &str| {
            scene
                .materials
                .iter()
                .find(|m| m.name == name)
                .unwrap_or_else(|| panic!("material {name}"))
        };
        let matte = by_name("matte");
        assert_eq!(matte.model, SurfaceModel::Lambert);
        assert_eq!(matte.base_color, Rgb::new(0.5, 0.25, 0.125));
        let light = by_name("light");
        assert_eq!(light.emission, Rgb::new(10.0, 9.0, 8.0));
        let glossy = by_name("glossy");
        assert_eq!(glossy.model, SurfaceModel::MetallicRoughness);
        assert!((glossy.roughness - 0.02f32.sqrt().sqrt()).abs() < 1e-6);
        assert_eq!(glossy.metallic, 0.0);
        // The floor quad (two triangles) faces +y, computed smooth normals agree.
        for t in 1..3 {
            let [a, b, c] = g.triangle_positions(t);
            assert!((b - a).cross(c - a).normalize().abs_diff_eq(Vec3::Y, 1e-6));
            let [i, _, _] = g.triangles[t];
            assert!(g.normals[i as usize].abs_diff_eq(Vec3::Y, 1e-6));
        }
        // v is flipped to glTF's convention: the vertex with vt 0 1 gets uv (0, 0).
        let corner = g
            .positions
            .iter()
            .position(|p| *p == Vec3::new(-1.0, 0.0, 1.0))
            .expect("corner");
        assert_eq!(g.uvs[corner], Vec2::new(0.0, 0.0));
        // The lamp's file normals are kept.
        let lamp = g
            .material_ids
            .iter()
            .position(|&m| scene.materials[m as usize].name == "light");
        let [i, _, _] = g.triangles[lamp.expect("lamp triangle")];
        assert_eq!(g.normals[i as usize], Vec3::NEG_Y);
        // Faces before any "usemtl" get the default material.
        assert_eq!(scene.materials[g.material_ids[0] as usize].name, "default");
    }

    #[test]
    fn obj_without_materials_gets_the_default() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = write_files(dir.path(), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", None);
        let scene = load(&path).expect("load");
        assert_eq!(scene.materials.len(), 1);
        assert_eq!(scene.materials[0].name, "default");
        assert_eq!(scene.geometry.normals, vec![Vec3::Z; 3]);
        let camera = scene.camera_or_default(None, None).expect("default camera");
        assert_eq!(camera.name, "default");
    }

    #[test]
    fn missing_obj_and_mtl_files_are_io_errors() {
        let dir = tempfile::tempdir().expect("tempdir");
        let missing = dir.path().join("none.obj");
        let error = load(&missing).expect_err("missing obj");
        assert!(
            matches!(error, Error::Io { ref path, .. } if path == &missing),
            "{error}"
        );
        let path = write_files(dir.path(), OBJ, None);
        let error = load(&path).expect_err("missing mtl");
        assert!(
            matches!(error, Error::Io { ref path, .. } if path.ends_with("scene.mtl")),
            "{error}"
        );
    }

    #[test]
    fn bad_obj_input_is_an_invalid_file() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = write_files(dir.path(), "v 0 0 0\nv 1 0 0\nf 1 2 7\n", None);
        let message = load(&path).expect_err("bad index").to_string();
        assert!(
            message.starts_with(&path.display().to_string()),
            "{message}"
        );
        let path = write_files(dir.path(), "v 0 0 0\nv 1 0 0\n", None);
        let message = load(&path).expect_err("no faces").to_string();
        assert!(message.contains("contains no triangles"), "{message}");
        let path = write_files(dir.path(), "v 0 0 0\nv inf 0 0\nv 0 1 0\nf 1 2 3\n", None);
        let message = load(&path).expect_err("inf").to_string();
        assert!(
            message.contains("non-finite vertex position in object"),
            "{message}"
        );
    }

    #[test]
    fn phong_exponent_maps_to_walter_roughness() {
        assert_eq!(phong_exponent_to_roughness(0.0), 1.0);
        let r = phong_exponent_to_roughness(98.0);
        assert!((r * r - (2.0f32 / 100.0).sqrt()).abs() < 1e-6);
    }
}
