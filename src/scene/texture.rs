//! Image textures: binary PPM (P6) loading, bilinear lookup with repeat wrap.
//!
//! Orientation: `v = 0` is the bottom row of the image and `v = 1` its top row (row 0
//! of the file), the OpenGL convention for images stored top row first. Checked on the
//! BART kitchen's license plate, which reads "JOCKE 1" upright only this way (with
//! row 0 at `v = 0` it is upside down). Loaders of formats with the other convention
//! (glTF: `v = 0` at the top) flip `v` when they load. Values are used as stored, `byte / 255`, without a gamma curve, matching the
//! rest of the pipeline, which displays shading values directly.

use std::path::Path;

use glam::{Vec2, Vec3};

use super::{error::ImageError, SceneError};

/// An RGB texture.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    /// Name as referenced by the scene (file name for loaded textures).
    pub name: String,
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// Texels, row-major, row 0 first.
    pub texels: Vec<Vec3>,
}

/// Largest texture side accepted, to turn absurd headers into errors instead of
/// allocation failures.
pub const MAX_TEXTURE_SIDE: u32 = 16384;

impl Texture {
    /// Build from a closure giving the color of each texel.
    pub fn from_fn(name: &str, width: u32, height: u32, f: impl Fn(u32, u32) -> Vec3) -> Self {
        let mut texels = Vec::with_capacity((width * height) as usize);
        for y in 0..height {
            for x in 0..width {
                texels.push(f(x, y));
            }
        }
        Self {
            name: name.to_string(),
            width,
            height,
            texels,
        }
    }

    /// Read a binary PPM (P6, maxval ≤ 255 or ≤ 65535, `#` comments in the header).
    pub fn load_ppm(path: &Path) -> Result<Self, SceneError> {
        let bytes = std::fs::read(path).map_err(|e| SceneError::Io {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
        let name = path
            .file_name()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        Self::parse_ppm(&name, &bytes).map_err(|source| SceneError::Texture {
            path: path.to_path_buf(),
            source,
            context: None,
        })
    }

    /// Parse PPM bytes; the error does not name the file, which the caller knows.
    pub fn parse_ppm(name: &str, bytes: &[u8]) -> Result<Self, ImageError> {
        let mut pos = 0usize;
        let mut fields = [0u32; 3];
        if bytes.len() < 2 || &bytes[0..2] != b"P6" {
            return Err(ImageError::NotPpm);
        }
        pos += 2;
        for (i, field) in fields.iter_mut().enumerate() {
            // Skip whitespace and comments.
            loop {
                match bytes.get(pos) {
                    Some(b) if b.is_ascii_whitespace() => pos += 1,
                    Some(b'#') => {
                        while pos < bytes.len() && bytes[pos] != b'\n' {
                            pos += 1;
                        }
                    }
                    _ => break,
                }
            }
            let start = pos;
            while pos < bytes.len() && bytes[pos].is_ascii_digit() {
                pos += 1;
            }
            let what = ["width", "height", "maxval"][i];
            let text = std::str::from_utf8(&bytes[start..pos]).unwrap_or("");
            *field = text
                .parse::<u32>()
                .map_err(|_| ImageError::PpmHeaderField(what))?;
        }
        // Exactly one whitespace byte separates the header from the data.
        if !bytes.get(pos).is_some_and(|b| b.is_ascii_whitespace()) {
            return Err(ImageError::PpmHeaderEnd);
        }
        pos += 1;
        let [w, h, maxval] = fields;
        if w == 0 || h == 0 || w > MAX_TEXTURE_SIDE || h > MAX_TEXTURE_SIDE {
            return Err(ImageError::Size {
                width: w,
                height: h,
            });
        }
        if maxval == 0 || maxval > 65535 {
            return Err(ImageError::PpmMaxval(maxval));
        }
        let bpc = if maxval < 256 { 1 } else { 2 };
        let need = (w as usize) * (h as usize) * 3 * bpc;
        let data = &bytes[pos..];
        if data.len() < need {
            return Err(ImageError::PpmTruncated {
                got: data.len(),
                need,
                width: w,
                height: h,
            });
        }
        let scale = 1.0 / maxval as f32;
        let texels = (0..(w * h) as usize)
            .map(|i| {
                let c = |k: usize| -> f32 {
                    let j = (i * 3 + k) * bpc;
                    let v = if bpc == 1 {
                        data[j] as u32
                    } else {
                        (data[j] as u32) << 8 | data[j + 1] as u32
                    };
                    v.min(maxval) as f32 * scale
                };
                Vec3::new(c(0), c(1), c(2))
            })
            .collect();
        Ok(Self {
            name: name.to_string(),
            width: w,
            height: h,
            texels,
        })
    }

    fn texel(&self, x: i64, y: i64) -> Vec3 {
        let x = x.rem_euclid(self.width as i64) as usize;
        let y = y.rem_euclid(self.height as i64) as usize;
        self.texels[y * self.width as usize + x]
    }

    /// Bilinear lookup with repeat wrap; texel centers sit at half-integer coordinates.
    pub fn sample(&self, uv: Vec2) -> Vec3 {
        if !uv.is_finite() {
            return self.texels[0];
        }
        let x = uv.x.rem_euclid(1.0) * self.width as f32 - 0.5;
        let y = (1.0 - uv.y.rem_euclid(1.0)) * self.height as f32 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let a = self.texel(x0, y0).lerp(self.texel(x0 + 1, y0), fx);
        let b = self.texel(x0, y0 + 1).lerp(self.texel(x0 + 1, y0 + 1), fx);
        a.lerp(b, fy)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ppm(w: u32, h: u32, px: &[u8]) -> Vec<u8> {
        let mut v = format!("P6\n# comment\n{w} {h}\n255\n").into_bytes();
        v.extend_from_slice(px);
        v
    }

    #[test]
    fn parses_and_samples_with_repeat() {
        let t = Texture::parse_ppm("t", &ppm(2, 1, &[255, 0, 0, 0, 0, 255])).unwrap();
        assert_eq!((t.width, t.height), (2, 1));
        // Texel centers: u = 0.25 is pure red, u = 0.75 pure blue, u = 1.25 wraps to red.
        assert!((t.sample(Vec2::new(0.25, 0.5)) - Vec3::X).length() < 1e-6);
        assert!((t.sample(Vec2::new(0.75, 0.5)) - Vec3::Z).length() < 1e-6);
        assert!((t.sample(Vec2::new(1.25, 0.5)) - Vec3::X).length() < 1e-6);
        // Halfway between centers: the mean.
        assert!((t.sample(Vec2::new(0.5, 0.5)) - Vec3::new(0.5, 0.0, 0.5)).length() < 1e-6);
    }

    #[test]
    fn rejects_bad_headers() {
        assert!(Texture::parse_ppm("t", b"P3\n1 1\n255\n").is_err());
        assert!(Texture::parse_ppm("t", &ppm(2, 2, &[0; 5])).is_err());
        assert!(Texture::parse_ppm("t", b"P6\n0 1\n255\n").is_err());
        assert!(Texture::parse_ppm("t", b"P6\n99999999 1\n255\n").is_err());
        assert!(Texture::parse_ppm("t", b"P6\nx 1\n255\n").is_err());
    }
}
