//! The TOML scene format: cameras, named materials, and the built-in primitives (triangle,
//! quad, polygon, tetrahedron, sphere) with transforms. A file may include others; the
//! including file's camera and `[render]` settings win, its materials replace same-named ones,
//! and shapes and models accumulate. `[[model]]` tables place glTF/OBJ files (relative to
//! the scene file that names them) through `place.rs`. docs/scene-format.md documents the
//! format with `scenes/room.toml`.

use super::model::{LightUnits, import_model_with};
use super::place::{self, bounding_box};
use super::shared::{Scene, UpAxis};
use crate::error::{Error, Result, closest_match};
use crate::math::{Affine3A, Quat, Vec3};
use crate::scene::{
    Camera, Emitter, EnvironmentLight, EnvironmentSource, FresnelModel, Material, Mesh, Name,
    Sphere, Transform,
};
use crate::settings::{MAX_IMAGE_SIDE, MAX_PIXELS, MAX_SHADOW_RAYS, SceneDefaults};
use serde::Deserialize;
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use toml::Spanned;

/// The hexagonal room, built into the binary so that it works from any directory.
pub const BUILTIN_ROOM: &str = include_str!("../../../scenes/room.toml");

/// Include target that names the built-in hexagonal room instead of a file.
const BUILTIN_ROOM_NAME: &str = "builtin:room";

/// The built-in hexagonal room, loaded.
pub(super) fn builtin_room() -> Result<Scene> {
    load(Path::new(BUILTIN_ROOM_NAME), BUILTIN_ROOM)
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    #[serde(default)]
    include: Vec<Spanned<String>>,
    camera: Option<Spanned<CameraDef>>,
    render: Option<RenderDef>,
    environment: Option<Spanned<EnvironmentDef>>,
    #[serde(default)]
    materials: BTreeMap<String, Spanned<MaterialDef>>,
    #[serde(default, rename = "shape")]
    shapes: Vec<Spanned<ShapeDef>>,
    #[serde(default, rename = "model")]
    models: Vec<Spanned<ModelDef>>,
}

/// `[[model]]`: a glTF or OBJ file placed in the scene.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ModelDef {
    /// Path relative to the scene file.
    file: Spanned<String>,
    /// Where the model's anchor lands: its origin, or with `fit` its bottom centre. Without
    /// it, the model stands on the hexagonal room's stage as a bare model does (and then takes no
    /// `rotation`, `scale` or `fit`).
    #[serde(default)]
    position: Option<[f32; 3]>,
    /// Degrees about x, then y, then z (about the anchor).
    #[serde(default)]
    rotation: Option<[f32; 3]>,
    #[serde(default)]
    scale: Option<ScaleDef>,
    /// The file's up axis; "y" files are turned to +z up.
    #[serde(default)]
    up: UpAxis,
    /// Scale so that the largest extent equals this, anchored at the bottom centre.
    fit: Option<f32>,
    /// A material of the scene replacing the file's.
    material: Option<Spanned<String>>,
    /// How the file's glTF light intensities are read ("spec", "unitless", "raw").
    #[serde(default)]
    light_units: LightUnits,
}

/// `[camera]`: a pinhole looking from `eye` at `look_at`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraDef {
    eye: [f32; 3],
    look_at: [f32; 3],
    #[serde(default = "z_up")]
    up: [f32; 3],
    /// Vertical field of view in degrees.
    vfov: f32,
}

/// `[environment]`: the light at infinity, a constant `color` or an equirectangular `file`
/// (relative to the scene file).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct EnvironmentDef {
    color: Option<[f32; 3]>,
    file: Option<String>,
    #[serde(default = "unit")]
    strength: f32,
    /// Degrees about +Z.
    #[serde(default)]
    rotation: f32,
    #[serde(default)]
    hide_from_camera: bool,
}

