//! The film: per-pixel sums of sample radiance and sample counts, the error estimate that
//! adaptive sampling reads, the optional auxiliary layers (albedo, normal, depth: the
//! denoiser's guides and `--aov`), and the resolved image.

use crate::math::Rgb;
use rayon::prelude::*;
use std::ops::Range;

/// Accumulated samples. Sums are f64 so that long renders do not lose precision, and each
/// pixel's samples are added in sample order, so the sums are bit-reproducible.
pub struct Film {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    sum: Vec<[f64; 3]>,
    /// Sums of each pixel's odd-numbered samples (its second, fourth, ...), for the error
    /// estimate of adaptive sampling; empty when the film keeps no estimate.
    odd_sum: Vec<[f64; 3]>,
    samples: Vec<u32>,
    /// Sums of each pixel's samples' auxiliary values; empty when the film keeps no layers.
    aov_sum: Vec<AovSum>,
    /// Samples discarded because their radiance was NaN or infinite.
    pub rejected_samples: u64,
}

/// One sample's auxiliary values, recorded at its path's first non-specular hit
/// (`wavefront::aov`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AovSample {
    /// Reflectance there, times the tints of the mirrors and glass on the way.
    pub albedo: Rgb,
    /// Unit shading normal there, world space (zero where the path escaped).
    pub normal: Rgb,
    /// Distance from the camera to the camera ray's first hit (0 where it escaped).
    pub depth: f32,
    /// Light the camera sees directly or through mirrors and glass only (emitters, the
    /// environment): the part of the colour the denoiser leaves alone.
    pub emission: Rgb,
}

/// Per-pixel sums of [`AovSample`]s, in f64 and in sample order like the colour sums.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AovSum {
    albedo: [f64; 3],
    normal: [f64; 3],
    depth: f64,
    emission: [f64; 3],
}

impl AovSum {
    #[inline]
    fn add(&mut self, sample: &AovSample) {
        for c in 0..3 {
            self.albedo[c] += sample.albedo[c] as f64;
            self.normal[c] += sample.normal[c] as f64;
            self.emission[c] += sample.emission[c] as f64;
        }
        self.depth += sample.depth as f64;
    }
}

/// A per-pixel layer of the film besides its colour.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Layer {
    /// Mean albedo at the first non-specular hit.
    Albedo,
    /// Mean shading normal there, renormalised (zero where every sample escaped).
    Normal,
    /// Mean camera distance of the first hit (x in all three channels).
    Depth,
    /// Mean light seen directly or through mirrors and glass (part of the colour).
    Emission,
    /// Samples taken (x in all three channels).
    Samples,
    /// Estimated variance of the pixel's mean, per channel (adaptive sampling only).
    Variance,
}

impl Film {
    /// An empty film.
    pub fn new(width: u32, height: u32) -> Self {
        let n = width as usize * height as usize;
        Film {
            width,
            height,
            sum: vec![[0.0; 3]; n],
            odd_sum: Vec::new(),
            samples: vec![0; n],
            aov_sum: Vec::new(),
            rejected_samples: 0,
        }
    }

    /// The same film, keeping the auxiliary layers too (56 more bytes per pixel).
    pub fn with_aovs(self) -> Self {
        let n = self.samples.len();
        Film {
            aov_sum: vec![AovSum::default(); n],
            ..self
        }
    }

    /// Whether pixel `i`'s samples saw light directly or through mirrors and glass (the part
    /// of the colour the denoiser leaves alone); false on a film without auxiliary layers.
    pub fn sees_light(&self, i: usize) -> bool {
        self.aov_sum.get(i).is_some_and(|s| s.emission != [0.0; 3])
    }

    /// Whether the film keeps the auxiliary layers.
    pub fn has_aovs(&self) -> bool {
        !self.aov_sum.is_empty()
    }

    /// Bytes per pixel of the auxiliary layers.
    pub fn aov_bytes_per_pixel() -> u64 {
        size_of::<AovSum>() as u64
    }

