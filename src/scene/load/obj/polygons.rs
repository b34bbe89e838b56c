//! Polygons cut into triangles: ear clipping in the polygon's plane, so concave faces come out
//! right (a fan is correct only for convex faces). Degenerate (zero-area) polygons add
//! nothing; a polygon that cannot be cut into ears (self-intersecting, twisted) is refused,
//! and the reader then triangulates it as a fan with a warning.

use crate::math::{Vec2, Vec3};

/// Triangulates one polygon (vertex indices into `positions`) by ear clipping in its plane,
/// appending triangles with the polygon's winding. Degenerate (zero-area) polygons add
/// nothing; polygons that cannot be cut into ears (self-intersecting) are refused.
pub(super) fn triangulate_polygon(
    positions: &[Vec3],
    polygon: &[u32],
    out: &mut Vec<[u32; 3]>,
) -> std::result::Result<(), String> {
    match polygon.len() {
        0..=2 => return Ok(()),
        3 => {
            out.push([polygon[0], polygon[1], polygon[2]]);
            return Ok(());
        }
        _ => {}
    }
    let self_intersecting = || {
        format!(
            "the {}-sided polygon intersects itself and cannot be triangulated",
            polygon.len()
        )
    };
    let Some(flat) = in_plane(positions, polygon) else {
        return Ok(());
    };
    // Ear clipping assumes a simple polygon: refuse edges that properly cross.
    if has_crossing_edges(&flat) {
        return Err(self_intersecting());
    }
    clip_ears(&flat, polygon, out).map_err(|()| self_intersecting())
}

/// The signed area of the parallelogram on `b - a` and `c - a` (positive counter-clockwise).
fn cross(a: Vec2, b: Vec2, c: Vec2) -> f32 {
    (b - a).perp_dot(c - a)
}

/// The polygon's vertices in a 2D frame of its plane, counter-clockwise (by Newell's normal);
/// `None` for a degenerate polygon.
fn in_plane(positions: &[Vec3], polygon: &[u32]) -> Option<Vec<Vec2>> {
    let p = |i: u32| positions[i as usize];
    let mut normal = Vec3::ZERO;
    for k in 0..polygon.len() {
        let (a, b) = (p(polygon[k]), p(polygon[(k + 1) % polygon.len()]));
        normal += Vec3::new(
            (a.y - b.y) * (a.z + b.z),
            (a.z - b.z) * (a.x + b.x),
            (a.x - b.x) * (a.y + b.y),
        );
    }
    let normal = if normal.length_squared() > 0.0 {
        normal.normalize()
    } else {
        // Zero net area: a bow tie (refused by the caller) or a degenerate polygon (skipped).
        let (a, b, c) = (p(polygon[0]), p(polygon[1]), p(polygon[2]));
        let n = (b - a).cross(c - a);
        if n.length_squared().is_nan() || n.length_squared() <= 0.0 {
            return None;
        }
        n.normalize()
    };
    let (u_axis, v_axis) = normal.any_orthonormal_pair();
    Some(
        polygon
            .iter()
            .map(|&i| Vec2::new(p(i).dot(u_axis), p(i).dot(v_axis)))
            .collect(),
    )
}

/// Whether two edges of the closed polygon properly cross.
fn has_crossing_edges(flat: &[Vec2]) -> bool {
    let m = flat.len();
    for i in 0..m {
        for j in i + 2..m {
            if i == 0 && j == m - 1 {
                continue; // adjacent through the closing edge
            }
            let (a, b, c, d) = (flat[i], flat[(i + 1) % m], flat[j], flat[(j + 1) % m]);
            let (d1, d2) = (cross(a, b, c), cross(a, b, d));
            let (d3, d4) = (cross(c, d, a), cross(c, d, b));
            if d1 * d2 < 0.0 && d3 * d4 < 0.0 {
                return true;
            }
        }
    }
    false
}

