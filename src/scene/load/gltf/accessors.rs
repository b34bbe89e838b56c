//! The data of glTF accessors beyond plain floats: attributes of any component type
//! (`KHR_mesh_quantization`: byte, short, normalized or not) read and dequantized as the
//! specification says, sparse accessors applied, and the error for compressed geometry
//! wavetrace cannot decode (`KHR_draco_mesh_compression`; meshopt is decoded by
//! `meshopt.rs`). Primitives (`primitives.rs`), deformations (`deform.rs`) and GPU
//! instances (`nodes.rs`) read their numbers here.

use gltf::accessor::DataType;

/// Extensions that compress geometry, with the advice given when a file needs one.
const COMPRESSION: &[(&str, &str, &str)] = &[(
    "KHR_draco_mesh_compression",
    "Draco",
    "re-export the model with mesh compression turned off (in Blender's glTF exporter: \
         untick Compression)",
)];

/// The error message for a file whose geometry can only be read through a compression
/// extension wavetrace does not decode, if `extension` is one.
pub(super) fn compression_message(extension: &str) -> Option<String> {
    COMPRESSION
        .iter()
        .find(|(name, _, _)| *name == extension)
        .map(|(name, codec, advice)| {
            format!(
                "the geometry is compressed with {codec} ({name}), which wavetrace cannot \
                 decode; {advice}"
            )
        })
}

/// The Draco message when a file uses Draco without requiring it and yet leaves accessors
/// without data (no `bufferView`, no `sparse`): the uncompressed fallback is missing.
pub(super) fn draco_without_fallback(root: &gltf::json::Root) -> Option<String> {
    let uses_draco = root
        .extensions_used
        .iter()
        .any(|e| e == "KHR_draco_mesh_compression");
    let data_missing = root
        .accessors
        .iter()
        .any(|a| a.buffer_view.is_none() && a.sparse.is_none());
    (uses_draco && data_missing).then(|| {
        compression_message("KHR_draco_mesh_compression").expect("listed")
            + " (accessors without bufferView hold only Draco data)"
    })
}

/// Component types an attribute may hold, with `KHR_mesh_quantization`'s additions; the
/// integer types of normals and tangents must be normalized (checked by [`check_attribute`]).
pub(super) fn allowed_types(semantic: &str) -> &'static [DataType] {
    use DataType::*;
    match semantic {
        "POSITION" | "TEXCOORD" => &[F32, I8, U8, I16, U16],
        "NORMAL" | "TANGENT" => &[F32, I8, I16],
        _ => &[F32],
    }
}

/// Why an accessor cannot hold a `semantic` attribute, if it cannot.
pub(super) fn check_attribute(accessor: &gltf::Accessor, semantic: &str) -> Option<String> {
    let data_type = accessor.data_type();
    if !allowed_types(semantic).contains(&data_type) {
        return Some(format!(
            "{semantic} accessor {} holds {:?} {:?}, which glTF does not allow there",
            accessor.index(),
            accessor.dimensions(),
            data_type
        ));
    }
    if matches!(semantic, "NORMAL" | "TANGENT")
        && data_type != DataType::F32
        && !accessor.normalized()
    {
        return Some(format!(
            "{semantic} accessor {} holds {data_type:?} that is not normalized, which \
             KHR_mesh_quantization does not allow",
            accessor.index()
        ));
    }
    None
}

/// One component of type `data_type` at the start of `bytes` as a float: normalized integers
/// map to [0, 1] or [-1, 1] by the glTF 2.0 rules (3.11: `max(c / 127, -1)` for bytes, ...),
/// unnormalized ones keep their value.
fn component(bytes: &[u8], data_type: DataType, normalized: bool) -> f32 {
    let (value, scale) = match data_type {
        DataType::I8 => (bytes[0] as i8 as f32, 127.0),
        DataType::U8 => (bytes[0] as f32, 255.0),
        DataType::I16 => (i16::from_le_bytes([bytes[0], bytes[1]]) as f32, 32767.0),
        DataType::U16 => (u16::from_le_bytes([bytes[0], bytes[1]]) as f32, 65535.0),
        DataType::U32 => (
            u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]) as f32,
            u32::MAX as f32,
        ),
        DataType::F32 => {
            return f32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]);
        }
    };
    if normalized {
        (value / scale).max(-1.0)
    } else {
        value
    }
}

