//! Error of an image against a reference image: the figures of noise comparisons, shared by
//! the examples that make them (`examples/image_error.rs`, `examples/equal_time.rs`, which
//! include this file as a module); its tests run with the end-to-end tests
//! (`tests/e2e/main.rs` includes it too).
//!
//! Per-sample variance shows in the plain mean squared error; the relative MSE weighs dark
//! pixels as much as bright ones; the share of the squared error held by the worst 1% of
//! pixels tells fireflies (a few pixels hold most of it) from noise spread over the image.

use wavetrace::Image;

/// The constant of the relative MSE's denominator: `(x - ref)^2 / (ref^2 + RELATIVE_EPSILON)`,
/// per pixel and channel, so that black reference pixels do not divide by zero (the
/// definition of the MSE reports of pbrt-v4's `imgtool` and of Mitsuba comparisons).
pub const RELATIVE_EPSILON: f64 = 0.01;

/// Error figures of one image against a reference.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImageError {
    /// Mean squared error over pixels and channels.
    pub mse: f64,
    /// Root-mean-square error per channel (red, green, blue).
    pub rmse_per_channel: [f64; 3],
    /// Mean over pixels and channels of `(x - ref)^2 / (ref^2 + 0.01)`.
    pub relative_mse: f64,
    /// Fraction of the total squared error (summed over channels) held by the 1% of pixels
    /// with the largest squared error.
    pub top_percent_share: f64,
    /// Mean of the reference over pixels and channels (to put the RMSE in proportion).
    pub reference_mean: f64,
}

impl ImageError {
    /// The root-mean-square error over pixels and channels.
    pub fn rmse(&self) -> f64 {
        self.mse.sqrt()
    }
}

/// The error of `image` against `reference`; `None` if their sizes differ or they are empty.
pub fn image_error(image: &Image, reference: &Image) -> Option<ImageError> {
    if (image.width, image.height) != (reference.width, reference.height) || image.pixels.is_empty()
    {
        return None;
    }
    let mut channel_squared = [0.0f64; 3];
    let mut relative = 0.0f64;
    let mut reference_sum = 0.0f64;
    let mut pixel_squared = Vec::with_capacity(image.pixels.len());
    for (p, r) in image.pixels.iter().zip(&reference.pixels) {
        let (p, r) = (p.to_array(), r.to_array());
        let mut squared = 0.0;
        for c in 0..3 {
            let (x, y) = (p[c] as f64, r[c] as f64);
            let d2 = (x - y) * (x - y);
            channel_squared[c] += d2;
            relative += d2 / (y * y + RELATIVE_EPSILON);
            reference_sum += y;
            squared += d2;
        }
        pixel_squared.push(squared);
    }
    let n = image.pixels.len() as f64;
    let total: f64 = channel_squared.iter().sum();
    // The worst 1% of pixels (at least one).
    let top = (pixel_squared.len() / 100).max(1);
    let cut = pixel_squared.len() - top;
    pixel_squared.select_nth_unstable_by(cut, f64::total_cmp);
    let top_sum: f64 = pixel_squared[cut..].iter().sum();
    Some(ImageError {
        mse: total / (3.0 * n),
        rmse_per_channel: channel_squared.map(|s| (s / n).sqrt()),
        relative_mse: relative / (3.0 * n),
        top_percent_share: if total > 0.0 { top_sum / total } else { 0.0 },
        reference_mean: reference_sum / (3.0 * n),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use wavetrace::math::Rgb;

    fn image(pixels: Vec<Rgb>) -> Image {
        Image {
            width: pixels.len() as u32,
            height: 1,
            pixels,
        }
    }

    #[test]
    fn figures_match_their_definitions() {
        // 200 pixels of reference 0.5; the image is off by 0.1 in red everywhere and by 1 in
        // all channels at one pixel (the top 1% is two pixels: that one and one other).
        let reference = image(vec![Rgb::splat(0.5); 200]);
        let mut pixels = vec![Rgb::new(0.6, 0.5, 0.5); 200];
        pixels[17] = Rgb::new(1.6, 1.5, 1.5);
        let e = image_error(&image(pixels), &reference).unwrap();
        let big = 1.1f64 * 1.1 + 2.0; // pixel 17's squared error, summed over channels
        let small = 0.1f64 * 0.1; // every other pixel's
        let total = big + 199.0 * small;
        assert!((e.mse - total / 600.0).abs() < 1e-7, "{e:?}");
        let red = ((1.1f64 * 1.1 + 199.0 * small) / 200.0).sqrt();
        assert!((e.rmse_per_channel[0] - red).abs() < 1e-6);
        assert!((e.rmse_per_channel[1] - (1.0f64 / 200.0).sqrt()).abs() < 1e-6);
        assert!((e.relative_mse - total / 0.26 / 600.0).abs() < 1e-6);
        assert!((e.top_percent_share - (big + small) / total).abs() < 1e-6);
        assert!((e.reference_mean - 0.5).abs() < 1e-9);
    }

    #[test]
    fn equal_images_have_no_error_and_sizes_must_match() {
        let a = image(vec![Rgb::new(0.1, 2.0, 0.0); 10]);
        let e = image_error(&a, &a).unwrap();
        assert_eq!(
            (e.mse, e.relative_mse, e.top_percent_share),
            (0.0, 0.0, 0.0)
        );
        assert!(image_error(&a, &image(vec![Rgb::ZERO; 9])).is_none());
    }
}