/// Cuts ears off the (simple, counter-clockwise) polygon until a triangle is left, appending
/// each; `Err` when no ear can be cut. Pass 0 takes strictly convex ears; pass 1 also
/// collinear ones (they add zero-area triangles, which flattening skips), so chains of
/// collinear vertices cannot block it.
fn clip_ears(flat: &[Vec2], polygon: &[u32], out: &mut Vec<[u32; 3]>) -> Result<(), ()> {
    let mut remaining: Vec<usize> = (0..polygon.len()).collect();
    while remaining.len() > 3 {
        let m = remaining.len();
        let mut clipped = false;
        'passes: for strict in [true, false] {
            for k in 0..m {
                let (ia, ib, ic) = (
                    remaining[(k + m - 1) % m],
                    remaining[k],
                    remaining[(k + 1) % m],
                );
                let (a, b, c) = (flat[ia], flat[ib], flat[ic]);
                let turn = cross(a, b, c);
                if (strict && turn <= 0.0) || turn < 0.0 {
                    continue;
                }
                let contains_other = remaining.iter().any(|&j| {
                    if j == ia || j == ib || j == ic {
                        return false;
                    }
                    let q = flat[j];
                    cross(a, b, q) >= 0.0
                        && cross(b, c, q) >= 0.0
                        && cross(c, a, q) >= 0.0
                        && q != a
                        && q != b
                        && q != c
                });
                if turn > 0.0 && contains_other {
                    continue;
                }
                out.push([polygon[ia], polygon[ib], polygon[ic]]);
                remaining.remove(k);
                clipped = true;
                break 'passes;
            }
        }
        if !clipped {
            return Err(());
        }
    }
    out.push([
        polygon[remaining[0]],
        polygon[remaining[1]],
        polygon[remaining[2]],
    ]);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn area(positions: &[Vec3], tris: &[[u32; 3]]) -> f32 {
        tris.iter()
            .map(|&[a, b, c]| {
                let (a, b, c) = (
                    positions[a as usize],
                    positions[b as usize],
                    positions[c as usize],
                );
                0.5 * (b - a).cross(c - a).z
            })
            .sum()
    }

    #[test]
    fn concave_polygons_are_cut_into_ears_with_the_right_area() {
        // An L shape (area 3) whose fan from vertex 0 would cover the notch.
        let l = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(2.0, 1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(1.0, 2.0, 0.0),
            Vec3::new(0.0, 2.0, 0.0),
        ];
        for rotation in 0..6u32 {
            let polygon: Vec<u32> = (0..6).map(|k| (k + rotation) % 6).collect();
            let mut tris = Vec::new();
            triangulate_polygon(&l, &polygon, &mut tris).unwrap();
            assert_eq!(tris.len(), 4);
            assert!((area(&l, &tris) - 3.0).abs() < 1e-6, "rotation {rotation}");
            for &[a, b, c] in &tris {
                let (a, b, c) = (l[a as usize], l[b as usize], l[c as usize]);
                assert!((b - a).cross(c - a).z >= 0.0, "winding kept");
            }
        }
    }

    #[test]
    fn convex_polygons_with_collinear_vertices_triangulate() {
        let square = [
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(2.0, 0.0, 1.0),
            Vec3::new(2.0, 2.0, 1.0),
            Vec3::new(0.0, 2.0, 1.0),
        ];
        let mut tris = Vec::new();
        triangulate_polygon(&square, &[0, 1, 2, 3, 4], &mut tris).unwrap();
        assert!((area(&square, &tris) - 4.0).abs() < 1e-6);
    }

    #[test]
    fn self_intersecting_polygons_are_refused() {
        // A bow tie.
        let bow = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(2.0, 2.0, 0.0),
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 2.0, 0.0),
        ];
        let mut tris = Vec::new();
        let e = triangulate_polygon(&bow, &[0, 1, 2, 3], &mut tris).unwrap_err();
        assert!(e.contains("intersects itself"), "{e}");
        // A pentagon whose first edge crosses the third.
        let crossed = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(2.0, 2.0, 0.0),
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 2.0, 0.0),
            Vec3::new(1.0, 3.0, 0.0),
        ];
        assert!(triangulate_polygon(&crossed, &[0, 1, 2, 3, 4], &mut tris).is_err());
        // Collinear points only: nothing to render, no error.
        let line = [Vec3::ZERO, Vec3::X, 2.0 * Vec3::X, 3.0 * Vec3::X];
        tris.clear();
        triangulate_polygon(&line, &[0, 1, 2, 3], &mut tris).unwrap();
        assert!(tris.is_empty());
    }
}
