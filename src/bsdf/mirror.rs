//! Perfect specular reflection: all light leaves in the mirror direction.

use crate::math::{Rgb, Vec3A};

use super::BsdfSample;

/// Mirror direction of `wo` about the local normal `+z`.
#[inline]
pub fn reflect(wo: Vec3A) -> Vec3A {
    Vec3A::new(-wo.x, -wo.y, wo.z)
}

/// The only direction a mirror can return; its weight is the tint.
#[inline]
pub fn sample(tint: Rgb, wo: Vec3A) -> Option<BsdfSample> {
    (wo.z != 0.0).then_some(BsdfSample {
        wi: reflect(wo),
        weight: tint,
        pdf: 1.0,
        is_delta: true,
    })
}
