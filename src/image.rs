//! RGB images and their two file forms. The renderer's values are display values, the
//! scenes' own convention (docs/colour.md): a PNG holds them clamped to [0, 1] and
//! quantized to 8 bits, which is what a viewer expects of a PNG (sRGB-encoded bytes);
//! an OpenEXR file holds linear light, as EXR viewers expect, which is
//! [`display_to_linear`] of each value, unclamped (HDR).

use std::path::Path;

use glam::Vec3;

use crate::output;

/// A linear RGB image, row-major, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Pixels.
    pub pixels: Vec<Vec3>,
}

/// Quantize one channel as displayed: clamp to [0, 1], round to 8 bits (NaN: 0).
#[inline]
pub fn quantize(v: f32) -> u8 {
    // A NaN stays NaN through the clamp, and `as` turns it into 0: no branch, so
    // loops over pixels compile to vector code.
    (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
}

/// `px` quantized into `out`, three bytes a pixel.
fn quantize_pixels(px: &[Vec3], out: &mut [u8]) {
    for (o, p) in out.chunks_exact_mut(3).zip(px) {
        o.copy_from_slice(&[quantize(p.x), quantize(p.y), quantize(p.z)]);
    }
}

/// Linear light of a display value: the sRGB decoding (IEC 61966-2-1), continued past
/// 1 along its power curve for the highlights a PNG clips, and odd about 0, so that
/// every value keeps its information. What an OpenEXR file holds of a display value.
pub fn display_to_linear(v: f32) -> f32 {
    let a = f64::from(v).abs();
    let l = if a <= 0.04045 {
        a / 12.92
    } else {
        ((a + 0.055) / 1.055).powf(2.4)
    };
    (l.copysign(f64::from(v))) as f32
}

/// The display value of linear light: the inverse of [`display_to_linear`] (sRGB
/// encoding, continued past 1 and odd about 0).
pub fn linear_to_display(v: f32) -> f32 {
    let l = f64::from(v).abs();
    let a = if l <= 0.0031308 {
        l * 12.92
    } else {
        1.055 * l.powf(1.0 / 2.4) - 0.055
    };
    (a.copysign(f64::from(v))) as f32
}

impl Image {
    /// A black image.
    pub fn new(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            pixels: vec![Vec3::ZERO; (width as usize) * (height as usize)],
        }
    }

    /// Pixel at `(x, y)`.
    pub fn get(&self, x: u32, y: u32) -> Vec3 {
        self.pixels[(y * self.width + x) as usize]
    }

    /// The displayed image: 8-bit RGB, clamped and quantized.
    pub fn to_rgb8(&self) -> Vec<u8> {
        use rayon::prelude::*;
        let mut out = vec![0u8; self.pixels.len() * 3];
        out.par_chunks_mut(3 * 4096)
            .zip(self.pixels.par_chunks(4096))
            .for_each(|(o, px)| quantize_pixels(px, o));
        out
    }

    /// [`Image::to_rgb8`] into `out` (resized to fit), on the calling thread.
    pub fn quantize_into(&self, out: &mut Vec<u8>) {
        out.resize(self.pixels.len() * 3, 0);
        quantize_pixels(&self.pixels, out);
    }

    /// Write the displayed image as PNG, atomically (see [`write_png_rgb8`]).
    pub fn save_png(&self, path: &Path) -> std::io::Result<()> {
        write_png_rgb8(path, self.width, self.height, &self.to_rgb8())
    }

    /// Write the image as OpenEXR: linear light ([`display_to_linear`] of every value),
    /// 32-bit float RGB, nothing clamped or quantized, atomically (see
    /// [`crate::output`]).
    pub fn save_exr(&self, path: &Path) -> std::io::Result<()> {
        use exr::prelude::{Image as ExrImage, SpecificChannels, Vec2, WritableImage};
        // An EXR under another format's name would mislead every program that opens it.
        output::require_extension(path, "exr", "OpenEXR")
            .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidInput, e.to_string()))?;
        let w = self.width as usize;
        let channels = SpecificChannels::rgb(|Vec2(x, y): Vec2<usize>| {
            let p = self.pixels[y * w + x].to_array().map(display_to_linear);
            (p[0], p[1], p[2])
        });
        let image = ExrImage::from_channels((w, self.height as usize), channels);
        output::write_seekable(path, |file| image.write().to_buffered(file).map_err(exr_io))
    }

    /// The same image in linear light, as [`Image::save_exr`] writes it.
    pub fn to_linear(&self) -> Image {
        self.map(display_to_linear)
    }

    /// The display values of an image in linear light (as [`read_exr`] reads one).
    pub fn to_display_values(&self) -> Image {
        self.map(linear_to_display)
    }

    fn map(&self, f: fn(f32) -> f32) -> Image {
        let pixels = self
            .pixels
            .iter()
            .map(|p| Vec3::from_array(p.to_array().map(f)))
            .collect();
        Image { pixels, ..*self }
    }

    /// Write the image in `format`: PNG as displayed, OpenEXR in linear light.
    pub fn save(&self, path: &Path, format: ImageFormat) -> std::io::Result<()> {
        match format {
            ImageFormat::Png => self.save_png(path),
            ImageFormat::Exr => self.save_exr(path),
        }
    }
}

