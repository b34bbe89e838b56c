//! Root-mean-square error of linear EXR images against a reference, per channel and over all
//! channels, for equal-time noise comparisons (README, "Multiple importance sampling").
//!
//! `cargo run --release --example image_error -- reference.exr a.exr [b.exr ...]`

use std::path::Path;
use wavetrace::output::read_exr;

fn main() -> anyhow::Result<()> {
    let paths: Vec<String> = std::env::args().skip(1).collect();
    let Some((reference, others)) = paths.split_first() else {
        anyhow::bail!("usage: image_error reference.exr image.exr [image.exr ...]");
    };
    let reference = read_exr(Path::new(reference))?;
    let mean: f64 = reference
        .pixels
        .iter()
        .map(|p| (p.x + p.y + p.z) as f64 / 3.0)
        .sum::<f64>()
        / reference.pixels.len() as f64;
    for path in others {
        let image = read_exr(Path::new(path))?;
        if (image.width, image.height) != (reference.width, reference.height) {
            anyhow::bail!("'{path}': size differs from the reference");
        }
        let mut squared = [0.0f64; 3];
        for (p, r) in image.pixels.iter().zip(&reference.pixels) {
            let d = *p - *r;
            squared[0] += (d.x as f64).powi(2);
            squared[1] += (d.y as f64).powi(2);
            squared[2] += (d.z as f64).powi(2);
        }
        let n = image.pixels.len() as f64;
        let rmse = squared.map(|s| (s / n).sqrt());
        let total = (squared.iter().sum::<f64>() / (3.0 * n)).sqrt();
        println!(
            "{path}: rmse {total:.5} (relative to the mean {:.4}), per channel {:.5} {:.5} {:.5}",
            total / mean,
            rmse[0],
            rmse[1],
            rmse[2]
        );
    }
    Ok(())
}
