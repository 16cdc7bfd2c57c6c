//! Writes the seed corpora of the fuzz targets to `fuzz/corpus/<target>/seed-*` (small
//! files, made from the repository's scenes and from code; nothing large is committed):
//!
//! ```text
//! cargo run --manifest-path fuzz/Cargo.toml --example make_seeds [NBRDF_DIR]
//! ```
//!
//! `NBRDF_DIR` (optional) is a directory of NBRDF `.npy` networks; its `alum-bronze_*.npy`
//! tensors are added to the `npy` corpus.

use renderer::formats::image_part::ImagePart;
use renderer::formats::latent_file::{LatentFile, WeightType};
use renderer::neural::mapping::MappingForm;
use renderer::neural::nbrdf::TENSOR_NAMES;
use renderer_fuzz::{
    fuzz_path, latent_mode2_input, merl_header, render_probe, scene_file, valid_npy_tensors, CORNELL_BIN, MTL_SEPARATOR,
};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

fn main() {
    let fuzz_dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let repo = fuzz_dir.parent().expect("repository root");
    let corpus = fuzz_dir.join("corpus");
    let nbrdf_dir = std::env::args().nth(1).map(PathBuf::from);

    let mut count = 0;
    let mut write = |target: &str, name: &str, bytes: &[u8]| {
        let dir = corpus.join(target);
        std::fs::create_dir_all(&dir).expect("create corpus directory");
        std::fs::write(dir.join(format!("seed-{name}")), bytes).expect("write seed");
        count += 1;
    };

    // glTF: the Cornell box as it is (its scene.bin is served from memory), as a GLB, with a
    // data: URI buffer, and a small textured strip scene with cameras, lights and extras.
    let cornell = std::fs::read(repo.join("scenes/cornell-box/scene.gltf")).expect("cornell box");
    write("gltf", "cornell.gltf", &cornell);
    let mut doc: Value = serde_json::from_slice(&cornell).expect("cornell JSON");
    doc["buffers"][0]
        .as_object_mut()
        .expect("buffer object")
        .remove("uri");
    write("gltf", "cornell.glb", &glb(&doc, CORNELL_BIN));
    doc["buffers"][0]["uri"] = json!(format!(
        "data:application/octet-stream;base64,{}",
        base64(CORNELL_BIN)
    ));
    write("gltf", "cornell-data-uri.gltf", &to_json(&doc));
    let (strip, strip_bin) = strip_scene();
    write("gltf", "strip.glb", &glb(&strip, &strip_bin));
    let (features, features_bin) = features_scene();
    let features = glb(&features, &features_bin);
    let loaded = renderer::scene::gltf::load_from_bytes_with(&features, &fuzz_path("scene.gltf"), |p| scene_file(p, &[]))
        .expect("the features seed loads");
    let tangents = &loaded.geometry.tangents;
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    assert!(tangents.len() == 20 && tangents[..16].iter().all(|t| t.w.abs() == 1.0), "file and MikkTSpace tangents: {tangents:?}");
    render_probe(loaded);
    write("gltf", "features.glb", &features);
    let (instanced, instanced_bin) = instanced_scene();
    let instanced = glb(&instanced, &instanced_bin);
    let loaded = renderer::scene::gltf::load_from_bytes_with(&instanced, &fuzz_path("scene.gltf"), |p| scene_file(p, &[]))
        .expect("the instancing seed loads");
    assert_eq!((loaded.meshes.len(), loaded.instances.len()), (1, 3), "instanced");
    render_probe(loaded);
    write("gltf", "instanced.glb", &instanced);

    // OBJ (+ MTL after the separator line).
    write(
        "obj",
        "triangle.obj",
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    );
    let mut with_mtl = OBJ.as_bytes().to_vec();
    with_mtl.extend_from_slice(MTL_SEPARATOR);
    with_mtl.extend_from_slice(MTL.as_bytes());
    write("obj", "materials.obj", &with_mtl);
    write(
        "obj",
        "textured.obj",
        b"mtllib t.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
          vn 0 0 1\nusemtl wood\nf 1/1/1 2/2/1 3/3/1 4/4/1\n#--mtl--\nnewmtl wood\n\
          Kd 1 1 1\nmap_Kd wood.png\nKs 0.1 0.1 0.1\nNs 20\nKe 0 0 0\n",
    );

    // MERL: the valid header (stands for a full table of zeros), header + one value (tiled to
    // a full table), a NaN value, wrong dims, a truncated header.
    let header = merl_header();
    write("merl", "header", &header);
    let mut one = header.clone();
    one.extend_from_slice(&(0.5f64).to_le_bytes());
    write("merl", "header-value", &one);
    let mut nan = header.clone();
    nan.extend_from_slice(&[0; 64]);
    nan.extend_from_slice(&f64::NAN.to_le_bytes());
    write("merl", "header-nan", &nan);
    let mut dims = header.clone();
    dims[8..12].copy_from_slice(&90i32.to_le_bytes());
    write("merl", "dims", &dims);
    write("merl", "short", &header[..7]);

    // .npy: the first byte picks the tensor (0 fc1 ... 5 b3).
    for (i, bytes) in valid_npy_tensors().iter().enumerate() {
        let mut input = vec![i as u8];
        input.extend_from_slice(bytes);
        write("npy", &format!("small_{}", TENSOR_NAMES[i]), &input);
    }
    if let Some(dir) = nbrdf_dir {
        for (i, name) in TENSOR_NAMES.iter().enumerate() {
            let path = dir.join(format!("alum-bronze_{name}.npy"));
            let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            let mut input = vec![i as u8];
            input.extend_from_slice(&bytes);
            write("npy", &format!("alum-bronze_{name}"), &input);
        }
    }

    // latent.bin: small files with the f_ref table left to the target (mode 2; one carries
    // an encoder), and the start of the shipped file, checksum fixed (mode 1) and as it is
    // (mode 0).
    for (weight_type, name) in [
        (WeightType::F32, "small-f32"),
        (WeightType::F16, "small-f16"),
    ] {
        write(
            "latent",
            name,
            &latent_mode2_input(&{
                let mut file = LatentFile::synthetic(&[5], weight_type);
                file.mapping = MappingForm::Code;
                file
            }),
        );
    }
    write(
        "latent",
        "small-encoder",
        &latent_mode2_input(
            &LatentFile::synthetic(&[5], WeightType::F16).with_synthetic_encoder(),
        ),
    );
    if let Ok(shipped) = std::fs::read(repo.join("scenes/materials/latent.bin")) {
        let mut input = vec![1];
        input.extend_from_slice(&shipped[..shipped.len().min(4096)]);
        write("latent", "shipped-head-fixed", &input);
        let mut input = vec![0];
        input.extend_from_slice(&shipped[..shipped.len().min(256)]);
        write("latent", "shipped-head", &input);
    }
    // Image parts: a band of a 6×4 image with settings, the whole image as one part, and a
    // plain EXR (no settings, data window = display window).
    let dir = std::env::temp_dir().join(format!("make-seeds-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temporary directory");
    let part = |region: &str, settings: bool| {
        let region: renderer::film::Region = region.parse().expect("region");
        ImagePart {
            full_width: 6,
            full_height: 4,
            region,
            pixels: (0..region.pixel_count()).map(|i| renderer::Rgb::new(i as f32, 0.5, 1e-3)).collect(),
            settings: if settings { [("seed".to_string(), "1".to_string())].into() } else { Default::default() },
        }
    };
    for (name, p) in [("band.exr", part("0,2,6,4", true)), ("whole.exr", part("0,0,6,4", true)), ("plain.exr", part("0,0,6,4", false))] {
        let path = dir.join(name);
        p.write_exr(&path).expect("write part");
        write("image_part", name, &std::fs::read(&path).expect("read part"));
    }
    let _ = std::fs::remove_dir_all(&dir);
    println!("wrote {count} seeds under {}", corpus.display());
}

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

/// A two-triangle strip with UVs, an external texture, a perspective camera, three punctual
/// lights, material extras and a constant environment.
fn strip_scene() -> (Value, Vec<u8>) {
    let positions: [[f32; 3]; 4] = [[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [1., 1., 0.]];
    let uvs: [[f32; 2]; 4] = [[0., 1.], [1., 1.], [0., 0.], [1., 0.]];
    let mut bin: Vec<u8> = positions
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    bin.extend(uvs.iter().flatten().flat_map(|v| v.to_le_bytes()));
    bin.extend([0u16, 1, 2, 3].iter().flat_map(|v| v.to_le_bytes()));
    let doc = json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_lights_punctual"],
        "scene": 0,
        "scenes": [{"nodes": [0, 1, 2], "extras": {"environment": {"color": [0.1, 0.2, 0.3]}}}],
        "nodes": [
            {"mesh": 0, "rotation": [0.0, 0.0, 0.0, 1.0], "scale": [1.0, 1.0, -1.0]},
            {"camera": 0, "translation": [0.5, 0.5, 3.0], "children": [3]},
            {"extensions": {"KHR_lights_punctual": {"light": 0}}, "translation": [0.0, 2.0, 0.0]},
            {"extensions": {"KHR_lights_punctual": {"light": 1}},
             "matrix": [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 1.0]}
        ],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.7, "znear": 0.01, "aspectRatio": 1.5}}],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"type": "point", "intensity": 3415.0, "color": [1.0, 0.9, 0.8]},
            {"type": "spot", "intensity": 2.0, "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.5}}
        ]}},
        "meshes": [{"name": "strip", "primitives": [
            {"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2, "mode": 5, "material": 0},
            {"attributes": {"POSITION": 0}, "mode": 6}
        ]}],
        "materials": [{"name": "wood", "doubleSided": true,
            "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0.0},
            "emissiveFactor": [0.0, 0.0, 0.0],
            "extras": {"brdf": "merl:materials/alum-bronze.binary"}}],
        "textures": [{"source": 0}],
        "images": [{"uri": "wood%20grain.png"}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
             "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 0.0]},
            {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"},
            {"bufferView": 2, "componentType": 5123, "count": 4, "type": "SCALAR"}
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 48},
            {"buffer": 0, "byteOffset": 48, "byteLength": 32},
            {"buffer": 0, "byteOffset": 80, "byteLength": 8}
        ],
        "buffers": [{"byteLength": bin.len()}]
    });
    (doc, bin)
}

