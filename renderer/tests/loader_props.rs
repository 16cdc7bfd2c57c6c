//! Property tests of the file loaders (glTF, OBJ/MTL, MERL `.binary`, NBRDF `.npy`,
//! `latent.bin`): valid inputs of each format, randomly mutated (byte flips, truncation,
//! insertions, edits of the glTF JSON or the OBJ/MTL text), must never panic, and must
//! either load or fail with a file error ([`Error::InvalidFile`] or [`Error::Io`]) whose
//! message names the file. Then the inputs the fuzz targets (`fuzz/`, see
//! `docs/fuzzing.md`) found crashing, as regression cases.
//!
//! The files come from memory (the loaders' `from_bytes` entry points); nothing is written.

use proptest::prelude::*;
use proptest::test_runner::Config;
use renderer::formats::latent_file::{LatentFile, WeightType};
use renderer::formats::merl::{MerlTable, BIN_COUNT, FILE_BYTES, PHI_D_BINS, THETA_D_BINS, THETA_H_BINS};
use renderer::neural::nbrdf::{tensor_from_bytes, NbrdfNetwork, TENSOR_NAMES};
use renderer::scene::{gltf, obj, SceneDescription};
use renderer::Error;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// Cases per property; the whole file stays well under 15 s in the dev profile.
const CASES: u32 = 128;
/// Cases of the properties whose inputs are full-size tables (35 MB MERL, 8.7 MB latent).
const LARGE_CASES: u32 = 24;

// ---------------------------------------------------------------------------------------
// Checks and mutations shared by every format.

/// Checks a failed load: a file error whose path ends with one of `names` (any path when
/// `names` is empty) and whose message starts with that path.
fn check_file_error(error: &Error, names: &[&str]) -> Result<(), TestCaseError> {
    let message = error.to_string();
    match error {
        Error::InvalidFile { path, .. } | Error::Io { path, .. } => {
            let shown = path.display().to_string();
            prop_assert!(!shown.is_empty(), "{message}");
            prop_assert!(
                names.is_empty() || names.iter().any(|n| shown.ends_with(n)),
                "error names {} instead of one of {names:?}: {message}",
                path.display()
            );
            prop_assert!(message.starts_with(&shown), "{message}");
        }
        other => prop_assert!(false, "not a file error: {other}"),
    }
    Ok(())
}

/// One random change to a byte string.
#[derive(Clone, Debug)]
enum Mutation {
    /// XOR the byte at (position mod length) with a non-zero mask.
    Flip(usize, u8),
    /// Set the byte at (position mod length).
    Set(usize, u8),
    /// Keep only the first (position mod (length + 1)) bytes.
    Truncate(usize),
    /// Insert bytes at (position mod (length + 1)).
    Insert(usize, Vec<u8>),
    /// Remove up to `n` bytes from (position mod length).
    Remove(usize, usize),
    /// Overwrite 4 bytes at (position mod length) with a little-endian u32 (a length or
    /// count field, say).
    Word(usize, u32),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    let word = prop_oneof![
        Just(0u32),
        Just(1),
        Just(u32::MAX),
        Just(0x7fff_ffff),
        Just(1 << 20),
        Just(1 << 31),
        any::<u32>()
    ];
    prop_oneof![
        3 => (any::<usize>(), 1u8..).prop_map(|(p, m)| Mutation::Flip(p, m)),
        2 => (any::<usize>(), any::<u8>()).prop_map(|(p, b)| Mutation::Set(p, b)),
        1 => any::<usize>().prop_map(Mutation::Truncate),
        1 => (any::<usize>(), prop::collection::vec(any::<u8>(), 1..16))
            .prop_map(|(p, b)| Mutation::Insert(p, b)),
        1 => (any::<usize>(), 1usize..64).prop_map(|(p, n)| Mutation::Remove(p, n)),
        2 => (any::<usize>(), word).prop_map(|(p, w)| Mutation::Word(p, w)),
    ]
}

/// 1 to 4 mutations.
fn mutations() -> impl Strategy<Value = Vec<Mutation>> {
    prop::collection::vec(mutation(), 1..5)
}

