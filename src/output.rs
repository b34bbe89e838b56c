//! Image files: PNG (exposure, sRGB, 8 bit) or OpenEXR (linear float RGB, with named
//! auxiliary layers such as `albedo.R` beside the colour for `--aov`), chosen by the
//! extension. Files are written to a temporary file beside the target and renamed into place,
//! so an existing image is never left half-overwritten.

use crate::error::{Error, Result};
use crate::film::{Image, Pixels};
use image::ImageEncoder;
use std::fs::File;
use std::io::{BufWriter, Seek, Write};
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

/// Writes `image` (an [`Image`], or a film resolved as it is written) to `path`; `exposure`
/// (in stops) applies to PNG only.
pub fn write_image(path: &Path, image: &impl Pixels, exposure: f32) -> Result<()> {
    let format = ImageFormat::from_path(path)?;
    write_atomically(path, |file| match format {
        ImageFormat::Png => encode_png(file, path, image, exposure),
        ImageFormat::Exr => encode_exr(file, path, image),
    })
}

/// A named layer of a multi-layer OpenEXR file: its channels are written as `name.channel`
/// (`albedo.R`, `normal.X`, `depth.Z`), as Blender, OpenImageIO and Mitsuba name them.
pub struct NamedLayer<'a> {
    /// Layer name.
    pub name: &'a str,
    /// Channel names, one per component of `image` used (at most three: R, G, B).
    pub channels: &'a [&'a str],
    /// The layer's values (only the first `channels.len()` components are written).
    pub image: Image,
}

/// Writes one OpenEXR file holding `color` as its R, G, B channels and every layer of `layers`
/// beside it (f32, one part, channels sorted by name as the format wants).
pub fn write_exr_layers(path: &Path, color: &Image, layers: &[NamedLayer]) -> Result<()> {
    use exr::prelude::{
        AnyChannel, AnyChannels, Encoding, FlatSamples, Image as ExrImage, Layer, LayerAttributes,
        LineOrder, SmallVec, WritableImage,
    };
    if ImageFormat::from_path(path)? != ImageFormat::Exr {
        return Err(Error::input(
            path,
            None,
            "auxiliary layers need an OpenEXR (.exr) output",
        ));
    }
    let component = |image: &Image, c: usize| -> FlatSamples {
        FlatSamples::F32(image.pixels.iter().map(|p| p[c]).collect())
    };
    let mut list: SmallVec<[AnyChannel<FlatSamples>; 4]> = SmallVec::new();
    for (c, name) in ["R", "G", "B"].into_iter().enumerate() {
        list.push(AnyChannel::new(name, component(color, c)));
    }
    for layer in layers {
        for (c, channel) in layer.channels.iter().enumerate().take(3) {
            let name = format!("{}.{channel}", layer.name);
            list.push(AnyChannel::new(name.as_str(), component(&layer.image, c)));
        }
    }
    let size = (color.width as usize, color.height as usize);
    let encoding = Encoding {
        line_order: LineOrder::Increasing,
        ..Encoding::FAST_LOSSLESS
    };
    let channels = AnyChannels::sort(list);
    let image = ExrImage::from_layer(Layer::new(
        size,
        LayerAttributes::default(),
        encoding,
        channels,
    ));
    write_atomically(path, |out| {
        image
            .write()
            .to_buffered(out)
            .map_err(|e| exr_write_error(path, e))
    })
}

/// Checks, before a long render, that `path` can be written: a known extension, an existing
/// directory, and permission to create files in it (a temporary file is made and removed).
pub fn check_writable(path: &Path) -> Result<()> {
    ImageFormat::from_path(path)?;
    if path.is_dir() {
        return Err(Error::input(path, None, "is a directory, not a file"));
    }
    let directory = parent_directory(path);
    if !directory.is_dir() {
        let problem = if directory.exists() {
            "is not a directory"
        } else {
            "does not exist"
        };
        return Err(Error::input(
            path,
            None,
            format!("output directory '{}' {problem}", directory.display()),
        ));
    }
    let probe = temporary_path(path);
    std::fs::File::create(&probe).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        action: "cannot write",
        source,
    })?;
    std::fs::remove_file(&probe).map_err(|source| Error::Io {
        path: probe.clone(),
        action: "cannot remove",
        source,
    })
}

