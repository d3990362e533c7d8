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
    /// e^(−3.125) ≈ 4.4% of a fresh one at the same place; a longer support costs
    /// more per refresh for no gain (docs/performance.md, "Tuning records").
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
    /// The filter's sample volume as a multiple of the paper's `V_s = 1/R_l` (one
    /// sample per sigma-box of the kernel). Ours halves it: the still-region history
    /// carries still pixels, so the splats serve what moves or changes, where a
    /// sharper, younger kernel costs less than the blur of a wider one.
    pub filter_volume: f64,
    /// The filter volume on a refresh whose view moved (one that re-splats the ring;
    /// `None`: [`ReconParams::filter_volume`] on every refresh). While the view moves,
    /// every sample shown has been reprojected from the view it was traced in and the
    /// still-region history is cut where it no longer fits, so the image rests on the
    /// splats alone, and a wide kernel spreads each sample's small misplacements and
    /// the far surfaces' samples between a near surface's: a smaller volume trades
    /// noise for a sharper, younger image there. While the view holds, samples land
    /// where they were traced and the history converges, and the volume stays as it is.
    pub moving_view_volume: Option<f64>,
    /// A depth test between reprojected samples (`None`: the paper's reconstructor,
    /// where every sample reaches every pixel of its footprint).
    pub visibility: Option<Visibility>,
    /// Place a sample of a moving object where its surface point is at display time,
    /// evaluated from the scene's animation (the rigid transform or the morphing
    /// triangle it hit, [`crate::trace::Anchor`]), instead of extrapolating the velocity
    /// it had when traced (off: the paper's). A rotating or morphing object's samples
    /// then stay on it however old, where extrapolated ones drift off along tangents.
    /// Needs the scene at each refresh ([`super::Reconstructor::set_motion`]).
    pub exact_motion: bool,
    /// Carry the accumulators from one refresh to the next, decayed and moved with
    /// the surfaces they show, and splat each sample once, at the first refresh after
    /// it arrives (`carry.rs`): a refresh then costs the new samples and the pixels,
    /// not the ring. Off: the paper's reconstructor, which splats the whole ring within
    /// the temporal cutoff at every refresh with a Gaussian temporal weight.
    pub carry: bool,
    /// With [`ReconParams::carry`]: the time constant of the carried sums' exponential
    /// decay as a multiple of the tile's temporal extent `e_t`. Ours: 0.6, the best of
    /// 0.35–1.4 on `toycar` (docs/performance.md, carried accumulators); the ring's Gaussian
    /// weights have a mean age of 0.8 `e_t`.
    pub decay_scale: f32,
    /// With [`ReconParams::carry`]: a refresh whose view is not the previous
    /// refresh's re-splats the ring as without carrying (its cost is then the ring's),
    /// and carrying starts again from that refresh's sums once the view holds. Off:
    /// the sums are moved with the view at every refresh.
    pub resplat_moving_view: bool,
}

/// The visibility pass of the splat: reprojected samples are a point cloud seen from a
/// new view, and without a depth test the background seen before a silhouette moved
/// shows through the object that now covers it (EWA surface splatting's visibility
/// splatting, Zwicker et al. 2001). Each pixel's front depth is the nearest depth of
/// the samples that land in it (still ones of any age, moving ones while recent); a
/// sample is splatted only if it lies within the tolerance of the front depth of the
/// pixel it lands in. The test is per sample, not
/// per pixel of its footprint: a silhouette pixel that both surfaces partly cover
/// keeps both surfaces' samples from the pixels around it, so edges stay
/// anti-aliased (a per-pixel test, measured, widened every foreground
/// object by its samples' footprints and raised the error of every window).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Visibility {
    /// Relative depth tolerance: a sample at depth `z` reaches a pixel of front depth
    /// `z_f` only if `z ≤ z_f · (1 + tolerance)`.
    pub depth_tolerance: f32,
    /// Moving samples set front depths only while younger than this many temporal
    /// sigmas: extrapolated by their velocity, an old one may no longer be where the
    /// surface is, and must not hide what is really there. Still samples reproject
    /// exactly and set front depths at any age.
    pub setter_age_sigmas: f32,
    /// While the view moves (a refresh that re-splats the ring), each pixel's front
    /// depth is also the nearest of its eight neighbours' times this ratio (`None`:
    /// its own only). A near surface the view has just brought in has few samples, and
    /// they land on few of the pixels their footprints cover; in the others, samples
    /// of a far surface seen before and reprojected from the old view would show
    /// through it as dots. Only a surface this many times farther is hidden, so that
    /// ordinary silhouettes keep their edges; while the view holds, samples are not
    /// reprojected across views and the fronts stay as they are.
    pub moving_view_spread: Option<f32>,
    /// A spread front hides a far sample only where the view's motion since the
    /// sample was traced moved it across the near surface: the point at the near depth
    /// on the ray it was traced along now lies at least this many pixels from it. A far
    /// sample with less parallax was traced past the near surface's edge, where it
    /// still is, and shows what is there (the sky above a horizon of grass), however
    /// the view turned since.
    pub spread_parallax: f32,
    /// While the view moves, a far sample is also hidden where a front this many times
    /// nearer lies anywhere in its footprint's box (`None`: only in the pixels around
    /// it) and the view's motion carried it across that front by
    /// [`Visibility::footprint_parallax`] pixels or more. At low rates the samples of a
    /// near surface the view brings in land farther apart than a pixel's neighbours,
    /// and the far surface's samples, reprojected with footprints as wide as those
    /// gaps, show through it.
    pub footprint_spread: Option<f32>,
    /// The parallax, pixels, of [`Visibility::footprint_spread`].
    pub footprint_parallax: f32,
    /// How far beyond a far sample's footprint, pixels, [`Visibility::footprint_spread`]
    /// looks for a near front: as far as the view's motion carried the sample across
    /// that front, up to this many pixels (0: the footprint's box alone). At low rates
    /// a near surface the view brings in has samples several pixels apart, and where
    /// the parallax has slid it that far over a far surface, the far surface's
    /// reprojected samples show between them.
    pub footprint_reach: f32,
    /// The reach is at most this many times the spacing of one refresh's new samples,
    /// `sqrt(pixels / (rate · Δt))` (`Δt`: the time since the previous refresh). At
    /// higher rates a near surface's samples lie closer together, and a wide reach
    /// would make every far sample look far around it for nothing.
    pub footprint_reach_spacings: f32,
}