impl EnvironmentDef {
    /// The component, with the file resolved against the scene file's folder.
    fn resolve(&self, source: &Source, offset: usize) -> Result<EnvironmentLight> {
        let err = |m: &str| source.error(offset, format!("environment: {m}"));
        let source_of = match (&self.color, &self.file) {
            (Some(rgb), None) => EnvironmentSource::Color(Vec3::from(*rgb)),
            (None, Some(file)) => {
                let base = source.path.parent().unwrap_or(Path::new("."));
                EnvironmentSource::File(base.join(file))
            }
            _ => {
                return Err(err(
                    "give exactly one of color = [r, g, b] or file = \"...\"",
                ));
            }
        };
        if !(self.strength.is_finite() && self.strength >= 0.0) {
            return Err(err(&format!(
                "strength must be a finite number >= 0, got {}",
                self.strength
            )));
        }
        if !self.rotation.is_finite() {
            return Err(err("rotation must be a finite number of degrees"));
        }
        Ok(EnvironmentLight {
            source: source_of,
            strength: self.strength,
            rotation_degrees: self.rotation,
            visible_to_camera: !self.hide_from_camera,
        })
    }
}

/// `[render]`: settings the CLI's flags may override. Spanned so that a bad value is
/// reported where it stands; the limits are those of [`crate::settings`].
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RenderDef {
    width: Option<Spanned<u32>>,
    height: Option<Spanned<u32>>,
    spp: Option<Spanned<u32>>,
    shadow_rays: Option<Spanned<u32>>,
    sampler: Option<crate::math::rng::Sampler>,
    filter: Option<crate::filter::FilterKind>,
    filter_width: Option<Spanned<f32>>,
}

impl RenderDef {
    /// Checks every stated value against the renderer's limits, before anything is allocated.
    fn validate(&self, source: &Source) -> Result<SceneDefaults> {
        let check = |value: &Option<Spanned<u32>>,
                     range: std::ops::RangeInclusive<u32>,
                     what: &str|
         -> Result<Option<u32>> {
            match value {
                Some(v) if !range.contains(v.get_ref()) => Err(source.error(
                    v.span().start,
                    if *range.end() == u32::MAX {
                        format!(
                            "{what} must be at least {}, got {}",
                            range.start(),
                            v.get_ref()
                        )
                    } else {
                        format!(
                            "{what} {} is outside the accepted range {}..={}",
                            v.get_ref(),
                            range.start(),
                            range.end()
                        )
                    },
                )),
                _ => Ok(value.as_ref().map(|v| *v.get_ref())),
            }
        };
        let defaults = SceneDefaults {
            width: check(&self.width, 1..=MAX_IMAGE_SIDE, "width")?,
            height: check(&self.height, 1..=MAX_IMAGE_SIDE, "height")?,
            spp: check(&self.spp, 1..=u32::MAX, "spp (samples per pixel)")?,
            shadow_rays: check(&self.shadow_rays, 1..=MAX_SHADOW_RAYS, "shadow_rays")?,
            sampler: self.sampler,
            filter: self.filter,
            filter_width: match &self.filter_width {
                Some(w) => Some(
                    crate::filter::PixelFilter::check_width(*w.get_ref())
                        .map(|()| *w.get_ref())
                        .map_err(|m| source.error(w.span().start, m))?,
                ),
                None => None,
            },
        };
        if let (Some(w), Some(h), Some(at)) = (defaults.width, defaults.height, &self.height)
            && w as u64 * h as u64 > MAX_PIXELS
        {
            return Err(source.error(
                at.span().start,
                format!("image size {w}x{h} exceeds the limit of {MAX_PIXELS} pixels"),
            ));
        }
        Ok(defaults)
    }
}

fn z_up() -> [f32; 3] {
    [0.0, 0.0, 1.0]
}

fn one() -> [f32; 3] {
    [1.0; 3]
}

/// `[materials.NAME]`, tagged by `type`.
#[derive(Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
enum MaterialDef {
    Diffuse {
        albedo: [f32; 3],
    },
    Mirror {
        #[serde(default = "one")]
        tint: [f32; 3],
    },
    Dielectric {
        ior: f32,
        #[serde(default)]
        fresnel: FresnelDef,
        #[serde(default = "one")]
        tint: [f32; 3],
    },
    /// glTF metallic-roughness; the defaults are glTF's except `metallic` (0 here: a plastic).
    Pbr {
        base_color: [f32; 3],
        #[serde(default)]
        metallic: f32,
        #[serde(default = "half")]
        roughness: f32,
        #[serde(default = "unit")]
        specular: f32,
        #[serde(default = "one")]
        specular_color: [f32; 3],
        #[serde(default = "glass_ior")]
        ior: f32,
        #[serde(default)]
        transmission: f32,
        #[serde(default)]
        clearcoat: f32,
        #[serde(default)]
        clearcoat_roughness: f32,
        #[serde(default)]
        sheen_color: [f32; 3],
        #[serde(default)]
        sheen_roughness: f32,
    },
}