/// Writes `path` all at once: `encode` writes into a temporary file beside it, which is
/// flushed to disk and then renamed over `path`. On any failure (including a full disk) the
/// temporary file is removed and whatever was at `path` before is left untouched.
pub fn write_atomically(
    path: &Path,
    encode: impl FnOnce(&mut BufWriter<File>) -> Result<()>,
) -> Result<()> {
    let temporary = temporary_path(path);
    let io_error = |source| Error::Io {
        path: path.to_path_buf(),
        action: "cannot write",
        source,
    };
    let file = File::create(&temporary).map_err(io_error)?;
    let mut writer = BufWriter::new(file);
    let written = encode(&mut writer)
        .and_then(|()| writer.flush().map_err(io_error))
        .and_then(|()| writer.get_ref().sync_all().map_err(io_error));
    drop(writer);
    let result = written.and_then(|()| std::fs::rename(&temporary, path).map_err(io_error));
    if result.is_err() {
        let _ = std::fs::remove_file(&temporary);
    }
    result
}

/// The directory a file is in (`.` for a bare file name).
fn parent_directory(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// `.NAME.tmp-PID` beside the target, so the rename stays within one file system. Public so
/// that a process quitting in a hurry (a second Ctrl-C) can remove it.
pub fn temporary_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.tmp-{}", std::process::id()))
}

