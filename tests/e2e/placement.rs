//! The bare-model rule's placement: a model in the seed room stands on the floor, in full
//! view of the room's camera, its front (+Z in the file) turned to the camera (or, for a
//! model much deeper than wide, its long side), and covers a large part of the image.
//!
//! Coverage is measured by rendering: every room surface is made black and non-emitting,
//! every model surface a two-sided emitter of radiance 1 on a black material, so a pixel's
//! value is the fraction of its area where the camera sees the model. Generated OBJ models
//! (+Y up, front +Z, as Blender exports them): a blob with a nose, a long row of cubes, a
//! flat panel facing front, the same panel edge-on, a tall thin pole.

use std::f32::consts::PI;
use std::path::{Path, PathBuf};
use wavetrace::math::{Rgb, Vec3};
use wavetrace::scene::load::{
    LoadOptions, ROOM_EYE, ROOM_FLOOR, ROOM_PROPS, ROOM_VIEW_FILL, UpAxis, load_scene_with,
};
use wavetrace::scene::{Emitter, Material, Mesh, Name, PunctualLight, Transform};
use wavetrace::{RenderSettings, flatten};

use crate::common::render_image;

/// A model: vertices (file frame, +Y up) and triangles (counter-clockwise seen from outside).
struct Model {
    name: &'static str,
    vertices: Vec<[f32; 3]>,
    triangles: Vec<[usize; 3]>,
}

impl Model {
    fn add_box(&mut self, lo: [f32; 3], hi: [f32; 3]) {
        let base = self.vertices.len();
        for c in 0..8 {
            let pick = |bit: usize, k: usize| if c & bit == 0 { lo[k] } else { hi[k] };
            self.vertices.push([pick(1, 0), pick(2, 1), pick(4, 2)]);
        }
        // Faces by corner bits (x = 1, y = 2, z = 4), each wound outward.
        for [a, b, c, d] in [
            [0, 4, 6, 2], // -x
            [1, 3, 7, 5], // +x
            [0, 1, 5, 4], // -y
            [2, 6, 7, 3], // +y
            [0, 2, 3, 1], // -z
            [4, 5, 7, 6], // +z
        ] {
            self.triangles.push([base + a, base + b, base + c]);
            self.triangles.push([base + a, base + c, base + d]);
        }
    }

    fn write_obj(&self, dir: &Path) -> PathBuf {
        let mut text = String::from("o model\n");
        for v in &self.vertices {
            text += &format!("v {} {} {}\n", v[0], v[1], v[2]);
        }
        for t in &self.triangles {
            text += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
        }
        let path = dir.join(format!("{}.obj", self.name));
        std::fs::write(&path, text).unwrap();
        path
    }
}

fn empty(name: &'static str) -> Model {
    Model {
        name,
        vertices: vec![],
        triangles: vec![],
    }
}

/// A lumpy sphere of radius about 1, with a nose: the vertex towards +Z sticks out to 1.4.
fn blob() -> Model {
    let mut m = empty("blob");
    let (rings, segments) = (16, 24);
    m.vertices.push([0.0, 1.0, 0.0]);
    for r in 1..rings {
        let theta = PI * r as f32 / rings as f32;
        for s in 0..segments {
            let phi = 2.0 * PI * s as f32 / segments as f32;
            let lump = 1.0 + 0.08 * (3.0 * phi).sin() * theta.sin();
            // phi = 0 points at +Z; the equator's vertex there is the nose.
            let nose = if r == rings / 2 && s == 0 { 1.4 } else { 1.0 };
            let radius = lump * nose;
            m.vertices.push([
                radius * theta.sin() * phi.sin(),
                radius * theta.cos(),
                radius * theta.sin() * phi.cos(),
            ]);
        }
    }
    m.vertices.push([0.0, -1.0, 0.0]);
    let ring = |r: usize, s: usize| 1 + (r - 1) * segments + s % segments;
    let bottom = m.vertices.len() - 1;
    for s in 0..segments {
        m.triangles.push([0, ring(1, s), ring(1, s + 1)]);
        m.triangles
            .push([bottom, ring(rings - 1, s + 1), ring(rings - 1, s)]);
        for r in 1..rings - 1 {
            let (a, b, c, d) = (
                ring(r, s),
                ring(r + 1, s),
                ring(r + 1, s + 1),
                ring(r, s + 1),
            );
            m.triangles.push([a, b, c]);
            m.triangles.push([a, c, d]);
        }
    }
    m
}

fn row_of_cubes() -> Model {
    let mut m = empty("row");
    for i in 0..4 {
        let x = i as f32 * 1.25;
        m.add_box([x, 0.0, 0.0], [x + 1.0, 1.0, 1.0]);
    }
    m
}

