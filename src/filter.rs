//! Pixel reconstruction filters, by filter importance sampling (pbrt-v4's `FilterSampler`
//! idea): each camera sample's offset around its pixel's centre is drawn from the filter's
//! distribution and the sample is added with weight 1 to its own pixel. Pixels stay
//! independent of each other, so images stay bit-identical for any thread count and batch
//! size, and a pixel's mean is an unbiased estimate of the filtered image there.
//!
//! This module owns the filters' shapes, their sampling tables and the spreading of a light
//! path's splat over the pixels whose filters reach it; the camera ([`crate::camera`]) owns
//! the projection between film positions and rays.
//!
//! Widths follow Cycles' "pixel filter width", so that a Blender user's setting means the same
//! image here (Cycles' `film.cpp` scales its width per filter before tabulating it):
//!
//! | filter            | support (offset from the pixel centre)  | shape                                  |
//! |-------------------|-----------------------------------------|----------------------------------------|
//! | `box`             | `[-width/2, width/2]`                   | constant                               |
//! | `gaussian`        | `[-1.5 width, 1.5 width]`               | `exp(-x^2 / (2 s^2))`, `s = width / 4` |
//! | `blackman-harris` | `[-width, width]`                       | the 4-term Blackman-Harris window      |
//!
//! The 2-D filter is the product of two 1-D ones (separable). The box is sampled exactly; the
//! Gaussian and Blackman-Harris are tabulated once per render as a piecewise-constant density
//! of [`TABLE_BINS`] bins over `[0, radius]` (the filters are even) and sampled by its inverse
//! CDF. Light-path splats are weighted with the very same tabulated density, so the two
//! estimators of a pixel agree exactly, whatever the table's resolution.

use crate::math::{Rgb, Vec2};

/// Widest accepted filter, in pixels: a wider one blurs the image beyond any use and makes
/// each light-path splat touch thousands of pixels.
pub const MAX_FILTER_WIDTH: f32 = 16.0;

/// Bins of a tabulated filter over `[0, radius]`: 0.6% of the radius each, far below what an
/// image shows, and 1 KiB per table.
pub const TABLE_BINS: usize = 256;

/// The shape of a pixel filter.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FilterKind {
    /// Every sample uniform over a square of the width's side (width 1: inside the pixel).
    Box,
    /// A Gaussian of standard deviation `width / 4`, cut at 6 standard deviations.
    Gaussian,
    /// The Blackman-Harris window over `[-width, width]`: Cycles' default.
    BlackmanHarris,
}

impl FilterKind {
    /// The width a filter takes when none is given: 1 px for the box (each sample inside its
    /// pixel), Cycles' 1.5 px for the others.
    pub fn default_width(self) -> f32 {
        match self {
            FilterKind::Box => 1.0,
            FilterKind::Gaussian | FilterKind::BlackmanHarris => 1.5,
        }
    }

    /// The name used on the command line and in scene files.
    pub fn name(self) -> &'static str {
        match self {
            FilterKind::Box => "box",
            FilterKind::Gaussian => "gaussian",
            FilterKind::BlackmanHarris => "blackman-harris",
        }
    }

    /// Largest offset from the pixel centre, per axis, that a filter of `width` reaches.
    fn radius(self, width: f32) -> f32 {
        match self {
            FilterKind::Box => 0.5 * width,
            FilterKind::Gaussian => 1.5 * width,
            FilterKind::BlackmanHarris => width,
        }
    }

    /// The 1-D filter at offset `x` (pixels, `|x| <= radius`), unnormalized.
    fn profile(self, x: f64, width: f64) -> f64 {
        match self {
            FilterKind::Box => 1.0,
            FilterKind::Gaussian => {
                let sigma = width / 4.0;
                (-0.5 * (x / sigma) * (x / sigma)).exp()
            }
            FilterKind::BlackmanHarris => {
                // The window over [-width, width], phase 0 at its left end.
                let phase = std::f64::consts::PI * (x / width + 1.0);
                0.35875 - 0.48829 * phase.cos() + 0.14128 * (2.0 * phase).cos()
                    - 0.01168 * (3.0 * phase).cos()
            }
        }
    }
}

/// A pixel filter: its shape and width (Cycles' meaning, see the module doc).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PixelFilter {
    /// The shape.
    pub kind: FilterKind,
    /// Width in pixels, in `(0, MAX_FILTER_WIDTH]`.
    pub width: f32,
}

impl Default for PixelFilter {
    /// The box of 1 px: each sample uniform inside its pixel (scene files' and the built-in
    /// room's default, and wavetrace's only filter before filters were added).
    fn default() -> Self {
        PixelFilter::BOX
    }
}

