//! Decoding a texture image (PNG, JPEG, WebP) with a memory check first: an image whose
//! texels would not fit in the memory the process can still take is refused with the reason
//! (the loaders skip it with a warning, as any image that cannot be decoded), before any
//! texel is allocated.

use crate::memory::{Needed, available, shortfall};
use image::{ColorType, DynamicImage, ImageDecoder, ImageReader};
use std::io::Cursor;

/// Decodes an encoded image, refusing it (with why) if it cannot be decoded or would not fit.
pub(super) fn decode_image_bytes(bytes: &[u8]) -> Result<DynamicImage, String> {
    let decoder = ImageReader::new(Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| format!("cannot decode it: {e}"))?
        .into_decoder()
        .map_err(|e| format!("cannot decode it: {e}"))?;
    let (width, height) = decoder.dimensions();
    let needed = texture_peak_bytes(
        decoder.color_type(),
        u64::from(width) * u64::from(height),
        decoder.total_bytes(),
    );
    let what = format!("decoding its {width} x {height} texels");
    let room = Needed {
        resident: needed,
        address_space: needed,
    };
    if let Some(why) = shortfall(&what, room, available()) {
        return Err(why);
    }
    DynamicImage::from_decoder(decoder).map_err(|e| format!("cannot decode it: {e}"))
}

/// Upper bound of the bytes alive at once while an image of `texels` texels, `decoded` bytes
/// as decoded, becomes a texture. An 8-bit image's texture keeps its bytes: a copy or a
/// conversion of the decoded image, at most 4 bytes a texel. Other formats become linear RGB
/// (12 bytes a texel) and alpha (4), made through a conversion (float: an RGB copy, 12;
/// 16-bit and others: an RGBA16 copy and its two byte views, 24).
fn texture_peak_bytes(color: ColorType, texels: u64, decoded: u64) -> u64 {
    let per_texel = match color {
        ColorType::L8 | ColorType::La8 | ColorType::Rgb8 | ColorType::Rgba8 => 4,
        ColorType::Rgb32F | ColorType::Rgba32F => 16 + 12,
        _ => 16 + 24,
    };
    decoded.saturating_add(texels.saturating_mul(per_texel))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn png(width: u32, height: u32) -> Vec<u8> {
        let image = image::RgbaImage::from_fn(width, height, |x, y| {
            image::Rgba([x as u8, y as u8, 7, 255])
        });
        let mut bytes = Vec::new();
        image
            .write_to(&mut Cursor::new(&mut bytes), image::ImageFormat::Png)
            .unwrap();
        bytes
    }

    #[test]
    fn a_png_decodes_to_its_texels() {
        let decoded = decode_image_bytes(&png(5, 3)).unwrap();
        assert_eq!((decoded.width(), decoded.height()), (5, 3));
        assert_eq!(decoded.to_rgba8().get_pixel(4, 2).0, [4, 2, 7, 255]);
    }

    #[test]
    fn bytes_that_are_no_image_are_refused_with_a_reason() {
        let why = decode_image_bytes(b"not an image at all").unwrap_err();
        assert!(why.starts_with("cannot decode it"), "{why}");
    }

    #[test]
    fn the_estimate_covers_the_texture_and_the_conversions() {
        // 8-bit grey: 1 byte decoded + at most 4 for the texture's copy or conversion.
        assert_eq!(texture_peak_bytes(ColorType::L8, 10, 10), 50);
        // 16-bit RGBA: 8 decoded + 16 + 24 for the RGBA16 copy and its byte views.
        assert_eq!(texture_peak_bytes(ColorType::Rgba16, 10, 80), 480);
        assert_eq!(texture_peak_bytes(ColorType::Rgba16, u64::MAX, 1), u64::MAX);
    }
}
