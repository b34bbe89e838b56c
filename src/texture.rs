//! Textures: linear RGB texels with a sampler (wrap per axis, magnification and
//! minification filters), looked up by texture coordinate; their mipmaps ([`Mipmapped`],
//! built once per texture by flatten, box-filtered in linear space) and trilinear lookups at a
//! level of detail; the `KHR_texture_transform` of texture coordinates, and how the render
//! scene's materials and lights refer to textures ([`TextureRef`], [`SurfaceTextures`],
//! [`TexturedEmission`]). Pure data and
//! math; loaders fill them and shading reads them. Colour data (base colour, emission) is
//! stored sRGB-encoded and decoded here; data textures (metallic-roughness, normal maps) are
//! stored linear.
//!
//! Texture coordinates follow glTF: `(0, 0)` is the top-left corner of the image (the first
//! stored row), `u` runs right and `v` down. The OBJ loader flips `v` to match.

use crate::math::{Rgb, Vec2};
use std::sync::Arc;

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

/// The glTF sampler's `minFilter`: how texels are combined where the texture is minified
/// (the level of detail is above 0), and whether and how mipmap levels are used.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MinFilter {
    /// The nearest texel of the full image (no mipmaps).
    Nearest,
    /// Bilinear in the full image (no mipmaps).
    Linear,
    /// The nearest texel of the nearest level.
    NearestMipmapNearest,
    /// Bilinear in the nearest level.
    LinearMipmapNearest,
    /// The nearest texel of the two nearest levels, blended.
    NearestMipmapLinear,
    /// Bilinear in the two nearest levels, blended (trilinear): the default.
    LinearMipmapLinear,
}

impl MinFilter {
    /// The filter within a level, and whether levels blend (`Some(true)`), the nearest one
    /// is taken (`Some(false)`) or there are none (`None`).
    fn parts(self) -> (Filter, Option<bool>) {
        match self {
            MinFilter::Nearest => (Filter::Nearest, None),
            MinFilter::Linear => (Filter::Linear, None),
            MinFilter::NearestMipmapNearest => (Filter::Nearest, Some(false)),
            MinFilter::LinearMipmapNearest => (Filter::Linear, Some(false)),
            MinFilter::NearestMipmapLinear => (Filter::Nearest, Some(true)),
            MinFilter::LinearMipmapLinear => (Filter::Linear, Some(true)),
        }
    }

