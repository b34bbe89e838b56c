//! Checks on glTF input that the `gltf` crate leaves out or reports without a place: the GLB
//! container, JSON syntax, buffer files, buffer view and accessor ranges, cameras. Each error
//! names the file, the place (byte, line and column, buffer, view, accessor, node) and the
//! problem, so that the importer (`mod.rs` and the files it lists) can read what passes without
//! surprises.

use crate::error::{Error, Result};
use std::path::Path;

/// GLB header: magic `glTF`, version 2, total length; then chunks of (length, type, data).
const GLB_HEADER: usize = 12;
const CHUNK_HEADER: usize = 8;

/// Checks the GLB container of a `.glb` file (or any input starting with the GLB magic):
/// magic, version and that the header's and each chunk's length fit in the file.
pub(super) fn check_glb(path: &Path, bytes: &[u8]) -> Result<()> {
    let fail = |message: String| Err(Error::input(path, None, message));
    if !bytes.starts_with(b"glTF") {
        let start = bytes[..bytes.len().min(4)].escape_ascii();
        return fail(format!(
            "not a binary glTF file: it starts with \"{start}\" instead of the magic \"glTF\""
        ));
    }
    if bytes.len() < GLB_HEADER {
        return fail(format!(
            "truncated: {} bytes, less than the 12-byte GLB header",
            bytes.len()
        ));
    }
    let word = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().expect("4 bytes"));
    let version = word(4);
    if version != 2 {
        return fail(format!(
            "GLB version {version} is not supported (only 2 is)"
        ));
    }
    let length = word(8) as usize;
    // gltf 1.4.1 subtracts the header size from this length unchecked (found by fuzzing).
    if length < GLB_HEADER {
        return fail(format!(
            "the GLB header gives a length of {length} bytes, less than the header itself"
        ));
    }
    if length > bytes.len() {
        return fail(format!(
            "truncated: the GLB header gives a length of {length} bytes, the file has {}",
            bytes.len()
        ));
    }
    let mut at = GLB_HEADER;
    let mut chunk = 0;
    while at < length {
        if at + CHUNK_HEADER > length {
            return fail(format!(
                "truncated: chunk {chunk} starts at byte {at} but its 8-byte header does not fit \
                 in the {length} bytes"
            ));
        }
        let chunk_length = word(at) as usize;
        let end = at + CHUNK_HEADER + chunk_length;
        if end > length {
            let kind = String::from_utf8_lossy(&bytes[at + 4..at + 8]).into_owned();
            return fail(format!(
                "truncated: chunk {chunk} ({kind:?}) needs bytes {at}..{end}, the file has {length}"
            ));
        }
        at = end;
        chunk += 1;
    }
    Ok(())
}

/// The error for a glTF whose JSON does not parse, at its line and column (in the JSON chunk
/// of a GLB). JSON has no NaN or infinity: a non-finite number written as `NaN` or
/// `Infinity` is said to be that.
pub(super) fn json_error(
    path: &Path,
    json: &[u8],
    in_glb: bool,
    error: &gltf::json::Error,
) -> Error {
    let (line, column) = (error.line(), error.column());
    let text = String::from_utf8_lossy(json);
    let at_error = text
        .lines()
        .nth(line.saturating_sub(1))
        .map(|l| l.get(column.saturating_sub(1)..).unwrap_or(""))
        .unwrap_or("");
    let word: String = at_error
        .trim_start_matches('-')
        .chars()
        .take_while(|c| c.is_ascii_alphabetic())
        .collect();
    let message = if ["nan", "inf", "infinity"].contains(&word.to_ascii_lowercase().as_str()) {
        "a number is not finite (JSON has no NaN or infinity)".to_string()
    } else {
        // serde_json appends " at line L column C": the location says that already.
        let full = error.to_string();
        match full.rfind(" at line ") {
            Some(i) => full[..i].to_string(),
            None => full,
        }
    };
    let chunk = if in_glb { "JSON chunk, " } else { "" };
    Error::input(
        path,
        Some(format!("{chunk}line {line}, column {column}")),
        format!("invalid JSON: {message}"),
    )
}

/// Whether the file's extension is `.glb`.
pub(super) fn path_is_glb(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("glb"))
}

