//! Frame numbers of animation renders: `--frames A-B[:STEP]` ranges and the output file of
//! each frame (Blender's `#` convention). The time of frame F is F / fps seconds, so frame
//! numbers mean what they mean on Blender's timeline (whose keys the glTF importer puts at
//! time x fps).

use std::path::{Path, PathBuf};

/// The frame Blender shows after importing a glTF file: its startup scene's current frame.
/// A render without `--frame` poses animated scenes here.
pub const BLENDER_CURRENT_FRAME: u32 = 1;

/// The frames per second of Blender's startup scene, the default of `--fps`.
pub const DEFAULT_FPS: f32 = 24.0;

/// Frames `first..=last`, every `step`th: `A-B[:STEP]`, or `A` for one frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameRange {
    /// The first frame rendered.
    pub first: u32,
    /// The last frame of the range (rendered if `step` lands on it).
    pub last: u32,
    /// The distance between rendered frames (at least 1).
    pub step: u32,
}

impl FrameRange {
    /// Parses `A-B[:STEP]` (or `A`); a range that ends before it starts, a step of 0 and
    /// anything but digits are errors that say why.
    pub fn parse(text: &str) -> Result<FrameRange, String> {
        let number = |part: &str, what: &str| {
            let part = part.trim();
            if part.is_empty() || !part.bytes().all(|b| b.is_ascii_digit()) {
                return Err(format!(
                    "'{text}': the {what} '{part}' is not a whole number (expected A-B[:STEP], \
                     e.g. 1-250 or 0-100:10)"
                ));
            }
            part.parse::<u32>()
                .map_err(|_| format!("'{text}': the {what} '{part}' is too large"))
        };
        let (range, step) = match text.split_once(':') {
            Some((range, step)) => (range, number(step, "step")?),
            None => (text, 1),
        };
        let (first, last) = match range.split_once('-') {
            Some((a, b)) => (number(a, "first frame")?, number(b, "last frame")?),
            None => {
                let a = number(range, "frame")?;
                (a, a)
            }
        };
        if step == 0 {
            return Err(format!("'{text}': the step must be at least 1"));
        }
        if last < first {
            return Err(format!(
                "'{text}': the last frame {last} comes before the first {first}"
            ));
        }
        Ok(FrameRange { first, last, step })
    }

    /// The frames rendered, in order.
    pub fn frames(&self) -> std::iter::StepBy<std::ops::RangeInclusive<u32>> {
        (self.first..=self.last).step_by(self.step as usize)
    }
}

/// The output file of `frame`: the last run of `#` in the file name replaced by the frame
/// number, zero-padded to the run's length (Blender's convention: `f-####.png`, frame 7 ->
/// `f-0007.png`; a longer number is written whole). Without `#` and with `append`, the
/// number is added, padded to four digits, before the extension (Blender appends it to the
/// path; here the extension picks the format, so it stays last): `f.png` -> `f0007.png`.
pub fn frame_path(pattern: &Path, frame: u32, append: bool) -> PathBuf {
    let Some(name) = pattern
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
    else {
        return pattern.to_path_buf();
    };
    let name = match name.rfind('#') {
        Some(end) => {
            let start = name[..end].trim_end_matches('#').len();
            let width = end + 1 - start;
            format!("{}{frame:0width$}{}", &name[..start], &name[end + 1..])
        }
        None if append => match name.rfind('.').filter(|&dot| dot > 0) {
            Some(dot) => format!("{}{frame:04}{}", &name[..dot], &name[dot..]),
            None => format!("{name}{frame:04}"),
        },
        None => return pattern.to_path_buf(),
    };
    pattern.with_file_name(name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_parse_and_step() {
        let r = FrameRange::parse("0-24").unwrap();
        assert_eq!(r.frames().count(), 25);
        let r = FrameRange::parse("3-10:3").unwrap();
        assert_eq!(r.frames().collect::<Vec<_>>(), [3, 6, 9]);
        assert_eq!(
            FrameRange::parse("7").unwrap().frames().collect::<Vec<_>>(),
            [7]
        );
        for bad in ["5-2", "1-5:0", "a-b", "", "-3-5", "1-", "1-5:x", "1.5-3"] {
            assert!(FrameRange::parse(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn frame_numbers_replace_the_last_hash_run_or_are_appended() {
        let p = |s: &str, f, a| frame_path(Path::new(s), f, a);
        assert_eq!(p("out/f-####.png", 7, true), Path::new("out/f-0007.png"));
        assert_eq!(p("a##/f-##.exr", 123, true), Path::new("a##/f-123.exr"));
        assert_eq!(p("f-#-#.png", 5, true), Path::new("f-#-5.png"));
        assert_eq!(p("f.png", 12, true), Path::new("f0012.png"));
        assert_eq!(p("f", 12, true), Path::new("f0012"));
        assert_eq!(p("f.png", 12, false), Path::new("f.png"));
    }
}
