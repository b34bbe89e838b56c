//! Partial films: part `K` of `N` of a frame (a band of whole rows of adaptive sampling's
//! tiles, [`part_rows`]) written to a file with its pixels' raw accumulators, and the merge
//! of all `N` files back into the frame's film.
//!
//! The file (all numbers little-endian):
//!
//! ```text
//! offset  size  field
//!      0     8  magic "WAVEPART"
//!      8     4  format version (1)
//!     12     4  part index K (0-based)
//!     16     4  part count N
//!     20     4  image width
//!     24     4  image height
//!     28     4  first pixel row of the part
//!     32     4  pixel rows in the part
//!     36     4  flags: bit 0 set when each pixel carries its odd-sample sum (adaptive sampling)
//!     40     4  exposure in stops for a PNG output (f32)
//!     44     8  samples rejected as NaN or infinite in the part
//!     52     4  length L of the identity text
//!     56     L  identity text (UTF-8): the program's version, the scene file's name and
//!               fingerprint, and every setting that affects the pixels, one per line
//!   56+L     -  per pixel of the part's rows, row-major: sum of samples (3 x f64), odd-sample
//!               sum (3 x f64, only with flag bit 0), samples taken (u32)
//!    end-8   8  FNV-1a 64 of every byte before it
//! ```
//!
//! The accumulators are the film's own, so the merged film is the film a whole render would
//! have held, bit for bit, and the image is written from it by the same function.

use super::fnv1a64;
use crate::error::{Error, Result};
use crate::film::{Film, PixelAccumulator};
use crate::wavefront::TILE;
use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::str::FromStr;

/// The file's first bytes.
const MAGIC: &[u8; 8] = b"WAVEPART";
/// The format version this build reads and writes.
const VERSION: u32 = 1;
/// Bytes before the identity text.
const FIXED_HEADER: usize = 56;
/// Bytes of the trailing checksum.
const CHECKSUM: usize = 8;

/// Part `index` of `count` (`--part K/N`): 0-based, as Slurm's array indices and
/// Kubernetes' `JOB_COMPLETION_INDEX` count.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PartIndex {
    /// K, in `0..count`.
    pub index: u32,
    /// N, at least 1.
    pub count: u32,
}

impl FromStr for PartIndex {
    type Err = String;

    fn from_str(text: &str) -> std::result::Result<Self, String> {
        let usage = || format!("expected K/N with 0 <= K < N (K 0-based), got '{text}'");
        let (index, count) = text.split_once('/').ok_or_else(usage)?;
        let index: u32 = index.trim().parse().map_err(|_| usage())?;
        let count: u32 = count.trim().parse().map_err(|_| usage())?;
        if count == 0 || index >= count {
            return Err(usage());
        }
        Ok(PartIndex { index, count })
    }
}

