//! Texture lookups at a hit, for the shade stage: vertex colours, base colour, metallic-roughness
//! and normal maps change the material and shading normal, read at the mipmap level the
//! path's ray cone gives ([`crate::ray_cone`]); emission textures change the radiance a light
//! emits, both where a ray hits it and where a shadow ray samples it. Plain functions over the
//! render scene; nothing allocates.

use crate::bsdf::{Anisotropy, Bsdf};
use crate::geometry::Shape;
use crate::lights::{LightPoints, LightSamples};
use crate::math::frame::Frame;
use crate::math::{Rgb, Vec2, Vec3, Vec3A, Vec4};
use crate::ray_cone::log2_uv_footprint;
use crate::render_scene::RenderScene;
use crate::scene::AlphaMode;
use crate::texture::{SurfaceTextures, TextureRef, TexturedEmission};

/// Value at barycentrics `b` of a triangle whose vertices hold `v`.
#[inline]
fn interpolate<T>(v: [T; 3], b: Vec2) -> T
where
    T: std::ops::Mul<f32, Output = T> + std::ops::Add<Output = T>,
{
    let [v0, v1, v2] = v;
    v0 * (1.0 - b.x - b.y) + v1 * b.x + v2 * b.y
}

/// The texel of `t` at the primitive's coordinates `uv` (level 0 of its mipmaps).
#[inline]
fn lookup(scene: &RenderScene, t: &TextureRef, uv: Vec2) -> Rgb {
    scene.textures[t.texture as usize].lookup(t.uv_transform.apply(uv))
}

/// The colour of `t` at the primitive's coordinates `uv`, filtered over a footprint whose
/// width in those coordinates is `2^log2_footprint` (negative infinity: level 0).
#[inline]
fn lookup_filtered(scene: &RenderScene, t: &TextureRef, uv: Vec2, log2_footprint: f32) -> Rgb {
    let texture = &scene.textures[t.texture as usize];
    let lod = texture.level_of_detail(&t.uv_transform, log2_footprint);
    texture.lookup_at(t.uv_transform.apply(uv), lod)
}

/// `log2` of the width, in texture coordinates, of the footprint of a ray cone `width` wide
/// at its hit on `slot` (unit geometric normal `ng`, `wo` back along the ray); negative
/// infinity (level 0) without a cone or on a sphere (which has no texture coordinates).
#[inline]
fn log2_footprint(scene: &RenderScene, slot: usize, width: f32, ng: Vec3A, wo: Vec3A) -> f32 {
    let Shape::Triangle(triangle) = scene.shape(slot) else {
        return f32::NEG_INFINITY;
    };
    if width.is_nan() || width <= 0.0 {
        return f32::NEG_INFINITY;
    }
    let [a, b, c] = scene.vertex_uvs(slot);
    let uv_area2 = (b - a).perp_dot(c - a).abs();
    let world_area2 = triangle.e1.cross(triangle.e2).length();
    log2_uv_footprint(width, ng.dot(wo), world_area2, uv_area2)
}

/// The shading normal at barycentrics `b` of the primitive in `slot`, whose unit geometric
/// normal is `ng`: the vertex normals interpolated and turned to `ng`'s side (the geometric
/// normal decides the sides), or `ng` itself where the primitive has none (flat-shaded
/// triangles, spheres).
#[inline(always)]
pub(super) fn shading_normal(scene: &RenderScene, slot: usize, b: Vec2, ng: Vec3A) -> Vec3A {
    // The flat part's normals are read in place: copied out into the slot the instanced
    // part's normals are returned in, they were read back across the copy's two stores, a
    // stalled load at every hit (perf: 9% of the shade stage's time in the room).
    match scene.flat_vertex_normals(slot) {
        Some(normals) => interpolated_normal(normals, b, ng),
        None => interpolated_normal(&scene.vertex_normals(slot), b, ng),
    }
}