fn half() -> f32 {
    0.5
}

fn unit() -> f32 {
    1.0
}

fn glass_ior() -> f32 {
    1.5
}

#[derive(Deserialize, Default, Clone, Copy)]
#[serde(rename_all = "snake_case")]
enum FresnelDef {
    #[default]
    Exact,
    Schlick,
}

#[derive(Deserialize, Clone, Copy, PartialEq, Eq, Debug)]
#[serde(rename_all = "snake_case")]
enum ShapeKind {
    Triangle,
    Quad,
    Polygon,
    Tetrahedron,
    Sphere,
}

/// `[[shape]]`: one primitive, its material, optional emission and transform.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ShapeDef {
    #[serde(rename = "type")]
    kind: ShapeKind,
    name: Option<String>,
    material: Spanned<String>,
    #[serde(default)]
    vertices: Vec<[f32; 3]>,
    center: Option<[f32; 3]>,
    radius: Option<f32>,
    /// Emitted radiance; makes the shape an area light.
    emission: Option<[f32; 3]>,
    #[serde(default)]
    two_sided: bool,
    #[serde(default)]
    translate: Option<[f32; 3]>,
    /// Degrees about x, then y, then z.
    #[serde(default)]
    rotate: Option<[f32; 3]>,
    #[serde(default)]
    scale: Option<ScaleDef>,
}

#[derive(Deserialize, Clone, Copy)]
#[serde(untagged)]
enum ScaleDef {
    Uniform(f32),
    PerAxis([f32; 3]),
}

/// Where a definition came from, for error messages.
#[derive(Clone)]
struct Source {
    path: PathBuf,
    text: Arc<str>,
}

impl Source {
    fn error(&self, offset: usize, message: impl Into<String>) -> Error {
        Error::input_at(&self.path, &self.text, offset, message)
    }
}

/// Everything gathered from a file and its includes, before entities are spawned.
#[derive(Default)]
struct Gathered {
    camera: Option<(Source, Spanned<CameraDef>)>,
    environment: Option<EnvironmentLight>,
    defaults: SceneDefaults,
    materials: BTreeMap<String, Material>,
    shapes: Vec<(Source, Spanned<ShapeDef>)>,
    models: Vec<(Source, Spanned<ModelDef>)>,
}

/// Loads a TOML scene from `text`, which was read from `path`.
pub fn load(path: &Path, text: &str) -> Result<Scene> {
    let mut gathered = Gathered::default();
    let mut stack = Vec::new();
    gather(
        Source {
            path: path.to_path_buf(),
            text: text.into(),
        },
        &mut stack,
        &mut gathered,
    )?;
    spawn(gathered, path)
}