impl PixelFilter {
    /// The box of 1 px.
    pub const BOX: PixelFilter = PixelFilter {
        kind: FilterKind::Box,
        width: 1.0,
    };

    /// Cycles' default, Blackman-Harris of 1.5 px: model files' default.
    pub const CYCLES: PixelFilter = PixelFilter {
        kind: FilterKind::BlackmanHarris,
        width: 1.5,
    };

    /// Checks the width: a finite number of pixels in `(0, MAX_FILTER_WIDTH]`.
    pub fn check_width(width: f32) -> Result<(), String> {
        if width.is_finite() && width > 0.0 && width <= MAX_FILTER_WIDTH {
            Ok(())
        } else {
            Err(format!(
                "the pixel filter width must be a number of pixels in (0, {MAX_FILTER_WIDTH}], \
                 got {width}"
            ))
        }
    }
}

/// A filter prepared for sampling: camera-ray offsets from uniform numbers, and the weights
/// that spread a light path's splat over the pixels. Built once per render; `Copy` (about
/// 1 KiB) so that the camera that holds it stays a plain value.
#[derive(Clone, Copy, Debug)]
pub struct FilterSampler {
    kind: FilterKind,
    width: f32,
    /// Largest offset from the pixel centre per axis, in pixels.
    radius: f32,
    /// Tabulated filters: CDF of `|offset|` over `[0, radius]` in [`TABLE_BINS`] equal bins,
    /// `cdf[0] = 0`, `cdf[TABLE_BINS] = 1`. Unused for the box.
    cdf: [f32; TABLE_BINS + 1],
}

impl Default for FilterSampler {
    fn default() -> Self {
        FilterSampler::new(PixelFilter::BOX)
    }
}

impl FilterSampler {
    /// Prepares `filter` (its width checked by [`PixelFilter::check_width`] beforehand).
    pub fn new(filter: PixelFilter) -> Self {
        let radius = filter.kind.radius(filter.width);
        let mut cdf = [0.0f32; TABLE_BINS + 1];
        if filter.kind != FilterKind::Box {
            // Each bin's mass by the midpoint rule on 16 sub-intervals, in f64.
            const SUBSTEPS: usize = 16;
            let bin = radius as f64 / TABLE_BINS as f64;
            let mut masses = [0.0f64; TABLE_BINS];
            for (i, mass) in masses.iter_mut().enumerate() {
                *mass = (0..SUBSTEPS)
                    .map(|s| {
                        let x = (i as f64 + (s as f64 + 0.5) / SUBSTEPS as f64) * bin;
                        filter.kind.profile(x, filter.width as f64).max(0.0)
                    })
                    .sum::<f64>();
            }
            let total: f64 = masses.iter().sum();
            let mut running = 0.0f64;
            for (i, mass) in masses.iter().enumerate() {
                running += mass;
                cdf[i + 1] = (running / total) as f32;
            }
            cdf[TABLE_BINS] = 1.0;
        }
        FilterSampler {
            kind: filter.kind,
            width: filter.width,
            radius,
            cdf,
        }
    }

    /// Whether this is today's exact box of 1 px (which keeps the seed's arithmetic bit for bit).
    #[inline]
    fn is_unit_box(&self) -> bool {
        self.kind == FilterKind::Box && self.width == 1.0
    }

    /// Largest offset from a pixel's centre, per axis, that a sample reaches (pixels).
    #[inline]
    pub fn radius(&self) -> f32 {
        self.radius
    }

    /// The offset of a camera sample from its pixel's top-left corner, in pixels, from the
    /// uniform pair `u`: the pixel centre plus an offset drawn from the filter, each axis by
    /// its own number through a monotone map (so a stratified pattern stays stratified).
    /// The box of 1 px returns `u` itself.
    #[inline]
    pub fn sample_jitter(&self, u: Vec2) -> Vec2 {
        if self.is_unit_box() {
            return u;
        }
        Vec2::new(0.5 + self.sample_offset(u.x), 0.5 + self.sample_offset(u.y))
    }

    /// An offset from the pixel centre along one axis (pixels), from a uniform `u` in [0, 1),
    /// by the inverse CDF of the 1-D filter over `[-radius, radius]`.
    #[inline]
    pub fn sample_offset(&self, u: f32) -> f32 {
        if self.kind == FilterKind::Box {
            return self.width * (u - 0.5);
        }
        // The filter is even: the lower half of u maps to negative offsets, mirrored, so that
        // the map stays monotone over [0, 1).
        let (v, sign) = if u < 0.5 {
            (1.0 - 2.0 * u, -1.0)
        } else {
            (2.0 * u - 1.0, 1.0)
        };
        // The first bin whose upper CDF exceeds v: never a bin of zero mass.
        let bin = self.cdf[1..]
            .partition_point(|&c| c <= v)
            .min(TABLE_BINS - 1);
        let (low, high) = (self.cdf[bin], self.cdf[bin + 1]);
        let within = if high > low {
            ((v - low) / (high - low)).clamp(0.0, 1.0)
        } else {
            1.0
        };
        sign * (bin as f32 + within) * (self.radius / TABLE_BINS as f32)
    }