/// The vertex `normals` interpolated at barycentrics `b` and turned to `ng`'s side; `ng`
/// where they are zero (flat-shaded).
#[inline(always)]
fn interpolated_normal([n0, n1, n2]: &[Vec3; 3], b: Vec2, ng: Vec3A) -> Vec3A {
    if *n0 == Vec3::ZERO {
        return ng;
    }
    let ns = Vec3A::from(*n0 * (1.0 - b.x - b.y) + *n1 * b.x + *n2 * b.y).normalize_or(ng);
    if ns.dot(ng) < 0.0 { -ns } else { ns }
}

/// The material of a hit on `slot` at barycentrics `b`, with its vertex colour and textures
/// applied (both multiply the base colour, as in glTF), and the
/// shading normal, normal-mapped if the material has a normal map. `ng` is the geometric
/// normal, `ns` the interpolated shading normal (on `ng`'s side) and `wo` the direction back
/// along the ray.
/// Textures are read at level 0 of their mipmaps (no footprint: light paths and their
/// vertices); [`textured_surface_in_cone`] filters them over a ray cone's footprint.
#[inline]
pub(super) fn textured_surface(
    scene: &RenderScene,
    material: usize,
    slot: usize,
    b: Vec2,
    ng: Vec3A,
    ns: Vec3A,
    wo: Vec3A,
) -> (Bsdf, Vec3A) {
    textured_surface_in_cone(scene, material, slot, b, ng, ns, wo, 0.0)
}

/// The BSDF of `material`, borrowed from the scene, when nothing varies it over the surface
/// (no textures, no vertex colours: what [`textured_surface_in_cone`] would return for every
/// hit); `None` when that function must make it. The BSDF value is large enough that each
/// copy is a `memcpy` call, which the shade stage saves for the common case.
#[inline(always)]
pub(super) fn uniform_material(scene: &RenderScene, material: usize) -> Option<&Bsdf> {
    (scene.material_textures[material].is_empty() && !scene.has_vertex_colors())
        .then(|| &scene.materials[material])
}

/// [`textured_surface`] for a ray whose cone is `cone_width` wide at the hit
/// ([`crate::ray_cone::RayCone::width_at`]): colour, metallic-roughness and normal textures
/// are read at the mipmap level of the cone's footprint; alpha (specular strength) at level 0.
#[inline]
#[allow(clippy::too_many_arguments)]
pub(super) fn textured_surface_in_cone(
    scene: &RenderScene,
    material: usize,
    slot: usize,
    b: Vec2,
    ng: Vec3A,
    ns: Vec3A,
    wo: Vec3A,
    cone_width: f32,
) -> (Bsdf, Vec3A) {
    let mut bsdf = scene.materials[material];
    if scene.has_vertex_colors() {
        bsdf = bsdf.tinted(interpolate(scene.vertex_colors(slot), b).truncate());
    }
    let textures = &scene.material_textures[material];
    if textures.is_empty() {
        return (bsdf, ns);
    }
    let uv = interpolate(scene.vertex_uvs(slot), b);
    let footprint = log2_footprint(scene, slot, cone_width, ng, wo);
    if textures.base_color.is_set() {
        bsdf = bsdf.tinted(lookup_filtered(scene, &textures.base_color, uv, footprint));
    }
    if textures.metallic_roughness.is_set() {
        let c = lookup_filtered(scene, &textures.metallic_roughness, uv, footprint);
        bsdf = bsdf.with_metallic_roughness_scaled(c.z, c.y);
    }
    if textures.specular.is_set() || textures.specular_color.is_set() {
        bsdf = specular_textured(scene, textures, (uv, footprint), bsdf);
    }
    if textures.has_layer_textures() {
        bsdf = layers_textured(scene, textures, (uv, footprint), bsdf);
    }
    if textures.has_film_textures() {
        bsdf = film_textured(scene, textures, (uv, footprint), bsdf);
    }
    let mut shading = ns;
    if textures.normal.is_set() {
        let map = (&textures.normal, textures.normal_scale);
        shading = mapped_normal(scene, map, slot, b, (uv, footprint), ng, ns, wo);
        bsdf = bsdf.with_bump_shadowing(shading, ns);
    }
    if textures.clearcoat_normal.is_set() {
        // The coat's own map, in the same tangent frame about the smooth normal.
        let map = (&textures.clearcoat_normal, textures.clearcoat_normal_scale);
        let coat = mapped_normal(scene, map, slot, b, (uv, footprint), ng, ns, wo);
        bsdf = bsdf.with_coat_normal(coat, shading);
    }
    if textures.anisotropic {
        bsdf = anisotropy_oriented(scene, textures, slot, b, (uv, footprint), shading, bsdf);
    }
    (bsdf, shading)
}

