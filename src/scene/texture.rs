//! Image textures: binary PPM (P6) loading, bilinear lookup with repeat wrap, and a mip
//! pyramid for filtered (trilinear) lookups.
//!
//! The pyramid is built once when the texture is made, so a lookup never allocates. Each
//! level halves the previous one (rounding down, at least 1) and is its exact area
//! average: a destination texel averages the source texels under its footprint, with
//! fractional weights where an odd size makes footprints straddle texels. Area averaging
//! keeps every level's mean equal to the image's mean, which is what a filtered lookup of
//! a far-away surface should converge to.
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
    /// Mip levels 1.. (level 0 is `texels`), built by [`Texture::new`].
    mips: Vec<MipLevel>,
}

/// One level of a mip pyramid.
#[derive(Clone, Debug, PartialEq)]
pub struct MipLevel {
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
    /// A texture from its texels (row-major, row 0 first), with its mip pyramid.
    ///
    /// # Panics
    /// When `texels.len() != width * height` or a side is 0: callers validate sizes
    /// from files before they allocate texels, so this is a programming error.
    pub fn new(name: &str, width: u32, height: u32, texels: Vec<Vec3>) -> Self {
        assert!(
            width > 0 && height > 0 && texels.len() == width as usize * height as usize,
            "texture {name}: {} texels for {width}x{height}",
            texels.len()
        );
        let mips = build_mips(width, height, &texels);
        Self {
            name: name.to_string(),
            width,
            height,
            texels,
            mips,
        }
    }

    /// Build from a closure giving the color of each texel.
    pub fn from_fn(name: &str, width: u32, height: u32, f: impl Fn(u32, u32) -> Vec3) -> Self {
        let mut texels = Vec::with_capacity(width as usize * height as usize);
        for y in 0..height {
            for x in 0..width {
                texels.push(f(x, y));
            }
        }
        Self::new(name, width, height, texels)
    }

    /// Number of levels in the pyramid, level 0 included.
    pub fn levels(&self) -> usize {
        1 + self.mips.len()
    }

    /// Level `i` of the pyramid as `(width, height, texels)`; `None` past the last.
    pub fn level(&self, i: usize) -> Option<(u32, u32, &[Vec3])> {
        match i {
            0 => Some((self.width, self.height, &self.texels)),
            _ => self
                .mips
                .get(i - 1)
                .map(|m| (m.width, m.height, m.texels.as_slice())),
        }
    }