fn gather(source: Source, stack: &mut Vec<PathBuf>, out: &mut Gathered) -> Result<()> {
    let file: SceneFile = toml::from_str(&source.text).map_err(|e| {
        let offset = e.span().map_or(0, |s| s.start);
        source.error(offset, toml_message(&e))
    })?;
    stack.push(canonical(&source.path));

    for include in &file.include {
        let (child_path, child_text) = if include.get_ref() == BUILTIN_ROOM_NAME {
            (
                PathBuf::from(BUILTIN_ROOM_NAME),
                Arc::<str>::from(BUILTIN_ROOM),
            )
        } else {
            let base = source.path.parent().unwrap_or(Path::new("."));
            let child = base.join(include.get_ref());
            if !child.is_file() {
                return Err(source.error(
                    include.span().start,
                    format!("included file '{}' does not exist", child.display()),
                ));
            }
            let text = std::fs::read_to_string(&child).map_err(|e| {
                source.error(
                    include.span().start,
                    format!("cannot read included file '{}': {e}", child.display()),
                )
            })?;
            (child, text.into())
        };
        if stack.contains(&canonical(&child_path)) {
            return Err(source.error(
                include.span().start,
                format!("include cycle: '{}' includes itself", child_path.display()),
            ));
        }
        gather(
            Source {
                path: child_path,
                text: child_text,
            },
            stack,
            out,
        )?;
    }

    if let Some(camera) = file.camera {
        out.camera = Some((source.clone(), camera));
    }
    if let Some(environment) = file.environment {
        out.environment = Some(
            environment
                .get_ref()
                .resolve(&source, environment.span().start)?,
        );
    }
    if let Some(render) = file.render {
        out.defaults = out.defaults.overridden_by(render.validate(&source)?);
    }
    for (name, def) in file.materials {
        let material = material_from_def(def.get_ref())
            .map_err(|m| source.error(def.span().start, format!("material '{name}': {m}")))?;
        out.materials.insert(name, material);
    }
    out.shapes
        .extend(file.shapes.into_iter().map(|s| (source.clone(), s)));
    out.models
        .extend(file.models.into_iter().map(|m| (source.clone(), m)));
    stack.pop();
    Ok(())
}

fn canonical(path: &Path) -> PathBuf {
    std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf())
}

/// toml's message without its own rendering of the source line (we add line and column),
/// with a suggestion when an unknown key or type is close to an expected one.
fn toml_message(e: &toml::de::Error) -> String {
    let message = e.message().trim_end_matches('\n').to_string();
    match suggestion_for_unknown(&message) {
        Some(close) => format!("{message}; did you mean `{close}`?"),
        None => message,
    }
}

/// serde reports unknown keys as "unknown field `X`, expected one of `a`, `b`" (and enum
/// tags as "unknown variant `X`, expected ..."); returns the expected name closest to `X`.
fn suggestion_for_unknown(message: &str) -> Option<String> {
    let rest = message
        .strip_prefix("unknown field ")
        .or_else(|| message.strip_prefix("unknown variant "))?;
    let (unknown, expected) = rest.split_once(", expected ")?;
    let candidates: Vec<&str> = expected.split('`').skip(1).step_by(2).collect();
    closest_match(unknown.trim_matches('`'), candidates).map(str::to_string)
}

fn finite(values: &[f32], what: &str) -> std::result::Result<(), String> {
    if values.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(format!("{what} must be finite numbers"))
    }
}

fn material_from_def(def: &MaterialDef) -> std::result::Result<Material, String> {
    Ok(match *def {
        MaterialDef::Diffuse { albedo } => {
            finite(&albedo, "albedo")?;
            if albedo.iter().any(|&a| !(0.0..=1.0).contains(&a)) {
                return Err("albedo components must lie in [0, 1]".into());
            }
            Material::Lambertian {
                albedo: Vec3::from(albedo),
            }
        }
        MaterialDef::Mirror { tint } => {
            finite(&tint, "tint")?;
            Material::Mirror {
                tint: Vec3::from(tint),
            }
        }
        MaterialDef::Dielectric { ior, fresnel, tint } => {
            finite(&[ior], "ior")?;
            finite(&tint, "tint")?;
            if ior <= 0.0 {
                return Err(format!("ior must be positive, got {ior}"));
            }
            let fresnel = match fresnel {
                FresnelDef::Exact => FresnelModel::Exact,
                FresnelDef::Schlick => FresnelModel::Schlick,
            };
            Material::Dielectric {
                ior,
                fresnel,
                tint: Vec3::from(tint),
            }
        }
        MaterialDef::Pbr {
            base_color,
            metallic,
            roughness,
            specular,
            specular_color,
            ior,
            transmission,
            clearcoat,
            clearcoat_roughness,
            sheen_color,
            sheen_roughness,
        } => {
            finite(&base_color, "base_color")?;
            finite(&specular_color, "specular_color")?;
            finite(&sheen_color, "sheen_color")?;
            finite(
                &[
                    metallic,
                    roughness,
                    specular,
                    ior,
                    transmission,
                    clearcoat,
                    clearcoat_roughness,
                    sheen_roughness,
                ],
                "pbr parameters",
            )?;
            for (colour, what) in [(base_color, "base_color"), (sheen_color, "sheen_color")] {
                if colour.iter().any(|&a| !(0.0..=1.0).contains(&a)) {
                    return Err(format!("{what} components must lie in [0, 1]"));
                }
            }
            for (value, what) in [
                (metallic, "metallic"),
                (roughness, "roughness"),
                (specular, "specular"),
                (transmission, "transmission"),
                (clearcoat, "clearcoat"),
                (clearcoat_roughness, "clearcoat_roughness"),
                (sheen_roughness, "sheen_roughness"),
            ] {
                if !(0.0..=1.0).contains(&value) {
                    return Err(format!("{what} must lie in [0, 1], got {value}"));
                }
            }
            if specular_color.iter().any(|&a| a < 0.0) {
                return Err("specular_color components must be non-negative".into());
            }
            if ior < 1.0 || (transmission > 0.0 && ior == 1.0) {
                return Err(format!(
                    "ior must be at least 1 (above 1 with transmission), got {ior}"
                ));
            }
            Material::MetallicRoughness {
                base_color: Vec3::from(base_color),
                metallic,
                roughness,
                specular,
                specular_color: Vec3::from(specular_color),
                ior,
                transmission,
                clearcoat,
                clearcoat_roughness,
                sheen_color: Vec3::from(sheen_color),
                sheen_roughness,
            }
        }
    })
}

