//! The glTF document and its buffers: parsing and validation (with guards against inputs
//! that make the `gltf` crate panic), GLB binary chunks, `data:` URIs and external files.

use super::*;

/// The glTF extensions the loader reads (see the module documentation).
pub(super) const SUPPORTED_EXTENSIONS: [&str; 9] = [
    "KHR_lights_punctual",
    "KHR_materials_clearcoat",
    "KHR_materials_emissive_strength",
    "KHR_materials_ior",
    "KHR_materials_sheen",
    "KHR_materials_specular",
    "KHR_materials_transmission",
    "KHR_materials_volume",
    "KHR_texture_transform",
];

/// Parses a `.gltf` or `.glb` file (an unsupported extension in `extensionsRequired` is an
/// error naming it) and runs the `gltf` crate's validation, which checks
/// every index into the document's arrays. Three inputs that make the `gltf` crate (1.4)
/// panic are turned into errors first: a GLB header whose total length is below the
/// header's own 12 bytes (an overflowing subtraction in `binary.rs`), a primitive whose
/// POSITION names a missing accessor (the validation indexes the accessors with it
/// unchecked, `gltf-json` `mesh.rs`), and an image in a bufferView without a mimeType or with
/// neither a uri nor a bufferView (`image.rs` unwraps them).
pub(super) fn parse_and_validate(bytes: &[u8], path: &Path) -> Result<Gltf> {
    let invalid = |e: &dyn std::fmt::Display| {
        Error::invalid_file(path, format!("not a valid glTF file: {e}"))
    };
    if let Some(header) = bytes.first_chunk::<12>().filter(|h| h.starts_with(b"glTF")) {
        let length = u32::from_le_bytes([header[8], header[9], header[10], header[11]]);
        if length < 12 {
            return Err(invalid(&format!(
                "GLB header gives a total length of {length} bytes, less than the 12-byte header"
            )));
        }
    }
    let Gltf { document, blob } =
        Gltf::from_slice_without_validation(bytes).map_err(|e| invalid(&e))?;
    let json = document.into_json();
    if let Some(name) = json.extensions_required.iter().find(|e| !SUPPORTED_EXTENSIONS.contains(&e.as_str())) {
        return Err(Error::invalid_file(
            path,
            format!(
                "requires the glTF extension {name}, which this renderer does not support (supported: {})",
                SUPPORTED_EXTENSIONS.join(", ")
            ),
        ));
    }
    let accessor_count = json.accessors.len();
    for (m, mesh) in json.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let position = ::gltf::json::validation::Checked::Valid(::gltf::Semantic::Positions);
            if let Some(index) = primitive.attributes.get(&position) {
                if index.value() >= accessor_count {
                    return Err(invalid(&format!(
                        "meshes[{m}].primitives[{p}].attributes.POSITION: accessor {} does not exist ({accessor_count} accessors)",
                        index.value()
                    )));
                }
            }
        }
    }
    for (i, image) in json.images.iter().enumerate() {
        // The `gltf` crate (1.4) unwraps both when it reads an image's source.
        match (&image.buffer_view, &image.mime_type, &image.uri) {
            (Some(_), None, _) => return Err(invalid(&format!("images[{i}]: an image in a bufferView needs a mimeType"))),
            (None, _, None) => return Err(invalid(&format!("images[{i}]: has neither a uri nor a bufferView"))),
            _ => {}
        }
    }
    let document = Document::from_json(json).map_err(|e| invalid(&e))?;
    Ok(Gltf { document, blob })
}

/// Reads every buffer of the document: the GLB binary chunk, `data:` URIs, or files relative
/// to `base`; checks each holds at least its declared `byteLength`.
pub(super) fn load_buffers(
    path: &Path,
    base: &Path,
    document: &Document,
    mut blob: Option<Vec<u8>>,
    read_file: &mut dyn FnMut(&Path) -> std::io::Result<Vec<u8>>,
) -> Result<Vec<Vec<u8>>> {
    let mut buffers = Vec::new();
    for buffer in document.buffers() {
        let i = buffer.index();
        let (data, origin) = match buffer.source() {
            ::gltf::buffer::Source::Bin => (
                blob.take().ok_or_else(|| {
                    Error::invalid_file(
                        path,
                        format!("buffer {i} refers to a GLB binary chunk the file lacks"),
                    )
                })?,
                "the GLB binary chunk".to_string(),
            ),
            ::gltf::buffer::Source::Uri(uri) => (
                read_uri(path, base, uri, &format!("buffer {i}"), read_file)?,
                describe_uri(uri),
            ),
        };
        if data.len() < buffer.length() {
            return Err(Error::invalid_file(
                path,
                format!(
                    "buffer {i} ({origin}) is truncated: {} bytes, byteLength says {}",
                    data.len(),
                    buffer.length()
                ),
            ));
        }
        buffers.push(data);
    }
    Ok(buffers)
}

/// A short description of a URI for messages (data URIs are not quoted in full).
pub(super) fn describe_uri(uri: &str) -> String {
    if uri.starts_with("data:") {
        "data URI".to_string()
    } else {
        format!("'{uri}'")
    }
}

/// The bytes a URI refers to: a base64 `data:` URI, a `file:` URI, or a percent-encoded
/// path relative to `base`. `what` names the referring object in error messages.
pub(super) fn read_uri(
    path: &Path,
    base: &Path,
    uri: &str,
    what: &str,
    read_file: &mut dyn FnMut(&Path) -> std::io::Result<Vec<u8>>,
) -> Result<Vec<u8>> {
    if uri.starts_with("data:") {
        let data = ::gltf::buffer::Data::from_source(::gltf::buffer::Source::Uri(uri), None)
            .map_err(|e| Error::invalid_file(path, format!("{what}: bad data URI: {e}")))?;
        return Ok(data.0);
    }
    let file_path = if let Some(rest) = uri
        .strip_prefix("file://")
        .or_else(|| uri.strip_prefix("file:"))
    {
        PathBuf::from(percent_decode(rest, path, what)?)
    } else if uri.contains(':') {
        return Err(Error::invalid_file(
            path,
            format!("{what}: unsupported URI scheme in '{uri}' (only data: and relative paths)"),
        ));
    } else {
        base.join(percent_decode(uri, path, what)?)
    };
    read_file(&file_path).map_err(|e| Error::io(file_path, e))
}

/// Decodes `%XX` escapes of a URI path.
pub(super) fn percent_decode(uri: &str, path: &Path, what: &str) -> Result<String> {
    let bad = || Error::invalid_file(path, format!("{what}: malformed URI '{uri}'"));
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = bytes.get(i + 1..i + 3).ok_or_else(bad)?;
            let hex = std::str::from_utf8(hex).map_err(|_| bad())?;
            out.push(u8::from_str_radix(hex, 16).map_err(|_| bad())?);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).map_err(|_| bad())
}
