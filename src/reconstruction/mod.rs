//! The adaptive space-time reconstructor (paper §5, §6.2).
//!
//! The reconstructor keeps its own deep buffer: a ring of the `N` most recent samples
//! the sampler traced, in the order they were pushed. At each display refresh (time
//! `t`) it
//!
//! 1. reprojects every sample to the current view: world point `hit_point + velocity ·
//!    (t − t_sample)` projected by the current camera (misses carry a far hit point,
//!    1e6 along their ray, so only camera rotation moves them). In the paper's preset
//!    there is no depth test: stale samples behind newly visible surfaces are
//!    suppressed by the temporal filter only. With [`ReconParams::visibility`] (ours)
//!    each pixel's front depth is the nearest of the samples landing in it (still ones
//!    of any age, moving ones younger than `setter_age_sigmas` temporal sigmas; while
//!    the view moves, also `moving_view_spread` times the nearest of its eight
//!    neighbours'), and a sample landing behind its pixel's front (beyond the depth
//!    tolerance) is not splatted;
//! 2. looks up the filter of the tile containing the reprojected pixel (extents from the
//!    tile's local sample rate and gradients, [`filter::extents`]) and the splat scale
//!    of that pixel (from the previous refresh's coverage map);
//! 3. splats it: a Gaussian `w = exp(−½((dx/e_x)² + (dy/e_y)² + (age/e_t)²))` over
//!    the pixels whose centers lie within `spatial_cutoff · scale` sigmas along x and
//!    along y (a box, at most `max_radius` pixels from the sample) — the splat scale
//!    widens the footprint (the paper's point size), not the kernel, so a wide splat
//!    only matters where no nearer sample outweighs it; samples older than
//!    `temporal_cutoff · e_t` are skipped;
//! 4. divides accumulated weighted color by accumulated weight; pixels no sample
//!    reached (accumulated weight below `MIN_WEIGHT` = 1e-24: holes) are filled from
//!    the coarsest-necessary level of a 2×2 pull pyramid of the same sums (a wider box
//!    pass: the weighted mean of the nearest block that has samples), so a hole never
//!    shows black unless nothing at all was sampled yet. With
//!    [`ReconParams::fill_weight`] > 0 (ours) holes and every pixel of lower weight
//!    are instead completed from a smooth pull-push interpolation (`pullpush.rs`), so
//!    sparse regions are not a patchwork of flat cells;
//! 5. updates the splat scale map from the coverage (samples whose footprint covers
//!    each pixel): fewer than `undersampled` → ×`grow`, more than `oversampled` →
//!    ×`shrink`, clamped to `scale_bounds`.
//!
//! With [`ReconParams::carry`] (ours) only the samples pushed since the previous refresh
//! go through steps 1–3, onto the accumulators of the previous refresh, decayed and moved
//! with the surfaces they show (`carry.rs`): a refresh then costs the new samples and the
//! pixels, not the ring. The rest of this comment describes the ring's refresh, which
//! the paper's preset keeps and which places the new samples when carrying.
//!
//! How a refresh stays cheap (the same images as evaluating the above directly, up to
//! f32 rounding: `tests::fast_path_matches_direct_evaluation`):
//!
//! - **Stale cut.** Samples older than `temporal_cutoff ·` (largest `e_t` of any tile)
//!   fail step 3 wherever they land, so they are skipped before reprojection: `push`
//!   keeps the running largest time at the end of every block of 256 pushes
//!   (non-decreasing whatever order samples come in), and a binary search finds the
//!   blocks that are stale as a whole. With the camera moving (BART kitchen) this skips
//!   about 70% of the ring.
//! - **Filters per tile.** Each refresh computes one filter per tile (with the
//!   constants a splat needs) and a per-pixel tile lookup of 4 bytes, so a sample finds
//!   its filter from a table that fits a core's L2 cache (256×256).
//!   [`Reconstructor::filter_map`] is built from the table on request.
//! - **A struct-of-arrays ring, placed in blocks.** The ring ([`ring::Ring`]) keeps
//!   one array per field. Samples go through each stage a block of 64 at a time:
//!   reprojection in vector code over the hit point, velocity and time arrays; the
//!   pixel lookups, independent loads in flight together; the temporal cull,
//!   footprint and temporal weight of every lane in vector code (float bounds turned
//!   into integers without saturating conversions); then a list of survivors, and
//!   only they read their color and are binned. No branch depends on a sample until
//!   the survivors' loop.
//! - **Vector splats.** Accumulators are cells of 8 aligned pixels × 5 channels (weighted
//!   r, g, b, weight, weighted age), one 256-bit vector per channel. A splat computes
//!   the Gaussian column weights of the cells it touches (8 lanes at a time, zero
//!   outside its footprint, branch-free fast exp), multiplies them by its colour once,
//!   and adds `(g_x·c)·g_y` to each row with one fused multiply-add per channel and
//!   cell. Coverage comes from corner differences, four per splat and band.
//! - **No allocation per refresh**: bins, accumulators and the pull pyramid are
//!   reused; a few holes read memoised block sums around them instead of a whole
//!   pyramid (the same sums added in the same order, so the same image).
//!
//! Splatting runs in parallel over horizontal bands of rows (16 rows with several
//! threads, 64 on one); each band visits the samples touching it in ring order and
//! writes only its own pixels, and every weight is computed from offsets to the
//! splat's own first row and column, so every pixel's sums are formed from the same
//! terms in the same order whatever the thread count (bit-identical images).
//!
//! This file holds the [`Reconstructor`] and the order of a refresh's steps; each step
//! lives in its own file: `filter_table.rs` (the per-tile filters and per-pixel lookup
//! of step 2), `place.rs` (the stale cut, steps 1–3 up to the temporal cull, binning into
//! row bands), `splat.rs` (accumulating step 3's splats), `resolve.rs` (steps 4 and 5),
//! `holes.rs` and `pullpush.rs` (step 4's hole and low-density filling); `lanes.rs` holds the 8-lane arithmetic they
//! share, `params.rs` the parameters and presets.