/// Loads every buffer (external file, data URI or the GLB's BIN chunk), naming the buffer
/// and its file when one is missing, unreadable or shorter than its `byteLength`; the meshopt
/// placeholders (`placeholders[i]`, see `meshopt::placeholder_buffers`) stay empty.
pub(super) fn import_buffers(
    path: &Path,
    document: &gltf::Document,
    base: &Path,
    mut blob: Option<Vec<u8>>,
    placeholders: &[bool],
) -> Result<Vec<gltf::buffer::Data>> {
    let mut out = Vec::new();
    for buffer in document.buffers() {
        if placeholders.get(buffer.index()) == Some(&true) {
            // A meshopt fallback without data: only compressed views name it.
            out.push(gltf::buffer::Data(Vec::new()));
            continue;
        }
        let at = Some(format!("buffer {}", buffer.index()));
        let source = match buffer.source() {
            gltf::buffer::Source::Bin => "the GLB's BIN chunk".to_string(),
            gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => "its data URI".into(),
            gltf::buffer::Source::Uri(uri) => format!("'{}'", base.join(uri).display()),
        };
        let data = gltf::buffer::Data::from_source_and_blob(buffer.source(), Some(base), &mut blob)
            .map_err(|e| {
                let why = match e {
                    gltf::Error::MissingBlob => "the file has no BIN chunk".to_string(),
                    gltf::Error::Io(e) => e.to_string(),
                    other => other.to_string(),
                };
                Error::input(path, at.clone(), format!("cannot load {source}: {why}"))
            })?;
        if data.len() < buffer.length() {
            // `data` is padded to a multiple of 4: tell a file's own size.
            let held = match buffer.source() {
                gltf::buffer::Source::Uri(uri) if !uri.starts_with("data:") => {
                    std::fs::metadata(base.join(uri)).map_or(data.len() as u64, |m| m.len())
                }
                _ => data.len() as u64,
            };
            return Err(Error::input(
                path,
                at,
                format!(
                    "{source} holds {held} bytes, less than the buffer's byteLength {}",
                    buffer.length()
                ),
            ));
        }
        out.push(data);
    }
    Ok(out)
}

/// Checks that every buffer view lies inside its buffer and every accessor (sparse parts
/// included) inside its buffer view, so that reading them cannot fail half-way.
pub(super) fn check_ranges(path: &Path, document: &gltf::Document) -> Result<()> {
    for view in document.views() {
        let buffer = view.buffer();
        let end = view.offset().checked_add(view.length());
        if end.is_none_or(|end| end > buffer.length()) {
            return Err(Error::input(
                path,
                Some(format!("buffer view {}", view.index())),
                format!(
                    "bytes {}..{} lie outside buffer {} ({} bytes)",
                    view.offset(),
                    end.map_or("overflow".to_string(), |e| e.to_string()),
                    buffer.index(),
                    buffer.length()
                ),
            ));
        }
    }
    for accessor in document.accessors() {
        let at = || Some(accessor_location(document, &accessor));
        let element = accessor.size();
        // gltf 1.4.1's reader computes `count - 1` and asserts `stride >= element` (found
        // by fuzzing): both are glTF rules, checked here.
        if accessor.count() == 0 || accessor.sparse().is_some_and(|s| s.count() == 0) {
            return Err(Error::input(
                path,
                at(),
                "count is 0 (glTF requires at least 1 element)",
            ));
        }
        if let Some(view) = accessor.view() {
            let stride = view.stride().unwrap_or(element);
            if stride < element {
                return Err(Error::input(
                    path,
                    at(),
                    format!(
                        "buffer view {} has a byteStride of {stride}, less than the element size \
                         {element}",
                        view.index()
                    ),
                ));
            }
            let needed = span(accessor.offset(), accessor.count(), stride, element);
            if needed.is_none_or(|n| n > view.length()) {
                return Err(Error::input(
                    path,
                    at(),
                    format!(
                        "{} elements of {element} bytes (stride {stride}) from offset {} run \
                         past the end of buffer view {} ({} bytes)",
                        accessor.count(),
                        accessor.offset(),
                        view.index(),
                        view.length()
                    ),
                ));
            }
        }
        if let Some(sparse) = accessor.sparse() {
            let index_size = match sparse.indices().index_type() {
                gltf::accessor::sparse::IndexType::U8 => 1,
                gltf::accessor::sparse::IndexType::U16 => 2,
                gltf::accessor::sparse::IndexType::U32 => 4,
            };
            let parts = [
                (
                    "indices",
                    sparse.indices().view(),
                    sparse.indices().offset(),
                    index_size,
                ),
                (
                    "values",
                    sparse.values().view(),
                    sparse.values().offset(),
                    element,
                ),
            ];
            for (what, view, offset, size) in parts {
                if span(offset, sparse.count(), size, size).is_none_or(|n| n > view.length()) {
                    return Err(Error::input(
                        path,
                        at(),
                        format!(
                            "the sparse {what} ({} of {size} bytes from offset {offset}) run past \
                             the end of buffer view {} ({} bytes)",
                            sparse.count(),
                            view.index(),
                            view.length()
                        ),
                    ));
                }
            }
        }
    }
    Ok(())
}

/// Bytes from the start of a view that `count` elements of `size` bytes, `stride` apart,
/// starting at `offset`, reach; `None` on overflow.
fn span(offset: usize, count: usize, stride: usize, size: usize) -> Option<usize> {
    if count == 0 {
        return Some(offset);
    }
    stride
        .checked_mul(count - 1)?
        .checked_add(size)?
        .checked_add(offset)
}

