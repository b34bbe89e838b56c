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
    let distance = n.abs().dot(error);
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
