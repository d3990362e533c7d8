//! Linear RGB images and their display form (clamped to [0, 1], quantized to 8 bits).

use std::{fs::File, path::Path};

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

/// Quantize one linear channel as displayed: clamp to [0, 1], round to 8 bits.
#[inline]
pub fn quantize(v: f32) -> u8 {
    if v.is_nan() {
        return 0;
    }
    (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
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
            .for_each(|(o, px)| {
                for (o, p) in o.chunks_exact_mut(3).zip(px) {
                    o.copy_from_slice(&[quantize(p.x), quantize(p.y), quantize(p.z)]);
                }
            });
        out
    }

    /// Write the displayed image as PNG, atomically (see [`write_png_rgb8`]).
    pub fn save_png(&self, path: &Path) -> std::io::Result<()> {
        write_png_rgb8(path, self.width, self.height, &self.to_rgb8())
    }
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

/// Read a PNG exactly as stored (no expansion of palettes, depths or alpha).
pub fn read_png(path: &Path) -> std::io::Result<StoredPng> {
    let dec = png::Decoder::new(std::io::BufReader::new(File::open(path)?));
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
}
