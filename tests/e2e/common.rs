//! Helpers shared by the end-to-end tests: scenes from TOML text, renders on a given number
//! of threads, and the statistics of image means.

use serde_json::{Value, json};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use wavetrace::math::{Vec3, Vec3A};
use wavetrace::scene::{Mesh, Transform};
use wavetrace::{
    Flow, Image, RenderScene, RenderSettings, RenderStats, flatten, render,
    scene::load::load_scene_str,
};

/// Flattens a TOML scene given as text (includes resolve against the repository's `scenes/`).
pub fn scene_from_toml(text: &str) -> RenderScene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/test-scene.toml");
    let scene = load_scene_str(&path, text).expect("test scene loads");
    flatten(&scene.world, &path).expect("test scene flattens")
}

/// The shipped seed room.
pub fn room() -> RenderScene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/room.toml");
    let scene = wavetrace::load_scene(&path).expect("room loads");
    flatten(&scene.world, &path).expect("room flattens")
}

/// Renders on a pool of `threads` threads.
pub fn render_with_threads(
    scene: &RenderScene,
    settings: &RenderSettings,
    threads: usize,
) -> (Image, RenderStats) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    let (film, stats) = pool
        .install(|| render(scene, settings, |_| Flow::Continue))
        .expect("render succeeds");
    (film.resolve(), stats)
}

/// Renders with the default thread count.
pub fn render_image(scene: &RenderScene, settings: &RenderSettings) -> Image {
    render_with_threads(scene, settings, 0).0
}

/// Luminance-free per-channel mean of an image, in f64.
pub fn mean(image: &Image) -> [f64; 3] {
    let mut s = [0.0f64; 3];
    for p in &image.pixels {
        for c in 0..3 {
            s[c] += p[c] as f64;
        }
    }
    s.map(|x| x / image.pixels.len() as f64)
}

/// The image mean of an estimator and its standard error, from two independent renders `a`
/// and `b` (different seeds): the error of (a + b) / 2 has the variance of (a - b) / 2, summed
/// over independent pixels.
pub fn mean_and_error(a: &Image, b: &Image) -> ([f64; 3], [f64; 3]) {
    let p = a.pixels.len() as f64;
    let (ma, mb) = (mean(a), mean(b));
    let mut var = [0.0f64; 3];
    for (x, y) in a.pixels.iter().zip(&b.pixels) {
        for c in 0..3 {
            let d = (x[c] - y[c]) as f64;
            var[c] += d * d / 4.0;
        }
    }
    let mean = [0, 1, 2].map(|c| (ma[c] + mb[c]) / 2.0);
    (mean, var.map(|v| v.sqrt() / p))
}

/// Renders the estimator twice with different seeds and returns its mean and standard error.
pub fn estimate(scene: &RenderScene, settings: &RenderSettings) -> ([f64; 3], [f64; 3]) {
    let (a, b) = independent_pair(scene, settings);
    mean_and_error(&a, &b)
}

/// Two renders with independent seeds (`settings.seed` and another derived from it), both
/// checked for NaN and infinite pixels: the pair [`mean_and_error`] takes.
pub fn independent_pair(scene: &RenderScene, settings: &RenderSettings) -> (Image, Image) {
    let a = render_image(scene, settings);
    let b = render_image(
        scene,
        &RenderSettings {
            seed: settings.seed ^ 0xA5A5_5A5A_1234_4321,
            ..*settings
        },
    );
    assert_finite(&a);
    assert_finite(&b);
    (a, b)
}

/// Panics if any pixel is NaN or infinite.
pub fn assert_finite(image: &Image) {
    assert!(
        image.pixels.iter().all(|p| p.is_finite()),
        "image has NaN or infinite pixels"
    );
}