/// Applies `mutations` to `bytes`, positions limited to `range` (taken modulo its length,
/// so a mutation can be aimed at a part of a large file).
fn mutate_in(bytes: &mut Vec<u8>, mutations: &[Mutation], range: std::ops::Range<usize>) {
    for m in mutations {
        let (start, len) = (range.start.min(bytes.len()), range.len());
        let span = len.min(bytes.len() - start);
        let at = |p: usize, n: usize| start + if n == 0 { 0 } else { p % n };
        match m {
            Mutation::Flip(p, mask) if span > 0 => bytes[at(*p, span)] ^= mask,
            Mutation::Set(p, b) if span > 0 => bytes[at(*p, span)] = *b,
            Mutation::Truncate(p) => bytes.truncate(at(*p, span + 1)),
            Mutation::Insert(p, b) => {
                let i = at(*p, span + 1);
                bytes.splice(i..i, b.iter().copied());
            }
            Mutation::Remove(p, n) if span > 0 => {
                let i = at(*p, span);
                bytes.drain(i..(i + n).min(bytes.len()));
            }
            Mutation::Word(p, w) if span >= 4 => {
                let i = at(*p, span - 3);
                bytes[i..i + 4].copy_from_slice(&w.to_le_bytes());
            }
            _ => {}
        }
    }
}

fn mutate(bytes: &mut Vec<u8>, mutations: &[Mutation]) {
    mutate_in(bytes, mutations, 0..usize::MAX);
}

// ---------------------------------------------------------------------------------------
// glTF.

fn repo_file(relative: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join(relative)
}

/// The Cornell box's `.gltf` and `.bin` bytes.
fn cornell() -> &'static (Vec<u8>, Vec<u8>) {
    static FILES: OnceLock<(Vec<u8>, Vec<u8>)> = OnceLock::new();
    FILES.get_or_init(|| {
        let read = |p: &str| std::fs::read(repo_file(p)).expect("shipped Cornell box");
        (
            read("scenes/cornell-box/scene.gltf"),
            read("scenes/cornell-box/scene.bin"),
        )
    })
}

/// Path the fuzzed scenes pretend to have (nothing is read from there).
fn scene_path(name: &str) -> PathBuf {
    PathBuf::from("/props").join(name)
}

/// The files a scene may refer to: `scene.bin` (the Cornell box buffer), any `.png` (a 1×1
/// image), any `.mtl` (`mtl`); everything else is "not found".
fn scene_file(path: &Path, mtl: &[u8]) -> std::io::Result<Vec<u8>> {
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
    if name == "scene.bin" {
        Ok(cornell().1.clone())
    } else if name.ends_with(".png") {
        let mut png = Vec::new();
        image::RgbImage::from_raw(1, 1, vec![200, 100, 50])
            .expect("image")
            .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .expect("encode PNG");
        Ok(png)
    } else if name.ends_with(".mtl") {
        Ok(mtl.to_vec())
    } else {
        Err(std::io::ErrorKind::NotFound.into())
    }
}

fn load_gltf(bytes: &[u8]) -> renderer::Result<SceneDescription> {
    gltf::load_from_bytes_with(bytes, &scene_path("scene.gltf"), |p| scene_file(p, &[]))
}

/// Loads a glTF input and checks the outcome (a valid scene or a file error).
fn check_gltf(bytes: &[u8]) -> Result<(), TestCaseError> {
    match load_gltf(bytes) {
        Ok(scene) => prop_assert!(scene.validate().is_ok()),
        Err(e) => check_file_error(&e, &["scene.gltf", "scene.bin", ".png"])?,
    }
    Ok(())
}

/// A binary glTF of `doc` with `bin` as its BIN chunk.
fn glb(doc: &Value, bin: &[u8]) -> Vec<u8> {
    let mut json = serde_json::to_vec(doc).expect("JSON");
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let mut bin = bin.to_vec();
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = b"glTF".to_vec();
    for word in [2, total as u32, json.len() as u32] {
        out.extend_from_slice(&word.to_le_bytes());
    }
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}

/// The Cornell box as one `.glb` (its buffer as the BIN chunk).
fn cornell_glb() -> Vec<u8> {
    let mut doc: Value = serde_json::from_slice(&cornell().0).expect("Cornell JSON");
    doc["buffers"][0]
        .as_object_mut()
        .expect("buffer")
        .remove("uri");
    glb(&doc, &cornell().1)
}

/// A JSON value to put somewhere in a glTF document: numbers that are indices, counts,
/// offsets or factors, out of range or not, and values of the wrong type.
fn json_value() -> impl Strategy<Value = Value> {
    prop_oneof![
        (-3i64..40).prop_map(|n| json!(n)),
        prop_oneof![
            Just(json!(4_294_967_295u64)),
            Just(json!(i64::MAX)),
            Just(json!(-1)),
            Just(json!(1e39)),
            Just(json!(-0.0)),
            Just(json!(5126)),
            Just(json!(5123)),
            Just(json!(5121)),
        ],
        (-10.0f64..10.0).prop_map(|x| json!(x)),
        prop_oneof![
            Just(json!("VEC2")),
            Just(json!("SCALAR")),
            Just(json!("MAT4")),
            Just(json!("orthographic")),
            Just(json!("data:application/octet-stream;base64,AAAA")),
            Just(json!("missing.bin")),
            Just(json!("texture.png")),
            Just(json!("file:///nonexistent")),
            Just(json!("%zz")),
            Just(json!("diffuse")),
            Just(json!("")),
        ],
        Just(Value::Null),
        any::<bool>().prop_map(Value::Bool),
        Just(json!([])),
        Just(json!([0, 0, 0])),
        Just(json!({})),
        Just(json!({"index": 0})),
    ]
}

