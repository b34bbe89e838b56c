//! Wavefront OBJ/MTL import: the OBJ is read by our streaming reader (`reader.rs`), which
//! cuts polygons into triangles as it reads (`polygons.rs`); the MTL libraries are read by
//! tobj and mapped to wavetrace's materials (`materials.rs`). Each object/group/`usemtl` run
//! becomes one entity with its own [`crate::scene::Mesh`] and material, placed by the file's
//! up-axis conversion. A polygon that cannot be cut into ears (twisted, non-planar) is
//! triangulated as a fan, with a warning; bad faces are skipped with one warning.

mod materials;
mod polygons;
mod reader;

use crate::error::Result;
use crate::math::Rgb;
use crate::scene::load::shared::{Scene, UpAxis, check_mesh};
use crate::scene::{Material, MaterialTextures, Name, TextureSlot, Transform, VertexColors};
use crate::settings::SceneDefaults;
use materials::{DEFAULT_GREY, ImportedMaterial, TextureCache};
use std::path::Path;

/// Loads an OBJ file (and its MTL libraries) into a new world.
pub(super) fn load(path: &Path, up: UpAxis) -> Result<Scene> {
    // Running out of memory while loading is refused with an error, not an allocation abort:
    // the file's size first (its meshes take about as much as its text), then each growth
    // of the reader's columns (`reader.rs`).
    if let Ok(size) = std::fs::metadata(path).map(|m| m.len()) {
        crate::memory::check_fits(
            path,
            &format!("reading the file ({:.1} MB)", size as f64 / 1e6),
            crate::memory::Needed {
                resident: size,
                address_space: size,
            },
            crate::memory::available(),
        )?;
    }
    let mut warnings = Vec::new();
    let obj = reader::read(path, materials::load_mtl_checked, &mut warnings)?;
    crate::memory::trace_phase("parse");
    let dir = path.parent().unwrap_or(Path::new(".")).to_path_buf();
    let any_material = !obj.materials.is_empty();
    materials::warn_unread_libraries(path, &obj.libraries, any_material, &mut warnings);
    let mut texture_cache = TextureCache::new();
    let imported: Vec<ImportedMaterial> = obj
        .materials
        .iter()
        .map(|m| materials::import_material(m, &dir, &mut texture_cache, &mut warnings))
        .collect();
    let world = spawn_runs(path, obj.runs, &imported, up, &mut warnings)?;
    crate::memory::trace_phase("meshes");
    Ok(Scene {
        world,
        defaults: SceneDefaults::default(),
        warnings,
    })
}

/// Spawns one entity per run, with its material (a default grey when it names none the
/// libraries define, warned once), emission, `map_Kd` texture and vertex colours.
fn spawn_runs(
    path: &Path,
    runs: Vec<reader::Run>,
    imported: &[ImportedMaterial],
    up: UpAxis,
    warnings: &mut Vec<String>,
) -> Result<hecs::World> {
    let default: ImportedMaterial = (
        Material::Lambertian {
            albedo: Rgb::splat(DEFAULT_GREY),
        },
        None,
        None,
    );
    let mut world = hecs::World::new();
    let transform = Transform(up.world_from_file());
    let mut unknown_material_warned = false;
    for run in runs {
        let name = run.name;
        let (material, emitter, texture) = match run.material {
            Some(id) if id < imported.len() => imported[id].clone(),
            Some(_) | None => {
                if !imported.is_empty() && !unknown_material_warned {
                    unknown_material_warned = true;
                    warnings.push(format!(
                        "{}: object '{name}' has no known material; using a default grey",
                        path.display()
                    ));
                }
                default.clone()
            }
        };
        check_mesh(path, &format!("object '{name}'"), &run.mesh)?;
        let entity = world.spawn((Name(name), transform, run.mesh, material));
        if let Some(colors) = run.colors.filter(|c| c.iter().all(|c| c.is_finite())) {
            world
                .insert_one(entity, VertexColors(colors))
                .expect("just spawned");
        }
        if let Some(e) = emitter {
            world.insert_one(entity, e).expect("just spawned");
        }
        if let Some(t) = texture {
            world
                .insert_one(
                    entity,
                    MaterialTextures {
                        base_color: Some(TextureSlot::new(t)),
                        ..Default::default()
                    },
                )
                .expect("just spawned");
        }
    }
    Ok(world)
}