    /// Whether the filter reads mipmap levels.
    pub fn uses_mipmaps(self) -> bool {
        self.parts().1.is_some()
    }
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
    /// The magnification filter: lookups at level of detail 0 or below, and every lookup
    /// that has no footprint (alpha coverage, emission, light paths).
    pub filter: Filter,
    /// The minification filter: lookups of [`Mipmapped::lookup_at`] above level 0.
    pub min_filter: MinFilter,
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
                min_filter: MinFilter::LinearMipmapLinear,
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
            min_filter: MinFilter::LinearMipmapLinear,
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
            Texels::Linear { alpha, .. } => self.filtered(self.filter, uv, |i, j| alpha[j * w + i]),
            Texels::Bytes { data, channels, .. } => self.filtered(self.filter, uv, |i, j| {
                alpha_of(data[(j * w + i) * channels + channels - 1])
            }),
        }
    }

    /// The bytes the texels take.
    pub fn texel_bytes(&self) -> usize {
        match &self.texels {
            Texels::Linear { rgb, alpha } => {
                std::mem::size_of_val(rgb.as_slice()) + std::mem::size_of_val(alpha.as_slice())
            }
            Texels::Bytes { data, .. } => data.len(),
        }
    }

    /// Width and height in texels.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// The filtered colour at texture coordinate `uv`.
    #[inline]
    pub fn lookup(&self, uv: Vec2) -> Rgb {
        self.filtered(self.filter, uv, |i, j| self.texel(i, j))
    }

    /// The colour at `uv` filtered with `filter` (whatever the sampler says).
    #[inline]
    fn lookup_with(&self, filter: Filter, uv: Vec2) -> Rgb {
        self.filtered(filter, uv, |i, j| self.texel(i, j))
    }

    /// The value of `texel(i, j)` filtered at `uv` with `filter` and the texture's wrap modes.
    #[inline]
    fn filtered<T>(&self, filter: Filter, uv: Vec2, texel: impl Fn(usize, usize) -> T) -> T
    where
        T: std::ops::Mul<f32, Output = T> + std::ops::Add<Output = T>,
    {
        let (w, h) = (self.width as i64, self.height as i64);
        let x = uv.x * w as f32;
        let y = uv.y * h as f32;
        if !(x.is_finite() && y.is_finite()) {
            return texel(0, 0);
        }
        match filter {
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

    /// The linear colour and alpha of texel `k` (row-major).
    #[inline]
    fn linear_texel(&self, k: usize) -> [f32; 4] {
        let c = self.texel_at(k);
        let alpha = match &self.texels {
            Texels::Linear { alpha, .. } => alpha.get(k).copied().unwrap_or(1.0),
            Texels::Bytes { data, channels, .. } if channels.is_multiple_of(2) => {
                alpha_of(data[k * channels + channels - 1])
            }
            Texels::Bytes { .. } => 1.0,
        };
        [c.x, c.y, c.z, alpha]
    }

    /// The next mipmap level: half the size along each axis (rounded down, at least 1),
    /// each texel the area-weighted mean of the texels its rectangle covers, in linear values
    /// (a box filter; with an odd size a texel is shared by two), stored as this level is
    /// (8-bit texels re-encoded to the nearest byte in the same encoding). Works a row at a
    /// time: no linear copy of the level is made.
    fn downsampled(&self) -> Texture {
        let (w, h) = (self.width as usize, self.height as usize);
        let (w2, h2) = ((w / 2).max(1), (h / 2).max(1));
        let mut columns = Vec::new();
        box_weights(w, w2, |i, k, weight| columns.push((i, k, weight)));
        let mut rows = Vec::new();
        box_weights(h, h2, |j, k, weight| rows.push((j, k, weight)));
        let mut writer = LevelWriter::new(&self.texels, w2 * h2);
        let mut line = vec![[0.0f32; 4]; w2];
        let mut next_row = 0;
        for j in 0..h2 {
            line.fill([0.0; 4]);
            while let Some(&(_, k, wy)) = rows.get(next_row).filter(|r| r.0 == j) {
                for &(i, kx, wx) in &columns {
                    let texel = self.linear_texel(k * w + kx);
                    for (sum, value) in line[i].iter_mut().zip(texel) {
                        *sum += value * wx * wy;
                    }
                }
                next_row += 1;
            }
            line.iter().for_each(|t| writer.push(t));
        }
        Texture {
            width: w2 as u32,
            height: h2 as u32,
            texels: writer.finish(),
            ..*self
        }
    }
}

/// Texels of a new level stored as those of `like` are, one linear texel at a time.
enum LevelWriter<'a> {
    Linear {
        rgb: Vec<Rgb>,
        alpha: Option<Vec<f32>>,
    },
    Bytes {
        data: Vec<u8>,
        channels: usize,
        decode: &'a [f32; 256],
        has_alpha: bool,
    },
}

impl<'a> LevelWriter<'a> {
    fn new(like: &'a Texels, texels: usize) -> Self {
        match like {
            Texels::Linear { alpha, .. } => LevelWriter::Linear {
                rgb: Vec::with_capacity(texels),
                alpha: (!alpha.is_empty()).then(|| Vec::with_capacity(texels)),
            },
            Texels::Bytes {
                channels,
                decode,
                has_alpha,
                ..
            } => LevelWriter::Bytes {
                data: Vec::with_capacity(texels * channels),
                channels: *channels,
                decode,
                has_alpha: *has_alpha,
            },
        }
    }

