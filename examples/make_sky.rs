//! Writes `assets/sky.hdr`: a 512 x 256 equirectangular clear sky with a sun, made from
//! formulas, for the environment light (Blender/Cycles mapping, +Z up, so the picture's
//! centre column faces +X).
//!
//! - Sky: the CIE standard clear sky's luminance distribution (CIE S 011/E:2003, type 12):
//!   `L(theta, gamma) / L_zenith = f(gamma) phi(theta) / (f(Z_sun) phi(0))`, with gradation
//!   `phi(theta) = 1 - exp(-0.32 / cos theta)` and indicatrix
//!   `f(gamma) = 0.91 + 10 exp(-3 gamma) + 0.45 cos^2 gamma` (theta the view's zenith angle,
//!   gamma its angle to the sun), tinted from a deep blue zenith to a pale horizon and warm
//!   near the sun.
//! - Sun: a disk 1 degree across (about twice the real sun, so that it covers more than one
//!   0.7-degree texel), 40 degrees above the horizon at azimuth 35 degrees (from +X toward
//!   +Y), its texels weighted by the fraction of them the disk covers. Its radiance makes
//!   the sun's irradiance on level ground 5 times the sky's, as on a clear day at that
//!   elevation, so it casts crisp, clearly visible shadows.
//! - Ground: below the horizon, a Lambertian ground of albedo (0.30, 0.26, 0.20) lit by sun
//!   and sky: radiance `albedo * E / pi`.
//!
//! The scale is set so that level ground receives an irradiance of 3 (luminance): a white
//! diffuse surface facing up reads about 1 at exposure 0.
//!
//! `cargo run --release --features examples --example make_sky` writes the file; `-- --preview out.png` also
//! writes a tone-mapped PNG to look at.

use std::f64::consts::PI;
use std::path::Path;

const WIDTH: usize = 512;
const HEIGHT: usize = 256;
const SUN_ELEVATION_DEGREES: f64 = 40.0;
const SUN_AZIMUTH_DEGREES: f64 = 35.0;
const SUN_RADIUS_DEGREES: f64 = 0.5;
/// Irradiance on level ground, in luminance: from the sky, and from the sun.
const SKY_IRRADIANCE: f64 = 0.5;
const SUN_IRRADIANCE: f64 = 2.5;
const GROUND_ALBEDO: [f64; 3] = [0.30, 0.26, 0.20];
/// Sub-samples per texel side for the sky and the sun's coverage.
const SKY_SUBSAMPLES: usize = 4;
const SUN_SUBSAMPLES: usize = 64;

type Colour = [f64; 3];

fn luminance(c: Colour) -> f64 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

fn scaled(c: Colour, k: f64) -> Colour {
    c.map(|x| x * k)
}

fn mix(a: Colour, b: Colour, t: f64) -> Colour {
    std::array::from_fn(|k| a[k] + (b[k] - a[k]) * t)
}

/// Unit luminance.
fn normalised(c: Colour) -> Colour {
    scaled(c, 1.0 / luminance(c))
}