fn spawn(gathered: Gathered, path: &Path) -> Result<Scene> {
    let mut world = hecs::World::new();
    let Some((camera_source, camera)) = gathered.camera else {
        return Err(Error::input(path, None, "the scene has no [camera]"));
    };
    let camera_span = camera.span().start;
    let c = camera.into_inner();
    let cam_err = |m: String| camera_source.error(camera_span, format!("camera: {m}"));
    for (v, what) in [(&c.eye, "eye"), (&c.look_at, "look_at"), (&c.up, "up")] {
        finite(v, what).map_err(cam_err)?;
    }
    finite(&[c.vfov], "vfov").map_err(cam_err)?;
    if !(c.vfov > 0.0 && c.vfov < 180.0) {
        return Err(cam_err(format!(
            "vfov must lie in (0, 180) degrees, got {}",
            c.vfov
        )));
    }
    let (eye, target, up) = (Vec3::from(c.eye), Vec3::from(c.look_at), Vec3::from(c.up));
    if (target - eye).length() == 0.0
        || (target - eye).cross(up).length() < 1e-6 * (target - eye).length() * up.length()
    {
        return Err(cam_err(
            "look_at must differ from eye and up must not be parallel to the view direction".into(),
        ));
    }
    let camera = Camera::look_at(eye, target, up, c.vfov.to_radians());
    // Finite but huge coordinates can still overflow on the way to a unit direction.
    if !(camera.forward.is_finite() && camera.up.is_finite()) {
        return Err(cam_err(
            "eye and look_at are too far apart to give a view direction".into(),
        ));
    }
    world.spawn((Name("camera".into()), camera));
    if let Some(environment) = gathered.environment {
        world.spawn((Name("environment".into()), environment));
    }

    for (index, (source, shape)) in gathered.shapes.iter().enumerate() {
        let span = shape.span().start;
        let def = shape.get_ref();
        let name = def
            .name
            .clone()
            .unwrap_or_else(|| format!("{:?} {index}", def.kind).to_lowercase());
        let err = |m: String| source.error(span, format!("shape '{name}': {m}"));
        let material = *gathered
            .materials
            .get(def.material.get_ref())
            .ok_or_else(|| {
                let known: Vec<&str> = gathered.materials.keys().map(String::as_str).collect();
                let wanted = def.material.get_ref();
                let hint = match closest_match(wanted, known.iter().copied()) {
                    Some(close) => format!("did you mean '{close}'?"),
                    None if known.is_empty() => "the scene defines no [materials]".into(),
                    None => format!("known: {}", known.join(", ")),
                };
                source.error(
                    def.material.span().start,
                    format!("shape '{name}': unknown material '{wanted}' ({hint})"),
                )
            })?;
        let transform = Transform(shape_transform(def).map_err(err)?);
        let emitter = match def.emission {
            Some(e) => {
                finite(&e, "emission").map_err(err)?;
                if e.iter().any(|&x| x < 0.0) {
                    return Err(err("emission must not be negative".into()));
                }
                Some(Emitter {
                    radiance: Vec3::from(e),
                    two_sided: def.two_sided,
                })
            }
            None => None,
        };
        let entity = if def.kind == ShapeKind::Sphere {
            let (Some(center), Some(radius)) = (def.center, def.radius) else {
                return Err(err("a sphere needs `center` and `radius`".into()));
            };
            finite(&center, "center").map_err(err)?;
            if !(radius.is_finite() && radius > 0.0) {
                return Err(err(format!(
                    "radius must be a positive number, got {radius}"
                )));
            }
            if !(Vec3::from(center).abs().max_element() + radius).is_finite() {
                return Err(err(
                    "center and radius are too large: the sphere's bounds overflow".into(),
                ));
            }
            if !def.vertices.is_empty() {
                return Err(err(
                    "a sphere takes `center` and `radius`, not `vertices`".into()
                ));
            }
            let placed = Transform(transform.0 * Affine3A::from_translation(Vec3::from(center)));
            world.spawn((Name(name.clone()), placed, Sphere { radius }, material))
        } else {
            if def.center.is_some() || def.radius.is_some() {
                return Err(err(format!(
                    "a {:?} takes `vertices`, not `center`/`radius`",
                    def.kind
                )
                .to_lowercase()));
            }
            let mesh = mesh_from_vertices(def.kind, &def.vertices).map_err(err)?;
            world.spawn((Name(name.clone()), transform, mesh, material))
        };
        if let Some(emitter) = emitter {
            world
                .insert_one(entity, emitter)
                .expect("entity was just spawned");
        }
    }
    let mut warnings = Vec::new();
    // A file named by several `[[model]]` tables (with the same `up` and `light_units`) is
    // loaded once; its meshes are shared by the placements ([`place::share_meshes`]).
    type ModelKey = (PathBuf, UpAxis, LightUnits);
    let model_key = |source: &Source, def: &ModelDef| -> ModelKey {
        let file = source
            .path
            .parent()
            .unwrap_or(Path::new("."))
            .join(def.file.get_ref());
        let file = std::fs::canonicalize(&file).unwrap_or(file);
        (file, def.up, def.light_units)
    };
    let mut placements = HashMap::<ModelKey, usize>::new();
    for (source, model) in &gathered.models {
        *placements
            .entry(model_key(source, model.get_ref()))
            .or_default() += 1;
    }
    let mut loaded = HashMap::<ModelKey, hecs::World>::new();
    for (source, model) in &gathered.models {
        let def = model.get_ref();
        let err = |m: String| source.error(model.span().start, format!("model: {m}"));
        let base = source.path.parent().unwrap_or(Path::new("."));
        let file = base.join(def.file.get_ref());
        if !file.is_file() {
            return Err(source.error(
                def.file.span().start,
                format!("model file '{}' does not exist", file.display()),
            ));
        }
        let material = match &def.material {
            None => None,
            Some(name) => Some(*gathered.materials.get(name.get_ref()).ok_or_else(|| {
                source.error(
                    name.span().start,
                    format!("unknown material '{}'", name.get_ref()),
                )
            })?),
        };
        let key = model_key(source, def);
        let imported = match loaded.get(&key) {
            Some(model) => Scene {
                world: place::copy_model(model),
                defaults: SceneDefaults::default(),
                // Given with the first placement.
                warnings: Vec::new(),
            },
            None => {
                let mut imported = import_model_with(&file, def.up, def.light_units)?;
                if placements[&key] > 1 {
                    place::share_meshes(&mut imported.world);
                    loaded.insert(key, place::copy_model(&imported.world));
                }
                imported
            }
        };
        if def.position.is_none() {
            if def.rotation.is_some() || def.scale.is_some() || def.fit.is_some() {
                return Err(err(
                    "rotation, scale and fit need a position (without one, the model stands \
                     on the room's stage, turned and sized by the bare-model rule)"
                        .into(),
                ));
            }
            warnings.extend(imported.warnings);
            place::stage_model(&mut world, imported.world, material, &file)?;
            continue;
        }
        let anchor = match def.fit {
            None => Affine3A::IDENTITY,
            Some(fit) => {
                if !(fit.is_finite() && fit > 0.0) {
                    return Err(err(format!("fit must be a positive number, got {fit}")));
                }
                let (lo, hi) = bounding_box(&imported.world)
                    .ok_or_else(|| err(format!("'{}' has no geometry", file.display())))?;
                place::fit_transform(lo, hi, fit, Vec3::ZERO)
            }
        };
        let placement = placement_transform(def.position, def.rotation, def.scale).map_err(err)?;
        place::merge_model(&mut world, imported.world, placement * anchor, material);
        warnings.extend(imported.warnings);
    }
    Ok(Scene {
        world,
        defaults: gathered.defaults,
        warnings,
    })
}