/// `bsdf` with its `KHR_materials_anisotropy` turned into the shading frame of this hit
/// (the one `Frame::from_normal(ns)` makes, which the shade stage uses): the direction, in
/// the tangent frame (tangent made orthogonal to `ns`, bitangent `cross(ns, tangent) * w`),
/// is the material's rotation applied to the texture's red-green direction (or to the
/// tangent), and the texture's blue multiplies the strength. Where the frame degenerates
/// (zero or normal-parallel tangents, a zero texture direction) the hit is isotropic.
#[inline(never)]
fn anisotropy_oriented(
    scene: &RenderScene,
    textures: &SurfaceTextures,
    slot: usize,
    b: Vec2,
    (uv, footprint): (Vec2, f32),
    ns: Vec3A,
    bsdf: Bsdf,
) -> Bsdf {
    let Some(anisotropy) = bsdf.anisotropy() else {
        return bsdf;
    };
    let tangents: [Vec4; 3] = scene.vertex_tangents(slot);
    let t = Vec3A::from(interpolate(tangents, b).truncate());
    let tangent = (t - ns * ns.dot(t)).normalize_or_zero();
    let handedness = if tangents[0].w < 0.0 { -1.0 } else { 1.0 };
    let bitangent = ns.cross(tangent) * handedness;
    let (mut direction, mut strength) = (anisotropy.direction, anisotropy.strength);
    if textures.anisotropy.is_set() {
        let c = lookup_filtered(scene, &textures.anisotropy, uv, footprint);
        let d = Vec2::new(2.0 * c.x - 1.0, 2.0 * c.y - 1.0);
        direction = Vec2::new(
            direction.x * d.x - direction.y * d.y,
            direction.y * d.x + direction.x * d.y,
        );
        strength *= c.z.clamp(0.0, 1.0);
    }
    let world = tangent * direction.x + bitangent * direction.y;
    let frame = Frame::from_normal(ns);
    let local = Vec2::new(world.dot(frame.s), world.dot(frame.t)).normalize_or_zero();
    if local == Vec2::ZERO || strength <= 0.0 || !local.is_finite() {
        return bsdf.with_anisotropy(Anisotropy::NONE);
    }
    bsdf.with_anisotropy(Anisotropy {
        strength,
        direction: local,
        ..anisotropy
    })
}

/// `bsdf` with its dielectric's specular strength and colour scaled by the
/// `KHR_materials_specular` textures (strength: the alpha of `specularTexture`).
#[inline(never)]
fn specular_textured(
    scene: &RenderScene,
    textures: &SurfaceTextures,
    (uv, footprint): (Vec2, f32),
    bsdf: Bsdf,
) -> Bsdf {
    let strength = if textures.specular.is_set() {
        let t = &textures.specular;
        scene.textures[t.texture as usize].lookup_alpha(t.uv_transform.apply(uv))
    } else {
        1.0
    };
    let colour = if textures.specular_color.is_set() {
        lookup_filtered(scene, &textures.specular_color, uv, footprint)
    } else {
        Rgb::ONE
    };
    bsdf.with_specular_scaled(strength, colour)
}