/// A 2 x 1.5 panel facing +Z (the front), one-sided.
fn panel_front() -> Model {
    let mut m = empty("panel");
    m.vertices = vec![
        [-1.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.5, 0.0],
        [-1.0, 1.5, 0.0],
    ];
    m.triangles = vec![[0, 1, 2], [0, 2, 3]];
    m
}

/// The same panel turned to face +X: edge-on from the front.
fn panel_side() -> Model {
    let mut m = panel_front();
    m.name = "panel-side";
    for v in &mut m.vertices {
        *v = [0.0, v[1], -v[0]];
    }
    m
}

fn pole() -> Model {
    let mut m = empty("pole");
    m.add_box([-0.05, 0.0, -0.05], [0.05, 4.0, 0.05]);
    m
}

/// The world position of file-frame point `p` of the placed model (entity "model").
fn placed(world: &hecs::World, p: [f32; 3]) -> Vec3 {
    placed_entity(world, "model", p)
}

/// The world position of point `p` of the placed entity named `name`, in its own frame.
fn placed_entity(world: &hecs::World, name: &str, p: [f32; 3]) -> Vec3 {
    let (_, t) = world
        .query::<(&Name, &Transform)>()
        .iter()
        .find(|(n, _)| n.0 == name)
        .map(|(n, t)| (n.0.clone(), *t))
        .expect("the model is in the room");
    // The OBJ loader keeps the file's positions; its transform turns them +Z up.
    t.0.transform_point3(Vec3::from(p))
}

struct Measured {
    /// Fraction of the image's pixels that see the model.
    coverage: f64,
    /// Fraction of the image's rows that see the model anywhere.
    height: f64,
    /// Fraction of the image's columns that see the model anywhere.
    width: f64,
}

/// Renders the model (the entities named `name`) alone as a white emitter in the
/// blacked-out room, 128 x 128.
fn measure(mut world: hecs::World, path: &Path, name: &str) -> Measured {
    let model: Vec<hecs::Entity> = world
        .query::<(hecs::Entity, &Name)>()
        .iter()
        .filter(|(_, n)| n.0 == name)
        .map(|(e, _)| e)
        .collect();
    let others: Vec<hecs::Entity> = world
        .query::<(hecs::Entity, &Material)>()
        .iter()
        .map(|(e, _)| e)
        .filter(|e| !model.contains(e))
        .collect();
    let black = Material::Lambertian { albedo: Rgb::ZERO };
    for e in others {
        world.insert_one(e, black).unwrap();
        let _ = world.remove_one::<Emitter>(e);
    }
    for e in model {
        let glow = Emitter {
            radiance: Rgb::ONE,
            two_sided: true,
        };
        world.insert(e, (black, glow)).unwrap();
    }
    let lights: Vec<hecs::Entity> = world
        .query::<(hecs::Entity, &PunctualLight)>()
        .iter()
        .map(|(e, _)| e)
        .collect();
    for e in lights {
        world.despawn(e).unwrap();
    }
    let flat = flatten(&world, path).unwrap();
    let settings = RenderSettings {
        width: 128,
        height: 128,
        spp: 4,
        ..Default::default()
    };
    let image = render_image(&flat, &settings);
    let (w, h) = (image.width as usize, image.height as usize);
    let seen = |x: usize, y: usize| image.pixels[y * w + x].x > 0.5;
    let coverage = image.pixels.iter().map(|p| p.x as f64).sum::<f64>() / (w * h) as f64;
    let rows = (0..h).filter(|&y| (0..w).any(|x| seen(x, y))).count();
    let columns = (0..w).filter(|&x| (0..h).any(|y| seen(x, y))).count();
    Measured {
        coverage,
        height: rows as f64 / h as f64,
        width: columns as f64 / w as f64,
    }
}