/// One edit of a JSON document: which node (index into a depth-first list of all nodes),
/// and what to do there.
#[derive(Clone, Debug)]
enum JsonEdit {
    /// Replace the node by a value.
    Replace(usize, Value),
    /// Remove the node from its parent object or array.
    Remove(usize),
    /// Add a key with a value to an object node (or push onto an array node).
    Add(usize, String, Value),
}

fn json_edits() -> impl Strategy<Value = Vec<JsonEdit>> {
    let key = prop_oneof![
        Just("indices"),
        Just("material"),
        Just("mode"),
        Just("byteStride"),
        Just("byteOffset"),
        Just("sparse"),
        Just("children"),
        Just("camera"),
        Just("NORMAL"),
        Just("TEXCOORD_0"),
        Just("extras"),
        Just("baseColorTexture"),
        Just("environment"),
        Just("brdf"),
        Just("scene"),
    ]
    .prop_map(str::to_string);
    let edit = prop_oneof![
        3 => (any::<usize>(), json_value()).prop_map(|(i, v)| JsonEdit::Replace(i, v)),
        1 => any::<usize>().prop_map(JsonEdit::Remove),
        2 => (any::<usize>(), key, json_value()).prop_map(|(i, k, v)| JsonEdit::Add(i, k, v)),
    ];
    prop::collection::vec(edit, 1..4)
}

/// JSON pointers of every node of `v`, depth first.
fn pointers(v: &Value, at: String, out: &mut Vec<String>) {
    out.push(at.clone());
    match v {
        Value::Object(map) => {
            for (k, child) in map {
                pointers(
                    child,
                    format!("{at}/{}", k.replace('~', "~0").replace('/', "~1")),
                    out,
                );
            }
        }
        Value::Array(items) => {
            for (i, child) in items.iter().enumerate() {
                pointers(child, format!("{at}/{i}"), out);
            }
        }
        _ => {}
    }
}

fn apply_json_edit(doc: &mut Value, edit: &JsonEdit) {
    let mut all = Vec::new();
    pointers(doc, String::new(), &mut all);
    let pick = |i: usize| all[i % all.len()].clone();
    match edit {
        JsonEdit::Replace(i, value) => {
            if let Some(node) = doc.pointer_mut(&pick(*i)) {
                *node = value.clone();
            }
        }
        JsonEdit::Remove(i) => {
            let pointer = pick(*i);
            let Some((parent, last)) = pointer.rsplit_once('/') else {
                return;
            };
            match doc.pointer_mut(parent) {
                Some(Value::Object(map)) => {
                    map.remove(&last.replace("~1", "/").replace("~0", "~"));
                }
                Some(Value::Array(items)) => {
                    if let Ok(k) = last.parse::<usize>() {
                        items.remove(k);
                    }
                }
                _ => {}
            }
        }
        JsonEdit::Add(i, key, value) => match doc.pointer_mut(&pick(*i)) {
            Some(Value::Object(map)) => {
                map.insert(key.clone(), value.clone());
            }
            Some(Value::Array(items)) => items.push(value.clone()),
            _ => {}
        },
    }
}

proptest! {
    #![proptest_config(Config { cases: CASES, failure_persistence: None, ..Config::default() })]

    #[test]
    fn gltf_json_with_byte_mutations_never_panics(m in mutations()) {
        let mut bytes = cornell().0.clone();
        mutate(&mut bytes, &m);
        check_gltf(&bytes)?;
    }

    #[test]
    fn glb_with_byte_mutations_never_panics(m in mutations(), header_only in any::<bool>()) {
        let mut bytes = cornell_glb();
        // Half the cases aim at the GLB and chunk headers.
        let range = if header_only { 0..20 } else { 0..usize::MAX };
        mutate_in(&mut bytes, &m, range);
        check_gltf(&bytes)?;
    }

    #[test]
    fn gltf_with_json_edits_never_panics(edits in json_edits(), binary in any::<bool>()) {
        let mut doc: Value = serde_json::from_slice(&cornell().0).expect("Cornell JSON");
        for edit in &edits {
            apply_json_edit(&mut doc, edit);
        }
        let bytes = if binary {
            if let Some(buffer) = doc.pointer_mut("/buffers/0").and_then(Value::as_object_mut) {
                buffer.remove("uri");
            }
            glb(&doc, &cornell().1)
        } else {
            serde_json::to_vec(&doc).expect("JSON")
        };
        check_gltf(&bytes)?;
    }
}

