//! Lights: one area light per primitive of each emitting entity, the punctual lights in
//! world space, the environment light, and the light table over all of them.

use super::Primitives;
use super::materials;
use crate::error::{Error, Result};
use crate::lights::{AreaLight, DeltaLight, Environment, LightTable, SpotCone};
use crate::math::{Rgb, Vec3, Vec3A};
use crate::render_scene::NO_EMITTER;
use crate::scene::{
    Emitter, EnvironmentLight, EnvironmentSource, Name, PunctualLight, SpotFalloff, Transform,
};
use crate::texture::{EmissionCoverage, TextureRef, TexturedEmission};
use obvhs::aabb::Aabb;
use std::path::Path;

/// The scene's lights: the table, the emission textures of its area lights (empty when none
/// has one), and per group its first light (or [`NO_EMITTER`]).
pub(super) struct SceneLights {
    pub(super) table: LightTable,
    pub(super) textured_emission: Vec<Option<TexturedEmission>>,
    /// Lights come from the primitives, not the slots: light `first_light[g] + k` is the
    /// `k`-th primitive of group `g`.
    pub(super) first_light: Vec<u32>,
}

/// The light table over the emitting primitives of `prims`, the punctual lights
/// `delta_lights` and the environment (chosen by its power over a sphere of `scene_radius`).
pub(super) fn scene_lights(
    prims: &Primitives,
    delta_lights: Vec<DeltaLight>,
    environment: Option<Environment>,
    scene_radius: f32,
) -> SceneLights {
    let groups = &prims.groups;
    let mut area_lights = Vec::new();
    let mut textured_emission = Vec::new();
    let mut first_light = Vec::with_capacity(groups.len());
    for (g, group) in groups.iter().enumerate() {
        let Some(emitter) = group.emitter else {
            first_light.push(NO_EMITTER);
            continue;
        };
        first_light.push(area_lights.len() as u32);
        let end = groups.get(g + 1).map_or(prims.count, |next| next.first);
        let record = prims.alpha_records.get(group.alpha as usize);
        for prim in group.first..end {
            let mut radiance = emitter.radiance;
            // A textured emitter is chosen by its mean radiance; shading applies the texel
            // (and an alpha-tested one's coverage at sampled points).
            let coverage = record.map(|r| EmissionCoverage {
                mode: r.mode,
                factor: r.factor,
                texture: r.texture,
                vertex_alpha: if r.vertex_alpha {
                    prims.vertex_alphas(prim)
                } else {
                    [1.0; 3]
                },
            });
            let (texture, mean) = group
                .emission_texture
                .unwrap_or((TextureRef::default(), Rgb::ONE));
            radiance *= mean;
            textured_emission.push((texture.is_set() || coverage.is_some()).then(|| {
                TexturedEmission {
                    texture,
                    radiance: emitter.radiance,
                    inverse_mean: materials::inverse_or_zero(mean),
                    uvs: prims.uvs(prim),
                    coverage,
                }
            }));
            let shape = prims.shape(prim);
            area_lights.push(AreaLight::new(shape, radiance, emitter.two_sided));
        }
    }
    let mut lights =
        LightTable::with_environment(area_lights, delta_lights, environment, scene_radius);
    let textured_emission = if textured_emission.iter().any(Option::is_some) {
        lights.locate_samples_on_triangles();
        textured_emission
    } else {
        Vec::new()
    };
    SceneLights {
        table: lights,
        textured_emission,
        first_light,
    }
}

