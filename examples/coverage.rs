//! Measures how much of the room camera's image a model covers when `wavetrace render MODEL`
//! places it in the seed room (the bare-model rule), the figures of the coverage table in
//! `docs/importing.md`.
//!
//! ```text
//! cargo run --release --features examples --example coverage -- [--up z] [--size N] MODEL...
//! ```
//!
//! Each model is placed exactly as the command line places it (`place_in_room`), then, as in
//! `tests/e2e/placement.rs`, every room surface is made black and non-emitting and every model
//! surface a two-sided emitter of radiance 1 on a black material (textures and alpha dropped:
//! the opaque silhouette), so a pixel's value is the fraction of its area where the camera
//! sees the model. Prints, per model: its triangles, whether the command line would put it in
//! the room, the covered fraction of the pixels, of the rows and of the columns, and which
//! side faces the camera (the front, file +Z, unless the rule turns a deep model's long side).

use std::path::Path;
use wavetrace::math::{Rgb, Vec3};
use wavetrace::scene::load::{
    LoadOptions, Placement, UpAxis, import_model, load_scene_placed, room_stage_transform,
};
use wavetrace::scene::{
    AlphaCoverage, Emitter, EnvironmentLight, Material, MaterialTextures, Mesh, PunctualLight,
};
use wavetrace::{Flow, RenderSettings, flatten, render};

/// Marks the entities that came from the model file.
struct ModelPart;

struct Measured {
    triangles: usize,
    placement: Placement,
    coverage: f64,
    height: f64,
    width: f64,
    facing: &'static str,
    warnings: usize,
}

fn measure(path: &Path, up: UpAxis, size: u32) -> wavetrace::Result<Measured> {
    let options = LoadOptions {
        up,
        ..Default::default()
    };
    // What the command line does with the file (in the room, or as it is).
    let (_, placement) = load_scene_placed(path, &options)?;
    // The same file placed in the room, its entities marked.
    let mut model = import_model(path, up)?;
    let triangles = model
        .world
        .query::<&Mesh>()
        .iter()
        .map(|m| m.indices.len())
        .sum();
    // The front: file +Z, which the axis conversion puts at world -Y (for `--up z` files the
    // front is their -Y, also world -Y).
    let stage = room_stage_transform(&model.world).expect("the model has geometry");
    let front = stage.transform_vector3(Vec3::NEG_Y).normalize();
    let facing = if front.x < -0.999 {
        "front (+Z)"
    } else if stage.transform_vector3(Vec3::NEG_X).normalize().x < -0.999 {
        "right side (-X): deep model"
    } else {
        "other"
    };
    let entities: Vec<hecs::Entity> = model.world.iter().map(|e| e.entity()).collect();
    for e in entities {
        model.world.insert_one(e, ModelPart).expect("exists");
    }
    let warnings = model.warnings.len();
    let mut world = wavetrace::scene::load::place_in_room(model, path)?.world;

    let black = Material::Lambertian { albedo: Rgb::ZERO };
    let surfaces: Vec<(hecs::Entity, bool)> = world
        .query::<(hecs::Entity, &Material, Option<&ModelPart>)>()
        .iter()
        .map(|(e, _, part)| (e, part.is_some()))
        .collect();
    for (e, is_model) in surfaces {
        let _ = world.remove_one::<MaterialTextures>(e);
        let _ = world.remove_one::<AlphaCoverage>(e);
        let _ = world.remove_one::<Emitter>(e);
        world.insert_one(e, black).expect("exists");
        if is_model {
            let glow = Emitter {
                radiance: Rgb::ONE,
                two_sided: true,
            };
            world.insert_one(e, glow).expect("exists");
        }
    }
    let lights: Vec<hecs::Entity> = world
        .query::<(
            hecs::Entity,
            Option<&PunctualLight>,
            Option<&EnvironmentLight>,
        )>()
        .iter()
        .filter(|(_, p, env)| p.is_some() || env.is_some())
        .map(|(e, _, _)| e)
        .collect();
    for e in lights {
        world.despawn(e).expect("exists");
    }
    let flat = flatten(&world, path)?;
    let settings = RenderSettings {
        width: size,
        height: size,
        spp: 4,
        ..Default::default()
    };
    let (film, _) = render(&flat, &settings, |_| Flow::Continue)?;
    let image = film.resolve();
    let (w, h) = (image.width as usize, image.height as usize);
    let seen = |x: usize, y: usize| image.pixels[y * w + x].x > 0.5;
    let coverage = image.pixels.iter().map(|p| p.x as f64).sum::<f64>() / (w * h) as f64;
    let rows = (0..h).filter(|&y| (0..w).any(|x| seen(x, y))).count();
    let columns = (0..w).filter(|&x| (0..h).any(|y| seen(x, y))).count();
    Ok(Measured {
        triangles,
        placement,
        coverage,
        height: rows as f64 / h as f64,
        width: columns as f64 / w as f64,
        facing,
        warnings,
    })
}

fn main() {
    let mut up = UpAxis::Y;
    let mut size = 256;
    let mut files = Vec::new();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--up" => {
                up = match args.next().as_deref() {
                    Some("z") => UpAxis::Z,
                    Some("y") => UpAxis::Y,
                    _ => panic!("--up y|z"),
                }
            }
            "--size" => size = args.next().and_then(|s| s.parse().ok()).expect("--size N"),
            _ => files.push(a),
        }
    }
    println!(
        "| model | triangles | placed | pixels covered | image height | image width | facing the camera | load warnings |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for file in files {
        let path = Path::new(&file);
        let name = path.file_name().unwrap().to_string_lossy();
        match measure(path, up, size) {
            Ok(m) => println!(
                "| {name} | {} | {:?} | {:.1}% | {:.0}% | {:.0}% | {} | {} |",
                m.triangles,
                m.placement,
                100.0 * m.coverage,
                100.0 * m.height,
                100.0 * m.width,
                m.facing,
                m.warnings
            ),
            Err(e) => println!("| {name} | error: {e} |"),
        }
    }
}
