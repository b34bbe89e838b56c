//! OBJ text checks around tobj: the face indices are checked before tobj reads them, and
//! tobj's errors (which give neither a line nor the bad value) are explained afterwards.
//!
//! Why before: tobj 4.0.5 turns a relative index that reaches before the first element into a
//! huge `usize` and multiplies it, which overflows (a panic in debug builds, wrong data in
//! release; found by fuzzing). Checking here also lets every message name the line and value.

use std::borrow::Cow;

/// The OBJ text as tobj should read it, with the same line numbers: a line ending in `\\`
/// continues on the next (joined here, the next left empty); lines (`l`), points (`p`) and faces
/// of fewer than three vertices are blanked, since tobj would drop them silently or make a
/// triangle of `l 1 2 3`. Each kind of dropped element gets one warning; so does `usemtl` in a
/// file that loads no material library. The text itself when nothing changes (most files: no
/// copy of a large file), else one new string.
pub(super) fn preprocess<'a>(
    path: &std::path::Path,
    text: &'a str,
    warnings: &mut Vec<String>,
) -> Cow<'a, str> {
    let summary = rewrite(text, None);
    let out = if summary.changed {
        let mut out = String::with_capacity(text.len() + 1);
        rewrite(text, Some(&mut out));
        Cow::Owned(out)
    } else {
        Cow::Borrowed(text)
    };
    let file = path.display();
    let what = [
        "line elements (l) are not rendered",
        "point elements (p) are not rendered",
        "faces with fewer than 3 vertices are skipped",
    ];
    for (k, (count, line)) in summary.dropped.into_iter().enumerate() {
        if count > 0 {
            warnings.push(format!(
                "{file}: {} ({count}, first at line {line})",
                what[k]
            ));
        }
    }
    if let (Some(line), false) = (summary.usemtl, summary.mtllib) {
        warnings.push(format!(
            "{file}: line {line}: usemtl names a material but the file loads no material \
             library (mtllib); using a default grey"
        ));
    }
    out
}

/// What [`rewrite`] found.
#[derive(Default)]
struct Rewrite {
    /// (count, first line) of each dropped kind: lines, points, short faces.
    dropped: [(usize, usize); 3],
    /// The first `usemtl` line.
    usemtl: Option<usize>,
    /// Whether some `mtllib` line exists.
    mtllib: bool,
    /// Whether the text needs rewriting (a continuation or a dropped element).
    changed: bool,
}

/// Reads `text` line by line as [`preprocess`] describes, writing the rewritten text to `out`
/// if given (a pass without `out` only finds whether a rewrite is needed).
fn rewrite(text: &str, mut out: Option<&mut String>) -> Rewrite {
    let mut found = Rewrite::default();
    let mut lines = text.lines().enumerate().peekable();
    while let Some((first, line)) = lines.next() {
        let mut logical = Cow::Borrowed(line);
        let mut joined = 0;
        while logical.trim_end().ends_with('\\') {
            let kept = logical.trim_end();
            let kept = kept[..kept.len() - 1].to_string();
            found.changed = true;
            logical = match lines.next() {
                Some((_, next)) => {
                    joined += 1;
                    Cow::Owned(format!("{kept} {next}"))
                }
                None => {
                    logical = Cow::Owned(kept);
                    break;
                }
            };
        }
        let mut words = logical.split_whitespace();
        let kind = match words.next() {
            Some("l") => Some(0),
            Some("p") => Some(1),
            Some("f") if matches!(words.clone().count(), 1 | 2) => Some(2),
            Some("mtllib") => {
                found.mtllib = true;
                None
            }
            Some("usemtl") => {
                found.usemtl.get_or_insert(first + 1);
                None
            }
            _ => None,
        };
        if let Some(k) = kind {
            found.changed = true;
            found.dropped[k].0 += 1;
            if found.dropped[k].1 == 0 {
                found.dropped[k].1 = first + 1;
            }
        }
        if let Some(out) = out.as_deref_mut() {
            if kind.is_none() {
                out.push_str(&logical);
            }
            out.push('\n');
            // The lines joined into this one stay, empty, to keep the line numbers.
            for _ in 0..joined {
                out.push('\n');
            }
        }
    }
    found
}