/// `bsdf` with its clearcoat and sheen scaled by the `KHR_materials_clearcoat` and `_sheen`
/// textures: clearcoat by the red of `clearcoatTexture`, its roughness by the green of
/// `clearcoatRoughnessTexture`, the sheen colour by `sheenColorTexture`, its roughness by
/// the alpha of `sheenRoughnessTexture` (level 0, as every alpha).
#[inline(never)]
fn layers_textured(
    scene: &RenderScene,
    textures: &SurfaceTextures,
    (uv, footprint): (Vec2, f32),
    bsdf: Bsdf,
) -> Bsdf {
    let colour = |t: &TextureRef| {
        if t.is_set() {
            lookup_filtered(scene, t, uv, footprint)
        } else {
            Rgb::ONE
        }
    };
    let sheen_roughness = if textures.sheen_roughness.is_set() {
        let t = &textures.sheen_roughness;
        scene.textures[t.texture as usize].lookup_alpha(t.uv_transform.apply(uv))
    } else {
        1.0
    };
    bsdf.with_layers_scaled(
        colour(&textures.clearcoat).x,
        colour(&textures.clearcoat_roughness).y,
        colour(&textures.sheen_color),
        sheen_roughness,
    )
}

/// `bsdf` with its thin film scaled by the `KHR_materials_iridescence` textures: the factor by
/// the red of `iridescenceTexture`, the thickness mixed from minimum to maximum by the green
/// of `iridescenceThicknessTexture`.
#[inline(never)]
fn film_textured(
    scene: &RenderScene,
    textures: &SurfaceTextures,
    (uv, footprint): (Vec2, f32),
    bsdf: Bsdf,
) -> Bsdf {
    let channel = |t: &TextureRef, pick: fn(Rgb) -> f32| {
        if t.is_set() {
            pick(lookup_filtered(scene, t, uv, footprint))
        } else {
            1.0
        }
    };
    bsdf.with_film_scaled(
        channel(&textures.iridescence, |c| c.x),
        channel(&textures.iridescence_thickness, |c| c.y),
    )
}

/// The shading normal from a tangent-space normal map. The tangent is made orthogonal to
/// `ns` (Gram-Schmidt); the bitangent is `cross(ns, tangent) * w`. A mapped normal that would
/// put the viewer on the other side than the geometric normal does, or point into the
/// surface, is refused (`ns` is kept): such a frame would let the BSDF scatter through the
/// surface. The geometric normal still decides sides and ray offsets in the shade stage, so
/// light never leaks whatever the map says.
#[inline]
#[allow(clippy::too_many_arguments)]
fn mapped_normal(
    scene: &RenderScene,
    (map, scale): (&TextureRef, f32),
    slot: usize,
    b: Vec2,
    (uv, footprint): (Vec2, f32),
    ng: Vec3A,
    ns: Vec3A,
    wo: Vec3A,
) -> Vec3A {
    let tangents: [Vec4; 3] = scene.vertex_tangents(slot);
    let t = interpolate(tangents, b);
    let tangent = Vec3A::from(t.truncate());
    let tangent = (tangent - ns * ns.dot(tangent)).normalize_or_zero();
    if tangent == Vec3A::ZERO {
        return ns;
    }
    let handedness = if tangents[0].w < 0.0 { -1.0 } else { 1.0 };
    let bitangent = ns.cross(tangent) * handedness;
    let c = lookup_filtered(scene, map, uv, footprint);
    let s = scale;
    let m = Vec3A::new(
        (2.0 * c.x - 1.0) * s,
        (2.0 * c.y - 1.0) * s,
        2.0 * c.z - 1.0,
    );
    let n = (tangent * m.x + bitangent * m.y + ns * m.z).normalize_or_zero();
    let viewer_side_kept = (n.dot(wo) > 0.0) == (ng.dot(wo) > 0.0);
    if n.dot(ng) > 0.0 && viewer_side_kept {
        n
    } else {
        ns
    }
}

/// Radiance leaving area light `light` at barycentrics `b` of its triangle where a ray hit
/// it: its texel times its factor if it has an emission texture, else its constant radiance.
/// (A ray that hits an alpha-tested emitter has passed its coverage test: no coverage here.)
#[inline]
pub(super) fn emitted_radiance(scene: &RenderScene, light: u32, b: Vec2) -> Rgb {
    match scene.textured_emission.get(light as usize) {
        Some(Some(e)) => e.radiance * emission_texel(scene, e, b),
        _ => scene.lights.lights[light as usize].radiance,
    }
}

