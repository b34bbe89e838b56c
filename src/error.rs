//! The library's error type. Every variant names the file it is about and, where it is
//! known, the place in it (TOML line and column, glTF node or accessor, OBJ line).

use std::path::{Path, PathBuf};

/// Result alias used across the crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Everything that can go wrong between a scene file and an image file.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file could not be read or written.
    #[error("{}: {action}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What was being done ("cannot read", "cannot write", ...).
        action: &'static str,
        /// The operating system's reason.
        #[source]
        source: std::io::Error,
    },
    /// The content of an input file is wrong.
    #[error("{}{}: {message}", path.display(), location.as_deref().map(|l| format!(":{l}")).unwrap_or_default())]
    Input {
        /// The file.
        path: PathBuf,
        /// Where in the file: "line 3, column 7", "mesh 'Cube' (index 2)", ...
        location: Option<String>,
        /// What is wrong, lowercase, no trailing period.
        message: String,
    },
    /// Settings that cannot be rendered (zero samples, absurd resolution, ...).
    #[error("invalid settings: {0}")]
    Settings(String),
    /// The image could not be encoded.
    #[error("{}: cannot encode image: {message}", path.display())]
    Encode {
        /// The output file.
        path: PathBuf,
        /// The encoder's reason.
        message: String,
    },
}

impl Error {
    /// An input error with an optional location.
    pub fn input(path: &Path, location: Option<String>, message: impl Into<String>) -> Self {
        Error::Input {
            path: path.to_path_buf(),
            location,
            message: message.into(),
        }
    }

    /// An input error at a byte offset of a text file, reported as line and column.
    pub fn input_at(path: &Path, text: &str, offset: usize, message: impl Into<String>) -> Self {
        Error::input(path, Some(line_column(text, offset)), message)
    }
}

/// "line L, column C" (both 1-based) of a byte offset in `text`.
pub fn line_column(text: &str, offset: usize) -> String {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let column = before
        .rfind('\n')
        .map_or(before.len(), |nl| before.len() - nl - 1)
        + 1;
    format!("line {line}, column {column}")
}

/// The candidate closest to a mistyped `word`, if one is close enough to be what was meant
/// (at most one edit per three characters, at least one; case is ignored).
pub fn closest_match<'a>(
    word: &str,
    candidates: impl IntoIterator<Item = &'a str>,
) -> Option<&'a str> {
    let word = word.to_lowercase();
    let allowed = (word.chars().count() / 3).max(1);
    candidates
        .into_iter()
        .map(|c| (strsim::damerau_levenshtein(&word, &c.to_lowercase()), c))
        .filter(|&(distance, _)| distance <= allowed)
        .min_by_key(|&(distance, _)| distance)
        .map(|(_, c)| c)
}

#[cfg(test)]
mod tests {
    #[test]
    fn closest_match_finds_typos_only() {
        let keys = ["eye", "look_at", "up", "vfov"];
        assert_eq!(super::closest_match("vfof", keys), Some("vfov"));
        assert_eq!(super::closest_match("lookat", keys), Some("look_at"));
        assert_eq!(super::closest_match("Eye", keys), Some("eye"));
        assert_eq!(super::closest_match("shutter", keys), None);
        assert_eq!(
            super::closest_match("materails", ["materials", "shape"]),
            Some("materials")
        );
    }

    #[test]
    fn line_column_counts_from_one() {
        let t = "a = 1\nbb = [\n  3]\n";
        assert_eq!(super::line_column(t, 0), "line 1, column 1");
        assert_eq!(super::line_column(t, 6), "line 2, column 1");
        assert_eq!(super::line_column(t, 15), "line 3, column 3");
    }
}
