//! Small math vocabulary shared by every stage: vector types, colours, orthonormal frames,
//! warping functions and the counter-based random numbers. Nothing here knows about scenes.

pub mod frame;
pub mod rng;
pub mod sampling;

pub use glam::{Affine3A, Mat3, Mat3A, Mat4, Quat, Vec2, Vec3, Vec3A, Vec4};

/// Linear RGB radiance, throughput or reflectance (Rec.709 primaries, no gamma).
pub type Rgb = Vec3;

/// Luminance of a linear Rec.709 colour.
#[inline]
pub fn luminance(c: Rgb) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// Largest component, used by Russian roulette and light power.
#[inline]
pub fn max_component(c: Rgb) -> f32 {
    c.x.max(c.y).max(c.z)
}

/// Moves a surface point off the surface, far enough along the geometric normal `n` that a
/// ray leaving in direction `w` cannot hit the surface it starts on, whatever the rounding
/// error `error` (per component) of `p` (pbrt's construction; handles leaving from inside).
#[inline]
pub fn offset_ray_origin(p: Vec3A, error: Vec3A, n: Vec3A, w: Vec3A) -> Vec3A {
    // Never zero: a point computed exactly (error 0, e.g. on the plane z = 0) still moves by
    // at least one float, so the surface it leaves lies strictly behind the new origin.
    let distance = n.abs().dot(error).max(f32::MIN_POSITIVE);
    let offset = if w.dot(n) < 0.0 {
        -distance * n
    } else {
        distance * n
    };
    let moved = p + offset;
    // Round away from p so that the offset is not lost to rounding.
    let away = |x: f32, o: f32| {
        if o > 0.0 {
            x.next_up()
        } else if o < 0.0 {
            x.next_down()
        } else {
            x
        }
    };
    Vec3A::new(
        away(moved.x, offset.x),
        away(moved.y, offset.y),
        away(moved.z, offset.z),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offset_origin_leaves_an_exactly_computed_surface() {
        // A point exactly on z = 0 has zero rounding error; the offset must still move it up.
        let p = Vec3A::new(0.25, -0.5, 0.0);
        let q = offset_ray_origin(p, Vec3A::ZERO, Vec3A::Z, Vec3A::new(0.1, 0.0, 1.0));
        assert!(q.z > 0.0 && q.x == p.x && q.y == p.y);
        let below = offset_ray_origin(p, Vec3A::ZERO, Vec3A::Z, -Vec3A::Z);
        assert!(below.z < 0.0);
    }
}
