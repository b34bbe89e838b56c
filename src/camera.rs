//! The camera as the render uses it, pinhole or orthographic: film coordinates to
//! world-space rays and back, with the pixel filter that places each camera sample around
//! its pixel ([`crate::filter`]) and each camera ray's cone ([`crate::ray_cone`]).

use crate::filter::{FilterSampler, PixelFilter};
use crate::math::{Rgb, Vec2, Vec3A};
use crate::ray_cone::RayCone;
use crate::scene::{Camera, Projection};

/// A camera prepared for an image of a given size: a pinhole, or orthographic (parallel
/// rays from a film through the eye, perpendicular to it).
#[derive(Clone, Copy, Debug)]
pub struct PinholeCamera {
    eye: Vec3A,
    /// Whether rays are parallel (orthographic) rather than from the eye.
    orthographic: bool,
    /// Image-plane point of the film's top-left corner, relative to the eye: at unit
    /// distance in front of it (pinhole), or in the film's plane through it (orthographic).
    top_left: Vec3A,
    /// Step across one pixel to the right, in world units on that plane.
    pixel_right: Vec3A,
    /// Step across one pixel downward.
    pixel_down: Vec3A,
    width: u32,
    height: u32,
    /// Unit normal of the image plane (toward the scene) and its distance from the eye.
    plane_normal: Vec3A,
    plane_distance: f32,
    /// Area of one pixel on the image plane.
    pixel_area: f32,
    /// Where a pixel's samples fall around it (the box of 1 px unless [`Self::with_filter`]).
    filter: FilterSampler,
}

impl PinholeCamera {
    /// The camera for a `width` x `height` film; the vertical field of view (or, orthographic,
    /// the film's height) is kept and the horizontal one follows the film's aspect ratio.
    pub fn new(camera: &Camera, width: u32, height: u32) -> Self {
        let forward = Vec3A::from(camera.forward);
        let up = Vec3A::from(camera.up);
        let right = forward.cross(up).normalize();
        let (half_height, centre, orthographic) = match camera.projection {
            Projection::Perspective => ((camera.vfov * 0.5).tan(), forward, false),
            Projection::Orthographic { half_height } => (half_height, Vec3A::ZERO, true),
        };
        let half_width = half_height * width as f32 / height as f32;
        let top_left = centre - half_width * right + half_height * up;
        let pixel_right = right * (2.0 * half_width / width as f32);
        let pixel_down = -up * (2.0 * half_height / height as f32);
        // The plane spanned by the pixel steps (perpendicular to `forward` unless the up
        // vector was not perpendicular to it), facing the scene.
        let normal = pixel_right.cross(pixel_down).normalize();
        let plane_normal = if normal.dot(forward) < 0.0 {
            -normal
        } else {
            normal
        };
        PinholeCamera {
            eye: camera.eye.into(),
            orthographic,
            top_left,
            pixel_right,
            pixel_down,
            width,
            height,
            plane_normal,
            plane_distance: top_left.dot(plane_normal),
            pixel_area: pixel_right.cross(pixel_down).length(),
            filter: FilterSampler::default(),
        }
    }

    /// The camera with pixel filter `filter` (its table built here, once per render).
    pub fn with_filter(self, filter: PixelFilter) -> Self {
        PinholeCamera {
            filter: FilterSampler::new(filter),
            ..self
        }
    }

    /// The ray cone of every camera ray ([`crate::ray_cone`]): a point at the eye spreading
    /// by one pixel's angle (its height on the image plane over the plane's distance), or,
    /// orthographic, one pixel's height that does not spread.
    #[inline]
    pub fn ray_cone(&self) -> RayCone {
        if self.orthographic {
            return RayCone {
                width: self.pixel_down.length(),
                spread: 0.0,
            };
        }
        RayCone {
            width: 0.0,
            spread: self.pixel_down.length() / self.plane_distance,
        }
    }

    /// Whether the camera is orthographic. Its rays' directions are all the same (a delta
    /// density, [`Self::direction_density`] is 0): light paths cannot reach its film, and
    /// the render traces none for it (`wavefront::light_paths::caustics_traced`).
    #[inline]
    pub fn is_orthographic(&self) -> bool {
        self.orthographic
    }

