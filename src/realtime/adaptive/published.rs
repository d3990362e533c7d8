//! What the adaptive method's controllers publish for its other threads: each band's
//! tiles for the sampling threads, its tiling for the reconstructor's filters, the
//! history counts the image builder hands back, and the bands themselves.

use std::sync::{
    atomic::{AtomicU32, AtomicU64, Ordering},
    Arc, Mutex,
};

use super::settings::AdaptiveSettings;
use crate::{
    methods::adaptive::{
        tiling::{Pending, Rect},
        Sampler, SamplerParams,
    },
    realtime::{
        config::RtConfig,
        shared::{lock, Shared},
    },
    tiles::TilingSnapshot,
};

/// Sampling threads one controller serves. The controller alone takes in 4.7–5 times
/// what one sampling thread traces on the cheapest scene (built-in `toycar`, the
/// `controller_*` figures of `frameless bench`), and more on costlier ones.
pub const THREADS_PER_CONTROLLER: usize = 4;

/// Fewest rows in a controller's band: a band holds tiles of at least the sampler's
/// smallest side in both directions, and room to adapt them.
pub(super) const MIN_BAND_ROWS: u32 = 32;

/// Controller threads for `sampling_threads` sampling threads on the CPU.
pub fn controllers(sampling_threads: usize) -> usize {
    sampling_threads.div_ceil(THREADS_PER_CONTROLLER).max(1)
}

/// Controller threads for a run. With a GPU tracer a few feeder threads deliver what
/// many CPU threads would, and the cores the other sampling threads leave idle take in
/// their samples: one controller per two of them. (On the H100 host of session 26,
/// four controllers for 16 cores held adaptive to 7.2 M samples/s, near the 7.8 M that
/// `frameless bench` gives four controllers, while the GPU tracer shaded 15 M.)
pub fn controllers_for(config: &RtConfig) -> usize {
    if config.rays.is_some() {
        config.sampling_threads.div_ceil(2).max(1)
    } else {
        controllers(config.sampling_threads)
    }
}

/// The bands of a `width × height` image for `n` controllers: whole rows, heights
/// differing by at most one, fewer bands where the image has too few rows, and one
/// band when `sampler` reprojects crosshairs.
pub fn bands(width: u32, height: u32, n: usize, sampler: &SamplerParams) -> Vec<Rect> {
    let most = (height / MIN_BAND_ROWS).max(1) as usize;
    let n = if sampler.reprojection {
        1
    } else {
        n.clamp(1, most)
    } as u32;
    (0..n)
        .map(|i| Rect {
            x0: 0,
            y0: height * i / n,
            x1: width,
            y1: height * (i + 1) / n,
        })
        .collect()
}

/// What one band's controller publishes.
pub(super) struct BandPublished {
    /// The band's pixels.
    pub(super) rect: Rect,
    /// The band's tile selection the sampling threads read.
    pub(super) snapshot: Mutex<Arc<TileSnapshot>>,
    /// Bumped with every new snapshot of this band.
    pub(super) seq: AtomicU64,
    /// A snapshot of the band's tiling (image coordinates) for the reconstructor's
    /// filters; `None` until the controller has a sampler.
    pub(super) tiling: Mutex<Option<Arc<TilingSnapshot>>>,
}

/// What the controllers publish for the other threads of the method.
pub(super) struct Published {
    /// The method's settings, which every thread of it reads.
    pub(super) settings: AdaptiveSettings,
    pub(super) bands: Vec<BandPublished>,
    /// Bumped with every new snapshot of any band, so that readers lock only when one
    /// changed.
    pub(super) snapshot_seq: AtomicU64,
    /// The reconstructor's still-region history counts after its newest image, with
    /// a number that grows with every map, for
    /// [`crate::methods::adaptive::SamplerParams::discount_converged`] (the
    /// evaluation passes them after every refresh too); each controller reads its
    /// band's rows of a map it has not seen.
    pub(super) history_counts: Mutex<(u64, Vec<f32>)>,
    /// Crosshair centres each pixel has had, for
    /// [`crate::methods::adaptive::SamplerParams::stratified_positions`]
    /// (empty when off); relaxed counters: two threads drawing the same index at once
    /// only repeat one position.
    pub(super) pixel_draws: Vec<AtomicU32>,
    /// Visits whose reprojection step a controller ran, and skipped (behind).
    pub(super) reprojected_visits: AtomicU64,
    pub(super) skipped_reprojections: AtomicU64,
    /// History count maps the controllers passed to their samplers.
    pub(super) history_maps: AtomicU64,
}

