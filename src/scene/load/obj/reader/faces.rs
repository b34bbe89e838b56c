//! Faces: each `f` statement's corners resolved to the current run's vertices (added when
//! new), triangles appended, polygons cut into ears (`polygons.rs`) or, when they refer to a
//! position not yet read, deferred to the end of the run; a polygon that cannot be cut into
//! ears becomes a fan with its count kept for the summary warning.

use super::{Corners, Deferred, NONE, Reader, SMOOTHED, grow};
use crate::error::Result;
use std::collections::HashMap;
use std::path::Path;

impl<L: FnMut(&Path) -> tobj::MTLLoadResult> Reader<'_, L> {
    /// `f v1 v2 v3 ...`, each corner `v`, `v/vt`, `v//vn` or `v/vt/vn`.
    pub(super) fn face(&mut self, words: std::str::SplitWhitespace, line: usize) -> Result<()> {
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
        if let Err(why) = super::super::polygons::triangulate_polygon(
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
    pub(super) fn fan(&mut self, polygon: &[u32], line: usize, why: String) {
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
}