#[test]
fn gltf_seeds_load() {
    for bytes in [cornell().0.clone(), cornell_glb()] {
        let scene = load_gltf(&bytes).expect("the Cornell box loads");
        assert!(scene.geometry.triangle_count() > 0 && !scene.cameras.is_empty());
    }
}

// ---------------------------------------------------------------------------------------
// OBJ and MTL.

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
vn 0 1 0
usemtl matte
f 7/4/1 6/3/1 5/2/1 4/1/1
o lamp
v 0 2 0
v 1 2 0
v 0 2 1
usemtl light
f -3 -1 -2
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
map_Kd wood.png
newmtl light
Kd 0 0 0
Ke 10 9 8
newmtl glossy
Kd 0.1 0.2 0.3
Ks 0.5 0.5 0.5
Ns 98
";

fn check_obj(obj_bytes: &[u8], mtl: &[u8]) -> Result<(), TestCaseError> {
    let path = scene_path("scene.obj");
    match obj::load_from_bytes_with(obj_bytes, &path, |p| scene_file(p, mtl)) {
        Ok(scene) => prop_assert!(scene.validate().is_ok()),
        // A mutated `mtllib` or `map_Kd` line may name any file.
        Err(e) => check_file_error(&e, &[])?,
    }
    Ok(())
}

/// A token to put into OBJ or MTL text: indices and numbers in and out of range, and
/// keywords.
fn text_token() -> impl Strategy<Value = String> {
    prop_oneof![
        (-20i64..20).prop_map(|n| n.to_string()),
        prop_oneof![
            Just("0"),
            Just("-0"),
            Just("4294967295"),
            Just("-4294967296"),
            Just("99999999999999999999"),
            Just("nan"),
            Just("inf"),
            Just("-inf"),
            Just("1e39"),
            Just("1/2/3"),
            Just("1//"),
            Just("//"),
            Just("/"),
            Just("f"),
            Just("v"),
            Just("vt"),
            Just("vn"),
            Just("usemtl"),
            Just("mtllib"),
            Just("newmtl"),
            Just("map_Kd"),
            Just("Kd"),
            Just("Ns"),
            Just("\n"),
            Just(""),
        ]
        .prop_map(str::to_string),
    ]
}

/// Replaces the whitespace-separated token at (index mod count) by `token`.
fn replace_token(text: &str, index: usize, token: &str) -> String {
    let spans: Vec<(usize, usize)> = {
        let mut spans = Vec::new();
        let mut start = None;
        for (i, c) in text.char_indices() {
            match (c.is_whitespace(), start) {
                (false, None) => start = Some(i),
                (true, Some(s)) => {
                    spans.push((s, i));
                    start = None;
                }
                _ => {}
            }
        }
        if let Some(s) = start {
            spans.push((s, text.len()));
        }
        spans
    };
    if spans.is_empty() {
        return text.to_string();
    }
    let (a, b) = spans[index % spans.len()];
    format!("{}{token}{}", &text[..a], &text[b..])
}

proptest! {
    #![proptest_config(Config { cases: CASES, failure_persistence: None, ..Config::default() })]

    #[test]
    fn obj_and_mtl_with_byte_mutations_never_panic(m in mutations(), in_mtl in any::<bool>()) {
        let (mut obj_bytes, mut mtl) = (OBJ.as_bytes().to_vec(), MTL.as_bytes().to_vec());
        mutate(if in_mtl { &mut mtl } else { &mut obj_bytes }, &m);
        check_obj(&obj_bytes, &mtl)?;
    }

    #[test]
    fn obj_and_mtl_with_token_edits_never_panic(
        edits in prop::collection::vec((any::<usize>(), text_token(), any::<bool>()), 1..5),
    ) {
        let (mut obj_text, mut mtl) = (OBJ.to_string(), MTL.to_string());
        for (index, token, in_mtl) in &edits {
            let text = if *in_mtl { &mut mtl } else { &mut obj_text };
            *text = replace_token(text, *index, token);
        }
        check_obj(obj_text.as_bytes(), mtl.as_bytes())?;
    }
}

#[test]
fn obj_seed_loads() {
    let path = scene_path("scene.obj");
    let scene = obj::load_from_bytes_with(OBJ.as_bytes(), &path, |p| scene_file(p, MTL.as_bytes()))
        .expect("the OBJ seed loads");
    assert_eq!(scene.geometry.triangle_count(), 5);
    assert_eq!(scene.textures.len(), 1);
}

// ---------------------------------------------------------------------------------------
// MERL `.binary`.

