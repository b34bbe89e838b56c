//! The OBJ reader: reads the file line by line through a `BufReader` (never its whole text)
//! and writes each object/group/`usemtl` run straight into the compact columns of a [`Mesh`]
//! (positions; normals, texture coordinates and vertex colours only when the file has them;
//! `u32` triangles), checking every statement as it goes, so that errors name the line.
//!
//! Our own reader rather than tobj's (tobj still reads the MTL files): tobj has no streaming
//! or memory-bounded mode; it keeps a 104-byte record per face and a map of every distinct
//! vertex until the end of the file, about 200 bytes per face on top of the text.
//!
//! Rules, those of the OBJ format as tobj and Blender read it: a line ending in `\` continues
//! on the next; index 0 is invalid; a negative index counts back from the last element
//! defined above the line; a positive one may refer forward, but not past the file's last
//! element. `l` lines, `p` points and faces of fewer than three vertices are skipped with one
//! warning each. Polygons are cut into ears (`polygons.rs`) as they are read; one referring
//! forward waits until its run's vertices are gathered at the end.
//!
//! This file holds the reader's state and its statements; `reader/faces.rs` reads faces,
//! `reader/gather.rs` ends the read (the runs' columns and the summary warnings).

use crate::error::{Error, Result};
use crate::math::{Vec2, Vec3, Vec4};
use crate::scene::Mesh;
use std::collections::HashMap;
use std::io::BufRead;
use std::path::{Path, PathBuf};

mod faces;
mod gather;

/// A missing `vt` or `vn` index in a corner.
const NONE: u32 = u32::MAX;
/// The `vn` of a corner without one in a face of smoothing group `k` (the file's `k`-th
/// distinct group) is `SMOOTHED + k`: its vertex takes the mean of its faces' normals in that
/// group. Normal indices past the file's last are clamped below it.
const SMOOTHED: u32 = 0xF000_0000;
/// The name of a run before any `o` or `g` (tobj's, which messages and tests know).
const UNNAMED: &str = "unnamed_object";
/// Growth of the large columns below this many bytes is not checked against the memory
/// left (reading /proc for every small vector would cost more than it protects).
const CHECKED_GROWTH: usize = 1 << 20;

/// One object/group/`usemtl` run of the file, ready to become an entity.
pub(super) struct Run {
    /// The `o`/`g` name (`unnamed_object` before any).
    pub name: String,
    /// Index into [`Obj::materials`], `None` without a known `usemtl`.
    pub material: Option<usize>,
    /// The run's own vertices (in order of first use, as tobj numbers them) and triangles.
    pub mesh: Mesh,
    /// `v x y z r g b` colours per vertex (clamped, alpha 1), when the file has colours.
    pub colors: Option<Vec<Vec4>>,
}

/// What [`read`] returns: the runs in file order and the materials of the `mtllib` files.
pub(super) struct Obj {
    pub runs: Vec<Run>,
    pub materials: Vec<tobj::Material>,
    /// The `mtllib` files named, in order, with the error of each one that failed to load.
    pub libraries: Vec<(PathBuf, Option<tobj::LoadError>)>,
}

/// Reads the OBJ file at `path`, loading each `mtllib` through `load_mtl` (given the full
/// path). Warnings about skipped elements go to `warnings`, one per kind.
pub(super) fn read(
    path: &Path,
    load_mtl: impl FnMut(&Path) -> tobj::MTLLoadResult,
    warnings: &mut Vec<String>,
) -> Result<Obj> {
    if path.is_dir() {
        return Err(Error::input(path, None, "is a directory, not a file"));
    }
    let cannot_read = |source| Error::Io {
        path: path.to_path_buf(),
        action: "cannot read",
        source,
    };
    let file = std::fs::File::open(path).map_err(cannot_read)?;
    let mut input = std::io::BufReader::with_capacity(1 << 16, file);
    let dir = path.parent().unwrap_or(Path::new(".")).to_path_buf();
    let mut reader = Reader::new(path, dir, load_mtl);
    let mut bytes = Vec::new();
    let mut logical = String::new();
    let (mut number, mut first) = (0usize, 0usize);
    loop {
        bytes.clear();
        if input.read_until(b'\n', &mut bytes).map_err(cannot_read)? == 0 {
            break;
        }
        number += 1;
        let line = std::str::from_utf8(&bytes).map_err(|_| {
            Error::input(
                path,
                Some(format!("line {number}")),
                "the line is not UTF-8 text",
            )
        })?;
        if logical.is_empty() {
            first = number;
        }
        // `\` at the end continues the statement on the next line (its number is the first's).
        let trimmed = line.trim_end();
        if let Some(kept) = trimmed.strip_suffix('\\') {
            logical.push_str(kept);
            logical.push(' ');
            continue;
        }
        if logical.is_empty() {
            reader.statement(line, number)?;
        } else {
            logical.push_str(line);
            let joined = std::mem::take(&mut logical);
            reader.statement(&joined, first)?;
            logical = joined;
            logical.clear();
        }
    }
    if !logical.is_empty() {
        let joined = std::mem::take(&mut logical);
        reader.statement(&joined, first)?;
    }
    reader.finish(warnings)
}