    fn push(&mut self, t: &[f32; 4]) {
        match self {
            LevelWriter::Linear { rgb, alpha } => {
                rgb.push(Rgb::new(t[0], t[1], t[2]));
                if let Some(alpha) = alpha {
                    alpha.push(t[3]);
                }
            }
            LevelWriter::Bytes {
                data,
                channels,
                decode,
                ..
            } => {
                let colour = if *channels <= 2 { &t[..1] } else { &t[..3] };
                data.extend(colour.iter().map(|&x| encode_byte(decode, x)));
                if channels.is_multiple_of(2) {
                    data.push((t[3].clamp(0.0, 1.0) * 255.0).round() as u8);
                }
            }
        }
    }

    fn finish(self) -> Texels {
        match self {
            LevelWriter::Linear { rgb, alpha } => Texels::Linear {
                rgb,
                alpha: alpha.unwrap_or_default(),
            },
            LevelWriter::Bytes {
                data,
                channels,
                decode,
                has_alpha,
            } => Texels::Bytes {
                data,
                channels,
                decode: Box::new(*decode),
                has_alpha,
            },
        }
    }
}

/// The byte whose decoded value (by the increasing table `decode`) is nearest `x`.
fn encode_byte(decode: &[f32; 256], x: f32) -> u8 {
    let above = decode.partition_point(|&d| d < x).min(255);
    if above > 0 && (x - decode[above - 1]) <= (decode[above] - x) {
        (above - 1) as u8
    } else {
        above as u8
    }
}

/// The weights of a box filter that reduces `n` texels to `m` (`m <= n`): destination texel
/// `i` covers source texels `[i n / m, (i + 1) n / m)`, each counted by the length it
/// overlaps; calls `add(i, k, weight)` for each overlap (weights of one `i` sum to 1).
fn box_weights(n: usize, m: usize, mut add: impl FnMut(usize, usize, f32)) {
    let scale = n as f64 / m as f64;
    for i in 0..m {
        let (start, end) = (i as f64 * scale, (i + 1) as f64 * scale);
        let mut k = start.floor() as usize;
        while (k as f64) < end && k < n {
            let overlap = (end.min(k as f64 + 1.0) - start.max(k as f64)) / scale;
            if overlap > 0.0 {
                add(i, k, overlap as f32);
            }
            k += 1;
        }
    }
}

/// A texture with its mipmap levels, as the render scene holds it: built once per texture
/// by flatten ([`Mipmapped::new`]) when its minification filter reads mipmaps. Level 0 is
/// the image itself (shared with the scene that loaded it); each further level halves the
/// size ([`Texture::downsampled`]) down to 1 x 1, adding a third to the texels' memory.
/// Dereferences to the image, whose lookups are level 0's.
#[derive(Clone, Debug, PartialEq)]
pub struct Mipmapped {
    image: Arc<Texture>,
    /// Levels 1, 2, ... (empty when the sampler reads no mipmaps).
    levels: Vec<Texture>,
    /// `log2(width x height) / 2`: the texture's part of the level of detail.
    half_log2_texels: f32,
}

impl std::ops::Deref for Mipmapped {
    type Target = Texture;
    fn deref(&self) -> &Texture {
        &self.image
    }
}

impl Mipmapped {
    /// The image with its mipmap levels if its minification filter reads them.
    pub fn new(image: Arc<Texture>) -> Self {
        let mut levels: Vec<Texture> = Vec::new();
        if image.min_filter.uses_mipmaps() {
            let mut last: &Texture = &image;
            while last.width > 1 || last.height > 1 {
                levels.push(last.downsampled());
                last = levels.last().expect("just pushed");
            }
        }
        let half_log2_texels = 0.5 * (image.width as f32 * image.height as f32).log2();
        Mipmapped {
            image,
            levels,
            half_log2_texels,
        }
    }

    /// The number of levels, the image included.
    pub fn level_count(&self) -> usize {
        1 + self.levels.len()
    }