    /// A layer of the film as an image; `None` for albedo, normal or depth on a film that
    /// keeps no auxiliary layers, and for the variance on a film without error estimate.
    pub fn layer(&self, layer: Layer) -> Option<Image> {
        let available = match layer {
            Layer::Albedo | Layer::Normal | Layer::Depth | Layer::Emission => self.has_aovs(),
            Layer::Samples => true,
            Layer::Variance => !self.odd_sum.is_empty(),
        };
        if !available {
            return None;
        }
        let pixels = (0..self.samples.len())
            .into_par_iter()
            .map(|i| self.layer_pixel(layer, i))
            .collect();
        Some(Image {
            width: self.width,
            height: self.height,
            pixels,
        })
    }

    fn layer_pixel(&self, layer: Layer, i: usize) -> Rgb {
        let n = self.samples[i];
        let inv = if n > 0 { 1.0 / n as f64 } else { 0.0 };
        let mean = |v: [f64; 3]| {
            Rgb::new(
                (v[0] * inv) as f32,
                (v[1] * inv) as f32,
                (v[2] * inv) as f32,
            )
        };
        match layer {
            Layer::Albedo => mean(self.aov_sum[i].albedo),
            Layer::Normal => mean(self.aov_sum[i].normal).normalize_or_zero(),
            Layer::Depth => Rgb::splat((self.aov_sum[i].depth * inv) as f32),
            Layer::Emission => mean(self.aov_sum[i].emission),
            Layer::Samples => Rgb::splat(n as f32),
            Layer::Variance => {
                // The mean of all samples minus the mean of the odd half is half the
                // difference of the two halves' means, whose variance is 4 sigma^2 / n: its
                // square estimates the variance of the pixel's mean, sigma^2 / n (one
                // sample of it, unbiased, noisy).
                let (all, odd) = (self.sum[i], self.odd_sum[i]);
                let d = |c: usize| ((all[c] - 2.0 * odd[c]) * inv) as f32;
                Rgb::new(d(0) * d(0), d(1) * d(1), d(2) * d(2))
            }
        }
    }

    /// An empty film that also keeps the sums of odd-numbered samples, for
    /// [`Film::pixel_error`] (24 more bytes per pixel).
    pub fn with_error_estimate(width: u32, height: u32) -> Self {
        let n = width as usize * height as usize;
        Film {
            odd_sum: vec![[0.0; 3]; n],
            ..Film::new(width, height)
        }
    }

    /// Bytes per pixel of a film, with or without the error estimate.
    pub fn bytes_per_pixel(error_estimate: bool) -> u64 {
        let sums = size_of::<[f64; 3]>() * if error_estimate { 2 } else { 1 };
        (sums + size_of::<u32>()) as u64
    }

    /// Adds one sample to a pixel; a NaN or infinite sample is counted and discarded.
    pub fn add_sample(&mut self, pixel: u32, radiance: Rgb) {
        self.add_sample_with_aov(pixel, radiance, None);
    }

    /// Adds one sample and, if the film keeps auxiliary layers and `aov` is given, its
    /// auxiliary values (only when the sample itself is added, so that every layer averages
    /// the same samples).
    pub fn add_sample_with_aov(&mut self, pixel: u32, radiance: Rgb, aov: Option<&AovSample>) {
        let i = pixel as usize;
        let odd_sum = self.odd_sum.get_mut(i);
        let added = accumulate(&mut self.sum[i], odd_sum, &mut self.samples[i], radiance);
        if added && let (Some(sum), Some(aov)) = (self.aov_sum.get_mut(i), aov) {
            sum.add(aov);
        }
        self.rejected_samples += u64::from(!added);
    }

    /// The pixel's relative error estimate, Cycles' formula: the difference between the mean
    /// of all its samples and the mean of its odd-numbered half (summed over the channels)
    /// over the square root of its brightness, so that the threshold means about the same
    /// visible noise in dark and bright regions (noise is seen relative to brightness, but
    /// dark regions would never converge with a purely relative error). Infinite without an
    /// estimate (no odd sums kept, or fewer than two samples). Read it at an even sample
    /// count, when both halves hold as many samples.
    pub fn pixel_error(&self, index: usize) -> f32 {
        let n = self.samples[index];
        let Some(odd) = self.odd_sum.get(index) else {
            return f32::INFINITY;
        };
        if n < 2 {
            return f32::INFINITY;
        }
        let (all, inv_n) = (self.sum[index], 1.0 / n as f64);
        let mut difference = 0.0;
        let mut brightness = 0.0;
        for c in 0..3 {
            difference += (all[c] - 2.0 * odd[c]).abs() * inv_n;
            brightness += all[c] * inv_n;
        }
        (difference / (1e-4 + brightness.max(0.0).sqrt())) as f32
    }

