//! Error of linear EXR images against a reference: RMSE (overall and per channel), relative
//! MSE and the share of the squared error in the worst 1% of pixels (see
//! `examples/common/image_error.rs`), for noise comparisons (README, "Multiple importance sampling").
//!
//! `cargo run --release --features examples --example image_error -- reference.exr a.exr [b.exr ...]`

// The error measures, shared with `equal_time` (each example uses part of them).
#[allow(dead_code)]
#[path = "common/image_error.rs"]
mod image_error;

use image_error::image_error;
use std::path::Path;
use wavetrace::output::read_exr;

fn main() -> anyhow::Result<()> {
    let paths: Vec<String> = std::env::args().skip(1).collect();
    let Some((reference, others)) = paths.split_first() else {
        anyhow::bail!("usage: image_error reference.exr image.exr [image.exr ...]");
    };
    let reference = read_exr(Path::new(reference))?;
    for path in others {
        let image = read_exr(Path::new(path))?;
        let Some(e) = image_error(&image, &reference) else {
            anyhow::bail!("'{path}': size differs from the reference");
        };
        println!(
            "{path}: rmse {:.5} (relative to the mean {:.4}), per channel {:.5} {:.5} {:.5}, \
             mse {:.6}, relative mse {:.5}, top 1% of pixels hold {:.1}% of the squared error",
            e.rmse(),
            e.rmse() / e.reference_mean,
            e.rmse_per_channel[0],
            e.rmse_per_channel[1],
            e.rmse_per_channel[2],
            e.mse,
            e.relative_mse,
            100.0 * e.top_percent_share
        );
    }
    Ok(())
}
