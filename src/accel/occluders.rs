//! What can block a shadow ray. A shadow ray runs from a point of the scene (on a surface,
//! pushed off it by a rounding bound) to a point on a light, or toward a directional light.
//! A triangle with the whole scene on one side of its plane (every vertex, sphere and
//! punctual light, and the way to every directional light) bounds the scene: a wall, floor or
//! ceiling of a convex room. No such segment crosses its plane, so it never blocks one, and the
//! shadow stage traces a tree over the other primitives only. In the hexagonal room that leaves
//! the tetrahedron and the two spheres: one node instead of about four per shadow packet.
//! (An origin pushed off its surface may lie behind such a plane by that rounding bound; the
//! plane does not block a ray from there, as the full tree's test might: a band as wide as
//! the rounding, which no image can show.)

use super::build::{Bvh4, build_bvh};
use super::leaf_prims::LeafPrim;
use crate::geometry::Shape;
use crate::lights::{DeltaKind, DeltaLight};
use glam::DVec3;
use rayon::prelude::*;

/// Scenes are checked only while triangles x points stays below this, a bound on the check's
/// time: it tests every triangle's plane against every point of the scene.
const MAX_CHECKS: usize = 1 << 24;

/// How far (relative to the coordinates' magnitude) a point may lie behind a plane and still
/// count as on it: the rounding of the check itself in `f64`, far below the rounding of the
/// surface points that `f32` arithmetic makes (which the ray origins' offsets cover).
const ON_PLANE: f64 = 1e-12;

/// The primitives that can block a shadow ray, with their own tree.
#[derive(Clone, Debug)]
pub struct Occluders {
    /// The tree over `leaf_prims`.
    pub bvh: Bvh4,
    /// The primitives' records in the tree's slot order.
    pub leaf_prims: Vec<LeafPrim>,
}

/// [`occluders`] of the `count` primitives (`triangles` of them triangles) whose shapes
/// `shape_of` gives: their shapes are made only when the scene is small enough to check.
pub fn occluders_of(
    count: usize,
    triangles: usize,
    shape_of: impl Fn(usize) -> Shape,
    delta_lights: &[DeltaLight],
) -> Option<Occluders> {
    if too_many_checks(triangles, count, delta_lights.len()) {
        return None;
    }
    let shapes: Vec<Shape> = (0..count).map(shape_of).collect();
    occluders(&shapes, delta_lights)
}

/// Whether checking `triangles` triangles against every point of a scene of `primitives`
/// primitives and `lights` punctual lights would take more than [`MAX_CHECKS`] tests.
fn too_many_checks(triangles: usize, primitives: usize, lights: usize) -> bool {
    let point_count = 3 * triangles + (primitives - triangles) + lights;
    triangles.saturating_mul(point_count) > MAX_CHECKS
}

/// The occluders of the scene made of `shapes` and the punctual lights `delta_lights`, or
/// `None` when no triangle bounds the scene (or the scene is too large to check, or the tree
/// over the rest would be refused): then every primitive may block.
pub fn occluders(shapes: &[Shape], delta_lights: &[DeltaLight]) -> Option<Occluders> {
    let triangles = (shapes.iter())
        .filter(|s| matches!(s, Shape::Triangle(_)))
        .count();
    if too_many_checks(triangles, shapes.len(), delta_lights.len()) {
        return None;
    }
    let points = scene_points(shapes, delta_lights);
    let extent = points.iter().fold(0.0, |e: f64, p| {
        e.max(p.position.abs().max_element() + p.radius)
    });
    let rest: Vec<Shape> = (shapes.par_iter())
        .filter(|shape| !bounds_the_scene(shape, &points, extent))
        .copied()
        .collect();
    if rest.len() == shapes.len() {
        return None;
    }
    let (bvh, order) = build_bvh(&rest)?;
    let leaf_prims = order
        .iter()
        .map(|&i| LeafPrim::new(&rest[i as usize]))
        .collect();
    Some(Occluders { bvh, leaf_prims })
}

/// A place a shadow ray can start or end: a ball (a point has radius 0), or, for a
/// directional light, a direction to infinity.
struct ScenePoint {
    position: DVec3,
    radius: f64,
    at_infinity: bool,
}

/// Every vertex and sphere of the scene, every point and spot light's position, and the way
/// to every directional light (the direction its shadow rays leave in).
fn scene_points(shapes: &[Shape], delta_lights: &[DeltaLight]) -> Vec<ScenePoint> {
    let point = |p: glam::Vec3A, radius: f32| ScenePoint {
        position: p.as_dvec3(),
        radius: f64::from(radius),
        at_infinity: false,
    };
    let mut points = Vec::new();
    for shape in shapes {
        match shape {
            Shape::Triangle(t) => points.extend(t.vertices().map(|v| point(v, 0.0))),
            Shape::Sphere(s) => points.push(point(s.center, s.radius)),
        }
    }
    for light in delta_lights {
        points.push(match light.kind {
            DeltaKind::Point { position } | DeltaKind::Spot { position, .. } => {
                point(position, 0.0)
            }
            DeltaKind::Directional { direction } => ScenePoint {
                position: -direction.as_dvec3(),
                radius: 0.0,
                at_infinity: true,
            },
        });
    }
    points
}