    /// Samples held by the pixel of row-major index `index`.
    pub fn pixel_samples(&self, index: usize) -> u32 {
        self.samples[index]
    }

    /// Fewest, mean and most samples per pixel among the pixels `pixels`.
    pub fn spp_range(&self, pixels: Range<u32>) -> (u32, f64, u32) {
        let samples = &self.samples[pixels.start as usize..pixels.end as usize];
        let total: u64 = samples.iter().map(|&n| n as u64).sum();
        let mean = total as f64 / samples.len().max(1) as f64;
        let min = samples.iter().copied().min().unwrap_or(0);
        let max = samples.iter().copied().max().unwrap_or(0);
        (min, mean, max)
    }

    /// Whether the film keeps the sums of odd-numbered samples (adaptive sampling's error
    /// estimate).
    pub fn has_error_estimate(&self) -> bool {
        !self.odd_sum.is_empty()
    }

    /// The raw accumulators of the pixel of row-major index `index`, exactly as the film
    /// holds them (for a partial film written to a file and merged, [`crate::farm`]).
    pub fn accumulator(&self, index: usize) -> PixelAccumulator {
        PixelAccumulator {
            sum: self.sum[index],
            odd_sum: self.odd_sum.get(index).copied().unwrap_or([0.0; 3]),
            samples: self.samples[index],
        }
    }

    /// Sets the raw accumulators of a pixel, as [`Film::accumulator`] read them (the odd sum
    /// is dropped by a film without the error estimate).
    pub fn set_accumulator(&mut self, index: usize, accumulator: PixelAccumulator) {
        self.sum[index] = accumulator.sum;
        if let Some(odd_sum) = self.odd_sum.get_mut(index) {
            *odd_sum = accumulator.odd_sum;
        }
        self.samples[index] = accumulator.samples;
    }

    /// The pixels `pixels` cut into consecutive regions of `size` pixels (the last may be
    /// shorter), to be filled in parallel.
    pub fn regions_mut(
        &mut self,
        pixels: Range<u32>,
        size: usize,
    ) -> impl IndexedParallelIterator<Item = FilmRegion<'_>> {
        let range = pixels.start as usize..pixels.end as usize;
        // Without odd sums each region gets an empty slice of them.
        let regions = range.len().div_ceil(size);
        let odd_sums = optional_chunks(&mut self.odd_sum, range.clone(), size, regions);
        let aov_sums = optional_chunks(&mut self.aov_sum, range.clone(), size, regions);
        self.sum[range.clone()]
            .par_chunks_mut(size)
            .zip(self.samples[range].par_chunks_mut(size))
            .zip(odd_sums)
            .zip(aov_sums)
            .enumerate()
            .map(
                move |(k, (((sum, samples), odd_sum), aov_sum))| FilmRegion {
                    first_pixel: pixels.start + (k * size) as u32,
                    sum,
                    odd_sum,
                    samples,
                    aov_sum,
                    rejected_samples: 0,
                },
            )
    }

    /// Fewest samples any pixel holds.
    pub fn min_samples(&self) -> u32 {
        self.samples.iter().copied().min().unwrap_or(0)
    }

    /// The mean radiance per pixel, row-major from the top-left.
    pub fn resolve(&self) -> Image {
        Image {
            width: self.width,
            height: self.height,
            pixels: (0..self.samples.len()).map(|i| self.pixel(i)).collect(),
        }
    }
}

/// `column[range]` cut into chunks of `size`, or `regions` empty slices when the column is
/// not kept (empty).
fn optional_chunks<T>(
    column: &mut [T],
    range: std::ops::Range<usize>,
    size: usize,
    regions: usize,
) -> Vec<&mut [T]> {
    if column.is_empty() {
        std::iter::repeat_with(|| &mut [][..])
            .take(regions)
            .collect()
    } else {
        column[range].chunks_mut(size).collect()
    }
}

