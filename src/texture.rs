//! Textures: linear RGB texels with a sampler (wrap and filter per axis), looked up by
//! texture coordinate, the `KHR_texture_transform` of texture coordinates, and how the render
//! scene's materials and lights refer to textures ([`TextureRef`], [`SurfaceTextures`],
//! [`TexturedEmission`]). Pure data and
//! math; loaders fill them and shading reads them. Colour data (base colour, emission) is
//! stored sRGB-encoded and decoded here; data textures (metallic-roughness, normal maps) are
//! stored linear.
//!
//! Texture coordinates follow glTF: `(0, 0)` is the top-left corner of the image (the first
//! stored row), `u` runs right and `v` down. The OBJ loader flips `v` to match.

use crate::math::{Rgb, Vec2};

/// What happens outside `[0, 1]` along one axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wrap {
    /// Tile the image.
    Repeat,
    /// Repeat the edge texel.
    ClampToEdge,
    /// Tile, mirroring every other copy.
    MirroredRepeat,
}

/// How texels are combined at a lookup.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Filter {
    /// The texel the point falls in.
    Nearest,
    /// Bilinear interpolation of the four nearest texel centres.
    Linear,
}

/// How a texture's stored values map to the linear values it holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Encoding {
    /// sRGB transfer function (colour textures).
    Srgb,
    /// Stored as they are, scaled to [0, 1] (data textures).
    Linear,
}

/// `KHR_texture_transform` as the 2 x 3 matrix `uv' = T R S uv` (row-major: two rows of
/// `[a, b, offset]`), applied to a mesh's texture coordinates at each lookup.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UvTransform(pub [[f32; 3]; 2]);

impl Default for UvTransform {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl UvTransform {
    /// Leaves coordinates as they are.
    pub const IDENTITY: UvTransform = UvTransform([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);

    /// From the extension's `offset`, `rotation` (radians) and `scale`.
    pub fn from_offset_rotation_scale(offset: [f32; 2], rotation: f32, scale: [f32; 2]) -> Self {
        let ([ox, oy], [sx, sy]) = (offset, scale);
        let (s, c) = rotation.sin_cos();
        UvTransform([[c * sx, s * sy, ox], [-s * sx, c * sy, oy]])
    }

    /// The transformed coordinates.
    #[inline]
    pub fn apply(&self, uv: Vec2) -> Vec2 {
        let [r0, r1] = self.0;
        Vec2::new(
            r0[0] * uv.x + r0[1] * uv.y + r0[2],
            r1[0] * uv.x + r1[1] * uv.y + r1[2],
        )
    }
}

/// An RGB texture in linear colour, with its sampler.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    width: u32,
    height: u32,
    /// Row-major texels, row 0 at the top (`v = 0`).
    texels: Texels,
    /// Wrap modes along `u` and `v`.
    pub wrap: [Wrap; 2],
    /// Filter used for every lookup (no mipmapping: a path tracer supersamples anyway).
    pub filter: Filter,
}

/// The texels as stored. 8-bit images keep their bytes, decoded to linear through a table at
/// each lookup (the same values a decoded copy would hold, in a quarter of its memory: an
/// 8192 x 8192 RGBA image takes 256 MiB instead of 1 GiB); other formats are kept as linear
/// floats.
#[derive(Clone, Debug, PartialEq)]
enum Texels {
    Linear {
        rgb: Vec<Rgb>,
        /// Alpha (coverage, linear), kept only when some texel is not opaque: empty means
        /// opaque everywhere.
        alpha: Vec<f32>,
    },
    Bytes {
        /// `channels` bytes a texel: grey, grey + alpha, RGB or RGBA.
        data: Vec<u8>,
        channels: usize,
        /// Byte -> linear colour value (alpha is always linear: byte / 255).
        decode: Box<[f32; 256]>,
        /// Whether some texel is not opaque (else alpha lookups give 1).
        has_alpha: bool,
    },
}

/// A stored alpha value (8 or 16 bits) in [0, 1]; alpha is never sRGB-encoded.
trait AlphaValue: Copy {
    fn unit(self) -> f32;
}

impl AlphaValue for u8 {
    fn unit(self) -> f32 {
        self as f32 / 255.0
    }
}

impl AlphaValue for u16 {
    fn unit(self) -> f32 {
        self as f32 / 65535.0
    }
}

fn alpha_of<T: AlphaValue>(x: T) -> f32 {
    x.unit()
}

/// A stored value in [0, 1] to linear.
fn decode(x: f32, encoding: Encoding) -> f32 {
    match encoding {
        Encoding::Srgb => srgb_to_linear(x),
        Encoding::Linear => x,
    }
}

/// sRGB-encoded 8-bit value to linear, as a table (the transfer function of IEC 61966-2-1).
fn srgb_to_linear(x: f32) -> f32 {
    if x <= 0.04045 {
        x / 12.92
    } else {
        ((x + 0.055) / 1.055).powf(2.4)
    }
}

impl Texture {
    /// A texture from linear texels (row-major, row 0 at the top). `None` if the sizes
    /// do not match or the image is empty.
    pub fn new(width: u32, height: u32, texels: Vec<Rgb>) -> Option<Self> {
        (width > 0 && height > 0 && texels.len() == width as usize * height as usize).then_some(
            Texture {
                width,
                height,
                texels: Texels::Linear {
                    rgb: texels,
                    alpha: Vec::new(),
                },
                wrap: [Wrap::Repeat; 2],
                filter: Filter::Linear,
            },
        )
    }