    /// The eye (the pinhole).
    #[inline]
    pub fn eye(&self) -> Vec3A {
        self.eye
    }

    /// The density, per unit solid angle, of the direction of a camera ray of one pixel when
    /// that ray goes along `direction` (unit) through the pixel, for the box filter of 1 px:
    /// it samples the pixel's area on the image plane uniformly, and an area `dA` there
    /// subtends `dA cos^3(theta) / h^2` (`h` the plane's distance, `theta` the angle to its
    /// normal). Zero for directions away from the image plane. With another filter, the density
    /// for a pixel is this times the filter's density at the offset from the pixel's centre
    /// ([`Self::splat`] applies it); the caustics' MIS weights use this one on both sides, which
    /// keeps their sum 1 (an unbiased, if not exactly balanced, heuristic).
    /// An orthographic camera's rays all share one direction: 0.
    #[inline]
    pub fn direction_density(&self, direction: Vec3A) -> f32 {
        let cos = direction.dot(self.plane_normal);
        if cos <= 0.0 || self.orthographic {
            return 0.0;
        }
        self.plane_distance * self.plane_distance / (self.pixel_area * cos * cos * cos)
    }

    /// The film position (pixels from the film's top-left corner, x right, y down) the world
    /// point `p` projects to, if it lies in front of the camera (of its film's plane,
    /// orthographic); it may lie off the film. Through the eye, or orthographic along the
    /// plane's normal.
    #[inline]
    pub fn film_position(&self, p: Vec3A) -> Option<Vec2> {
        let d = p - self.eye;
        let along = d.dot(self.plane_normal);
        if along <= 0.0 || !along.is_finite() {
            return None;
        }
        let on_plane = if self.orthographic {
            d - self.plane_normal * along - self.top_left
        } else {
            d * (self.plane_distance / along) - self.top_left
        };
        let x = on_plane.dot(self.pixel_right) / self.pixel_right.length_squared();
        let y = on_plane.dot(self.pixel_down) / self.pixel_down.length_squared();
        Some(Vec2::new(x, y))
    }

    /// The film position of the world point `p` if some pixel's camera rays (through its
    /// filter) pass through it: in front of the camera, and on the film or within the
    /// filter's reach of it.
    #[inline]
    pub fn film_point(&self, p: Vec3A) -> Option<Vec2> {
        self.film_position(p)
            .filter(|&at| self.filter.reaches_film(at, self.width, self.height))
    }

    /// The pixel (row-major index) whose camera rays pass through the world point `p` with
    /// the box filter of 1 px, if it lies in front of the camera and projects into the image.
    #[inline]
    pub fn pixel_of(&self, p: Vec3A) -> Option<u32> {
        let at = self.film_position(p)?;
        let inside =
            at.x >= 0.0 && at.y >= 0.0 && at.x < self.width as f32 && at.y < self.height as f32;
        // Rounding at the far edge can still give the width or height itself.
        let (column, row) = (at.x as u32, at.y as u32);
        (inside && column < self.width && row < self.height).then(|| row * self.width + column)
    }

    /// Adds a light path's contribution `value` at film position `film_point` (from
    /// [`Self::film_point`], weighted with [`Self::direction_density`]) to the pixels whose
    /// filters reach it (`splats`, one per pixel, row-major), each times its filter's
    /// density: the camera's importance for that pixel. With the box of 1 px, the one pixel
    /// the point falls in.
    #[inline]
    pub fn splat(&self, film_point: Vec2, value: Rgb, splats: &mut [Rgb]) {
        self.filter.splat(film_point, value, self.width, splats);
    }