    /// The bytes the mipmap levels (beyond the image) take.
    pub fn mipmap_bytes(&self) -> usize {
        self.levels.iter().map(Texture::texel_bytes).sum()
    }

    /// Level `k` (0: the image), the last one beyond the chain.
    fn level(&self, k: usize) -> &Texture {
        match k {
            0 => &self.image,
            _ => &self.levels[(k - 1).min(self.levels.len() - 1)],
        }
    }

    /// The level of detail of a lookup through `transform` at a hit whose footprint gives
    /// `log2_footprint` ([`crate::ray_cone`]: log2 of the footprint's width in texture
    /// coordinates of the mesh); negative infinity (level 0) without a footprint.
    #[inline]
    pub fn level_of_detail(&self, transform: &UvTransform, log2_footprint: f32) -> f32 {
        let [r0, r1] = transform.0;
        let det = (r0[0] * r1[1] - r0[1] * r1[0]).abs();
        log2_footprint + self.half_log2_texels + 0.5 * det.log2()
    }

    /// The colour at `uv` for level of detail `lod` (log2 of the footprint's width in
    /// texels): the magnification filter at level 0 where `lod <= 0` (or is not a number),
    /// else the minification filter, across the two nearest levels (trilinear) or at the
    /// nearest as the sampler says, clamped to the last level.
    #[inline]
    pub fn lookup_at(&self, uv: Vec2, lod: f32) -> Rgb {
        if lod.is_nan() || lod <= 0.0 {
            return self.image.lookup(uv);
        }
        let (filter, blend) = self.image.min_filter.parts();
        let last = self.levels.len() as f32;
        match blend {
            None => self.image.lookup_with(filter, uv),
            Some(false) => {
                let k = (lod + 0.5).floor().min(last) as usize;
                self.level(k).lookup_with(filter, uv)
            }
            Some(true) => {
                let lod = lod.min(last);
                let k = lod.floor();
                let f = lod - k;
                let k = k as usize;
                let near = self.level(k).lookup_with(filter, uv);
                if f > 0.0 {
                    near * (1.0 - f) + self.level(k + 1).lookup_with(filter, uv) * f
                } else {
                    near
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
    /// Red multiplies the clearcoat (`KHR_materials_clearcoat`).
    pub clearcoat: TextureRef,
    /// Green multiplies the clearcoat's roughness.
    pub clearcoat_roughness: TextureRef,
    /// The coat's own tangent-space normal map.
    pub clearcoat_normal: TextureRef,
    /// Multiplies the coat's normal map's x and y.
    pub clearcoat_normal_scale: f32,
    /// Multiplies the sheen colour (`KHR_materials_sheen`).
    pub sheen_color: TextureRef,
    /// Alpha multiplies the sheen's roughness.
    pub sheen_roughness: TextureRef,
    /// Red multiplies the thin film's factor (`KHR_materials_iridescence`).
    pub iridescence: TextureRef,
    /// Green mixes the thin film's thickness from its minimum to its maximum.
    pub iridescence_thickness: TextureRef,
    /// Whether the material is anisotropic: its direction is turned into each hit's
    /// shading frame (`KHR_materials_anisotropy`).
    pub anisotropic: bool,
    /// Red and green the anisotropy direction in tangent space, blue multiplies its strength.
    pub anisotropy: TextureRef,
}

impl SurfaceTextures {
    /// Whether the material reads no texture (the common, fast case).
    #[inline]
    pub fn is_empty(&self) -> bool {
        !(self.base_color.is_set()
            || self.metallic_roughness.is_set()
            || self.normal.is_set()
            || self.clearcoat_normal.is_set()
            || self.specular.is_set()
            || self.specular_color.is_set()
            || self.has_layer_textures()
            || self.has_film_textures()
            || self.anisotropic)
    }

    /// Whether a thin-film (iridescence) texture is set.
    #[inline]
    pub fn has_film_textures(&self) -> bool {
        self.iridescence.is_set() || self.iridescence_thickness.is_set()
    }

    /// Whether a clearcoat or sheen texture is set.
    #[inline]
    pub fn has_layer_textures(&self) -> bool {
        self.clearcoat.is_set()
            || self.clearcoat_roughness.is_set()
            || self.sheen_color.is_set()
            || self.sheen_roughness.is_set()
    }
}

/// The alpha coverage (MASK or BLEND) of an emitting triangle, as light sampling weighs
/// its points: the coverage is the material's factor x the base-colour texture's alpha
/// (level 0) x the vertex colours' alpha; a sampled point emits its radiance times the
/// coverage (BLEND, as Cycles' mix of transparent and emission shaders) or times whether the
/// coverage reaches the cutoff (MASK). Rays that hit the surface pass the coverage test
/// already, so a hit sees the radiance in full.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EmissionCoverage {
    /// MASK (with its cutoff) or BLEND.
    pub mode: crate::scene::AlphaMode,
    /// The material's alpha factor.
    pub factor: f32,
    /// The base-colour texture, when its alpha counts (else unset).
    pub texture: TextureRef,
    /// The vertex colours' alpha at the triangle's vertices (1 without).
    pub vertex_alpha: [f32; 3],
}

/// The emission texture and alpha coverage of one triangle light (either may be absent). Its
/// [`crate::lights::AreaLight::radiance`] is `radiance` times the texture's mean (the power
/// estimate that chooses lights); the radiance leaving a point is `radiance` times the texel
/// there (times the coverage for a point light sampling chose: [`EmissionCoverage`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TexturedEmission {
    /// The emissive texture (unset: none).
    pub texture: TextureRef,
    /// The emitter's radiance before the texture (`emissiveFactor` x strength).
    pub radiance: Rgb,
    /// Per channel, 1 / the texture's mean (0 where the mean is 0, which makes the texture 0
    /// everywhere in that channel): turns a light sample drawn for the mean into one for the texel.
    pub inverse_mean: Rgb,
    /// Texture coordinates of the triangle's vertices, in the light's vertex order.
    pub uvs: [Vec2; 3],
    /// The alpha coverage of an emitter with alpha MASK or BLEND.
    pub coverage: Option<EmissionCoverage>,
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

    fn linear_mean(t: &Texture) -> Rgb {
        t.mean()
    }

    #[test]
    fn mipmap_levels_halve_down_to_one_texel_and_keep_the_mean() {
        // 5 x 3 linear texels of distinct values: levels 2 x 1 and 1 x 1, each the
        // area-weighted box of the one before, so every level averages to the image's mean.
        let texels: Vec<Rgb> = (0..15)
            .map(|k| Rgb::new(k as f32, (k * k) as f32, 1.0))
            .collect();
        let image = Texture::new(5, 3, texels).unwrap();
        let mipmapped = Mipmapped::new(Arc::new(image.clone()));
        assert_eq!(mipmapped.level_count(), 3);
        assert_eq!(mipmapped.level(1).size(), (2, 1));
        assert_eq!(mipmapped.level(2).size(), (1, 1));
        for k in 1..3 {
            let error = (linear_mean(mipmapped.level(k)) - image.mean())
                .abs()
                .max_element();
            assert!(
                error < 1e-4 * image.mean().max_element(),
                "level {k}: {error}"
            );
        }
        // Texel (0, 0) of level 1 covers columns [0, 2.5) of all three rows.
        let expected = [0, 1, 5, 6, 10, 11].iter().map(|&k| k as f32).sum::<f32>()
            + 0.5 * [2, 7, 12].iter().map(|&k| k as f32).sum::<f32>();
        let level1 = mipmapped.level(1).texel(0, 0).x;
        assert!((level1 - expected / 7.5).abs() < 1e-5, "{level1}");
        // A texture whose sampler reads no mipmaps gets none.
        let mut plain = image;
        plain.min_filter = MinFilter::Linear;
        assert_eq!(Mipmapped::new(Arc::new(plain)).level_count(), 1);
    }

    #[test]
    fn srgb_levels_average_in_linear_space() {
        // Black and white sRGB bytes average to linear 0.5 (sRGB byte 188), not to byte 128.
        let bytes = vec![0, 0, 0, 255, 255, 255, 255, 255, 255, 0, 0, 0];
        let t = Texture::from_srgb8(2, 2, 3, bytes).unwrap();
        let m = Mipmapped::new(Arc::new(t));
        let grey = m.level(1).texel(0, 0);
        // The nearest byte is 188 (0.5029; 187 decodes to 0.4969).
        assert_eq!(grey, Rgb::splat(srgb_to_linear(188.0 / 255.0)), "{grey}");
        assert!(matches!(m.level(1).texels, Texels::Bytes { .. }));
        // Alpha is averaged as it is (linear).
        let t = Texture::from_srgb8(2, 1, 2, vec![255, 255, 255, 51]).unwrap();
        let m = Mipmapped::new(Arc::new(t));
        assert_eq!(m.level(1).lookup_alpha(Vec2::splat(0.5)), 153.0 / 255.0);
    }

    #[test]
    fn lookups_blend_levels_as_the_minification_filter_says() {
        // An 8 x 8 checker of single texels: level 0 alternates, levels 1 up are grey 0.5.
        let texels: Vec<Rgb> = (0..64)
            .map(|k| Rgb::splat(((k % 8 + k / 8) % 2) as f32))
            .collect();
        let mut image = Texture::new(8, 8, texels).unwrap();
        image.filter = Filter::Nearest;
        let uv = Vec2::new(0.5 / 8.0, 0.5 / 8.0); // the centre of texel (0, 0), black
        let grey = Rgb::splat(0.5);
        let close = |a: Rgb, b: Rgb| (a - b).abs().max_element() < 1e-6;
        for (filter, at_half, at_two) in [
            (MinFilter::LinearMipmapLinear, Rgb::splat(0.25), grey),
            (MinFilter::NearestMipmapLinear, Rgb::splat(0.25), grey),
            (MinFilter::LinearMipmapNearest, grey, grey),
            (MinFilter::NearestMipmapNearest, grey, grey),
            (MinFilter::Linear, Rgb::ZERO, Rgb::ZERO),
            (MinFilter::Nearest, Rgb::ZERO, Rgb::ZERO),
        ] {
            image.min_filter = filter;
            let m = Mipmapped::new(Arc::new(image.clone()));
            assert_eq!(
                m.lookup_at(uv, 0.0),
                Rgb::ZERO,
                "{filter:?}: level 0, magnified"
            );
            assert_eq!(
                m.lookup_at(uv, f32::NAN),
                Rgb::ZERO,
                "{filter:?}: no footprint"
            );
            assert!(close(m.lookup_at(uv, 0.5), at_half), "{filter:?}");
            assert!(close(m.lookup_at(uv, 2.0), at_two), "{filter:?}");
            assert!(close(m.lookup_at(uv, 1e9), at_two), "{filter:?}: clamped");
        }
    }

    #[test]
    fn the_level_of_detail_counts_texels_and_the_uv_transform() {
        let image = Texture::new(256, 64, vec![Rgb::ONE; 256 * 64]).unwrap();
        let m = Mipmapped::new(Arc::new(image));
        // A footprint of 1/128 of the texture square covers sqrt(256 x 64) / 128 = 1 texel.
        let lod = m.level_of_detail(&UvTransform::IDENTITY, -7.0);
        assert!(lod.abs() < 1e-6, "{lod}");
        // Scaling the coordinates by 4 makes the footprint 4 times as wide in texels.
        let t = UvTransform::from_offset_rotation_scale([0.3, 0.1], 0.7, [4.0, 4.0]);
        assert!((m.level_of_detail(&t, -7.0) - 2.0).abs() < 1e-5);
        assert_eq!(m.level_of_detail(&t, f32::NEG_INFINITY), f32::NEG_INFINITY);
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