pub mod device;
pub mod filter;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod ring;
pub use passes::{PassTimes, PASSES};

mod carry;
mod carry_edits;
#[cfg(test)]
mod carry_tests;
mod filter_table;
#[cfg(all(test, feature = "gpu"))]
mod gpu_tests;
mod history;
mod holes;
mod lanes;
mod late;
mod params;
mod passes;
mod place;
mod plan;
mod pullpush;
mod resolve;
mod splat;
mod spread;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod visibility_tests;

use std::sync::OnceLock;

use glam::Vec3;

use crate::{
    image::Image,
    scene::CameraFrame,
    tiles::TilingSnapshot,
    trace::{Anchor, SceneState, StreamSample},
};
pub use filter::{Extents, FilterBounds};
use filter_table::{Lookup, TileFilter};
use history::History;
pub use history::HistoryParams;
pub use lanes::fast_exp_neg;
pub(crate) use lanes::{prefetch, prefetch_addr, touch};
pub use params::{ReconParams, Visibility};
use plan::RefreshPlan;
pub use ring::Ring;
use splat::{Splat, BAND_ROWS, CHANNELS};
use spread::FootprintTest;

/// One sample of the reconstructor's deep buffer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RingSample {
    /// Sub-pixel position where it was traced.
    pub x: f32,
    /// Sub-pixel position where it was traced.
    pub y: f32,
    /// Time it was traced.
    pub t: f64,
    /// Its color.
    pub color: Vec3,
    /// World point of the primary hit (far point along the ray for a miss).
    pub hit_point: Vec3,
    /// World velocity of the hit point.
    pub velocity: Vec3,
    /// What the hit point is fixed to (where it is at display time, exactly).
    pub anchor: Anchor,
}

impl From<&StreamSample> for RingSample {
    fn from(s: &StreamSample) -> Self {
        Self {
            x: s.x,
            y: s.y,
            t: s.t,
            color: s.sample.color,
            hit_point: s.sample.hit_point,
            velocity: s.sample.velocity,
            anchor: s.sample.anchor,
        }
    }
}

