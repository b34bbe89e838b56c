//! Meshopt-compressed buffer views (`EXT_meshopt_compression`, `KHR_meshopt_compression`)
//! decoded at load: each compressed view becomes a buffer of its own holding the decoded
//! bytes, so the accessor readers read it as any other view.
//!
//! The bitstreams (modes ATTRIBUTES, TRIANGLES, INDICES) and the filters (NONE, OCTAHEDRAL,
//! QUATERNION, EXPONENTIAL, and KHR's COLOR) are decoded by the `meshopt` crate, the bindings to
//! meshoptimizer, which is the reference implementation of both extensions. The conditions the
//! specifications put on `byteStride`, `count` and `filter` are checked here first: the decoders
//! assert them. A view that cannot be decoded keeps its uncompressed data when its buffer has
//! any; otherwise the primitives that read it are dropped, with one warning naming the view.

use super::fix::plural;
use gltf::json::Value;
use std::collections::BTreeMap;
use std::path::Path;

/// The two extensions, which differ only in KHR's COLOR filter.
const EXTENSIONS: [&str; 2] = ["EXT_meshopt_compression", "KHR_meshopt_compression"];

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Mode {
    Attributes,
    Triangles,
    Indices,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Filter {
    None,
    Octahedral,
    Quaternion,
    Exponential,
    Color,
}

/// A view's extension object, checked.
#[derive(Clone, Debug, PartialEq)]
struct Compressed {
    buffer: usize,
    offset: usize,
    length: usize,
    stride: usize,
    count: usize,
    mode: Mode,
    filter: Filter,
}

/// The extension of `extensions` (a view's or a buffer's `extensions` map), with its name.
fn extension_of(
    extensions: Option<&serde_json::Map<String, Value>>,
) -> Option<(&'static str, &Value)> {
    let extensions = extensions?;
    EXTENSIONS
        .iter()
        .find_map(|name| extensions.get(*name).map(|e| (*name, e)))
}

/// Reads and checks a view's extension object against the specification's conditions;
/// `view_length` is the parent view's `byteLength`.
fn parse(name: &str, ext: &Value, view_length: usize) -> Result<Compressed, String> {
    let number = |key: &str, default: Option<usize>| -> Result<usize, String> {
        match ext.get(key) {
            None => default.ok_or_else(|| format!("{name} has no {key}")),
            Some(v) => v
                .as_u64()
                .and_then(|n| usize::try_from(n).ok())
                .ok_or_else(|| format!("{name}'s {key} is not a non-negative integer: {v}")),
        }
    };
    let mode = match ext.get("mode").and_then(Value::as_str) {
        Some("ATTRIBUTES") => Mode::Attributes,
        Some("TRIANGLES") => Mode::Triangles,
        Some("INDICES") => Mode::Indices,
        other => return Err(format!("{name} has an unknown mode {other:?}")),
    };
    let filter = match ext.get("filter").map(|f| f.as_str()) {
        None | Some(Some("NONE")) => Filter::None,
        Some(Some("OCTAHEDRAL")) => Filter::Octahedral,
        Some(Some("QUATERNION")) => Filter::Quaternion,
        Some(Some("EXPONENTIAL")) => Filter::Exponential,
        Some(Some("COLOR")) if name == "KHR_meshopt_compression" => Filter::Color,
        Some(other) => return Err(format!("{name} has an unknown filter {other:?}")),
    };
    let c = Compressed {
        buffer: number("buffer", None)?,
        offset: number("byteOffset", Some(0))?,
        length: number("byteLength", None)?,
        stride: number("byteStride", None)?,
        count: number("count", None)?,
        mode,
        filter,
    };
    let stride_ok = match (c.mode, c.filter) {
        (Mode::Attributes, Filter::None) => {
            c.stride.is_multiple_of(4) && (4..=256).contains(&c.stride)
        }
        (Mode::Attributes, Filter::Octahedral | Filter::Color) => matches!(c.stride, 4 | 8),
        (Mode::Attributes, Filter::Quaternion) => c.stride == 8,
        (Mode::Attributes, Filter::Exponential) => {
            c.stride.is_multiple_of(4) && (4..=256).contains(&c.stride)
        }
        (Mode::Triangles | Mode::Indices, Filter::None) => matches!(c.stride, 2 | 4),
        (Mode::Triangles | Mode::Indices, _) => {
            return Err(format!("{name}: mode {:?} takes no filter", c.mode));
        }
    };
    if !stride_ok {
        return Err(format!(
            "{name}: byteStride {} is not allowed with mode {:?} and filter {:?}",
            c.stride, c.mode, c.filter
        ));
    }
    if c.count == 0 || (c.mode == Mode::Triangles && !c.count.is_multiple_of(3)) {
        return Err(format!(
            "{name}: count {} is not allowed with mode {:?}",
            c.count, c.mode
        ));
    }
    if c.count.checked_mul(c.stride) != Some(view_length) {
        return Err(format!(
            "{name}: count {} times byteStride {} is not the view's byteLength {view_length}",
            c.count, c.stride
        ));
    }
    Ok(c)
}

/// An element of `N` bytes, for the vertex decoder (which takes the element size from its
/// output type); arrays above 32 elements have no `Default`.
#[derive(Clone, Copy)]
struct Element<const N: usize>([u8; N]);

impl<const N: usize> Default for Element<N> {
    fn default() -> Self {
        Self([0; N])
    }
}

fn decode_attributes_of<const N: usize>(bytes: &[u8], count: usize) -> meshopt::Result<Vec<u8>> {
    let elements = meshopt::encoding::decode_vertex_buffer::<Element<N>>(bytes, count)?;
    Ok(elements.iter().flat_map(|e| e.0).collect())
}

/// The vertex decoder for an element size (checked: a multiple of 4 up to 256).
fn decode_attributes(bytes: &[u8], count: usize, stride: usize) -> meshopt::Result<Vec<u8>> {
    macro_rules! by_stride {
        ($($n:literal)*) => {
            match stride {
                $($n => decode_attributes_of::<$n>(bytes, count),)*
                _ => unreachable!("byteStride checked by parse"),
            }
        };
    }
    by_stride!(4 8 12 16 20 24 28 32 36 40 44 48 52 56 60 64 68 72 76 80 84 88 92 96 100 104 108
        112 116 120 124 128 132 136 140 144 148 152 156 160 164 168 172 176 180 184 188 192 196
        200 204 208 212 216 220 224 228 232 236 240 244 248 252 256)
}

/// Groups `bytes` into elements of four components of `K` bytes each (native byte order, as
/// the decoders write them).
fn lanes<const K: usize>(bytes: &[u8]) -> impl Iterator<Item = [[u8; K]; 4]> + '_ {
    bytes
        .chunks_exact(4 * K)
        .map(|e| std::array::from_fn(|i| std::array::from_fn(|b| e[i * K + b])))
}