/// Reads `N` components per element from a buffer view region, `None` when it lies outside
/// its buffer.
fn read_elements<const N: usize>(
    bytes: &[u8],
    start: usize,
    stride: usize,
    count: usize,
    data_type: DataType,
    normalized: bool,
) -> Option<Vec<[f32; N]>> {
    let size = data_type.size();
    let mut out = Vec::new();
    out.try_reserve_exact(count).ok()?;
    for i in 0..count {
        let at = start.checked_add(i.checked_mul(stride)?)?;
        let element = bytes.get(at..at.checked_add(N * size)?)?;
        out.push(std::array::from_fn(|k| {
            component(&element[k * size..], data_type, normalized)
        }));
    }
    Some(out)
}

/// The accessor's elements as floats of `N` components (any component type, normalized or
/// not, sparse substitution applied), or `None` when its data lies outside its buffers or the
/// accessor does not hold `N` components.
pub(super) fn read_floats<const N: usize>(
    accessor: &gltf::Accessor,
    buffers: &[gltf::buffer::Data],
) -> Option<Vec<[f32; N]>> {
    if accessor.dimensions().multiplicity() != N {
        return None;
    }
    let data_type = accessor.data_type();
    let normalized = accessor.normalized();
    let count = accessor.count();
    let element_size = N * data_type.size();
    let mut values = match accessor.view() {
        Some(view) => {
            let bytes = &buffers.get(view.buffer().index())?.0;
            let start = view.offset().checked_add(accessor.offset())?;
            let stride = view.stride().unwrap_or(element_size);
            read_elements::<N>(bytes, start, stride, count, data_type, normalized)?
        }
        None => vec![[0.0; N]; count],
    };
    if let Some(sparse) = accessor.sparse() {
        let indices = sparse.indices();
        let index_view = indices.view();
        let index_bytes = &buffers.get(index_view.buffer().index())?.0;
        let index_start = index_view.offset().checked_add(indices.offset())?;
        let values_part = sparse.values();
        let value_view = values_part.view();
        let value_bytes = &buffers.get(value_view.buffer().index())?.0;
        let value_start = value_view.offset().checked_add(values_part.offset())?;
        let index_type = match indices.index_type() {
            gltf::accessor::sparse::IndexType::U8 => DataType::U8,
            gltf::accessor::sparse::IndexType::U16 => DataType::U16,
            gltf::accessor::sparse::IndexType::U32 => DataType::U32,
        };
        let targets = read_elements::<1>(
            index_bytes,
            index_start,
            index_type.size(),
            sparse.count(),
            index_type,
            false,
        )?;
        let replacements = read_elements::<N>(
            value_bytes,
            value_start,
            element_size,
            sparse.count(),
            data_type,
            normalized,
        )?;
        for ([target], value) in targets.into_iter().zip(replacements) {
            *values.get_mut(target as usize)? = value;
        }
    }
    Some(values)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normalized_integers_follow_the_specification() {
        let n = |bytes: &[u8], t| component(bytes, t, true);
        assert_eq!(n(&[127], DataType::I8), 1.0);
        assert_eq!(n(&[0x81], DataType::I8), -1.0); // -127
        assert_eq!(n(&[0x80], DataType::I8), -1.0); // -128 clamps
        assert_eq!(n(&[255], DataType::U8), 1.0);
        assert_eq!(n(&[51], DataType::U8), 0.2);
        assert_eq!(n(&0x7fffi16.to_le_bytes(), DataType::I16), 1.0);
        assert_eq!(n(&(-32768i16).to_le_bytes(), DataType::I16), -1.0);
        assert_eq!(n(&65535u16.to_le_bytes(), DataType::U16), 1.0);
        assert_eq!(
            component(&(-300i16).to_le_bytes(), DataType::I16, false),
            -300.0
        );
        assert_eq!(component(&200u8.to_le_bytes(), DataType::U8, false), 200.0);
    }

    #[test]
    fn compression_messages_name_the_codec() {
        let draco = compression_message("KHR_draco_mesh_compression").unwrap();
        assert!(
            draco.contains("Draco") && draco.contains("re-export"),
            "{draco}"
        );
        // Decoded (meshopt.rs), not refused.
        assert!(compression_message("EXT_meshopt_compression").is_none());
        assert!(compression_message("KHR_texture_transform").is_none());
    }
}
