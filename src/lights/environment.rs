//! The environment light: radiance arriving from infinitely far away, either one constant
//! colour or an equirectangular (latitude-longitude) image read from a Radiance `.hdr` or
//! OpenEXR `.exr` file, scaled by a strength and turned about the up axis (+Z). It owns the
//! image, the 2-D piecewise-constant distribution that importance-samples it, and the
//! `eval` / `sample` / `pdf` trio that next-event estimation, MIS and camera rays use
//! (pbrt-v4's `ImageInfiniteLight` and `UniformInfiniteLight`, Mitsuba's `envmap` and
//! `constant`, Cycles' world background).
//!
//! Conventions:
//! - **Directions** are world-space and point *away* from the scene, toward the sky:
//!   `eval(d)` is the radiance arriving at any point from direction `d` (a camera ray that
//!   escapes along `d` sees `eval(d)`).
//! - **Mapping** is Blender/Cycles' equirectangular world mapping for a +Z-up world, so an
//!   HDRI looks here as it does in Blender: a direction `d` maps to
//!   `u = 0.5 - atan2(d.y, d.x) / (2 pi)` and `v = 0.5 + atan2(d.z, hypot(d.x, d.y)) / pi`,
//!   `v = 1` being the image's top row (+Z). So the image's centre column faces +X, its left
//!   quarter +Y, its right quarter -Y, its left and right edges -X.
//! - **Rotation** `rotation_degrees` is Blender's Mapping node (type Point) rotation about Z
//!   in front of the Environment Texture: the lookup direction is the world direction turned
//!   by `+rotation` (counter-clockwise seen from above), so the picture turns by `-rotation`.
//!   A sun at azimuth `phi` (from +X toward +Y) moves to `phi - rotation`.
//! - **Lookup** is nearest-texel, the same piecewise-constant function that the sampling
//!   distribution is built on. Then `eval / pdf` is constant within a texel up to the
//!   sin(theta) factor, so next-event estimation of a bright sun has the least variance, and
//!   the density is exactly the sampler's (bilinear lookup would also be unbiased with this
//!   density, since MIS only needs a valid pdf, but noisier, and would blur a small sun).

use crate::error::{Error, Result};
use crate::math::sampling::{sample_discrete, sample_uniform_sphere};
use crate::math::{Rgb, Vec2, Vec3A, luminance};
use std::f32::consts::{PI, TAU};
use std::path::Path;

/// One direction chosen by [`Environment::sample`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EnvSample {
    /// Unit world direction toward the sky.
    pub direction: Vec3A,
    /// `eval(direction)`: radiance arriving from it.
    pub radiance: Rgb,
    /// `pdf(direction)`: solid-angle density. Zero only at the poles of a map (a set of
    /// measure zero), where the caller drops the sample.
    pub pdf: f32,
}

/// A constant or image-based light at infinity. Immutable once built; `eval`, `sample` and
/// `pdf` allocate nothing.
#[derive(Clone, Debug)]
pub struct Environment {
    source: Source,
    /// `(cos, sin)` of the rotation: map direction = R_z(rotation) world direction.
    rotation: Vec2,
}

#[derive(Clone, Debug)]
enum Source {
    /// Strength already applied.
    Constant(Rgb),
    Map(EquirectMap),
}

/// An equirectangular image and its sampling distribution, both over the same texels.
#[derive(Clone, Debug)]
struct EquirectMap {
    width: usize,
    height: usize,
    /// Row-major from the top row (+Z), strength already applied.
    texels: Vec<Rgb>,
    /// Per texel, the density of the distribution over the unit square `(s, t)` (column and
    /// row coordinates in [0, 1)): the texel's weight times `width * height / total weight`.
    density: Vec<f32>,
    /// Running sums of the rows' weights (the last entry is the total): the marginal.
    row_cdf: Vec<f32>,
    /// Per row, running sums of its texels' weights: the conditionals, `width` per row.
    column_cdfs: Vec<f32>,
    /// Integral of luminance(radiance) over the sphere, in W / (m^2) per unit luminance.
    luminance_integral: f32,
}

/// Each texel's sampling weight gets this fraction of the map's mean luminance added (times
/// sin theta, like the rest), so that no direction has zero density: black regions still get
/// a few samples, at a cost below 0.1% of them.
const WEIGHT_FLOOR: f64 = 1e-3;

impl Environment {
    /// A constant environment of `radiance * strength` from every direction. `origin` names
    /// where the values came from in errors: the scene file, or the command-line option.
    pub fn constant(radiance: Rgb, strength: f32, origin: &Path) -> Result<Self> {
        check_strength(strength, origin)?;
        if !radiance.is_finite() || radiance.min_element() < 0.0 {
            return Err(Error::input(
                origin,
                None,
                format!(
                    "environment colour must be three finite numbers >= 0, got {}, {}, {}",
                    radiance.x, radiance.y, radiance.z
                ),
            ));
        }
        let radiance = radiance * strength;
        if !radiance.is_finite() {
            return Err(Error::input(
                origin,
                None,
                "environment colour times strength overflows",
            ));
        }
        Ok(Environment {
            source: Source::Constant(radiance),
            rotation: Vec2::new(1.0, 0.0),
        })
    }