/// One pixel's accumulators in a [`Film`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PixelAccumulator {
    /// Sum of the pixel's samples.
    pub sum: [f64; 3],
    /// Sum of its odd-numbered samples (zero in a film without the error estimate).
    pub odd_sum: [f64; 3],
    /// Samples taken.
    pub samples: u32,
}

/// A run of consecutive pixels of a [`Film`], borrowed to add samples to them: the regions
/// of one film are filled in parallel, each pixel's samples still in sample order.
pub struct FilmRegion<'a> {
    first_pixel: u32,
    sum: &'a mut [[f64; 3]],
    odd_sum: &'a mut [[f64; 3]],
    samples: &'a mut [u32],
    aov_sum: &'a mut [AovSum],
    /// Samples discarded because their radiance was NaN or infinite.
    pub rejected_samples: u64,
}

impl FilmRegion<'_> {
    /// The pixels of the region.
    pub fn pixels(&self) -> Range<u32> {
        self.first_pixel..self.first_pixel + self.samples.len() as u32
    }

    /// Adds one sample to a pixel of the region (a film-wide index); a NaN or infinite sample
    /// is counted and discarded.
    #[inline]
    pub fn add_sample(&mut self, pixel: u32, radiance: Rgb) {
        self.add_sample_with_aov(pixel, radiance, None);
    }

    /// Adds one sample and its auxiliary values, as [`Film::add_sample_with_aov`].
    #[inline]
    pub fn add_sample_with_aov(&mut self, pixel: u32, radiance: Rgb, aov: Option<&AovSample>) {
        let i = (pixel - self.first_pixel) as usize;
        let odd_sum = self.odd_sum.get_mut(i);
        let added = accumulate(&mut self.sum[i], odd_sum, &mut self.samples[i], radiance);
        if added && let (Some(sum), Some(aov)) = (self.aov_sum.get_mut(i), aov) {
            sum.add(aov);
        }
        self.rejected_samples += u64::from(!added);
    }
}

/// Adds a finite sample to a pixel's sum and count, and to its odd sum (if kept) when it is
/// the pixel's second, fourth, ... sample; returns false (adding nothing) otherwise.
#[inline]
fn accumulate(
    sum: &mut [f64; 3],
    odd_sum: Option<&mut [f64; 3]>,
    samples: &mut u32,
    radiance: Rgb,
) -> bool {
    if !radiance.is_finite() {
        return false;
    }
    let value = [radiance.x as f64, radiance.y as f64, radiance.z as f64];
    for c in 0..3 {
        sum[c] += value[c];
    }
    if let Some(odd_sum) = odd_sum
        && *samples % 2 == 1
    {
        for c in 0..3 {
            odd_sum[c] += value[c];
        }
    }
    *samples += 1;
    true
}

/// Pixels that can be written to an image file: a resolved [`Image`], or a [`Film`] resolved
/// pixel by pixel as the file is written (no second image-sized buffer beside the film).
pub trait Pixels: Sync {
    /// Width and height.
    fn size(&self) -> (u32, u32);
    /// The pixel of row-major index `index`, row 0 at the top.
    fn pixel(&self, index: usize) -> Rgb;
}

impl Pixels for Film {
    fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// The mean of the pixel's samples; black without samples.
    fn pixel(&self, index: usize) -> Rgb {
        let (s, n) = (self.sum[index], self.samples[index]);
        let inv = if n > 0 { 1.0 / n as f64 } else { 0.0 };
        Rgb::new(
            (s[0] * inv) as f32,
            (s[1] * inv) as f32,
            (s[2] * inv) as f32,
        )
    }
}

impl Pixels for Image {
    fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    fn pixel(&self, index: usize) -> Rgb {
        self.pixels[index]
    }
}

/// A linear RGB image.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Row-major pixels, row 0 at the top.
    pub pixels: Vec<Rgb>,
}

impl Image {
    /// Pixel at column `x`, row `y`.
    pub fn at(&self, x: u32, y: u32) -> Rgb {
        self.pixels[(y * self.width + x) as usize]
    }