/// The adaptive reconstructor.
pub struct Reconstructor {
    params: ReconParams,
    /// The scene at the next refresh's time, to place moving samples exactly (used
    /// by that refresh only, so a stale scene is never applied to a later one).
    motion: Option<std::sync::Arc<SceneState>>,
    width: u32,
    height: u32,
    rate: f64,
    capacity: usize,
    ring: Ring,
    /// Cut the ring's stale prefix before placing samples (off only to test the cut).
    skip_stale: bool,
    /// Place at most this many of the newest samples (a real-time time budget).
    live_limit: Option<usize>,
    /// Samples placed at the last refresh (the ring past its stale part and limit).
    placed: usize,
    /// Filter per tile at the last refresh.
    tiles: Vec<TileFilter>,
    /// Each pixel's tile.
    lookup: Vec<Lookup>,
    /// Where each of `tiles` lies on the image (clipped to it).
    tile_rects: Vec<crate::tiles::Rect>,
    /// `lookup` is not yet this refresh's (a GPU refresh needs none on the CPU).
    lookup_stale: bool,
    /// The tile rectangles `lookup` was made from: a refresh whose tiles lie where
    /// they did keeps it. Live, the sampler's tiles mostly keep their places from one
    /// image to the next (docs/performance.md, session 50).
    map_rects: Vec<crate::tiles::Rect>,
    /// Per-pixel filter map, built on request from `tiles` and `tile_rects`.
    filters: OnceLock<Vec<[f32; 3]>>,
    scale: Vec<f32>,
    coverage: Vec<u32>,
    /// Accumulators: per row, [`CHANNELS`] runs of `cs` floats (see
    /// [`splat::channel_stride`]).
    acc: Vec<f32>,
    cs: usize,
    /// Per-row coverage differences, rows of `width + 1`.
    cov: Vec<i32>,
    /// With [`ReconParams::carry`]: each pixel's coverage decayed over the refreshes
    /// (unused otherwise).
    cover: Vec<f32>,
    /// With [`ReconParams::carry`]: the accumulators' state between refreshes.
    carried: Option<Box<carry::Carried>>,
    /// This refresh re-splats the ring although the reconstructor carries
    /// ([`ReconParams::resplat_moving_view`]).
    resplat: bool,
    /// Front depths of the visibility pass, one per pixel (empty without it).
    front: Vec<f32>,
    /// The fronts' spread while the view moves ([`Visibility::moving_view_spread`]).
    spread: spread::Spread,
    /// Where the eye was at the recent refreshes, and as `(age, eye)` from the
    /// newest ([`spread::EyeTrack::ages`]): the eye a sample was traced from.
    eyes: spread::EyeTrack,
    eye_ages: Vec<(f32, Vec3)>,
    /// Rows per band of the splat at the last refresh.
    band_rows: usize,
    /// Splats of the last refresh: per piece of the ring (in ring order), per band.
    /// Kept across refreshes so their allocations are reused.
    binned: Vec<Vec<Vec<Splat>>>,
    /// Pieces of `binned` filled at the last refresh.
    pieces: usize,
    /// Where the place pass put each sample it placed, `(x, y, depth)` in logical ring
    /// order from index `located_from`, for the carry's cut to read instead of
    /// projecting every new sample again (the same arithmetic); `None` once read, and
    /// where no place pass ran (a refresh on the GPU).
    located: Vec<[f32; 3]>,
    located_from: Option<usize>,
    /// Dense pull pyramid of the hole filling (levels 1 and up), reused.
    pyramid: Vec<(usize, usize, Vec<[f64; CHANNELS]>)>,
    /// Pull-push levels of the low-density fill (level 1 and up), reused.
    pull: pullpush::Pyramid,
    /// The coverage weight of a fill whose last push into the image is still to come
    /// (the history's blend does it a row at a time, as it reads the rows).
    pending_push: Option<f32>,
    /// The carry's decay, left for the splat's band pass to apply ([`carry::LateDecay`]).
    late_decay: Option<carry::LateDecay>,
    /// A spent [`carry::LateDecay`]'s per-pixel flags, cleared, for the next.
    late_flags: Vec<bool>,
    /// Whether a refresh on the CPU leaves the carry's decay to the splat: always,
    /// but in the test that holds it to decaying at once.
    decay_late: bool,
    image: Image,
    /// Weight-averaged sample age of each pixel at the last refresh.
    age: Vec<f32>,
    mean_age: f64,
    holes: usize,
    /// The still-region history, if the parameters ask for one.
    history: Option<History>,
    /// The GPU side, when refreshes run there ([`Reconstructor::use_gpu`]).
    #[cfg(feature = "gpu")]
    gpu: Option<Box<gpu::GpuRecon>>,
    /// The initial front depths a carrying refresh on the GPU sent last, kept between
    /// refreshes: the GPU keeps them too, and the next refresh sends only those that
    /// changed (`gpu_front_changes`, `[pixel, bits]`) where it can.
    #[cfg(feature = "gpu")]
    gpu_front: Vec<u32>,
    #[cfg(feature = "gpu")]
    gpu_front_changes: Vec<[u32; 2]>,
    /// [`FEW_FRONTS`]; the tests lift it (`None`) so that their small images, dense
    /// with samples, go the incremental way too.
    #[cfg(feature = "gpu")]
    few_fronts: Option<usize>,
    /// Refreshes whose kept fronts were checked against a full recompute.
    #[cfg(all(test, feature = "gpu"))]
    kept_fronts_checked: usize,
    /// Why the GPU side was given up, if it failed at a refresh (they then run on the
    /// CPU).
    gpu_failure: Option<String>,
    /// Wall time of each step of the CPU refreshes.
    passes: PassTimes,
    /// While a refresh is built in two parts ([`Reconstructor::reconstruct_taking_late`]):
    /// the newest sample time its temporal filter counts ages from.
    origin_ahead: Option<f64>,
    /// How much newer the samples a second part took in were than the first part's
    /// newest, smoothed over refreshes: where the first part expects the ages' origin.
    late_gap: f64,
}

/// Where more than one pixel in this many may have a changed carried front beyond
/// those the cut settled (which come with theirs), they are all recomputed in order
/// rather than one by one ([`Reconstructor::pack_fronts`]).
#[cfg(feature = "gpu")]
const FEW_FRONTS: usize = 16;

impl Reconstructor {
    /// Check that a reconstructor for a `width × height` display with `params` fits the
    /// run budgets ([`crate::limits`]) before any of it is allocated.
    pub fn check_budget(
        width: u32,
        height: u32,
        params: &ReconParams,
    ) -> Result<(), crate::limits::LimitError> {
        crate::limits::check_display(width, height)?;
        let n = width as u64 * height as u64;
        let capacity = (params.ring_factor * n as f64).round().max(1.0);
        let per_sample = (ring::field::COUNT * 4 + 8) as f64;
        crate::limits::check_buffer(
            "reconstructor's sample ring",
            (capacity * per_sample).min(u64::MAX as f64) as u64,
            &format!(
                "ring factor {} × {width}x{height} pixels",
                params.ring_factor
            ),
        )
    }