impl fmt::Display for PartIndex {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// The pixel rows of part `part` of an image `height` rows high: the rows of [`TILE`]-pixel
/// tiles are shared out in order, as evenly as they go (adaptive sampling decides each tile
/// from its own pixels, so a tile must not be cut between parts). An error when there are
/// fewer tile rows than parts.
pub fn part_rows(height: u32, part: PartIndex) -> Result<Range<u32>> {
    let tile_rows = height.div_ceil(TILE) as u64;
    if part.count as u64 > tile_rows {
        return Err(Error::Settings(format!(
            "--part {part}: a {height}-pixel-high image has {tile_rows} rows of {TILE}x{TILE} \
             tiles, too few for {} parts (at most {tile_rows})",
            part.count
        )));
    }
    let boundary = |k: u64| (k * tile_rows / part.count as u64) as u32 * TILE;
    let first = boundary(part.index as u64);
    let last = boundary(part.index as u64 + 1).min(height);
    Ok(first..last)
}

/// What identifies the render a part belongs to, and its place in it.
#[derive(Clone, Debug, PartialEq)]
pub struct PartHeader {
    /// Which part.
    pub part: PartIndex,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Program version, scene fingerprint and every setting that affects the pixels, one per
    /// line: parts merge only when their identities are equal.
    pub identity: String,
    /// Exposure in stops applied when the merged frame is written as a PNG.
    pub exposure: f32,
}

/// Writes the pixels of part `header.part` of `film` (rendered by
/// [`crate::wavefront::render_rows`] over [`part_rows`]) to `path`, all at once (a temporary
/// file renamed into place).
pub fn write_part(path: &Path, header: &PartHeader, film: &Film) -> Result<()> {
    let rows = part_rows(header.height, header.part)?;
    if (film.width, film.height) != (header.width, header.height) {
        return Err(Error::Settings(format!(
            "the film is {}x{}, the part's header says {}x{}",
            film.width, film.height, header.width, header.height
        )));
    }
    let error_estimate = film.has_error_estimate();
    let pixels = (rows.start * film.width) as usize..(rows.end * film.width) as usize;
    let mut bytes = Vec::with_capacity(
        FIXED_HEADER + header.identity.len() + pixels.len() * record_size(error_estimate) + 8,
    );
    bytes.extend_from_slice(MAGIC);
    for word in [
        VERSION,
        header.part.index,
        header.part.count,
        header.width,
        header.height,
        rows.start,
        rows.len() as u32,
        u32::from(error_estimate),
    ] {
        bytes.extend_from_slice(&word.to_le_bytes());
    }
    bytes.extend_from_slice(&header.exposure.to_le_bytes());
    bytes.extend_from_slice(&film.rejected_samples.to_le_bytes());
    bytes.extend_from_slice(&(header.identity.len() as u32).to_le_bytes());
    bytes.extend_from_slice(header.identity.as_bytes());
    for pixel in pixels {
        let accumulator = film.accumulator(pixel);
        let sums = if error_estimate {
            &[accumulator.sum, accumulator.odd_sum][..]
        } else {
            &[accumulator.sum][..]
        };
        for value in sums.iter().flatten() {
            bytes.extend_from_slice(&value.to_le_bytes());
        }
        bytes.extend_from_slice(&accumulator.samples.to_le_bytes());
    }
    let checksum = fnv1a64(&bytes);
    bytes.extend_from_slice(&checksum.to_le_bytes());
    crate::output::write_atomically(path, |file| {
        std::io::Write::write_all(file, &bytes).map_err(|source| Error::Io {
            path: path.to_path_buf(),
            action: "cannot write",
            source,
        })
    })
}

/// Checks, before a long render, that a part file can be written at `path`: an existing
/// directory and permission to create files in it (a temporary file is made and removed).
pub fn check_part_writable(path: &Path) -> Result<()> {
    let io_error = |source| Error::Io {
        path: path.to_path_buf(),
        action: "cannot write",
        source,
    };
    if path.is_dir() {
        return Err(Error::input(path, None, "is a directory, not a file"));
    }
    let probe = crate::output::temporary_path(path);
    std::fs::File::create(&probe).map_err(io_error)?;
    std::fs::remove_file(&probe).map_err(io_error)
}

/// Bytes per pixel record.
fn record_size(error_estimate: bool) -> usize {
    8 * 3 * if error_estimate { 2 } else { 1 } + 4
}

/// A part read back from its file.
struct PartFile {
    header: PartHeader,
    rows: Range<u32>,
    error_estimate: bool,
    rejected_samples: u64,
    /// The pixel records, [`record_size`] bytes each.
    records: Vec<u8>,
}

/// Little-endian reads from a part file's bytes, each naming the file in its error.
struct Reader<'a> {
    path: &'a Path,
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take(&mut self, n: usize) -> Result<&[u8]> {
        let end = self
            .at
            .checked_add(n)
            .filter(|&end| end <= self.bytes.len());
        let Some(end) = end else {
            return Err(Error::input(
                self.path,
                None,
                "part file cut short (truncated, or not a part file)",
            ));
        };
        let taken = &self.bytes[self.at..end];
        self.at = end;
        Ok(taken)
    }

    fn u32(&mut self) -> Result<u32> {
        Ok(u32::from_le_bytes(
            self.take(4)?.try_into().expect("4 bytes"),
        ))
    }

    fn u64(&mut self) -> Result<u64> {
        Ok(u64::from_le_bytes(
            self.take(8)?.try_into().expect("8 bytes"),
        ))
    }
}