/// Applies `filter` in place to decoded attribute data of element size `stride`.
fn apply_filter(data: &mut Vec<u8>, filter: Filter, stride: usize) {
    use meshopt::encoding::{
        decode_filter_color, decode_filter_exp, decode_filter_oct, decode_filter_quat,
    };
    match (filter, stride) {
        (Filter::None, _) => {}
        (Filter::Octahedral | Filter::Color, 4) => {
            let mut v: Vec<[i8; 4]> = lanes::<1>(data).map(|e| e.map(|c| c[0] as i8)).collect();
            if filter == Filter::Octahedral {
                decode_filter_oct(&mut v);
            } else {
                decode_filter_color(&mut v);
            }
            *data = v.iter().flatten().map(|&c| c as u8).collect();
        }
        (Filter::Octahedral | Filter::Color | Filter::Quaternion, _) => {
            let mut v: Vec<[i16; 4]> = lanes::<2>(data)
                .map(|e| e.map(i16::from_ne_bytes))
                .collect();
            match filter {
                Filter::Octahedral => decode_filter_oct(&mut v),
                Filter::Color => decode_filter_color(&mut v),
                _ => decode_filter_quat(&mut v),
            }
            *data = v.iter().flatten().flat_map(|c| c.to_ne_bytes()).collect();
        }
        (Filter::Exponential, _) => {
            // Each 32-bit value is decoded by itself, whatever the element size.
            let mut v: Vec<[u32; 1]> = data
                .chunks_exact(4)
                .map(|c| [u32::from_ne_bytes([c[0], c[1], c[2], c[3]])])
                .collect();
            decode_filter_exp(&mut v);
            *data = v.iter().flat_map(|c| c[0].to_ne_bytes()).collect();
        }
    }
}