    /// The camera ray of pixel `pixel` (row-major, row 0 at the top) for the uniform pair `u`
    /// in [0,1)^2: through the film position the pixel filter draws from `u` (with the box of
    /// 1 px, `u` itself inside the pixel); origin and unit direction. Orthographic: from that
    /// film position along the film's normal.
    #[inline]
    pub fn generate_ray(&self, pixel: u32, u: Vec2) -> (Vec3A, Vec3A) {
        let jitter = self.filter.sample_jitter(u);
        let x = (pixel % self.width) as f32 + jitter.x;
        let y = (pixel / self.width) as f32 + jitter.y;
        let d = self.top_left + x * self.pixel_right + y * self.pixel_down;
        if self.orthographic {
            return (self.eye + d, self.plane_normal);
        }
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

    #[test]
    fn pixel_of_inverts_generate_ray() {
        let c = Camera::look_at(
            Vec3::new(0.3, -2.0, 0.5),
            Vec3::new(0.0, 0.0, 0.2),
            Vec3::Z,
            50f32.to_radians(),
        );
        let cam = PinholeCamera::new(&c, 37, 23);
        for pixel in [0, 5, 36, 37 * 11 + 17, 37 * 23 - 1] {
            let (o, d) = cam.generate_ray(pixel, Vec2::new(0.25, 0.75));
            assert_eq!(cam.pixel_of(o + 3.7 * d), Some(pixel));
        }
        assert_eq!(cam.pixel_of(cam.eye() - Vec3A::new(0.0, 1.0, 0.0)), None);
    }

    #[test]
    fn an_orthographic_film_spans_its_magnification_and_inverts() {
        // ymag 2 (film 4 tall) on a 40 x 20 image: 8 wide, every ray along forward (+x).
        let mut c = Camera::look_at(Vec3::new(-3.0, 0.0, 0.0), Vec3::ZERO, Vec3::Z, 1.0);
        c.projection = Projection::Orthographic { half_height: 2.0 };
        let cam = PinholeCamera::new(&c, 40, 20);
        let (o, d) = cam.generate_ray(0, Vec2::ZERO);
        assert!(
            (o - Vec3A::new(-3.0, 4.0, 2.0)).length() < 1e-5,
            "top-left {o}"
        );
        assert_eq!(d, Vec3A::X);
        let (o, d) = cam.generate_ray(40 * 20 - 1, Vec2::ONE);
        assert!(
            (o - Vec3A::new(-3.0, -4.0, -2.0)).length() < 1e-5,
            "bottom-right {o}"
        );
        assert_eq!(d, Vec3A::X);
        for pixel in [0, 7, 39, 40 * 9 + 21, 40 * 20 - 1] {
            let (o, d) = cam.generate_ray(pixel, Vec2::new(0.25, 0.75));
            assert_eq!(cam.pixel_of(o + 11.0 * d), Some(pixel));
        }
        assert_eq!(
            cam.pixel_of(Vec3A::new(-3.5, 0.0, 0.0)),
            None,
            "behind the film"
        );
        assert_eq!(cam.direction_density(Vec3A::X), 0.0, "a delta in direction");
        let cone = cam.ray_cone();
        assert!(
            (cone.width - 0.2).abs() < 1e-6 && cone.spread == 0.0,
            "{cone:?}"
        );
    }

    #[test]
    fn direction_density_integrates_to_one_over_a_pixel() {
        // The solid angle of a pixel (the integral of 1 / density over it) against the solid
        // angle its four corner rays bound, from the closed form of a planar quadrilateral
        // (two spherical triangles, Van Oosterom and Strackee).
        let c = Camera::look_at(Vec3::ZERO, Vec3::X, Vec3::Z, 70f32.to_radians());
        let cam = PinholeCamera::new(&c, 16, 12);
        let triangle = |a: Vec3A, b: Vec3A, c: Vec3A| {
            let numerator = a.dot(b.cross(c)).abs();
            let denominator = 1.0 + a.dot(b) + b.dot(c) + c.dot(a);
            2.0 * numerator.atan2(denominator) as f64
        };
        for pixel in [0, 7 * 16 + 9, 16 * 12 - 1] {
            let corner = |x: f32, y: f32| cam.generate_ray(pixel, Vec2::new(x, y)).1;
            let (a, b, c, d) = (
                corner(0.0, 0.0),
                corner(1.0, 0.0),
                corner(1.0, 1.0),
                corner(0.0, 1.0),
            );
            let exact = triangle(a, b, c) + triangle(a, c, d);
            let n = 64;
            let mut sum = 0.0f64;
            for i in 0..n {
                for j in 0..n {
                    let jitter =
                        Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                    let (_, dir) = cam.generate_ray(pixel, jitter);
                    sum += 1.0 / cam.direction_density(dir) as f64;
                }
            }
            let estimate = sum / (n * n) as f64;
            assert!(
                (estimate / exact - 1.0).abs() < 1e-3,
                "{estimate} vs {exact}"
            );
        }
    }
}