/// Corners of a run: the global indices of each of its vertices, in order of first use.
enum Corners {
    /// Every corner so far names a position only (`f 1 2 3`): the position is the vertex.
    Positions(Vec<u32>),
    /// Some corner carries `vt` or `vn`: distinct (v, vt, vn) triples are the vertices.
    Triples {
        keys: Vec<[u32; 3]>,
        /// Triple -> local vertex; alive only while its run is read.
        map: HashMap<[u32; 3], u32, FastHash>,
    },
}

impl Corners {
    fn len(&self) -> usize {
        match self {
            Corners::Positions(p) => p.len(),
            Corners::Triples { keys, .. } => keys.len(),
        }
    }

    fn position(&self, local: usize) -> u32 {
        match self {
            Corners::Positions(p) => p[local],
            Corners::Triples { keys, .. } => keys[local][0],
        }
    }
}

/// A polygon that referred to a position not yet defined: cut into ears once the run's
/// vertices are gathered.
struct Deferred {
    line: usize,
    corners: Vec<u32>,
}

/// A run being read.
struct RunBuilder {
    name: String,
    material: Option<usize>,
    /// Whether a face (of three or more vertices) was read: a run without any is not split
    /// off when the name or material changes, as in tobj.
    has_faces: bool,
    triangles: Vec<[u32; 3]>,
    corners: Corners,
    deferred: Vec<Deferred>,
}

impl RunBuilder {
    fn new(name: String, material: Option<usize>) -> Self {
        RunBuilder {
            name,
            material,
            has_faces: false,
            triangles: Vec::new(),
            corners: Corners::Positions(Vec::new()),
            deferred: Vec::new(),
        }
    }
}

/// The reader's state between lines.
struct Reader<'p, L> {
    path: &'p Path,
    dir: PathBuf,
    load_mtl: L,
    positions: Vec<Vec3>,
    /// Per position, once some `v` has colours (white for those without).
    colors: Vec<Vec3>,
    /// Whether some `v` line had no colour while others had (one warning).
    uncoloured: bool,
    texcoords: Vec<Vec2>,
    normals: Vec<Vec3>,
    /// Global position -> the current run's vertex (`NONE` when unused), for
    /// [`Corners::Positions`]; entries are reset when a run ends.
    local_of_position: Vec<u32>,
    /// Positions referred to forward (not yet defined) in the current run -> its vertex.
    forward: HashMap<u32, u32, FastHash>,
    /// The lines of `v` statements that are not finite, with their position index.
    non_finite: Vec<(u32, usize)>,
    /// Largest positive index of each kind (v, vt, vn) and its line, checked at the end.
    largest: [(u64, usize); 3],
    run: RunBuilder,
    done: Vec<RunBuilder>,
    faces: usize,
    /// (count, first line) of skipped `l`, `p` and short faces.
    dropped: [(usize, usize); 3],
    first_usemtl: Option<usize>,
    /// The first `usemtl` without a name (its faces take the default material).
    nameless_usemtl: Option<usize>,
    /// Faces skipped for a bad index: count, and the first one's line and reason.
    bad_faces: (usize, Option<(usize, String)>),
    /// Triangles skipped because they name a position past the file's last.
    missing_position_triangles: usize,
    materials: Vec<tobj::Material>,
    material_names: HashMap<String, usize>,
    libraries: Vec<(PathBuf, Option<tobj::LoadError>)>,
    /// The smoothing group of the faces read now (`s`): `None` for `s off` / `s 0`, else
    /// the marker of its corners without `vn` (see [`SMOOTHED`]).
    smoothing: Option<u32>,
    /// Group number -> marker, for the groups seen so far.
    smoothing_groups: HashMap<String, u32>,
    /// Statements of kinds wavetrace does not read: keyword -> (count, first line).
    ignored: std::collections::BTreeMap<String, (usize, usize)>,
    /// Polygons triangulated as fans (ear clipping failed): count, first line and reason.
    fanned: usize,
    first_fanned: Option<(usize, String)>,
    /// Whether the file had anything but white space.
    content: bool,
    // Scratch for one face, reused.
    face_corners: Vec<[u32; 3]>,
    face: Vec<u32>,
    face_positions: Vec<Vec3>,
    face_polygon: Vec<u32>,
    face_triangles: Vec<[u32; 3]>,
}

