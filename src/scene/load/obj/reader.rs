//! The OBJ reader: reads the file line by line through a `BufReader` (never its whole text)
//! and writes each object/group/`usemtl` run straight into the compact columns of a [`Mesh`]
//! (positions; normals, texture coordinates and vertex colours only when the file has them;
//! `u32` triangles), checking every statement as it goes, so that errors name the line.
//!
//! Our own reader rather than tobj's (tobj still reads the MTL files): tobj has no streaming
//! or memory-bounded mode; it keeps a 104-byte record per face and a map of every distinct
//! vertex until the end of the file, about 200 bytes per face on top of the text (issue 21).
//!
//! Rules, those of the OBJ format as tobj and Blender read it: a line ending in `\` continues
//! on the next; index 0 is invalid; a negative index counts back from the last element
//! defined above the line; a positive one may refer forward, but not past the file's last
//! element. `l` lines, `p` points and faces of fewer than three vertices are skipped with one
//! warning each. Polygons are cut into ears ([`super::polygons::triangulate_polygon`]) as they are
//! read; one referring forward waits until its run's vertices are gathered at the end.

use crate::error::{Error, Result};
use crate::math::{Vec2, Vec3, Vec4};
use crate::scene::Mesh;
use std::collections::HashMap;
use std::io::BufRead;
use std::path::{Path, PathBuf};

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
            "o" | "g" => {
                let name = rest_after(text, keyword);
                let name = if name.is_empty() { UNNAMED } else { name };
                if self.run.has_faces {
                    self.end_run(RunBuilder::new(name.to_string(), self.run.material))?;
                } else {
                    self.run.name = name.to_string();
                }
                Ok(())
            }
            "mtllib" => {
                // One name, which may hold spaces (as tobj reads it), if that file exists;
                // else the names the statement lists (the format allows several).
                let rest = rest_after(text, keyword);
                let whole = self.dir.join(rest);
                if whole.is_file() || !rest.contains(char::is_whitespace) {
                    self.load_library(whole);
                } else {
                    for name in rest.split_whitespace() {
                        self.load_library(self.dir.join(name));
                    }
                }
                Ok(())
            }
            "s" => {
                let group = rest_after(text, keyword);
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
            "usemtl" => {
                let name = rest_after(text, keyword);
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

    /// `f v1 v2 v3 ...`, each corner `v`, `v/vt`, `v//vn` or `v/vt/vn`.
    fn face(&mut self, words: std::str::SplitWhitespace, line: usize) -> Result<()> {
        if words.clone().take(3).count() < 3 {
            self.drop_element(2, line);
            return Ok(());
        }
        let mut corners = std::mem::take(&mut self.face_corners);
        corners.clear();
        let largest_before = self.largest;
        for word in words {
            match self.corner(word, line) {
                Ok(corner) => corners.push(corner),
                Err(why) => {
                    // One bad face is skipped, not the file.
                    self.largest = largest_before;
                    self.bad_faces.0 += 1;
                    self.bad_faces.1.get_or_insert((line, why));
                    self.face_corners = corners;
                    return Ok(());
                }
            }
        }
        let mut face = std::mem::take(&mut self.face);
        face.clear();
        let mut forward = false;
        for &[v, vt, mut vn] in &corners {
            forward |= v as usize >= self.positions.len();
            if let (NONE, Some(marker)) = (vn, self.smoothing) {
                vn = marker;
            }
            face.push(self.vertex_of(v, vt, vn, line)?);
        }
        self.face_corners = corners;
        self.faces += 1;
        self.run.has_faces = true;
        let result = if face.len() == 3 {
            self.push_triangle([face[0], face[1], face[2]], line)
        } else if forward {
            self.run.deferred.push(Deferred {
                line,
                corners: face.clone(),
            });
            Ok(())
        } else {
            self.polygon(&face, line)
        };
        self.face = face;
        result
    }

    fn push_triangle(&mut self, triangle: [u32; 3], line: usize) -> Result<()> {
        let at = self.at(line);
        grow(&mut self.run.triangles, at)?;
        self.run.triangles.push(triangle);
        Ok(())
    }

    /// Cuts a polygon of the current run (its vertices, all with known positions) into ears.
    fn polygon(&mut self, face: &[u32], line: usize) -> Result<()> {
        self.face_positions.clear();
        self.face_polygon.clear();
        for (k, &local) in face.iter().enumerate() {
            let position = self.run.corners.position(local as usize);
            self.face_positions.push(self.positions[position as usize]);
            self.face_polygon.push(k as u32);
        }
        self.face_triangles.clear();
        if let Err(why) = super::polygons::triangulate_polygon(
            &self.face_positions,
            &self.face_polygon,
            &mut self.face_triangles,
        ) {
            self.fan(&self.face_polygon.clone(), line, why);
        }
        for k in 0..self.face_triangles.len() {
            let [a, b, c] = self.face_triangles[k];
            self.push_triangle([face[a as usize], face[b as usize], face[c as usize]], line)?;
        }
        Ok(())
    }

    /// A twisted or strongly non-planar polygon: a fan from its first vertex covers it
    /// (exactly so for a convex one), though maybe not as its author meant.
    fn fan(&mut self, polygon: &[u32], line: usize, why: String) {
        self.fanned += 1;
        self.first_fanned.get_or_insert((line, why));
        for k in 1..polygon.len() - 1 {
            self.face_triangles
                .push([polygon[0], polygon[k], polygon[k + 1]]);
        }
    }

    /// The (v, vt, vn) indices of a corner, 0-based (`NONE` for a missing vt or vn), or why
    /// it has none. Positive indices past what is defined so far are checked at the end.
    fn corner(&mut self, word: &str, line: usize) -> std::result::Result<[u32; 3], String> {
        const KINDS: [&str; 3] = ["vertex", "texture coordinate", "normal"];
        let counts = [
            self.positions.len(),
            self.texcoords.len(),
            self.normals.len(),
        ];
        let mut out = [NONE; 3];
        for (kind, part) in word.split('/').enumerate() {
            if kind > 2 {
                return Err(format!(
                    "face: '{word}' has more than three '/'-separated indices"
                ));
            }
            if part.is_empty() && kind > 0 {
                continue; // `v//vn` or `v/vt/`
            }
            let Ok(index) = part.parse::<i64>() else {
                return Err(format!("face: '{part}' in '{word}' is not an index"));
            };
            let what = KINDS[kind];
            if index == 0 {
                return Err(format!(
                    "face: {what} index 0 in '{word}' is invalid (OBJ indices count from 1, \
                         or back from -1)"
                ));
            }
            let magnitude = index.unsigned_abs();
            out[kind] = if index < 0 {
                if magnitude > counts[kind] as u64 {
                    return Err(format!(
                        "face: relative {what} index {index} in '{word}' reaches before the \
                             first {what} ({} defined above this line)",
                        counts[kind]
                    ));
                }
                (counts[kind] as u64 - magnitude) as u32
            } else {
                if magnitude > self.largest[kind].0 {
                    self.largest[kind] = (magnitude, line);
                }
                // Past the largest possible count: out of range, found at the end.
                (magnitude - 1).min(SMOOTHED as u64 - 1) as u32
            };
        }
        Ok(out)
    }

    /// The current run's vertex for a corner, added if new.
    fn vertex_of(&mut self, v: u32, vt: u32, vn: u32, line: usize) -> Result<u32> {
        let at = self.at(line);
        if vt == NONE
            && vn == NONE
            && let Corners::Positions(used) = &mut self.run.corners
        {
            // The position is the vertex: a table lookup, no hashing.
            let known = self.local_of_position.get(v as usize).copied();
            if let Some(local) = known.filter(|&l| l != NONE) {
                return Ok(local);
            }
            if let Some(&local) = self.forward.get(&v) {
                return Ok(local);
            }
            let local = used.len() as u32;
            grow(used, at)?;
            used.push(v);
            match known {
                Some(_) => self.local_of_position[v as usize] = local,
                None => {
                    self.forward.insert(v, local);
                }
            }
            return Ok(local);
        }
        if let Corners::Positions(used) = &mut self.run.corners {
            // The first corner with vt or vn: the vertices so far become (v, -, -) triples.
            let used = std::mem::take(used);
            self.reset_position_table(&used);
            let mut map = HashMap::default();
            map.try_reserve(used.len())
                .map_err(|_| at.out_of_memory(used.len() * 16))?;
            let mut keys = Vec::new();
            keys.try_reserve_exact(used.len())
                .map_err(|_| at.out_of_memory(used.len() * 12))?;
            for (local, &v) in used.iter().enumerate() {
                keys.push([v, NONE, NONE]);
                map.insert([v, NONE, NONE], local as u32);
            }
            self.run.corners = Corners::Triples { keys, map };
        }
        let Corners::Triples { keys, map } = &mut self.run.corners else {
            unreachable!("made above")
        };
        let key = [v, vt, vn];
        if let Some(&local) = map.get(&key) {
            return Ok(local);
        }
        let local = keys.len() as u32;
        if map.len() == map.capacity() {
            let extra = map.capacity().max(64);
            // hashbrown's buckets: 16 bytes of entry and one control byte, at most 7/8 full.
            let bytes = extra * 17 * 8 / 7;
            at.check_growth(bytes)?;
            map.try_reserve(extra)
                .map_err(|_| at.out_of_memory(bytes))?;
        }
        grow(keys, at)?;
        keys.push(key);
        map.insert(key, local);
        Ok(local)
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

    /// Drops from a run the vertices whose position index is past the file's last, with the
    /// triangles and deferred polygons that use them (counted in
    /// `missing_position_triangles`); the run's vertices are renumbered in order.
    fn drop_missing_positions(
        &mut self,
        corners: Corners,
        triangles: &mut Vec<[u32; 3]>,
        deferred: Vec<Deferred>,
    ) -> (Corners, Vec<Deferred>) {
        let count = self.positions.len();
        let exists = |k: usize| (corners.position(k) as usize) < count;
        if (0..corners.len()).all(exists) {
            return (corners, deferred);
        }
        let mut renumbered = vec![NONE; corners.len()];
        let mut next = 0;
        for (k, slot) in renumbered.iter_mut().enumerate() {
            if exists(k) {
                *slot = next;
                next += 1;
            }
        }
        let before = triangles.len();
        triangles.retain(|t| t.iter().all(|&c| renumbered[c as usize] != NONE));
        self.missing_position_triangles += before - triangles.len();
        for t in triangles.iter_mut() {
            *t = t.map(|c| renumbered[c as usize]);
        }
        let deferred = deferred
            .into_iter()
            .filter_map(|mut polygon| {
                if polygon
                    .corners
                    .iter()
                    .any(|&c| renumbered[c as usize] == NONE)
                {
                    self.missing_position_triangles += polygon.corners.len() - 2;
                    return None;
                }
                for c in &mut polygon.corners {
                    *c = renumbered[*c as usize];
                }
                Some(polygon)
            })
            .collect();
        let corners = match corners {
            Corners::Positions(used) => {
                Corners::Positions(used.into_iter().filter(|&v| (v as usize) < count).collect())
            }
            Corners::Triples { keys, .. } => Corners::Triples {
                keys: keys
                    .into_iter()
                    .filter(|k| (k[0] as usize) < count)
                    .collect(),
                map: HashMap::default(),
            },
        };
        (corners, deferred)
    }

    /// Checks the indices against the file's counts, gathers every run's columns and says
    /// what was skipped.
    fn finish(mut self, warnings: &mut Vec<String>) -> Result<Obj> {
        if !self.content {
            return Err(Error::input(self.path, None, "file is empty"));
        }
        // Indices past the file's last element: faces naming a missing position are skipped
        // (in `gather`); a missing texture coordinate or normal drops that column from the
        // objects that name it.
        const KINDS: [&str; 3] = ["vertex", "texture coordinate", "normal"];
        const PLURALS: [&str; 3] = ["vertices", "texture coordinates", "normals"];
        const CONSEQUENCES: [&str; 3] = [
            "",
            "the objects that name one render without texture coordinates",
            "the objects that name one render with the triangles' own normals",
        ];
        let counts = [
            self.positions.len(),
            self.texcoords.len(),
            self.normals.len(),
        ];
        let mut out_of_range: [Option<String>; 3] = [None, None, None];
        for kind in 0..3 {
            let (index, line) = self.largest[kind];
            if index > counts[kind] as u64 {
                let what = KINDS[kind];
                let plural = if counts[kind] == 1 {
                    what
                } else {
                    PLURALS[kind]
                };
                out_of_range[kind] = Some(format!(
                    "line {line} names {what} {index}, and the file has {} {plural}",
                    counts[kind]
                ));
            }
        }
        let file = self.path.display().to_string();
        for kind in 1..3 {
            if let Some(why) = &out_of_range[kind] {
                warnings.push(format!(
                    "{file}: {} indices past the file's last are ignored ({why}); {}",
                    KINDS[kind], CONSEQUENCES[kind]
                ));
            }
        }
        // The last run, or tobj's one empty run of a file without faces.
        if self.run.has_faces || self.done.is_empty() {
            let last = RunBuilder::new(String::new(), None);
            self.end_run(last)?;
        }
        self.local_of_position = Vec::new();
        self.forward = HashMap::default();
        let what = [
            "line elements (l) are not rendered",
            "point elements (p) are not rendered",
            "faces with fewer than 3 vertices are skipped",
        ];
        for (k, &(count, line)) in self.dropped.iter().enumerate() {
            if count > 0 {
                warnings.push(format!(
                    "{file}: {} ({count}, first at line {line})",
                    what[k]
                ));
            }
        }
        if !self.ignored.is_empty() {
            let list: Vec<String> = self
                .ignored
                .iter()
                .map(|(keyword, (count, line))| {
                    format!("{keyword} ({count}, first at line {line})")
                })
                .collect();
            warnings.push(format!(
                "{file}: statements wavetrace does not read are ignored: {}",
                list.join(", ")
            ));
        }
        if let Some((line, why)) = &self.bad_faces.1 {
            let count = self.bad_faces.0;
            warnings.push(format!(
                "{file}: faces with a bad index are skipped ({count}, first at line {line}: {why})"
            ));
        }
        if let Some(line) = self.nameless_usemtl {
            warnings.push(format!(
                "{file}: line {line}: usemtl without a material name; its faces use a default grey"
            ));
        }
        if let (Some(line), true) = (self.first_usemtl, self.libraries.is_empty()) {
            warnings.push(format!(
                "{file}: line {line}: usemtl names a material but the file loads no material \
                 library (mtllib); using a default grey"
            ));
        }
        if self.uncoloured {
            warnings.push(format!(
                "{file}: some vertices have colours (v x y z r g b) and others not; those \
                 without are white"
            ));
        }
        let builders = std::mem::take(&mut self.done);
        let mut runs = Vec::with_capacity(builders.len());
        for builder in builders {
            runs.push(self.gather(builder)?);
        }
        if let (Some(why), true) = (&out_of_range[0], self.missing_position_triangles > 0) {
            let count = self.missing_position_triangles;
            warnings.push(format!(
                "{file}: faces naming a vertex past the file's last are skipped ({count} \
                 triangle{}; {why})",
                if count == 1 { "" } else { "s" }
            ));
        }
        if let Some((line, why)) = self.first_fanned.take() {
            let fanned = self.fanned;
            warnings.push(format!(
                "{file}: {fanned} polygon{} could not be cut into ears and {} triangulated as a \
                 fan, which may be wrong (first, line {line}: {why})",
                if fanned == 1 { "" } else { "s" },
                if fanned == 1 { "was" } else { "were" },
            ));
        }
        Ok(Obj {
            runs,
            materials: self.materials,
            libraries: self.libraries,
        })
    }

    /// A run's columns from the file's: its vertices in order of first use.
    fn gather(&mut self, builder: RunBuilder) -> Result<Run> {
        let RunBuilder {
            name,
            material,
            mut triangles,
            corners,
            deferred,
            ..
        } = builder;
        let (corners, deferred) = self.drop_missing_positions(corners, &mut triangles, deferred);
        let n = corners.len();
        let positions: Vec<Vec3> = collect_fallibly(self.at(0), n, |k| {
            self.positions[corners.position(k) as usize]
        })?;
        if let Some(bad) = positions.iter().position(|p| !p.is_finite()) {
            let global = corners.position(bad);
            let line = self
                .non_finite
                .iter()
                .find(|&&(index, _)| index == global)
                .map_or(0, |&(_, line)| line);
            let p = positions[bad];
            return Err(self.error(
                line,
                format!("vertex ({}, {}, {}) is not finite", p.x, p.y, p.z),
            ));
        }
        let mut smoothed = false;
        let (mut normals, uvs) = match &corners {
            Corners::Positions(_) => (Vec::new(), Vec::new()),
            Corners::Triples { keys, .. } => {
                smoothed = keys.iter().any(|k| is_smoothed(k[2]));
                // A column only when every vertex has a normal or is smoothed (below), as
                // before (tobj's shorter columns were dropped); a vertex of a face outside
                // any smoothing group then has none, and its triangles shade flat.
                let normals =
                    if smoothed || keys.iter().all(|k| (k[2] as usize) < self.normals.len()) {
                        collect_fallibly(self.at(0), n, |k| {
                            self.normals
                                .get(keys[k][2] as usize)
                                .copied()
                                .unwrap_or(Vec3::ZERO)
                        })?
                    } else {
                        Vec::new()
                    };
                // OBJ's v runs up the image; wavetrace's (glTF's) runs down.
                let uvs = if keys.iter().all(|k| (k[1] as usize) < self.texcoords.len()) {
                    collect_fallibly(self.at(0), n, |k| {
                        let t = self.texcoords[keys[k][1] as usize];
                        Vec2::new(t.x, 1.0 - t.y)
                    })?
                } else {
                    Vec::new()
                };
                (normals, uvs)
            }
        };
        let colors = if self.colors.is_empty() {
            None
        } else {
            Some(collect_fallibly(self.at(0), n, |k| {
                self.colors[corners.position(k) as usize]
                    .clamp(Vec3::ZERO, Vec3::ONE)
                    .extend(1.0)
            })?)
        };
        for polygon in deferred {
            self.face_triangles.clear();
            let identity: Vec<u32> = (0..polygon.corners.len() as u32).collect();
            let corner_positions: Vec<Vec3> = polygon
                .corners
                .iter()
                .map(|&local| positions[local as usize])
                .collect();
            if let Err(why) = super::polygons::triangulate_polygon(
                &corner_positions,
                &identity,
                &mut self.face_triangles,
            ) {
                self.fan(&identity, polygon.line, why);
            }
            for &[a, b, c] in &self.face_triangles {
                let corner = |k: u32| polygon.corners[k as usize];
                triangles.push([corner(a), corner(b), corner(c)]);
            }
        }
        if let (true, Corners::Triples { keys, .. }) = (smoothed, &corners) {
            smooth_normals(&positions, &triangles, keys, &mut normals);
        }
        drop(corners);
        triangles.shrink_to_fit();
        Ok(Run {
            name,
            material,
            mesh: Mesh {
                positions,
                normals,
                uvs,
                indices: triangles,
            },
            colors,
        })
    }
}

/// Whether a corner's `vn` is a smoothing group's marker (see [`SMOOTHED`]).
fn is_smoothed(vn: u32) -> bool {
    (SMOOTHED..NONE).contains(&vn)
}

/// The normals of the smoothed vertices (whose key names a smoothing group, and whose entry
/// in `normals` is zero): the mean of their triangles' normals weighted by the triangle's
/// angle at the vertex, as Blender and Mitsuba compute vertex normals, so that a vertex's
/// normal does not depend on how its faces were cut into triangles. Each vertex is one
/// group's (the group is in its key), so the faces of other groups meet it along a crease.
///
/// Where the normals cancel, the vertex is on a two-sided sheet (each face also there with
/// the opposite winding, as some exporters write thin surfaces): its normal is then the mean
/// with each face's normal turned toward the first's, a normal of the sheet up to its sign,
/// which the flattening turns to each triangle's side.
fn smooth_normals(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    keys: &[[u32; 3]],
    normals: &mut [Vec3],
) {
    // Per smoothed vertex: the sum of its weights, to tell a cancelled mean.
    let mut weights = vec![0.0f32; normals.len()];
    let accumulate = |normals: &mut [Vec3], weights: &mut [f32], orient: bool| {
        for triangle in triangles {
            let p = triangle.map(|c| positions[c as usize]);
            let normal = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
            for k in 0..3 {
                let corner = triangle[k] as usize;
                let wanted = if orient {
                    weights[corner] < 0.0
                } else {
                    is_smoothed(keys[corner][2])
                };
                if wanted {
                    let along = |other: usize| (p[other] - p[k]).normalize_or_zero();
                    let angle = along((k + 1) % 3)
                        .dot(along((k + 2) % 3))
                        .clamp(-1.0, 1.0)
                        .acos();
                    let sign = if normals[corner].dot(normal) < 0.0 && orient {
                        -1.0
                    } else {
                        1.0
                    };
                    normals[corner] += sign * angle * normal;
                    if !orient {
                        weights[corner] += angle;
                    }
                }
            }
        }
    };
    accumulate(normals, &mut weights, false);
    let mut cancelled = false;
    for (normal, weight) in normals.iter_mut().zip(&mut weights) {
        if *weight > 0.0 && normal.length() < 1e-3 * *weight {
            // Marked by a negative weight for the second pass.
            *normal = Vec3::ZERO;
            *weight = -1.0;
            cancelled = true;
        }
    }
    if cancelled {
        accumulate(normals, &mut weights, true);
    }
    for (normal, key) in normals.iter_mut().zip(keys) {
        if is_smoothed(key[2]) {
            // Zero when the vertex's triangles are all degenerate: they shade flat.
            *normal = normal.normalize_or_zero();
        }
    }
}

/// `n` values of `value(k)`, allocated fallibly.
fn collect_fallibly<T>(at: At, n: usize, value: impl Fn(usize) -> T) -> Result<Vec<T>> {
    let bytes = n * std::mem::size_of::<T>();
    at.check_growth(bytes)?;
    let mut out = Vec::new();
    out.try_reserve_exact(n)
        .map_err(|_| at.out_of_memory(bytes))?;
    out.extend((0..n).map(value));
    Ok(out)
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
mod tests {
    use super::*;

    /// Reads `text` as `m.obj` (no material library can load), with its warnings.
    fn read_text(text: &str) -> Result<(Obj, Vec<String>)> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.obj");
        std::fs::write(&path, text).unwrap();
        let mut warnings = Vec::new();
        let obj = read(
            &path,
            |_| Err(tobj::LoadError::OpenFileFailed),
            &mut warnings,
        )?;
        // Warnings name the file by its full path: keep the name only.
        let prefix = format!("{}: ", path.display());
        let warnings = warnings
            .iter()
            .map(|w| w.replace(&prefix, "m.obj: "))
            .collect();
        Ok((obj, warnings))
    }

    fn error(text: &str) -> String {
        match read_text(text) {
            Ok(_) => panic!("{text:?} loaded"),
            Err(e) => e.to_string(),
        }
    }

    const SQUARE: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
                          vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\nvn 0 0 -1\n";

    #[test]
    fn indices_of_every_form_name_the_same_vertices() {
        // Positive, negative (relative to the lines above), and the forms v/vt, v//vn, v/vt/vn.
        for face in [
            "f 1/1/1 2/2/1 3/3/1",
            "f -4/-4/-2 -3/-3/-2 -2/-2/-2",
            "f 1/1/1 -3/2/-2 3/-2/1",
        ] {
            let (obj, warnings) = read_text(&format!("{SQUARE}{face}\n")).unwrap();
            assert!(warnings.is_empty(), "{warnings:?}");
            let mesh = &obj.runs[0].mesh;
            assert_eq!(mesh.indices, [[0, 1, 2]], "{face}");
            assert_eq!(
                mesh.positions,
                [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0)]
            );
            // v is flipped: OBJ's runs up the image.
            let uvs = [
                Vec2::new(0.0, 1.0),
                Vec2::new(1.0, 1.0),
                Vec2::new(1.0, 0.0),
            ];
            assert_eq!(mesh.uvs, uvs, "{face}");
            assert_eq!(mesh.normals, [Vec3::Z; 3], "{face}");
        }
        let (obj, _) = read_text(&format!("{SQUARE}f 1//2 2//2 3//2\n")).unwrap();
        let mesh = &obj.runs[0].mesh;
        assert_eq!((mesh.normals.len(), mesh.uvs.len()), (3, 0));
        assert_eq!(mesh.normals[0], Vec3::NEG_Z);
        let (obj, _) = read_text(&format!("{SQUARE}f 1/4 2/3 3/2\n")).unwrap();
        let mesh = &obj.runs[0].mesh;
        assert_eq!((mesh.normals.len(), mesh.uvs.len()), (0, 3));
        assert_eq!(mesh.uvs[0], Vec2::new(0.0, 0.0));
    }

    #[test]
    fn vertices_are_shared_within_a_run_and_split_by_their_attributes() {
        // A quad of two triangles sharing two positions: 4 vertices, in order of first use.
        let (obj, _) = read_text(&format!("{SQUARE}f 3 1 2\nf 1 3 4\n")).unwrap();
        let mesh = &obj.runs[0].mesh;
        assert_eq!(mesh.indices, [[0, 1, 2], [1, 0, 3]]);
        assert_eq!(mesh.positions[0], Vec3::new(1.0, 1.0, 0.0));
        assert_eq!(mesh.positions.len(), 4);
        // The same position with two normals is two vertices; a corner without vt or vn
        // after some with them is a vertex of its own, and the run keeps no partial column.
        let (obj, _) = read_text(&format!("{SQUARE}f 1 2 3\nf 1//1 3//2 4//1\n")).unwrap();
        let mesh = &obj.runs[0].mesh;
        assert_eq!(mesh.indices, [[0, 1, 2], [3, 4, 5]]);
        assert_eq!(mesh.positions.len(), 6);
        assert!(mesh.normals.is_empty(), "vertices 0 to 2 have no normal");
        let (obj, _) = read_text(&format!("{SQUARE}f 1//1 2//1 3//1\nf 1//1 3//1 4//2\n")).unwrap();
        let mesh = &obj.runs[0].mesh;
        assert_eq!(mesh.indices, [[0, 1, 2], [0, 2, 3]]);
        assert_eq!(mesh.normals[3], Vec3::NEG_Z);
    }

    #[test]
    fn objects_groups_and_materials_make_runs_with_their_own_vertices() {
        let text = format!(
            "{SQUARE}usemtl red\nf 1 2 3\ng wall\nf 3 4 1\nusemtl blue\nusemtl red\nf 4 1 2\n\
             usemtl blue\nf 4 2 3\no\ng floor  tiles \no empty\n"
        );
        let (obj, warnings) = read_text(&text).unwrap();
        let runs: Vec<(&str, usize, usize)> = obj
            .runs
            .iter()
            .map(|r| {
                (
                    r.name.as_str(),
                    r.mesh.positions.len(),
                    r.mesh.indices.len(),
                )
            })
            .collect();
        // `usemtl` names no known material here (no library): every run has `None`, so a
        // change of name splits nothing; `g wall` does. A run without faces is no entity.
        assert_eq!(runs, [("unnamed_object", 3, 1), ("wall", 4, 3)]);
        assert!(obj.runs.iter().all(|r| r.material.is_none()));
        // Run-local vertices: `wall` numbers its own from 0 in order of first use.
        assert_eq!(obj.runs[1].mesh.indices, [[0, 1, 2], [1, 2, 3], [1, 3, 0]]);
        assert_eq!(obj.runs[1].mesh.positions[0], Vec3::new(1.0, 1.0, 0.0));
        assert_eq!(
            warnings,
            [
                "m.obj: line 11: usemtl names a material but the file loads no material library \
              (mtllib); using a default grey"
            ]
        );
        // A file without faces is one empty run (tobj's behaviour), not an error here.
        let (obj, _) = read_text("v 0 0 0\n").unwrap();
        assert_eq!(obj.runs.len(), 1);
        assert!(obj.runs[0].mesh.indices.is_empty());
    }

    #[test]
    fn materials_split_runs_when_they_change() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.obj");
        std::fs::write(
            &path,
            format!(
                "mtllib a.mtl\n{SQUARE}f 1 2 3\nusemtl red\nusemtl red\nf 1 2 3\n\
                 usemtl blue\nusemtl gone\nf 1 2 3\ng x\nusemtl blue\nf 1 2 3\n"
            ),
        )
        .unwrap();
        let library = "newmtl red\nKd 1 0 0\nnewmtl blue\nKd 0 0 1\n";
        let mut warnings = Vec::new();
        let obj = read(
            &path,
            |p| {
                assert_eq!(p, dir.path().join("a.mtl"));
                tobj::load_mtl_buf(&mut library.as_bytes())
            },
            &mut warnings,
        )
        .unwrap();
        let runs: Vec<(&str, Option<usize>)> = obj
            .runs
            .iter()
            .map(|r| (r.name.as_str(), r.material))
            .collect();
        assert_eq!(
            runs,
            [
                ("unnamed_object", None),
                ("unnamed_object", Some(0)),
                ("unnamed_object", None),
                ("x", Some(1)),
            ]
        );
        assert_eq!(obj.materials.len(), 2);
        assert!(warnings.is_empty(), "{warnings:?}");
    }

    /// A roof: two unit squares meeting at a right angle along the edge x = 0 (vertices 1, 2),
    /// one sloping down to +x, one to -x, with `head` before the first face and `middle`
    /// between the two.
    fn roof(head: &str, middle: &str) -> Obj {
        let text = format!(
            "v 0 0 1\nv 0 1 1\nv 1 0 0\nv 1 1 0\nv -1 0 0\nv -1 1 0\n\
             {head}f 1 3 4 2\n{middle}f 1 2 6 5\n"
        );
        let (obj, warnings) = read_text(&text).unwrap();
        assert!(warnings.is_empty(), "{warnings:?}");
        obj
    }

    #[test]
    fn smoothing_groups_give_faces_without_normals_smooth_vertex_normals() {
        // Without `s` (or with `s off`) the faces shade flat: no normal column.
        for head in ["", "s off\n", "s 0\n"] {
            let obj = roof(head, "");
            assert!(obj.runs[0].mesh.normals.is_empty(), "{head:?}");
            assert_eq!(obj.runs[0].mesh.positions.len(), 6);
        }
        // One group: the ridge's two vertices are shared and take the mean normal, straight
        // up; each eave keeps its own face's normal. The squares' two triangles each would
        // count twice at a corner where the square is cut, once elsewhere, if the triangles
        // were weighted alike: the angles weigh them as the square's one face.
        let obj = roof("s 1\n", "");
        let mesh = &obj.runs[0].mesh;
        assert_eq!(mesh.positions.len(), 6);
        let h = std::f32::consts::FRAC_1_SQRT_2;
        // The smooth roof's normal at a vertex: up on the ridge, the slope's at the eaves.
        let smooth = |position: &Vec3| match position.x {
            0.0 => Vec3::Z,
            x if x > 0.0 => Vec3::new(h, 0.0, h),
            _ => Vec3::new(-h, 0.0, h),
        };
        for (position, normal) in mesh.positions.iter().zip(&mesh.normals) {
            let expected = smooth(position);
            assert!(
                (*normal - expected).length() < 1e-6,
                "{position}: {normal} against {expected}"
            );
        }
        // Two groups: the ridge is a crease, its vertices split, each with its face's normal.
        let obj = roof("s 1\n", "s 2\n");
        let mesh = &obj.runs[0].mesh;
        assert_eq!(mesh.positions.len(), 8);
        for (k, normal) in mesh.normals.iter().enumerate() {
            let side = if k < 4 { h } else { -h };
            assert!(
                (*normal - Vec3::new(side, 0.0, h)).length() < 1e-6,
                "{k}: {normal}"
            );
        }
        // A group and a flat face: the flat face's own vertices have no normal (zero: the
        // flattening shades their triangles flat); the ridge splits.
        let obj = roof("s 1\n", "s off\n");
        let mesh = &obj.runs[0].mesh;
        assert_eq!(mesh.positions.len(), 8);
        assert!(
            mesh.normals[..4]
                .iter()
                .all(|n| (*n - Vec3::new(h, 0.0, h)).length() < 1e-6)
        );
        assert!(mesh.normals[4..].iter().all(|n| *n == Vec3::ZERO));
        // A two-sided roof (each face again with the opposite winding, sharing its
        // vertices): the normals cancel, and the sheet's normal is taken up to its sign.
        let obj = roof("s 1\nf 2 4 3 1\n", "f 5 6 2 1\n");
        let mesh = &obj.runs[0].mesh;
        assert_eq!(mesh.positions.len(), 6);
        for (position, normal) in mesh.positions.iter().zip(&mesh.normals) {
            let expected = smooth(position);
            assert!(
                (normal.dot(expected).abs() - 1.0).abs() < 1e-6,
                "{position}: {normal} against {expected}"
            );
        }
        // Faces with their own normals keep them whatever the group.
        let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 1 0\ns 1\nf 1//1 2//1 3//1\n";
        let (obj, _) = read_text(text).unwrap();
        assert_eq!(obj.runs[0].mesh.normals, [Vec3::Y; 3]);
    }

    #[test]
    fn statements_not_read_are_named_in_one_warning() {
        let text = "# a comment\ncstype bspline\ndeg 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n\
                    curv 0 1 1 2 3\nmg 1\nf 1 2 3\nbevel off\ncurv 0 1 3 2 1\n";
        let (obj, warnings) = read_text(text).unwrap();
        assert_eq!(obj.runs[0].mesh.indices.len(), 1);
        assert_eq!(
            warnings,
            [
                "m.obj: statements wavetrace does not read are ignored: bevel (1, first at line \
              10), cstype (1, first at line 2), curv (2, first at line 7), deg (1, first at \
              line 3)"
            ]
        );
    }

    #[test]
    fn mtllib_reads_a_name_with_spaces_if_that_file_exists_else_each_name() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.obj");
        std::fs::write(dir.path().join("my lib.mtl"), "").unwrap();
        let libraries = |statement: &str| {
            std::fs::write(&path, format!("{statement}\n{SQUARE}f 1 2 3\n")).unwrap();
            let mut asked = Vec::new();
            read(
                &path,
                |p| {
                    asked.push(p.file_name().unwrap().to_string_lossy().into_owned());
                    tobj::load_mtl_buf(&mut "".as_bytes())
                },
                &mut Vec::new(),
            )
            .unwrap();
            asked
        };
        assert_eq!(libraries("mtllib my lib.mtl"), ["my lib.mtl"]);
        assert_eq!(libraries("mtllib a.mtl  b.mtl"), ["a.mtl", "b.mtl"]);
        assert_eq!(libraries("mtllib one.mtl"), ["one.mtl"]);
    }

    #[test]
    fn continuations_lines_points_and_short_faces_with_one_warning_each() {
        let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 \\\n 3\nl 1 2 3\nl 2 3\n\
                    f 1 2\np 1\nf\nf 2 \\\n4 \\\n  3\nf 1 2 bad\n";
        let (_, warnings) = read_text(text).unwrap();
        assert_eq!(
            warnings.last().unwrap(),
            "m.obj: faces with a bad index are skipped (1, first at line 15: face: 'bad' in \
             'bad' is not an index)"
        );
        let text = text.replace("f 1 2 bad\n", "");
        let (obj, warnings) = read_text(&text).unwrap();
        assert_eq!(obj.runs[0].mesh.indices, [[0, 1, 2], [1, 3, 2]]);
        assert_eq!(
            warnings,
            [
                "m.obj: line elements (l) are not rendered (2, first at line 7)",
                "m.obj: point elements (p) are not rendered (1, first at line 10)",
                "m.obj: faces with fewer than 3 vertices are skipped (2, first at line 9)",
            ]
        );
    }

    #[test]
    fn polygons_are_cut_into_ears_also_when_they_refer_forward() {
        // An L shape (area 3), once with its vertices above, once with them below the face.
        let vertices = "v 0 0 0\nv 2 0 0\nv 2 1 0\nv 1 1 0\nv 1 2 0\nv 0 2 0\n";
        let face = "f 1 2 3 4 5 6\n";
        let (above, _) = read_text(&format!("{vertices}{face}")).unwrap();
        let (below, _) = read_text(&format!("{face}{vertices}")).unwrap();
        let mut expected = Vec::new();
        let polygon: Vec<u32> = (0..6).collect();
        let positions = &above.runs[0].mesh.positions;
        super::super::polygons::triangulate_polygon(positions, &polygon, &mut expected).unwrap();
        assert_eq!(expected.len(), 4);
        assert_eq!(above.runs[0].mesh.indices, expected);
        assert_eq!(below.runs[0].mesh.indices, expected);
        assert_eq!(below.runs[0].mesh.positions, *positions);
        // A forward triangle, and one past the end of the file.
        let (obj, _) = read_text("f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n").unwrap();
        assert_eq!(obj.runs[0].mesh.positions[2], Vec3::Y);
        let (obj, warnings) = read_text("f 1 2 4\nf 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n").unwrap();
        assert_eq!(obj.runs[0].mesh.indices.len(), 1);
        assert_eq!(obj.runs[0].mesh.positions.len(), 3);
        assert_eq!(
            warnings,
            [
                "m.obj: faces naming a vertex past the file's last are skipped (1 triangle; line 1 \
              names vertex 4, and the file has 3 vertices)"
            ]
        );
    }

    /// One bad face is skipped with a warning naming the first; a texture coordinate or
    /// normal index past the file's last drops that column from its object (trimesh's
    /// `cubevt.obj` names `vt` it does not have); a nameless `usemtl` (Rhino's
    /// `wallhole.obj`) takes the default material.
    #[test]
    fn bad_indices_skip_their_faces_and_name_line_and_value() {
        let v = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\n";
        let good = "f 1 2 3\n";
        let skipped = |f: &str| {
            let (obj, warnings) = read_text(&format!("{v}{good}{f}\n")).unwrap();
            let triangles: Vec<usize> = obj.runs.iter().map(|r| r.mesh.indices.len()).collect();
            assert_eq!(triangles, [1], "{f}: {warnings:?}");
            assert_eq!(warnings.len(), 1, "{warnings:?}");
            warnings[0].clone()
        };
        let w = skipped("f 0 1 2");
        assert!(
            w.starts_with("m.obj: faces with a bad index are skipped (1, first at line 7: face: vertex index 0 in '0' is invalid"),
            "{w}"
        );
        let w = skipped("f 1 2 5");
        assert_eq!(
            w,
            "m.obj: faces naming a vertex past the file's last are skipped (1 triangle; line 7 \
             names vertex 5, and the file has 4 vertices)"
        );
        let w = skipped("f 2 3 4 9");
        assert!(w.contains("(2 triangles; line 7 names vertex 9"), "{w}");
        let w = skipped("f -1 -2 -5");
        assert!(w.contains("relative vertex index -5 in '-5' reaches before the first vertex (4 defined above this line)"), "{w}");
        let w = skipped("f 1/-2147483648 2/1 3/1");
        assert!(
            w.contains("relative texture coordinate index -2147483648"),
            "{w}"
        );
        let w = skipped("f 1/1/1/1 2 3");
        assert!(w.contains("more than three"), "{w}");
        let w = skipped("f /1 2 3");
        assert!(w.contains("face: '' in '/1' is not an index"), "{w}");
        // Two bad faces: one warning that counts them.
        let (_, warnings) = read_text(&format!("{v}{good}f 0 1 2\nf x 1 2\n")).unwrap();
        assert_eq!(warnings.len(), 1);
        assert!(
            warnings[0].contains("skipped (2, first at line 7"),
            "{warnings:?}"
        );

        // Attribute indices past the last: the face stays, its object loses the column.
        let (obj, warnings) = read_text(&format!("{v}f 1/1/1 2/1/1 3/1/1\n")).unwrap();
        let mesh = &obj.runs[0].mesh;
        assert_eq!(mesh.indices.len(), 1);
        assert!(mesh.normals.is_empty());
        assert_eq!(mesh.uvs.len(), 3, "the texture coordinates are kept");
        assert_eq!(
            warnings,
            [
                "m.obj: normal indices past the file's last are ignored (line 6 names normal 1, \
              and the file has 0 normals); the objects that name one render with the \
              triangles' own normals"
            ]
        );
        let (obj, warnings) = read_text(&format!("{v}f 1/2 2/1 3/99999999999\n")).unwrap();
        assert!(obj.runs[0].mesh.uvs.is_empty());
        assert_eq!(warnings.len(), 1);
        assert!(
            warnings[0].contains("texture coordinate indices past the file's last are ignored (line 6 names texture coordinate 99999999999, and the file has 1 texture coordinate)"),
            "{warnings:?}"
        );

        // A nameless usemtl.
        let (obj, warnings) = read_text(&format!("usemtl \n{v}{good}")).unwrap();
        assert_eq!(obj.runs[0].material, None);
        assert_eq!(
            warnings,
            ["m.obj: line 1: usemtl without a material name; its faces use a default grey"]
        );
    }

    #[test]
    fn bad_numbers_name_line_and_value() {
        let e = error("v 0 0 0\nv 1 x 0\n");
        assert!(e.ends_with(":line 2: vertex: 'x' is not a number"), "{e}");
        let e = error("v 0 0 0\nvt 0\n");
        assert!(
            e.ends_with(":line 2: texture coordinate: 2 numbers needed, found 1"),
            "{e}"
        );
        let e = error("vn 0 0\n");
        assert!(
            e.ends_with(":line 1: normal: 3 numbers needed, found 2"),
            "{e}"
        );
        let e = error("v 1 2 3 0\n");
        assert!(
            e.ends_with(":line 1: vertex: w is 0 (positions are divided by w)"),
            "{e}"
        );
        let e = error("v 1 2 3 4 5\n");
        assert!(e.contains("found 5 numbers"), "{e}");
        let e = error("v 1 2 3 0.5 0.5 red\n");
        assert!(e.ends_with("vertex: 'red' is not a number"), "{e}");
        // Non-finite vertices are refused where a face uses them, naming their line.
        let text = "v 0 0 0\nv 1 0 0\nv 0 1e39 0\nv nan 0 0\nf 1 2 3\n";
        let e = error(text);
        assert!(
            e.ends_with(":line 3: vertex (0, inf, 0) is not finite"),
            "{e}"
        );
        assert!(read_text(&text.replace("f 1 2 3", "f 1 2 -1")).is_err());
        assert!(
            read_text(&text.replace("f 1 2 3", "f 1 2 1")).is_ok(),
            "unused: no error"
        );
        // `w` divides.
        let (obj, _) = read_text("v 2 4 6 2\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
        assert_eq!(obj.runs[0].mesh.positions[0], Vec3::new(1.0, 2.0, 3.0));
        assert!(error("  \n\n").ends_with("file is empty"));
        let e = error("v 0 0 0\nv \u{0}\u{ff}");
        assert!(e.contains("line 2"), "{e}");
    }

    #[test]
    fn vertex_colours_where_some_vertices_have_none_are_white() {
        let text = "v 0 0 0\nv 1 0 0 1 0 0\nv 0 1 0 0 2 0\nv 1 1 0\nf 1 2 3\nf 4 3 2\n";
        let (obj, warnings) = read_text(text).unwrap();
        let colors = obj.runs[0].colors.as_ref().unwrap();
        let expected = [Vec3::ONE, Vec3::X, Vec3::Y, Vec3::ONE].map(|c| c.extend(1.0));
        assert_eq!(colors, &expected, "clamped to [0, 1]");
        assert_eq!(
            warnings,
            [
                "m.obj: some vertices have colours (v x y z r g b) and others not; those without \
              are white"
            ]
        );
        let (obj, _) = read_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
        assert!(obj.runs[0].colors.is_none());
    }
}