/// Radiance leaving area light `light` at barycentrics `b` of its triangle where light
/// sampling chose the point (a light path's start): [`emitted_radiance`] times the
/// emitter's alpha coverage there ([`EmissionCoverage`]).
#[inline]
pub(super) fn sampled_emitted_radiance(scene: &RenderScene, light: u32, b: Vec2) -> Rgb {
    match scene.textured_emission.get(light as usize) {
        Some(Some(e)) => e.radiance * emission_texel(scene, e, b) * emission_coverage(scene, e, b),
        _ => scene.lights.lights[light as usize].radiance,
    }
}

/// The emission texel of `e` at barycentrics `b` (1 without an emission texture).
#[inline]
fn emission_texel(scene: &RenderScene, e: &TexturedEmission, b: Vec2) -> Rgb {
    if e.texture.is_set() {
        lookup(scene, &e.texture, interpolate(e.uvs, b))
    } else {
        Rgb::ONE
    }
}

/// The weight of a sampled point at barycentrics `b` of the emitter of `e` for its alpha
/// coverage: the coverage (BLEND) or whether it reaches the cutoff (MASK); 1 when opaque.
#[inline]
fn emission_coverage(scene: &RenderScene, e: &TexturedEmission, b: Vec2) -> f32 {
    let Some(c) = &e.coverage else {
        return 1.0;
    };
    let mut alpha = c.factor * interpolate(c.vertex_alpha, b);
    if c.texture.is_set() {
        let uv = c.texture.uv_transform.apply(interpolate(e.uvs, b));
        alpha *= scene.textures[c.texture.texture as usize].lookup_alpha(uv);
    }
    match c.mode {
        AlphaMode::Blend => alpha.clamp(0.0, 1.0),
        AlphaMode::Mask { cutoff } => f32::from(u8::from(alpha >= cutoff)),
    }
}

/// Rescales the radiance of each lane of `samples` that chose a light with an emission
/// texture by texel / mean at the sampled point: the table chose and weighted the light as if
/// it emitted its mean radiance everywhere (the density is unchanged: the estimate stays
/// unbiased); and by the coverage there for an alpha-tested emitter.
#[inline]
pub(super) fn texture_light_samples(
    scene: &RenderScene,
    (mut samples, points): (LightSamples, LightPoints),
) -> LightSamples {
    if !scene.textured_emission.is_empty() {
        samples.radiance = textured_radiance(scene, samples.radiance, points);
    }
    samples
}