    /// A texture from sRGB-encoded 8-bit data with `channels` bytes per texel (1: grey,
    /// 2: grey + alpha, 3: RGB, 4: RGBA; alpha, always linear, is kept if not all opaque).
    pub fn from_srgb8(width: u32, height: u32, channels: usize, bytes: Vec<u8>) -> Option<Self> {
        Self::from_bytes8(width, height, channels, bytes, Encoding::Srgb)
    }

    /// Like [`Self::from_srgb8`] for 16-bit little-endian channels.
    pub fn from_srgb16(width: u32, height: u32, channels: usize, bytes: &[u8]) -> Option<Self> {
        Self::from_bytes16(width, height, channels, bytes, Encoding::Srgb)
    }

    /// A texture from 8-bit data with `channels` bytes per texel, decoded as `encoding` says
    /// (kept as they are: see [`Texels`]).
    pub fn from_bytes8(
        width: u32,
        height: u32,
        channels: usize,
        bytes: Vec<u8>,
        encoding: Encoding,
    ) -> Option<Self> {
        let texels = width as usize * height as usize;
        if texels == 0 || !(1..=4).contains(&channels) || bytes.len() != texels * channels {
            return None;
        }
        let has_alpha = channels.is_multiple_of(2)
            && bytes.chunks_exact(channels).any(|t| t[channels - 1] < 255);
        Some(Texture {
            width,
            height,
            texels: Texels::Bytes {
                data: bytes,
                channels,
                decode: Box::new(std::array::from_fn(|i| decode(i as f32 / 255.0, encoding))),
                has_alpha,
            },
            wrap: [Wrap::Repeat; 2],
            filter: Filter::Linear,
        })
    }

    /// Like [`Self::from_bytes8`] for 16-bit little-endian channels.
    pub fn from_bytes16(
        width: u32,
        height: u32,
        channels: usize,
        bytes: &[u8],
        encoding: Encoding,
    ) -> Option<Self> {
        let values: Vec<u16> = bytes
            .chunks_exact(2)
            .map(|c| u16::from_le_bytes([c[0], c[1]]))
            .collect();
        Self::from_encoded(width, height, channels, &values, |v| {
            decode(v as f32 / 65535.0, encoding)
        })
    }

    /// The mean of the texels: what the texture averages to over its whole image.
    pub fn mean(&self) -> Rgb {
        let count = self.width as usize * self.height as usize;
        let sum = (0..count).fold(glam::DVec3::ZERO, |a, k| a + self.texel_at(k).as_dvec3());
        (sum / count as f64).as_vec3()
    }

    fn from_encoded<T: AlphaValue>(
        width: u32,
        height: u32,
        channels: usize,
        data: &[T],
        decode: impl Fn(T) -> f32,
    ) -> Option<Self> {
        if !(1..=4).contains(&channels) || data.len() != width as usize * height as usize * channels
        {
            return None;
        }
        let texels = data
            .chunks_exact(channels)
            .map(|t| match channels {
                1 | 2 => Rgb::splat(decode(t[0])),
                _ => Rgb::new(decode(t[0]), decode(t[1]), decode(t[2])),
            })
            .collect();
        let mut texture = Self::new(width, height, texels)?;
        if channels.is_multiple_of(2) {
            let opacity: Vec<f32> = data
                .chunks_exact(channels)
                .map(|t| alpha_of(t[channels - 1]))
                .collect();
            if let (true, Texels::Linear { alpha, .. }) =
                (opacity.iter().any(|&a| a < 1.0), &mut texture.texels)
            {
                *alpha = opacity;
            }
        }
        Some(texture)
    }