/// Encodes an 8-bit sRGB PNG into `out`; `path` names the file in errors.
fn encode_png(out: &mut impl Write, path: &Path, image: &impl Pixels, exposure: f32) -> Result<()> {
    let scale = exposure.exp2();
    let (width, height) = image.size();
    let bytes: Vec<u8> = (0..width as usize * height as usize)
        .flat_map(|i| (image.pixel(i) * scale).to_array())
        .map(|c| {
            (linear_to_srgb(if c.is_finite() {
                c.clamp(0.0, 1.0)
            } else {
                0.0
            }) * 255.0)
                .round() as u8
        })
        .collect();
    image::codecs::png::PngEncoder::new(out)
        .write_image(&bytes, width, height, image::ExtendedColorType::Rgb8)
        .map_err(|e| match e {
            image::ImageError::IoError(source) => Error::Io {
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

/// Encodes a linear float RGB OpenEXR into `out`; `path` names the file in errors.
fn encode_exr(out: &mut (impl Write + Seek), path: &Path, image: &impl Pixels) -> Result<()> {
    use exr::prelude::{Encoding, Image as ExrImage, LineOrder, SpecificChannels, WritableImage};
    let (width, height) = image.size();
    let w = width as usize;
    let channels = SpecificChannels::rgb(|pos: exr::math::Vec2<usize>| {
        let p = image.pixel(pos.y() * w + pos.x());
        (p.x, p.y, p.z)
    });
    // Tiles are compressed in parallel; an increasing line order makes the writer put them in
    // the file in a fixed order, so the same image is the same file whatever the thread timing.
    let encoding = Encoding {
        line_order: LineOrder::Increasing,
        ..Encoding::FAST_LOSSLESS
    };
    ExrImage::from_encoded_channels((w, height as usize), encoding, channels)
        .write()
        .to_buffered(out)
        .map_err(|e| exr_write_error(path, e))
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

/// The error of a failed EXR write: the disk's (full, unwritable) or the encoder's.
fn exr_write_error(path: &Path, e: exr::error::Error) -> Error {
    match e {
        exr::error::Error::Io(source) => Error::Io {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Rgb;

    /// Stands for a full disk: accepts `room` bytes, then fails every write with ENOSPC.
    struct DiskFull<W> {
        inner: W,
        room: usize,
    }

    impl<W: Write> Write for DiskFull<W> {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            if self.room == 0 {
                return Err(std::io::Error::from_raw_os_error(28)); // ENOSPC
            }
            let n = buf.len().min(self.room);
            self.room -= n;
            self.inner.write(&buf[..n])
        }
        fn flush(&mut self) -> std::io::Result<()> {
            self.inner.flush()
        }
    }

    impl<W: Seek> Seek for DiskFull<W> {
        fn seek(&mut self, pos: std::io::SeekFrom) -> std::io::Result<u64> {
            self.inner.seek(pos)
        }
    }

    fn noise_image() -> Image {
        // Varied pixels so that the encoded file is larger than the room on the "disk".
        let pixels = (0..64 * 64)
            .map(|i| Rgb::new((i % 7) as f32 / 7.0, (i % 13) as f32 / 13.0, (i % 5) as f32))
            .collect();
        Image {
            width: 64,
            height: 64,
            pixels,
        }
    }

    fn directory_listing(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn full_disk_keeps_the_old_image_and_leaves_no_temporary_file() {
        let dir = tempfile::tempdir().unwrap();
        let image = noise_image();
        for name in ["old.png", "old.exr"] {
            let path = dir.path().join(name);
            std::fs::write(&path, b"the previous image").unwrap();
            let err = write_atomically(&path, |file| {
                let mut full = DiskFull {
                    inner: file,
                    room: 1000,
                };
                match ImageFormat::from_path(&path).unwrap() {
                    ImageFormat::Png => encode_png(&mut full, &path, &image, 0.0),
                    ImageFormat::Exr => encode_exr(&mut full, &path, &image),
                }
            })
            .unwrap_err();
            let text = err.to_string();
            assert!(text.contains(name), "{text}");
            assert!(text.contains("No space left on device"), "{text}");
            assert_eq!(std::fs::read(&path).unwrap(), b"the previous image");
        }
        assert_eq!(directory_listing(dir.path()), ["old.exr", "old.png"]);
    }

    #[test]
    fn successful_write_replaces_the_image_and_leaves_no_temporary_file() {
        let dir = tempfile::tempdir().unwrap();
        let image = noise_image();
        let exr = dir.path().join("new.exr");
        std::fs::write(&exr, b"the previous image").unwrap();
        write_image(&exr, &image, 0.0).unwrap();
        assert_eq!(read_exr(&exr).unwrap(), image);
        write_image(&dir.path().join("new.png"), &image, 0.0).unwrap();
        assert_eq!(directory_listing(dir.path()), ["new.exr", "new.png"]);
    }

    #[test]
    fn a_film_writes_the_same_files_as_its_resolved_image() {
        let mut film = crate::film::Film::new(7, 5);
        for (i, p) in noise_image().pixels.iter().take(35).enumerate() {
            film.add_sample(i as u32 % 33, *p); // two pixels without samples, two with two
        }
        let dir = tempfile::tempdir().unwrap();
        for name in ["a.exr", "a.png"] {
            let (from_film, resolved) = (
                dir.path().join(name),
                dir.path().join("r".to_owned() + name),
            );
            write_image(&from_film, &film, 1.5).unwrap();
            write_image(&resolved, &film.resolve(), 1.5).unwrap();
            if name.ends_with(".exr") {
                assert_eq!(read_exr(&from_film).unwrap(), film.resolve());
            } else {
                assert_eq!(
                    std::fs::read(&from_film).unwrap(),
                    std::fs::read(&resolved).unwrap()
                );
            }
        }
    }

    #[test]
    fn an_exr_written_again_is_the_same_file_whatever_the_thread_timing() {
        // 16 tiles of 64 x 64, compressed by four threads: without a fixed line order the
        // tiles land in the file in the order the threads finish them.
        let (width, height) = (256, 256);
        let pixels = (0..width * height)
            .map(|i| Rgb::new((i % 7) as f32, (i % 61) as f32 * 0.01, (i / width) as f32))
            .collect();
        let image = Image {
            width: width as u32,
            height: height as u32,
            pixels,
        };
        let dir = tempfile::tempdir().unwrap();
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(4)
            .build()
            .unwrap();
        let files: Vec<Vec<u8>> = (0..8)
            .map(|k| {
                let path = dir.path().join(format!("{k}.exr"));
                pool.install(|| write_image(&path, &image, 0.0)).unwrap();
                std::fs::read(&path).unwrap()
            })
            .collect();
        assert!(files.iter().all(|f| *f == files[0]));
        let meta = exr::meta::MetaData::read_from_file(dir.path().join("0.exr"), false).unwrap();
        assert_eq!(
            meta.headers[0].line_order,
            exr::meta::attribute::LineOrder::Increasing
        );
        assert_eq!(read_exr(&dir.path().join("0.exr")).unwrap(), image);
    }

    #[test]
    fn unwritable_outputs_are_refused_before_rendering() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("no/such/dir/out.png");
        let err = check_writable(&missing).unwrap_err().to_string();
        assert!(err.contains("does not exist"), "{err}");
        let err = check_writable(dir.path()).unwrap_err().to_string();
        assert!(err.contains("unknown output extension"), "{err}");
        let as_dir = dir.path().join("d.png");
        std::fs::create_dir(&as_dir).unwrap();
        let err = check_writable(&as_dir).unwrap_err().to_string();
        assert!(err.contains("is a directory"), "{err}");
        check_writable(&dir.path().join("fine.png")).unwrap();
        assert_eq!(directory_listing(dir.path()), ["d.png"]);
    }

    #[test]
    fn srgb_curve_known_values() {
        assert_eq!(super::linear_to_srgb(0.0), 0.0);
        assert!((super::linear_to_srgb(1.0) - 1.0).abs() < 1e-6);
        assert!(((super::linear_to_srgb(0.18) * 255.0).round() - 118.0).abs() < 0.5);
    }
}
