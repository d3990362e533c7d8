//! Visualisations of the sampler's state (paper Figs. 3, 4, 7): tiling overlay, gradient
//! map, sample density and occlusion maps.

use glam::Vec3;

use super::Sampler;
use crate::{
    image::Image,
    tiles::{TileGradients, TilingSnapshot},
};

/// Tile borders drawn in yellow over `base` (paper Fig. 3).
pub fn tiling_overlay(s: &Sampler, base: &Image) -> Image {
    tiling_overlay_of(&s.tiling().snapshot(), base)
}

/// [`tiling_overlay`] from a tiling's snapshot alone (what the real-time mode holds).
pub fn tiling_overlay_of(t: &TilingSnapshot, base: &Image) -> Image {
    let mut img = base.clone();
    let w = img.width;
    for tile in &t.tiles {
        let r = tile.rect;
        for x in r.x0..r.x1 {
            img.pixels[(r.y0 * w + x) as usize] = Vec3::new(1.0, 1.0, 0.0);
        }
        for y in r.y0..r.y1 {
            img.pixels[(y * w + r.x0) as usize] = Vec3::new(1.0, 1.0, 0.0);
        }
    }
    img
}

fn per_tile(
    t: &TilingSnapshot,
    (w, h): (u32, u32),
    f: impl Fn(&TileGradients) -> Vec3,
) -> Image {
    let mut img = Image::new(w, h);
    for tile in &t.tiles {
        let r = tile.rect;
        let c = f(tile);
        for y in r.y0..r.y1 {
            for x in r.x0..r.x1 {
                img.pixels[(y * w + x) as usize] = c;
            }
        }
    }
    img
}

/// Robust scale: the 95th percentile of positive values (so a few outliers do not
/// wash the map out).
fn p95(mut v: Vec<f64>) -> f64 {
    v.retain(|x| *x > 0.0 && x.is_finite());
    if v.is_empty() {
        return 1.0;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    v[((v.len() - 1) as f64 * 0.95) as usize]
}

/// Per-tile gradients as color: red Gx, green Gy, blue Gt (paper Fig. 4), each scaled by
/// its 95th percentile over tiles.
pub fn gradient_map(s: &Sampler) -> Image {
    gradient_map_of(&s.tiling().snapshot(), s.buffer_size())
}

/// [`gradient_map`] from a tiling's snapshot of a `size` image.
pub fn gradient_map_of(t: &TilingSnapshot, size: (u32, u32)) -> Image {
    let g: Vec<(f64, f64, f64)> = t.tiles.iter().map(|g| (g.gx, g.gy, g.gt)).collect();
    let (sx, sy, st) = (
        p95(g.iter().map(|v| v.0).collect()),
        p95(g.iter().map(|v| v.1).collect()),
        p95(g.iter().map(|v| v.2).collect()),
    );
    per_tile(t, size, |g| {
        Vec3::new((g.gx / sx) as f32, (g.gy / sy) as f32, (g.gt / st) as f32)
    })
}

/// Local sample rate (samples per pixel per second ∝ 1 / tile area, since tiles are
/// chosen uniformly) on a log scale, dark = sparse, bright = dense (paper Fig. 7 left).
pub fn density_map(s: &Sampler) -> Image {
    density_map_of(&s.tiling().snapshot(), s.buffer_size())
}

/// [`density_map`] from a tiling's snapshot of a `size` image.
pub fn density_map_of(t: &TilingSnapshot, size: (u32, u32)) -> Image {
    let areas: Vec<f64> = t.tiles.iter().map(|g| g.rect.area() as f64).collect();
    let (amin, amax) = areas
        .iter()
        .fold((f64::MAX, 0.0f64), |(a, b), &x| (a.min(x), b.max(x)));
    let span = (amax / amin).ln().max(1e-9);
    per_tile(t, size, |g| {
        let a = g.rect.area() as f64;
        let v = (1.0 - (a / amin).ln() / span) as f32;
        Vec3::new(v, v * 0.8, v * 0.3)
    })
}

/// Recent occlusion events per pixel (decayed with age), red on black (paper Fig. 7
/// right).
pub fn occlusion_map(s: &Sampler, now: f64) -> Image {
    let (w, h) = s.buffer_size();
    let vals: Vec<f64> = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| s.occlusion_at(x, y, now))
        .collect();
    let scale = p95(vals.clone());
    Image {
        width: w,
        height: h,
        pixels: vals
            .iter()
            .map(|v| Vec3::new((v / scale) as f32, 0.0, 0.0))
            .collect(),
    }
}