    /// Whether some texel is not opaque.
    pub fn has_alpha(&self) -> bool {
        match &self.texels {
            Texels::Linear { alpha, .. } => !alpha.is_empty(),
            Texels::Bytes { has_alpha, .. } => *has_alpha,
        }
    }

    /// The filtered alpha (coverage) at texture coordinate `uv`; 1 for an opaque texture.
    #[inline]
    pub fn lookup_alpha(&self, uv: Vec2) -> f32 {
        if !self.has_alpha() {
            return 1.0;
        }
        let w = self.width as usize;
        match &self.texels {
            Texels::Linear { alpha, .. } => self.filtered(uv, |i, j| alpha[j * w + i]),
            Texels::Bytes { data, channels, .. } => self.filtered(uv, |i, j| {
                alpha_of(data[(j * w + i) * channels + channels - 1])
            }),
        }
    }

    /// Width and height in texels.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// The filtered colour at texture coordinate `uv`.
    #[inline]
    pub fn lookup(&self, uv: Vec2) -> Rgb {
        self.filtered(uv, |i, j| self.texel(i, j))
    }

    /// The value of `texel(i, j)` filtered at `uv` with the texture's sampler.
    #[inline]
    fn filtered<T>(&self, uv: Vec2, texel: impl Fn(usize, usize) -> T) -> T
    where
        T: std::ops::Mul<f32, Output = T> + std::ops::Add<Output = T>,
    {
        let (w, h) = (self.width as i64, self.height as i64);
        let x = uv.x * w as f32;
        let y = uv.y * h as f32;
        if !(x.is_finite() && y.is_finite()) {
            return texel(0, 0);
        }
        match self.filter {
            Filter::Nearest => {
                let i = wrap_index(x.floor() as i64, w, self.wrap[0]);
                let j = wrap_index(y.floor() as i64, h, self.wrap[1]);
                texel(i, j)
            }
            Filter::Linear => {
                let (xs, ys) = (x - 0.5, y - 0.5);
                let (x0, y0) = (xs.floor(), ys.floor());
                let (fx, fy) = (xs - x0, ys - y0);
                let (x0, y0) = (x0 as i64, y0 as i64);
                let i0 = wrap_index(x0, w, self.wrap[0]);
                let i1 = wrap_index(x0 + 1, w, self.wrap[0]);
                let j0 = wrap_index(y0, h, self.wrap[1]);
                let j1 = wrap_index(y0 + 1, h, self.wrap[1]);
                let top = texel(i0, j0) * (1.0 - fx) + texel(i1, j0) * fx;
                let bottom = texel(i0, j1) * (1.0 - fx) + texel(i1, j1) * fx;
                top * (1.0 - fy) + bottom * fy
            }
        }
    }

    #[inline]
    fn texel(&self, i: usize, j: usize) -> Rgb {
        self.texel_at(j * self.width as usize + i)
    }

    /// The linear colour of texel `k` in row-major order.
    #[inline]
    fn texel_at(&self, k: usize) -> Rgb {
        match &self.texels {
            Texels::Linear { rgb, .. } => rgb[k],
            Texels::Bytes {
                data,
                channels,
                decode,
                ..
            } => {
                let t = &data[k * channels..];
                match channels {
                    1 | 2 => Rgb::splat(decode[t[0] as usize]),
                    _ => Rgb::new(
                        decode[t[0] as usize],
                        decode[t[1] as usize],
                        decode[t[2] as usize],
                    ),
                }
            }
        }
    }
}

/// Texel index `i` of an axis of `n` texels, wrapped into `0..n`. Coordinates are clamped
/// to a large range first so that the integer arithmetic cannot overflow.
#[inline]
fn wrap_index(i: i64, n: i64, wrap: Wrap) -> usize {
    let i = i.clamp(-(1 << 40), 1 << 40);
    (match wrap {
        Wrap::ClampToEdge => i.clamp(0, n - 1),
        Wrap::Repeat => i.rem_euclid(n),
        Wrap::MirroredRepeat => {
            let period = i.rem_euclid(2 * n);
            if period < n {
                period
            } else {
                2 * n - 1 - period
            }
        }
    }) as usize
}

/// Marks an unset texture in a [`TextureRef`].
pub const NO_TEXTURE: u32 = u32::MAX;

/// A texture of [`crate::render_scene::RenderScene::textures`] and the transform from the primitive's UVs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TextureRef {
    /// Index into [`crate::render_scene::RenderScene::textures`] ([`NO_TEXTURE`] for none).
    pub texture: u32,
    /// `KHR_texture_transform`, applied at each lookup.
    pub uv_transform: UvTransform,
}

