//! Analytic spheres: centre and radius in world space (their transforms must scale
//! uniformly), with bounds the BVH builder can order.

use super::lights::validate_emitter;
use super::materials::MaterialTable;
use super::{Group, Primitives, Source};
use crate::error::{Error, Result};
use crate::geometry::SphereGeom;
use crate::math::Vec3;
use crate::scene::{Emitter, Material, Name, Sphere, Transform, Volume};
use std::path::Path;

/// Appends every sphere of the world to `prims` (one group each), its material to
/// `materials`.
pub(super) fn flatten_spheres(
    world: &hecs::World,
    path: &Path,
    materials: &mut MaterialTable,
    prims: &mut Primitives,
) -> Result<()> {
    for (name, transform, sphere, (material, volume), emitter) in world
        .query::<(
            Option<&Name>,
            Option<&Transform>,
            &Sphere,
            (&Material, Option<&Volume>),
            Option<&Emitter>,
        )>()
        .iter()
    {
        let name = name.map_or("unnamed sphere", |n| n.0.as_str());
        let transform = transform.copied().unwrap_or_default().0;
        let scale = Vec3::new(
            transform.matrix3.x_axis.length(),
            transform.matrix3.y_axis.length(),
            transform.matrix3.z_axis.length(),
        );
        if (scale.max_element() - scale.min_element()) > 1e-4 * scale.max_element() {
            return Err(Error::input(
                path,
                Some(format!("sphere '{name}'")),
                "a sphere's transform must scale uniformly",
            ));
        }
        let geom = SphereGeom {
            center: transform.translation,
            radius: sphere.radius * scale.x,
        };
        // The bounds too must be finite: the BVH builder cannot order infinite boxes.
        let reach = geom.center.abs().max_element() + geom.radius;
        if !(geom.radius > 0.0 && reach.is_finite()) {
            return Err(Error::input(
                path,
                Some(format!("sphere '{name}'")),
                "radius must be positive and the sphere's bounds finite",
            ));
        }
        let material = materials.index(material, None, volume, None);
        let emitter = validate_emitter(emitter, path, name)?;
        prims.groups.push(Group {
            first: prims.count,
            material,
            emitter,
            emission_texture: None,
            alpha: crate::accel::alpha::OPAQUE,
        });
        prims.sources.push(Source::Sphere(geom));
        prims.count += 1;
    }
    Ok(())
}