/// The 1-based line of every polygon tobj returns, in file order, or the first bad face index
/// as (line, message). tobj reads `f` and `l` lines alike and, with points and lines ignored,
/// returns those with no index or with three or more (so `l 1 2 3` is a triangle).
///
/// Rules (those of tobj, made explicit): index 0 is invalid; a negative index counts back
/// from the last element defined before the line; a positive one may refer forward but not
/// past the last element of the file; `v/vt/vn` has at most three parts.
pub(super) fn face_lines(text: &str) -> Result<Vec<u32>, (usize, String)> {
    const KINDS: [&str; 3] = ["vertex", "texture coordinate", "normal"];
    const PLURALS: [&str; 3] = ["vertices", "texture coordinates", "normals"];
    let mut counts = [0usize; 3];
    // Largest positive index of each kind, and its line (checked once the totals are known).
    let mut largest = [(0usize, 0usize); 3];
    let mut faces = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let number = i + 1;
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => counts[0] += 1,
            Some("vt") => counts[1] += 1,
            Some("vn") => counts[2] += 1,
            Some("f" | "l") => {
                if !matches!(words.clone().count(), 1 | 2) {
                    faces.push(u32::try_from(number).unwrap_or(u32::MAX));
                }
                for word in words {
                    for (kind, part) in word.split('/').enumerate() {
                        if kind > 2 {
                            return Err((
                                number,
                                format!("face: '{word}' has more than three '/'-separated indices"),
                            ));
                        }
                        if part.is_empty() && kind > 0 {
                            continue; // `v//vn` or `v/vt/`
                        }
                        let Ok(index) = part.parse::<i64>() else {
                            return Err((
                                number,
                                format!("face: '{part}' in '{word}' is not an index"),
                            ));
                        };
                        let what = KINDS[kind];
                        if index == 0 {
                            return Err((
                                number,
                                format!(
                                    "face: {what} index 0 in '{word}' is invalid (OBJ indices \
                                     count from 1, or back from -1)"
                                ),
                            ));
                        }
                        let magnitude = index.unsigned_abs() as usize;
                        if index < 0 && magnitude > counts[kind] {
                            return Err((
                                number,
                                format!(
                                    "face: relative {what} index {index} in '{word}' reaches \
                                     before the first {what} ({} defined above this line)",
                                    counts[kind]
                                ),
                            ));
                        }
                        if index > 0 && magnitude > largest[kind].0 {
                            largest[kind] = (magnitude, number);
                        }
                    }
                }
            }
            _ => {}
        }
    }
    for kind in 0..3 {
        let (index, number) = largest[kind];
        if index > counts[kind] {
            let what = KINDS[kind];
            return Err((
                number,
                format!(
                    "face: {what} index {index} out of range (the file has {} {})",
                    counts[kind],
                    if counts[kind] == 1 {
                        what
                    } else {
                        PLURALS[kind]
                    }
                ),
            ));
        }
    }
    Ok(faces)
}

/// The line tobj's `error` comes from and what is wrong there, for the errors of number
/// syntax and counts (`v`, `vt`, `vn`, `usemtl`); `None` for the others.
pub(super) fn explain(text: &str, error: &tobj::LoadError) -> Option<(usize, String)> {
    use tobj::LoadError as E;
    let (keyword, what, needed) = match error {
        E::PositionParseError | E::ColorParseError | E::ScalingByZeroError => ("v", "vertex", 3),
        E::TexcoordParseError => ("vt", "texture coordinate", 2),
        E::NormalParseError => ("vn", "normal", 3),
        E::MaterialParseError => ("usemtl", "", 0),
        _ => return None,
    };
    for (i, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        if words.next() != Some(keyword) {
            continue;
        }
        let words: Vec<&str> = words.collect();
        let problem = if keyword == "usemtl" {
            words
                .is_empty()
                .then(|| "usemtl needs a material name".to_string())
        } else if let Some(bad) = words
            .iter()
            .take(needed)
            .find(|w| w.parse::<f32>().is_err())
        {
            Some(format!("{what}: '{bad}' is not a number"))
        } else if words.len() < needed {
            Some(format!(
                "{what}: {needed} numbers needed, found {}",
                words.len()
            ))
        } else if keyword == "v" {
            // x y z, then nothing, w (not zero) or r g b
            match &words[3..] {
                [] => None,
                [w] => match w.parse::<f32>() {
                    Err(_) => Some(format!("vertex: '{w}' is not a number")),
                    Ok(0.0) => Some("vertex: w is 0 (positions are divided by w)".to_string()),
                    Ok(_) => None,
                },
                [_, _, _] => None,
                more => Some(format!(
                    "vertex: expected x y z, optionally followed by w or by r g b; found {} \
                     numbers",
                    3 + more.len()
                )),
            }
        } else {
            None
        };
        if let Some(problem) = problem {
            return Some((i + 1, problem));
        }
    }
    None
}