fn merl_header() -> Vec<u8> {
    [THETA_H_BINS, THETA_D_BINS, PHI_D_BINS]
        .iter()
        .flat_map(|&d| (d as i32).to_le_bytes())
        .collect()
}

/// A valid full-size `.binary` file (every value 1.0, one bin unmeasured).
fn merl_file() -> &'static [u8] {
    static FILE: OnceLock<Vec<u8>> = OnceLock::new();
    FILE.get_or_init(|| {
        let mut bytes = merl_header();
        bytes.reserve(FILE_BYTES as usize);
        for i in 0..3 * BIN_COUNT {
            let v: f64 = if i == 1234 { -1.0 } else { 1.0 };
            bytes.extend_from_slice(&v.to_le_bytes());
        }
        bytes
    })
}

fn check_merl(bytes: &[u8]) -> Result<(), TestCaseError> {
    match MerlTable::from_bytes(bytes, "props/table.binary") {
        Ok(table) => prop_assert!(table.raw().iter().all(|v| v.is_finite())),
        Err(e) => check_file_error(&e, &["table.binary"])?,
    }
    Ok(())
}

proptest! {
    #![proptest_config(Config { cases: CASES, failure_persistence: None, ..Config::default() })]

    /// Short inputs: the header and size checks, which must not allocate a table.
    #[test]
    fn short_merl_inputs_are_rejected(m in mutations(), extra in prop::collection::vec(any::<u8>(), 0..64)) {
        let mut bytes = merl_header();
        bytes.extend_from_slice(&extra);
        mutate(&mut bytes, &m);
        prop_assume!(bytes.len() as u64 != FILE_BYTES);
        prop_assert!(MerlTable::from_bytes(&bytes, "props/table.binary").is_err());
        check_merl(&bytes)?;
    }
}

proptest! {
    #![proptest_config(Config { cases: LARGE_CASES, failure_persistence: None, ..Config::default() })]

    #[test]
    fn full_size_merl_with_mutations_never_panics(m in mutations(), header in any::<bool>()) {
        let mut bytes = merl_file().to_vec();
        let range = if header { 0..16 } else { 0..usize::MAX };
        mutate_in(&mut bytes, &m, range);
        check_merl(&bytes)?;
    }

    #[test]
    fn truncated_merl_is_rejected(keep in 0usize..FILE_BYTES as usize) {
        let bytes = &merl_file()[..keep];
        let message = MerlTable::from_bytes(bytes, "props/table.binary")
            .expect_err("truncated")
            .to_string();
        prop_assert!(message.starts_with("props/table.binary: truncated MERL file"), "{}", message);
    }
}

#[test]
fn merl_seed_loads_and_non_finite_values_are_named() {
    let table = MerlTable::from_bytes(merl_file(), "props/table.binary").expect("valid table");
    assert!(!table.is_measured(1234));
    let mut nan = merl_file().to_vec();
    let at = 12 + 8 * (2 * BIN_COUNT + 7);
    nan[at..at + 8].copy_from_slice(&f64::INFINITY.to_le_bytes());
    let message = MerlTable::from_bytes(&nan, "props/table.binary")
        .expect_err("infinite value")
        .to_string();
    assert!(
        message.contains("table.binary") && message.contains("blue"),
        "{message}"
    );
}

// ---------------------------------------------------------------------------------------
// NBRDF `.npy` tensors.