    /// An equirectangular environment map from a Radiance `.hdr` or OpenEXR `.exr` file (the
    /// first RGB layer; alpha is ignored, as Blender ignores it in the world).
    pub fn from_file(path: &Path, strength: f32, rotation_degrees: f32) -> Result<Self> {
        check_strength(strength, path)?;
        check_rotation(rotation_degrees, path)?;
        let (width, height, texels) = read_image(path)?;
        Self::from_texels(width, height, texels, strength, rotation_degrees, path)
    }

    /// An equirectangular environment map from texels in row-major order, top row (+Z)
    /// first. `origin` names the file (or generator) in errors.
    pub fn from_texels(
        width: usize,
        height: usize,
        texels: Vec<Rgb>,
        strength: f32,
        rotation_degrees: f32,
        origin: &Path,
    ) -> Result<Self> {
        check_strength(strength, origin)?;
        check_rotation(rotation_degrees, origin)?;
        if height == 0 || width != 2 * height {
            return Err(Error::input(
                origin,
                None,
                format!(
                    "environment map is {width} x {height} pixels: an equirectangular \
                     (latitude-longitude) map must be exactly twice as wide as high"
                ),
            ));
        }
        if texels.len() != width * height {
            return Err(Error::input(
                origin,
                None,
                format!(
                    "environment map has {} pixels, but {width} x {height} needs {}",
                    texels.len(),
                    width * height
                ),
            ));
        }
        check_texels(&texels, width, origin)?;
        let texels: Vec<Rgb> = texels.into_iter().map(|t| t * strength).collect();
        if let Some(bad) = texels.iter().position(|t| !t.is_finite()) {
            return Err(Error::input(
                origin,
                Some(pixel_location(bad, width)),
                format!("environment map value times strength {strength} overflows"),
            ));
        }
        let radians = rotation_degrees.to_radians();
        Ok(Environment {
            source: Source::Map(EquirectMap::new(width, height, texels)),
            rotation: Vec2::new(radians.cos(), radians.sin()),
        })
    }

    /// Radiance arriving from world direction `direction` (need not be unit length).
    #[inline]
    pub fn eval(&self, direction: Vec3A) -> Rgb {
        match &self.source {
            Source::Constant(radiance) => *radiance,
            Source::Map(map) => map.texels[map.texel_index(self.to_map(direction))],
        }
    }

    /// Solid-angle density with which [`Environment::sample`] chooses `direction`.
    #[inline]
    pub fn pdf(&self, direction: Vec3A) -> f32 {
        match &self.source {
            Source::Constant(_) => 1.0 / (4.0 * PI),
            Source::Map(map) => {
                let m = self.to_map(direction);
                let sin_theta = Vec2::new(m.x, m.y).length() / m.length();
                if sin_theta > 0.0 {
                    // dω = sin θ dθ dφ = 2 π² sin θ ds dt.
                    map.density[map.texel_index(m)] / (2.0 * PI * PI * sin_theta)
                } else {
                    0.0
                }
            }
        }
    }

    /// A direction chosen in proportion to luminance (a map) or uniformly (a constant), from
    /// two uniform numbers in [0, 1).
    #[inline]
    pub fn sample(&self, u: Vec2) -> EnvSample {
        let direction = match &self.source {
            Source::Constant(radiance) => {
                return EnvSample {
                    direction: sample_uniform_sphere(u),
                    radiance: *radiance,
                    pdf: 1.0 / (4.0 * PI),
                };
            }
            Source::Map(map) => self.to_world(map.sample_map_direction(u)),
        };
        // The same functions as a BSDF-sampled ray's lookup, so that MIS sees one density;
        // they differ from the chosen texel's values only on texel edges (measure zero).
        EnvSample {
            direction,
            radiance: self.eval(direction),
            pdf: self.pdf(direction),
        }
    }

    /// The light's power as seen by a scene inside a sphere of radius `scene_radius`, for
    /// choosing among lights: `pi r^2` (the disk the scene presents to each direction) times
    /// the integral of luminance(radiance) over the sphere, as pbrt-v4's `Phi` of its infinite
    /// lights (for a constant, `pi r^2 * 4 pi * luminance`).
    pub fn power_estimate(&self, scene_radius: f32) -> f32 {
        let integral = match &self.source {
            Source::Constant(radiance) => 4.0 * PI * luminance(*radiance),
            Source::Map(map) => map.luminance_integral,
        };
        PI * scene_radius * scene_radius * integral
    }

    /// True for a constant colour (no image).
    pub fn is_constant(&self) -> bool {
        matches!(self.source, Source::Constant(_))
    }

    /// World direction to map direction: R_z(+rotation).
    #[inline]
    fn to_map(&self, d: Vec3A) -> Vec3A {
        let Vec2 { x: c, y: s } = self.rotation;
        Vec3A::new(c * d.x - s * d.y, s * d.x + c * d.y, d.z)
    }

