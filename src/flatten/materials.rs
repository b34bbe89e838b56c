//! The materials of the world as the render scene keeps them: the scattering model of each
//! [`Material`] ([`bsdf_of`]), the distinct textures each one reads (interned by pointer),
//! and tangents for normal maps. Lookups happen in `wavefront::surface`.

use crate::bsdf::microfacet::alpha_from_roughness;
use crate::bsdf::{
    Anisotropy, Bsdf, BumpShadowing, FresnelModel, Layered, MetallicRoughness, ThinFilm,
};
use crate::math::{Rgb, Vec2, Vec3A, Vec4};
use crate::scene::{Iridescence, Material, MaterialTextures, TextureSlot, Volume};
use crate::texture::{Mipmapped, SurfaceTextures, Texture, TextureRef};
use std::sync::Arc;

/// The thin film of an entity's `KHR_materials_iridescence`, or [`ThinFilm::NONE`].
fn thin_film_of(iridescence: Option<&Iridescence>) -> ThinFilm {
    match iridescence {
        Some(i) if i.factor > 0.0 => ThinFilm {
            factor: i.factor,
            ior: i.ior,
            thickness: i.thickness_maximum,
            thickness_minimum: i.thickness_minimum,
        },
        _ => ThinFilm::NONE,
    }
}

/// The render-side scattering model of a scene material; `mr_textured` says whether a
/// metallic-roughness texture varies it (which rules out the mirror special case), `film` is
/// its thin film (which rules out the mirror too: the film colours the metal's reflection),
/// and `anisotropy` is its `KHR_materials_anisotropy` (which rules out both smooth special
/// cases: it roughens them along its direction).
pub(super) fn bsdf_of(
    m: &Material,
    mr_textured: bool,
    film: ThinFilm,
    anisotropy: Anisotropy,
) -> Bsdf {
    match *m {
        Material::Lambertian { albedo } => Bsdf::Lambertian { albedo },
        Material::Mirror { tint } => Bsdf::Mirror { tint },
        Material::Unlit { color } => Bsdf::Unlit { color },
        Material::Dielectric { ior, fresnel, tint } => Bsdf::Dielectric { ior, fresnel, tint },
        Material::MetallicRoughness {
            base_color,
            metallic,
            roughness,
            specular,
            specular_color,
            ior,
            transmission,
            clearcoat,
            clearcoat_roughness,
            sheen_color,
            sheen_roughness,
        } => {
            let base = MetallicRoughness {
                base_color,
                metallic,
                alpha: alpha_from_roughness(roughness),
                ior,
                specular,
                specular_color,
                transmission,
                bump: BumpShadowing::NONE,
                film,
                anisotropy,
            };
            let layered = Layered {
                base,
                clearcoat,
                clearcoat_alpha: alpha_from_roughness(clearcoat_roughness),
                sheen_color,
                sheen_roughness,
                coat_normal: None,
            };
            if layered.has_layers() {
                return Bsdf::layered(layered);
            }
            let smooth = roughness == 0.0 && anisotropy.is_none();
            if transmission == 1.0 && metallic == 0.0 && smooth {
                // Smooth clear glass stays the exact delta dielectric.
                return Bsdf::Dielectric {
                    ior,
                    fresnel: FresnelModel::Exact,
                    tint: base_color,
                };
            }
            if metallic == 1.0 && smooth && !mr_textured && !film.is_present() {
                // A smooth metal is the perfect mirror (the alpha -> 0 limit; for a coloured
                // metal, Schlick's brightening toward grazing angles is left out).
                return Bsdf::Mirror { tint: base_color };
            }
            Bsdf::metallic_roughness(base)
        }
    }
}

/// The distinct materials of the scene, with the textures they read and the absorption of
/// the medium inside.
#[derive(Default)]
pub(super) struct MaterialTable {
    /// Each material's scattering model, textures and absorption, in order of first use.
    materials: Vec<(Bsdf, SurfaceTextures, Rgb)>,
    /// The distinct textures.
    pub(super) interner: TextureInterner,
}

