//! Linear RGB images and their display form (clamped to [0, 1], quantized to 8 bits).

use std::{fs::File, io::BufWriter, path::Path};

use glam::Vec3;

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

    /// Write the displayed image as PNG. Writes to a temporary file first and renames,
    /// so an interrupted write never leaves a truncated PNG under the final name.
    pub fn save_png(&self, path: &Path) -> std::io::Result<()> {
        write_png_rgb8(path, self.width, self.height, &self.to_rgb8())
    }
}

/// Write 8-bit RGB data as a PNG file, atomically (temporary file + rename), with
/// compact (slower) compression.
pub fn write_png_rgb8(path: &Path, width: u32, height: u32, rgb: &[u8]) -> std::io::Result<()> {
    write_png(path, width, height, rgb, png::Compression::Balanced)
}

/// As [`write_png_rgb8`] with fast (larger) compression, for caches.
pub fn write_png_rgb8_fast(
    path: &Path,
    width: u32,
    height: u32,
    rgb: &[u8],
) -> std::io::Result<()> {
    write_png(path, width, height, rgb, png::Compression::Fast)
}

/// Write bytes to `path` atomically (temporary file beside it + rename), so an
/// interrupted run never leaves a truncated file that looks complete.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(".partial");
    let tmp = path.with_file_name(name);
    std::fs::write(&tmp, bytes)?;
    std::fs::rename(&tmp, path)
}

fn write_png(
    path: &Path,
    width: u32,
    height: u32,
    rgb: &[u8],
    level: png::Compression,
) -> std::io::Result<()> {
    let tmp = path.with_extension("png.partial");
    {
        let file = BufWriter::new(File::create(&tmp)?);
        let mut enc = png::Encoder::new(file, width, height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_compression(level);
        let mut w = enc.write_header().map_err(std::io::Error::other)?;
        w.write_image_data(rgb).map_err(std::io::Error::other)?;
        w.finish().map_err(std::io::Error::other)?;
    }
    std::fs::rename(&tmp, path)
}

/// Read an 8-bit RGB or RGBA PNG (used by tests and reference comparisons).
pub fn read_png_rgb8(path: &Path) -> std::io::Result<(u32, u32, Vec<u8>)> {
    let dec = png::Decoder::new(std::io::BufReader::new(File::open(path)?));
    let mut reader = dec.read_info().map_err(std::io::Error::other)?;
    let mut buf = vec![0; reader.output_buffer_size().unwrap_or(0)];
    let info = reader.next_frame(&mut buf).map_err(std::io::Error::other)?;
    let (w, h) = (info.width, info.height);
    let data = &buf[..info.buffer_size()];
    let rgb = match info.color_type {
        png::ColorType::Rgb => data.to_vec(),
        png::ColorType::Rgba => data.chunks(4).flat_map(|c| [c[0], c[1], c[2]]).collect(),
        other => {
            return Err(std::io::Error::other(format!(
                "unsupported PNG color type {other:?}"
            )));
        }
    };
    Ok((w, h, rgb))
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
        std::fs::remove_dir_all(&dir).ok();
    }
}