impl<'p, L: FnMut(&Path) -> tobj::MTLLoadResult> Reader<'p, L> {
    fn new(path: &'p Path, dir: PathBuf, load_mtl: L) -> Self {
        Reader {
            path,
            dir,
            load_mtl,
            positions: Vec::new(),
            colors: Vec::new(),
            uncoloured: false,
            texcoords: Vec::new(),
            normals: Vec::new(),
            local_of_position: Vec::new(),
            forward: HashMap::default(),
            non_finite: Vec::new(),
            largest: [(0, 0); 3],
            run: RunBuilder::new(UNNAMED.to_string(), None),
            done: Vec::new(),
            faces: 0,
            dropped: [(0, 0); 3],
            first_usemtl: None,
            nameless_usemtl: None,
            bad_faces: (0, None),
            missing_position_triangles: 0,
            materials: Vec::new(),
            material_names: HashMap::new(),
            libraries: Vec::new(),
            smoothing: None,
            smoothing_groups: HashMap::new(),
            ignored: Default::default(),
            fanned: 0,
            first_fanned: None,
            content: false,
            face_corners: Vec::new(),
            face: Vec::new(),
            face_positions: Vec::new(),
            face_polygon: Vec::new(),
            face_triangles: Vec::new(),
        }
    }

    fn error(&self, line: usize, message: impl Into<String>) -> Error {
        Error::input(self.path, Some(format!("line {line}")), message)
    }