    /// A reconstructor for a `width × height` display fed by a sampler spending `rate`
    /// samples per second (the `R` of the local rate `R_l`). Callers check
    /// [`Reconstructor::check_budget`] first where the size comes from a user.
    pub fn new(width: u32, height: u32, rate: f64, params: ReconParams) -> Self {
        let n = (width * height) as usize;
        let capacity = ((params.ring_factor * n as f64).round() as usize).max(1);
        let cs = splat::channel_stride(width as usize);
        let scale0 = initial_scale(&params);
        // One tile, the whole image, which the map of zeros already shows.
        let whole = crate::tiles::Rect {
            x0: 0,
            y0: 0,
            x1: width,
            y1: height,
        };
        Self {
            motion: None,
            params,
            width,
            height,
            rate,
            capacity,
            ring: Ring::new(capacity),
            skip_stale: true,
            live_limit: None,
            placed: 0,
            tiles: vec![TileFilter::new([1.0; 3], params.spatial_cutoff)],
            lookup: vec![Lookup { tile: 0 }; n],
            tile_rects: vec![whole],
            lookup_stale: false,
            map_rects: vec![whole],
            filters: OnceLock::new(),
            scale: vec![scale0; n],
            coverage: vec![0; n],
            acc: vec![0.0; height as usize * CHANNELS * cs],
            cs,
            cov: vec![0; height as usize * (width as usize + 1)],
            cover: vec![0.0; n],
            carried: params
                .carry
                .then(|| Box::new(carry::Carried::new(n, height as usize * CHANNELS * cs))),
            resplat: false,
            front: Vec::new(),
            spread: spread::Spread::default(),
            eyes: spread::EyeTrack::default(),
            eye_ages: Vec::new(),
            band_rows: BAND_ROWS,
            binned: Vec::new(),
            pieces: 0,
            located: Vec::new(),
            located_from: None,
            pyramid: Vec::new(),
            pull: pullpush::Pyramid::default(),
            pending_push: None,
            late_decay: None,
            late_flags: Vec::new(),
            decay_late: true,
            image: Image::new(width, height),
            age: vec![0.0; n],
            mean_age: 0.0,
            holes: n,
            history: params.history.map(|h| History::new(width, height, h)),
            #[cfg(feature = "gpu")]
            gpu: None,
            #[cfg(feature = "gpu")]
            gpu_front: Vec::new(),
            #[cfg(feature = "gpu")]
            few_fronts: Some(FEW_FRONTS),
            #[cfg(feature = "gpu")]
            gpu_front_changes: Vec::new(),
            #[cfg(all(test, feature = "gpu"))]
            kept_fronts_checked: 0,
            gpu_failure: None,
            passes: PassTimes::default(),
            origin_ahead: None,
            late_gap: 0.0,
        }
    }

    /// Allocate now, and back with memory, the per-pixel state that CPU refreshes
    /// would otherwise allocate or first write during the first refreshes (the
    /// still-region history, the fill's pyramid, the accumulators and carried sums)
    /// and the sample ring: a live pipeline calls it before its clock starts, so that
    /// its first images are not held up by the system mapping in pages (at 1920×1080
    /// about 400 MB, and first builds of 0.2–0.3 s). The ring fills over seconds, but
    /// mapping its pages in as samples arrived slowed every build while it filled
    /// (docs/performance.md, session 50). With refreshes on a GPU only the ring, which the CPU
    /// keeps there too. Changes no result.
    pub fn prepare(&mut self) {
        use lanes::touch;
        self.ring.prepare();
        if self.refreshes_on_gpu() {
            return;
        }
        let (w, h) = (self.width as usize, self.height as usize);
        touch(&mut self.acc);
        touch(&mut self.cov);
        touch(&mut self.cover);
        touch(&mut self.coverage);
        touch(&mut self.age);
        touch(&mut self.image.pixels);
        if let Some(c) = &mut self.carried {
            c.prepare();
        }
        if let Some(hist) = &mut self.history {
            hist.prepare();
        }
        self.pull.prepare(w, h);
    }

    /// Run refreshes on `ctx`'s GPU from now on. An error if the adapter is too small
    /// for this display's buffers.
    #[cfg(feature = "gpu")]
    pub fn use_gpu(&mut self, ctx: std::sync::Arc<gpu::GpuContext>) -> Result<(), gpu::GpuError> {
        let scale0 = initial_scale(&self.params);
        self.scale.fill(scale0);
        self.gpu = Some(Box::new(gpu::GpuRecon::new(
            ctx,
            (self.width, self.height),
            self.capacity,
            scale0,
            self.history.as_ref().map(|h| *h.params()),
            self.gpu_sums_back(),
        )?));
        if let Some(c) = &mut self.carried {
            // For the GPU to replay.
            c.edits = Some(Default::default());
        }
        Ok(())
    }

    /// What a GPU side gives back of the carried sums, when carrying: a moving view
    /// moves them on the CPU unless it re-splats the ring, and that needs them all;
    /// otherwise the CPU's carry needs only which pixels hold sums.
    #[cfg(feature = "gpu")]
    fn gpu_sums_back(&self) -> Option<gpu::SumsBack> {
        self.carried.as_ref().map(|_| {
            if self.holds_only_back() {
                gpu::SumsBack::Holds
            } else {
                gpu::SumsBack::All
            }
        })
    }

    /// Whether a GPU that keeps the carried sums gives back only which pixels hold
    /// some (`SumsBack::Holds`): unless a moving view moves them on the CPU.
    fn holds_only_back(&self) -> bool {
        !self.params.reproject || self.params.resplat_moving_view
    }

    /// Run refreshes on a GPU: this build has none.
    #[cfg(not(feature = "gpu"))]
    pub fn use_gpu(
        &mut self,
        ctx: std::sync::Arc<device::GpuContext>,
    ) -> Result<(), device::GpuError> {
        match *ctx {}
    }

    /// Where refreshes run: the CPU, or the GPU adapter in words.
    pub fn used(&self) -> device::ReconUsed {
        #[cfg(feature = "gpu")]
        if let Some(g) = &self.gpu {
            return g.context().used();
        }
        device::ReconUsed::cpu()
    }

    /// Why the GPU side was given up at a refresh, if it was.
    pub fn gpu_failure(&self) -> Option<&str> {
        self.gpu_failure.as_deref()
    }

    /// With refreshes on a GPU that carry: of the carrying refreshes so far, how many
    /// uploaded every pixel's carried sums and how many replayed the CPU's carry on
    /// the sums the GPU kept (only the view's holding refreshes can).
    pub fn gpu_carried_sums(&self) -> Option<(u64, u64)> {
        #[cfg(feature = "gpu")]
        if let (Some(g), Some(_)) = (&self.gpu, &self.carried) {
            let by = g.carried_by();
            return Some((by.upload, by.replay));
        }
        None
    }

