//! The filter table of one refresh: one [`TileFilter`] per tile of the sampler's tiling
//! (with the constants a splat needs) and one 4-byte [`Lookup`] per pixel, the pixel's
//! tile, so that a sample finds its filter from a table that fits a core's L2 cache.

use std::sync::OnceLock;

use rayon::prelude::*;

use super::{filter, Reconstructor};
use crate::tiles::{Rect, TilingSnapshot};

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

/// The tile of the pixel a sample lands in. Four bytes, so that the table of a 256×256
/// image stays in a core's L2 cache: samples land in scattered pixels. The pixel's
/// splat scale is read from the splat scales themselves: copying them in here made
/// every refresh write the whole map, which the tiles alone fill in cache.
#[derive(Clone, Copy, Debug)]
pub(super) struct Lookup {
    /// Index of the pixel's tile in the filter table.
    pub(super) tile: u32,
}

impl Reconstructor {
    /// Rebuild the per-tile filters and their rectangles from the sampler's tiling, and
    /// the pixel → tile map where the CPU places this refresh's samples (a GPU paints
    /// its own from the rectangles; the CPU's is then made only if something here
    /// reads it, [`Reconstructor::ensure_lookup`]).
    pub(super) fn update_filters(&mut self, tiling: &TilingSnapshot) {
        let cut = self.params.spatial_cutoff;
        self.filters = OnceLock::new();
        self.tiles.clear();
        self.tile_rects.clear();
        if let Some(e) = self.params.fixed_filter {
            self.tiles.push(TileFilter::new(
                [e.ex as f32, e.ey as f32, e.et as f32],
                cut,
            ));
            self.tile_rects.push(Rect {
                x0: 0,
                y0: 0,
                x1: self.width,
                y1: self.height,
            });
        } else {
            self.tile_filters(tiling);
        }
        self.lookup_stale = true;
        if !self.refreshes_on_gpu() {
            self.ensure_lookup();
        }
    }

    /// The adaptive filter of every tile of `tiling`, and its rectangle on the image.
    fn tile_filters(&mut self, tiling: &TilingSnapshot) {
        let (w, h) = (self.width, self.height);
        let cut = self.params.spatial_cutoff;
        let tiles = tiling.tiles.len();
        let bounds = &self.params.bounds;
        let logs = bounds.logs();
        let (rate, volume) = (self.rate, self.filter_volume());
        // Each tile's filter on its own (logarithms and exponentials, a tenth of a
        // microsecond a tile: 30,000 tiles at 1920×1080), in parallel.
        self.tiles
            .par_extend(tiling.tiles.par_iter().with_min_len(256).map(|tile| {
                let rl = filter::local_rate(rate, tiles, tile.rect.area());
                let v_s = volume / rl;
                let e = filter::extents_in(v_s, tile.gx, tile.gy, tile.gt, bounds, &logs);
                TileFilter::new([e.ex as f32, e.ey as f32, e.et as f32], cut)
            }));
        self.tile_rects.extend(tiling.tiles.iter().map(|t| {
            let r = t.rect;
            let (x1, y1) = (r.x1.min(w), r.y1.min(h));
            Rect {
                x0: r.x0.min(x1),
                y0: r.y0.min(y1),
                x1,
                y1,
            }
        }));
    }

    /// The filters' volume on this refresh: the moving view's
    /// ([`super::ReconParams::moving_view_volume`]) where the view moved, else
    /// [`super::ReconParams::filter_volume`].
    fn filter_volume(&self) -> f64 {
        let moving = self.params.moving_view_volume.filter(|_| self.resplat);
        moving.unwrap_or(self.params.filter_volume)
    }

    /// The pixel → tile map from this refresh's tile rectangles, if not made since the
    /// filters were: the pixels of each tile that is not where the map's tile of its
    /// index was (tiles do not overlap and cover the image, so every pixel whose tile
    /// changed lies in one of them).
    pub(super) fn ensure_lookup(&mut self) {
        if !std::mem::take(&mut self.lookup_stale) {
            return;
        }
        let w = self.width as usize;
        let bands = (self.height as usize).div_ceil(MAP_ROWS);
        // The tiles that reach each band of rows, so that bands fill their part of
        // the map in parallel (tiles do not overlap: the order does not matter).
        let mut reach: Vec<Vec<u32>> = vec![Vec::new(); bands];
        let moved = |(k, r): &(usize, &Rect)| self.map_rects.get(*k) != Some(*r);
        for (k, r) in self.tile_rects.iter().enumerate().filter(moved) {
            if r.y0 < r.y1 {
                for band in &mut reach[r.y0 as usize / MAP_ROWS..=(r.y1 as usize - 1) / MAP_ROWS] {
                    band.push(k as u32);
                }
            }
        }
        let rects = &self.tile_rects;
        self.lookup
            .par_chunks_mut(MAP_ROWS * w)
            .zip(&reach)
            .enumerate()
            .for_each(|(b, (band, ks))| {
                let y0 = b * MAP_ROWS;
                let rows = band.len() / w.max(1);
                for &k in ks {
                    let r = rects[k as usize];
                    let (x0, x1) = (r.x0 as usize, r.x1 as usize);
                    let ys = (r.y0 as usize).max(y0)..(r.y1 as usize).min(y0 + rows);
                    for y in ys {
                        for l in &mut band[(y - y0) * w + x0..(y - y0) * w + x1] {
                            l.tile = k;
                        }
                    }
                }
            });
        self.map_rects.clone_from(&self.tile_rects);
    }

    /// Whether a GPU carries out the refreshes (it may fail over to the CPU).
    pub(super) fn refreshes_on_gpu(&self) -> bool {
        #[cfg(feature = "gpu")]
        return self.gpu.is_some();
        #[cfg(not(feature = "gpu"))]
        false
    }
}

/// Rows per band of the pixel → tile map's parallel fill.
const MAP_ROWS: usize = 16;