fn shape_transform(def: &ShapeDef) -> std::result::Result<Affine3A, String> {
    placement_transform(def.translate, def.rotate, def.scale)
}

/// `translate * rotate_z * rotate_y * rotate_x * scale`: rotations apply about x first.
fn placement_transform(
    translate: Option<[f32; 3]>,
    rotate: Option<[f32; 3]>,
    scale: Option<ScaleDef>,
) -> std::result::Result<Affine3A, String> {
    let translate = translate.unwrap_or([0.0; 3]);
    let rotate = rotate.unwrap_or([0.0; 3]);
    let scale = match scale {
        None => [1.0; 3],
        Some(ScaleDef::Uniform(s)) => [s; 3],
        Some(ScaleDef::PerAxis(s)) => s,
    };
    finite(&translate, "translate")?;
    finite(&rotate, "rotate")?;
    finite(&scale, "scale")?;
    if scale.contains(&0.0) {
        return Err("scale must not be zero".into());
    }
    let [rx, ry, rz] = rotate.map(f32::to_radians);
    let rotation =
        Quat::from_rotation_z(rz) * Quat::from_rotation_y(ry) * Quat::from_rotation_x(rx);
    Ok(Affine3A::from_scale_rotation_translation(
        Vec3::from(scale),
        rotation,
        Vec3::from(translate),
    ))
}