/// The file formats images are written in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageFormat {
    /// 8-bit RGB PNG of the displayed image: clamped to [0, 1] and quantized.
    Png,
    /// 32-bit float RGB OpenEXR in linear light (high dynamic range).
    Exr,
}

impl ImageFormat {
    /// Every format: extension (lowercase, no dot) and name.
    pub const ALL: [(ImageFormat, &'static str, &'static str); 2] = [
        (ImageFormat::Png, "png", "PNG, display-quantised 8-bit"),
        (ImageFormat::Exr, "exr", "OpenEXR, linear HDR"),
    ];

    /// The file name extension, lowercase, without the dot.
    pub fn extension(self) -> &'static str {
        match self {
            ImageFormat::Png => "png",
            ImageFormat::Exr => "exr",
        }
    }

    /// Check, before any work, that an image can be written at `path` (see
    /// [`output::check_file_target`]) and choose its format by the extension: `.png` or
    /// `.exr` (any case); anything else is an error naming both.
    pub fn for_output(path: &Path) -> Result<Self, output::OutputError> {
        let formats = Self::ALL.map(|(_, x, name)| (x, name));
        let x = output::check_file_target_of(path, &formats)?;
        Ok(Self::ALL
            .iter()
            .find(|(_, e, _)| *e == x)
            .map(|(f, _, _)| *f)
            .expect("a listed extension"))
    }
}

fn exr_io(e: exr::error::Error) -> std::io::Error {
    match e {
        exr::error::Error::Io(e) => e,
        other => std::io::Error::other(other.to_string()),
    }
}

/// Read the first RGB(A) layer of an OpenEXR file as stored, in linear light (alpha
/// dropped); [`Image::to_display_values`] gives its display values.
pub fn read_exr(path: &Path) -> std::io::Result<Image> {
    let read = exr::prelude::read_first_rgba_layer_from_file(
        path,
        |size, _| Image::new(size.0 as u32, size.1 as u32),
        |img: &mut Image, pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            let w = img.width as usize;
            img.pixels[pos.1 * w + pos.0] = Vec3::new(r, g, b);
        },
    )
    .map_err(exr_io)?;
    Ok(read.layer_data.channel_data.pixels)
}

/// Write 8-bit RGB data as a PNG file, atomically (see [`crate::output`]), with
/// compact (slower) compression.
pub fn write_png_rgb8(path: &Path, width: u32, height: u32, rgb: &[u8]) -> std::io::Result<()> {
    write_png(path, width, height, rgb, png::Compression::Balanced, &[])
}

/// As [`write_png_rgb8`] with fast (larger) compression, for caches and sequences.
pub fn write_png_rgb8_fast(
    path: &Path,
    width: u32,
    height: u32,
    rgb: &[u8],
) -> std::io::Result<()> {
    write_png(path, width, height, rgb, png::Compression::Fast, &[])
}