    /// Map direction to world direction: R_z(-rotation).
    #[inline]
    fn to_world(&self, m: Vec3A) -> Vec3A {
        let Vec2 { x: c, y: s } = self.rotation;
        Vec3A::new(c * m.x + s * m.y, -s * m.x + c * m.y, m.z)
    }
}

impl EquirectMap {
    fn new(width: usize, height: usize, texels: Vec<Rgb>) -> Self {
        // Weights: luminance times the sine at the row's centre (rows near the poles cover
        // less solid angle), plus a floor. Sums in f64: a sun can be 1e5 times the sky.
        let mean_luminance =
            texels.iter().map(|&t| luminance(t) as f64).sum::<f64>() / texels.len() as f64;
        let floor = if mean_luminance > 0.0 {
            WEIGHT_FLOOR * mean_luminance
        } else {
            1.0 // A black map: uniform over the sphere.
        };
        let mut weights = vec![0.0f64; width * height];
        let mut luminance_integral = 0.0f64;
        let d_phi = std::f64::consts::TAU / width as f64;
        for i in 0..height {
            let theta = |edge: usize| edge as f64 / height as f64 * std::f64::consts::PI;
            let sin_centre = ((i as f64 + 0.5) / height as f64 * std::f64::consts::PI).sin();
            let texel_solid_angle = d_phi * (theta(i).cos() - theta(i + 1).cos());
            for j in 0..width {
                let l = luminance(texels[i * width + j]) as f64;
                weights[i * width + j] = (l + floor) * sin_centre;
                luminance_integral += l * texel_solid_angle;
            }
        }
        let total: f64 = weights.iter().sum();
        let density_scale = (width * height) as f64 / total;
        let density = weights
            .iter()
            .map(|&w| (w * density_scale) as f32)
            .collect();
        let mut row_cdf = Vec::with_capacity(height);
        let mut column_cdfs = Vec::with_capacity(width * height);
        let mut rows_so_far = 0.0f64;
        for row in weights.chunks_exact(width) {
            let mut so_far = 0.0f64;
            for &w in row {
                so_far += w;
                column_cdfs.push(so_far as f32);
            }
            rows_so_far += so_far;
            row_cdf.push(rows_so_far as f32);
        }
        EquirectMap {
            width,
            height,
            texels,
            density,
            row_cdf,
            column_cdfs,
            luminance_integral: luminance_integral as f32,
        }
    }

    /// Index of the texel that map direction `m` falls in.
    #[inline]
    fn texel_index(&self, m: Vec3A) -> usize {
        let s = 0.5 - m.y.atan2(m.x) * (1.0 / TAU);
        let t = 0.5 - m.z.atan2(Vec2::new(m.x, m.y).length()) * (1.0 / PI);
        // `as usize` saturates NaN and negatives to 0; `min` catches s or t rounding to 1.
        let column = ((s * self.width as f32) as usize).min(self.width - 1);
        let row = ((t * self.height as f32) as usize).min(self.height - 1);
        row * self.width + column
    }

    /// A map direction: a row from the marginal, a column from that row's conditional, then a
    /// uniform point in the texel's (s, t) rectangle.
    #[inline]
    fn sample_map_direction(&self, u: Vec2) -> Vec3A {
        let row = sample_discrete(&self.row_cdf, u.y);
        let dt = remap_within(&self.row_cdf, row, u.y);
        let cdf = &self.column_cdfs[row * self.width..(row + 1) * self.width];
        let column = sample_discrete(cdf, u.x);
        let ds = remap_within(cdf, column, u.x);
        let s = (column as f32 + ds) / self.width as f32;
        let t = (row as f32 + dt) / self.height as f32;
        let (sin_theta, cos_theta) = (PI * t).sin_cos();
        let (sin_phi, cos_phi) = (PI - TAU * s).sin_cos();
        Vec3A::new(sin_theta * cos_phi, sin_theta * sin_phi, cos_theta)
    }
}

/// Where `u` falls within entry `index` of `cdf`, as a fraction in [0, 1): the leftover of
/// the discrete choice, reused as a fresh uniform number.
#[inline]
fn remap_within(cdf: &[f32], index: usize, u: f32) -> f32 {
    let low = if index == 0 { 0.0 } else { cdf[index - 1] };
    let width = cdf[index] - low;
    if width > 0.0 {
        ((u * cdf[cdf.len() - 1] - low) / width).clamp(0.0, 1.0 - f32::EPSILON / 2.0)
    } else {
        0.5
    }
}

fn check_strength(strength: f32, origin: &Path) -> Result<()> {
    if strength.is_finite() && strength >= 0.0 {
        Ok(())
    } else {
        Err(Error::input(
            origin,
            None,
            format!("environment strength must be a finite number >= 0, got {strength}"),
        ))
    }
}

fn check_rotation(degrees: f32, origin: &Path) -> Result<()> {
    if degrees.is_finite() {
        Ok(())
    } else {
        Err(Error::input(
            origin,
            None,
            format!("environment rotation must be a finite number of degrees, got {degrees}"),
        ))
    }
}

fn pixel_location(index: usize, width: usize) -> String {
    format!("pixel ({}, {})", index % width, index / width)
}