/// Asserts |x - y| <= k * sqrt(ex^2 + ey^2) per channel, and prints the z-scores.
pub fn assert_agree(
    what: &str,
    (x, ex): ([f64; 3], [f64; 3]),
    (y, ey): ([f64; 3], [f64; 3]),
    k: f64,
) {
    for c in 0..3 {
        let sigma = (ex[c] * ex[c] + ey[c] * ey[c]).sqrt();
        let z = (x[c] - y[c]) / sigma;
        eprintln!(
            "{what}: channel {c}: {:.5} vs {:.5} (sigma {:.2e}, z = {z:.2})",
            x[c], y[c], sigma
        );
        assert!(
            z.abs() <= k,
            "{what}: channel {c} differs by {z:.2} sigma ({} vs {})",
            x[c],
            y[c]
        );
    }
}

/// A test scene in the box [-1, 1]^3: a TOML scene file with a camera, the given
/// `[materials]` lines, one quad per wall named in `walls` (floor, left, back, right,
/// ceiling, front; `None` leaves the wall out, opening the box), a square ceiling light of
/// half-width `light_half` and radiance `light_radiance` (material `black`, which
/// `materials` must define) just below the ceiling, and `extra_shapes` (TOML `[[shape]]`
/// tables) after them.
pub struct BoxScene<'a> {
    /// The `[camera]` table's body.
    pub camera: &'a str,
    /// The `[materials]` table's body.
    pub materials: &'a str,
    /// Material of each wall: floor (z = -1), left (x = -1), back (y = 1), right (x = 1),
    /// ceiling (z = 1), front (y = -1); all face into the box.
    pub walls: [Option<&'a str>; 6],
    /// Half-width of the square light.
    pub light_half: f32,
    /// Radiance of the light (grey).
    pub light_radiance: f32,
    /// More `[[shape]]` tables.
    pub extra_shapes: &'a str,
}

/// The camera most box tests use: from the front, a little above the middle.
pub const BOX_CAMERA: &str = "eye = [0, -0.9, 0.3]\nlook_at = [0, 0.5, -0.6]\nvfov = 75";

impl BoxScene<'_> {
    /// The scene file's text.
    pub fn toml(&self) -> String {
        const WALLS: [&str; 6] = [
            "[[-1,-1,-1],[1,-1,-1],[1,1,-1],[-1,1,-1]]",
            "[[-1,-1,-1],[-1,1,-1],[-1,1,1],[-1,-1,1]]",
            "[[-1,1,-1],[1,1,-1],[1,1,1],[-1,1,1]]",
            "[[1,-1,-1],[1,-1,1],[1,1,1],[1,1,-1]]",
            "[[-1,-1,1],[-1,1,1],[1,1,1],[1,-1,1]]",
            "[[-1,-1,-1],[-1,-1,1],[1,-1,1],[1,-1,-1]]",
        ];
        let mut text = format!(
            "\n[camera]\n{}\n[materials]\n{}\n",
            self.camera.trim(),
            self.materials.trim()
        );
        for (material, vertices) in self.walls.iter().zip(WALLS) {
            if let Some(material) = material {
                text += &format!(
                    "[[shape]]\ntype = \"quad\"\nmaterial = \"{material}\"\nvertices = {vertices}\n"
                );
            }
        }
        let (h, l) = (self.light_half, self.light_radiance);
        text += &format!(
            "[[shape]]\ntype = \"quad\"\nmaterial = \"black\"\nemission = [{l}, {l}, {l}]\n\
             vertices = [[-{h},-{h},0.99],[-{h},{h},0.99],[{h},{h},0.99],[{h},-{h},0.99]]\n"
        );
        text + self.extra_shapes.trim_start()
    }
}

