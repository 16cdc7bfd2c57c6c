//! Tests of the glTF loader.

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

/// Intensities are photometric (cd for point and spot, lx for directional, as the
/// specification says) and become radiometric at 683 lm/W: Blender writes its 3 W/m² sun as
/// 2,049 lx.
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
            {"type": "point", "color": [1.0, 0.5, 0.25], "intensity": 2732.0},
            {"type": "spot", "intensity": 6830.0, "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.5}},
            {"type": "directional", "color": [0.5, 0.5, 0.5], "intensity": 2049.0}
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

/// `KHR_materials_transmission` and `KHR_materials_volume`: the factor is read; a volume
/// with thickness > 0 gives σa = −ln(colour) / distance (zero for the default infinite
/// distance); thickness 0 or no volume is thin-walled; bad values are errors naming the
/// material.
#[test]
fn transmission_and_volume_are_read() {
    let doc = material_doc(json!([
        {"name": "thin", "extensions": {"KHR_materials_transmission": {"transmissionFactor": 0.75}}},
        {"name": "solid", "extensions": {
            "KHR_materials_transmission": {"transmissionFactor": 1.0},
            "KHR_materials_volume": {"thicknessFactor": 0.1, "attenuationColor": [0.5, 0.25, 1.0], "attenuationDistance": 2.0}}},
        {"name": "clear", "extensions": {
            "KHR_materials_transmission": {"transmissionFactor": 1.0},
            "KHR_materials_volume": {"thicknessFactor": 1.0}}},
        {"name": "zero-thickness", "extensions": {"KHR_materials_volume": {"thicknessFactor": 0.0}}}
    ]));
    let scene = load_doc(&doc).expect("load");
    let by_name = |n: &str| scene.materials.iter().find(|m| m.name == n).unwrap();
    assert_eq!((by_name("thin").transmission, by_name("thin").volume), (0.75, None));
    let sigma = by_name("solid").volume.unwrap().sigma_a;
    let expected = Rgb::new(0.5f32.ln(), 0.25f32.ln(), 0.0) / -2.0;
    assert!((sigma - expected).abs().max_element() < 1e-6, "{sigma}");
    assert_eq!(by_name("clear").volume.unwrap().sigma_a, Rgb::ZERO);
    assert_eq!(by_name("zero-thickness").volume, None);
    assert!(by_name("thin").transmits() && !by_name("zero-thickness").transmits());

    for (extension, problem) in [
        (json!({"KHR_materials_transmission": {"transmissionFactor": 1.5}}), "transmission factor 1.5"),
        (json!({"KHR_materials_volume": {"thicknessFactor": 1.0, "attenuationDistance": -1.0}}), "invalid KHR_materials_volume"),
        (json!({"KHR_materials_volume": {"thicknessFactor": 1.0, "attenuationColor": [0.0, 1.0, 1.0]}}), "invalid KHR_materials_volume"),
        (json!({"KHR_materials_volume": {"thicknessFactor": -1.0}}), "thicknessFactor -1"),
    ] {
        let doc = material_doc(json!([{"name": "bad", "extensions": extension}]));
        let message = expect_error(&doc, problem);
        assert!(message.contains("'bad'"), "{message}");
    }
}

/// `KHR_materials_clearcoat` and `KHR_materials_sheen` (read from the JSON): factors,
/// textures with their texCoord and transform, the coat's normal map and its scale; a zero
/// coat or black sheen is no layer; bad values are errors naming the material.
#[test]
fn clearcoat_and_sheen_are_read() {
    let mut doc = material_doc(json!([
        {"name": "coated", "extensions": {"KHR_materials_clearcoat": {
            "clearcoatFactor": 0.75, "clearcoatRoughnessFactor": 0.25,
            "clearcoatTexture": {"index": 0}, "clearcoatRoughnessTexture": {"index": 0, "texCoord": 1},
            "clearcoatNormalTexture": {"index": 0, "scale": 0.5, "extensions": {"KHR_texture_transform": {"scale": [2.0, 2.0]}}}}}},
        {"name": "velvet", "extensions": {"KHR_materials_sheen": {
            "sheenColorFactor": [0.5, 0.25, 1.0], "sheenRoughnessFactor": 0.6, "sheenColorTexture": {"index": 0}}}},
        {"name": "none", "extensions": {"KHR_materials_clearcoat": {"clearcoatFactor": 0.0}, "KHR_materials_sheen": {}}}
    ]));
    doc["textures"] = json!([{"source": 0}]);
    doc["images"] = json!([{"uri": format!("data:image/png;base64,{}", base64(&two_texel_png()))}]);
    let scene = load_doc(&doc).expect("load");
    let by_name = |n: &str| scene.materials.iter().find(|m| m.name == n).unwrap();
    let coat = by_name("coated").clearcoat.expect("coat");
    assert_eq!((coat.factor, coat.roughness), (0.75, 0.25));
    assert!(coat.texture.is_some());
    assert_eq!(coat.roughness_texture.unwrap().tex_coord, 1);
    let normal = coat.normal_texture.expect("coat normal map");
    assert_eq!(normal.scale, 0.5);
    assert_ne!(normal.texture.transform, crate::scene::TextureRef::new(0).transform, "the texture transform is read");
    let sheen = by_name("velvet").sheen.expect("sheen");
    assert_eq!((sheen.color, sheen.roughness), (Rgb::new(0.5, 0.25, 1.0), 0.6));
    assert!(sheen.color_texture.is_some() && sheen.roughness_texture.is_none());
    assert!(by_name("none").clearcoat.is_none() && by_name("none").sheen.is_none());

    for (extension, problem) in [
        (json!({"KHR_materials_clearcoat": {"clearcoatFactor": 2.0}}), "clearcoatFactor 2"),
        (json!({"KHR_materials_clearcoat": {"clearcoatFactor": 1.0, "clearcoatTexture": {"index": 7}}}), "names texture 7"),
        (json!({"KHR_materials_sheen": {"sheenColorFactor": [1.0, 0.5]}}), "sheenColorFactor"),
        (json!({"KHR_materials_sheen": {"sheenColorFactor": [1.0, 1.0, 1.0], "sheenRoughnessFactor": "rough"}}), "sheenRoughnessFactor"),
    ] {
        let doc = material_doc(json!([{"name": "bad", "extensions": extension}]));
        let message = expect_error(&doc, problem);
        assert!(message.contains("'bad'"), "{message}");
    }
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
        "material 'x' extras: give only one of bsdf, neural",
    );
    let unknown = material_doc(json!([{"name": "y", "extras": {"bsdf": "glass"}}]));
    expect_error(&unknown, "unknown bsdf 'glass'");
    let bad = material_doc(json!([{"name": "z", "extras": {"brdf": "phong:x"}}]));
    expect_error(&bad, "material 'z' extras: BRDF binding kind 'phong:x' not found");
}

