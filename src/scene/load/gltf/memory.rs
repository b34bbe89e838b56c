//! What loading a glTF file will allocate, checked before it is allocated: a file whose
//! reading, buffers or meshes would not fit in the memory the process can still take is
//! refused with the error of [`crate::memory::check_fits`] rather than ending in an
//! allocation abort (flattening checks the render scene later, `flatten::check_memory`).
//!
//! The figures are upper bounds of what the loader allocates (sizes from the types; see
//! `docs/performance.md`, "Memory per triangle, and scenes that do not fit"), so a file that
//! fits is never refused here.

use crate::error::Result;
use crate::memory::{Needed, available, check_fits};
use std::path::Path;

/// Bytes per vertex of a read primitive: the mesh's positions (12), normals (12) and texture
/// coordinates (8) as `Vec3`/`Vec2`, tangents (16, with a normal map), and vertex colours
/// (16 kept, 16 more for the copy made while converting them).
const POSITION_BYTES: u64 = 12;
const NORMAL_BYTES: u64 = 12;
const UV_BYTES: u64 = 8;
const TANGENT_BYTES: u64 = 16;
const COLOR_BYTES: u64 = 32;
/// Bytes per triangle: the flat `u32` index list (12) and the mesh's `[u32; 3]` triangles
/// (12), both alive at the end of reading a primitive; a strip or fan also has its own
/// index list (4 bytes an index) besides the triangle list it is turned into.
const TRIANGLE_BYTES: u64 = 24;
const STRIP_INDEX_BYTES: u64 = 4;

/// Refuses a file whose bytes would not fit once read: the file itself and, alive with it, the
/// copy of a GLB's BIN chunk that becomes its buffer (at most the file's size) or the parsed
/// JSON of a `.gltf` (counted as much again).
pub(super) fn check_file(path: &Path) -> Result<()> {
    let Ok(size) = std::fs::metadata(path).map(|m| m.len()) else {
        return Ok(()); // reading reports the error
    };
    let bytes = size.saturating_mul(2);
    check_fits(
        path,
        &format!("reading the file ({:.1} MB)", size as f64 / 1e6),
        Needed {
            resident: bytes,
            address_space: bytes,
        },
        available(),
    )
}

/// Refuses a file whose buffers would not fit once loaded: an external file is read whole
/// (its size on disk, padded to 4 bytes), a data URI decoded (at most 3 bytes per 4
/// characters); the GLB's BIN chunk is already in memory, and meshopt placeholders
/// (`placeholders[i]`) hold nothing.
pub(super) fn check_buffers(
    path: &Path,
    document: &gltf::Document,
    base: &Path,
    placeholders: &[bool],
) -> Result<()> {
    let total: u64 = document
        .buffers()
        .filter(|b| placeholders.get(b.index()) != Some(&true))
        .map(|buffer| match buffer.source() {
            gltf::buffer::Source::Bin => 0,
            gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
                (uri.len() as u64).div_ceil(4) * 3 + 3
            }
            // A file shorter than byteLength is refused when it is read; one that cannot be
            // read too.
            gltf::buffer::Source::Uri(uri) => std::fs::metadata(base.join(uri))
                .map_or(buffer.length() as u64, |m| m.len())
                .saturating_add(3),
        })
        .fold(0, u64::saturating_add);
    check_fits(
        path,
        &format!("loading its buffers ({:.1} MB)", total as f64 / 1e6),
        Needed {
            resident: total,
            address_space: total,
        },
        available(),
    )
}

/// Refuses a file whose meshes would not fit once read from their accessors: every triangle
/// primitive's vertices and triangles (counts from its accessors, so an accessor without a
/// buffer view, all zeros, counts as much as one with data) at the bytes per element above,
/// once per read: a mesh is read once however many nodes draw it, and once more per node that
/// deforms it (skin or morph weights).
pub(super) fn check_meshes(path: &Path, document: &gltf::Document) -> Result<()> {
    let (triangles, bytes) = meshes_size(document);
    check_fits(
        path,
        &format!("reading its meshes ({triangles} triangles)"),
        Needed {
            resident: bytes,
            address_space: bytes,
        },
        available(),
    )
}