/// As [`write_png_rgb8_fast`], with `(keyword, text)` tEXt chunks (Latin-1 text).
pub fn write_png_rgb8_tagged(
    path: &Path,
    width: u32,
    height: u32,
    rgb: &[u8],
    text: &[(&str, &str)],
) -> std::io::Result<()> {
    write_png(path, width, height, rgb, png::Compression::Fast, text)
}

/// Write a palette PNG: one byte a pixel indexing `palette` (RGB triples, at most 256),
/// atomically (see [`crate::output`]).
pub fn write_png_indexed(
    path: &Path,
    width: u32,
    height: u32,
    indices: &[u8],
    palette: &[u8],
) -> std::io::Result<()> {
    output::require_extension(path, "png", "PNG")
        .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidInput, e.to_string()))?;
    output::write_with(path, |file| {
        let mut enc = png::Encoder::new(file, width, height);
        enc.set_color(png::ColorType::Indexed);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_palette(palette.to_vec());
        enc.set_compression(png::Compression::Balanced);
        let mut w = enc.write_header().map_err(std::io::Error::other)?;
        w.write_image_data(indices).map_err(std::io::Error::other)?;
        w.finish().map_err(std::io::Error::other)
    })
}

fn write_png(
    path: &Path,
    width: u32,
    height: u32,
    rgb: &[u8],
    level: png::Compression,
    text: &[(&str, &str)],
) -> std::io::Result<()> {
    // PNG bytes under another format's name would mislead every program that opens it.
    output::require_extension(path, "png", "PNG")
        .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidInput, e.to_string()))?;
    output::write_with(path, |file| {
        let mut enc = png::Encoder::new(file, width, height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_compression(level);
        for (keyword, t) in text {
            enc.add_text_chunk(keyword.to_string(), t.to_string())
                .map_err(std::io::Error::other)?;
        }
        let mut w = enc.write_header().map_err(std::io::Error::other)?;
        w.write_image_data(rgb).map_err(std::io::Error::other)?;
        w.finish().map_err(std::io::Error::other)
    })
}

/// Read an 8-bit RGB or RGBA PNG (used by tests and reference comparisons).
pub fn read_png_rgb8(path: &Path) -> std::io::Result<(u32, u32, Vec<u8>)> {
    let png = read_png(path)?;
    let rgb = match png.color {
        png::ColorType::Rgb => png.data,
        png::ColorType::Rgba => png
            .data
            .chunks(4)
            .flat_map(|c| [c[0], c[1], c[2]])
            .collect(),
        other => {
            return Err(std::io::Error::other(format!(
                "unsupported PNG color type {other:?}"
            )));
        }
    };
    Ok((png.width, png.height, rgb))
}

/// A PNG as stored in its file, without conversions.
pub struct StoredPng {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Colour type of the file.
    pub color: png::ColorType,
    /// Bits per channel of the file.
    pub depth: png::BitDepth,
    /// Pixel data, rows in order, in the file's colour type and depth.
    pub data: Vec<u8>,
    /// The tEXt chunks before the image data, as `(keyword, text)`.
    pub text: Vec<(String, String)>,
}