/// The object forms of `extras.neural`: a mixture weighted by a texture, a latent blend
/// along one channel, a tinted code (any with a tint), tables and networks as parts; every
/// bad form is a one-line error naming the file and the material.
#[test]
fn neural_extras_objects_vary_codes_with_textures() {
    use crate::scene::{Varying, VaryingForm};
    let forms = json!([
        {"name": "worn", "extras": {"neural": {"mix": ["gold-paint", "merl:t/rust.binary", "neural:chrome"], "weights": {"index": 0, "texCoord": 1}}}},
        {"name": "ramp", "extras": {"neural": {"blend": ["gold-paint", "neural:chrome"], "t": {"index": 0}, "channel": 3, "tint": {"index": 0}}}},
        {"name": "painted", "extras": {"neural": {"code": "gold-paint", "tint": {"index": 0, "extensions": {"KHR_texture_transform": {"scale": [4.0, 4.0]}}}}}},
        {"name": "plain", "extras": {"neural": {"code": "nbrdf:/abs/net"}}}
    ]);
    let dir = tempfile::tempdir().expect("tempdir");
    let with_texture = |materials: Value| {
        let mut doc = material_doc(materials);
        doc["textures"] = json!([{"source": 0}]);
        doc["images"] = json!([{"uri": format!("data:image/png;base64,{}", base64(&two_texel_png()))}]);
        doc
    };
    let mut doc = with_texture(forms);
    let prims: Vec<Value> = (0..4).map(|m| json!({"attributes": {"POSITION": 0}, "material": m})).collect();
    doc["meshes"][0]["primitives"] = json!(prims);
    let scene = load(&write(dir.path(), "scene.gltf", &doc)).expect("load");
    let varying = |i: usize| match &scene.materials[i].model {
        SurfaceModel::Varying(v) => v.clone(),
        other => panic!("material {i}: {other:?}"),
    };
    let Varying { form: VaryingForm::Mix { parts, weights }, tint: None } = varying(0) else { panic!("{:?}", varying(0)) };
    assert_eq!(parts, vec![Binding::Neural("gold-paint".into()), Binding::Merl(dir.path().join("t/rust.binary")), Binding::Neural("chrome".into())]);
    assert_eq!(weights.tex_coord, 1);
    let Varying { form: VaryingForm::Blend { ends, channel, .. }, tint: Some(_) } = varying(1) else { panic!("{:?}", varying(1)) };
    assert_eq!((ends, channel), (["gold-paint".to_string(), "chrome".to_string()], 3));
    let Varying { form: VaryingForm::One(Binding::Neural(name)), tint: Some(tint) } = varying(2) else { panic!("{:?}", varying(2)) };
    assert_eq!(name, "gold-paint");
    assert!(tint.transform.is_some(), "KHR_texture_transform is honoured");
    assert!(matches!(varying(3), Varying { form: VaryingForm::One(Binding::Nbrdf(_)), tint: None }));
    assert_eq!(scene.textures.len(), 2, "one image, decoded linear (weights, t) and sRGB (tint)");

    for (neural, problem) in [
        (json!({"mix": ["a", "b", "c", "d", "e"], "weights": {"index": 0}}), "'mix' lists 5 codes (2 to 4 allowed)"),
        (json!({"mix": ["a"], "weights": {"index": 0}}), "'mix' lists 1 codes"),
        (json!({"mix": ["a", "b"]}), "neural weights is missing"),
        (json!({"mix": ["a", "b"], "weights": {"index": 3}}), "names texture 3"),
        (json!({"mix": "a", "weights": {"index": 0}}), "'mix' must be a list of codes"),
        (json!({"mix": ["a", 7], "weights": {"index": 0}}), "names 7"),
        (json!({"blend": ["a", "b"], "t": {"index": 0}, "channel": 4}), "channel 4 is out of range"),
        (json!({"blend": ["a", "merl:x.binary"], "t": {"index": 0}}), "blend interpolates latent codes"),
        (json!({"blend": ["a", "b", "c"], "t": {"index": 0}}), "'blend' lists 3 codes"),
        (json!({"code": "a", "weights": {"index": 0}}), "unknown key 'weights'"),
        (json!({"code": "a", "mix": ["a", "b"]}), "must be one of"),
        (json!({}), "must be one of"),
        (json!({"code": "phong:x"}), "phong:x"),
    ] {
        let doc = with_texture(json!([{"name": "bad", "extras": {"neural": neural}}]));
        let message = expect_error(&doc, problem);
        assert!(message.contains("material 'bad'"), "{message}");
    }
}