impl Default for TextureRef {
    fn default() -> Self {
        TextureRef {
            texture: NO_TEXTURE,
            uv_transform: UvTransform::IDENTITY,
        }
    }
}

impl TextureRef {
    /// Whether a texture is set.
    #[inline]
    pub fn is_set(&self) -> bool {
        self.texture != NO_TEXTURE
    }
}

/// The textures one flattened material reads at a hit (see [`MaterialTextures`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SurfaceTextures {
    /// Multiplies the material's colour.
    pub base_color: TextureRef,
    /// Blue multiplies metallic, green roughness.
    pub metallic_roughness: TextureRef,
    /// Tangent-space normal map.
    pub normal: TextureRef,
    /// Multiplies the normal map's x and y.
    pub normal_scale: f32,
    /// Alpha multiplies the dielectric's `specular` (`KHR_materials_specular`).
    pub specular: TextureRef,
    /// Multiplies the dielectric's `specular_color` (`KHR_materials_specular`).
    pub specular_color: TextureRef,
}

impl SurfaceTextures {
    /// Whether the material reads no texture (the common, fast case).
    #[inline]
    pub fn is_empty(&self) -> bool {
        !(self.base_color.is_set()
            || self.metallic_roughness.is_set()
            || self.normal.is_set()
            || self.specular.is_set()
            || self.specular_color.is_set())
    }
}

/// The emission texture of one triangle light. Its [`crate::lights::AreaLight::radiance`] is
/// `radiance` times the texture's mean (the power estimate that chooses lights); the radiance
/// leaving a point is `radiance` times the texel there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TexturedEmission {
    /// The emissive texture.
    pub texture: TextureRef,
    /// The emitter's radiance before the texture (`emissiveFactor` x strength).
    pub radiance: Rgb,
    /// Per channel, 1 / the texture's mean (0 where the mean is 0, which makes the texture 0
    /// everywhere in that channel): turns a light sample drawn for the mean into one for the texel.
    pub inverse_mean: Rgb,
    /// Texture coordinates of the triangle's vertices, in the light's vertex order.
    pub uvs: [Vec2; 3],
}

#[cfg(test)]
mod tests {
    use super::*;

    fn checker() -> Texture {
        // 2x2: black, white / white, black.
        let (b, w) = (Rgb::ZERO, Rgb::ONE);
        Texture::new(2, 2, vec![b, w, w, b]).unwrap()
    }

    #[test]
    fn nearest_lookup_wraps_as_asked() {
        let mut t = checker();
        t.filter = Filter::Nearest;
        assert_eq!(t.lookup(Vec2::new(0.25, 0.25)), Rgb::ZERO);
        assert_eq!(t.lookup(Vec2::new(0.75, 0.25)), Rgb::ONE);
        assert_eq!(t.lookup(Vec2::new(1.25, 0.25)), Rgb::ZERO, "repeat");
        t.wrap = [Wrap::ClampToEdge; 2];
        assert_eq!(t.lookup(Vec2::new(1.25, 0.25)), Rgb::ONE, "clamp");
        assert_eq!(t.lookup(Vec2::new(-3.0, 0.25)), Rgb::ZERO, "clamp");
        t.wrap = [Wrap::MirroredRepeat; 2];
        assert_eq!(t.lookup(Vec2::new(1.25, 0.25)), Rgb::ONE, "mirror");
        assert_eq!(t.lookup(Vec2::new(-0.25, 0.25)), Rgb::ZERO, "mirror");
    }

    #[test]
    fn linear_lookup_interpolates_between_texel_centres() {
        let mut t = checker();
        t.wrap = [Wrap::ClampToEdge; 2];
        assert_eq!(t.lookup(Vec2::new(0.25, 0.25)), Rgb::ZERO, "texel centre");
        let mid = t.lookup(Vec2::new(0.5, 0.25));
        assert!((mid - Rgb::splat(0.5)).abs().max_element() < 1e-6);
        assert!((t.lookup(Vec2::new(0.5, 0.5)) - Rgb::splat(0.5)).length() < 1e-6);
    }