/// Reads and checks a part file (magic, version, checksum, sizes, rows).
fn read_part(path: &Path) -> Result<PartFile> {
    let bytes = std::fs::read(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        action: "cannot read",
        source,
    })?;
    let bad = |message: String| Error::input(path, None, message);
    if bytes.len() < MAGIC.len() || &bytes[..MAGIC.len()] != MAGIC {
        return Err(bad(
            "not a wavetrace part file (made by `render --part`)".into()
        ));
    }
    let mut reader = Reader {
        path,
        bytes: &bytes,
        at: MAGIC.len(),
    };
    let version = reader.u32()?;
    if version != VERSION {
        return Err(bad(format!(
            "part file format version {version}; this wavetrace reads version {VERSION}"
        )));
    }
    let (index, count, width, height) =
        (reader.u32()?, reader.u32()?, reader.u32()?, reader.u32()?);
    let (first_row, row_count, flags) = (reader.u32()?, reader.u32()?, reader.u32()?);
    let exposure = f32::from_bits(reader.u32()?);
    let rejected_samples = reader.u64()?;
    let identity_length = reader.u32()? as usize;
    let identity = String::from_utf8(reader.take(identity_length)?.to_vec())
        .map_err(|_| bad("identity text is not UTF-8".into()))?;
    let body_start = reader.at;
    let Some(checked_length) = bytes.len().checked_sub(CHECKSUM) else {
        return Err(bad("part file cut short".into()));
    };
    let stored = u64::from_le_bytes(bytes[checked_length..].try_into().expect("8 bytes"));
    if checked_length < body_start || fnv1a64(&bytes[..checked_length]) != stored {
        return Err(bad(
            "part file damaged: its checksum does not match (truncated or changed)".into(),
        ));
    }
    if count == 0 || index >= count || width == 0 || height == 0 || flags > 1 {
        return Err(bad(format!(
            "part file header is invalid (part {index}/{count}, {width}x{height}, flags {flags})"
        )));
    }
    let part = PartIndex { index, count };
    let rows = part_rows(height, part).map_err(|e| bad(e.to_string()))?;
    let error_estimate = flags == 1;
    let expected = rows.len() as u64 * width as u64 * record_size(error_estimate) as u64;
    if rows != (first_row..first_row + row_count)
        || (checked_length - body_start) as u64 != expected
    {
        return Err(bad(format!(
            "part {part} of a {width}x{height} image should hold rows {}..{} ({expected} bytes \
             of pixels); the file holds rows {first_row}..{} ({} bytes)",
            rows.start,
            rows.end,
            first_row as u64 + row_count as u64,
            checked_length - body_start
        )));
    }
    Ok(PartFile {
        header: PartHeader {
            part,
            width,
            height,
            identity,
            exposure,
        },
        rows,
        error_estimate,
        rejected_samples,
        records: bytes[body_start..checked_length].to_vec(),
    })
}

/// A frame merged from its parts.
pub struct MergedFrame {
    /// The film, as the whole render would have held it.
    pub film: Film,
    /// The parts' common identity (see [`PartHeader::identity`]).
    pub identity: String,
    /// Exposure in stops for a PNG output, as the parts were rendered with.
    pub exposure: f32,
}

/// Merges the part files `paths`, in any order, into the frame's film. Every part of the
/// same render must be there exactly once; a missing, repeated or foreign part (another
/// scene, setting, seed or part count) is an error naming the file.
pub fn merge_parts(paths: &[PathBuf]) -> Result<MergedFrame> {
    let Some(first_path) = paths.first() else {
        return Err(Error::Settings("no part files to merge".into()));
    };
    let first = read_part(first_path)?;
    let (width, height, count) = (
        first.header.width,
        first.header.height,
        first.header.part.count,
    );
    let mut film = if first.error_estimate {
        Film::with_error_estimate(width, height)
    } else {
        Film::new(width, height)
    };
    let mut source: Vec<Option<&Path>> = vec![None; count as usize];
    let identity = first.header.identity.clone();
    let error_estimate = first.error_estimate;
    for (k, path) in paths.iter().enumerate() {
        let part = if k == 0 {
            // Read above; read again would cost a second pass over the largest files.
            None
        } else {
            Some(read_part(path)?)
        };
        let part = part.as_ref().unwrap_or(&first);
        check_same_render(path, &part.header, first_path, &first.header)?;
        if part.error_estimate != error_estimate {
            return Err(Error::input(
                path,
                None,
                format!(
                    "rendered with{} adaptive sampling's error estimate, {} with{}",
                    if part.error_estimate { "" } else { "out" },
                    first_path.display(),
                    if error_estimate { "" } else { "out" }
                ),
            ));
        }
        let slot = &mut source[part.header.part.index as usize];
        if let Some(earlier) = slot {
            return Err(Error::input(
                path,
                None,
                format!(
                    "part {} given twice (also {})",
                    part.header.part,
                    earlier.display()
                ),
            ));
        }
        *slot = Some(path);
        fill_film(&mut film, part);
    }
    let missing: Vec<String> = (0..count)
        .filter(|&k| source[k as usize].is_none())
        .map(|k| k.to_string())
        .collect();
    if !missing.is_empty() {
        return Err(Error::input(
            first_path,
            None,
            format!(
                "part {} of {count} of this render missing: give all {count} part files",
                missing.join(", ")
            ),
        ));
    }
    Ok(MergedFrame {
        film,
        identity,
        exposure: first.header.exposure,
    })
}

/// An error naming `path` unless its header belongs to the same render as `reference`'s.
fn check_same_render(
    path: &Path,
    header: &PartHeader,
    reference_path: &Path,
    reference: &PartHeader,
) -> Result<()> {
    let differs = |what: String| {
        Err(Error::input(
            path,
            None,
            format!(
                "belongs to another render than {}: {what}",
                reference_path.display()
            ),
        ))
    };
    if header.part.count != reference.part.count {
        return differs(format!(
            "split into {} parts, not {}",
            header.part.count, reference.part.count
        ));
    }
    if (header.width, header.height) != (reference.width, reference.height) {
        return differs(format!(
            "{}x{}, not {}x{}",
            header.width, header.height, reference.width, reference.height
        ));
    }
    if header.identity != reference.identity
        || header.exposure.to_bits() != reference.exposure.to_bits()
    {
        let line = header
            .identity
            .lines()
            .zip(reference.identity.lines())
            .find(|(a, b)| a != b)
            .map_or_else(
                || "identity differs".to_string(),
                |(a, b)| format!("'{a}', not '{b}'"),
            );
        return differs(line);
    }
    Ok(())
}