fn scratch(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("wavetrace-place-{}-{test}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn bare_models_stand_on_the_floor_face_the_camera_and_fill_the_image() {
    let dir = scratch("stage");
    // (model, least coverage, least image height, the file-frame direction that must face
    // the camera)
    let cases: [(Model, f64, f64, [f32; 3]); 5] = [
        (blob(), 0.12, 0.40, [0.0, 0.0, 1.0]),
        (row_of_cubes(), 0.12, 0.0, [0.0, 0.0, 1.0]),
        (panel_front(), 0.12, 0.40, [0.0, 0.0, 1.0]),
        // Edge-on from the front (its face towards +X): kept as it is, its -X side (its right)
        // towards the camera.
        (panel_side(), 0.12, 0.40, [-1.0, 0.0, 0.0]),
        (pole(), 0.0, 0.40, [0.0, 0.0, 1.0]),
    ];
    let mut report = Vec::new();
    for (model, least_coverage, least_height, facing) in cases {
        let path = model.write_obj(&dir);
        let scene = load_scene_with(&path, &LoadOptions::default()).expect("loads");
        let world = &scene.world;
        let points: Vec<Vec3> = model.vertices.iter().map(|&p| placed(world, p)).collect();
        let lowest = points.iter().map(|p| p.z).fold(f32::INFINITY, f32::min);
        assert!(
            (lowest - ROOM_FLOOR).abs() < 1e-4,
            "{}: stands on the floor ({lowest})",
            model.name
        );
        for p in &points {
            let d = p.x - ROOM_EYE.x;
            assert!(
                p.y.abs().max(p.z.abs()) <= ROOM_VIEW_FILL * d * (1.0 + 1e-4),
                "{}: {p} is out of the camera's view",
                model.name
            );
        }
        // Facing: the file's `facing` direction, placed, points at the camera (-x).
        let origin = placed(world, [0.0, 0.0, 0.0]);
        let toward = (placed(world, facing) - origin).normalize();
        assert!(
            toward.x < -0.999,
            "{}: {facing:?} faces {toward}, not the camera",
            model.name
        );
        // The room's props that the model would stand in are gone; the light stays.
        let names: Vec<String> = world.query::<&Name>().iter().map(|n| n.0.clone()).collect();
        assert!(names.iter().any(|n| n == "area light"));
        for prop in ROOM_PROPS.iter().filter(|p| names.iter().any(|n| n == *p)) {
            let (plo, phi) = prop_box(world, prop);
            let (mlo, mhi) = points
                .iter()
                .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| {
                    (lo.min(*p), hi.max(*p))
                });
            assert!(
                !(plo.cmple(mhi).all() && phi.cmpge(mlo).all()),
                "{}: {prop} overlaps the model",
                model.name
            );
        }
        let m = measure(scene.world, &path, "model");
        report.push(format!(
            "{}: {:.1}% of the pixels, {:.0}% of the height, {:.0}% of the width",
            model.name,
            100.0 * m.coverage,
            100.0 * m.height,
            100.0 * m.width
        ));
        assert!(
            m.coverage >= least_coverage && m.height >= least_height,
            "{}",
            report.last().unwrap()
        );
    }
    eprintln!("{}", report.join("\n"));
}

#[test]
fn the_readme_model_stands_in_the_room_facing_and_filling_the_camera() {
    // `assets/suzanne.glb`, a Blender export (one mesh node "Suzanne", no transform), whose
    // face is glTF's front (+Z): what `wavetrace render assets/suzanne.glb` shows.
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/suzanne.glb");
    let scene = load_scene_with(&path, &LoadOptions::default()).expect("loads");
    let origin = placed_entity(&scene.world, "Suzanne", [0.0, 0.0, 0.0]);
    let toward = (placed_entity(&scene.world, "Suzanne", [0.0, 0.0, 1.0]) - origin).normalize();
    assert!(
        toward.x < -0.999,
        "the face looks along {toward}, not at the camera"
    );
    let m = measure(scene.world, &path, "Suzanne");
    // Measured: 18.3% of the pixels at 256 x 256 (examples/coverage.rs), 61% of the height.
    assert!(
        m.coverage >= 0.12 && m.height >= 0.40,
        "Suzanne covers {:.1}% of the pixels, {:.0}% of the height",
        100.0 * m.coverage,
        100.0 * m.height
    );
}

fn prop_box(world: &hecs::World, name: &str) -> (Vec3, Vec3) {
    let mut single = hecs::World::new();
    for (n, mesh, t) in world.query::<(&Name, &Mesh, &Transform)>().iter() {
        if n.0 == name {
            single.spawn((mesh.clone(), *t));
        }
    }
    for (n, s, t) in world
        .query::<(&Name, &wavetrace::scene::Sphere, &Transform)>()
        .iter()
    {
        if n.0 == name {
            single.spawn((*s, *t));
        }
    }
    wavetrace::scene::load::bounding_box(&single).unwrap()
}

#[test]
fn up_z_keeps_a_z_up_file_standing() {
    // The pole written +Z up: with --up z it stands (tall), read as +Y up it would lie.
    let dir = scratch("up");
    let mut m = pole();
    m.name = "pole-z-up";
    for v in &mut m.vertices {
        *v = [v[0], -v[2], v[1]];
    }
    let path = m.write_obj(&dir);
    let height = |up| {
        let options = LoadOptions {
            up,
            ..Default::default()
        };
        let scene = load_scene_with(&path, &options).unwrap();
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for (n, mesh, t) in scene.world.query::<(&Name, &Mesh, &Transform)>().iter() {
            if n.0 == "model" {
                for p in &mesh.positions {
                    let z = t.0.transform_point3(*p).z;
                    lo = lo.min(z);
                    hi = hi.max(z);
                }
            }
        }
        (hi - lo, m.vertices.len())
    };
    let (standing, _) = height(UpAxis::Z);
    let (lying, _) = height(UpAxis::Y);
    assert!(standing > 10.0 * lying, "{standing} vs {lying}");
}