/// A 2 × 1 PNG with texels (255, 128, 0) and (10, 20, 30).
fn two_texel_png() -> Vec<u8> {
    let mut png = Vec::new();
    image::RgbImage::from_raw(2, 1, vec![255, 128, 0, 10, 20, 30])
        .expect("image")
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .expect("encode png");
    png
}

#[test]
fn base_color_texture_is_decoded_from_srgb() {
    let png = two_texel_png();
    let mut doc = material_doc(
        json!([{"name": "tex", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]),
    );
    doc["textures"] = json!([{"source": 0}]);
    doc["images"] = json!([{"uri": format!("data:image/png;base64,{}", base64(&png))}]);
    let scene = load_doc(&doc).expect("load");
    assert_eq!(scene.materials[0].base_color_texture, Some(crate::scene::TextureRef::new(0)));
    let t = &scene.textures[0];
    assert_eq!((t.width, t.height), (2, 1));
    assert!((t.texel(0).x - 1.0).abs() < 1e-5 && t.texel(0).z == 0.0);
    assert!((t.texel(0).y - 0.215_861).abs() < 1e-4, "{}", t.texel(0));
    assert!((t.texel(1).x - 0.003_035).abs() < 1e-5, "{}", t.texel(1));
}

/// One image used as sRGB base colour and as linear metallic-roughness data is decoded once
/// per encoding; the samplers' wrap and filter modes, KHR_texture_transform and texCoord 0
/// or 1 are read; a texCoord beyond 1 is a warning.
#[test]
fn texture_references_read_samplers_transforms_and_encodings() {
    use crate::scene::texture::{texture_transform, Filter, Wrap};
    let png = two_texel_png();
    let mut doc = material_doc(json!([
        {"name": "a", "pbrMetallicRoughness": {
            "baseColorTexture": {"index": 0, "extensions": {"KHR_texture_transform": {"offset": [0.5, 0.0], "rotation": 0.25, "scale": [2.0, 3.0]}}},
            "metallicRoughnessTexture": {"index": 1, "texCoord": 1}}},
        {"name": "b", "pbrMetallicRoughness": {"baseColorTexture": {"index": 1}}},
        {"name": "c", "pbrMetallicRoughness": {"baseColorTexture": {"index": 1, "texCoord": 3}}}
    ]));
    doc["extensionsUsed"] = json!(["KHR_texture_transform"]);
    doc["samplers"] = json!([{"magFilter": 9728, "wrapS": 33071, "wrapT": 33648}]);
    doc["textures"] = json!([{"source": 0, "sampler": 0}, {"source": 0}]);
    doc["images"] = json!([{"uri": format!("data:image/png;base64,{}", base64(&png))}]);
    let scene = load_doc(&doc).expect("load");
    assert_eq!(scene.textures.len(), 2, "one image, two encodings");
    let [a, b] = [&scene.materials[0], &scene.materials[1]];
    let base = a.base_color_texture.expect("base colour texture");
    assert_eq!(base.wrap, [Wrap::ClampToEdge, Wrap::MirroredRepeat]);
    assert_eq!(base.filter, Filter::Nearest);
    assert_eq!(base.transform, Some(texture_transform(Vec2::new(0.5, 0.0), 0.25, Vec2::new(2.0, 3.0))));
    let mr = a.metallic_roughness_texture.expect("metallic-roughness texture");
    assert_eq!((mr.wrap, mr.filter, mr.transform, mr.tex_coord), ([Wrap::Repeat; 2], Filter::Linear, None, 1));
    assert_eq!(base.tex_coord, 0);
    assert_eq!(scene.materials[2].base_color_texture.map(|t| t.tex_coord), Some(0));
    assert_ne!(mr.texture, base.texture);
    assert_eq!(b.base_color_texture.map(|t| t.texture), Some(base.texture), "the sRGB decoding is shared");
    assert!((scene.textures[mr.texture].texel(0).y - 128.0 / 255.0).abs() < 1e-6, "linear data");
    assert!((scene.textures[base.texture].texel(0).y - 0.215_861).abs() < 1e-4, "sRGB colour");
    assert_eq!(scene.warnings.len(), 1, "{:?}", scene.warnings);
    assert!(scene.warnings[0].contains("material 'c' uses TEXCOORD_3"), "{:?}", scene.warnings);
}

/// TEXCOORD_1 is read; a mesh without it repeats its TEXCOORD_0 in the second set.
#[test]
fn second_texture_coordinate_set_is_read_and_falls_back_to_the_first() {
    let mut bin = Bin::default();
    let p = bin.vec3(&TRIANGLE);
    let t0 = bin.vec2(&[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]);
    let t1 = bin.vec2(&[[0.5, 0.5], [0.25, 0.5], [0.5, 0.25]]);
    let root = json!({
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0, 1]}],
        "nodes": [{"mesh": 0}, {"mesh": 1}],
        "meshes": [
            {"primitives": [{"attributes": {"POSITION": p, "TEXCOORD_0": t0}}]},
            {"primitives": [{"attributes": {"POSITION": p, "TEXCOORD_0": t0, "TEXCOORD_1": t1}}]}
        ]
    });
    let scene = load_doc(&bin.embed(root)).expect("load");
    let g = &scene.geometry;
    assert_eq!(g.uvs1.len(), 6);
    assert_eq!(g.uvs1[..3], g.uvs[..3]);
    assert_eq!(g.uvs1[3..], [Vec2::new(0.5, 0.5), Vec2::new(0.25, 0.5), Vec2::new(0.5, 0.25)]);
    let without = load_doc(&triangle_doc(json!([{"mesh": 0}]), json!([0]), json!({}))).expect("load");
    assert!(without.geometry.uvs1.is_empty(), "no second set stored when no mesh has one");
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