impl MaterialTable {
    /// The index of the scene material `m` with its textures and the medium inside, added
    /// if new.
    pub(super) fn index(
        &mut self,
        m: &Material,
        textures: Option<&MaterialTextures>,
        volume: Option<&Volume>,
        iridescence: Option<&Iridescence>,
    ) -> u32 {
        let surface = self.interner.surface(textures);
        let film = thin_film_of(iridescence);
        let anisotropy =
            textures
                .and_then(|t| t.anisotropy.as_ref())
                .map_or(Anisotropy::NONE, |a| Anisotropy {
                    strength: a.strength,
                    mapping: a.mapping,
                    direction: Vec2::new(a.rotation.cos(), a.rotation.sin()),
                });
        let bsdf = bsdf_of(m, surface.metallic_roughness.is_set(), film, anisotropy);
        let absorption = volume.map_or(Rgb::ZERO, |v| v.absorption);
        let key = (bsdf, surface, absorption);
        let found = self.materials.iter().position(|b| *b == key);
        found.unwrap_or_else(|| {
            self.materials.push(key);
            self.materials.len() - 1
        }) as u32
    }

    /// The scattering models, by index.
    pub(super) fn bsdfs(&self) -> Vec<Bsdf> {
        self.materials.iter().map(|m| m.0).collect()
    }

    /// The absorption coefficient inside each material, by index; empty when nothing
    /// absorbs (the shading stage then skips the media).
    pub(super) fn absorptions(&self) -> Vec<Rgb> {
        if self.materials.iter().all(|m| m.2 == Rgb::ZERO) {
            return Vec::new();
        }
        self.materials.iter().map(|m| m.2).collect()
    }

    /// Whether some material may transmit through a rough lobe (whatever its textures make
    /// of it) or holds an absorbing medium.
    pub(super) fn transmits_or_absorbs(&self) -> bool {
        self.materials
            .iter()
            .any(|m| m.0.may_transmit() || m.2 != Rgb::ZERO)
    }

    /// The textures each material reads, by index.
    pub(super) fn surface_textures(&self) -> Vec<SurfaceTextures> {
        self.materials.iter().map(|m| m.1).collect()
    }
}

/// Collects distinct textures (by pointer) into the render scene's texture list.
#[derive(Default)]
pub(super) struct TextureInterner {
    pub textures: Vec<Arc<Texture>>,
}

impl TextureInterner {
    /// The reference to `slot`'s texture, added if new.
    pub fn intern(&mut self, slot: Option<&TextureSlot>) -> TextureRef {
        let Some(slot) = slot else {
            return TextureRef::default();
        };
        let index = self
            .textures
            .iter()
            .position(|known| Arc::ptr_eq(known, &slot.texture))
            .unwrap_or_else(|| {
                self.textures.push(slot.texture.clone());
                self.textures.len() - 1
            });
        TextureRef {
            texture: index as u32,
            uv_transform: slot.uv_transform,
        }
    }

    /// The surface textures of a scene material.
    pub fn surface(&mut self, textures: Option<&MaterialTextures>) -> SurfaceTextures {
        let Some(t) = textures else {
            return SurfaceTextures::default();
        };
        SurfaceTextures {
            base_color: self.intern(t.base_color.as_ref()),
            metallic_roughness: self.intern(t.metallic_roughness.as_ref()),
            normal: self.intern(t.normal.as_ref()),
            normal_scale: t.normal_scale,
            specular: self.intern(t.specular.as_ref()),
            specular_color: self.intern(t.specular_color.as_ref()),
            clearcoat: self.intern(t.clearcoat.as_ref()),
            clearcoat_roughness: self.intern(t.clearcoat_roughness.as_ref()),
            clearcoat_normal: self.intern(t.clearcoat_normal.as_ref()),
            clearcoat_normal_scale: t.clearcoat_normal_scale,
            sheen_color: self.intern(t.sheen_color.as_ref()),
            sheen_roughness: self.intern(t.sheen_roughness.as_ref()),
            iridescence: self.intern(t.iridescence.as_ref()),
            iridescence_thickness: self.intern(t.iridescence_thickness.as_ref()),
            anisotropic: t.anisotropy.as_ref().is_some_and(|a| a.strength > 0.0),
            anisotropy: self.intern(t.anisotropy.as_ref().and_then(|a| a.texture.as_ref())),
        }
    }
}

