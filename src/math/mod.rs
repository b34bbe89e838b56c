//! Small math vocabulary shared by every stage: vector types, colours, rays, orthonormal
//! frames, warping functions and the counter-based random numbers. Nothing here knows about
//! scenes.

pub mod frame;
pub mod rng;
pub mod sampling;
pub mod sobol;

pub use glam::{Affine3A, BVec4A, Mat3, Mat3A, Mat4, Quat, Vec2, Vec3, Vec3A, Vec4};

/// A ray as ray-casting clients give it (`RenderScene::closest_hits`): the segment from
/// `origin` along the unit `direction` up to `t_max`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Where the ray starts.
    pub origin: Vec3A,
    /// Unit direction.
    pub direction: Vec3A,
    /// Farthest distance a hit may have.
    pub t_max: f32,
}

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
#[inline(always)]
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
    step_toward(moved, offset)
}

/// Per component: `x.next_up()` where `sign > 0`, `x.next_down()` where `sign < 0`, `x` where
/// `sign` is zero; infinities and NaN pass through. Written as the same integer operations on
/// every lane, without branches or bools, so that the compiler keeps the lanes in one vector
/// register: three scalar steps, with their branches on the special cases (the sign of an
/// offset is a coin flip for the branch predictor), cost about 90 instructions per origin.
#[inline(always)]
fn step_toward(x: Vec3A, sign: Vec3A) -> Vec3A {
    let (x, sign) = (x.extend(0.0).to_array(), sign.extend(0.0).to_array());
    // All ones where `condition` holds, else zero.
    let mask = |condition: bool| 0u32.wrapping_sub(u32::from(condition));
    let stepped: [f32; 4] = std::array::from_fn(|k| {
        let bits = x[k].to_bits();
        let up = mask(sign[k] > 0.0);
        // Toward zero (a negative number going up, or a positive one going down) the bits
        // shrink by one, away from zero they grow by one: `bits + 1 + 2 * shrinks` with
        // `shrinks` all ones (-1) or zero.
        let shrinks = !((bits >> 31).wrapping_neg() ^ up);
        let away = bits
            .wrapping_add(1)
            .wrapping_add(shrinks.wrapping_add(shrinks));
        // From either zero the step lands on the smallest subnormal of the direction's sign.
        let zero = mask(bits << 1 == 0);
        let from_zero = 1 | (!up & 0x8000_0000);
        let moved = (zero & from_zero) | (!zero & away);
        let stays = mask(bits & 0x7f80_0000 == 0x7f80_0000) | mask(sign[k] == 0.0);
        f32::from_bits((stays & bits) | (!stays & moved))
    });
    Vec3A::from_vec4(Vec4::from_array(stepped))
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
        // Each value in every lane, the lanes going different ways.
        let step = |x: f32, signs: [f32; 3]| step_toward(Vec3A::splat(x), Vec3A::from(signs));
        for x in values {
            for signs in [[2.0, -0.5, 0.0], [-0.5, 0.0, 2.0], [0.0, 2.0, -0.5]] {
                let stepped = step(x, signs).to_array();
                for (k, sign) in signs.into_iter().enumerate() {
                    let expected = match () {
                        _ if sign > 0.0 => x.next_up(),
                        _ if sign < 0.0 => x.next_down(),
                        _ => x,
                    };
                    assert_eq!(stepped[k].to_bits(), expected.to_bits(), "{x:e} {sign}");
                }
            }
        }
        for x in [f32::INFINITY, f32::NEG_INFINITY] {
            assert_eq!(step(x, [1.0, -1.0, 0.0]), Vec3A::splat(x));
        }
        assert!(step(f32::NAN, [1.0, -1.0, 0.0]).is_nan_mask().all());
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