    /// Where the reader is, for the errors of [`grow`].
    fn at(&self, line: usize) -> At<'p> {
        At {
            path: self.path,
            line,
            faces: self.faces,
        }
    }

    /// Reads one statement (a line, continuations joined) whose first line is `line`.
    fn statement(&mut self, text: &str, line: usize) -> Result<()> {
        let mut words = text.split_whitespace();
        let Some(keyword) = words.next() else {
            return Ok(());
        };
        self.content = true;
        match keyword {
            "v" => self.vertex(words, line),
            "vt" => {
                let [u, v] = self.numbers(words, "texture coordinate", line)?;
                let at = self.at(line);
                grow(&mut self.texcoords, at)?;
                self.texcoords.push(Vec2::new(u, v));
                Ok(())
            }
            "vn" => {
                let [x, y, z] = self.numbers(words, "normal", line)?;
                let at = self.at(line);
                grow(&mut self.normals, at)?;
                self.normals.push(Vec3::new(x, y, z));
                Ok(())
            }
            "f" => self.face(words, line),
            "l" => {
                self.drop_element(0, line);
                Ok(())
            }
            "p" => {
                self.drop_element(1, line);
                Ok(())
            }
            "o" | "g" => self.name_run(rest_after(text, keyword)),
            "mtllib" => {
                self.material_libraries(rest_after(text, keyword));
                Ok(())
            }
            "s" => self.smoothing_group(rest_after(text, keyword), line),
            "usemtl" => self.use_material(rest_after(text, keyword), line),
            // Comments, and statements that change nothing in a render: grouping for
            // editors, the level of detail, and the per-object flags of ray tracers.
            _ if keyword.starts_with('#') => Ok(()),
            "mg" | "lod" | "shadow_obj" | "trace_obj" => Ok(()),
            _ => {
                self.ignored
                    .entry(keyword.to_string())
                    .or_insert((0, line))
                    .0 += 1;
                Ok(())
            }
        }
    }

    /// `o name` or `g name`: a run with faces ends, else the run is renamed.
    fn name_run(&mut self, name: &str) -> Result<()> {
        let name = if name.is_empty() { UNNAMED } else { name };
        if self.run.has_faces {
            self.end_run(RunBuilder::new(name.to_string(), self.run.material))?;
        } else {
            self.run.name = name.to_string();
        }
        Ok(())
    }

    /// `mtllib`: one name, which may hold spaces (as tobj reads it), if that file exists;
    /// else the names the statement lists (the format allows several).
    fn material_libraries(&mut self, rest: &str) {
        let whole = self.dir.join(rest);
        if whole.is_file() || !rest.contains(char::is_whitespace) {
            self.load_library(whole);
        } else {
            for name in rest.split_whitespace() {
                self.load_library(self.dir.join(name));
            }
        }
    }

    /// `s group`: the smoothing group of the faces that follow (`off`, `0` or nothing: none).
    fn smoothing_group(&mut self, group: &str, line: usize) -> Result<()> {
        self.smoothing = match group {
            "off" | "0" | "" => None,
            group => {
                let next = self.smoothing_groups.len() as u32;
                if next >= NONE - SMOOTHED {
                    return Err(self.error(line, "too many smoothing groups"));
                }
                let k = *self
                    .smoothing_groups
                    .entry(group.to_string())
                    .or_insert(next);
                Some(SMOOTHED + k)
            }
        };
        Ok(())
    }

    /// `usemtl name`: a run with faces ends when the material changes.
    fn use_material(&mut self, name: &str, line: usize) -> Result<()> {
        let material = if name.is_empty() {
            self.nameless_usemtl.get_or_insert(line);
            None
        } else {
            self.first_usemtl.get_or_insert(line);
            self.material_names.get(name).copied()
        };
        if material != self.run.material && self.run.has_faces {
            self.end_run(RunBuilder::new(self.run.name.clone(), material))?;
        } else {
            self.run.material = material;
        }
        Ok(())
    }

    /// Loads the material library at `full`, keeping its error for the summary.
    fn load_library(&mut self, full: PathBuf) {
        match (self.load_mtl)(&full) {
            Ok((materials, names)) => {
                let offset = self.materials.len();
                self.materials.extend(materials);
                for (name, index) in names {
                    self.material_names.insert(name, index + offset);
                }
                self.libraries.push((full, None));
            }
            Err(e) => self.libraries.push((full, Some(e))),
        }
    }

    /// The first `N` numbers of a `vt` or `vn` statement (more are ignored, as by tobj).
    fn numbers<'w, const N: usize>(
        &self,
        words: impl Iterator<Item = &'w str>,
        what: &str,
        line: usize,
    ) -> Result<[f32; N]> {
        let mut out = [0.0; N];
        let mut found = 0;
        for (k, word) in words.take(N).enumerate() {
            out[k] = word
                .parse()
                .map_err(|_| self.error(line, format!("{what}: '{word}' is not a number")))?;
            found += 1;
        }
        if found < N {
            return Err(self.error(line, format!("{what}: {N} numbers needed, found {found}")));
        }
        Ok(out)
    }

    /// `v x y z`, optionally followed by `w` (which divides x, y, z) or by `r g b`.
    fn vertex(&mut self, mut words: std::str::SplitWhitespace, line: usize) -> Result<()> {
        let [x, y, z] = self.numbers(words.by_ref(), "vertex", line)?;
        let rest: Vec<&str> = words.collect();
        let number = |word: &str| {
            word.parse::<f32>()
                .map_err(|_| self.error(line, format!("vertex: '{word}' is not a number")))
        };
        let mut position = Vec3::new(x, y, z);
        let mut color = None;
        match rest[..] {
            [] => {}
            [w] => {
                let w = number(w)?;
                if w == 0.0 {
                    return Err(self.error(line, "vertex: w is 0 (positions are divided by w)"));
                }
                position = Vec3::new(x / w, y / w, z / w);
            }
            [r, g, b] => color = Some(Vec3::new(number(r)?, number(g)?, number(b)?)),
            _ => {
                return Err(self.error(
                    line,
                    format!(
                        "vertex: expected x y z, optionally followed by w or by r g b; found {} \
                         numbers",
                        3 + rest.len()
                    ),
                ));
            }
        }
        let index = self.positions.len();
        if index >= (NONE - 1) as usize {
            return Err(self.error(line, "more than 4 billion vertices"));
        }
        if !position.is_finite() {
            self.non_finite.push((index as u32, line));
        }
        let at = self.at(line);
        grow(&mut self.positions, at)?;
        self.positions.push(position);
        grow(&mut self.local_of_position, at)?;
        self.local_of_position.push(NONE);
        match color {
            Some(c) => {
                if self.colors.len() < index {
                    // Colours start here: the vertices above are white.
                    self.uncoloured |= index > 0;
                    self.colors.resize(index, Vec3::ONE);
                }
                grow(&mut self.colors, at)?;
                self.colors.push(c);
            }
            None if !self.colors.is_empty() => {
                self.uncoloured = true;
                grow(&mut self.colors, at)?;
                self.colors.push(Vec3::ONE);
            }
            None => {}
        }
        Ok(())
    }

    fn drop_element(&mut self, kind: usize, line: usize) {
        let (count, first) = &mut self.dropped[kind];
        *count += 1;
        if *first == 0 {
            *first = line;
        }
    }

    /// Clears the table entries of a run's positions (only those: a table the size of the
    /// file's positions is not swept once per run).
    fn reset_position_table(&mut self, used: &[u32]) {
        for &v in used {
            if let Some(entry) = self.local_of_position.get_mut(v as usize) {
                *entry = NONE;
            }
        }
        self.forward.clear();
    }

    /// Ends the current run (which has faces) and starts `next`.
    fn end_run(&mut self, next: RunBuilder) -> Result<()> {
        let mut run = std::mem::replace(&mut self.run, next);
        match &mut run.corners {
            Corners::Positions(used) => {
                let used = std::mem::take(used);
                self.reset_position_table(&used);
                run.corners = Corners::Positions(used);
            }
            Corners::Triples { map, .. } => *map = HashMap::default(),
        }
        self.done.push(run);
        Ok(())
    }
}

