//! The reconstructor's parameters and the presets the evaluation compares (the paper's
//! reconstructor and its ablations), apart from the code so that callers configuring a
//! method need not read the pipeline.

use super::{
    filter::{Extents, FilterBounds},
    history::HistoryParams,
};

/// Parameters of the reconstructor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReconParams {
    /// Ring capacity as a multiple of the pixel count (paper: N = 400K at 256×256 ≈ 6).
    pub ring_factor: f64,
    /// Reproject samples to the current view (off: splat where they were traced).
    pub reproject: bool,
    /// A fixed filter for every sample instead of the adaptive one (ablation).
    pub fixed_filter: Option<Extents>,
    /// Clamps of the adaptive filter.
    pub bounds: FilterBounds,
    /// Spatial footprint radius in sigmas.
    pub spatial_cutoff: f32,
    /// Samples older than this many temporal sigmas get no weight. Default 2.5, the
    /// spatial cutoff: the kernel's support is cut at the same
    /// number of sigmas in space and time, so a dropped sample weighs at most
    /// e^(−3.125) ≈ 4.4% of a fresh one at the same place. (3 sigmas changed the
    /// Table 1 RMS by at most 0.1 of 255 and cost 12% more per refresh: README.)
    pub temporal_cutoff: f32,
    /// Largest footprint radius, pixels (bounds the cost of one splat).
    pub max_radius: f32,
    /// A pixel reached by fewer samples than this is undersampled.
    pub undersampled: u32,
    /// A pixel reached by more samples than this is oversampled.
    pub oversampled: u32,
    /// Splat scale factor applied where undersampled.
    pub grow: f32,
    /// Splat scale factor applied where oversampled.
    pub shrink: f32,
    /// Range of the per-pixel splat scale (multiplies the footprint radius, not the
    /// kernel). The lower bound 1 never cuts the kernel inside `spatial_cutoff` sigmas:
    /// growth widens splats to cover sparse regions, shrinking returns them.
    pub scale_bounds: (f32, f32),
    /// Accumulated weight below which a pixel is completed from a smooth (pull-push)
    /// interpolation of its neighbourhood, holes included (`pullpush.rs`); 0: holes
    /// only, from the flat mean of the nearest pyramid block that has samples (the
    /// paper's reconstructor). 1 is one fresh sample at the pixel's centre.
    pub fill_weight: f32,
    /// A per-pixel history of still samples blended over the reconstruction, so that
    /// still regions keep converging (`None`: the paper's reconstructor, whose image
    /// stops improving once the ring's horizon is reached).
    pub history: Option<HistoryParams>,
}

impl ReconParams {
    /// The paper's reconstructor: reprojection, adaptive filter, adaptive splat size.
    pub fn paper() -> Self {
        Self {
            ring_factor: 6.0,
            reproject: true,
            fixed_filter: None,
            bounds: FilterBounds::default(),
            spatial_cutoff: 2.5,
            temporal_cutoff: 2.5,
            max_radius: 24.0,
            undersampled: 4,
            oversampled: 32,
            grow: 4.0,
            shrink: 0.7,
            scale_bounds: (1.0, 16.0),
            fill_weight: 0.0,
            history: None,
        }
    }

    /// Ours: the paper's reconstructor with the still-region history
    /// ([`HistoryParams::default`]) and the pull-push fill of sparsely covered pixels.
    pub fn converging() -> Self {
        Self {
            history: Some(HistoryParams::default()),
            fill_weight: 1.0,
            ..Self::paper()
        }
    }

    /// The real-time reconstructor (`frameless view`): [`ReconParams::converging`] with
    /// a ring of 2 × pixels samples. The reconstructor's cost is linear in the ring; at
    /// the 6 × pixels of the paper (sized for 400K samples/s) one refresh costs 20–35 ms
    /// on this project's 2-core machine, more than a 60 Hz refresh, while at the
    /// 0.1–0.25 M samples/s reached in real time 2 × pixels still holds the last
    /// 0.5–1.5 s of samples at 256×256. Splats are at most 8 px in radius (paper: 24):
    /// sparse early samples otherwise grow huge footprints through the coverage-driven
    /// splat size.
    pub fn realtime() -> Self {
        Self {
            ring_factor: 2.0,
            max_radius: 8.0,
            ..Self::converging()
        }
    }

    /// Ablation of [`ReconParams::converging`]: samples splat where they were traced.
    pub fn no_reprojection() -> Self {
        Self {
            reproject: false,
            ..Self::converging()
        }
    }

    /// Ablation: a non-adaptive filter, `e_x = e_y = 1` px, `e_t = 0.1` s everywhere
    /// (adaptive splat size still widens it where samples are sparse).
    pub fn fixed_filter() -> Self {
        Self {
            fixed_filter: Some(Extents {
                ex: 1.0,
                ey: 1.0,
                et: 0.1,
            }),
            ..Self::converging()
        }
    }
}

impl Default for ReconParams {
    fn default() -> Self {
        Self::converging()
    }
}