impl Default for Visibility {
    /// A tolerance of 10% of the depth; front depths from still samples and from
    /// moving ones younger than one temporal sigma (weight above `e^(−½)`); while the
    /// view moves, a surface three times farther than a neighbouring pixel's front is
    /// hidden (of 1, 1.5, 2, 2.5 and 3 on a head turn that shows a near wall, three
    /// kept the gain there and changed no other window measured; docs/methods.md),
    /// but only over far samples moved across the near surface by two pixels or more
    /// (of half a pixel, one and two, two kept the head turn's gain and `terrain`'s
    /// horizon sharp); and within a footprint's box, a surface five times farther moved
    /// four pixels or more across a front there (of ratios 3 and 5 and parallaxes 2, 4
    /// and 8, the pair that kept the head turn's gain and changed no other window
    /// measured by more than 0.2%; docs/methods.md), the box widened by as far as the
    /// move carried the far sample, up to 16 pixels and two and a half times the
    /// spacing of a refresh's new samples (16 pixels alone won the head turn at 100K
    /// but made a moving view's refresh 10–25% dearer at live rates, where the spacing
    /// bounds it to about 6; docs/methods.md).
    fn default() -> Self {
        Self {
            depth_tolerance: 0.1,
            setter_age_sigmas: 1.0,
            moving_view_spread: Some(3.0),
            spread_parallax: 2.0,
            footprint_spread: Some(5.0),
            footprint_parallax: 4.0,
            footprint_reach: 16.0,
            footprint_reach_spacings: 2.5,
        }
    }
}

impl ReconParams {
    /// The visibility pass, if it is on and can act: it needs samples reprojected to
    /// the current view.
    pub fn visibility_in_use(&self) -> Option<Visibility> {
        self.visibility.filter(|_| self.reproject)
    }

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
            filter_volume: 1.0,
            moving_view_volume: None,
            visibility: None,
            exact_motion: false,
            carry: false,
            decay_scale: 1.0,
            resplat_moving_view: false,
        }
    }

    /// Ours: the paper's reconstructor with the still-region history
    /// ([`HistoryParams::default`]), the pull-push fill of sparsely covered pixels,
    /// half the filter volume (a quarter while the view moves,
    /// [`ReconParams::moving_view_volume`]), the visibility pass, exact motion, and accumulators
    /// carried between refreshes while the view holds ([`ReconParams::carry`],
    /// [`ReconParams::resplat_moving_view`]), so that each sample is splatted once
    /// there.
    pub fn converging() -> Self {
        Self {
            history: Some(HistoryParams::default()),
            fill_weight: 1.0,
            filter_volume: 0.5,
            moving_view_volume: Some(0.25),
            visibility: Some(Visibility::default()),
            exact_motion: true,
            carry: true,
            decay_scale: 0.6,
            resplat_moving_view: true,
            ..Self::paper()
        }
    }

    /// Our reconstructor as every command runs it (`adaptive` in `frameless eval`,
    /// `table1` and `render`, and in `frameless view` and `live`):
    /// [`ReconParams::converging`] with a ring of 2 × pixels samples (it only holds the
    /// samples until their first refresh, and an image thread that falls behind may
    /// take in that many at once). Splats are at most 8 px in radius (paper: 24):
    /// sparse early samples otherwise grow huge footprints through the coverage-driven
    /// splat size. A tile's gradients widen its filter to at most 2 px (the paper's
    /// bound is 8): past that, a flat tile's wide Gaussians bled across the edges
    /// beside it; where samples are sparse, the coverage-driven splat size still widens
    /// the footprints (docs/methods.md, "The spatial extent's bound").
    pub fn realtime() -> Self {
        Self {
            ring_factor: 2.0,
            max_radius: 8.0,
            bounds: FilterBounds {
                extent_xy: (0.4, 2.0),
                ..FilterBounds::default()
            },
            ..Self::converging()
        }
    }

    /// Ablation of [`ReconParams::realtime`]: samples splat where they were traced.
    pub fn no_reprojection() -> Self {
        Self {
            reproject: false,
            // Depths need the current view: samples splat where they were traced.
            visibility: None,
            ..Self::realtime()
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
            ..Self::realtime()
        }
    }
}

impl Default for ReconParams {
    fn default() -> Self {
        Self::converging()
    }
}