/// The first `v` line whose x, y or z is not finite (`nan`, `inf`, or beyond the f32 range),
/// as (line, message).
pub(super) fn non_finite_vertex(text: &str) -> Option<(usize, String)> {
    text.lines().enumerate().find_map(|(i, line)| {
        let mut words = line.split_whitespace();
        if words.next() != Some("v") {
            return None;
        }
        let xyz: Vec<f32> = words.take(3).filter_map(|w| w.parse().ok()).collect();
        match xyz[..] {
            [x, y, z] if !(x.is_finite() && y.is_finite() && z.is_finite()) => {
                Some((i + 1, format!("vertex ({x}, {y}, {z}) is not finite")))
            }
            _ => None,
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn continuations_lines_and_short_faces_are_preprocessed_with_one_warning_each() {
        let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 \\\n 3\nl 1 2 3\nl 2 3\n\
                    f 1 2\nusemtl x\nf 2 4 3\n";
        let mut warnings = Vec::new();
        let out = preprocess(std::path::Path::new("m.obj"), text, &mut warnings);
        let lines: Vec<&str> = out.lines().collect();
        assert_eq!(lines.len(), text.lines().count(), "line numbers are kept");
        assert_eq!(
            lines[4].split_whitespace().collect::<Vec<_>>(),
            ["f", "1", "2", "3"]
        );
        assert_eq!(lines[5], "");
        assert_eq!(lines[6], "");
        assert_eq!(lines[8], "");
        assert_eq!(lines[10], "f 2 4 3");
        assert_eq!(
            warnings,
            [
                "m.obj: line elements (l) are not rendered (2, first at line 7)",
                "m.obj: faces with fewer than 3 vertices are skipped (1, first at line 9)",
                "m.obj: line 10: usemtl names a material but the file loads no material library \
                 (mtllib); using a default grey",
            ]
        );
        assert_eq!(face_lines(&out).unwrap(), vec![5, 11]);
    }

    #[test]
    fn faces_are_listed_with_their_lines() {
        let text = "v 0 0 0\nv 1 0 0\n\nv 0 1 0\nf 1 2 3\n# c\nf -3 -2 -1\nf 1 2\nl 1 2 3\n";
        assert_eq!(face_lines(text).unwrap(), vec![5, 7, 9]);
    }

    #[test]
    fn bad_face_indices_name_line_and_value() {
        let v = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\n";
        let error = |f: &str| face_lines(&format!("{v}{f}\n")).unwrap_err();
        let (line, message) = error("f 0 1 2");
        assert_eq!(line, 5);
        assert!(
            message.contains("vertex index 0 in '0' is invalid"),
            "{message}"
        );
        let (_, message) = error("f 1 2 4");
        assert!(message.contains("vertex index 4 out of range (the file has 3 vertices)"));
        let (_, message) = error("f -1 -2 -4");
        assert!(message.contains("relative vertex index -4 in '-4' reaches before the first"));
        // tobj 4.0.5 overflowed on this one (fuzzing)
        let (_, message) = error("f 1/-2147483648 2/1 3/1");
        assert!(message.contains("relative texture coordinate index -2147483648"));
        let (_, message) = error("f 1/1/1 2/1 3/1");
        assert!(message.contains("normal index 1 out of range (the file has 0 normals)"));
        let (_, message) = error("f 1 2 three");
        assert!(message.contains("'three' in 'three' is not an index"));
        let (_, message) = error("f 1/1/1/1 2 3");
        assert!(message.contains("more than three"));
        // forward references are allowed, as tobj allows them
        assert!(face_lines("f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n").is_ok());
    }

    #[test]
    fn non_finite_vertices_are_found() {
        let text = "v 0 0 0\nvn nan 0 0\nv 1 0 0\nv 0 1e39 0\nv nan 0 0\n";
        assert_eq!(
            non_finite_vertex(text),
            Some((4, "vertex (0, inf, 0) is not finite".into()))
        );
        assert_eq!(non_finite_vertex("v 0 0 0\n"), None);
    }

    #[test]
    fn number_errors_are_explained() {
        use tobj::LoadError as E;
        let text = "v 0 0 0\nv 1 x 0\nvt 0\nvn 0 0 1e999999\nv 1 2 3 0\nusemtl\n";
        assert_eq!(
            explain(text, &E::PositionParseError),
            Some((2, "vertex: 'x' is not a number".into()))
        );
        assert_eq!(
            explain(text, &E::TexcoordParseError),
            Some((3, "texture coordinate: 2 numbers needed, found 1".into()))
        );
        assert_eq!(
            explain(text, &E::NormalParseError),
            None,
            "1e999999 parses as inf"
        );
        assert_eq!(explain(text, &E::FaceVertexOutOfBounds), None);
        assert_eq!(
            explain("usemtl\n", &E::MaterialParseError),
            Some((1, "usemtl needs a material name".into()))
        );
        assert_eq!(
            explain("v 1 2 3 0\n", &E::ScalingByZeroError),
            Some((1, "vertex: w is 0 (positions are divided by w)".into()))
        );
    }
}