/// Decodes a checked view from its compressed bytes; the result is `count * stride` bytes,
/// indices in little-endian order as glTF stores them.
fn decode(c: &Compressed, bytes: &[u8]) -> Result<Vec<u8>, String> {
    let failed = |e: meshopt::Error| format!("the meshopt data does not decode ({e})");
    let decoded = match c.mode {
        Mode::Attributes => {
            let mut data = decode_attributes(bytes, c.count, c.stride).map_err(failed)?;
            apply_filter(&mut data, c.filter, c.stride);
            data
        }
        Mode::Triangles | Mode::Indices => {
            use meshopt::encoding::{decode_index_buffer, decode_index_sequence};
            let triangles = c.mode == Mode::Triangles;
            if c.stride == 2 {
                let indices: Vec<u16> = if triangles {
                    decode_index_buffer(bytes, c.count)
                } else {
                    decode_index_sequence(bytes, c.count)
                }
                .map_err(failed)?;
                indices.iter().flat_map(|i| i.to_le_bytes()).collect()
            } else {
                let indices: Vec<u32> = if triangles {
                    decode_index_buffer(bytes, c.count)
                } else {
                    decode_index_sequence(bytes, c.count)
                }
                .map_err(failed)?;
                indices.iter().flat_map(|i| i.to_le_bytes()).collect()
            }
        }
    };
    debug_assert_eq!(decoded.len(), c.count * c.stride);
    Ok(decoded)
}

/// Whether the file uses either extension (listed in `extensionsUsed`, or found on a view
/// of a file that forgot to list it).
pub(super) fn uses_meshopt(root: &gltf::json::Root) -> bool {
    root.extensions_used
        .iter()
        .any(|e| EXTENSIONS.contains(&e.as_str()))
        || root
            .buffer_views
            .iter()
            .any(|v| extension_of(v.extensions.as_ref().map(|e| &e.others)).is_some())
}

/// The buffers that hold no data of their own and need none: those without `uri` marked as
/// fallbacks, or read only by compressed views (the specification's placeholder buffer, which
/// need not be marked). The GLB's BIN chunk (the first buffer without `uri` when the file has
/// one) is never among them unless it is marked.
pub(super) fn placeholder_buffers(root: &gltf::json::Root, has_bin: bool) -> Vec<bool> {
    let mut placeholder: Vec<bool> = root
        .buffers
        .iter()
        .map(|b| {
            b.uri.is_none()
                && extension_of(b.extensions.as_ref().map(|e| &e.others))
                    .is_some_and(|(_, e)| e.get("fallback") == Some(&Value::Bool(true)))
        })
        .collect();
    let mut read_plainly = vec![false; root.buffers.len()];
    let mut read_compressed = vec![false; root.buffers.len()];
    for view in &root.buffer_views {
        let compressed = extension_of(view.extensions.as_ref().map(|e| &e.others)).is_some();
        let flags = if compressed {
            &mut read_compressed
        } else {
            &mut read_plainly
        };
        if let Some(f) = flags.get_mut(view.buffer.value()) {
            *f = true;
        }
    }
    let bin = root.buffers.iter().position(|b| b.uri.is_none());
    for (i, b) in root.buffers.iter().enumerate() {
        let is_bin = has_bin && bin == Some(i);
        if b.uri.is_none() && !is_bin && read_compressed[i] && !read_plainly[i] {
            placeholder[i] = true;
        }
    }
    placeholder
}

/// Decodes every compressed view of `root`: the decoded bytes are appended to `buffers` (and
/// a matching buffer to `root`), and the view points at them. `placeholder` says which buffers
/// hold no data (from [`placeholder_buffers`]). Views that fail are reported in `warnings`.
pub(super) fn decode_views(
    path: &Path,
    root: &mut gltf::json::Root,
    buffers: &mut Vec<gltf::buffer::Data>,
    placeholder: &[bool],
    warnings: &mut Vec<String>,
) {
    let file = path.display();
    let mut failed_views = Vec::new();
    for v in 0..root.buffer_views.len() {
        let view = &root.buffer_views[v];
        let Some((name, ext)) = extension_of(view.extensions.as_ref().map(|e| &e.others)) else {
            continue;
        };
        let result = parse(name, ext, view.byte_length.0 as usize).and_then(|c| {
            let source = buffers
                .get(c.buffer)
                .filter(|_| !placeholder.get(c.buffer).copied().unwrap_or(true))
                .ok_or_else(|| format!("{name}: buffer {} holds no data", c.buffer))?;
            let bytes = c
                .offset
                .checked_add(c.length)
                .and_then(|end| source.0.get(c.offset..end))
                .ok_or_else(|| {
                    format!(
                        "{name}: bytes {}..{} lie outside buffer {} ({} bytes)",
                        c.offset,
                        c.offset.saturating_add(c.length),
                        c.buffer,
                        source.0.len()
                    )
                })?;
            // The decoders allocate the whole output at once: refuse what cannot fit rather
            // than abort.
            let size = (c.count * c.stride) as u64;
            if let Some(free) = crate::memory::available().resident
                && size > free
            {
                return Err(format!(
                    "{name}: the decoded view would take {size} bytes, more than the {free} \
                     bytes of free memory"
                ));
            }
            decode(&c, bytes)
        });
        match result {
            Ok(decoded) => {
                let view = &mut root.buffer_views[v];
                view.buffer = gltf::json::Index::new(buffers.len() as u32);
                view.byte_offset = None;
                view.byte_length = decoded.len().into();
                root.buffers.push(gltf::json::Buffer {
                    byte_length: decoded.len().into(),
                    name: None,
                    uri: None,
                    extensions: None,
                    extras: Default::default(),
                });
                buffers.push(gltf::buffer::Data(decoded));
            }
            Err(why) => {
                let fallback = view.buffer.value();
                if placeholder.get(fallback).copied().unwrap_or(true) {
                    warnings.push(format!(
                        "{file}: buffer view {v}: {why}; the primitives that read it are \
                         skipped"
                    ));
                    failed_views.push(v);
                } else {
                    warnings.push(format!(
                        "{file}: buffer view {v}: {why}; its uncompressed data in buffer \
                         {fallback} is read instead"
                    ));
                }
            }
        }
    }
    if !failed_views.is_empty() {
        drop_primitives_reading(path, root, &failed_views, warnings);
    }
}

