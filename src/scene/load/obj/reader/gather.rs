//! The end of the read: the indices checked against the file's counts, each run's columns
//! gathered from the file's (its vertices in order of first use, polygons that referred
//! forward cut into ears, smoothing groups' normals computed), and the summary warnings of
//! what was skipped, one per kind.

use super::{At, Corners, Deferred, NONE, Obj, Reader, Run, RunBuilder, SMOOTHED};
use crate::error::{Error, Result};
use crate::math::{Vec2, Vec3};
use crate::scene::Mesh;
use std::collections::HashMap;
use std::path::Path;

/// The kinds of index, in the order of `Reader::largest`.
const KINDS: [&str; 3] = ["vertex", "texture coordinate", "normal"];

impl<L: FnMut(&Path) -> tobj::MTLLoadResult> Reader<'_, L> {
    /// Checks the indices against the file's counts, gathers every run's columns and says
    /// what was skipped.
    pub(super) fn finish(mut self, warnings: &mut Vec<String>) -> Result<Obj> {
        if !self.content {
            return Err(Error::input(self.path, None, "file is empty"));
        }
        // Indices past the file's last element: faces naming a missing position are skipped
        // (in `gather`); a missing texture coordinate or normal drops that column from the
        // objects that name it.
        const CONSEQUENCES: [&str; 3] = [
            "",
            "the objects that name one render without texture coordinates",
            "the objects that name one render with the triangles' own normals",
        ];
        let out_of_range = self.out_of_range();
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
        self.warn_skipped(&file, warnings);
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

    /// For each kind of index (v, vt, vn), why the largest one is past the file's last, if
    /// it is.
    fn out_of_range(&self) -> [Option<String>; 3] {
        const PLURALS: [&str; 3] = ["vertices", "texture coordinates", "normals"];
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
        out_of_range
    }

    /// One warning per kind of statement skipped or ignored while reading.
    fn warn_skipped(&self, file: &str, warnings: &mut Vec<String>) {
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
        let positions = self.gather_positions(&corners)?;
        let (mut normals, uvs, smoothed) = match &corners {
            Corners::Positions(_) => (Vec::new(), Vec::new(), false),
            Corners::Triples { keys, .. } => self.gather_normals_and_uvs(keys)?,
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
            self.triangulate_deferred(polygon, &positions, &mut triangles);
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

    /// The run's positions; a position that is not finite is an error naming its line.
    fn gather_positions(&self, corners: &Corners) -> Result<Vec<Vec3>> {
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
        Ok(positions)
    }

    /// The normals and texture coordinates of a run whose corners are (v, vt, vn) triples,
    /// and whether some vertex is smoothed (its normal still to compute).
    fn gather_normals_and_uvs(&self, keys: &[[u32; 3]]) -> Result<(Vec<Vec3>, Vec<Vec2>, bool)> {
        let n = keys.len();
        let smoothed = keys.iter().any(|k| is_smoothed(k[2]));
        // A column only when every vertex has a normal or is smoothed (below), as
        // before (tobj's shorter columns were dropped); a vertex of a face outside
        // any smoothing group then has none, and its triangles shade flat.
        let normals = if smoothed || keys.iter().all(|k| (k[2] as usize) < self.normals.len()) {
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
        Ok((normals, uvs, smoothed))
    }

    /// Cuts a polygon that referred forward into triangles of the run (as a fan, with the
    /// count kept for the warning, when it cannot be cut into ears).
    fn triangulate_deferred(
        &mut self,
        polygon: Deferred,
        positions: &[Vec3],
        triangles: &mut Vec<[u32; 3]>,
    ) {
        self.face_triangles.clear();
        let identity: Vec<u32> = (0..polygon.corners.len() as u32).collect();
        let corner_positions: Vec<Vec3> = polygon
            .corners
            .iter()
            .map(|&local| positions[local as usize])
            .collect();
        if let Err(why) = super::super::polygons::triangulate_polygon(
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