/// Copies a part's pixel records into the film, and adds its rejected samples.
fn fill_film(film: &mut Film, part: &PartFile) {
    let size = record_size(part.error_estimate);
    let first_pixel = (part.rows.start * film.width) as usize;
    let f64_at = |record: &[u8], k: usize| {
        f64::from_le_bytes(record[8 * k..8 * k + 8].try_into().expect("8 bytes"))
    };
    for (offset, record) in part.records.chunks_exact(size).enumerate() {
        let sum = [f64_at(record, 0), f64_at(record, 1), f64_at(record, 2)];
        let odd_sum = if part.error_estimate {
            [f64_at(record, 3), f64_at(record, 4), f64_at(record, 5)]
        } else {
            [0.0; 3]
        };
        let samples = u32::from_le_bytes(record[size - 4..].try_into().expect("4 bytes"));
        let accumulator = PixelAccumulator {
            sum,
            odd_sum,
            samples,
        };
        film.set_accumulator(first_pixel + offset, accumulator);
    }
    film.rejected_samples += part.rejected_samples;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Rgb;

    #[test]
    fn part_indices_parse_and_refuse_what_is_not_k_of_n() {
        assert_eq!("3/4".parse(), Ok(PartIndex { index: 3, count: 4 }));
        for bad in ["4/4", "0/0", "1", "a/b", "-1/4", "1/-4", "", "1/2/3"] {
            assert!(bad.parse::<PartIndex>().is_err(), "{bad}");
        }
    }

    #[test]
    fn parts_cover_the_rows_in_whole_tile_rows() {
        // 61 rows: 8 tile rows, the last 5 pixels high.
        let rows: Vec<Range<u32>> = (0..3)
            .map(|index| part_rows(61, PartIndex { index, count: 3 }).unwrap())
            .collect();
        assert_eq!(rows, [0..16, 16..40, 40..61]);
        assert!(part_rows(61, PartIndex { index: 0, count: 9 }).is_err());
        assert_eq!(
            part_rows(5, PartIndex { index: 0, count: 1 }).unwrap(),
            0..5
        );
    }

    /// A film of `width` x 20 with a few samples in every pixel of the rows `rows`.
    fn film_with_samples(width: u32, rows: Range<u32>, error_estimate: bool) -> Film {
        let mut film = if error_estimate {
            Film::with_error_estimate(width, 20)
        } else {
            Film::new(width, 20)
        };
        for pixel in rows.start * width..rows.end * width {
            for sample in 0..3 {
                let u = |d| crate::math::rng::uniform(pixel as u64, sample, d);
                film.add_sample(pixel, Rgb::new(u(0), u(1) * 1e-7, u(2) * 1e9));
            }
        }
        film
    }

    #[test]
    fn merged_parts_hold_the_whole_film_bit_for_bit() {
        let dir = tempfile::tempdir().unwrap();
        for error_estimate in [false, true] {
            let whole = film_with_samples(7, 0..20, error_estimate);
            let mut paths = Vec::new();
            for index in (0..3).rev() {
                let part = PartIndex { index, count: 3 };
                let film = film_with_samples(7, part_rows(20, part).unwrap(), error_estimate);
                let path = dir.path().join(format!("part-{index}"));
                let header = PartHeader {
                    part,
                    width: 7,
                    height: 20,
                    identity: "test".into(),
                    exposure: 0.0,
                };
                write_part(&path, &header, &film).unwrap();
                paths.push(path);
            }
            let merged = merge_parts(&paths).unwrap().film;
            for pixel in 0..140 {
                assert_eq!(merged.accumulator(pixel), whole.accumulator(pixel));
            }
            // One missing, one twice, one damaged.
            let error = |paths: &[PathBuf]| merge_parts(paths).err().unwrap().to_string();
            assert!(error(&paths[..2]).contains("part 0 of 3 of this render missing"));
            let twice = [paths[0].clone(), paths[1].clone(), paths[0].clone()];
            assert!(error(&twice).contains("given twice"), "{}", error(&twice));
            let mut bytes = std::fs::read(&paths[1]).unwrap();
            bytes[74] ^= 1;
            std::fs::write(&paths[1], &bytes).unwrap();
            assert!(error(&paths).contains("checksum"), "{}", error(&paths));
        }
    }
}