/// Removes the primitives that read any of `views` (through an attribute, the indices or a
/// morph target, sparse parts included), with one warning counting them.
fn drop_primitives_reading(
    path: &Path,
    root: &mut gltf::json::Root,
    views: &[usize],
    warnings: &mut Vec<String>,
) {
    let accessor_reads = |a: usize| {
        root.accessors.get(a).is_some_and(|accessor| {
            let view = accessor.buffer_view.map(|v| v.value());
            let sparse = accessor.sparse.as_ref().map_or(Vec::new(), |s| {
                vec![s.indices.buffer_view.value(), s.values.buffer_view.value()]
            });
            view.into_iter().chain(sparse).any(|v| views.contains(&v))
        })
    };
    let mut dropped = BTreeMap::<usize, usize>::new();
    let mut meshes = std::mem::take(&mut root.meshes);
    for (m, mesh) in meshes.iter_mut().enumerate() {
        mesh.primitives.retain(|p| {
            let attributes = p.attributes.values().map(|a| a.value());
            let targets = p
                .targets
                .iter()
                .flatten()
                .flat_map(|t| [&t.positions, &t.normals, &t.tangents])
                .flatten()
                .map(|a| a.value());
            let reads = attributes
                .chain(p.indices.map(|i| i.value()))
                .chain(targets)
                .any(accessor_reads);
            if reads {
                *dropped.entry(m).or_default() += 1;
            }
            !reads
        });
    }
    root.meshes = meshes;
    let n: usize = dropped.values().sum();
    if n > 0 {
        let meshes: Vec<String> = dropped.keys().map(usize::to_string).collect();
        warnings.push(format!(
            "{}: {n} primitive{} skipped (meshes {}) because their compressed data does not \
             decode",
            path.display(),
            plural(n),
            meshes.join(", ")
        ));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn the_specification_conditions_are_checked() {
        let ext = |v: Value| parse("EXT_meshopt_compression", &v, 24);
        let ok = ext(
            json!({"buffer": 0, "byteLength": 10, "byteStride": 8, "count": 3,
                             "mode": "ATTRIBUTES", "filter": "QUATERNION"}),
        );
        assert_eq!(ok.unwrap().filter, Filter::Quaternion);
        for (bad, why) in [
            (
                json!({"buffer": 0, "byteLength": 10, "byteStride": 6, "count": 4,
                       "mode": "ATTRIBUTES"}),
                "byteStride 6",
            ),
            (
                json!({"buffer": 0, "byteLength": 10, "byteStride": 4, "count": 6,
                       "mode": "TRIANGLES", "filter": "OCTAHEDRAL"}),
                "takes no filter",
            ),
            (
                json!({"buffer": 0, "byteLength": 10, "byteStride": 2, "count": 15,
                       "mode": "TRIANGLES"}),
                "byteLength 24",
            ),
            (
                json!({"buffer": 0, "byteLength": 10, "byteStride": 8, "count": 3,
                       "mode": "ATTRIBUTES", "filter": "COLOR"}),
                "unknown filter",
            ),
            (
                json!({"buffer": 0, "byteLength": 10, "byteStride": 4, "count": 6,
                       "mode": "STRIPS"}),
                "unknown mode",
            ),
            (
                json!({"byteLength": 10, "byteStride": 4, "count": 6, "mode": "INDICES"}),
                "no buffer",
            ),
        ] {
            let e = ext(bad).unwrap_err();
            assert!(e.contains(why), "{e}");
        }
        let color = json!({"buffer": 0, "byteLength": 10, "byteStride": 8, "count": 3,
                           "mode": "ATTRIBUTES", "filter": "COLOR"});
        assert_eq!(
            parse("KHR_meshopt_compression", &color, 24).unwrap().filter,
            Filter::Color
        );
    }

    #[test]
    fn streams_round_trip_through_the_decoders() {
        // Odd strides and counts that are not multiples of the codec's groups of 16.
        let vertices: Vec<[u8; 12]> = (0..37u8)
            .map(|i| {
                std::array::from_fn(|k| i.wrapping_mul(7).wrapping_add((k as u8).wrapping_mul(31)))
            })
            .collect();
        let encoded = meshopt::encoding::encode_vertex_buffer(&vertices).unwrap();
        let c = Compressed {
            buffer: 0,
            offset: 0,
            length: encoded.len(),
            stride: 12,
            count: vertices.len(),
            mode: Mode::Attributes,
            filter: Filter::None,
        };
        assert_eq!(
            decode(&c, &encoded).unwrap(),
            vertices.concat(),
            "attributes"
        );

        let triangles: Vec<u32> = vec![0, 1, 2, 2, 1, 3, 3, 4, 2, 70000, 0, 1];
        let encoded = meshopt::encoding::encode_index_buffer(&triangles, 70001).unwrap();
        let c = Compressed {
            length: encoded.len(),
            stride: 4,
            count: triangles.len(),
            mode: Mode::Triangles,
            ..c
        };
        // The codec may rotate a triangle's corners (keeping its winding).
        let canonical = |t: &[u32]| {
            let first = (0..3).min_by_key(|&k| t[k]).unwrap();
            [0, 1, 2].map(|k| t[(first + k) % 3])
        };
        let decoded: Vec<u32> = decode(&c, &encoded)
            .unwrap()
            .chunks_exact(4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        assert!(
            decoded
                .chunks_exact(3)
                .map(canonical)
                .eq(triangles.chunks_exact(3).map(canonical)),
            "triangles: {decoded:?}"
        );

        let sequence: Vec<u32> = vec![5, 4, 3, 9, 9, 0, 1];
        let encoded = meshopt::encoding::encode_index_sequence(&sequence, 10).unwrap();
        let c = Compressed {
            length: encoded.len(),
            stride: 2,
            count: sequence.len(),
            mode: Mode::Indices,
            ..c
        };
        let le: Vec<u8> = sequence
            .iter()
            .flat_map(|&i| (i as u16).to_le_bytes())
            .collect();
        assert_eq!(decode(&c, &encoded).unwrap(), le, "indices");
        // Garbage is an error, not a panic.
        assert!(decode(&c, &[0x55; 7]).is_err());
    }

    #[test]
    fn filters_invert_their_encoders_within_quantisation() {
        let normals: Vec<[f32; 4]> = [[0.0, 0.0, 1.0], [0.6, -0.8, 0.0], [-0.48, 0.6, -0.64]]
            .iter()
            .map(|n| [n[0], n[1], n[2], 0.0])
            .collect();
        let encoded = meshopt::encoding::encode_filter_oct::<i16>(&normals, 16);
        let mut bytes: Vec<u8> = encoded
            .iter()
            .flatten()
            .flat_map(|c| c.to_ne_bytes())
            .collect();
        apply_filter(&mut bytes, Filter::Octahedral, 8);
        for (chunk, n) in bytes.chunks_exact(8).zip(&normals) {
            for k in 0..3 {
                let c = i16::from_ne_bytes([chunk[2 * k], chunk[2 * k + 1]]) as f32 / 32767.0;
                assert!((c - n[k]).abs() < 2e-4, "{c} vs {}", n[k]);
            }
        }
        // Values with short mantissas, which 24 bits keep exactly.
        let values: Vec<[f32; 3]> = vec![[1.5, -2250.0, 0.375], [0.0, 1.0, -1.0]];
        let encoded =
            meshopt::encoding::encode_filter_exp(&values, 24, meshopt::EncodeExpMode::Separate);
        let mut bytes: Vec<u8> = encoded
            .iter()
            .flatten()
            .flat_map(|c| c.to_ne_bytes())
            .collect();
        apply_filter(&mut bytes, Filter::Exponential, 12);
        let decoded: Vec<f32> = bytes
            .chunks_exact(4)
            .map(|c| f32::from_ne_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        assert_eq!(decoded, values.concat());
    }
}