/// Punctual lights in world space. A directional light's power is taken over the disk that
/// the scene's bounding sphere casts, so that it is chosen in proportion to what it delivers.
pub(super) fn punctual_lights(
    world: &hecs::World,
    scene_bounds: Option<Aabb>,
    path: &Path,
) -> Result<Vec<DeltaLight>> {
    let scene_radius = scene_radius(scene_bounds);
    let mut out = Vec::new();
    for (name, transform, light) in world
        .query::<(Option<&Name>, Option<&Transform>, &PunctualLight)>()
        .iter()
    {
        let name = name.map_or("unnamed light", |n| n.0.as_str());
        let t = transform.copied().unwrap_or_default().0;
        let position = t.transform_point3a(Vec3A::ZERO);
        let direction = t.transform_vector3a(Vec3A::NEG_Z).normalize_or_zero();
        let bad = |m: &str| {
            Err(Error::input(
                path,
                Some(format!("light '{name}'")),
                m.to_string(),
            ))
        };
        if !position.is_finite() || direction == Vec3A::ZERO {
            return bad("the light's transform is degenerate");
        }
        let delta = match *light {
            PunctualLight::Point { intensity } => DeltaLight::point(position, intensity),
            PunctualLight::Spot {
                intensity,
                inner_cone,
                outer_cone,
                falloff,
            } => {
                // inner = outer is a hard-edged cone (Blender's Spot Blend 0).
                if !(0.0 <= inner_cone
                    && inner_cone <= outer_cone
                    && 0.0 < outer_cone
                    && outer_cone <= std::f32::consts::FRAC_PI_2)
                {
                    return bad(
                        "spot cone angles must satisfy 0 <= inner <= outer <= pi/2, outer > 0",
                    );
                }
                let cone = match falloff {
                    SpotFalloff::Gltf => SpotCone::gltf(inner_cone, outer_cone),
                    SpotFalloff::Blender { blend } if (0.0..=1.0).contains(&blend) => {
                        SpotCone::blender(outer_cone, blend)
                    }
                    SpotFalloff::Blender { .. } => {
                        return bad("a Blender spot's blend must lie in [0, 1]");
                    }
                };
                DeltaLight::spot(position, direction, intensity, cone)
            }
            PunctualLight::Directional { irradiance } => {
                DeltaLight::directional(direction, irradiance, scene_radius)
            }
        };
        if !(delta.intensity.is_finite() && delta.intensity.min_element() >= 0.0) {
            return bad("the light's intensity must be finite and non-negative");
        }
        if delta.intensity.max_element() > 0.0 {
            out.push(delta);
        }
    }
    Ok(out)
}

/// Radius of the scene's bounding sphere (1 for an empty scene), over which directional
/// lights and the environment deliver their power.
pub(super) fn scene_radius(scene_bounds: Option<Aabb>) -> f32 {
    scene_bounds.map_or(1.0, |b| ((b.max - b.min).length() * 0.5).max(1e-3))
}

/// The world's environment light, loaded and checked (errors name its file, or the scene
/// for a colour), and whether camera rays see it. More than one is an error.
pub(super) fn environment(world: &hecs::World, path: &Path) -> Result<(Option<Environment>, bool)> {
    let mut query = world.query::<&EnvironmentLight>();
    let mut found = query.iter();
    let Some(light) = found.next() else {
        return Ok((None, true));
    };
    if found.next().is_some() {
        return Err(Error::input(
            path,
            None,
            "the scene has more than one environment light",
        ));
    }
    let environment = match &light.source {
        EnvironmentSource::Color(rgb) => {
            let environment = Environment::constant(*rgb, light.strength, path)?;
            // Checked as a map's would be, though a constant has no direction to turn.
            if !light.rotation_degrees.is_finite() {
                return Err(Error::input(
                    path,
                    None,
                    "environment rotation must be a finite number of degrees",
                ));
            }
            environment
        }
        EnvironmentSource::File(file) => {
            Environment::from_file(file, light.strength, light.rotation_degrees)?
        }
    };
    Ok((Some(environment), light.visible_to_camera))
}

/// Emitters that emit nothing are dropped; invalid radiance is an error.
pub(super) fn validate_emitter(
    e: Option<&Emitter>,
    path: &Path,
    name: &str,
) -> Result<Option<Emitter>> {
    match e {
        Some(e) if !(e.radiance.is_finite() && e.radiance.min_element() >= 0.0) => {
            Err(Error::input(
                path,
                Some(format!("'{name}'")),
                "emitted radiance must be finite and non-negative",
            ))
        }
        Some(e) if e.radiance == Vec3::ZERO => Ok(None),
        other => Ok(other.copied()),
    }
}
