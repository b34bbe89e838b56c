//! Wavefront OBJ/MTL import: the OBJ is read by our streaming reader ([`super::obj_read`]),
//! the MTL libraries by tobj; each object/group/`usemtl` run becomes one entity with its own
//! [`crate::scene::Mesh`] and material, placed by the file's up-axis conversion.
//!
//! Polygons are triangulated by ear clipping in the polygon's plane ([`triangulate_polygon`]),
//! so concave faces come out right (a fan is correct only for convex faces). The MTL
//! mapping is documented in the README: `Kd`/`map_Kd`, `Ks`, `Ns`/`Pr`, `Pm`, `Ni` -> glTF
//! metallic-roughness, `Ke` -> one-sided emitter, `illum 3` or a mirror-like `Ks` with high
//! `Ns` -> mirror, `d` below 1 -> glass of index `Ni` (`Tr` is ignored, as Blender does). A
//! polygon that cannot be cut into ears (twisted, non-planar) is triangulated as a fan, with a
//! warning; bad faces are skipped with one warning.

use super::{Scene, SceneDefaults, UpAxis, check_mesh, obj_read};
use crate::error::Result;
use crate::math::{Rgb, Vec2, Vec3};
use crate::scene::{
    Emitter, FresnelModel, Material, MaterialTextures, Name, TextureSlot, Transform, VertexColors,
};
use crate::texture::Texture;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Albedo of faces without a usable material (Blender's default grey).
const DEFAULT_GREY: f32 = 0.8;
/// `Ks` at least this (every channel) and `Ns` at least [`MIRROR_MIN_NS`] read as a mirror.
const MIRROR_MIN_KS: f32 = 0.9;
/// See [`MIRROR_MIN_KS`] (Blender writes `Ns` 1000 for roughness 0).
const MIRROR_MIN_NS: f32 = 900.0;

/// Loads an OBJ file (and its MTL libraries) into a new world.
pub(super) fn load(path: &Path, up: UpAxis) -> Result<Scene> {
    // Running out of memory while loading is refused with an error, not an allocation abort:
    // the file's size first (its meshes take about as much as its text), then each growth
    // of the reader's columns (`obj_read`).
    if let Ok(size) = std::fs::metadata(path).map(|m| m.len()) {
        crate::memory::check_fits(
            path,
            &format!("reading the file ({:.1} MB)", size as f64 / 1e6),
            crate::memory::Needed {
                resident: size,
                address_space: size,
            },
            crate::memory::available(),
        )?;
    }
    let mut warnings = Vec::new();
    let obj = obj_read::read(path, load_mtl_checked, &mut warnings)?;
    crate::memory::trace_phase("parse");
    let dir = path.parent().unwrap_or(Path::new(".")).to_path_buf();
    if obj.materials.is_empty() {
        if let Some(e) = obj.libraries.iter().find_map(|(_, e)| e.as_ref()) {
            let names: Vec<String> = obj
                .libraries
                .iter()
                .map(|(p, _)| p.display().to_string())
                .collect();
            warnings.push(format!(
                "{}: cannot read material library {} ({e}); using a default grey material",
                path.display(),
                names.join(", ")
            ));
        }
    } else {
        // Some libraries loaded: each one that did not is named (tobj said nothing).
        for (library, e) in &obj.libraries {
            if let Some(e) = e {
                warnings.push(format!(
                    "{}: cannot read material library {} ({e}); faces using its materials \
                     get a default grey",
                    path.display(),
                    library.display()
                ));
            }
        }
    }

    let mut texture_cache: HashMap<PathBuf, Option<Arc<Texture>>> = HashMap::new();
    let imported: Vec<(Material, Option<Emitter>, Option<Arc<Texture>>)> = obj
        .materials
        .iter()
        .map(|m| import_material(m, &dir, &mut texture_cache, &mut warnings))
        .collect();
    let default = (
        Material::Lambertian {
            albedo: Rgb::splat(DEFAULT_GREY),
        },
        None,
        None,
    );

    let mut world = hecs::World::new();
    let transform = Transform(up.world_from_file());
    let mut unknown_material_warned = false;
    for run in obj.runs {
        let name = run.name;
        let (material, emitter, texture) = match run.material {
            Some(id) if id < imported.len() => imported[id].clone(),
            Some(_) | None => {
                if !imported.is_empty() && !unknown_material_warned {
                    unknown_material_warned = true;
                    warnings.push(format!(
                        "{}: object '{name}' has no known material; using a default grey",
                        path.display()
                    ));
                }
                default.clone()
            }
        };
        check_mesh(path, &format!("object '{name}'"), &run.mesh)?;
        let entity = world.spawn((Name(name), transform, run.mesh, material));
        if let Some(colors) = run.colors.filter(|c| c.iter().all(|c| c.is_finite())) {
            world
                .insert_one(entity, VertexColors(colors))
                .expect("just spawned");
        }
        if let Some(e) = emitter {
            world.insert_one(entity, e).expect("just spawned");
        }
        if let Some(t) = texture {
            world
                .insert_one(
                    entity,
                    MaterialTextures {
                        base_color: Some(TextureSlot::new(t)),
                        ..Default::default()
                    },
                )
                .expect("just spawned");
        }
    }
    crate::memory::trace_phase("meshes");
    Ok(Scene {
        world,
        defaults: SceneDefaults::default(),
        warnings,
    })
}

/// `tobj::load_mtl`, except that colour lines (`Ka`, `Kd`, `Ks`, `Ke`) with fewer than three
/// numbers are a parse error: tobj 4.0.5 panics on them (found by fuzzing).
fn load_mtl_checked(path: &Path) -> tobj::MTLLoadResult {
    let bytes = std::fs::read(path).map_err(|_| tobj::LoadError::OpenFileFailed)?;
    let text = std::str::from_utf8(&bytes).map_err(|_| tobj::LoadError::ReadError)?;
    for line in text.lines() {
        let mut words = line.split_whitespace();
        if matches!(words.next(), Some("Ka" | "Kd" | "Ks" | "Ke")) && words.count() < 3 {
            return Err(tobj::LoadError::MaterialParseError);
        }
    }
    tobj::load_mtl_buf(&mut text.as_bytes())
}

/// The README's MTL mapping.
fn import_material(
    m: &tobj::Material,
    dir: &Path,
    cache: &mut HashMap<PathBuf, Option<Arc<Texture>>>,
    warnings: &mut Vec<String>,
) -> (Material, Option<Emitter>, Option<Arc<Texture>>) {
    let rgb = |c: Option<[f32; 3]>| c.map(Rgb::from);
    let kd = rgb(m.diffuse).unwrap_or(Rgb::splat(DEFAULT_GREY));
    let ks = rgb(m.specular).unwrap_or(Rgb::ZERO);
    let ns = m.shininess.unwrap_or(0.0);
    let illum = m
        .illumination_model
        .unwrap_or(if ks == Rgb::ZERO { 1 } else { 2 });
    // Blender's rules: `d` (dissolve) alone says how see-through a surface is; `Tr` is
    // ignored, since exporters disagree on it (MeshLab writes `Tr 1` for opaque surfaces,
    // others `Tr 1` for invisible ones); `illum` does not make a surface transparent.
    let dissolve = m.dissolve.filter(|d| d.is_finite()).unwrap_or(1.0);
    if let Some(tr) = m
        .unknown_param
        .get("Tr")
        .and_then(|v| v.split_whitespace().next()?.parse::<f32>().ok())
        .filter(|&tr| tr > 0.0 && tr < 1.0 && m.dissolve.is_none())
    {
        warnings.push(format!(
            "material '{}': Tr {tr} is ignored (exporters disagree on whether Tr is \
             transparency or opacity; write d for see-through surfaces)",
            m.name
        ));
    }
    let transparent = dissolve < 1.0;
    if transparent && !matches!(illum, 4 | 6 | 7 | 9) {
        warnings.push(format!(
            "material '{}': d {dissolve} (a partly see-through surface) is approximated by \
             clear glass",
            m.name
        ));
    }
    let clamped = |c: Rgb, what: &str, warnings: &mut Vec<String>| {
        if c.min_element() < 0.0 || c.max_element() > 1.0 {
            warnings.push(format!(
                "material '{}': {what} {c} clamped to [0, 1]",
                m.name
            ));
        }
        c.clamp(Rgb::ZERO, Rgb::ONE)
    };
    let material = if transparent {
        Material::Dielectric {
            ior: m.optical_density.filter(|&n| n > 0.0).unwrap_or(1.5),
            fresnel: FresnelModel::Exact,
            tint: Rgb::ONE,
        }
    } else if illum == 3 || (ks.min_element() >= MIRROR_MIN_KS && ns >= MIRROR_MIN_NS) {
        let tint = if ks.max_element() > 0.0 { ks } else { Rgb::ONE };
        Material::Mirror {
            tint: clamped(tint, "Ks", warnings),
        }
    } else {
        // The PBR extension of MTL (Pr, Pm) where present; else roughness from the Phong
        // exponent, inverting Blender's export `Ns = 1000 (1 - roughness)^2`.
        let param = |key: &str| {
            m.unknown_param
                .get(key)
                .and_then(|v| v.split_whitespace().next()?.parse::<f32>().ok())
                .filter(|x| x.is_finite())
        };
        let roughness = param("Pr")
            .unwrap_or_else(|| 1.0 - (ns.max(0.0) / 1000.0).sqrt())
            .clamp(0.0, 1.0);
        let metallic = param("Pm").unwrap_or(0.0).clamp(0.0, 1.0);
        // Blender writes Ks = Specular IOR Level (x tint), where level 0.5 is glTF's default
        // specular layer: Ks 0 is no layer (exactly Lambertian), else specular colour 2 Ks.
        let ks = clamped(ks, "Ks", warnings);
        Material::MetallicRoughness {
            base_color: clamped(kd, "Kd", warnings),
            metallic,
            roughness,
            specular: if ks == Rgb::ZERO { 0.0 } else { 1.0 },
            specular_color: 2.0 * ks,
            ior: m
                .optical_density
                .filter(|&n| n.is_finite() && n >= 1.0)
                .unwrap_or(1.5),
            transmission: 0.0,
            clearcoat: 0.0,
            clearcoat_roughness: 0.0,
            sheen_color: Rgb::ZERO,
            sheen_roughness: 0.0,
        }
    };
    let emitter = rgb(m.emissive)
        .filter(|ke| ke.max_element() > 0.0)
        .map(|ke| Emitter {
            radiance: ke.max(Rgb::ZERO),
            two_sided: false,
        });
    let texture = m.diffuse_texture.as_ref().and_then(|file| {
        let (file, options) = texture_file_name(file);
        if !options.is_empty() {
            warnings.push(format!(
                "material '{}': map_Kd options {} are ignored",
                m.name,
                options.join(" ")
            ));
        }
        let full = dir.join(file);
        cache
            .entry(full.clone())
            .or_insert_with(|| match load_texture(&full) {
                Ok(t) => Some(Arc::new(t)),
                Err(e) => {
                    warnings.push(format!(
                        "material '{}': cannot load map_Kd '{}': {e}; using Kd alone",
                        m.name,
                        full.display()
                    ));
                    None
                }
            })
            .clone()
    });
    (material, emitter, texture)
}

/// The file name of a texture statement's arguments (`-o 0 0 0 fuze uv.jpg` -> `fuze uv.jpg`:
/// names may hold spaces) and the options before it, which are not supported.
fn texture_file_name(arguments: &str) -> (&str, Vec<&str>) {
    // MTL texture options and how many values each takes.
    const OPTIONS: &[(&str, usize)] = &[
        ("-blendu", 1),
        ("-blendv", 1),
        ("-bm", 1),
        ("-boost", 1),
        ("-cc", 1),
        ("-clamp", 1),
        ("-imfchan", 1),
        ("-mm", 2),
        ("-o", 3),
        ("-s", 3),
        ("-t", 3),
        ("-texres", 1),
        ("-type", 1),
    ];
    let mut rest = arguments.trim();
    let mut options = Vec::new();
    while let Some((flag, count)) = OPTIONS.iter().find(|(flag, _)| {
        rest.strip_prefix(flag)
            .is_some_and(|r| r.starts_with(char::is_whitespace))
    }) {
        options.push(*flag);
        rest = rest[flag.len()..].trim_start();
        // -o, -s and -t take one to three numbers: only the numbers are values.
        for _ in 0..*count {
            let word_end = rest.find(char::is_whitespace).unwrap_or(rest.len());
            let word = &rest[..word_end];
            if *count == 3 && word.parse::<f32>().is_err() {
                break;
            }
            rest = rest[word_end..].trim_start();
        }
    }
    (rest, options)
}

/// Reads an image file as an sRGB colour texture (repeat, bilinear).
pub(super) fn load_texture(path: &Path) -> std::result::Result<Texture, String> {
    let bytes = std::fs::read(path).map_err(|e| e.to_string())?;
    let image = super::image_decode::decode_image_bytes(&bytes)?;
    drop(bytes);
    let (width, height) = (image.width(), image.height());
    // Grey and RGB bytes become the texture as they are; others are made RGB (an alpha
    // channel is not the OBJ material's: that is `map_d`).
    let (channels, texels) = match image {
        image::DynamicImage::ImageLuma8(grey) => (1, grey.into_raw()),
        other => (3, other.into_rgb8().into_raw()),
    };
    Texture::from_srgb8(width, height, channels, texels)
        .ok_or_else(|| "the image is empty".to_string())
}

/// Triangulates one polygon (vertex indices into `positions`) by ear clipping in its plane,
/// appending triangles with the polygon's winding. Degenerate (zero-area) polygons add
/// nothing; polygons that cannot be cut into ears (self-intersecting) are refused.
pub(crate) fn triangulate_polygon(
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
    let p = |i: u32| positions[i as usize];
    // Newell's normal, then a 2D frame in the plane with the polygon counter-clockwise.
    let mut normal = Vec3::ZERO;
    for k in 0..polygon.len() {
        let (a, b) = (p(polygon[k]), p(polygon[(k + 1) % polygon.len()]));
        normal += Vec3::new(
            (a.y - b.y) * (a.z + b.z),
            (a.z - b.z) * (a.x + b.x),
            (a.x - b.x) * (a.y + b.y),
        );
    }
    let self_intersecting = || {
        format!(
            "the {}-sided polygon intersects itself and cannot be triangulated",
            polygon.len()
        )
    };
    let normal = if normal.length_squared() > 0.0 {
        normal.normalize()
    } else {
        // Zero net area: a bow tie (refused below) or a degenerate polygon (skipped).
        let (a, b, c) = (p(polygon[0]), p(polygon[1]), p(polygon[2]));
        let n = (b - a).cross(c - a);
        if n.length_squared().is_nan() || n.length_squared() <= 0.0 {
            return Ok(());
        }
        n.normalize()
    };
    let (u_axis, v_axis) = normal.any_orthonormal_pair();
    let flat: Vec<Vec2> = polygon
        .iter()
        .map(|&i| Vec2::new(p(i).dot(u_axis), p(i).dot(v_axis)))
        .collect();
    let cross = |a: Vec2, b: Vec2, c: Vec2| (b - a).perp_dot(c - a);
    // Ear clipping assumes a simple polygon: refuse edges that properly cross.
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
                return Err(self_intersecting());
            }
        }
    }
    let mut remaining: Vec<usize> = (0..polygon.len()).collect();
    // Pass 0 takes strictly convex ears; pass 1 also collinear ones (they add zero-area
    // triangles, which flattening skips), so chains of collinear vertices cannot block it.
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
            return Err(self_intersecting());
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