/// An extension the file only uses is named once in a warning and the scene loads with its
/// core parameters; one it requires is an error naming it; the supported ones load silently.
#[test]
fn unsupported_extensions_warn_once_or_fail_when_required() {
    let materials = json!({
        "extensionsUsed": ["KHR_materials_anisotropy", "KHR_materials_emissive_strength", "KHR_materials_iridescence"],
        "materials": [
            {"name": "brushed", "extensions": {"KHR_materials_anisotropy": {"anisotropyStrength": 1.0}}},
            {"name": "brushed2", "extensions": {"KHR_materials_anisotropy": {"anisotropyStrength": 0.5}}}
        ]
    });
    let scene = load_doc(&triangle_doc(json!([{"mesh": 0}]), json!([0]), materials)).expect("load");
    assert!(scene.warnings.len() == 2, "{:#?}", scene.warnings);
    assert!(scene.warnings[0].contains("KHR_materials_anisotropy") && scene.warnings[0].contains("scene.gltf"));
    assert!(scene.warnings[1].contains("KHR_materials_iridescence"));
    assert!(scene.materials.iter().any(|m| m.name == "brushed"), "{:?}", scene.materials);

    let required = json!({
        "extensionsUsed": ["KHR_lights_punctual", "KHR_draco_mesh_compression"],
        "extensionsRequired": ["KHR_lights_punctual", "KHR_draco_mesh_compression"]
    });
    let message = expect_error(&triangle_doc(json!([{"mesh": 0}]), json!([0]), required), "requires the glTF extension KHR_draco_mesh_compression");
    assert!(message.contains("supported: KHR_lights_punctual"), "{message}");

    let supported = json!({"extensionsUsed": ["KHR_lights_punctual"], "extensionsRequired": ["KHR_lights_punctual"]});
    let scene = load_doc(&triangle_doc(json!([{"mesh": 0}]), json!([0]), supported)).expect("load");
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
}