/// Triangulates the vertex list of a flat primitive; the winding of `vertices` sets the front.
fn mesh_from_vertices(kind: ShapeKind, vertices: &[[f32; 3]]) -> std::result::Result<Mesh, String> {
    let expected = match kind {
        ShapeKind::Triangle => Some(3),
        ShapeKind::Quad => Some(4),
        ShapeKind::Tetrahedron => Some(4),
        ShapeKind::Polygon => None,
        ShapeKind::Sphere => unreachable!("spheres are not meshes"),
    };
    if let Some(n) = expected.filter(|&n| n != vertices.len()) {
        return Err(format!(
            "needs exactly {n} vertices, got {}",
            vertices.len()
        ));
    }
    if vertices.len() < 3 {
        return Err(format!("needs at least 3 vertices, got {}", vertices.len()));
    }
    for v in vertices {
        finite(v, "vertices")?;
    }
    let positions: Vec<Vec3> = vertices.iter().map(|&v| Vec3::from(v)).collect();
    let indices = if kind == ShapeKind::Tetrahedron {
        tetrahedron_faces(&positions)?
    } else {
        convex_fan(&positions)?
    };
    Ok(Mesh {
        positions,
        indices,
        ..Default::default()
    })
}

/// Fan triangulation of a planar convex polygon. Anything else is refused, because a fan
/// would silently render a concave polygon wrong.
fn convex_fan(p: &[Vec3]) -> std::result::Result<Vec<[u32; 3]>, String> {
    let n = p.len();
    let mut normal = Vec3::ZERO; // Newell's method: robust polygon normal
    for i in 0..n {
        let (a, b) = (p[i], p[(i + 1) % n]);
        normal += Vec3::new(
            (a.y - b.y) * (a.z + b.z),
            (a.z - b.z) * (a.x + b.x),
            (a.x - b.x) * (a.y + b.y),
        );
    }
    let scale = p
        .iter()
        .map(|v| v.abs().max_element())
        .fold(1e-12f32, f32::max);
    if normal.length() <= 1e-6 * scale * scale {
        return Err("vertices are degenerate (zero area)".into());
    }
    let normal = normal.normalize();
    for i in 0..n {
        let (a, b, c) = (p[i], p[(i + 1) % n], p[(i + 2) % n]);
        if (b - a).cross(c - b).dot(normal) < -1e-6 * scale * scale {
            return Err("polygon is not convex (or its vertices are not in order)".into());
        }
        if (p[i] - p[0]).dot(normal).abs() > 1e-4 * scale {
            return Err("polygon vertices are not in one plane".into());
        }
    }
    Ok((1..n as u32 - 1).map(|i| [0, i, i + 1]).collect())
}

