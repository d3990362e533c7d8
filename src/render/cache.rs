//! On-disk cache of ideal images.
//!
//! Ideal images dominate an evaluation's cost, so they are kept across runs and methods,
//! keyed by everything that determines them: the scene's full content (a hash of its
//! model, so editing a file or texture changes the key), the camera path, image size,
//! the tracer's options (depth limit, texture filter), the tracer's
//! [`RENDERER_VERSION`], samples per pixel, seed, exact time and [`CACHE_VERSION`].
//! Entries are
//! written to a temporary file and renamed into place, and a file that does not decode
//! to the right size is re-rendered, so an interrupted run never poisons the cache.

use std::{
    fmt::Write as _,
    path::{Path, PathBuf},
};

use crate::{
    image::{read_png_rgb8, write_png_rgb8_fast, Image},
    render::still,
    sampling::rng::mix64,
    scene::{CameraPath, Scene},
    trace::{Tracer, RENDERER_VERSION},
};

/// Bump when the still renderer's sampling or the stored format changes what an entry
/// holds. Changes to the tracer itself bump [`RENDERER_VERSION`] instead.
pub const CACHE_VERSION: u64 = 1;

/// A streaming 64-bit hash that accepts formatted text.
struct Hasher(u64);

impl std::fmt::Write for Hasher {
    fn write_str(&mut self, s: &str) -> std::fmt::Result {
        for chunk in s.as_bytes().chunks(8) {
            let mut w = [0u8; 8];
            w[..chunk.len()].copy_from_slice(chunk);
            self.0 = mix64(self.0 ^ u64::from_le_bytes(w)).wrapping_add(chunk.len() as u64);
        }
        Ok(())
    }
}

/// A hash of a scene's entire content (its model as loaded).
pub fn scene_fingerprint(scene: &Scene) -> u64 {
    let mut h = Hasher(0x5ce7e);
    // Debug output is exact for floats (round-trip formatting) and covers every field.
    let _ = write!(h, "{scene:?}");
    h.0
}

/// The cache for one scene, camera and image size.
pub struct IdealCache {
    dir: PathBuf,
    base_key: u64,
    size: (u32, u32),
}

impl IdealCache {
    /// Open (creating) the cache directory for this tracer's scene, camera path and size.
    pub fn new(
        dir: &Path,
        tracer: &Tracer,
        camera_path: Option<&CameraPath>,
    ) -> std::io::Result<Self> {
        std::fs::create_dir_all(dir)?;
        let mut h = Hasher(CACHE_VERSION);
        let _ = write!(
            h,
            "{:x}|{}|{:?}|{:?}|renderer {}",
            scene_fingerprint(tracer.scene()),
            camera_path.map(|p| p.to_csv()).unwrap_or_default(),
            tracer.size(),
            // Every option, the texture filter included: entries made under one
            // setting are never served under another.
            tracer.options(),
            RENDERER_VERSION
        );
        Ok(Self {
            dir: dir.to_path_buf(),
            base_key: h.0,
            size: tracer.size(),
        })
    }

    fn path(&self, t: f64, spp: u32, seed: u64) -> PathBuf {
        let key = mix64(mix64(self.base_key ^ t.to_bits()) ^ ((spp as u64) << 32) ^ mix64(seed));
        self.dir.join(format!("{key:016x}.png"))
    }

    /// The ideal image at time `t`, from disk when present and valid, else rendered and
    /// stored. Returns the displayed (8-bit) values as an image.
    pub fn get_or_render(&self, tracer: &Tracer, t: f64, spp: u32, seed: u64) -> Image {
        let path = self.path(t, spp, seed);
        if let Ok((w, h, rgb)) = read_png_rgb8(&path) {
            if (w, h) == self.size && rgb.len() == (w * h * 3) as usize {
                return from_rgb8(w, h, &rgb);
            }
        }
        let img = still::render(tracer, t, spp, seed, &|_| {});
        let (w, h) = self.size;
        let rgb = img.to_rgb8();
        // A failed write only costs a re-render next time.
        let _ = write_png_rgb8_fast(&path, w, h, &rgb);
        from_rgb8(w, h, &rgb)
    }

    /// Whether the entry for time `t` exists (it may still be invalid).
    pub fn contains(&self, t: f64, spp: u32, seed: u64) -> bool {
        self.path(t, spp, seed).exists()
    }
}

/// An image holding displayed 8-bit values (exactly re-quantizable).
pub fn from_rgb8(w: u32, h: u32, rgb: &[u8]) -> Image {
    Image {
        width: w,
        height: h,
        pixels: rgb
            .chunks(3)
            .map(|c| glam::Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32) / 255.0)
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::{
        scene::builtin,
        trace::{TextureFilter, TraceOptions},
    };

    #[test]
    fn key_covers_the_texture_filter() {
        let dir = std::env::temp_dir().join(format!("frameless-cache-key-{}", std::process::id()));
        let scene = Arc::new(builtin::toycar());
        let key = |texture_filter| {
            let options = TraceOptions {
                texture_filter,
                ..TraceOptions::default()
            };
            let tracer = Tracer::new(scene.clone(), 8, 8, options);
            IdealCache::new(&dir, &tracer, None).unwrap().base_key
        };
        let none = key(TextureFilter::None);
        assert_eq!(none, key(TextureFilter::None));
        assert_ne!(none, key(TextureFilter::RayCones));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
