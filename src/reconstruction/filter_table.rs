//! The filter table of one refresh: one [`TileFilter`] per tile of the sampler's tiling
//! (with the constants a splat needs) and one 8-byte [`Lookup`] per pixel, so that a
//! sample finds its filter and splat scale in one load from a table that fits a core's
//! L2 cache.

use std::sync::OnceLock;

use super::{filter, Reconstructor};
use crate::tiles::TilingSnapshot;

/// A tile's filter at one refresh, with the per-sample constants derived from it.
#[derive(Clone, Copy, Debug)]
pub(super) struct TileFilter {
    /// `[e_x, e_y, e_t]`.
    pub(super) e: [f32; 3],
    pub(super) inv_et: f32,
    /// `½/e_x²`, `½/e_y²`.
    pub(super) ax: f32,
    pub(super) ay: f32,
    /// Footprint radii at splat scale 1: `spatial_cutoff · e_x`, `· e_y`.
    pub(super) cx: f32,
    pub(super) cy: f32,
}

impl TileFilter {
    pub(super) fn new(e: [f32; 3], spatial_cutoff: f32) -> Self {
        Self {
            e,
            inv_et: 1.0 / e[2],
            ax: 0.5 / (e[0] * e[0]),
            ay: 0.5 / (e[1] * e[1]),
            cx: spatial_cutoff * e[0],
            cy: spatial_cutoff * e[1],
        }
    }
}

/// What a sample needs of the pixel it lands in. Eight bytes, so that the table of a
/// 256×256 image stays in a core's L2 cache: samples land in scattered pixels.
#[derive(Clone, Copy, Debug)]
pub(super) struct Lookup {
    /// Index of the pixel's tile in the filter table.
    pub(super) tile: u32,
    /// The pixel's splat scale.
    pub(super) scale: f32,
}

impl Reconstructor {
    /// Rebuild the per-tile filters and the pixel → tile map from the sampler's tiling.
    pub(super) fn update_filters(&mut self, tiling: &TilingSnapshot) {
        let cut = self.params.spatial_cutoff;
        self.filters = OnceLock::new();
        self.tiles.clear();
        if let Some(e) = self.params.fixed_filter {
            self.tiles.push(TileFilter::new(
                [e.ex as f32, e.ey as f32, e.et as f32],
                cut,
            ));
            self.lookup.iter_mut().for_each(|l| l.tile = 0);
        } else {
            self.tile_filters(tiling);
        }
        for (l, &sc) in self.lookup.iter_mut().zip(&self.scale) {
            l.scale = sc;
        }
    }

    /// The adaptive filter of every tile of `tiling`, and the pixel → tile map.
    fn tile_filters(&mut self, tiling: &TilingSnapshot) {
        let w = self.width as usize;
        let cut = self.params.spatial_cutoff;
        let tiles = tiling.tiles.len();
        for tile in &tiling.tiles {
            let r = tile.rect;
            let rl = filter::local_rate(self.rate, tiles, r.area());
            let (gx, gy, gt) = (tile.gx, tile.gy, tile.gt);
            let v_s = self.params.filter_volume / rl;
            let e = filter::extents(v_s, gx, gy, gt, &self.params.bounds);
            let k = self.tiles.len() as u32;
            self.tiles.push(TileFilter::new(
                [e.ex as f32, e.ey as f32, e.et as f32],
                cut,
            ));
            let x1 = (r.x1 as usize).min(w);
            for y in r.y0 as usize..(r.y1 as usize).min(self.height as usize) {
                for l in &mut self.lookup[y * w + r.x0 as usize..y * w + x1] {
                    l.tile = k;
                }
            }
        }
    }
}