/// Direction of image coordinates (s, t) in [0, 1]^2 (t = 0 at the top), by Cycles'
/// equirectangular mapping: phi = pi - 2 pi s, theta = pi t.
fn direction(s: f64, t: f64) -> [f64; 3] {
    let (theta, phi) = (PI * t, PI - 2.0 * PI * s);
    [
        theta.sin() * phi.cos(),
        theta.sin() * phi.sin(),
        theta.cos(),
    ]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn sun_direction() -> [f64; 3] {
    let (elevation, azimuth) = (
        SUN_ELEVATION_DEGREES.to_radians(),
        SUN_AZIMUTH_DEGREES.to_radians(),
    );
    [
        elevation.cos() * azimuth.cos(),
        elevation.cos() * azimuth.sin(),
        elevation.sin(),
    ]
}

/// Sky radiance of unit zenith luminance, above the horizon.
fn sky(d: [f64; 3]) -> Colour {
    let sun = sun_direction();
    let gradation = |cos_theta: f64| 1.0 - (-0.32 / cos_theta.max(1e-4)).exp();
    let indicatrix = |gamma: f64| 0.91 + 10.0 * (-3.0 * gamma).exp() + 0.45 * gamma.cos().powi(2);
    let gamma = dot(d, sun).clamp(-1.0, 1.0).acos();
    let sun_zenith = sun[2].acos();
    let relative = indicatrix(gamma) * gradation(d[2]) / (indicatrix(sun_zenith) * gradation(1.0));
    let zenith_blue = normalised([0.22, 0.42, 1.0]);
    let horizon_pale = normalised([0.75, 0.85, 1.0]);
    let sun_warm = normalised([1.0, 0.88, 0.72]);
    let tint = mix(horizon_pale, zenith_blue, d[2].max(0.0).sqrt());
    let tint = mix(tint, sun_warm, 0.6 * (-3.0 * gamma).exp());
    scaled(normalised(tint), relative)
}

/// Irradiance weight of texel row `i` above the horizon: the integral of cos(theta) over
/// one texel, `d_phi * (sin^2 theta1 - sin^2 theta0) / 2`.
fn cosine_weight(i: usize) -> f64 {
    let theta = |edge: usize| edge as f64 / HEIGHT as f64 * PI;
    (2.0 * PI / WIDTH as f64) * (theta(i + 1).sin().powi(2) - theta(i).sin().powi(2)) / 2.0
}

fn main() {
    let sun = sun_direction();
    let sun_colour = normalised([1.0, 0.93, 0.85]);
    let cos_sun_radius = SUN_RADIUS_DEGREES.to_radians().cos();
    // Texels within this angle of the sun may hold part of its disk.
    let cos_near_sun = (SUN_RADIUS_DEGREES + 1.5).to_radians().cos();

    // Pass 1: sky of unit zenith luminance and the sun's coverage, per texel (top row first).
    let mut sky_texels = vec![[0.0; 3]; WIDTH * HEIGHT];
    let mut coverage = vec![0.0f64; WIDTH * HEIGHT];
    for i in 0..HEIGHT / 2 {
        for j in 0..WIDTH {
            let mut sum = [0.0; 3];
            for a in 0..SKY_SUBSAMPLES {
                for b in 0..SKY_SUBSAMPLES {
                    let s = (j as f64 + (b as f64 + 0.5) / SKY_SUBSAMPLES as f64) / WIDTH as f64;
                    let t = (i as f64 + (a as f64 + 0.5) / SKY_SUBSAMPLES as f64) / HEIGHT as f64;
                    let c = sky(direction(s, t));
                    (0..3).for_each(|k| sum[k] += c[k]);
                }
            }
            sky_texels[i * WIDTH + j] = scaled(sum, 1.0 / (SKY_SUBSAMPLES.pow(2)) as f64);
            let centre = direction(
                (j as f64 + 0.5) / WIDTH as f64,
                (i as f64 + 0.5) / HEIGHT as f64,
            );
            if dot(centre, sun) > cos_near_sun {
                // The fraction of the texel's solid angle inside the disk (sub-samples are
                // equal in (s, t), so weight each by its sin(theta)).
                let (mut inside, mut all) = (0.0, 0.0);
                for a in 0..SUN_SUBSAMPLES {
                    for b in 0..SUN_SUBSAMPLES {
                        let s =
                            (j as f64 + (b as f64 + 0.5) / SUN_SUBSAMPLES as f64) / WIDTH as f64;
                        let t =
                            (i as f64 + (a as f64 + 0.5) / SUN_SUBSAMPLES as f64) / HEIGHT as f64;
                        let weight = (PI * t).sin();
                        all += weight;
                        if dot(direction(s, t), sun) > cos_sun_radius {
                            inside += weight;
                        }
                    }
                }
                coverage[i * WIDTH + j] = inside / all;
            }
        }
    }

    // Pass 2: scale the sky and the sun to their irradiances on level ground.
    let (mut sky_unit, mut sun_unit) = (0.0, 0.0);
    for i in 0..HEIGHT / 2 {
        for j in 0..WIDTH {
            let k = i * WIDTH + j;
            sky_unit += (1.0 - coverage[k]) * luminance(sky_texels[k]) * cosine_weight(i);
            sun_unit += coverage[k] * cosine_weight(i);
        }
    }
    let zenith_luminance = SKY_IRRADIANCE / sky_unit;
    let sun_radiance = SUN_IRRADIANCE / sun_unit;
    let ground = scaled(GROUND_ALBEDO, (SKY_IRRADIANCE + SUN_IRRADIANCE) / PI);
    let mut texels = Vec::with_capacity(WIDTH * HEIGHT * 3);
    for i in 0..HEIGHT {
        for j in 0..WIDTH {
            let k = i * WIDTH + j;
            let colour = if i < HEIGHT / 2 {
                mix(
                    scaled(sky_texels[k], zenith_luminance),
                    scaled(sun_colour, sun_radiance),
                    coverage[k],
                )
            } else {
                ground
            };
            texels.extend(colour.map(|x| x as f32));
        }
    }

    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/sky.hdr");
    image::Rgb32FImage::from_raw(WIDTH as u32, HEIGHT as u32, texels.clone())
        .expect("buffer matches the size")
        .save_with_format(&path, image::ImageFormat::Hdr)
        .unwrap_or_else(|e| panic!("cannot write {}: {e}", path.display()));
    let covered = coverage.iter().filter(|&&c| c > 0.0).count();
    println!(
        "{}: {WIDTH} x {HEIGHT}, {} bytes; zenith luminance {zenith_luminance:.3}, sun radiance \
         {sun_radiance:.0} over {covered} texels; level-ground irradiance sun {SUN_IRRADIANCE} + \
         sky {SKY_IRRADIANCE} (ratio {:.1})",
        path.display(),
        std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0),
        SUN_IRRADIANCE / SKY_IRRADIANCE,
    );

    // Read back through the renderer's loader, as a check that it accepts the file.
    let env = wavetrace::internals::Environment::from_file(&path, 1.0, 0.0)
        .unwrap_or_else(|e| panic!("{e}"));
    println!(
        "loaded: power estimate for a unit scene radius {:.2}",
        env.power_estimate(1.0)
    );

    let mut args = std::env::args().skip(1);
    if let (Some(flag), Some(preview)) = (args.next(), args.next())
        && flag == "--preview"
    {
        // Reinhard on luminance, then sRGB, so that sky and ground stay readable.
        let pixels: Vec<u8> = texels
            .chunks_exact(3)
            .flat_map(|c| {
                let c = [c[0] as f64, c[1] as f64, c[2] as f64];
                let l = luminance(c);
                let k = if l > 0.0 { 1.0 / (1.0 + l) } else { 1.0 };
                c.map(|x| {
                    let x = (x * k).clamp(0.0, 1.0);
                    let srgb = if x <= 0.0031308 {
                        12.92 * x
                    } else {
                        1.055 * x.powf(1.0 / 2.4) - 0.055
                    };
                    (srgb * 255.0).round() as u8
                })
            })
            .collect();
        image::RgbImage::from_raw(WIDTH as u32, HEIGHT as u32, pixels)
            .expect("buffer matches the size")
            .save(&preview)
            .unwrap_or_else(|e| panic!("cannot write {preview}: {e}"));
        println!("preview: {preview}");
    }
}