/// The radiance of [`texture_light_samples`] in a scene with emission textures, off the
/// common path and from copies, so that the samples stay in registers in scenes without them.
/// Punctual lanes (`NOT_AREA_LIGHT`) have no entry and are left alone.
#[cold]
#[inline(never)]
fn textured_radiance(scene: &RenderScene, radiance: [Vec4; 3], points: LightPoints) -> [Vec4; 3] {
    let LightPoints {
        area_light,
        barycentric,
    } = points;
    let mut by_channel = radiance.map(|c| c.to_array());
    for (k, light) in area_light.into_iter().enumerate() {
        if let Some(Some(e)) = scene.textured_emission.get(light as usize) {
            let b = Vec2::new(barycentric[0][k], barycentric[1][k]);
            let texel = emission_texel(scene, e, b) * emission_coverage(scene, e, b);
            let lane = Rgb::new(by_channel[0][k], by_channel[1][k], by_channel[2][k]);
            let textured = lane * e.inverse_mean * texel;
            for (channel, value) in by_channel.iter_mut().zip(textured.to_array()) {
                channel[k] = value;
            }
        }
    }
    by_channel.map(Vec4::from_array)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::MetallicRoughness;
    use crate::math::Vec3A;

    /// A quad with `material` (JSON) whose textures are `images` in order (texture i reads
    /// image i), written as a glTF with its PNGs.
    fn textured_quad(
        dir: &std::path::Path,
        material: &str,
        images: &[image::RgbaImage],
    ) -> std::path::PathBuf {
        let mut uris = Vec::new();
        let mut textures = Vec::new();
        for (i, img) in images.iter().enumerate() {
            img.save(dir.join(format!("t{i}.png"))).unwrap();
            uris.push(format!(r#"{{"uri": "t{i}.png"}}"#));
            textures.push(format!(r#"{{"source": {i}, "sampler": 0}}"#));
        }
        let floats: [f32; 20] = [
            -1.0, -1.0, 0.0, 1.0, -1.0, 0.0, 1.0, 1.0, 0.0, -1.0, 1.0, 0.0, // positions
            0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0, 1.0, // uvs
        ];
        let mut bytes: Vec<u8> = floats.iter().flat_map(|x| x.to_le_bytes()).collect();
        bytes.extend([0u16, 1, 2, 0, 2, 3].iter().flat_map(|i| i.to_le_bytes()));
        std::fs::write(dir.join("quad.bin"), &bytes).unwrap();
        let gltf = format!(
            r#"{{"asset": {{"version": "2.0"}}, "scenes": [{{"nodes": [0]}}],
            "nodes": [{{"mesh": 0}}],
            "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0, "TEXCOORD_0": 1}},
                "indices": 2, "material": 0}}]}}],
            "materials": [{material}],
            "textures": [{}], "images": [{}],
            "samplers": [{{"magFilter": 9728}}],
            "buffers": [{{"uri": "quad.bin", "byteLength": {}}}],
            "bufferViews": [{{"buffer": 0, "byteOffset": 0, "byteLength": 48}},
                {{"buffer": 0, "byteOffset": 48, "byteLength": 32}},
                {{"buffer": 0, "byteOffset": 80, "byteLength": 12}}],
            "accessors": [
                {{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                  "min": [-1, -1, 0], "max": [1, 1, 0]}},
                {{"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"}},
                {{"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"}}]}}"#,
            textures.join(", "),
            uris.join(", "),
            bytes.len()
        );
        let path = dir.join("quad.gltf");
        std::fs::write(&path, gltf).unwrap();
        path
    }

    /// The material at the centroid of the quad of [`textured_quad`] (textures applied, `+z`
    /// for every direction) with its shading normal, and the file's warnings. The bare model
    /// is placed in the hexagonal room: the quad's slot is the one whose textures `reads`.
    fn quad_surface(
        dir: &std::path::Path,
        material: &str,
        images: &[image::RgbaImage],
        reads: fn(&SurfaceTextures) -> bool,
    ) -> ((Bsdf, Vec3A), Vec<String>) {
        let path = textured_quad(dir, material, images);
        let loaded = crate::load_scene(&path).unwrap();
        let scene = crate::flatten(&loaded.world, &path).unwrap();
        let slot = (scene.material.iter())
            .position(|&m| reads(&scene.material_textures[m as usize]))
            .expect("the quad's material reads its textures");
        let material = scene.material[slot] as usize;
        let (z, b) = (Vec3A::Z, Vec2::splat(1.0 / 3.0));
        let surface = textured_surface(&scene, material, slot, b, z, z, z);
        (surface, loaded.warnings)
    }

    #[test]
    fn metallic_roughness_texture_is_linear_blue_metallic_green_roughness() {
        let dir = tempfile::tempdir().unwrap();
        // A white metal (metallic 1, roughness 1) with a 1 x 1 metallic-roughness texture of
        // (red 0, green 128, blue 64).
        let material = r#"{"pbrMetallicRoughness": {"metallicFactor": 1.0,
            "roughnessFactor": 1.0, "metallicRoughnessTexture": {"index": 0}}}"#;
        let texel = image::RgbaImage::from_pixel(1, 1, image::Rgba([0, 128, 64, 255]));
        let ((bsdf, _), _) = quad_surface(dir.path(), material, &[texel], |t| {
            t.metallic_roughness.is_set()
        });
        let Bsdf::MetallicRoughness(MetallicRoughness {
            metallic, alpha, ..
        }) = bsdf
        else {
            panic!("{bsdf:?}")
        };
        // Linear: 64/255 = 0.251 and 128/255 = 0.502 (sRGB-decoded they would be 0.0513 and
        // 0.2158); blue is metallic, green is roughness, and alpha = roughness^2.
        assert!(
            (metallic - 64.0 / 255.0).abs() < 1e-6,
            "metallic {metallic}"
        );
        let roughness = 128.0f32 / 255.0;
        assert!(
            (alpha - roughness * roughness).abs() < 1e-6,
            "alpha {alpha}, roughness {}",
            alpha.sqrt()
        );
    }

    /// `iridescenceTexture`'s red multiplies the film's factor, `iridescenceThicknessTexture`'s
    /// green mixes its thickness from the minimum to the maximum (both linear).
    #[test]
    fn iridescence_textures_scale_the_factor_and_mix_the_thickness() {
        let dir = tempfile::tempdir().unwrap();
        let material = r#"{"pbrMetallicRoughness": {"metallicFactor": 0.0},
            "extensions": {"KHR_materials_iridescence": {"iridescenceFactor": 0.8,
                "iridescenceIor": 1.8, "iridescenceThicknessMinimum": 200.0,
                "iridescenceThicknessMaximum": 600.0, "iridescenceTexture": {"index": 0},
                "iridescenceThicknessTexture": {"index": 0}}}}"#;
        let texel = image::RgbaImage::from_pixel(1, 1, image::Rgba([128, 64, 10, 255]));
        let ((bsdf, _), warnings) = quad_surface(
            dir.path(),
            material,
            &[texel],
            SurfaceTextures::has_film_textures,
        );
        assert!(
            !warnings.iter().any(|w| w.contains("iridescence")),
            "{warnings:?}"
        );
        let Bsdf::MetallicRoughness(params) = bsdf else {
            panic!("{bsdf:?}")
        };
        let (red, green) = (128.0f32 / 255.0, 64.0f32 / 255.0);
        let film = params.film;
        assert!((film.factor - 0.8 * red).abs() < 1e-6, "{film:?}");
        assert!(
            (film.thickness - (200.0 + 400.0 * green)).abs() < 1e-3,
            "{film:?}"
        );
        assert_eq!(film.ior, 1.8);
    }

    /// The coat's normal map is decoded as the base's, in the same tangent frame: with the
    /// same texel and scale in both, the coat's normal is the shading normal; with the coat's
    /// alone, the shading normal stays the smooth one and the coat tilts as the base would.
    #[test]
    fn the_coat_normal_map_is_read_as_the_base_normal_map() {
        let dir = tempfile::tempdir().unwrap();
        let texel = image::RgbaImage::from_pixel(1, 1, image::Rgba([220, 90, 200, 255]));
        let both = r#"{"pbrMetallicRoughness": {"metallicFactor": 0.0},
            "normalTexture": {"index": 0, "scale": 0.5},
            "extensions": {"KHR_materials_clearcoat": {"clearcoatFactor": 1.0,
                "clearcoatNormalTexture": {"index": 0, "scale": 0.5}}}}"#;
        let coat_only = r#"{"pbrMetallicRoughness": {"metallicFactor": 0.0},
            "extensions": {"KHR_materials_clearcoat": {"clearcoatFactor": 1.0,
                "clearcoatNormalTexture": {"index": 0, "scale": 0.5}}}}"#;
        let surface = |material: &str| {
            let images = std::slice::from_ref(&texel);
            let ((bsdf, shading), warnings) = quad_surface(dir.path(), material, images, |t| {
                t.clearcoat_normal.is_set()
            });
            assert!(
                !warnings.iter().any(|w| w.contains("clearcoat")),
                "{warnings:?}"
            );
            let Bsdf::Layered(layered) = bsdf else {
                panic!("{bsdf:?}")
            };
            (layered.coat_normal.expect("the coat is mapped"), shading)
        };
        let (coat, shading) = surface(both);
        assert!(shading.z < 0.99, "the base is mapped: {shading}");
        assert!((coat - Vec3::Z).length() < 1e-5, "{coat}");
        let (coat_alone, smooth) = surface(coat_only);
        assert_eq!(smooth, Vec3A::Z);
        assert!(
            (coat_alone.z - shading.z).abs() < 1e-5,
            "{coat_alone} {shading}"
        );
    }

    #[test]
    fn clearcoat_and_sheen_textures_scale_their_factors_by_their_channels() {
        let dir = tempfile::tempdir().unwrap();
        // Clearcoat 1 (roughness 1) and white sheen (roughness 1); one RGBA texture of
        // (128, 64, 188, 51) serves every slot: clearcoat takes red (linear 0.502), its
        // roughness green (0.251), the sheen colour sRGB (0.2158, 0.0513, 0.5029), the sheen
        // roughness alpha (0.2).
        let material = r#"{"pbrMetallicRoughness": {"metallicFactor": 0.0},
            "extensions": {
                "KHR_materials_clearcoat": {"clearcoatFactor": 1.0,
                    "clearcoatRoughnessFactor": 1.0, "clearcoatTexture": {"index": 0},
                    "clearcoatRoughnessTexture": {"index": 0}},
                "KHR_materials_sheen": {"sheenColorFactor": [1.0, 1.0, 1.0],
                    "sheenRoughnessFactor": 1.0, "sheenColorTexture": {"index": 0},
                    "sheenRoughnessTexture": {"index": 0}}}}"#;
        let texel = image::RgbaImage::from_pixel(1, 1, image::Rgba([128, 64, 188, 51]));
        let ((bsdf, _), warnings) = quad_surface(
            dir.path(),
            material,
            &[texel],
            SurfaceTextures::has_layer_textures,
        );
        assert!(
            !warnings
                .iter()
                .any(|w| w.contains("sheen") || w.contains("clearcoat")),
            "{warnings:?}"
        );
        let Bsdf::Layered(layered) = bsdf else {
            panic!("{bsdf:?}")
        };
        let (red, green) = (128.0f32 / 255.0, 64.0f32 / 255.0);
        assert!((layered.clearcoat - red).abs() < 1e-6, "{layered:?}");
        assert!(
            (layered.clearcoat_alpha - green * green).abs() < 1e-6,
            "{layered:?}"
        );
        let expected = Rgb::new(0.2158605, 0.0512695, 0.5028865);
        assert!(
            (layered.sheen_color - expected).abs().max_element() < 1e-4,
            "{layered:?}"
        );
        assert!((layered.sheen_roughness - 0.2).abs() < 1e-6, "{layered:?}");
    }

    #[test]
    fn specular_textures_scale_the_strength_by_alpha_and_the_colour_by_srgb() {
        let dir = tempfile::tempdir().unwrap();
        // A dielectric with specular 0.8 and colour (2, 1.5, 1) (factors above 1 tint F0),
        // a specular texture of alpha 128 (its RGB unused) and a colour texture of sRGB 188.
        let material = r#"{"pbrMetallicRoughness": {"metallicFactor": 0.0},
            "extensions": {"KHR_materials_specular": {"specularFactor": 0.8,
                "specularColorFactor": [2.0, 1.5, 1.0],
                "specularTexture": {"index": 0}, "specularColorTexture": {"index": 1}}}}"#;
        let strength = image::RgbaImage::from_pixel(1, 1, image::Rgba([9, 9, 9, 128]));
        let colour = image::RgbaImage::from_pixel(1, 1, image::Rgba([188, 255, 0, 255]));
        let ((bsdf, _), _) = quad_surface(dir.path(), material, &[strength, colour], |t| {
            t.specular.is_set() && t.specular_color.is_set()
        });
        let Bsdf::MetallicRoughness(MetallicRoughness {
            specular,
            specular_color,
            ..
        }) = bsdf
        else {
            panic!("{bsdf:?}")
        };
        // Alpha is linear: 0.8 x 128/255; sRGB 188 is linear 0.5029.
        assert!((specular - 0.8 * 128.0 / 255.0).abs() < 1e-6, "{specular}");
        let expected = Rgb::new(2.0 * 0.50289, 1.5, 0.0);
        assert!(
            (specular_color - expected).abs().max_element() < 1e-4,
            "{specular_color}"
        );
    }
}