    /// The sampler's rate `R` (samples per second) that the filters scale with, from
    /// the next refresh on; the ring, splat scale and history stay. A rate that is not
    /// finite and positive is ignored.
    pub fn set_rate(&mut self, rate: f64) {
        if rate.is_finite() && rate > 0.0 {
            self.rate = rate;
        }
    }

    /// The parameters.
    pub fn params(&self) -> &ReconParams {
        &self.params
    }

    /// Place at most the `limit` newest samples of the ring at each refresh (`None`:
    /// all within the temporal cutoff), so that a display that must have an image at
    /// every refresh can bound the reconstruction's cost. Older samples are left out
    /// as if the ring were that short: the image is that of a shorter ring.
    pub fn set_live_limit(&mut self, limit: Option<usize>) {
        self.live_limit = limit;
    }

    /// Samples placed at the last refresh: the ring from its first sample within the
    /// temporal cutoff of some tile, at most the live limit.
    pub fn placed(&self) -> usize {
        self.placed
    }

    /// Ring capacity `N`.
    pub fn capacity(&self) -> usize {
        self.capacity
    }

    /// Samples in the ring, oldest first.
    pub fn ring(&self) -> &Ring {
        &self.ring
    }

    /// Append a sample (the oldest is dropped once the ring is full). Samples should
    /// come about in the order they were traced: any order is reconstructed the same,
    /// but the stale part of the ring is skipped only up to the first sample pushed
    /// after a recent one.
    pub fn push(&mut self, s: RingSample) {
        self.push_marked(s, false);
    }

    /// [`Reconstructor::push`], saying whether something moving took part in the
    /// sample beyond its own velocity ([`crate::trace::Sample::dynamic`]): such a
    /// sample cuts its pixel's still-region history instead of joining it.
    pub fn push_marked(&mut self, s: RingSample, dynamic: bool) {
        self.push_to_history(&s, dynamic);
        if let Some(c) = &mut self.carried {
            c.pending += 1;
        }
        self.ring.push(&s);
    }

    /// [`Reconstructor::push`] each of `ss`, in order.
    pub fn push_all(&mut self, ss: &[RingSample]) {
        for s in ss {
            self.push_to_history(s, false);
        }
        self.push_all_to_ring(ss);
    }

    /// The ring's part of pushing each of `ss`.
    fn push_all_to_ring(&mut self, ss: &[RingSample]) {
        if let Some(c) = &mut self.carried {
            c.pending += ss.len();
        }
        self.ring.extend(ss);
    }

    /// Give the still-region history samples no image will place (a live limit left
    /// them out of the ring): it takes in every sample it is given at the next
    /// refresh, and traced samples are worth as much to it placed or not.
    pub fn push_history_only(&mut self, stream: &[StreamSample]) {
        for s in stream {
            self.push_to_history(&RingSample::from(s), s.sample.dynamic);
        }
    }

    /// Note `s` for the still-region history, if there is one; `dynamic` as
    /// [`Reconstructor::push_marked`] takes it.
    fn push_to_history(&mut self, s: &RingSample, dynamic: bool) {
        if let Some(h) = &mut self.history {
            h.push(s, dynamic || s.velocity != Vec3::ZERO);
        }
    }

    /// Append the sampler's stream, as [`Reconstructor::push_marked`] each sample (the
    /// ring takes them a run at a time: one at a time cost twice as much).
    pub fn push_stream(&mut self, stream: &[StreamSample]) {
        let mut run = Vec::with_capacity(stream.len().min(ring::EXTEND_CHUNK));
        for part in stream.chunks(ring::EXTEND_CHUNK) {
            run.clear();
            run.extend(part.iter().map(RingSample::from));
            for (r, s) in run.iter().zip(part) {
                self.push_to_history(r, s.sample.dynamic);
            }
            self.push_all_to_ring(&run);
        }
    }

    /// The last reconstructed image.
    pub fn image(&self) -> &Image {
        &self.image
    }

    /// Each pixel's weight-averaged sample age at the last refresh, seconds (holes
    /// take the age of the block they were filled from).
    pub fn pixel_ages(&self) -> &[f32] {
        &self.age
    }

    /// Pixel mean of [`Reconstructor::pixel_ages`], seconds.
    pub fn mean_age(&self) -> f64 {
        self.mean_age
    }

    /// Samples in each pixel's still-region history (`None` without one).
    pub fn history_counts(&self) -> Option<&[f32]> {
        self.history.as_ref().map(|h| h.counts())
    }

    /// Pixels whose history was cut (a moving sample, or the reconstruction
    /// disagreed), in all.
    pub fn history_cuts(&self) -> u64 {
        self.history.as_ref().map_or(0, |h| h.cuts)
    }

    /// Pixels no sample reached at the last refresh (filled from the pyramid).
    pub fn holes(&self) -> usize {
        self.holes
    }

    /// Samples that reached each pixel at the last refresh (read back now where a GPU
    /// made that refresh and kept them).
    pub fn coverage(&mut self) -> &[u32] {
        self.read_gpu_extras();
        &self.coverage
    }

    /// Per-pixel splat scale used by the next refresh (read back now where a GPU made
    /// the last refresh and kept them).
    pub fn splat_scale(&mut self) -> &[f32] {
        self.read_gpu_extras();
        &self.scale
    }