/// Whether `shape` is a triangle with every point of `points` on one side of its plane (or
/// on it), `extent` being the largest coordinate magnitude among them.
fn bounds_the_scene(shape: &Shape, points: &[ScenePoint], extent: f64) -> bool {
    let Shape::Triangle(t) = shape else {
        return false;
    };
    let [v0, v1, v2] = t.vertices().map(|v| v.as_dvec3());
    let normal = (v1 - v0).cross(v2 - v0);
    let length = normal.length();
    if length == 0.0 {
        return false;
    }
    let normal = normal / length;
    let tolerance = ON_PLANE * extent;
    let (mut front, mut behind) = (false, false);
    for p in points {
        // The signed distance of the ball's nearest and farthest points; a direction only
        // has a side.
        let (lo, hi) = if p.at_infinity {
            let d = normal.dot(p.position);
            (d, d)
        } else {
            let d = normal.dot(p.position - v0);
            (d - p.radius, d + p.radius)
        };
        front |= hi > tolerance;
        behind |= lo < -tolerance;
        if front && behind {
            return false;
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::sphere::SphereGeom;
    use crate::geometry::triangle::TriangleGeom;
    use crate::math::{Rgb, Vec3A};

    fn quad(corners: [[f32; 3]; 4]) -> [Shape; 2] {
        let [a, b, c, d] = corners.map(Vec3A::from);
        [
            Shape::Triangle(TriangleGeom::new(a, b, c)),
            Shape::Triangle(TriangleGeom::new(a, c, d)),
        ]
    }

    /// A unit box's floor and ceiling, and what lies between them.
    fn box_with(inside: &[Shape]) -> Vec<Shape> {
        let mut shapes = Vec::new();
        shapes.extend(quad([
            [0., 0., 0.],
            [1., 0., 0.],
            [1., 1., 0.],
            [0., 1., 0.],
        ]));
        shapes.extend(quad([
            [0., 0., 1.],
            [0., 1., 1.],
            [1., 1., 1.],
            [1., 0., 1.],
        ]));
        shapes.extend_from_slice(inside);
        shapes
    }

    #[test]
    fn the_faces_of_a_convex_room_are_left_out_and_what_stands_inside_is_kept() {
        let ball = Shape::Sphere(SphereGeom {
            center: Vec3A::new(0.5, 0.5, 0.5),
            radius: 0.2,
        });
        let occluders = occluders(&box_with(&[ball]), &[]).expect("the floor and ceiling bound it");
        assert_eq!(occluders.leaf_prims, vec![LeafPrim::new(&ball)]);
        // The same from the shapes flattening gives one by one.
        let shapes = box_with(&[ball]);
        let triangles = shapes.len() - 1;
        let one_by_one =
            occluders_of(shapes.len(), triangles, |i| shapes[i], &[]).expect("the same occluders");
        assert_eq!(one_by_one.leaf_prims, occluders.leaf_prims);
    }

    #[test]
    fn a_face_with_anything_behind_it_is_kept() {
        // A sphere poking through the floor, a point light under it, the sun shining up
        // through it: the floor may block a shadow ray in each case; a sun overhead, the
        // ceiling.
        let poking = Shape::Sphere(SphereGeom {
            center: Vec3A::new(0.5, 0.5, 0.1),
            radius: 0.2,
        });
        let kept = |shapes: &[Shape], lights: &[DeltaLight]| {
            occluders(shapes, lights).map_or(shapes.to_vec(), |o| {
                let kept = |s: &Shape| o.leaf_prims.contains(&LeafPrim::new(s));
                shapes.iter().copied().filter(kept).collect()
            })
        };
        let (floor, ceiling) = (&box_with(&[])[..2], &box_with(&[])[2..4]);
        let mut expected = floor.to_vec();
        expected.push(poking);
        assert_eq!(kept(&box_with(&[poking]), &[]), expected);
        let below = DeltaLight::point(Vec3A::new(0.5, 0.5, -1.0), Rgb::ONE);
        assert_eq!(kept(&box_with(&[]), &[below]), floor);
        // A directional light's direction is the way its light travels.
        let rising = DeltaLight::directional(Vec3A::Z, Rgb::ONE, 1.0);
        assert_eq!(kept(&box_with(&[]), &[rising]), floor);
        let falling = DeltaLight::directional(-Vec3A::Z, Rgb::ONE, 1.0);
        assert_eq!(kept(&box_with(&[]), &[falling]), ceiling);
    }
}