    #[test]
    fn eight_bit_texels_look_up_as_their_decoded_floats() {
        // 3 x 2 RGBA bytes of every kind of value, against the same texels decoded up front.
        let bytes: Vec<u8> = (0..24u32).map(|k| (k * 37 % 256) as u8).collect();
        for encoding in [Encoding::Srgb, Encoding::Linear] {
            let stored = Texture::from_bytes8(3, 2, 4, bytes.clone(), encoding).unwrap();
            let floats: Vec<Rgb> = bytes
                .chunks_exact(4)
                .map(|t| Rgb::from_array([0, 1, 2].map(|c| decode(t[c] as f32 / 255.0, encoding))))
                .collect();
            let mut decoded = Texture::new(3, 2, floats).unwrap();
            if let Texels::Linear { alpha, .. } = &mut decoded.texels {
                *alpha = bytes.chunks_exact(4).map(|t| t[3] as f32 / 255.0).collect();
            }
            assert!(matches!(stored.texels, Texels::Bytes { .. }));
            assert_eq!(stored.mean(), decoded.mean());
            for k in 0..50 {
                let uv = Vec2::new(k as f32 * 0.137 - 1.0, k as f32 * 0.071 - 0.5);
                assert_eq!(stored.lookup(uv), decoded.lookup(uv), "{uv}");
                assert_eq!(stored.lookup_alpha(uv), decoded.lookup_alpha(uv), "{uv}");
            }
        }
    }

    #[test]
    fn alpha_is_kept_linear_only_when_some_texel_is_not_opaque() {
        let opaque = Texture::from_srgb8(2, 1, 4, vec![9, 9, 9, 255, 0, 0, 0, 255]).unwrap();
        assert!(!opaque.has_alpha());
        assert_eq!(opaque.lookup_alpha(Vec2::new(0.25, 0.5)), 1.0);
        let mut t = Texture::from_srgb8(2, 1, 2, vec![255, 255, 255, 51]).unwrap();
        t.wrap = [Wrap::ClampToEdge; 2];
        assert!(t.has_alpha());
        assert_eq!(t.lookup_alpha(Vec2::new(0.25, 0.5)), 1.0);
        assert_eq!(
            t.lookup_alpha(Vec2::new(0.75, 0.5)),
            0.2,
            "alpha is not sRGB-decoded"
        );
        assert!(
            (t.lookup_alpha(Vec2::new(0.5, 0.5)) - 0.6).abs() < 1e-6,
            "bilinear"
        );
        assert_eq!(t.lookup(Vec2::new(0.75, 0.5)), Rgb::ONE, "colour unchanged");
    }

    #[test]
    fn linear_bytes_stay_linear_and_the_mean_averages_texels() {
        let t = Texture::from_bytes8(2, 1, 3, vec![255, 51, 0, 0, 0, 0], Encoding::Linear).unwrap();
        assert_eq!(t.lookup(Vec2::new(0.25, 0.5)), Rgb::new(1.0, 0.2, 0.0));
        assert_eq!(t.mean(), Rgb::new(0.5, 0.1, 0.0));
    }

    #[test]
    fn uv_transform_offsets_rotates_and_scales() {
        assert_eq!(
            UvTransform::IDENTITY.apply(Vec2::new(0.3, 0.7)),
            Vec2::new(0.3, 0.7)
        );
        let t = UvTransform::from_offset_rotation_scale([0.5, 0.0], 0.0, [0.5, 1.0]);
        assert_eq!(t.apply(Vec2::new(1.0, 1.0)), Vec2::new(1.0, 1.0));
        // A quarter turn (the extension's rotation is counter-clockwise in UV space).
        let r = UvTransform::from_offset_rotation_scale(
            [0.0, 0.0],
            std::f32::consts::FRAC_PI_2,
            [1.0, 1.0],
        );
        assert!((r.apply(Vec2::new(1.0, 0.0)) - Vec2::new(0.0, -1.0)).length() < 1e-6);
    }

    #[test]
    fn srgb_bytes_decode_to_linear() {
        let t = Texture::from_srgb8(1, 1, 4, vec![255, 188, 0, 7]).unwrap();
        let c = t.lookup(Vec2::splat(0.5));
        assert!((c.x - 1.0).abs() < 1e-6 && (c.y - 0.5029).abs() < 1e-3 && c.z == 0.0);
        assert!(Texture::from_srgb8(2, 1, 3, vec![0; 5]).is_none());
    }
}