/// Triangles and bytes of reading every mesh as often as the loader reads it.
fn meshes_size(document: &gltf::Document) -> (u64, u64) {
    let mut reads = vec![0u64; document.meshes().len()];
    for node in document.nodes() {
        if let Some(mesh) = node.mesh() {
            let weights = node.weights().or(mesh.weights()).unwrap_or(&[]);
            let deformed = node.skin().is_some() || weights.iter().any(|&w| w != 0.0);
            let r = &mut reads[mesh.index()];
            *r = if deformed {
                r.saturating_add(1)
            } else {
                (*r).max(1)
            };
        }
    }
    let (mut triangles, mut bytes) = (0u64, 0u64);
    for mesh in document.meshes() {
        let mesh_reads = reads[mesh.index()];
        for primitive in mesh.primitives() {
            let (t, b) = primitive_size(&primitive);
            triangles = triangles.saturating_add(t.saturating_mul(mesh_reads));
            bytes = bytes.saturating_add(b.saturating_mul(mesh_reads));
        }
    }
    (triangles, bytes)
}

/// Triangles and bytes of one read of a primitive (none for points and lines).
fn primitive_size(primitive: &gltf::Primitive) -> (u64, u64) {
    use gltf::Semantic;
    use gltf::mesh::Mode;
    let Some(positions) = primitive.get(&Semantic::Positions) else {
        return (0, 0);
    };
    let vertices = positions.count() as u64;
    let indices = primitive.indices().map_or(vertices, |a| a.count() as u64);
    let (triangles, own_list) = match primitive.mode() {
        Mode::Triangles => (indices / 3, 0),
        Mode::TriangleStrip | Mode::TriangleFan => (
            indices.saturating_sub(2),
            indices.saturating_mul(STRIP_INDEX_BYTES),
        ),
        Mode::Points | Mode::Lines | Mode::LineLoop | Mode::LineStrip => return (0, 0),
    };
    // Attributes the loader reads only for some materials (texture coordinates of the set
    // the textures use, tangents with a normal map) are counted whenever present.
    let uvs = (0..8).any(|set| primitive.get(&Semantic::TexCoords(set)).is_some());
    let per_vertex = POSITION_BYTES
        + [
            (primitive.get(&Semantic::Normals).is_some(), NORMAL_BYTES),
            (uvs, UV_BYTES),
            (primitive.get(&Semantic::Tangents).is_some(), TANGENT_BYTES),
            (primitive.get(&Semantic::Colors(0)).is_some(), COLOR_BYTES),
        ]
        .iter()
        .filter(|(present, _)| *present)
        .map(|(_, b)| b)
        .sum::<u64>();
    let bytes = vertices
        .saturating_mul(per_vertex)
        .saturating_add(triangles.saturating_mul(TRIANGLE_BYTES))
        .saturating_add(own_list);
    (triangles, bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A document of one mesh (positions and normals of 10 vertices, a strip of 12 indices)
    /// drawn by three nodes, the last with morph weights.
    fn document() -> gltf::Document {
        let json = r#"{
            "asset": {"version": "2.0"},
            "buffers": [{"byteLength": 288}],
            "bufferViews": [{"buffer": 0, "byteLength": 240}, {"buffer": 0, "byteOffset": 240, "byteLength": 48}],
            "accessors": [
                {"bufferView": 0, "componentType": 5126, "count": 10, "type": "VEC3", "min": [0,0,0], "max": [1,1,1]},
                {"bufferView": 0, "componentType": 5126, "count": 10, "type": "VEC3"},
                {"bufferView": 1, "componentType": 5125, "count": 12, "type": "SCALAR"}
            ],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 2, "mode": 5}]}],
            "nodes": [{"mesh": 0}, {"mesh": 0}, {"mesh": 0, "weights": [0.5]}],
            "scenes": [{"nodes": [0, 1, 2]}]
        }"#;
        gltf::Gltf::from_slice(json.as_bytes()).unwrap().document
    }

    fn first_primitive(document: &gltf::Document) -> gltf::Primitive<'_> {
        document
            .meshes()
            .next()
            .unwrap()
            .primitives()
            .next()
            .unwrap()
    }

    #[test]
    fn a_primitive_counts_its_vertices_and_triangles_at_the_loaders_sizes() {
        let document = document();
        let primitive = first_primitive(&document);
        // 10 triangles from a strip of 12; 24 bytes per vertex, 24 per triangle, 4 per index.
        assert_eq!(primitive_size(&primitive), (10, 10 * 24 + 10 * 24 + 12 * 4));
    }

    #[test]
    fn a_shared_mesh_is_counted_once_and_once_more_per_deforming_node() {
        let document = document();
        let primitive = first_primitive(&document);
        let (triangles, bytes) = primitive_size(&primitive);
        // Two reads: one for the two plain nodes, one for the node with weights.
        assert_eq!(meshes_size(&document), (2 * triangles, 2 * bytes));
    }
}
