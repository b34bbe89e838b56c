//! The pinhole camera: film coordinates to world-space rays.

use crate::math::{Vec2, Vec3A};
use crate::scene::Camera;

/// A camera prepared for an image of a given size.
#[derive(Clone, Copy, Debug)]
pub struct PinholeCamera {
    eye: Vec3A,
    /// Image-plane point of the film's top-left corner, at unit distance from the eye.
    top_left: Vec3A,
    /// Step across one pixel to the right, in world units on that plane.
    pixel_right: Vec3A,
    /// Step across one pixel downward.
    pixel_down: Vec3A,
    width: u32,
}

impl PinholeCamera {
    /// The camera for a `width` x `height` film; the vertical field of view is kept and the
    /// horizontal one follows the film's aspect ratio.
    pub fn new(camera: &Camera, width: u32, height: u32) -> Self {
        let forward = Vec3A::from(camera.forward);
        let up = Vec3A::from(camera.up);
        let right = forward.cross(up).normalize();
        let half_height = (camera.vfov * 0.5).tan();
        let half_width = half_height * width as f32 / height as f32;
        PinholeCamera {
            eye: camera.eye.into(),
            top_left: forward - half_width * right + half_height * up,
            pixel_right: right * (2.0 * half_width / width as f32),
            pixel_down: -up * (2.0 * half_height / height as f32),
            width,
        }
    }

    /// The ray through `jitter` (in [0,1)^2) inside pixel `pixel` (row-major, row 0 at the
    /// top): origin and unit direction.
    #[inline]
    pub fn generate_ray(&self, pixel: u32, jitter: Vec2) -> (Vec3A, Vec3A) {
        let x = (pixel % self.width) as f32 + jitter.x;
        let y = (pixel / self.width) as f32 + jitter.y;
        let d = self.top_left + x * self.pixel_right + y * self.pixel_down;
        (self.eye, d.normalize())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;

    #[test]
    fn seed_camera_maps_corners_as_the_report_says() {
        // Eye (-1,0,0) looking +x, image plane x = 0 over y, z in [-1, 1]; left edge y = +1.
        let c = Camera::look_at(
            Vec3::new(-1.0, 0.0, 0.0),
            Vec3::ZERO,
            Vec3::Z,
            90f32.to_radians(),
        );
        let cam = PinholeCamera::new(&c, 800, 800);
        let (o, d) = cam.generate_ray(0, Vec2::ZERO);
        let p = o + d / d.x; // point on the plane x = 0
        assert!(
            (p - Vec3A::new(0.0, 1.0, 1.0)).length() < 1e-5,
            "top-left is (y, z) = (1, 1): {p}"
        );
        let (o, d) = cam.generate_ray(800 * 800 - 1, Vec2::ONE);
        let p = o + d / d.x;
        assert!(
            (p - Vec3A::new(0.0, -1.0, -1.0)).length() < 1e-4,
            "bottom-right: {p}"
        );
    }
}