/// The four faces of a tetrahedron, each wound so that its front faces outward.
fn tetrahedron_faces(p: &[Vec3]) -> std::result::Result<Vec<[u32; 3]>, String> {
    let volume = (p[1] - p[0]).cross(p[2] - p[0]).dot(p[3] - p[0]);
    if volume.abs() < 1e-9 {
        return Err("tetrahedron vertices are coplanar (zero volume)".into());
    }
    let faces = [[0u32, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]];
    Ok(faces
        .iter()
        .map(|&[a, b, c]| {
            let opposite = p[6 - (a + b + c) as usize];
            let (va, vb, vc) = (p[a as usize], p[b as usize], p[c as usize]);
            if (vb - va).cross(vc - va).dot(opposite - va) > 0.0 {
                [a, c, b]
            } else {
                [a, b, c]
            }
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::load::place::{ROOM_EYE, ROOM_FLOOR, ROOM_PROPS};

    #[test]
    fn the_stage_constants_are_those_of_the_room_file() {
        let room = builtin_room().unwrap();
        let cameras: Vec<Camera> = room.world.query::<&Camera>().iter().copied().collect();
        assert_eq!(cameras.len(), 1);
        let c = cameras[0];
        assert_eq!(c.eye, ROOM_EYE);
        assert!((c.forward - Vec3::X).length() < 1e-6 && (c.up - Vec3::Z).length() < 1e-6);
        assert!((c.vfov - 90f32.to_radians()).abs() < 1e-6);
        let names: Vec<String> = room
            .world
            .query::<&Name>()
            .iter()
            .map(|n| n.0.clone())
            .collect();
        for prop in ROOM_PROPS {
            assert!(names.iter().any(|n| n == prop), "{prop}");
        }
        let (lo, _) = bounding_box(&room.world).unwrap();
        assert_eq!(lo.z, ROOM_FLOOR);
    }

    #[test]
    fn tetrahedron_faces_point_outward() {
        let p = [
            Vec3::new(5.5, 2.2, -5.0),
            Vec3::new(4.461, 0.4, -5.0),
            Vec3::new(6.539, 0.4, -5.0),
            Vec3::new(5.5, 1.0, -3.0),
        ];
        let centroid = p.iter().copied().sum::<Vec3>() / 4.0;
        for [a, b, c] in tetrahedron_faces(&p).unwrap() {
            let (va, vb, vc) = (p[a as usize], p[b as usize], p[c as usize]);
            assert!((vb - va).cross(vc - va).dot(va - centroid) > 0.0);
        }
    }

    #[test]
    fn concave_polygons_are_refused() {
        let l = [
            [0.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [2.0, 1.0, 0.0],
            [1.0, 0.2, 0.0],
            [0.0, 1.0, 0.0],
        ];
        assert!(
            mesh_from_vertices(ShapeKind::Polygon, &l)
                .unwrap_err()
                .contains("convex")
        );
        let hex = [
            [-3.0, 0.0, 0.0],
            [0.0, -6.0, 0.0],
            [10.0, -6.0, 0.0],
            [13.0, 0.0, 0.0],
            [10.0, 6.0, 0.0],
            [0.0, 6.0, 0.0],
        ];
        assert_eq!(
            mesh_from_vertices(ShapeKind::Polygon, &hex)
                .unwrap()
                .indices
                .len(),
            4
        );
    }
}