/// `Err` unless the run exited with `code` without a panic, printed exactly one `error:` line
/// (and nothing else for exit code 1, where clap's usage text cannot follow) containing every
/// fragment.
pub fn check_failure(out: &Output, code: i32, fragments: &[&str]) -> Result<(), String> {
    let stderr = String::from_utf8_lossy(&out.stderr);
    let errors = stderr.lines().filter(|l| l.starts_with("error:")).count();
    let problem = if out.status.code() != Some(code) {
        format!("exit code {:?}, not {code}", out.status.code())
    } else if stderr.contains("panicked") || stderr.contains("backtrace") {
        "a panic".into()
    } else if errors != 1 || (code == 1 && stderr.lines().count() != 1) {
        "not exactly one error line".into()
    } else if let Some(missing) = fragments.iter().find(|f| !stderr.contains(*f)) {
        format!("'{missing}' missing")
    } else {
        return Ok(());
    };
    Err(format!("{problem} in: {stderr}"))
}

/// The names of the files in `dir`, sorted.
pub fn files_in(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// Set in the child process of `run_alone` to the name of the test it runs alone.
const RUN_ALONE: &str = "WAVETRACE_TEST_RUN_ALONE";

/// Runs `body` for the test `test` (its path in this binary, e.g. `large_obj::name`) in a child
/// process of this test binary that runs that test only, so that no other test shares the
/// process (for figures of the whole process, such as its peak memory). Passes on the child's
/// stderr; panics with its output unless it ran that one test and passed.
pub fn run_alone(test: &str, body: impl FnOnce()) {
    if std::env::var_os(RUN_ALONE).is_some_and(|name| name == test) {
        body();
        return;
    }
    let out = Command::new(std::env::current_exe().expect("the test binary's path"))
        .args([test, "--exact", "--nocapture", "--test-threads=1"])
        .env(RUN_ALONE, test)
        .output()
        .expect("the test binary runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    eprint!("{stderr}");
    assert!(
        out.status.success() && stdout.contains("test result: ok. 1 passed"),
        "{test} failed in its own process:\n{stdout}\n{stderr}"
    );
}

/// A glTF document whose one buffer is `<name>.bin` beside it, built from raw byte views;
/// meshopt-compressed views ([`GltfDoc::push_meshopt`]) add a fallback buffer without data.
#[derive(Default)]
pub struct GltfDoc {
    bytes: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
    /// The meshopt extension and the byte length of its fallback buffer (buffer 1).
    fallback: Option<(String, usize)>,
}

impl GltfDoc {
    /// Adds `data` as a buffer view (with `byteStride` when given) and `accessor` reading it.
    pub fn push(&mut self, data: Vec<u8>, stride: Option<usize>, accessor: Value) -> usize {
        self.align();
        let mut view =
            json!({"buffer": 0, "byteOffset": self.bytes.len(), "byteLength": data.len()});
        if let Some(stride) = stride {
            view["byteStride"] = json!(stride);
        }
        self.bytes.extend(data);
        self.add(view, accessor)
    }

    /// Pads buffer 0 so that the next view starts on a 4-byte boundary.
    fn align(&mut self) {
        while !self.bytes.len().is_multiple_of(4) {
            self.bytes.push(0);
        }
    }

    /// Adds `view` and `accessor` reading it; returns the accessor's index.
    fn add(&mut self, view: Value, mut accessor: Value) -> usize {
        self.views.push(view);
        accessor["bufferView"] = json!(self.views.len() - 1);
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }

    /// Adds a view compressed by meshopt: `compressed` goes to buffer 0, the view itself
    /// (`decoded_length` bytes, `byteStride` when given) lies in the fallback buffer 1, and
    /// `fields` (mode, filter, count, byteStride) complete the view's `extension` object.
    pub fn push_meshopt(
        &mut self,
        extension: &str,
        compressed: Vec<u8>,
        fields: Value,
        decoded_length: usize,
        stride: Option<usize>,
        accessor: Value,
    ) -> usize {
        self.align();
        let (_, fallback_length) = self.fallback.get_or_insert((extension.to_string(), 0));
        let mut ext = fields;
        ext["buffer"] = json!(0);
        ext["byteOffset"] = json!(self.bytes.len());
        ext["byteLength"] = json!(compressed.len());
        let mut view = json!({"buffer": 1, "byteOffset": *fallback_length,
                              "byteLength": decoded_length,
                              "extensions": {extension: ext}});
        if let Some(stride) = stride {
            view["byteStride"] = json!(stride);
        }
        *fallback_length += decoded_length.next_multiple_of(4);
        self.bytes.extend(compressed);
        self.add(view, accessor)
    }

    /// Adds 16-bit vertex indices.
    pub fn indices(&mut self, indices: &[u16]) -> usize {
        let data = indices.iter().flat_map(|i| i.to_le_bytes()).collect();
        self.push(
            data,
            None,
            json!({"componentType": 5123, "count": indices.len(), "type": "SCALAR"}),
        )
    }

    /// Adds vertex positions with the `min`/`max` glTF requires of them.
    pub fn positions(&mut self, values: &[[f32; 3]]) -> usize {
        let a = self.floats(values, "VEC3");
        let bound = |f: fn(f32, f32) -> f32| {
            (0..3)
                .map(|k| values.iter().map(|p| p[k]).reduce(f).unwrap_or(0.0))
                .collect::<Vec<f32>>()
        };
        self.accessors[a]["min"] = json!(bound(f32::min));
        self.accessors[a]["max"] = json!(bound(f32::max));
        a
    }

    /// Adds tightly packed floats as an accessor of type `kind` ("SCALAR", "VEC3", "MAT4", ...).
    pub fn floats<const N: usize>(&mut self, values: &[[f32; N]], kind: &str) -> usize {
        let data = values
            .iter()
            .flatten()
            .flat_map(|c| c.to_le_bytes())
            .collect();
        self.push(
            data,
            None,
            json!({"componentType": 5126, "count": values.len(), "type": kind}),
        )
    }

    pub fn write(self, dir: &Path, name: &str, mut doc: Value) -> PathBuf {
        let bin = format!("{name}.bin");
        std::fs::write(dir.join(&bin), &self.bytes).unwrap();
        doc["asset"] = json!({"version": "2.0"});
        doc["buffers"] = json!([{"byteLength": self.bytes.len(), "uri": bin}]);
        if let Some((extension, length)) = self.fallback {
            doc["buffers"]
                .as_array_mut()
                .unwrap()
                .push(json!({"byteLength": length, "extensions": {extension: {"fallback": true}}}));
        }
        doc["bufferViews"] = json!(self.views);
        doc["accessors"] = json!(self.accessors);
        let path = dir.join(name);
        std::fs::write(&path, serde_json::to_string_pretty(&doc).unwrap()).unwrap();
        path
    }
}

/// The same document as a binary glTF (buffer 0 in the BIN chunk).
pub fn glb(doc: &Value, bin: &[u8]) -> Vec<u8> {
    let mut doc = doc.clone();
    doc["buffers"][0] = json!({"byteLength": bin.len()});
    let mut json = serde_json::to_vec(&doc).unwrap();
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
        out.extend(word.to_le_bytes());
    }
    out.extend(b"JSON");
    out.extend(json);
    out.extend((bin.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(bin);
    out
}

/// The loaded meshes' vertices and their unit normals in world space.
pub fn world_vertices(scene: &wavetrace::Scene) -> Vec<(Vec3, Option<Vec3>)> {
    let mut out = Vec::new();
    for (mesh, transform) in scene.world.query::<(&Mesh, &Transform)>().iter() {
        let normal_matrix = transform.0.matrix3.inverse().transpose();
        for (i, p) in mesh.positions.iter().enumerate() {
            out.push((
                transform.0.transform_point3(*p),
                mesh.normals
                    .get(i)
                    .map(|n| Vec3::from(normal_matrix * Vec3A::from(*n)).normalize()),
            ));
        }
    }
    out
}