/// Read a PNG exactly as stored (no expansion of palettes, depths or alpha). Only a
/// regular file within the data-file limit is read ([`crate::limits::read_file`]): a
/// strip or cache entry may be a link to a device.
pub fn read_png(path: &Path) -> std::io::Result<StoredPng> {
    let bytes = crate::limits::read_file(path, crate::limits::MAX_DATA_FILE_BYTES)?;
    let dec = png::Decoder::new(std::io::Cursor::new(bytes));
    let mut reader = dec.read_info().map_err(std::io::Error::other)?;
    let text = reader
        .info()
        .uncompressed_latin1_text
        .iter()
        .map(|c| (c.keyword.clone(), c.text.clone()))
        .collect();
    let mut buf = vec![0; reader.output_buffer_size().unwrap_or(0)];
    let info = reader.next_frame(&mut buf).map_err(std::io::Error::other)?;
    buf.truncate(info.buffer_size());
    Ok(StoredPng {
        width: info.width,
        height: info.height,
        color: info.color_type,
        depth: info.bit_depth,
        data: buf,
        text,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantize_clamps_and_rounds() {
        assert_eq!(quantize(-1.0), 0);
        assert_eq!(quantize(2.0), 255);
        assert_eq!(quantize(0.5), 128);
        assert_eq!(quantize(f32::NAN), 0);
    }

    #[test]
    fn quantizing_on_one_thread_is_the_displayed_image() {
        let mut im = Image::new(97, 61);
        for (i, p) in im.pixels.iter_mut().enumerate() {
            let v = (i as f32 * 0.37).sin() * 1.4 - 0.2;
            *p = Vec3::new(v, -v, if i % 7 == 0 { f32::NAN } else { v * 0.5 });
        }
        // A reused buffer of another size is resized and overwritten.
        let mut out = vec![9u8; 5];
        im.quantize_into(&mut out);
        assert_eq!(out, im.to_rgb8());
    }

    #[test]
    fn the_srgb_transform_is_the_standards_and_its_own_inverse() {
        // IEC 61966-2-1 values: black, white, the segment joint, mid-grey.
        assert_eq!(display_to_linear(0.0), 0.0);
        assert_eq!(display_to_linear(1.0), 1.0);
        assert!((display_to_linear(0.04045) - 0.04045 / 12.92).abs() < 1e-9);
        assert!((display_to_linear(0.5) - 0.214_041).abs() < 1e-6);
        for i in -40..=80 {
            let v = i as f32 * 0.05;
            let back = linear_to_display(display_to_linear(v));
            assert!((back - v).abs() <= 1e-6 * v.abs().max(1.0), "{v}: {back}");
            // Monotone and odd: no value's order or sign is lost.
            assert_eq!(display_to_linear(-v), -display_to_linear(v));
            assert!(display_to_linear(v + 0.05) > display_to_linear(v));
        }
    }

    #[test]
    fn png_round_trip() {
        let dir = std::env::temp_dir().join(format!("frameless-png-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut img = Image::new(3, 2);
        img.pixels[4] = Vec3::new(1.0, 0.5, 0.0);
        let p = dir.join("a.png");
        img.save_png(&p).unwrap();
        let (w, h, rgb) = read_png_rgb8(&p).unwrap();
        assert_eq!((w, h), (3, 2));
        assert_eq!(rgb, img.to_rgb8());
        // PNG bytes are never written under another format's name.
        let e = img.save_png(&dir.join("a.jpg")).unwrap_err().to_string();
        assert!(e.contains(".jpg"), "{e}");
        assert!(!dir.join("a.jpg").exists());
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn exr_holds_linear_light_png_the_display() {
        let dir = std::env::temp_dir().join(format!("frameless-exr-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut img = Image::new(5, 3);
        for (i, p) in img.pixels.iter_mut().enumerate() {
            // Values past [0, 1] and between 8-bit steps: what PNG cannot hold.
            *p = Vec3::new(i as f32 * 0.37, 1.0 / (i as f32 + 3.0), 12.5 - i as f32);
        }
        let p = dir.join("a.EXR");
        assert_eq!(ImageFormat::for_output(&p).unwrap(), ImageFormat::Exr);
        img.save(&p, ImageFormat::Exr).unwrap();
        let stored = read_exr(&p).unwrap();
        assert_eq!(stored, img.to_linear());
        // Back through the documented transform, to within float rounding.
        for (a, b) in stored.to_display_values().pixels.iter().zip(&img.pixels) {
            assert!((*a - *b).abs().max_element() <= 1e-5 * b.abs().max_element().max(1.0));
        }
        let png = dir.join("a.png");
        assert_eq!(ImageFormat::for_output(&png).unwrap(), ImageFormat::Png);
        img.save(&png, ImageFormat::Png).unwrap();
        assert_eq!(read_png_rgb8(&png).unwrap().2, img.to_rgb8());
        let e = ImageFormat::for_output(&dir.join("a.jpg"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(".jpg") && e.contains(".png") && e.contains(".exr"),
            "{e}"
        );
        assert!(img.save_exr(&dir.join("b.png")).is_err());
        std::fs::remove_dir_all(&dir).ok();
    }
}