    /// Mean over all pixels.
    pub fn mean(&self) -> Rgb {
        let s = self.pixels.iter().fold([0.0f64; 3], |a, p| {
            [a[0] + p.x as f64, a[1] + p.y as f64, a[2] + p.z as f64]
        });
        let n = self.pixels.len().max(1) as f64;
        Rgb::new((s[0] / n) as f32, (s[1] / n) as f32, (s[2] / n) as f32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nan_and_infinite_samples_are_counted_and_discarded() {
        let mut film = Film::new(2, 1);
        film.add_sample(0, Rgb::new(1.0, 2.0, 3.0));
        film.add_sample(0, Rgb::new(f32::NAN, 0.0, 0.0));
        film.add_sample(0, Rgb::new(0.0, f32::INFINITY, 0.0));
        film.add_sample(1, Rgb::new(0.0, 0.0, f32::NEG_INFINITY));
        assert_eq!(film.rejected_samples, 3);
        let image = film.resolve();
        assert_eq!(image.pixels[0], Rgb::new(1.0, 2.0, 3.0));
        assert_eq!(image.pixels[1], Rgb::ZERO);
        assert_eq!(film.min_samples(), 0);
    }

    #[test]
    fn pixel_error_is_zero_for_constant_samples_and_grows_with_noise() {
        let mut film = Film::with_error_estimate(3, 1);
        for k in 0..64 {
            film.add_sample(0, Rgb::splat(0.5));
            // Alternating 0 and 1: the halves differ by the most (mean 0.5 either way).
            film.add_sample(1, Rgb::splat((k % 2) as f32));
            film.add_sample(2, Rgb::splat(0.5 + 0.01 * ((k * 7919) % 13) as f32));
        }
        assert_eq!(film.pixel_error(0), 0.0);
        // |mean - mean of the odd half| = 0.5 per channel, over sqrt(1.5).
        let expected = 1.5 / (1e-4 + 1.5f64.sqrt());
        assert!((film.pixel_error(1) as f64 - expected).abs() < 1e-6);
        assert!(film.pixel_error(2) > 0.0 && film.pixel_error(2) < film.pixel_error(1));
        assert_eq!(Film::new(1, 1).pixel_error(0), f32::INFINITY);
        assert_eq!(film.spp_range(0..3), (64, 64.0, 64));
    }

    #[test]
    fn regions_filled_in_parallel_match_samples_added_one_by_one() {
        // Two passes over pixels 5..1005 of a 40 x 30 film, some samples NaN or infinite.
        let radiance = |pass: u32, pixel: u32| {
            let u = |d| crate::math::rng::uniform(pixel as u64, pass, d);
            let c = Rgb::new(u(0), u(1), u(2));
            match u(3) {
                x if x < 0.05 => Rgb::new(f32::NAN, c.y, c.z),
                x if x < 0.1 => Rgb::new(c.x, f32::INFINITY, c.z),
                _ => c,
            }
        };
        let pixels = 5..1005;
        let (mut one_by_one, mut regions) = (
            Film::with_error_estimate(40, 30),
            Film::with_error_estimate(40, 30),
        );
        for pass in 0..2 {
            for p in pixels.clone() {
                one_by_one.add_sample(p, radiance(pass, p));
            }
            regions.rejected_samples += regions
                .regions_mut(pixels.clone(), 64)
                .map(|mut region| {
                    for p in region.pixels() {
                        region.add_sample(p, radiance(pass, p));
                    }
                    region.rejected_samples
                })
                .sum::<u64>();
        }
        // The regions tile the range in order, the last one shorter.
        let tiles: Vec<Range<u32>> = regions
            .regions_mut(pixels.clone(), 64)
            .map(|r| r.pixels())
            .collect();
        assert_eq!(tiles.len(), 16);
        assert_eq!(tiles[0], 5..69);
        assert!(tiles.windows(2).all(|t| t[0].end == t[1].start));
        assert_eq!(tiles[15], 965..1005);
        assert!(one_by_one.rejected_samples > 0);
        assert_eq!(regions.rejected_samples, one_by_one.rejected_samples);
        assert_eq!(regions.samples, one_by_one.samples);
        assert_eq!(regions.sum, one_by_one.sum);
        assert_eq!(regions.odd_sum, one_by_one.odd_sum);
        assert!(regions.odd_sum.iter().any(|s| s[0] != 0.0));
    }
}