    /// The density (per pixel of offset) of [`Self::sample_offset`] at `offset`: the
    /// tabulated filter, normalized over `[-radius, radius]`; 0 outside.
    #[inline]
    pub fn offset_density(&self, offset: f32) -> f32 {
        if self.kind == FilterKind::Box {
            let half = 0.5 * self.width;
            return if (-half..half).contains(&offset) {
                1.0 / self.width
            } else {
                0.0
            };
        }
        let bin_width = self.radius / TABLE_BINS as f32;
        let bin = (offset.abs() / bin_width) as usize;
        if bin >= TABLE_BINS {
            return 0.0;
        }
        0.5 * (self.cdf[bin + 1] - self.cdf[bin]) / bin_width
    }

    /// Whether some pixel of a `width` x `height` film takes samples at film position
    /// `position` (pixels from the film's top-left corner).
    #[inline]
    pub fn reaches_film(&self, position: Vec2, width: u32, height: u32) -> bool {
        let (w, h) = (width as f32, height as f32);
        if self.is_unit_box() {
            return position.x >= 0.0 && position.y >= 0.0 && position.x < w && position.y < h;
        }
        let r = self.radius;
        position.x > -r && position.y > -r && position.x < w + r && position.y < h + r
    }

    /// Adds `value`, a light path's contribution at film position `position` for a pixel of
    /// the box of 1 px, to the pixels of a `width`-wide film (`splats`, row-major) whose
    /// filters reach it, each weighted by its filter's density at the offset: the camera's
    /// importance for that pixel.
    pub fn splat(&self, position: Vec2, value: Rgb, width: u32, splats: &mut [Rgb]) {
        let height = splats.len() as u32 / width.max(1);
        if self.is_unit_box() {
            // The seed's arithmetic: the pixel the point falls in.
            if !self.reaches_film(position, width, height) {
                return;
            }
            // Rounding at the far edge can still give the width or height itself.
            let (column, row) = (position.x as u32, position.y as u32);
            if column < width && row < height {
                splats[(row * width + column) as usize] += value;
            }
            return;
        }
        let r = self.radius;
        let span = |at: f32, size: u32| {
            let first = (at - 0.5 - r).floor().max(0.0) as u32;
            let last = ((at - 0.5 + r).ceil().max(0.0) as u32).min(size.saturating_sub(1));
            first..=last
        };
        for row in span(position.y, height) {
            let weight_y = self.offset_density(position.y - (row as f32 + 0.5));
            if weight_y == 0.0 {
                continue;
            }
            for column in span(position.x, width) {
                let weight_x = self.offset_density(position.x - (column as f32 + 0.5));
                if weight_x > 0.0 {
                    splats[(row * width + column) as usize] += value * (weight_x * weight_y);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::rng::{path_key, uniform};

    fn filters() -> Vec<PixelFilter> {
        let mut all = Vec::new();
        for kind in [
            FilterKind::Box,
            FilterKind::Gaussian,
            FilterKind::BlackmanHarris,
        ] {
            for width in [0.5, kind.default_width(), 3.0] {
                all.push(PixelFilter { kind, width });
            }
        }
        all
    }

    /// The analytic filter's mass over `[a, b]`, normalized over its support (f64, fine
    /// midpoint rule): what the samples are checked against, independently of the table.
    fn analytic_mass(filter: PixelFilter, a: f64, b: f64) -> f64 {
        let r = filter.kind.radius(filter.width) as f64;
        let integral = |a: f64, b: f64| {
            let n = 4000;
            let h = (b - a) / n as f64;
            (0..n)
                .map(|i| {
                    filter
                        .kind
                        .profile(a + (i as f64 + 0.5) * h, filter.width as f64)
                })
                .sum::<f64>()
                * h
        };
        integral(a.max(-r), b.min(r)) / integral(-r, r)
    }

    #[test]
    fn samples_follow_the_filters_normalized_density() {
        // Chi-square of 200k offsets in 32 equal bins over the support against the analytic
        // filter; 31 degrees of freedom, 0.999 quantile 61.1.
        let (draws, bins) = (200_000u32, 32usize);
        for filter in filters() {
            let sampler = FilterSampler::new(filter);
            let r = sampler.radius() as f64;
            let mut counts = vec![0u32; bins];
            for i in 0..draws {
                let offset = sampler.sample_offset(uniform(path_key(11, i, 0), 0, 0)) as f64;
                assert!(offset.abs() <= r, "{filter:?}: {offset} beyond {r}");
                let bin = (((offset + r) / (2.0 * r)) * bins as f64) as usize;
                counts[bin.min(bins - 1)] += 1;
            }
            let mut chi2 = 0.0;
            for (b, &count) in counts.iter().enumerate() {
                let a = -r + 2.0 * r * b as f64 / bins as f64;
                let expected = draws as f64 * analytic_mass(filter, a, a + 2.0 * r / bins as f64);
                if expected > 5.0 {
                    chi2 += (count as f64 - expected).powi(2) / expected;
                }
            }
            assert!(chi2 < 61.1, "{filter:?}: chi2 {chi2}, counts {counts:?}");
        }
    }

    #[test]
    fn inverse_cdf_is_monotone_and_spans_the_support() {
        for filter in filters() {
            let sampler = FilterSampler::new(filter);
            let mut previous = f32::NEG_INFINITY;
            let n = 1 << 16;
            for i in 0..n {
                let offset = sampler.sample_offset(i as f32 / n as f32);
                assert!(
                    offset >= previous,
                    "{filter:?} at {i}: {offset} < {previous}"
                );
                previous = offset;
            }
            let r = sampler.radius();
            assert!(
                (sampler.sample_offset(0.0) + r).abs() < 1e-3 * r,
                "{filter:?}"
            );
            // The last of 2^16 points lies within the far tail (the Gaussian's last 1e-4 of
            // mass lies beyond 0.6 of its radius).
            assert!(
                previous <= r && previous > 0.6 * r,
                "{filter:?}: {previous}"
            );
            assert!(sampler.sample_offset(0.5).abs() < 1e-6, "{filter:?}");
        }
    }

    #[test]
    fn density_integrates_to_one_and_matches_the_filter() {
        for filter in filters() {
            let sampler = FilterSampler::new(filter);
            let r = sampler.radius() as f64;
            let n = 20_000;
            let h = 2.2 * r / n as f64;
            let total: f64 = (0..n)
                .map(|i| sampler.offset_density((-1.1 * r + (i as f64 + 0.5) * h) as f32) as f64)
                .sum::<f64>()
                * h;
            assert!((total - 1.0).abs() < 1e-3, "{filter:?}: {total}");
            // At the centre, the table matches the normalized analytic filter.
            let centre = analytic_mass(filter, -1e-3 * r, 1e-3 * r) / (2e-3 * r);
            let table = sampler.offset_density(0.0) as f64;
            assert!((table / centre - 1.0).abs() < 1e-2, "{filter:?}");
        }
    }

    #[test]
    fn unit_box_keeps_the_jitter_and_the_pixel() {
        let sampler = FilterSampler::new(PixelFilter::BOX);
        let u = Vec2::new(0.123, 0.987);
        assert_eq!(sampler.sample_jitter(u), u);
        let mut splats = vec![Rgb::ZERO; 12];
        sampler.splat(Vec2::new(2.99, 1.0), Rgb::ONE, 4, &mut splats);
        sampler.splat(Vec2::new(4.0, 1.0), Rgb::ONE, 4, &mut splats);
        assert_eq!(splats[6], Rgb::ONE);
        assert_eq!(splats.iter().map(|s| s.x).sum::<f32>(), 1.0);
    }

    #[test]
    fn splats_keep_their_total_on_average_over_a_pixel() {
        // Each pixel's weight is its filter's density at the offset; averaged over positions
        // inside a pixel (a narrow filter leaves gaps between pixels), the weights sum to 1.
        for filter in filters() {
            let sampler = FilterSampler::new(filter);
            let mut splats = vec![Rgb::ZERO; 40 * 40];
            let n = 32;
            for i in 0..n {
                for j in 0..n {
                    let at = Vec2::new(
                        20.0 + (i as f32 + 0.5) / n as f32,
                        19.0 + (j as f32 + 0.5) / n as f32,
                    );
                    sampler.splat(at, Rgb::ONE, 40, &mut splats);
                }
            }
            let total: f32 = splats.iter().map(|s| s.x).sum::<f32>() / (n * n) as f32;
            assert!((total - 1.0).abs() < 0.02, "{filter:?}: {total}");
        }
    }

    #[test]
    fn widths_outside_the_range_are_refused() {
        for bad in [0.0, -1.0, f32::NAN, f32::INFINITY, MAX_FILTER_WIDTH + 0.5] {
            assert!(PixelFilter::check_width(bad).is_err(), "{bad}");
        }
        assert!(PixelFilter::check_width(MAX_FILTER_WIDTH).is_ok());
        assert!(PixelFilter::check_width(0.01).is_ok());
    }
}