/// "accessor 3 (POSITION of mesh 'Cube', primitive 0)": the accessor and its first user.
fn accessor_location(document: &gltf::Document, accessor: &gltf::Accessor) -> String {
    let index = accessor.index();
    for mesh in document.meshes() {
        for primitive in mesh.primitives() {
            let semantic = primitive
                .attributes()
                .find(|(_, a)| a.index() == index)
                .map(|(s, _)| s.to_string())
                .or_else(|| {
                    primitive
                        .indices()
                        .filter(|a| a.index() == index)
                        .map(|_| "indices".to_string())
                });
            if let Some(semantic) = semantic {
                let mesh_name = match mesh.name() {
                    Some(n) => format!("mesh '{n}'"),
                    None => format!("mesh {}", mesh.index()),
                };
                return format!(
                    "accessor {index} ({semantic} of {mesh_name}, primitive {})",
                    primitive.index()
                );
            }
        }
    }
    format!("accessor {index}")
}

/// "node 'Lamp' (index 4)": a node as errors and warnings name it.
pub(super) fn node_location(node: &gltf::Node) -> String {
    match node.name() {
        Some(n) => format!("node '{n}' (index {})", node.index()),
        None => format!("node {}", node.index()),
    }
}

/// A perspective camera's field of view must lie in (0, pi) and its aspect ratio, if given,
/// be positive and finite; `Err` holds the message.
pub(super) fn check_perspective(p: &gltf::camera::Perspective) -> std::result::Result<(), String> {
    let yfov = p.yfov();
    if !(yfov > 0.0 && yfov < std::f32::consts::PI) {
        return Err(format!(
            "camera: yfov must lie in (0, pi) radians, got {yfov}"
        ));
    }
    if let Some(aspect) = p.aspect_ratio()
        && !(aspect > 0.0 && aspect.is_finite())
    {
        return Err(format!(
            "camera: aspectRatio must be a positive number, got {aspect}"
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn glb(json: &str, bin: &[u8]) -> Vec<u8> {
        let mut json = json.as_bytes().to_vec();
        while !json.len().is_multiple_of(4) {
            json.push(b' ');
        }
        let mut out = b"glTF".to_vec();
        let total = GLB_HEADER + CHUNK_HEADER + json.len() + CHUNK_HEADER + bin.len();
        out.extend(2u32.to_le_bytes());
        out.extend((total as u32).to_le_bytes());
        out.extend((json.len() as u32).to_le_bytes());
        out.extend(b"JSON");
        out.extend(&json);
        out.extend((bin.len() as u32).to_le_bytes());
        out.extend(b"BIN\0");
        out.extend(bin);
        out
    }

    #[test]
    fn glb_containers_are_checked_before_parsing() {
        let path = Path::new("m.glb");
        let good = glb("{}", &[0; 8]);
        assert!(check_glb(path, &good).is_ok());
        let message = |bytes: &[u8]| check_glb(path, bytes).unwrap_err().to_string();
        assert!(message(&good[..good.len() - 3]).contains("the GLB header gives a length of"));
        let mut short_chunk = good.clone();
        short_chunk[8..12].copy_from_slice(&((good.len() - 3) as u32).to_le_bytes());
        let e = message(&short_chunk[..good.len() - 3]);
        assert!(e.contains("chunk 1 (\"BIN\\0\") needs bytes"), "{e}");
        assert!(message(b"glTF\x02\0").contains("less than the 12-byte GLB header"));
        let mut short_length = good.clone();
        short_length[8..12].copy_from_slice(&11u32.to_le_bytes());
        assert!(message(&short_length).contains("less than the header itself"));
        assert!(message(b"{\"asset\": 1}").contains("instead of the magic"));
        let mut v1 = good.clone();
        v1[4] = 1;
        assert!(message(&v1).contains("GLB version 1"));
    }

    #[test]
    fn json_errors_have_line_column_and_say_nan() {
        let path = Path::new("m.gltf");
        let text = "{\n  \"nodes\": [{\"matrix\": [NaN, 0]}]\n}";
        let e = serde_json::from_str::<serde_json::Value>(text).unwrap_err();
        let message = json_error(path, text.as_bytes(), false, &e).to_string();
        assert!(message.starts_with("m.gltf:line 2, column"), "{message}");
        assert!(message.contains("not finite (JSON has no NaN"), "{message}");
        let text = "{\"a\": [1, 2}";
        let e = serde_json::from_str::<serde_json::Value>(text).unwrap_err();
        let message = json_error(path, text.as_bytes(), false, &e).to_string();
        assert!(
            message.contains("line 1, column 12: invalid JSON: expected"),
            "{message}"
        );
        assert!(!message.contains(" at line "), "{message}");
    }
}