    /// Bring up the coverage and splat scales a GPU's last refresh kept there (where
    /// the CPU's sums are its holds mask, nothing on the CPU reads them between
    /// refreshes). A GPU that cannot is given up, as after a refresh that fails there.
    fn read_gpu_extras(&mut self) {
        #[cfg(feature = "gpu")]
        if let Some(g) = &mut self.gpu {
            if let Err(e) = g.read_extras(&mut self.coverage, &mut self.scale) {
                self.give_up_gpu(e);
            }
        }
    }

    /// The filter extents each pixel had at the last refresh (`[e_x, e_y, e_t]`).
    pub fn filter_map(&self) -> &[[f32; 3]] {
        self.filters.get_or_init(|| {
            let w = self.width as usize;
            let mut map = vec![[0.0; 3]; w * self.height as usize];
            for (f, r) in self.tiles.iter().zip(&self.tile_rects) {
                for y in r.y0 as usize..r.y1 as usize {
                    map[y * w + r.x0 as usize..y * w + r.x1 as usize].fill(f.e);
                }
            }
            map
        })
    }

    /// Tell the still-region history that the view has been the one of the next
    /// refresh since time `t0` (the sampler knows; without it, samples count only if
    /// the view was also the same at the previous refresh).
    pub fn set_view_since(&mut self, t0: f64) {
        if let Some(h) = &mut self.history {
            h.set_view_since(t0);
        }
    }

    /// The scene at the next refresh's time: with [`ReconParams::exact_motion`],
    /// samples fixed to moving things are placed where their points are then (`None`,
    /// or without it: extrapolated by their velocity). Applies to the next refresh
    /// only; set it before each.
    pub fn set_motion(&mut self, state: Option<std::sync::Arc<SceneState>>) {
        self.motion = state;
    }

    /// The ratio this refresh spreads the front depths by, if it does: the view moved
    /// ([`Visibility::moving_view_spread`]).
    fn front_spread(&self) -> Option<f32> {
        let v = self.params.visibility_in_use()?;
        v.moving_view_spread.filter(|_| self.resplat)
    }

    /// The parameters as this refresh applies them: the fronts spread only while the
    /// view moves ([`Reconstructor::front_spread`]).
    #[cfg(feature = "gpu")]
    fn refresh_params(&self) -> ReconParams {
        let mut p = self.params;
        if let Some(v) = &mut p.visibility {
            v.moving_view_spread = self.front_spread();
            v.footprint_reach = self.footprint_reach(v);
        }
        p
    }

    /// The footprint's reach at this refresh: [`Visibility::footprint_reach`], at most
    /// [`Visibility::footprint_reach_spacings`] times the spacing of the samples the
    /// sampler's rate brings in between this refresh and the previous one.
    fn footprint_reach(&self, v: &Visibility) -> f32 {
        let pixels = (self.width * self.height) as f64;
        match self.eye_ages.get(1) {
            Some(&(dt, _)) if dt > 0.0 && self.rate > 0.0 => {
                let spacing = (pixels / (self.rate * dt as f64)).sqrt() as f32;
                v.footprint_reach.min(v.footprint_reach_spacings * spacing)
            }
            _ => v.footprint_reach,
        }
    }

    /// The spread's ratio, the parallax test's pixels
    /// ([`Visibility::spread_parallax`]) and the footprint's spread with its parallax
    /// and this refresh's reach ([`Visibility::footprint_spread`]).
    fn spread_test(&self) -> (f32, f32, Option<FootprintTest>) {
        let v = self.params.visibility.unwrap_or_default();
        let footprint = v.footprint_spread.map(|ratio| FootprintTest {
            ratio,
            parallax: v.footprint_parallax,
            reach: self.footprint_reach(&v),
        });
        (
            v.moving_view_spread.unwrap_or(1.0),
            v.spread_parallax,
            footprint,
        )
    }

    /// `1 / (1 + depth tolerance)` when the visibility pass is in use.
    fn visibility_keep(&self) -> Option<f32> {
        self.params
            .visibility_in_use()
            .map(|v| 1.0 / (1.0 + v.depth_tolerance))
    }

    /// Reconstruct the image at display time `t` seen by `camera`, with filters from
    /// `tiling` (the sampler's current tiling).
    pub fn reconstruct(&mut self, t: f64, camera: &CameraFrame, tiling: &TilingSnapshot) -> &Image {
        self.refresh(t, camera, tiling);
        // The scene given for this refresh is never applied to a later one.
        self.motion = None;
        &self.image
    }

    /// The image of the last refresh, handing it over instead of copying it: `spare`,
    /// an image of the same size whose pixels are of no further use (one shown
    /// before, say), becomes the buffer the next refresh writes, as every refresh
    /// writes every pixel. Without a spare, or with one of another size (dropped),
    /// the image is copied.
    pub fn take_image(&mut self, spare: Option<Image>) -> Image {
        match spare {
            Some(s) if (s.width, s.height) == (self.image.width, self.image.height) => {
                std::mem::replace(&mut self.image, s)
            }
            _ => self.image.clone(),
        }
    }

    /// [`Reconstructor::reconstruct`]'s steps: the plan, then its passes on the GPU if
    /// there is one, else (or if it failed now) on the CPU.
    fn refresh(&mut self, t: f64, camera: &CameraFrame, tiling: &TilingSnapshot) {
        self.eyes.push(t, camera.eye);
        self.eye_ages = self.eyes.ages();
        let mut plan = self.plan(t, camera, tiling);
        if !self.refresh_on_gpu(&mut plan) {
            self.refresh_on_cpu(&mut plan);
        }
        self.passes.count_refresh();
    }