/// Normal, emissive and alpha slots: the normal texture's scale, texCoord and
/// KHR_texture_transform (which the `gltf` crate leaves unparsed there), decoded as linear
/// data; the emissive texture as sRGB; alphaMode with its cutoff (default 0.5) and the base
/// colour factor's alpha; a malformed transform is an error naming the material.
#[test]
fn normal_emissive_and_alpha_slots_are_read() {
    use crate::scene::texture::texture_transform;
    let png = two_texel_png();
    let mut doc = material_doc(json!([
        {"name": "bumpy", "alphaMode": "MASK", "alphaCutoff": 0.25,
         "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 0.6]},
         "normalTexture": {"index": 0, "scale": 0.5, "texCoord": 1,
            "extensions": {"KHR_texture_transform": {"offset": [0.5, 0.0], "scale": [2.0, 2.0]}}},
         "emissiveTexture": {"index": 0}, "emissiveFactor": [1.0, 1.0, 1.0]},
        {"name": "veil", "alphaMode": "BLEND"},
        {"name": "cut", "alphaMode": "MASK"},
        {"name": "plain"}
    ]));
    doc["textures"] = json!([{"source": 0}]);
    doc["images"] = json!([{"uri": format!("data:image/png;base64,{}", base64(&png))}]);
    let scene = load_doc(&doc).expect("load");
    let m = &scene.materials;
    let normal = m[0].normal_texture.expect("normal map");
    assert_eq!((normal.scale, normal.texture.tex_coord), (0.5, 1));
    assert_eq!(normal.texture.transform, Some(texture_transform(Vec2::new(0.5, 0.0), 0.0, Vec2::splat(2.0))));
    assert!((scene.textures[normal.texture.texture].texel(0).y - 128.0 / 255.0).abs() < 1e-6, "linear");
    let emissive = m[0].emissive_texture.expect("emissive texture");
    assert!((scene.textures[emissive.texture].texel(0).y - 0.215_861).abs() < 1e-4, "sRGB");
    assert_eq!((m[0].alpha_mode, m[0].base_alpha), (AlphaMode::Mask { cutoff: 0.25 }, 0.6));
    assert_eq!(m[1].alpha_mode, AlphaMode::Blend);
    assert_eq!(m[2].alpha_mode, AlphaMode::Mask { cutoff: 0.5 });
    assert_eq!((m[3].alpha_mode, m[3].base_alpha, m[3].has_alpha()), (AlphaMode::Opaque, 1.0, false));

    doc["materials"][0]["normalTexture"]["extensions"]["KHR_texture_transform"]["scale"] = json!("big");
    expect_error(&doc, "the normal texture of material 'bumpy' has an invalid KHR_texture_transform: 'scale' must be an array of two numbers");
}

