//! The film: per-pixel sums of sample radiance, and the resolved image.

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
    samples: Vec<u32>,
    /// Samples discarded because their radiance was NaN or infinite.
    pub rejected_samples: u64,
}

impl Film {
    /// An empty film.
    pub fn new(width: u32, height: u32) -> Self {
        let n = width as usize * height as usize;
        Film {
            width,
            height,
            sum: vec![[0.0; 3]; n],
            samples: vec![0; n],
            rejected_samples: 0,
        }
    }

    /// Adds one sample to a pixel; a NaN or infinite sample is counted and discarded.
    pub fn add_sample(&mut self, pixel: u32, radiance: Rgb) {
        let i = pixel as usize;
        let added = accumulate(&mut self.sum[i], &mut self.samples[i], radiance);
        self.rejected_samples += u64::from(!added);
    }

    /// The pixels `pixels` cut into consecutive regions of `size` pixels (the last may be
    /// shorter), to be filled in parallel.
    pub fn regions_mut(
        &mut self,
        pixels: Range<u32>,
        size: usize,
    ) -> impl IndexedParallelIterator<Item = FilmRegion<'_>> {
        let range = pixels.start as usize..pixels.end as usize;
        self.sum[range.clone()]
            .par_chunks_mut(size)
            .zip(self.samples[range].par_chunks_mut(size))
            .enumerate()
            .map(move |(k, (sum, samples))| FilmRegion {
                first_pixel: pixels.start + (k * size) as u32,
                sum,
                samples,
                rejected_samples: 0,
            })
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

/// A run of consecutive pixels of a [`Film`], borrowed to add samples to them: the regions
/// of one film are filled in parallel, each pixel's samples still in sample order.
pub struct FilmRegion<'a> {
    first_pixel: u32,
    sum: &'a mut [[f64; 3]],
    samples: &'a mut [u32],
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
        let i = (pixel - self.first_pixel) as usize;
        let added = accumulate(&mut self.sum[i], &mut self.samples[i], radiance);
        self.rejected_samples += u64::from(!added);
    }
}

/// Adds a finite sample to a pixel's sum and count; returns false (adding nothing) otherwise.
#[inline]
fn accumulate(sum: &mut [f64; 3], samples: &mut u32, radiance: Rgb) -> bool {
    if !radiance.is_finite() {
        return false;
    }
    sum[0] += radiance.x as f64;
    sum[1] += radiance.y as f64;
    sum[2] += radiance.z as f64;
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
        let (mut one_by_one, mut regions) = (Film::new(40, 30), Film::new(40, 30));
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
    }
}