    /// The CPU's passes of `plan`.
    fn refresh_on_cpu(&mut self, plan: &mut RefreshPlan) {
        let mut lap = std::time::Instant::now();
        self.prepare_splats(plan);
        lap = self.passes.lap(1, lap);
        if self.carries_now() {
            let start = self.ring.len() - self.placed;
            self.carry_over(plan.t, &plan.camera, start, self.decay_late);
        }
        self.located_from = None;
        lap = self.passes.lap(3, lap);
        // After the carry: the fronts start from the still geometry it carried.
        self.front_depths();
        lap = self.passes.lap(2, lap);
        self.splat_to_end(plan, lap, None);
    }

    /// `plan`'s splat, resolve, fill and history on the CPU, from `lap`; with `added`,
    /// the splats of the pieces from it on go over the sums those before made.
    fn splat_to_end(
        &mut self,
        plan: &mut RefreshPlan,
        lap: std::time::Instant,
        added: Option<usize>,
    ) {
        let blend_follows = self.history.is_some() && plan.history.is_some();
        let lap = self.splat_and_resolve(lap, blend_follows, &plan.camera, added);
        if self.resplat {
            self.restart_carry();
        }
        let front = self.visibility_keep().map(|k| (&self.front[..], k));
        if let (Some(h), Some(step)) = (&mut self.history, plan.history.take()) {
            // The fill's last push, row by row as the blend reads the rows.
            let size = (self.width as usize, self.height as usize);
            let last = (self.pending_push.take())
                .and_then(|w0| self.pull.last_push(&self.acc, self.cs, size, w0));
            let push = |rows: &mut pullpush::PushRows, y, px: &mut [Vec3], age: &mut [f32]| {
                if let Some(l) = &last {
                    l.row(rows, y, px, age);
                }
            };
            let age_sum = h.apply_finishing(step, (&mut self.image, &mut self.age), front, &push);
            self.mean_age = age_sum / self.age.len().max(1) as f64;
        }
        self.passes.lap(6, lap);
    }

    /// Wall time of each step of the CPU refreshes so far.
    pub fn pass_times(&self) -> &PassTimes {
        &self.passes
    }

    /// `plan`'s passes on the GPU, if there is one; false if they are still to be done
    /// (no GPU, or it failed now: then it is given up, and the CPU carries out the same
    /// plan).
    fn refresh_on_gpu(&mut self, plan: &mut RefreshPlan) -> bool {
        #[cfg(feature = "gpu")]
        if self.gpu.is_some() {
            match self.reconstruct_on_gpu(plan) {
                Ok(()) => return true,
                Err(e) => {
                    if self.give_up_gpu(e) {
                        plan.start = self.live_range(plan.t);
                    }
                }
            }
        }
        let _ = plan;
        false
    }

    /// Refresh on the CPU from now on, the GPU having failed with `e`. Whether the
    /// CPU starts afresh: where its sums were only the GPU's holds mask, they start
    /// from the whole live ring, and the coverage and splat scales, which the GPU
    /// kept, from their first.
    #[cfg(feature = "gpu")]
    fn give_up_gpu(&mut self, e: gpu::GpuError) -> bool {
        self.gpu = None;
        self.gpu_failure = Some(e.to_string());
        let holds_only = self.gpu_sums_back() == Some(gpu::SumsBack::Holds);
        if let Some(c) = &mut self.carried {
            c.edits = None;
            c.restart |= holds_only;
        }
        if holds_only {
            self.scale.fill(initial_scale(&self.params));
            self.coverage.fill(0);
            self.lookup_stale = true;
        }
        holds_only
    }

    /// `plan`'s splat, resolve, fill and history on the GPU (when carrying, the carry
    /// step stays here).
    #[cfg(feature = "gpu")]
    fn reconstruct_on_gpu(&mut self, plan: &mut RefreshPlan) -> Result<(), gpu::GpuError> {
        let (t, camera, start) = (plan.t, plan.camera, plan.start);
        let pending = self.carried.as_ref().map(|c| c.pending);
        let lap = std::time::Instant::now();
        // Carrying: the CPU carries the sums to `t` (as `refresh_on_cpu` does), and
        // they go up with the new splats.
        let carrying = !self.resplat && self.carried.is_some();
        if carrying {
            self.carry_over(t, &camera, start, false);
        }
        let lap = self.passes.lap(3, lap);
        let fronts = if carrying { self.pack_fronts() } else { None };
        let carried = carrying.then(|| gpu::carried::CarriedIn {
            front: fronts.map(|sent| match sent {
                FrontsSent::All => gpu::carried::FrontsIn::All(&self.gpu_front),
                FrontsSent::Changes => gpu::carried::FrontsIn::Changes(&self.gpu_front_changes),
            }),
        });
        let pack_s = lap.elapsed().as_secs_f64();
        let max_r = self.max_footprint_radius();
        let params = self.refresh_params();
        let Some(g) = self.gpu.as_mut() else {
            return Ok(());
        };
        let before = g.times();
        g.set_eye_track(&self.eye_ages);
        // The sums the GPU kept from its last refresh are the CPU's before its
        // carry: replaying the carry there spares uploading every pixel's.
        let edits = self.carried.as_ref().and_then(|c| c.edits.as_ref());
        if carrying && !edits.is_some_and(|e| g.carry_by_replay(e)) {
            let sums = gpu::carried::CarriedSums {
                acc: &self.acc,
                cs: self.cs,
                w: self.width as usize,
                cover: &self.cover,
            };
            g.upload_carried(&sums)?;
        }
        let into = gpu::ReadInto {
            image: &mut self.image.pixels,
            age: &mut self.age,
            coverage: &mut self.coverage,
            scale: &mut self.scale,
            sums: (&mut self.acc, self.cs, &mut self.cover),
            // Given back with the step's outcome (`take_in_gpu_back`).
            counts: match (&mut self.history, &plan.history) {
                (Some(h), Some(_)) => h.take_gpu_counts(),
                _ => Vec::new(),
            },
            edited: edits.filter(|e| e.complete),
        };
        let back = g.refresh(
            &self.ring,
            start,
            plan.moved,
            t,
            self.params.reproject.then_some(&camera),
            &self.tiles,
            &self.tile_rects,
            &params,
            max_r,
            plan.history.as_ref(),
            carried.as_ref(),
            into,
        );
        let after = g.times();
        self.passes
            .add(7, pack_s + after.upload_s - before.upload_s);
        self.passes.add(8, after.wait_s - before.wait_s);
        self.passes.add(9, after.read_s - before.read_s);
        let back = back.inspect_err(|_| {
            // The CPU redoes this refresh: its new samples are pending again (the sums
            // already carried to `t` carry on over no time).
            if let (Some(c), Some(n)) = (&mut self.carried, pending) {
                c.pending = n;
            }
        })?;
        self.take_in_gpu_back(plan, back);
        Ok(())
    }