/// Tangents: read from TANGENT (turned with the node, the handedness flipped by a mirroring
/// transform) or, without it, computed by MikkTSpace with the bitangent pointing up the
/// image (−v); only meshes with a normal-mapped material get any.
#[test]
fn tangents_come_from_the_file_or_mikktspace() {
    let png = two_texel_png();
    let mut bin = Bin::default();
    let p = bin.vec3(&TRIANGLE);
    let n = bin.vec3(&[[0.0, 0.0, 1.0]; 3]);
    let uv = bin.vec2(&[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]);
    let data: Vec<u8> = [[0.0f32, 1.0, 0.0, 1.0]; 3].iter().flatten().flat_map(|x| x.to_le_bytes()).collect();
    let tangent = bin.push(&data, json!({"componentType": 5126, "count": 3, "type": "VEC4"}));
    let root = json!({
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0, 1, 2]}],
        "nodes": [{"mesh": 0}, {"mesh": 1, "scale": [-1.0, 1.0, 1.0]}, {"mesh": 2}],
        "meshes": [
            {"primitives": [{"attributes": {"POSITION": p, "NORMAL": n, "TEXCOORD_0": uv}, "material": 0}]},
            {"primitives": [{"attributes": {"POSITION": p, "NORMAL": n, "TEXCOORD_0": uv, "TANGENT": tangent}, "material": 0}]},
            {"primitives": [{"attributes": {"POSITION": p, "NORMAL": n, "TEXCOORD_0": uv}, "material": 1}]}
        ],
        "materials": [{"name": "bumpy", "normalTexture": {"index": 0}}, {"name": "smooth"}],
        "textures": [{"source": 0}],
        "images": [{"uri": format!("data:image/png;base64,{}", base64(&png))}]
    });
    let scene = load_doc(&bin.embed(root)).expect("load");
    let t = &scene.geometry.tangents;
    assert_eq!(t.len(), 9);
    // u runs along +x and v along +y, so the image's up (−v) is −y = −(n × t): w = −1.
    for v in &t[0..3] {
        assert!(v.abs_diff_eq(Vec4::new(1.0, 0.0, 0.0, -1.0), 1e-5), "MikkTSpace: {v}");
    }
    for v in &t[3..6] {
        assert!(v.abs_diff_eq(Vec4::new(0.0, 1.0, 0.0, -1.0), 1e-6), "mirrored file tangent: {v}");
    }
    assert_eq!(t[6..], [Vec4::ZERO; 3], "no normal map, no tangents");
    let without = load_doc(&triangle_doc(json!([{"mesh": 0}]), json!([0]), json!({}))).expect("load");
    assert!(without.geometry.tangents.is_empty(), "nothing stored when no material has a normal map");
}