/// The render scene's textures with their mipmaps, built here once per texture whose
/// sampler reads them; refused with an error when the levels (a third of the texels'
/// bytes more) would not fit in memory.
pub(super) fn mipmapped(
    textures: Vec<Arc<Texture>>,
    path: &std::path::Path,
) -> crate::Result<Vec<Mipmapped>> {
    let levels: u64 = (textures.iter())
        .filter(|t| t.min_filter.uses_mipmaps())
        .map(|t| t.texel_bytes() as u64 / 3 + 1)
        .sum();
    crate::memory::check_fits(
        path,
        &format!("the mipmaps of its {} textures", textures.len()),
        crate::memory::Needed {
            resident: levels,
            address_space: levels,
        },
        crate::memory::available(),
    )?;
    Ok(textures.into_iter().map(Mipmapped::new).collect())
}

/// `1 / x` per channel, 0 where `x` is 0.
pub(super) fn inverse_or_zero(x: Rgb) -> Rgb {
    Rgb::select(x.cmpgt(Rgb::ZERO), x.recip(), Rgb::ZERO)
}

/// A tangent for a triangle without `TANGENT` data, from its texture coordinates: `xyz` along
/// increasing `u`, `w` the handedness that makes `cross(n, xyz) * w` point along decreasing
/// `v` (glTF's `v` runs down the image, and normal maps' +y points up it). This is constant
/// per triangle and not MikkTSpace: maps baked against MikkTSpace tangents come out slightly
/// different across smooth-shaded triangles. Degenerate UVs give an arbitrary tangent.
pub(super) fn triangle_tangent(p: [Vec3A; 3], uv: [Vec2; 3], n: Vec3A) -> Vec4 {
    let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
    let (d1, d2) = (uv[1] - uv[0], uv[2] - uv[0]);
    let det = d1.x * d2.y - d2.x * d1.y;
    let fallback = || {
        let t = n.any_orthonormal_vector();
        Vec4::new(t.x, t.y, t.z, 1.0)
    };
    if det == 0.0 || !det.is_finite() {
        return fallback();
    }
    let dp_du = (e1 * d2.y - e2 * d1.y) / det;
    let dp_dv = (e2 * d1.x - e1 * d2.x) / det;
    let t = dp_du.normalize_or_zero();
    if t == Vec3A::ZERO || !t.is_finite() {
        return fallback();
    }
    let w = if n.cross(t).dot(-dp_dv) < 0.0 {
        -1.0
    } else {
        1.0
    };
    Vec4::new(t.x, t.y, t.z, w)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generated_tangents_follow_u_and_the_bitangent_points_up_the_image() {
        // A quad in the xy plane, facing +z, with glTF UVs: u along +x, v down the image
        // (along -y), so up the image is +y.
        let p = [Vec3A::ZERO, Vec3A::X, Vec3A::new(0.0, 1.0, 0.0)];
        let uv = [
            Vec2::new(0.0, 1.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(0.0, 0.0),
        ];
        let t = triangle_tangent(p, uv, Vec3A::Z);
        assert_eq!(t, Vec4::new(1.0, 0.0, 0.0, 1.0));
        let bitangent = Vec3A::Z.cross(Vec3A::X) * t.w;
        assert_eq!(bitangent, Vec3A::Y);
        // Mirrored UVs flip the handedness.
        let mirrored = [
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(0.0, 1.0),
        ];
        assert_eq!(triangle_tangent(p, mirrored, Vec3A::Z).w, -1.0);
        // Degenerate UVs still give a unit tangent in the plane.
        let t = triangle_tangent(p, [Vec2::ZERO; 3], Vec3A::Z);
        assert!((t.truncate().length() - 1.0).abs() < 1e-6 && t.z.abs() < 1e-6);
    }
}