    /// What a GPU refresh gave back besides the image, taken in (which counts as
    /// reading it back).
    #[cfg(feature = "gpu")]
    fn take_in_gpu_back(&mut self, plan: &mut RefreshPlan, back: gpu::Readback) {
        let lap = std::time::Instant::now();
        if self.resplat {
            self.restart_carry();
        }
        self.holes = back.holes;
        if let (Some(h), Some(step), Some(hb)) =
            (&mut self.history, plan.history.take(), back.history)
        {
            h.done_on_gpu(step, hb.counts, hb.cuts);
        }
        self.mean_age = lanes::lane_sum(&self.age) / self.age.len().max(1) as f64;
        self.passes.lap(9, lap);
    }

    /// With the visibility pass, the initial front depths a carrying refresh on the
    /// GPU adds the new splats to, by the CPU's rule ([`carry::carried_fronts`])
    /// over no new splat, into `gpu_front`, and which of them go up. Where the GPU kept
    /// the last refresh's and this carry is listed whole, a front can have changed
    /// only where the last read-back changed a weight or this carry edited a pixel
    /// (its takes, landings, cuts and settled geometry): those alone are recomputed
    /// (the settled ones the cut found already), and the ones that changed go up.
    /// Otherwise (the first refresh, a carry that restarted or moved with the view,
    /// sums that come back whole, a new GPU side) every pixel's.
    #[cfg(feature = "gpu")]
    fn pack_fronts(&mut self) -> Option<FrontsSent> {
        self.visibility_keep()?;
        let (n, w, cs) = (self.cover.len(), self.width as usize, self.cs);
        let since = self.gpu.as_ref().and_then(|g| g.fronts_since());
        let carried = self.carried.as_deref();
        let edits = carried
            .and_then(|c| c.edits.as_ref())
            .filter(|e| e.complete);
        if let (Some(changed), Some(c), Some(e)) = (since, carried, edits) {
            // The settled pixels come with their fronts, in the cut's order; the
            // other dirty ones are read at random, the whole image in order: on
            // lavapipe at 1280×720 33K dirty pixels of 922K were cheaper one by one,
            // 133K were not, nor 33K of 307K at 640×480 (performance.md, session 43).
            let dirty = changed.len() + e.takes.len() + e.cuts.len() + e.lands.len();
            let few = self.few_fronts.is_none_or(|f| dirty <= n / f);
            if self.gpu_front.len() == n && few {
                let lands = e.lands.iter().map(|l| l.1);
                let dirty = changed.iter().chain(&e.takes).chain(&e.cuts);
                let dirty = (&e.settled[..], dirty.copied().chain(lands));
                let (kept, changes) = (&mut self.gpu_front, &mut self.gpu_front_changes);
                carry::changed_front_bits(c, (&self.acc, w, cs), dirty, kept, changes);
                let few = changes.len() <= n / 4;
                #[cfg(test)]
                self.check_kept_fronts();
                // Eight bytes a change against four a pixel.
                return Some(if few {
                    FrontsSent::Changes
                } else {
                    FrontsSent::All
                });
            }
        }
        let mut bits = std::mem::take(&mut self.gpu_front);
        self.carried_front_bits(&mut bits);
        self.gpu_front = bits;
        Some(FrontsSent::All)
    }

    /// The fronts kept and brought up to date at the pixels that may have changed are
    /// those a full recompute gives.
    #[cfg(all(test, feature = "gpu"))]
    fn check_kept_fronts(&mut self) {
        let mut full = Vec::new();
        self.carried_front_bits(&mut full);
        let wrong = full.iter().zip(&self.gpu_front).position(|(a, b)| a != b);
        assert_eq!(wrong, None, "kept fronts differ from a full recompute");
        self.kept_fronts_checked += 1;
    }
}

/// Which of the initial front depths a carrying GPU refresh sends.
#[cfg(feature = "gpu")]
#[derive(Clone, Copy)]
enum FrontsSent {
    /// Every pixel's (`gpu_front`).
    All,
    /// Those that changed since the last refresh (`gpu_front_changes`).
    Changes,
}

/// Every pixel's splat scale before any refresh.
fn initial_scale(params: &ReconParams) -> f32 {
    params.scale_bounds.0.max(1e-3)
}
