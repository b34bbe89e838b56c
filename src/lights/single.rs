//! The one-light fast path: a scene lit by one area light (a triangle, or two triangles
//! making a parallelogram) samples it directly, without the table's choice.

use super::*;

/// The scene's only light, when it is one triangle, or two triangles of one emitter that
/// make a parallelogram (a quad light, as the hexagonal room's and most modelled area lights
/// are), sampled uniformly by area like its triangles. Every lane samples it, so its data
/// are splatted once instead of gathered lane by lane, and a parallelogram needs neither the
/// choice of a triangle nor the triangle warp: the hexagonal room's shade stage runs a quarter
/// fewer instructions.
#[derive(Clone, Copy, Debug)]
pub(super) struct SingleLight {
    /// Points are `corner + b1 edges[0] + b2 edges[1]`. Every vector here is one value in
    /// all lanes, by axis or channel.
    pub(super) corner: [Vec4; 3],
    pub(super) edges: [[Vec4; 3]; 2],
    /// Whether `(b1, b2)` covers the unit square (a parallelogram), or the unit triangle.
    pub(super) parallelogram: bool,
    pub(super) normal: [Vec4; 3],
    pub(super) pdf_area: Vec4,
    pub(super) radiance: [Vec4; 3],
    /// 1 if the light shines both ways, else 0.
    pub(super) two_sided: Vec4,
}

/// The [`SingleLight`] of a table of area lights `lights` and punctual lights `delta_lights`,
/// if it has one.
pub(super) fn single_light(
    lights: &[AreaLight],
    delta_lights: &[DeltaLight],
) -> Option<SingleLight> {
    if !delta_lights.is_empty() {
        return None;
    }
    let triangle = |light: &AreaLight| match light.shape {
        Shape::Triangle(t) => Some(t),
        Shape::Sphere(_) => None,
    };
    // Splatted, by axis or channel; `source` gives the normal, radiance and sides.
    let lanes = |v: Vec3A| v.to_array().map(Vec4::splat);
    let light =
        |source: &AreaLight, corner, [e1, e2]: [Vec3A; 2], parallelogram, pdf_area| SingleLight {
            corner: lanes(corner),
            edges: [lanes(e1), lanes(e2)],
            parallelogram,
            normal: lanes(source.normal),
            pdf_area: Vec4::splat(pdf_area),
            radiance: source.radiance.to_array().map(Vec4::splat),
            two_sided: Vec4::splat(if source.two_sided { 1.0 } else { 0.0 }),
        };
    match lights {
        [only] => {
            let t = triangle(only)?;
            Some(light(only, t.v0, [t.e1, t.e2], false, only.pdf_area))
        }
        [a, b] if a.radiance == b.radiance && a.two_sided == b.two_sided => {
            let (t, u) = (triangle(a)?, triangle(b)?);
            let (corner, edges) = parallelogram_of(t, u)?;
            // Same emitting side; the density is that of choosing a triangle by area and a
            // point on it uniformly: one over the whole area.
            let pdf_area = 1.0 / (a.area + b.area);
            (a.normal.dot(b.normal) > 1.0 - 1e-6).then(|| light(a, corner, edges, true, pdf_area))
        }
        _ => None,
    }
}

/// The corner and edges of the parallelogram that triangles `t` and `u` make, if they share an
/// edge (vertices `p` and `r`) and their other vertices `q` and `s` make it a parallelogram,
/// `q + s = p + r`, all to a rounding margin (the vertices are rebuilt from the edges).
fn parallelogram_of(t: TriangleGeom, u: TriangleGeom) -> Option<(Vec3A, [Vec3A; 2])> {
    let (tv, uv) = (t.vertices(), u.vertices());
    let extent = (tv.into_iter().chain(uv)).fold(0.0, |e: f32, v| e.max(v.abs().max_element()));
    let same = |a: Vec3A, b: Vec3A| (a - b).abs().max_element() <= 1e-6 * extent;
    (0..3).find_map(|k| {
        let (q, p, r) = (tv[k], tv[(k + 1) % 3], tv[(k + 2) % 3]);
        let shared = |v: Vec3A| uv.iter().any(|&w| same(v, w));
        let s = uv.into_iter().find(|&w| !same(w, p) && !same(w, r))?;
        (shared(p) && shared(r) && same(q + s, p + r)).then_some((q, [p - q, r - q]))
    })
}

impl SingleLight {
    /// Four samples seen from `p`, lane `k` at `(u[0][k], u[1][k])` in the unit square.
    #[inline(always)]
    pub(super) fn sample(&self, p: Vec3A, u: [Vec4; 2]) -> (LightSamples, LightPoints) {
        let b = if self.parallelogram {
            u
        } else {
            sample_triangle(u)
        };
        // The same operations in the same order as a triangle's `point`, lane by lane.
        let [e1, e2] = self.edges;
        let point = [0, 1, 2].map(|axis| self.corner[axis] + b[0] * e1[axis] + b[1] * e2[axis]);
        let samples = samples_toward(
            p,
            point,
            self.normal,
            self.pdf_area,
            self.radiance,
            self.two_sided,
        );
        let points = LightPoints {
            area_light: [0; LIGHT_LANES],
            barycentric: b,
        };
        (samples, points)
    }
}