/// A version `major`.0 `.npy` file of little-endian float32 with the given shape.
fn npy_f32(shape: &[usize], values: &[f32], major: u8) -> Vec<u8> {
    let dims: Vec<String> = shape.iter().map(usize::to_string).collect();
    let shape = if dims.len() == 1 {
        format!("({},)", dims[0])
    } else {
        format!("({})", dims.join(", "))
    };
    let mut header = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {shape}, }}");
    let prefix = if major == 1 { 10 } else { 12 };
    while (prefix + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut out = b"\x93NUMPY".to_vec();
    out.extend_from_slice(&[major, 0]);
    if major == 1 {
        out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    } else {
        out.extend_from_slice(&(header.len() as u32).to_le_bytes());
    }
    out.extend_from_slice(header.as_bytes());
    for v in values {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

const SHAPES: [&[usize]; 6] = [&[6, 21], &[21], &[21, 21], &[21], &[21, 3], &[3]];

/// Valid tensor files: a small network made in code (version 1.0 and 2.0 headers), and the
/// shipped alum-bronze network where the shared data directory has it.
fn npy_networks() -> &'static Vec<[Vec<u8>; 6]> {
    static NETS: OnceLock<Vec<[Vec<u8>; 6]>> = OnceLock::new();
    NETS.get_or_init(|| {
        let made = |major: u8| {
            SHAPES.map(|shape| {
                let n: usize = shape.iter().product();
                let values: Vec<f32> = (0..n).map(|i| ((i % 7) as f32 - 3.0) * 0.05).collect();
                npy_f32(shape, &values, major)
            })
        };
        let mut nets = vec![made(1), made(2)];
        let shipped = repo_file("../shared/data/nbrdf/merl/alum-bronze");
        let read = TENSOR_NAMES.map(|name| {
            let mut path = shipped.as_os_str().to_owned();
            path.push(format!("_{name}.npy"));
            std::fs::read(PathBuf::from(path)).ok()
        });
        if read.iter().all(Option::is_some) {
            nets.push(read.map(Option::unwrap_or_default));
        }
        nets
    })
}

proptest! {
    #![proptest_config(Config { cases: CASES, failure_persistence: None, ..Config::default() })]

    #[test]
    fn npy_with_mutations_never_panics(
        m in mutations(),
        net in any::<usize>(),
        which in 0usize..6,
        header in any::<bool>(),
    ) {
        let nets = npy_networks();
        let net = &nets[net % nets.len()];
        let mut bytes = net[which].clone();
        // Half the cases aim at the magic, version, header length and header text.
        let range = if header { 0..128 } else { 0..usize::MAX };
        mutate_in(&mut bytes, &m, range);
        let name = TENSOR_NAMES[which];
        let file = format!("net_{name}.npy");
        if let Err(e) = tensor_from_bytes(&bytes, name, &scene_path(&file)) {
            check_file_error(&e, &[&file])?;
        }
        let files: [&[u8]; 6] = std::array::from_fn(|i| if i == which { &bytes[..] } else { &net[i][..] });
        match NbrdfNetwork::from_npy_bytes(files, &scene_path("net")) {
            Ok(network) => {
                let f = network.eval_angles(0.3, 0.2, 1.0);
                prop_assert!(f.is_finite() && f.min_element() >= 0.0);
            }
            Err(e) => check_file_error(&e, &[&file])?,
        }
    }
}

#[test]
fn npy_seeds_load() {
    for net in npy_networks() {
        let files: [&[u8]; 6] = std::array::from_fn(|i| &net[i][..]);
        NbrdfNetwork::from_npy_bytes(files, &scene_path("net")).expect("valid network");
    }
}

// ---------------------------------------------------------------------------------------
// latent.bin.

/// FNV-1a 64 (the file's checksum).
fn fnv1a64(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h: u64, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// Replaces the last 8 bytes by the checksum of the rest (after a mutation, so that the
/// parser gets past the checksum).
fn fix_checksum(bytes: &mut Vec<u8>) {
    if bytes.len() >= 8 {
        bytes.truncate(bytes.len() - 8);
        let sum = fnv1a64(bytes);
        bytes.extend_from_slice(&sum.to_le_bytes());
    }
}

/// The bytes of a small valid file ([`LatentFile::synthetic`] with one hidden layer of 5 and
/// [`LatentFile::with_synthetic_encoder`]) and where its f_ref table starts and ends in them.
fn latent_file() -> &'static (Vec<u8>, std::ops::Range<usize>) {
    static FILE: OnceLock<(Vec<u8>, std::ops::Range<usize>)> = OnceLock::new();
    FILE.get_or_init(|| {
        let file = LatentFile::synthetic(&[5], WeightType::F32).with_synthetic_encoder();
        let bytes = file.to_bytes();
        // After f_ref: the codes (count, then name length, name, z, offsets, residual length
        // and residual each, all f32 here), the training names (count, then length and name
        // each) and the checksum.
        let codes: usize = file
            .latents
            .iter()
            .map(|l| 4 + l.name.len() + 4 * (l.z.len() + 3) + 4 + 4 * l.residual.len())
            .sum();
        let names: usize = file.training_materials.iter().map(|n| 4 + n.len()).sum();
        let tail = 4 + codes + 4 + names + 8;
        let end = bytes.len() - tail;
        (bytes, end - 6 * BIN_COUNT..end)
    })
}

fn check_latent(bytes: &[u8]) -> Result<(), TestCaseError> {
    match LatentFile::from_bytes(bytes, Path::new("props/latent.bin")) {
        Ok(file) => {
            for latent in &file.latents {
                let net = file.decode(&latent.z, latent.offset, &latent.residual);
                let y = net.forward(&vec![0.1; file.target_widths[0]]);
                prop_assert_eq!(y.len(), *file.target_widths.last().expect("widths"));
            }
            if let Some(encoder) = &file.encoder {
                prop_assert_eq!(encoder.encode(&[[0.1; 9]]).len(), file.latent_dim);
            }
        }
        Err(e) => check_file_error(&e, &["latent.bin"])?,
    }
    Ok(())
}

proptest! {
    #![proptest_config(Config { cases: LARGE_CASES, failure_persistence: None, ..Config::default() })]

    #[test]
    fn latent_with_mutations_never_panics(
        m in mutations(),
        region in 0usize..3,
        fix in any::<bool>(),
    ) {
        let (good, f_ref) = latent_file();
        let mut bytes = good.clone();
        // Aim at the head (shapes, flags, weights), the f_ref table, or the tail (codes,
        // names, checksum).
        let range = match region {
            0 => 0..f_ref.start,
            1 => f_ref.clone(),
            _ => f_ref.end..usize::MAX,
        };
        mutate_in(&mut bytes, &m, range);
        if fix {
            fix_checksum(&mut bytes);
        }
        check_latent(&bytes)?;
    }
}

#[test]
fn latent_seed_loads() {
    let file = LatentFile::from_bytes(&latent_file().0, Path::new("props/latent.bin"))
        .expect("valid latent file");
    assert_eq!(file.latent_names(), ["gold", "blue-acrylic"]);
    assert!(file.encoder.is_some(), "the seed carries an encoder");
    let (bytes, f_ref) = latent_file();
    let dims: Vec<u8> = [90u32, 90, 180]
        .iter()
        .flat_map(|d| d.to_le_bytes())
        .collect();
    assert_eq!(
        bytes[f_ref.start - 12..f_ref.start],
        dims[..],
        "f_ref located"
    );
}

// ---------------------------------------------------------------------------------------
// Regression cases found by the fuzz targets (docs/fuzzing.md), minimised by hand.

/// `gltf` target: a primitive whose POSITION names an accessor that does not exist made
/// the `gltf` crate's own validation index out of bounds.
#[test]
fn regression_gltf_position_of_a_missing_accessor() {
    let doc = json!({
        "asset": {"version": "2.0"},
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "nodes": [{"mesh": 0}],
        "scenes": [{"nodes": [0]}]
    });
    for bytes in [serde_json::to_vec(&doc).expect("JSON"), glb(&doc, &[])] {
        let message = load_gltf(&bytes).expect_err("missing accessor").to_string();
        assert!(
            message.starts_with("/props/scene.gltf: not a valid glTF file")
                && message.contains("POSITION"),
            "{message}"
        );
    }
}

/// `gltf` target: a GLB header whose total length is below 12 bytes made the `gltf` crate
/// subtract with overflow.
#[test]
fn regression_glb_length_below_its_header() {
    for length in [0u32, 5, 11] {
        let mut bytes = cornell_glb();
        bytes[8..12].copy_from_slice(&length.to_le_bytes());
        let message = load_gltf(&bytes).expect_err("bad GLB length").to_string();
        assert!(
            message.starts_with("/props/scene.gltf: not a valid glTF file")
                && message.contains(&format!("total length of {length} bytes")),
            "{message}"
        );
    }
}

/// `obj` target: an MTL colour line with fewer than three numbers (`Ks 0 -1`) made `tobj`
/// unwrap an error.
#[test]
fn regression_mtl_colour_with_two_numbers() {
    let obj_text = "mtllib t.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl m\nf 1 2 3\n";
    for line in ["Ks 0 -1", "Kd", "Ka 1", "Ke 0.5 0.5"] {
        let mtl = format!("newmtl m\n{line}\n");
        let path = scene_path("scene.obj");
        let message = obj::load_from_bytes_with(obj_text.as_bytes(), &path, |p| {
            scene_file(p, mtl.as_bytes())
        })
        .expect_err(line)
        .to_string();
        assert!(
            message.starts_with("/props/t.mtl: cannot parse material library: line 2")
                && message.contains("needs three numbers"),
            "{message}"
        );
    }
}

/// `obj` target: a relative index reaching before the first normal (`4//-4` with one `vn`)
/// made `tobj` compute a wrapped index and overflow multiplying it.
#[test]
fn regression_obj_relative_index_before_the_first_element() {
    let path = scene_path("scene.obj");
    for (face, kind) in [
        ("f 1//1 2//1 3//-4", "normal index -4"),
        ("f 1/-2 2/1 3/1", "texture coordinate index -2"),
        ("f -5 1 2", "vertex index -5"),
        ("f 1 2 99999999999", "vertex index 99999999999"),
    ] {
        let text = format!("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n{face}\n");
        let message = obj::load_from_bytes_with(text.as_bytes(), &path, |p| scene_file(p, &[]))
            .expect_err(face)
            .to_string();
        assert!(
            message.starts_with("/props/scene.obj: cannot parse OBJ: line 6")
                && message.contains(kind),
            "{message}"
        );
    }
    // Relative indices inside the range still load.
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf -3//-1 -2//-1 -1//-1\n";
    let scene = obj::load_from_bytes_with(text.as_bytes(), &path, |p| scene_file(p, &[]))
        .expect("relative indices");
    assert_eq!(scene.geometry.triangle_count(), 1);
}

/// `npy` target: a header of nested braces (`{'descr':{{{{...`) made `npyz`'s header parser
/// take exponential time (a libFuzzer timeout at about 120 braces).
#[test]
fn regression_npy_header_of_nested_brackets() {
    for open in ["{", "(", "["] {
        let mut header = format!("{{'descr':{}", open.repeat(4000));
        header.push('\n');
        let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
        bytes.extend_from_slice(&(header.len() as u16).to_le_bytes());
        bytes.extend_from_slice(header.as_bytes());
        let started = std::time::Instant::now();
        let message = tensor_from_bytes(&bytes, "b3", Path::new("props/net_b3.npy"))
            .expect_err("nested brackets")
            .to_string();
        assert!(
            started.elapsed().as_secs_f32() < 1.0,
            "took {:?}",
            started.elapsed()
        );
        assert!(message.starts_with("props/net_b3.npy: "), "{message}");
    }
}

/// Found reading `npyz` while fixing the case above: a version 2.0 header claiming 4 GiB was
/// allocated before being read.
#[test]
fn regression_npy_header_length_beyond_the_file() {
    let mut bytes = b"\x93NUMPY\x02\x00".to_vec();
    bytes.extend_from_slice(&u32::MAX.to_le_bytes());
    bytes.extend_from_slice(b"{'descr': '<f4', ");
    let message = tensor_from_bytes(&bytes, "b3", Path::new("props/net_b3.npy"))
        .expect_err("header beyond the file")
        .to_string();
    assert!(
        message.starts_with(
            "props/net_b3.npy: not a valid .npy file: the header claims 4294967295 bytes"
        ),
        "{message}"
    );
}

/// Found reviewing what the `latent` target's decode check relies on: a hypernetwork hidden
/// width of 0 passed validation, and decoding such a file panicked (`chunks_exact(0)`).
#[test]
fn regression_latent_hidden_width_zero() {
    let bytes = LatentFile::synthetic(&[0], WeightType::F32).to_bytes();
    let message = LatentFile::from_bytes(&bytes, Path::new("props/latent.bin"))
        .expect_err("hidden width 0")
        .to_string();
    assert!(
        message.starts_with("props/latent.bin: bad shape") && message.contains("[0]"),
        "{message}"
    );
}

/// `gltf` target (with the render probe): a scene whose vertices lie near 10³⁵ units from
/// the origin loaded, then broke the BVH build (`obvhs`: surface-area costs overflow f32 and
/// an assertion on its split decisions fails). Such coordinates are now an error.
#[test]
fn regression_gltf_coordinates_near_f32_max() {
    let doc = json!({
        "asset": {"version": "2.0"},
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "nodes": [{"mesh": 0}, {"mesh": 0, "scale": [1e30, 1e30, 1e30]}],
        "scenes": [{"nodes": [0, 1]}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0.0, 0.0, 0.0], "max": [1e5, 1e5, 0.0]}],
        "bufferViews": [{"buffer": 0, "byteLength": 36}],
        "buffers": [{"byteLength": 36}]
    });
    let bin: Vec<u8> = [0f32, 0.0, 0.0, 1e5, 0.0, 0.0, 0.0, 1e5, 0.0].iter().flat_map(|v| v.to_le_bytes()).collect();
    let message = load_gltf(&glb(&doc, &bin)).expect_err("coordinates near f32::MAX").to_string();
    assert!(message.starts_with("/props/scene.gltf: vertex 4 lies 1e35 scene units from the origin"), "{message}");
}

/// `gltf` target: an image stored in a bufferView without a mimeType (or with neither a uri
/// nor a bufferView) made the `gltf` crate unwrap `None` when the texture was read.
#[test]
fn regression_gltf_image_source_without_mime_type() {
    for image in [json!({"bufferView": 0}), json!({"name": "nothing"})] {
        let doc = json!({
            "asset": {"version": "2.0"},
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "material": 0}]}],
            "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
            "textures": [{"source": 0}],
            "images": [image],
            "nodes": [{"mesh": 0}],
            "scenes": [{"nodes": [0]}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 0.0]}],
            "bufferViews": [{"buffer": 0, "byteLength": 36}],
            "buffers": [{"byteLength": 36}]
        });
        let bin: Vec<u8> = [0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0].iter().flat_map(|v| v.to_le_bytes()).collect();
        let message = load_gltf(&glb(&doc, &bin)).expect_err("bad image source").to_string();
        assert!(message.starts_with("/props/scene.gltf: not a valid glTF file: images[0]"), "{message}");
    }
}