/// A quad with every texture feature the loader reads: normal maps (one mesh with TANGENT,
/// one without, so MikkTSpace runs), an emissive texture with emissive strength,
/// `KHR_texture_transform` on a base colour and (as raw JSON) on a normal texture, a
/// second texture-coordinate set, a clamped nearest sampler, alpha MASK and BLEND, ior and
/// specular, a JPEG and PNGs, and one mesh on two nodes.
fn features_scene() -> (Value, Vec<u8>) {
    let positions: [[f32; 3]; 4] = [[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]];
    let normals = [[0f32, 0., 1.]; 4];
    let uvs: [[f32; 2]; 4] = [[0., 1.], [1., 1.], [1., 0.], [0., 0.]];
    let uvs1: [[f32; 2]; 4] = [[0.5, 0.5], [0.25, 0.5], [0.25, 0.25], [0.5, 0.25]];
    let tangents = [[1f32, 0., 0., 1.]; 4];
    let mut bin: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let mut push = |bytes: Vec<u8>| {
        views.push(json!({"buffer": 0, "byteOffset": bin.len(), "byteLength": bytes.len()}));
        bin.extend(bytes);
    };
    let floats = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    push(floats(positions.as_flattened()));
    push(floats(normals.as_flattened()));
    push(floats(uvs.as_flattened()));
    push(floats(uvs1.as_flattened()));
    push(floats(tangents.as_flattened()));
    push([0u16, 1, 2, 0, 2, 3].iter().flat_map(|v| v.to_le_bytes()).collect());
    let doc = json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_materials_emissive_strength", "KHR_materials_ior", "KHR_materials_specular", "KHR_texture_transform"],
        "scene": 0,
        "scenes": [{"nodes": [0, 1, 2, 3]}],
        "nodes": [
            {"mesh": 0},
            {"mesh": 0, "translation": [0.0, 0.0, -1.0], "scale": [-1.0, 1.0, 1.0]},
            {"mesh": 1, "translation": [0.0, 0.0, -2.0]},
            {"camera": 0, "translation": [0.5, 0.5, 3.0]}
        ],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.7, "znear": 0.01}}],
        "meshes": [
            {"primitives": [
                {"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2, "TEXCOORD_1": 3, "TANGENT": 4}, "indices": 5, "material": 0},
                {"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2, "TEXCOORD_1": 3}, "indices": 5, "material": 1}
            ]},
            {"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 2}, "indices": 5, "material": 2}]}
        ],
        "materials": [
            {"name": "bumpy-lamp",
             "normalTexture": {"index": 1, "scale": 0.8, "extensions": {"KHR_texture_transform": {"offset": [0.1, 0.2], "rotation": 0.3, "scale": [2.0, 2.0]}}},
             "emissiveTexture": {"index": 0}, "emissiveFactor": [1.0, 0.5, 0.25],
             "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 3.0}},
             "pbrMetallicRoughness": {"baseColorTexture": {"index": 2, "extensions": {"KHR_texture_transform": {"scale": [4.0, 4.0]}}}}},
            {"name": "cutout", "alphaMode": "MASK", "alphaCutoff": 0.4, "doubleSided": true,
             "normalTexture": {"index": 1, "texCoord": 1},
             "pbrMetallicRoughness": {"baseColorTexture": {"index": 3, "texCoord": 1}, "metallicRoughnessTexture": {"index": 1}}},
            {"name": "veil", "alphaMode": "BLEND",
             "extensions": {"KHR_materials_ior": {"ior": 1.8}, "KHR_materials_specular": {"specularFactor": 0.7, "specularColorFactor": [1.0, 0.9, 0.8]}},
             "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 0.4], "baseColorTexture": {"index": 0}}}
        ],
        "samplers": [{"magFilter": 9728, "wrapS": 33071, "wrapT": 33648}],
        "textures": [{"source": 0}, {"source": 1}, {"source": 2}, {"source": 0, "sampler": 0}],
        "images": [{"uri": "sign.png"}, {"uri": "bumps.png"}, {"uri": "tiles.jpg"}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 0.0]},
            {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC2"},
            {"bufferView": 3, "componentType": 5126, "count": 4, "type": "VEC2"},
            {"bufferView": 4, "componentType": 5126, "count": 4, "type": "VEC4"},
            {"bufferView": 5, "componentType": 5123, "count": 6, "type": "SCALAR"}
        ],
        "bufferViews": views,
        "buffers": [{"byteLength": bin.len()}]
    });
    (doc, bin)
}
/// One mesh of 600 triangles (a fan around a quad's centre, cut out by an alpha texture,
/// normal-mapped) on three nodes, one mirrored, under a rotated parent: enough copies saved
/// that the loader instances it (two-level tracing).
fn instanced_scene() -> (Value, Vec<u8>) {
    let n = 600u32;
    let mut positions = vec![[0.0f32, 0.0, 0.0]];
    let mut uvs = vec![[0.5f32, 0.5]];
    for k in 0..n {
        let a = std::f32::consts::TAU * k as f32 / n as f32;
        positions.push([a.cos(), a.sin(), 0.0]);
        uvs.push([0.5 + 0.5 * a.cos(), 0.5 - 0.5 * a.sin()]);
    }
    let indices: Vec<u32> = (0..n).flat_map(|k| [0, 1 + k, 1 + (k + 1) % n]).collect();
    let mut bin: Vec<u8> = positions.iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
    let uv_offset = bin.len();
    bin.extend(uvs.iter().flatten().flat_map(|v| v.to_le_bytes()));
    let index_offset = bin.len();
    bin.extend(indices.iter().flat_map(|v| v.to_le_bytes()));
    let count = positions.len();
    let doc = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0, 4]}],
        "nodes": [
            {"children": [1, 2, 3], "rotation": [0.0, 0.3826834, 0.0, 0.9238795]},
            {"mesh": 0},
            {"mesh": 0, "translation": [2.5, 0.0, -1.0]},
            {"mesh": 0, "translation": [-2.5, 0.0, -1.0], "scale": [-1.0, 1.0, 1.0]},
            {"camera": 0, "translation": [0.0, 0.0, 6.0]}
        ],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.9, "znear": 0.01}}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2, "material": 0}]}],
        "materials": [{"name": "lace", "alphaMode": "MASK", "doubleSided": true,
            "normalTexture": {"index": 0}, "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
        "textures": [{"source": 0}],
        "images": [{"uri": "lace.png"}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": count, "type": "VEC3", "min": [-1.0, -1.0, 0.0], "max": [1.0, 1.0, 0.0]},
            {"bufferView": 1, "componentType": 5126, "count": count, "type": "VEC2"},
            {"bufferView": 2, "componentType": 5125, "count": indices.len(), "type": "SCALAR"}
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": uv_offset},
            {"buffer": 0, "byteOffset": uv_offset, "byteLength": index_offset - uv_offset},
            {"buffer": 0, "byteOffset": index_offset, "byteLength": bin.len() - index_offset}
        ],
        "buffers": [{"byteLength": bin.len()}]
    });
    (doc, bin)
}

fn to_json(doc: &Value) -> Vec<u8> {
    serde_json::to_vec_pretty(doc).expect("serialise JSON")
}

/// A binary glTF: header, JSON chunk, BIN chunk (both padded to 4 bytes).
fn glb(doc: &Value, bin: &[u8]) -> Vec<u8> {
    let mut json = serde_json::to_vec(doc).expect("serialise JSON");
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let mut bin = bin.to_vec();
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}

/// Standard base64 with padding.
fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
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