    /// Read a binary PPM (P6, maxval ≤ 255 or ≤ 65535, `#` comments in the header).
    pub fn load_ppm(path: &Path) -> Result<Self, SceneError> {
        let bytes = crate::scene::limits::read_bounded(path).map_err(|e| SceneError::Io {
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
        Ok(Self::new(name, w, h, texels))
    }

    /// Bilinear lookup with repeat wrap; texel centers sit at half-integer coordinates.
    /// Level 0 only, no footprint: the unfiltered lookup.
    pub fn sample(&self, uv: Vec2) -> Vec3 {
        if !uv.is_finite() {
            return self.texels[0];
        }
        bilinear(self.width, self.height, &self.texels, uv)
    }

    /// Trilinear lookup: bilinear on the two levels around `lod` (level 0 = full
    /// resolution, each level up halves it), blended by `lod`'s fraction. `lod` is
    /// clamped to the pyramid; a NaN `lod` reads level 0.
    pub fn sample_lod(&self, uv: Vec2, lod: f32) -> Vec3 {
        if !uv.is_finite() {
            return self.texels[0];
        }
        let top = self.mips.len() as f32;
        // `max` before `min`: NaN becomes 0.
        let lod = lod.max(0.0).min(top);
        let l0 = lod.floor();
        let f = lod - l0;
        let l0 = l0 as usize;
        let at = |i: usize| match self.level(i) {
            Some((w, h, t)) => bilinear(w, h, t, uv),
            None => Vec3::ZERO, // unreachable: `lod` is clamped to the pyramid
        };
        let a = at(l0);
        if f == 0.0 {
            return a;
        }
        a.lerp(at(l0 + 1), f)
    }
}

#[inline]
fn texel(width: u32, height: u32, texels: &[Vec3], x: i64, y: i64) -> Vec3 {
    let x = x.rem_euclid(width as i64) as usize;
    let y = y.rem_euclid(height as i64) as usize;
    texels[y * width as usize + x]
}

/// Bilinear lookup in one level, repeat wrap; `uv` must be finite.
#[inline]
fn bilinear(width: u32, height: u32, texels: &[Vec3], uv: Vec2) -> Vec3 {
    let x = uv.x.rem_euclid(1.0) * width as f32 - 0.5;
    let y = (1.0 - uv.y.rem_euclid(1.0)) * height as f32 - 0.5;
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let (x0, y0) = (x0 as i64, y0 as i64);
    let t = |x, y| texel(width, height, texels, x, y);
    let a = t(x0, y0).lerp(t(x0 + 1, y0), fx);
    let b = t(x0, y0 + 1).lerp(t(x0 + 1, y0 + 1), fx);
    a.lerp(b, fy)
}

/// Size of the level above a side of `n` texels.
fn half(n: u32) -> u32 {
    (n / 2).max(1)
}

/// Levels 1.. of the pyramid over a `width × height` level 0, down to 1×1.
///
/// Memory: every level is at most half the previous one in each side, so the whole
/// pyramid is at most a third of level 0 (plus one row or column per level where a side
/// has reached 1), and level 0 is bounded by [`MAX_TEXTURE_SIDE`] at load.
pub fn build_mips(width: u32, height: u32, texels: &[Vec3]) -> Vec<MipLevel> {
    let mut out: Vec<MipLevel> = Vec::new();
    let (mut w, mut h) = (width, height);
    if w == 0 || h == 0 || texels.len() != w as usize * h as usize {
        return out;
    }
    while w > 1 || h > 1 {
        let prev: &[Vec3] = out.last().map_or(texels, |m| &m.texels);
        let (nw, nh) = (half(w), half(h));
        let rows = downsample_rows(w, h, prev, nw);
        let cols = downsample_cols(nw, h, &rows, nh);
        out.push(MipLevel {
            width: nw,
            height: nh,
            texels: cols,
        });
        (w, h) = (nw, nh);
    }
    out
}

/// Weights of the source texels under destination texel `i` when `n` texels shrink to
/// `m`: the overlap of `[i·n/m, (i+1)·n/m)` with each source texel, over `n/m`.
fn footprint(i: u32, n: u32, m: u32, mut f: impl FnMut(usize, f32)) {
    let s = n as f64 / m as f64;
    let (lo, hi) = (i as f64 * s, (i + 1) as f64 * s);
    let mut j = lo.floor() as u32;
    while (j as f64) < hi && j < n {
        let overlap = (hi.min(j as f64 + 1.0) - lo.max(j as f64)).max(0.0);
        f(j as usize, (overlap / s) as f32);
        j += 1;
    }
}

/// Shrink each row from `w` to `nw` texels.
fn downsample_rows(w: u32, h: u32, src: &[Vec3], nw: u32) -> Vec<Vec3> {
    let mut out = Vec::with_capacity(nw as usize * h as usize);
    for y in 0..h as usize {
        let row = &src[y * w as usize..(y + 1) * w as usize];
        for x in 0..nw {
            let mut acc = Vec3::ZERO;
            footprint(x, w, nw, |j, wt| acc += row[j] * wt);
            out.push(acc);
        }
    }
    out
}

/// Shrink each column from `h` to `nh` texels (rows of width `w`).
fn downsample_cols(w: u32, h: u32, src: &[Vec3], nh: u32) -> Vec<Vec3> {
    let mut out = vec![Vec3::ZERO; w as usize * nh as usize];
    for y in 0..nh {
        let dst = &mut out[y as usize * w as usize..(y as usize + 1) * w as usize];
        footprint(y, h, nh, |j, wt| {
            let row = &src[j * w as usize..(j + 1) * w as usize];
            for (d, s) in dst.iter_mut().zip(row) {
                *d += *s * wt;
            }
        });
    }
    out
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

    fn mean(t: &[Vec3]) -> Vec3 {
        t.iter().copied().sum::<Vec3>() / t.len() as f32
    }

    #[test]
    fn pyramid_sizes_halve_to_one_rounding_down() {
        let t = Texture::from_fn("t", 5, 12, |x, y| Vec3::splat((x + y) as f32));
        let sizes: Vec<(u32, u32)> = (0..t.levels())
            .map(|i| t.level(i).map(|(w, h, _)| (w, h)).unwrap())
            .collect();
        assert_eq!(sizes, [(5, 12), (2, 6), (1, 3), (1, 1)]);
        assert!(t.level(t.levels()).is_none());
        let one = Texture::from_fn("one", 1, 1, |_, _| Vec3::ONE);
        assert_eq!(one.levels(), 1);
        assert_eq!(one.sample_lod(Vec2::splat(0.3), 4.0), Vec3::ONE);
    }

    #[test]
    fn pyramid_keeps_constants_and_means() {
        let c = Vec3::new(0.2, 0.5, 0.9);
        let t = Texture::from_fn("c", 7, 3, |_, _| c);
        for i in 0..t.levels() {
            let (_, _, tx) = t.level(i).unwrap();
            assert!(
                tx.iter().all(|v| (*v - c).abs().max_element() < 1e-6),
                "level {i}"
            );
        }
        for lod in [0.0, 0.5, 1.3, 2.0, 9.0] {
            assert!(
                (t.sample_lod(Vec2::new(0.37, 0.81), lod) - c)
                    .abs()
                    .max_element()
                    < 1e-6
            );
        }
        // A 4×4 checker of 1×1 texels: level 1 is uniform grey; so is the top level.
        let k = Texture::from_fn("k", 4, 4, |x, y| Vec3::splat(((x + y) % 2) as f32));
        let (w, h, l1) = k.level(1).unwrap();
        assert_eq!((w, h), (2, 2));
        assert!(l1.iter().all(|v| (*v - Vec3::splat(0.5)).length() < 1e-6));
        // Odd sizes: area averaging keeps the mean on every level.
        let r = Texture::from_fn("r", 9, 5, |x, y| {
            Vec3::new(x as f32, y as f32, (x * y) as f32)
        });
        let m0 = mean(&r.texels);
        for i in 1..r.levels() {
            let (_, _, tx) = r.level(i).unwrap();
            assert!((mean(tx) - m0).abs().max_element() < 1e-4, "level {i}");
        }
    }

    #[test]
    fn sample_lod_zero_is_sample_and_blends_between_levels() {
        let k = Texture::from_fn("k", 8, 8, |x, y| Vec3::splat(((x + y) % 2) as f32));
        for uv in [
            Vec2::new(0.1, 0.2),
            Vec2::new(0.5625, 0.4375),
            Vec2::new(-1.3, 7.9),
        ] {
            assert_eq!(k.sample_lod(uv, 0.0), k.sample(uv));
            assert_eq!(k.sample_lod(uv, -3.0), k.sample(uv));
            assert_eq!(k.sample_lod(uv, f32::NAN), k.sample(uv));
            // Level 1 and up are uniform 0.5: half way, the mean of level 0's and 0.5.
            let half = k.sample_lod(uv, 0.5);
            assert!((half - (k.sample(uv) + Vec3::splat(0.5)) * 0.5).length() < 1e-6);
            assert!((k.sample_lod(uv, 1.0) - Vec3::splat(0.5)).length() < 1e-6);
        }
        // A texel center of a black texel at level 0 reads black.
        assert_eq!(
            k.sample_lod(Vec2::new(1.0 / 16.0, 1.0 - 1.0 / 16.0), 0.0),
            Vec3::ZERO
        );
    }
}