/// Bad textures: a missing image file is an I/O error naming it; a truncated image, an
/// image in a format the renderer does not decode (GIF here) and a texture naming a missing
/// image are one-line errors naming the glTF file, the image and the material slot.
#[test]
fn bad_textures_are_errors_naming_the_file_and_the_image() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut doc = material_doc(json!([{"name": "tex", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]));
    doc["textures"] = json!([{"source": 0}]);
    doc["images"] = json!([{"uri": "wood.png"}]);
    let path = write(dir.path(), "scene.gltf", &doc);
    let error = load(&path).expect_err("missing image");
    assert!(matches!(error, Error::Io { ref path, .. } if path.ends_with("wood.png")), "{error}");

    let png = two_texel_png();
    std::fs::write(dir.path().join("wood.png"), &png[..png.len() / 2]).expect("write");
    let message = load(&path).expect_err("truncated").to_string();
    assert!(message.starts_with(&path.display().to_string()) && message.contains("cannot decode image 0 (base colour of material 'tex')"), "{message}");
    assert!(!message.contains('\n'), "{message}");

    std::fs::write(dir.path().join("wood.png"), b"GIF89a\x01\x00\x01\x00\x00\x00\x00;").expect("write");
    let message = load(&path).expect_err("GIF").to_string();
    assert!(message.contains("cannot decode image 0"), "{message}");

    doc["textures"] = json!([{"source": 0}, {"source": 3}]);
    doc["materials"][0]["emissiveTexture"] = json!({"index": 1});
    expect_error(&doc, "");
}

/// A mesh that three nodes use, big enough to be worth instancing, is stored once in its
/// own space with one instance per node (transforms from the root, a mirroring one
/// included); flattening the instances gives the triangles the nodes place. The Cornell
/// box's walls (a few triangles on three nodes) are copied instead.
#[test]
fn meshes_used_by_many_nodes_are_instanced() {
    let nodes = json!([
        {"children": [1, 2, 3], "translation": [0.0, 0.0, -5.0]},
        {"mesh": 0},
        {"mesh": 0, "translation": [2.0, 0.0, 0.0]},
        {"mesh": 0, "scale": [-1.0, 1.0, 1.0]}
    ]);
    let mut doc = triangle_doc(nodes, json!([0]), json!({}));
    let mut bin = Bin::default();
    let p = bin.vec3(&TRIANGLE);
    let n = bin.vec3(&[[0.0, 0.0, 1.0]; 3]);
    let repeated: Vec<u16> = (0..600).flat_map(|_| [0u16, 1, 2]).collect();
    let i = bin.indices(&repeated);
    doc["meshes"][0]["primitives"] = json!([{"attributes": {"POSITION": p, "NORMAL": n}, "indices": i}]);
    let doc = bin.embed(doc);
    let scene = load_doc(&doc).expect("load");
    assert_eq!(scene.meshes, vec![Mesh { first_triangle: 0, triangle_count: 600, first_vertex: 0, vertex_count: 3 }]);
    assert_eq!(scene.geometry.triangle_count(), 600, "stored once");
    assert_eq!(scene.world_triangle_count(), 0);
    assert_eq!(scene.triangle_instance_count(), 1800);
    let origins: Vec<Vec3> = scene.instances.iter().map(|i| i.object_to_world.transform_point3(Vec3::X)).collect();
    assert_eq!(origins, vec![Vec3::new(1.0, 0.0, -5.0), Vec3::new(3.0, 0.0, -5.0), Vec3::new(-1.0, 0.0, -5.0)]);
    assert_eq!(scene.world_bounds(), Some((Vec3::new(-1.0, 0.0, -5.0), Vec3::new(3.0, 1.0, -5.0))));

    let flat = scene.clone().flatten_instances().expect("flatten");
    assert!(flat.meshes.is_empty() && flat.instances.is_empty());
    assert_eq!(flat.geometry.triangle_count(), 1800);
    flat.validate().expect("valid");
    let mirrored = flat.geometry.triangle_positions(1200);
    assert!(close(mirrored[0], Vec3::new(0.0, 0.0, -5.0)) && close(mirrored[1], Vec3::new(0.0, 1.0, -5.0)), "winding flipped: {mirrored:?}");
    assert!(flat.geometry.normals.iter().all(|&n| close(n, Vec3::Z)));

    let cornell = shipped("scenes/cornell-box/scene.gltf").map(|p| load(&p).expect("load"));
    assert!(cornell.is_none_or(|c| c.instances.is_empty()), "small repeats are copied");
}