impl Published {
    /// Nothing published yet: one tile per band, nothing pending.
    pub(super) fn new(s: &Shared, settings: AdaptiveSettings) -> Self {
        let (w, h) = s.tracer.size();
        let c = &s.config;
        let bands = bands(w, h, controllers_for(c), &settings.sampler);
        Self {
            bands: bands
                .into_iter()
                .map(|rect| BandPublished {
                    rect,
                    snapshot: Mutex::new(Arc::new(TileSnapshot::whole(rect))),
                    seq: AtomicU64::new(0),
                    tiling: Mutex::new(None),
                })
                .collect(),
            snapshot_seq: AtomicU64::new(0),
            history_counts: Mutex::new((0, Vec::new())),
            reprojected_visits: AtomicU64::new(0),
            skipped_reprojections: AtomicU64::new(0),
            history_maps: AtomicU64::new(0),
            pixel_draws: if settings.sampler.stratified_positions {
                (0..w as usize * h as usize)
                    .map(|_| AtomicU32::new(0))
                    .collect()
            } else {
                Vec::new()
            },
            settings,
        }
    }

    /// Publish band `b`'s tiles, held by `sampler`, for the sampling threads.
    pub(super) fn snapshot(&self, b: usize, sampler: &Sampler) {
        let band = &self.bands[b];
        *lock(&band.snapshot) = Arc::new(TileSnapshot::of(sampler));
        band.seq.fetch_add(1, Ordering::Release);
        self.snapshot_seq.fetch_add(1, Ordering::Release);
    }

    /// Publish band `b`'s tiling for the reconstructor.
    pub(super) fn tiling(&self, b: usize, sampler: &Sampler) {
        let mut t = sampler.tiling().snapshot();
        let (ox, oy) = sampler.origin();
        for tile in &mut t.tiles {
            tile.rect = tile.rect.offset(ox, oy);
        }
        *lock(&self.bands[b].tiling) = Some(Arc::new(t));
    }

    /// Every band's tiling together; `None` until each has one.
    pub(super) fn whole_tiling(&self) -> Option<TilingSnapshot> {
        let mut tiles = Vec::new();
        for band in &self.bands {
            tiles.extend_from_slice(&lock(&band.tiling).as_ref()?.tiles);
        }
        Some(TilingSnapshot { tiles })
    }

    /// Tiles in all bands' newest snapshots.
    pub(super) fn tiles(&self) -> usize {
        self.bands
            .iter()
            .map(|b| lock(&b.snapshot).rects.len())
            .sum()
    }
}

/// One band's tile selection as the sampling threads read it.
pub(super) struct TileSnapshot {
    /// The tiles (image coordinates).
    pub(super) rects: Vec<Rect>,
    /// Each tile's pending crosshair.
    pub(super) pending: Vec<Option<Pending>>,
}

impl TileSnapshot {
    /// One tile, nothing pending.
    pub(super) fn whole(rect: Rect) -> Self {
        Self {
            rects: vec![rect],
            pending: vec![None],
        }
    }

    pub(super) fn of(sampler: &Sampler) -> Self {
        let t = sampler.tiling();
        let (ox, oy) = sampler.origin();
        let (rects, pending) = t
            .leaf_nodes()
            .map(|(_, n)| {
                let p = n.pending.map(|p| p.moved(ox as f32, oy as f32));
                (n.rect.offset(ox, oy), p)
            })
            .unzip();
        Self { rects, pending }
    }
}
