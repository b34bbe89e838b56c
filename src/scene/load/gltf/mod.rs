//! glTF 2.0 import (`.gltf` with external or data-URI buffers, `.glb`): the default scene's
//! node hierarchy becomes entities of the world, placed by `world_from_file` (which turns
//! glTF's +Y up into wavetrace's +Z up, see [`UpAxis`]). docs/importing.md documents what
//! becomes what.
//!
//! [`load`] reads like a table of contents, one file per part:
//! 1. read: the file's size checked against memory (`memory.rs`), the GLB container and JSON
//!    checked (`check.rs`) and fixed where a fix is safe (`fix.rs`), the required
//!    extensions checked;
//! 2. the document made with its buffers, meshopt views decoded (`meshopt.rs`), every view
//!    and accessor range checked (`check.rs`), the meshes' size checked (`memory.rs`), the
//!    features wavetrace ignores warned once each (`fix.rs`);
//! 3. materials (`materials.rs`) and the textures they read (`textures.rs`);
//! 4. spawn: the walk over the nodes (`nodes.rs`), which reads each primitive
//!    (`primitives.rs`, its numbers through `accessors.rs`, deformed by `deform.rs`) and
//!    spawns cameras and lights (`lights_cameras.rs`).

mod accessors;
pub(crate) mod animation;
mod check;
mod deform;
mod fix;
mod lights_cameras;
mod materials;
mod memory;
mod meshopt;
mod nodes;
mod primitives;
mod textures;

use crate::error::{Error, Result};
use crate::scene::load::shared::{Scene, UpAxis};
use crate::settings::SceneDefaults;
use materials::{ImportedMaterial, import_material};
use std::path::Path;

/// Loads a glTF file into a new world.
pub(super) fn load(path: &Path, up: UpAxis) -> Result<Scene> {
    let mut warnings = Vec::new();
    let (json, blob, animations) = read_json(path, &mut warnings)?;
    let (document, buffers) = open_document(path, json, blob, &mut warnings)?;
    fix::survey(path, &document, &mut warnings);
    let base = path.parent().unwrap_or(Path::new("."));
    let textures = textures::import_textures(&document, base, &buffers, path, &mut warnings);
    let mapping = lights_cameras::anisotropy_mapping(&document);
    let materials: Vec<ImportedMaterial> = document
        .materials()
        .map(|m| import_material(&m, &textures, mapping, &mut warnings))
        .collect();
    let parts = nodes::Parts {
        path,
        document: &document,
        buffers: &buffers,
        materials: &materials,
        animations: &animations,
    };
    let (mut world, root_indices) = nodes::spawn_nodes(&parts, up, &mut warnings)?;
    // The entities bound to animated nodes get the file's rig, which keeps the document and
    // the buffers to deform meshes again for each pose.
    let source = animation::GltfSource { document, buffers };
    animation::attach(
        path,
        animations,
        source,
        root_indices,
        up.world_from_file(),
        &mut world,
        &mut warnings,
    );
    Ok(Scene {
        world,
        defaults: SceneDefaults::default(),
        warnings,
    })
}

/// Reads the file's JSON (fixed by `fix.rs`) and, from a GLB, its BIN chunk; refuses files
/// that require an extension wavetrace cannot read.
fn read_json(
    path: &Path,
    warnings: &mut Vec<String>,
) -> Result<(gltf::json::Root, Option<Vec<u8>>, Option<serde_json::Value>)> {
    // Running out of memory while loading is refused with an error, not an allocation abort:
    // the file, its buffers and its meshes are each checked before they are read.
    memory::check_file(path)?;
    let bytes = std::fs::read(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        action: "cannot read",
        source,
    })?;
    let (json, blob) = if check::path_is_glb(path) || bytes.starts_with(b"glTF") {
        check::check_glb(path, &bytes)?;
        let glb = gltf::binary::Glb::from_slice(&bytes)
            .map_err(|e| Error::input(path, None, format!("not a valid glTF file: {e}")))?;
        let json = fix::parse_root(path, &glb.json, true, warnings)?;
        (json, glb.bin.map(|b| b.into_owned()))
    } else {
        (fix::parse_root(path, &bytes, false, warnings)?, None)
    };
    // `fix.rs` drops the animations before the strict reader; they are read from the JSON
    // here, channel by channel (`animation.rs`).
    let animations = animation::read_animations(&bytes);
    // The BIN chunk was copied out: the file's bytes are not kept while the buffers load.
    drop(bytes);
    crate::memory::trace_phase("read");
    for ext in &json.extensions_required {
        if let Some(message) = accessors::compression_message(ext) {
            return Err(Error::input(path, None, message));
        }
        if !fix::SUPPORTED_REQUIRED.contains(&ext.as_str()) {
            return Err(Error::input(
                path,
                None,
                format!(
                    "the file requires the extension '{ext}', which wavetrace does not support"
                ),
            ));
        }
    }
    if let Some(message) = accessors::draco_without_fallback(&json) {
        return Err(Error::input(path, None, message));
    }
    Ok((json, blob, animations))
}

/// The validated document and its buffers (meshopt-compressed views decoded), with every
/// range checked and the meshes' size checked against memory.
fn open_document(
    path: &Path,
    mut json: gltf::json::Root,
    blob: Option<Vec<u8>>,
    warnings: &mut Vec<String>,
) -> Result<(gltf::Document, Vec<gltf::buffer::Data>)> {
    // gltf-json 1.4.1's validation reads a primitive's POSITION accessor before checking that
    // it exists, and panics when it does not (found by fuzzing): `fix.rs` drops such
    // primitives before validation.
    // Checked by `read_json`: gltf-json's validation refuses required extensions it does not
    // know itself, even those with a fallback.
    json.extensions_required.clear();
    let meshopt = meshopt::uses_meshopt(&json);
    let placeholders = if meshopt {
        meshopt::placeholder_buffers(&json, blob.is_some())
    } else {
        Vec::new()
    };
    let document = document_from_json(path, json)?;
    let base = path.parent().unwrap_or(Path::new("."));
    memory::check_buffers(path, &document, base, &placeholders)?;
    let mut buffers = check::import_buffers(path, &document, base, blob, &placeholders)?;
    let document = if meshopt {
        // Compressed views become views of decoded buffers; the document is made again from
        // the changed JSON.
        let mut json = document.into_json();
        meshopt::decode_views(path, &mut json, &mut buffers, &placeholders, warnings);
        document_from_json(path, json)?
    } else {
        document
    };
    check::check_ranges(path, &document)?;
    crate::memory::trace_phase("buffers");
    memory::check_meshes(path, &document)?;
    Ok((document, buffers))
}

/// The validated document, or the validation errors in one message.
fn document_from_json(path: &Path, json: gltf::json::Root) -> Result<gltf::Document> {
    gltf::Document::from_json(json).map_err(|e| {
        Error::input(
            path,
            None,
            match e {
                gltf::Error::Validation(errors) => format!(
                    "invalid glTF: {}",
                    errors
                        .iter()
                        .map(|(p, e)| format!("{p}: {e}"))
                        .collect::<Vec<_>>()
                        .join("; ")
                ),
                other => format!("not a valid glTF file: {other}"),
            },
        )
    })
}
