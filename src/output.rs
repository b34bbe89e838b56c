//! Image files: PNG (exposure, sRGB, 8 bit) or OpenEXR (linear float RGB), chosen by the
//! extension. Files are written to a temporary file beside the target and renamed into place,
//! so an existing image is never left half-overwritten.

use crate::error::{Error, Result};
use crate::film::Image;
use std::path::{Path, PathBuf};

/// Output formats.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageFormat {
    /// 8-bit sRGB PNG.
    Png,
    /// Linear float32 RGB OpenEXR.
    Exr,
}

impl ImageFormat {
    /// The format for a path's extension.
    pub fn from_path(path: &Path) -> Result<Self> {
        match path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .as_deref()
        {
            Some("png") => Ok(ImageFormat::Png),
            Some("exr") => Ok(ImageFormat::Exr),
            _ => Err(Error::input(
                path,
                None,
                "unknown output extension (expected .png or .exr)",
            )),
        }
    }
}

/// The sRGB transfer function (OETF) on a linear value in [0, 1].
#[inline]
pub fn linear_to_srgb(x: f32) -> f32 {
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// Writes `image` to `path`; `exposure` (in stops) applies to PNG only.
pub fn write_image(path: &Path, image: &Image, exposure: f32) -> Result<()> {
    let format = ImageFormat::from_path(path)?;
    let temporary = temporary_path(path);
    let written = match format {
        ImageFormat::Png => write_png(&temporary, image, exposure),
        ImageFormat::Exr => write_exr(&temporary, image),
    };
    let result = written.and_then(|_| {
        std::fs::rename(&temporary, path).map_err(|source| Error::Io {
            path: path.to_path_buf(),
            action: "cannot write",
            source,
        })
    });
    if result.is_err() {
        let _ = std::fs::remove_file(&temporary);
    }
    result.map_err(|e| retarget(e, &temporary, path))
}

/// `.NAME.tmp-PID` beside the target, so the rename stays within one file system.
fn temporary_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.tmp-{}", std::process::id()))
}

/// Errors about the temporary file are reported against the file the user named.
fn retarget(e: Error, temporary: &Path, target: &Path) -> Error {
    match e {
        Error::Io {
            path,
            action,
            source,
        } if path == temporary => Error::Io {
            path: target.to_path_buf(),
            action,
            source,
        },
        Error::Encode { path, message } if path == temporary => Error::Encode {
            path: target.to_path_buf(),
            message,
        },
        other => other,
    }
}

fn write_png(path: &Path, image: &Image, exposure: f32) -> Result<()> {
    let scale = exposure.exp2();
    let bytes: Vec<u8> = image
        .pixels
        .iter()
        .flat_map(|p| (*p * scale).to_array())
        .map(|c| {
            (linear_to_srgb(if c.is_finite() {
                c.clamp(0.0, 1.0)
            } else {
                0.0
            }) * 255.0)
                .round() as u8
        })
        .collect();
    let buffer = image::RgbImage::from_raw(image.width, image.height, bytes)
        .expect("buffer size matches the image");
    let file = std::fs::File::create(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        action: "cannot write",
        source,
    })?;
    let mut writer = std::io::BufWriter::new(file);
    buffer
        .write_to(&mut writer, image::ImageFormat::Png)
        .map_err(|e| encode_error(path, e))?;
    use std::io::Write;
    writer.flush().map_err(|source| Error::Io {
        path: path.to_path_buf(),
        action: "cannot write",
        source,
    })?;
    writer.get_ref().sync_all().map_err(|source| Error::Io {
        path: path.to_path_buf(),
        action: "cannot write",
        source,
    })
}

fn encode_error(path: &Path, e: image::ImageError) -> Error {
    match e {
        image::ImageError::IoError(source) => Error::Io {
            path: path.to_path_buf(),
            action: "cannot write",
            source,
        },
        other => Error::Encode {
            path: path.to_path_buf(),
            message: other.to_string(),
        },
    }
}

fn write_exr(path: &Path, image: &Image) -> Result<()> {
    let w = image.width as usize;
    exr::prelude::write_rgb_file(path, w, image.height as usize, |x, y| {
        let p = image.pixels[y * w + x];
        (p.x, p.y, p.z)
    })
    .map_err(|e| match e {
        exr::error::Error::Io(source) => Error::Io {
            path: path.to_path_buf(),
            action: "cannot write",
            source,
        },
        other => Error::Encode {
            path: path.to_path_buf(),
            message: other.to_string(),
        },
    })
}

/// Reads a linear RGB OpenEXR file (used by tests and comparisons).
pub fn read_exr(path: &Path) -> Result<Image> {
    let img = exr::prelude::read_first_rgba_layer_from_file(
        path,
        |resolution, _| {
            (
                resolution.width(),
                vec![crate::math::Rgb::ZERO; resolution.width() * resolution.height()],
            )
        },
        |(w, pixels): &mut (usize, Vec<crate::math::Rgb>),
         pos,
         (r, g, b, _a): (f32, f32, f32, f32)| {
            pixels[pos.y() * *w + pos.x()] = crate::math::Rgb::new(r, g, b);
        },
    )
    .map_err(|e| Error::input(path, None, format!("cannot read OpenEXR: {e}")))?;
    let size = img.layer_data.size;
    Ok(Image {
        width: size.width() as u32,
        height: size.height() as u32,
        pixels: img.layer_data.channel_data.pixels.1,
    })
}

#[cfg(test)]
mod tests {
    #[test]
    fn srgb_curve_known_values() {
        assert_eq!(super::linear_to_srgb(0.0), 0.0);
        assert!((super::linear_to_srgb(1.0) - 1.0).abs() < 1e-6);
        assert!(((super::linear_to_srgb(0.18) * 255.0).round() - 118.0).abs() < 0.5);
    }
}