/// Where the reader is: the file, the line and the faces read, for the errors of memory
/// that runs out.
#[derive(Clone, Copy)]
struct At<'p> {
    path: &'p Path,
    line: usize,
    faces: usize,
}

impl At<'_> {
    /// Refuses `bytes` more when the process cannot have them (see [`crate::memory`]).
    fn check_growth(self, bytes: usize) -> Result<()> {
        if bytes < CHECKED_GROWTH {
            return Ok(());
        }
        crate::memory::check_fits(
            self.path,
            &self.what(),
            crate::memory::Needed {
                resident: bytes as u64,
                address_space: bytes as u64,
            },
            crate::memory::available(),
        )
    }

    fn what(self) -> String {
        match self.line {
            0 => format!("gathering the meshes of its {} faces", self.faces),
            line => format!(
                "reading it further (line {line}, {} faces read)",
                self.faces
            ),
        }
    }

    /// The error of an allocation the system refused.
    fn out_of_memory(self, bytes: usize) -> Error {
        Error::input(
            self.path,
            None,
            format!(
                "the scene does not fit in memory: {} needs {:.2} GiB more, which the system \
                 refuses; use a smaller model or fewer copies of it",
                self.what(),
                bytes as f64 / (1u64 << 30) as f64
            ),
        )
    }
}

/// Makes room for one more element in a large column: the growth is checked against the
/// memory the process may still take and reserved fallibly, so that a file too large ends
/// in the loader's error, not an allocation abort.
fn grow<T>(column: &mut Vec<T>, at: At) -> Result<()> {
    if column.len() < column.capacity() {
        return Ok(());
    }
    let extra = column.capacity().max(64);
    let bytes = extra * std::mem::size_of::<T>();
    at.check_growth(bytes)?;
    column
        .try_reserve_exact(extra)
        .map_err(|_| at.out_of_memory(bytes))
}

/// The text of a statement after its keyword, trimmed (names and file names may hold
/// spaces).
fn rest_after<'a>(text: &'a str, keyword: &str) -> &'a str {
    let start = text.trim_start();
    start[keyword.len()..].trim()
}

/// A fast, fixed hash for the small integer keys of the vertex maps (the standard SipHash
/// costs more than the rest of a lookup; nothing here needs protection from chosen keys
/// beyond a slower load).
#[derive(Clone, Copy, Default)]
struct FastHash;

impl std::hash::BuildHasher for FastHash {
    type Hasher = FastHasher;
    fn build_hasher(&self) -> FastHasher {
        FastHasher(0)
    }
}

/// Multiply-rotate hashing of 32-bit words (the Fx hash's scheme).
struct FastHasher(u64);

impl std::hash::Hasher for FastHasher {
    fn write(&mut self, bytes: &[u8]) {
        for chunk in bytes.chunks(4) {
            let mut word = [0u8; 4];
            word[..chunk.len()].copy_from_slice(chunk);
            self.write_u32(u32::from_le_bytes(word));
        }
    }
    fn write_u32(&mut self, word: u32) {
        self.0 = (self.0.rotate_left(5) ^ word as u64).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
    fn write_usize(&mut self, word: usize) {
        self.write_u32(word as u32);
        self.write_u32((word as u64 >> 32) as u32);
    }
    fn finish(&self) -> u64 {
        self.0
    }
}

#[cfg(test)]
mod tests;