/// A kind of bad texel: its description and its test.
type TexelProblem = (&'static str, fn(&Rgb) -> bool);

/// NaN, infinite or negative texels are refused: the first one is named, with the count.
fn check_texels(texels: &[Rgb], width: usize, origin: &Path) -> Result<()> {
    let problems: [TexelProblem; 2] = [
        ("NaN or infinite values", |t| !t.is_finite()),
        ("negative values", |t| t.min_element() < 0.0),
    ];
    for (what, is_bad) in problems {
        let mut bad = texels.iter().enumerate().filter(|(_, t)| is_bad(t));
        if let Some((first, _)) = bad.next() {
            let count = 1 + bad.count();
            return Err(Error::input(
                origin,
                Some(pixel_location(first, width)),
                format!(
                    "environment map has {what} ({count} pixel{} in all; the first is named)",
                    if count == 1 { "" } else { "s" }
                ),
            ));
        }
    }
    Ok(())
}

/// Width, height and texels (top row first) of a `.hdr` or `.exr` file.
fn read_image(path: &Path) -> Result<(usize, usize, Vec<Rgb>)> {
    std::fs::metadata(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        action: "cannot read environment map",
        source,
    })?;
    let extension = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match extension.as_deref() {
        Some("hdr") => {
            let reader = image::ImageReader::with_format(
                std::io::BufReader::new(std::fs::File::open(path).map_err(|source| Error::Io {
                    path: path.to_path_buf(),
                    action: "cannot read environment map",
                    source,
                })?),
                image::ImageFormat::Hdr,
            );
            let image = reader
                .decode()
                .map_err(|e| Error::input(path, None, format!("cannot read Radiance HDR: {e}")))?
                .into_rgb32f();
            let (width, height) = (image.width() as usize, image.height() as usize);
            let texels = image.pixels().map(|p| Rgb::from(p.0)).collect();
            Ok((width, height, texels))
        }
        Some("exr") => {
            let image = crate::output::read_exr(path)?;
            Ok((image.width as usize, image.height as usize, image.pixels))
        }
        _ => Err(Error::input(
            path,
            None,
            "unsupported environment map format: use an equirectangular Radiance .hdr or \
             OpenEXR .exr image",
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::chi_square::chi_square_survival;
    use crate::math::rng::{path_key, uniform2};
    use std::f64::consts::PI as PI64;

    const ORIGIN: &str = "test-sky.hdr";

    /// A high-contrast 2:1 map: a sky whose luminance falls from horizon to zenith, a black
    /// strip (zero radiance, kept in reach by the floor), a darker ground and a `sun_size`
    /// square of texels `sun` times brighter than the sky.
    fn sunny_texels(width: usize, sun: f32) -> Vec<Rgb> {
        let height = width / 2;
        let mut texels = Vec::with_capacity(width * height);
        for i in 0..height {
            for j in 0..width {
                let t = (i as f32 + 0.5) / height as f32;
                let value = if i >= height / 2 {
                    Rgb::new(0.2, 0.15, 0.1)
                } else if j == width / 8 {
                    Rgb::ZERO
                } else {
                    Rgb::new(0.3, 0.5, 1.0) * (0.3 + 1.5 * t)
                };
                texels.push(value);
            }
        }
        // The sun: two texels side by side, a quarter of the way up from the horizon.
        let (row, column) = (height / 4, 5 * width / 8);
        for dj in 0..2 {
            texels[row * width + column + dj] = Rgb::new(1.0, 0.9, 0.8) * sun;
        }
        texels
    }

    fn sunny(width: usize, sun: f32, rotation_degrees: f32) -> Environment {
        Environment::from_texels(
            width,
            width / 2,
            sunny_texels(width, sun),
            1.0,
            rotation_degrees,
            Path::new(ORIGIN),
        )
        .unwrap()
    }

    fn direction(theta: f64, phi: f64) -> Vec3A {
        Vec3A::new(
            (theta.sin() * phi.cos()) as f32,
            (theta.sin() * phi.sin()) as f32,
            theta.cos() as f32,
        )
    }

    fn uniforms(seed: u64, i: u32) -> Vec2 {
        uniform2(path_key(seed, i, 0), 0, 0)
    }

    /// Integral of `pdf` over the sphere by the midpoint rule on a `2n x n` (phi, theta) grid.
    fn pdf_integral(env: &Environment, n: usize) -> f64 {
        let (d_theta, d_phi) = (PI64 / n as f64, PI64 / n as f64);
        let mut sum = 0.0;
        for a in 0..n {
            let theta = (a as f64 + 0.5) * d_theta;
            for b in 0..2 * n {
                let phi = (b as f64 + 0.5) * d_phi;
                sum += env.pdf(direction(theta, phi)) as f64 * theta.sin();
            }
        }
        sum * d_theta * d_phi
    }

    #[test]
    fn pdf_integrates_to_one() {
        // Grid aligned with the texels (rotation 0): the midpoint rule is exact but for the
        // f32 density; turned by an odd angle, texel edges cut grid cells.
        let aligned = pdf_integral(&sunny(64, 5e4, 0.0), 1024);
        assert!((aligned - 1.0).abs() < 1e-4, "{aligned}");
        let turned = pdf_integral(&sunny(64, 5e4, 37.3), 2048);
        assert!((turned - 1.0).abs() < 2e-3, "{turned}");
        let constant = Environment::constant(Rgb::ONE, 1.0, Path::new(ORIGIN)).unwrap();
        assert!((pdf_integral(&constant, 256) - 1.0).abs() < 1e-5);
    }

    #[test]
    fn mapping_matches_blender() {
        // A 4 x 2 map: the upper row's columns cover, left to right, the quadrants
        // (-X, +Y), (+X, +Y), (+X, -Y), (-X, -Y); the lower row the same below the horizon.
        let texels: Vec<Rgb> = (0..8).map(|k| Rgb::splat(k as f32)).collect();
        let env =
            Environment::from_texels(4, 2, texels.clone(), 1.0, 0.0, Path::new(ORIGIN)).unwrap();
        let quadrants = [(-1.0, 1.0), (1.0, 1.0), (1.0, -1.0), (-1.0, -1.0)];
        for (k, (x, y)) in quadrants.into_iter().enumerate() {
            assert_eq!(env.eval(Vec3A::new(x, y, 0.5)), texels[k], "upper {k}");
            assert_eq!(env.eval(Vec3A::new(x, y, -0.5)), texels[4 + k], "lower {k}");
        }
        // Rotation 90 (Blender's Mapping node, Point, rotation Z = 90): the lookup direction
        // turns counter-clockwise, so (+X, +Y) reads the (-X, +Y) column.
        let turned =
            Environment::from_texels(4, 2, texels.clone(), 1.0, 90.0, Path::new(ORIGIN)).unwrap();
        assert_eq!(turned.eval(Vec3A::new(1.0, 1.0, 0.5)), texels[0]);
        assert_eq!(turned.eval(Vec3A::new(1.0, -1.0, -0.5)), texels[5]);
    }

    #[test]
    fn samples_match_the_pdf_chi_square() {
        // Bins are quarter texels in (phi, theta) of the map's frame, so that every bin edge
        // is a texel edge or inside none: pdf * sin(theta) is then constant within a bin, and
        // the 4 x 4 midpoint rule gives its expected count with no discontinuity error.
        // (The project's sphere-wide helper integrates over cells whose edges cross the
        // texels' density jumps, which a 5e4:1 sun turns into false failures.)
        for rotation in [0.0f32, 28.0] {
            let width = 32;
            let height = width / 2;
            // A 300:1 sun takes about half the samples, so that the sky's bins are tested too.
            let env = sunny(width, 300.0, rotation);
            let (phi_bins, theta_bins) = (4 * width, 4 * height);
            let samples = 1_000_000u32;
            let mut observed = vec![0.0f64; phi_bins * theta_bins];
            let radians = (rotation as f64).to_radians();
            let (c, s) = (radians.cos(), radians.sin());
            for i in 0..samples {
                let sample = env.sample(uniforms(11, i));
                let d = sample.direction;
                assert!((d.length() - 1.0).abs() < 1e-5);
                let (x, y, z) = (d.x as f64, d.y as f64, d.z as f64);
                // The map frame: R_z(+rotation), then Cycles' angles.
                let (mx, my) = (c * x - s * y, s * x + c * y);
                let u = 0.5 - my.atan2(mx) / (2.0 * PI64);
                let v = z.clamp(-1.0, 1.0).acos() / PI64;
                let b = ((u * phi_bins as f64) as usize).min(phi_bins - 1);
                let a = ((v * theta_bins as f64) as usize).min(theta_bins - 1);
                observed[a * phi_bins + b] += 1.0;
            }
            let sub = 4;
            let mut expected = vec![0.0f64; phi_bins * theta_bins];
            for a in 0..theta_bins {
                for b in 0..phi_bins {
                    let mut integral = 0.0;
                    for p in 0..sub {
                        for q in 0..sub {
                            let v = (a as f64 + (p as f64 + 0.5) / sub as f64) / theta_bins as f64;
                            let u = (b as f64 + (q as f64 + 0.5) / sub as f64) / phi_bins as f64;
                            let (theta, map_phi) = (PI64 * v, PI64 - 2.0 * PI64 * u);
                            let phi = map_phi - radians; // world = R_z(-rotation) map
                            integral += env.pdf(direction(theta, phi)) as f64 * theta.sin();
                        }
                    }
                    let cell = (PI64 / theta_bins as f64) * (2.0 * PI64 / phi_bins as f64);
                    expected[a * phi_bins + b] =
                        integral * cell / (sub * sub) as f64 * samples as f64;
                }
            }
            let total: f64 = expected.iter().sum::<f64>() / samples as f64;
            assert!(
                (total - 1.0).abs() < 1e-4,
                "rotation {rotation}: mass {total}"
            );
            // Pearson's statistic, bins expecting fewer than 5 pooled.
            let (mut statistic, mut dof) = (0.0, 0usize);
            let (mut pool_e, mut pool_o) = (0.0, 0.0);
            for (&e, &o) in expected.iter().zip(&observed) {
                assert!(e > 0.0 || o == 0.0, "samples where the pdf is 0");
                if e < 5.0 {
                    pool_e += e;
                    pool_o += o;
                } else {
                    statistic += (o - e) * (o - e) / e;
                    dof += 1;
                }
            }
            if pool_e > 0.0 {
                statistic += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
                dof += 1;
            }
            let p_value = chi_square_survival(statistic, (dof - 1) as f64);
            eprintln!("rotation {rotation}: chi2 {statistic:.1}, dof {dof}, p {p_value:.3}");
            assert!(
                p_value > 0.01,
                "rotation {rotation}: chi2 {statistic:.1}, dof {dof}, p {p_value:e}"
            );
        }
    }

    #[test]
    fn sample_returns_eval_and_pdf_of_its_direction() {
        let env = sunny(64, 5e4, 12.5);
        let mut sun_samples = 0;
        for i in 0..100_000 {
            let s = env.sample(uniforms(3, i));
            assert_eq!(s.radiance, env.eval(s.direction));
            assert_eq!(s.pdf, env.pdf(s.direction));
            assert!(s.pdf > 0.0 && s.pdf.is_finite());
            sun_samples += (s.radiance.x > 1e3) as u32;
        }
        // The two sun texels hold nearly all the weight (sky luminance ~0.5 over 2048 texels
        // against 2 x 4.6e4): most samples land on the sun.
        assert!(sun_samples > 90_000, "{sun_samples}");
    }

    /// Mean and standard error of `f` over `n` samples.
    fn mean_and_error(n: u32, f: impl Fn(u32) -> Rgb) -> (Rgb, Rgb) {
        let (mut sum, mut sum2) = ([0.0f64; 3], [0.0f64; 3]);
        for i in 0..n {
            let v = f(i).to_array();
            for k in 0..3 {
                sum[k] += v[k] as f64;
                sum2[k] += (v[k] as f64).powi(2);
            }
        }
        let n = n as f64;
        let mean = sum.map(|s| s / n);
        let error: [f64; 3] = std::array::from_fn(|k| ((sum2[k] / n - mean[k].powi(2)) / n).sqrt());
        (
            Rgb::from(mean.map(|m| m as f32)),
            Rgb::from(error.map(|e| e as f32)),
        )
    }

    #[test]
    fn irradiance_estimators_agree_with_the_closed_form() {
        // E = integral of L cos+ over the upper hemisphere. Exactly, per texel row above the
        // horizon: L * d_phi * (sin^2 theta1 - sin^2 theta0) / 2 (theta from +Z); the
        // rotation about Z does not change it.
        let width = 32;
        let height = width / 2;
        let texels = sunny_texels(width, 2e3);
        let env =
            Environment::from_texels(width, height, texels.clone(), 1.0, 40.0, Path::new(ORIGIN))
                .unwrap();
        let mut exact = [0.0f64; 3];
        for i in 0..height / 2 {
            let theta = |edge: usize| edge as f64 / height as f64 * PI64;
            let weight = (2.0 * PI64 / width as f64)
                * (theta(i + 1).sin().powi(2) - theta(i).sin().powi(2))
                / 2.0;
            for j in 0..width {
                let l = texels[i * width + j].to_array();
                for k in 0..3 {
                    exact[k] += l[k] as f64 * weight;
                }
            }
        }
        let n = 2_000_000;
        let (uniform, uniform_error) = mean_and_error(n, |i| {
            // Uniform on the upper hemisphere: cos theta = u, density 1 / (2 pi).
            let u = uniforms(21, i);
            let r = (1.0 - u.x * u.x).max(0.0).sqrt();
            let d = Vec3A::new(r * (TAU * u.y).cos(), r * (TAU * u.y).sin(), u.x);
            env.eval(d) * d.z * TAU
        });
        let (importance, importance_error) = mean_and_error(n, |i| {
            let s = env.sample(uniforms(22, i));
            if s.pdf > 0.0 {
                env.eval(s.direction) * s.direction.z.max(0.0) / s.pdf
            } else {
                Rgb::ZERO
            }
        });
        for k in 0..3 {
            let (a, ea, b, eb) = (
                uniform[k] as f64,
                uniform_error[k] as f64,
                importance[k] as f64,
                importance_error[k] as f64,
            );
            assert!(
                (a - exact[k]).abs() < 5.0 * ea,
                "uniform {a} +- {ea}, exact {}",
                exact[k]
            );
            assert!(
                (b - exact[k]).abs() < 5.0 * eb,
                "importance {b} +- {eb}, exact {}",
                exact[k]
            );
            assert!((a - b).abs() < 5.0 * (ea * ea + eb * eb).sqrt());
            eprintln!(
                "channel {k}: exact {:.4}, uniform {a:.4} +- {ea:.4}, importance {b:.4} +- {eb:.4}",
                exact[k]
            );
            // Importance sampling is the better estimator on a sunny map.
            assert!(eb < ea / 3.0, "channel {k}: {eb} vs {ea}");
        }
    }

    #[test]
    fn constant_irradiance_is_pi_l() {
        let l = Rgb::new(0.5, 1.0, 2.0);
        let env = Environment::constant(l, 1.5, Path::new(ORIGIN)).unwrap();
        let (mean, error) = mean_and_error(1_000_000, |i| {
            let s = env.sample(uniforms(31, i));
            assert_eq!(s.pdf, env.pdf(s.direction));
            s.radiance * s.direction.z.max(0.0) / s.pdf
        });
        for k in 0..3 {
            let exact = PI * l[k] * 1.5;
            assert!(
                (mean[k] - exact).abs() < 5.0 * error[k],
                "{} +- {} vs {exact}",
                mean[k],
                error[k]
            );
        }
        let power = env.power_estimate(2.0);
        let expected = PI * 4.0 * 4.0 * PI * luminance(l * 1.5);
        assert!((power - expected).abs() < 1e-4 * expected);
    }

    #[test]
    fn power_estimate_integrates_luminance() {
        // pi r^2 times the integral of luminance over the sphere, against its estimate from
        // the importance sampler.
        let env = sunny(64, 5e4, 0.0);
        let (mean, error) = mean_and_error(200_000, |i| {
            let s = env.sample(uniforms(41, i));
            Rgb::splat(luminance(s.radiance) / s.pdf)
        });
        let power = env.power_estimate(1.0) / PI;
        assert!(
            (power - mean.x).abs() < 5.0 * error.x + 1e-4 * power,
            "{power} vs {mean}"
        );
    }

    #[test]
    fn rotation_turns_the_sun_about_z() {
        // The same uniform numbers choose the same texel of the picture; turned by 90 degrees,
        // its world direction turns by -90 degrees about +Z (Blender's Mapping node sign).
        let still = sunny(64, 5e4, 0.0);
        let turned = sunny(64, 5e4, 90.0);
        for i in 0..1000 {
            let u = uniforms(51, i);
            let (a, b) = (still.sample(u), turned.sample(u));
            let expected = Vec3A::new(a.direction.y, -a.direction.x, a.direction.z);
            assert!((b.direction - expected).length() < 1e-5, "{a:?} {b:?}");
            assert_eq!(a.radiance, b.radiance);
        }
        // And the brightest sampled direction, the sun, moved from azimuth phi to phi - 90.
        let sun = |env: &Environment| {
            (0..1000)
                .map(|i| env.sample(uniforms(52, i)))
                .filter(|s| s.radiance.x > 1e3)
                .map(|s| s.direction)
                .sum::<Vec3A>()
                .normalize()
        };
        let (a, b) = (sun(&still), sun(&turned));
        let azimuth = |d: Vec3A| d.y.atan2(d.x).to_degrees();
        let turn = (azimuth(b) - azimuth(a) + 540.0).rem_euclid(360.0) - 180.0;
        assert!((turn + 90.0).abs() < 0.5, "{turn}");
    }

    #[test]
    fn shipped_sky_has_its_sun_where_the_generator_put_it() {
        // `assets/sky.hdr` from `examples/make_sky.rs`: level ground receives 2.5 from the
        // sun and 0.5 from the sky (luminance; RGBE keeps about 1%), and the brightest texel
        // lies at elevation 40 and azimuth 35 degrees, read through Cycles' mapping.
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/sky.hdr");
        let env = Environment::from_file(&path, 1.0, 0.0).unwrap();
        let Source::Map(map) = &env.source else {
            panic!("a map")
        };
        let (width, height) = (map.width, map.height);
        let mut irradiance = [0.0f64; 2]; // sun (texels above 100), sky
        for i in 0..height / 2 {
            let theta = |edge: usize| edge as f64 / height as f64 * PI64;
            let weight = (2.0 * PI64 / width as f64)
                * (theta(i + 1).sin().powi(2) - theta(i).sin().powi(2))
                / 2.0;
            for j in 0..width {
                let l = luminance(map.texels[i * width + j]) as f64;
                irradiance[(l < 100.0) as usize] += l * weight;
            }
        }
        eprintln!(
            "sky.hdr: level-ground irradiance sun {:.4}, sky {:.4}",
            irradiance[0], irradiance[1]
        );
        assert!((irradiance[0] - 2.5).abs() < 0.025 && (irradiance[1] - 0.5).abs() < 0.005);
        let brightest = (0..width * height)
            .max_by(|&a, &b| luminance(map.texels[a]).total_cmp(&luminance(map.texels[b])))
            .unwrap();
        let (i, j) = (brightest / width, brightest % width);
        let d = direction(
            PI64 * (i as f64 + 0.5) / height as f64,
            PI64 - 2.0 * PI64 * (j as f64 + 0.5) / width as f64,
        );
        let elevation = d.z.asin().to_degrees();
        let azimuth = d.y.atan2(d.x).to_degrees();
        // Within one texel (0.7 degrees).
        assert!(
            (elevation - 40.0).abs() < 0.71 && (azimuth - 35.0).abs() < 0.71,
            "{elevation} {azimuth}"
        );
    }

    fn error_text(result: Result<Environment>) -> String {
        result.unwrap_err().to_string()
    }

    #[test]
    fn bad_input_is_named() {
        let origin = Path::new(ORIGIN);
        let texels = || sunny_texels(16, 10.0);
        let text = error_text(Environment::from_texels(
            16,
            16,
            vec![Rgb::ONE; 256],
            1.0,
            0.0,
            origin,
        ));
        assert!(text.starts_with(ORIGIN) && text.contains("16 x 16") && text.contains("twice"));
        let mut nan = texels();
        nan[3 * 16 + 5].y = f32::NAN;
        nan[4 * 16].x = f32::INFINITY;
        let text = error_text(Environment::from_texels(16, 8, nan, 1.0, 0.0, origin));
        assert!(text.contains("pixel (5, 3)") && text.contains("NaN") && text.contains("2 pixels"));
        let mut negative = texels();
        negative[17].z = -1.0;
        let text = error_text(Environment::from_texels(16, 8, negative, 1.0, 0.0, origin));
        assert!(
            text.contains("pixel (1, 1)") && text.contains("negative"),
            "{text}"
        );
        for strength in [-1.0, f32::NAN, f32::INFINITY] {
            let text = error_text(Environment::from_texels(
                16,
                8,
                texels(),
                strength,
                0.0,
                origin,
            ));
            assert!(
                text.starts_with(ORIGIN) && text.contains("strength"),
                "{text}"
            );
            let text = error_text(Environment::constant(Rgb::ONE, strength, origin));
            assert!(text.contains("strength"), "{text}");
        }
        let text = error_text(Environment::constant(Rgb::new(1.0, -1.0, 0.0), 1.0, origin));
        assert!(text.contains("colour"), "{text}");
        let text = error_text(Environment::from_texels(
            16,
            8,
            texels(),
            1.0,
            f32::NAN,
            origin,
        ));
        assert!(text.contains("rotation"), "{text}");
        // Files: missing, of an unsupported kind, not what the extension says.
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("nowhere.hdr");
        let text = error_text(Environment::from_file(&missing, 1.0, 0.0));
        assert!(
            text.contains("nowhere.hdr") && text.contains("cannot read"),
            "{text}"
        );
        let png = dir.path().join("sky.png");
        std::fs::write(&png, b"not really").unwrap();
        let text = error_text(Environment::from_file(&png, 1.0, 0.0));
        assert!(
            text.contains("sky.png") && text.contains("unsupported"),
            "{text}"
        );
        for name in ["garbage.hdr", "garbage.exr"] {
            let path = dir.path().join(name);
            std::fs::write(&path, b"#?RADIANCE\nthis is not an image\n").unwrap();
            let text = error_text(Environment::from_file(&path, 1.0, 0.0));
            assert!(
                text.contains(name) && text.contains("cannot read"),
                "{text}"
            );
        }
        // A readable file of the wrong shape.
        let square = dir.path().join("square.exr");
        exr::prelude::write_rgb_file(&square, 4, 4, |_, _| (1.0f32, 1.0f32, 1.0f32)).unwrap();
        let text = error_text(Environment::from_file(&square, 1.0, 0.0));
        assert!(
            text.contains("square.exr") && text.contains("4 x 4"),
            "{text}"
        );
    }

    #[test]
    fn files_round_trip() {
        let (width, height) = (8usize, 4usize);
        let value = |x: usize, y: usize| {
            Rgb::new(
                0.1 + x as f32,
                0.5 * (y as f32 + 1.0),
                if (x, y) == (6, 1) { 1e4 } else { 0.25 },
            )
        };
        let dir = tempfile::tempdir().unwrap();
        let exr_path = dir.path().join("tiny.exr");
        exr::prelude::write_rgb_file(&exr_path, width, height, |x, y| {
            let v = value(x, y);
            (v.x, v.y, v.z)
        })
        .unwrap();
        let hdr_path = dir.path().join("tiny.hdr");
        let mut raw = Vec::new();
        for y in 0..height {
            for x in 0..width {
                raw.extend(value(x, y).to_array());
            }
        }
        image::Rgb32FImage::from_raw(width as u32, height as u32, raw)
            .unwrap()
            .save_with_format(&hdr_path, image::ImageFormat::Hdr)
            .unwrap();
        // Radiance's shared exponent keeps 8 bits of mantissa for the largest channel.
        for (path, tolerance) in [(&exr_path, 0.0), (&hdr_path, 1.0 / 128.0)] {
            let env = Environment::from_file(path, 2.0, 0.0).unwrap();
            for y in 0..height {
                for x in 0..width {
                    // The texel's centre, by Cycles' inverse mapping.
                    let s = (x as f64 + 0.5) / width as f64;
                    let t = (y as f64 + 0.5) / height as f64;
                    let got = env.eval(direction(PI64 * t, PI64 - 2.0 * PI64 * s));
                    let want = 2.0 * value(x, y);
                    let scale = want.max_element();
                    assert!(
                        (got - want).abs().max_element() <= tolerance * scale,
                        "{} ({x}, {y}): {got} vs {want}",
                        path.display()
                    );
                }
            }
        }
    }
}
