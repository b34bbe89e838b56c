//! Small math vocabulary shared by every stage: vector types, colours, orthonormal frames,
//! warping functions and the counter-based random numbers. Nothing here knows about scenes.

pub mod frame;
pub mod rng;
pub mod sampling;

pub use glam::{Affine3A, BVec4A, Mat3, Mat3A, Mat4, Quat, Vec2, Vec3, Vec3A, Vec4};

/// The 4 x 4 block `rows` transposed: lane `k` of vector `i` becomes lane `i` of vector `k`.
/// Turns one vector per item into one vector per coordinate (four items in SIMD lanes), and
/// back.
#[inline(always)]
pub fn transpose4(rows: [Vec4; 4]) -> [Vec4; 4] {
    let [a, b, c, d] = rows;
    let m = Mat4::from_cols(a, b, c, d).transpose();
    [m.x_axis, m.y_axis, m.z_axis, m.w_axis]
}

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
    Vec3A::new(
        step_toward(moved.x, offset.x),
        step_toward(moved.y, offset.y),
        step_toward(moved.z, offset.z),
    )
}

/// `x.next_up()` for `sign > 0`, `x.next_down()` for `sign < 0`, `x` for zero, for finite
/// `x`; infinities and NaN pass through. Branch-free: the sign of an offset is a coin flip
/// for the branch predictor (the standard functions branch on every special case).
#[inline(always)]
fn step_toward(x: f32, sign: f32) -> f32 {
    let bits = x.to_bits();
    let up = sign > 0.0;
    // Away from zero the bits grow by one, toward zero they shrink by one; from either
    // zero the step lands on the smallest subnormal of the direction's sign.
    let grows = (bits >> 31 == 0) == up;
    // +1 or -1 (wrapping) by arithmetic: the compiler made a branch of a select here.
    let step = (2 * u32::from(grows)).wrapping_sub(1);
    let stepped = if bits << 1 == 0 {
        if up { 1 } else { 0x8000_0001 }
    } else {
        bits.wrapping_add(step)
    };
    if (sign == 0.0) | !x.is_finite() {
        x
    } else {
        f32::from_bits(stepped)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn step_toward_is_next_up_and_next_down() {
        let specials = [
            0.0,
            -0.0,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            f32::MAX,
            -f32::MAX,
        ];
        let subnormal = f32::from_bits(1);
        let mut values: Vec<f32> = specials.into();
        values.extend([subnormal, -subnormal, 1.0, -1.0, 3.5e-20, -7.25e12]);
        values.extend((0..1000).map(|i| (i as f32 - 500.0) * 0.37));
        for x in values {
            assert_eq!(
                step_toward(x, 2.0).to_bits(),
                x.next_up().to_bits(),
                "{x:e} up"
            );
            assert_eq!(
                step_toward(x, -0.5).to_bits(),
                x.next_down().to_bits(),
                "{x:e} down"
            );
            assert_eq!(step_toward(x, 0.0).to_bits(), x.to_bits());
        }
        for x in [f32::INFINITY, f32::NEG_INFINITY] {
            assert_eq!(step_toward(x, 1.0), x);
        }
        assert!(step_toward(f32::NAN, 1.0).is_nan());
    }

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
