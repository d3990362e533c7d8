//! The adaptive frameless sampler (paper §4, §6.1, Fig. 5).
//!
//! Each iteration visits a tile chosen uniformly at random: it completes the crosshair
//! the tile initiated on its previous visit (five new co-temporal samples), reprojects
//! `r` crosshairs of the tile to the current view (with an occlusion ray each,
//! replacing occluded ones), and initiates the next crosshair at a random location in
//! the tile. After every chunk of completed crosshairs the K-D tiling is adjusted:
//! gain control sets the tile count from image-wide gradients, then splits and merges
//! equalise tile error. Every ray consumes one slot of the sample budget.

use std::{sync::Arc, time::Instant};

use glam::Vec3;

use super::{
    deep_buffer::{Crosshair, DeepBuffer},
    params::SamplerParams,
    tiling::{Pending, Rect, TileStats, Tiling, NONE},
};
use crate::{
    clock::Clock,
    methods::MethodError,
    sampling::Rng,
    scene::CameraFrame,
    trace::{
        batch::{self, GpuRays},
        Held, Sample, SceneState, StateCache, StreamSample, Tracer,
    },
};

/// Counters of the sampler's work.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct SamplerCounters {
    /// Rays traced (every kind), i.e. budget used.
    pub rays: u64,
    /// Crosshair centers and neighbours traced.
    pub crosshair_samples: u64,
    /// Initiating samples.
    pub initiating_samples: u64,
    /// Occlusion rays.
    pub occlusion_rays: u64,
    /// Crosshairs reprojected.
    pub reprojected: u64,
    /// Reprojected crosshairs found occluded (and replaced).
    pub occluded: u64,
    /// Reprojected crosshairs that left the screen.
    pub offscreen: u64,
    /// Crosshairs left in place because they cannot have moved
    /// (`skip_static_reprojection`).
    pub static_kept: u64,
    /// Tile visits.
    pub visits: u64,
    /// Tiling adjustments.
    pub adjustments: u64,
    /// Splits.
    pub splits: u64,
    /// Merges.
    pub merges: u64,
}

/// Upper bound of rays in one visit: complete (5) + r × (occlusion 1 + replace 5) + 1.
fn max_rays_per_visit(p: &SamplerParams) -> u64 {
    5 + p.reprojections_per_visit as u64 * 6 + 1
}

/// The sampler's state.
pub struct Sampler {
    params: SamplerParams,
    tracer: Arc<Tracer>,
    /// The GPU tracer its samples are traced on (`None`: the CPU tracer).
    rays: Option<Arc<GpuRays>>,
    clock: Clock,
    /// The corner of the pixels it adapts in the image: `(0, 0)` for the whole image,
    /// or that of the region a real-time controller adapts; every position it holds is
    /// relative to it.
    origin: (u32, u32),
    width: u32,
    height: u32,
    tiling: Tiling,
    buffer: DeepBuffer,
    occl_px: Vec<f64>,
    t_ref: f64,
    rng: Rng,
    /// Stratified positions: the seed of the per-pixel sequences, and how many centres
    /// each pixel has had (empty when off).
    seed: u64,
    pixel_draws: Vec<u32>,
    target_tiles: f64,
    since_adjust: usize,
    next_sample: u64,
    budget_end: u64,
    init_cursor: u32,
    initialized: bool,
    states: StateCache,
    /// Time of the first state seen with the current camera: crosshairs traced at or
    /// after it were traced from the camera the display has now.
    camera_since: f64,
    /// Time of the last change of view after the run's first view (−∞ while the view
    /// has not changed): when [`SamplerParams::new_view_prior_s`] starts to fade.
    view_changed_at: f64,
    stream: Vec<StreamSample>,
    counters: SamplerCounters,
    trace_s: f64,
    total_s: f64,
    error_sums: (f64, f64, f64),
    error_sums_tiles: usize,
    /// Floor of every tile's variance term while the view is new
    /// ([`SamplerParams::new_view_prior_s`]), set with the error sums.
    v_prior: f64,
    /// Summed-area table of each pixel's `1 / (1 + n)`, `n` its samples in the
    /// reconstructor's still-region history (`(width + 1) × (height + 1)`; empty: none).
    unconverged: Vec<f64>,
    /// Each tile's unconverged fraction (its mean of `1 / (1 + n)` from `unconverged`),
    /// by node: the tiling's adjustments ask for it several times per crosshair, and
    /// four reads scattered over an image-sized table each time were about half of
    /// the error terms' cost in a live controller at 1280×720. Set for every tile when
    /// the table is, and for the new tiles of every split and merge.
    unconverged_of: Vec<f64>,
}

/// Nodes ranked by an error: `(error, node)`.
type Ranked = Vec<(f64, u32)>;

/// Tiles examined per tiling adjustment.
const ADJUST_CANDIDATES: usize = 64;
/// Adjustments between full recomputations of the error normalisation sums, at
/// least; with more tiles than `ERROR_SUMS_EVERY · 2 · ADJUST_CANDIDATES` (4,096) the
/// full pass waits until the adjustments since have examined as many tiles as it
/// visits ([`error_sums_every`]), so that it never costs more than they do.
const ERROR_SUMS_EVERY: u64 = 32;

/// Adjustments between full recomputations of the error sums with `tiles` tiles: at
/// 1280×720's 14,400 tiles, a pass every 32 adjustments took about a seventh of a live
/// controller's time (docs/performance.md, session 27).
fn error_sums_every(tiles: usize) -> u64 {
    ERROR_SUMS_EVERY.max((tiles / (2 * ADJUST_CANDIDATES)) as u64)
}

/// Shortest time span a temporal gradient is measured over, seconds.
const MIN_GRADIENT_DT: f64 = 1e-3;

/// Seconds after which weights are rebased so that `exp` never overflows.
const REBASE_AFTER_S: f64 = 20.0;

/// A crosshair centre in `rect` for [`SamplerParams::stratified_positions`]: a uniformly
/// random pixel, and in it the next point of that pixel's own R2 sequence (Roberts 2018:
/// steps of the plastic number's inverse powers, whose points fill the square evenly from
/// any start) from a start drawn from `(seed, pixel)`; `next_draw(pixel index)` returns
/// how many centres that pixel had before and counts this one. The position is a pure
/// function of seed, pixel and count; shared by the sequential sampler and the
/// real-time sampling threads.
pub fn stratified_in(
    rect: Rect,
    rng: &mut Rng,
    seed: u64,
    width: u32,
    next_draw: impl FnOnce(usize) -> u32,
) -> (f32, f32) {
    let px = rect.x0 + rng.below(rect.width());
    let py = rect.y0 + rng.below(rect.height());
    stratified_at((px, py), seed, width, next_draw)
}

/// The next point of pixel `(px, py)`'s own R2 sequence ([`stratified_in`]), in
/// image coordinates; `next_draw(pixel index)` counts it.
fn stratified_at(
    (px, py): (u32, u32),
    seed: u64,
    width: u32,
    next_draw: impl FnOnce(usize) -> u32,
) -> (f32, f32) {
    const A: (f64, f64) = (0.754_877_666_246_692_7, 0.569_840_290_998_053_2);
    let p = py as u64 * width as u64 + px as u64;
    let k = next_draw(p as usize);
    let mut start = Rng::new(&[seed, 0x57a7, p]);
    let (u0, v0) = (start.uniform() as f64, start.uniform() as f64);
    let u = (u0 + k as f64 * A.0).fract() as f32;
    let v = (v0 + k as f64 * A.1).fract() as f32;
    (
        (px as f32 + u).min(px as f32 + 0.999),
        (py as f32 + v).min(py as f32 + 0.999),
    )
}

/// The crosshair `points` with each arm's end that is on screen moved, within its
/// pixel, to that pixel's next point of its own R2 sequence, as [`stratified_in`] places
/// centres: a still pixel gathers most of its samples from the arms of crosshairs
/// around it, and at the sub-pixel offsets of those crosshairs' centres they would not
/// cover it evenly. An arm then spans its length give or take a pixel; the gradients
/// still divide by its length.
pub fn stratified_arms(
    mut points: [(f32, f32); 5],
    (width, height): (u32, u32),
    seed: u64,
    mut next_draw: impl FnMut(usize) -> u32,
) -> [(f32, f32); 5] {
    for pt in &mut points[1..] {
        let (x, y) = *pt;
        if x >= 0.0 && y >= 0.0 && x < width as f32 && y < height as f32 {
            *pt = stratified_at((x as u32, y as u32), seed, width, &mut next_draw);
        }
    }
    points
}

/// The `next_draw` of [`stratified_in`] and [`stratified_arms`] over per-pixel counts
/// `draws`: a pixel's count, then that count plus one.
fn counter(draws: &mut [u32]) -> impl FnMut(usize) -> u32 + '_ {
    |p| {
        let k = draws[p];
        draws[p] = k.wrapping_add(1);
        k
    }
}

/// The tile a visit goes to, of `n` ([`SamplerParams::tile_choices`]): of `choices`
/// uniform draws, the one whose last crosshair is the oldest (`last(k)`: when tile `k`
/// initiated its pending crosshair, `None` if it has none, which counts as oldest; the
/// earlier draw wins ties). One draw is the paper's uniform choice, with the same
/// random numbers. Shared by the sequential sampler and the real-time sampling threads.
pub fn choose_tile(
    n: u32,
    choices: u32,
    rng: &mut Rng,
    last: impl Fn(usize) -> Option<f64>,
) -> usize {
    let when = |k: usize| last(k).unwrap_or(f64::NEG_INFINITY);
    let mut best = rng.below(n) as usize;
    for _ in 1..choices {
        let k = rng.below(n) as usize;
        if when(k) < when(best) {
            best = k;
        }
    }
    best
}

/// Where a crosshair's five samples go: the center `(x, y)`, then `arms.0` pixels away
/// in +x and −x and `arms.1` in +y and −y (the order [`crosshair_with`] traces them in).
pub fn crosshair_points((x, y): (f32, f32), (ax, ay): (f32, f32)) -> [(f32, f32); 5] {
    [(x, y), (x + ax, y), (x - ax, y), (x, y + ay), (x, y - ay)]
}

/// A crosshair at `(x, y, t)`: the center and its on-screen neighbours `arms.0` pixels
/// away in ±x and `arms.1` in ±y ([`SamplerParams::arms`]), traced by `trace` (center
/// first, then +x, −x, +y, −y), with gradients per pixel; `old` is the earlier sample
/// at the same location `(luminance, time)` for the temporal gradient. Shared by the
/// sequential sampler and the real-time sampling threads.
pub fn crosshair_with(
    width: u32,
    height: u32,
    points: [(f32, f32); 5],
    arms: (f32, f32),
    t: f64,
    old: Option<(f32, f64)>,
    mut trace: impl FnMut(f32, f32) -> Sample,
) -> Crosshair {
    let on_screen = |x: f32, y: f32| x >= 0.0 && y >= 0.0 && x < width as f32 && y < height as f32;
    let (x, y) = points[0];
    let c = trace(x, y);
    let (ax, ay) = arms;
    let mut lum = [c.luminance; 5];
    let mut p = [c.hit_point; 5];
    for (k, &(nx, ny)) in points[1..].iter().enumerate() {
        if on_screen(nx, ny) {
            let s = trace(nx, ny);
            lum[k + 1] = s.luminance;
            p[k + 1] = s.hit_point;
        }
    }
    let l0 = lum[0];
    // Per pixel of arm length; an arm off screen counts as flat (the paper's rule).
    let gx = ((l0 - lum[1]).abs() + (l0 - lum[2]).abs()) * 0.5 / ax;
    let gy = ((l0 - lum[3]).abs() + (l0 - lum[4]).abs()) * 0.5 / ay;
    let gt = old.map_or(0.0, |old| temporal_gradient((l0, t), old));
    Crosshair {
        x,
        y,
        t,
        lum,
        p,
        velocity: c.velocity,
        gx,
        gy,
        gt,
    }
}

/// Where a pending crosshair is completed, and where its temporal gradient is measured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Completion {
    /// Where the crosshair is traced.
    pub at: (f32, f32),
    /// Where its surface point is seen now, when that is not `at`: one more ray there
    /// measures the temporal gradient against the initiating sample (`None`: the
    /// crosshair's centre measures it).
    pub probe: Option<(f32, f32)>,
}

impl Completion {
    fn at(at: (f32, f32)) -> Self {
        Self { at, probe: None }
    }

    /// What the crosshair's centre compares with for its temporal gradient: the
    /// initiating sample `old`, unless a probe measures it instead.
    pub fn centre_compares_with(&self, old: (f32, f64)) -> Option<(f32, f64)> {
        self.probe.is_none().then_some(old)
    }
}

/// The crosshair of the completion `done` at time `t`, its points `points` (those of
/// `done.at`) traced by `trace` after the probe's, if there is one: its temporal
/// gradient against the earlier sample `old` from the probe where there is one, else
/// from its centre (none without `old`). Shared by the sequential sampler, the CPU
/// sampling threads and the GPU batches, so that all take the probe's sample first.
#[allow(clippy::too_many_arguments)]
pub fn complete_crosshair(
    width: u32,
    height: u32,
    done: Completion,
    points: [(f32, f32); 5],
    arms: (f32, f32),
    t: f64,
    old: Option<(f32, f64)>,
    mut trace: impl FnMut(f32, f32) -> Sample,
) -> Crosshair {
    let probe = done.probe.map(|(x, y)| trace(x, y));
    let centre_old = old.and_then(|o| done.centre_compares_with(o));
    let mut c = crosshair_with(width, height, points, arms, t, centre_old, &mut trace);
    if let (Some(s), Some(o)) = (probe, old) {
        c.gt = temporal_gradient((s.luminance, t), o);
    }
    c
}

/// The temporal gradient between luminance `lum` at time `t` and the earlier sample
/// `(luminance, time)` at the same point (0 unless `t` is later).
pub fn temporal_gradient((lum, t): (f32, f64), (old_lum, old_t): (f32, f64)) -> f32 {
    if t > old_t {
        ((lum - old_lum).abs() as f64 / (t - old_t).max(MIN_GRADIENT_DT)) as f32
    } else {
        0.0
    }
}

/// Where the crosshair `p` initiated in the tile `rect` is completed at time `now`.
///
/// With [`SamplerParams::follow_surface`], the temporal gradient compares the
/// initiating sample's surface point with where that point is seen now, so that it
/// measures change on the surface, not camera motion (which the reconstructor undoes
/// by reprojecting samples). A point still inside `rect` is completed there. A still
/// point the view has carried out of the tile (but not off screen) is probed where it
/// is now with one ray, and the crosshair is traced where it started: completing it
/// where the point went would move the tile's samples downstream of the view's motion,
/// and leave the tiles where the view brings in new surfaces with their initiating
/// samples alone. A moving point that has left the tile completes where it started,
/// unprobed: what its object left behind is the change to measure there, and the visit
/// is spent where that change is. Otherwise (and without the option) where it was
/// initiated. Shared by the sequential sampler and the real-time sampling threads.
pub fn completion_point(
    params: &SamplerParams,
    camera: &CameraFrame,
    p: &Pending,
    rect: Rect,
    now: f64,
    width: u32,
    height: u32,
) -> Completion {
    let start = Completion::at((p.x, p.y));
    if !params.follow_surface {
        return start;
    }
    let Some((x, y, _)) = camera.project(p.hit_point + p.velocity * (now - p.t) as f32) else {
        return start;
    };
    if rect.contains_point(x, y) {
        return Completion::at((x, y));
    }
    let on_screen = x >= 0.0 && y >= 0.0 && x < width as f32 && y < height as f32;
    if p.velocity == Vec3::ZERO && on_screen {
        return Completion {
            at: start.at,
            probe: Some((x, y)),
        };
    }
    start
}

impl Sampler {
    /// A sampler for `tracer`'s scene and image, spending `clock.rate` rays per second.
    pub fn new(
        tracer: Arc<Tracer>,
        clock: Clock,
        params: SamplerParams,
        seed: u64,
    ) -> Result<Self, MethodError> {
        let (width, height) = tracer.size();
        let whole = Rect {
            x0: 0,
            y0: 0,
            x1: width,
            y1: height,
        };
        Self::for_region(tracer, clock, params, seed, whole)
    }

    /// A sampler for the pixels of `region` of `tracer`'s image only, fed by real-time
    /// sampling threads ([`Sampler::ingest_crosshair`], [`Sampler::ingest_pending`]);
    /// it keeps its own tiling, deep buffer and gain control for those pixels. Every
    /// position it takes in, holds and hands out is relative to the region's corner
    /// ([`Sampler::origin`]). A region smaller than the image cannot reproject (its
    /// crosshairs could move out of it, and it cannot trace).
    pub fn for_region(
        tracer: Arc<Tracer>,
        clock: Clock,
        params: SamplerParams,
        seed: u64,
        region: Rect,
    ) -> Result<Self, MethodError> {
        params.validate()?;
        let (iw, ih) = tracer.size();
        let whole = region.x0 == 0 && region.y0 == 0 && (region.x1, region.y1) == (iw, ih);
        if region.x1 > iw || region.y1 > ih || region.area() == 0 {
            return Err(MethodError::Parameter {
                group: "sampler",
                name: "region",
                why: "must be a non-empty rectangle inside the image",
            });
        }
        if !whole && params.reprojection {
            return Err(MethodError::Parameter {
                group: "sampler",
                name: "reprojection",
                why: "must be off in a sampler of part of the image",
            });
        }
        let (width, height) = (region.width(), region.height());
        DeepBuffer::check_budget(width, height, params.depth).map_err(MethodError::Budget)?;
        let mut s = Self {
            params,
            tracer,
            rays: None,
            clock,
            origin: (region.x0, region.y0),
            width,
            height,
            tiling: Tiling::new(width, height),
            buffer: DeepBuffer::new(width, height, params.depth),
            occl_px: vec![0.0; (width * height) as usize],
            t_ref: clock.start,
            rng: Rng::new(&[seed, 0xada9]),
            seed,
            pixel_draws: if params.stratified_positions {
                vec![0; (width * height) as usize]
            } else {
                Vec::new()
            },
            target_tiles: params.fixed_tiles as f64,
            since_adjust: 0,
            next_sample: 0,
            budget_end: 0,
            init_cursor: 0,
            initialized: false,
            states: StateCache::new(),
            camera_since: f64::NEG_INFINITY,
            view_changed_at: f64::NEG_INFINITY,
            stream: Vec::new(),
            counters: SamplerCounters::default(),
            trace_s: 0.0,
            total_s: 0.0,
            error_sums: (0.0, 0.0, 0.0),
            error_sums_tiles: 1,
            v_prior: 0.0,
            unconverged: Vec::new(),
            unconverged_of: Vec::new(),
        };
        if params.uniform_tiling || !params.gain_control {
            // Start from a balanced grid of the fixed size (uniform tiling keeps it).
            s.grow_uniform(params.fixed_tiles.min(s.max_tiles()));
        }
        Ok(s)
    }

    /// The tiling.
    pub fn tiling(&self) -> &Tiling {
        &self.tiling
    }

    /// The corner of its region in the image (`(0, 0)` for the whole image), which its
    /// positions are relative to.
    pub fn origin(&self) -> (u32, u32) {
        self.origin
    }

    /// Size `(width, height)` of its region (the image's, for the whole image).
    pub fn buffer_size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// The deep buffer.
    pub fn buffer(&self) -> &DeepBuffer {
        &self.buffer
    }

    /// Work counters.
    pub fn counters(&self) -> SamplerCounters {
        self.counters
    }

    /// Parameters.
    pub fn params(&self) -> &SamplerParams {
        &self.params
    }

    /// Seconds spent in the tracer, and in the sampler overall.
    pub fn timing(&self) -> (f64, f64) {
        (self.trace_s, self.total_s)
    }

    /// The tile-count target of gain control.
    pub fn target_tiles(&self) -> f64 {
        self.target_tiles
    }

    /// Samples traced since the last call (for the reconstructor).
    pub fn drain_stream(&mut self) -> Vec<StreamSample> {
        std::mem::take(&mut self.stream)
    }

    /// Time of the last change of view the sampler has seen (the start of its run if
    /// none): every sample since was traced from the current view.
    pub fn camera_since(&self) -> f64 {
        self.camera_since
    }

    /// Per-pixel decayed occlusion weight, relative to an event happening now.
    pub fn occlusion_at(&self, x: u32, y: u32, now: f64) -> f64 {
        self.occl_px[(y * self.width + x) as usize] / self.weight(now)
    }

    fn max_tiles(&self) -> usize {
        ((self.width as f64 * self.height as f64 * self.params.max_tiles_per_pixel) as usize).max(1)
    }

    #[inline]
    fn weight(&self, t: f64) -> f64 {
        (self.params.decay * (t - self.t_ref)).exp()
    }

    fn contribution(&self, c: &Crosshair) -> TileStats {
        let w = self.weight(c.t);
        let (mut l, mut l2) = (0.0f64, 0.0f64);
        for &v in &c.lum {
            l += v as f64;
            l2 += v as f64 * v as f64;
        }
        TileStats {
            wc: w,
            wl: w * l,
            wl2: w * l2,
            wgx: w * c.gx as f64,
            wgy: w * c.gy as f64,
            wgt: w * c.gt as f64,
            count: 1.0,
            sum_t: c.t,
            wt: w * c.t,
            occl: 0.0,
        }
    }

    /// Statistics of a rectangle computed from the deep buffer (splits, validation).
    pub fn stats_of(&self, r: Rect) -> TileStats {
        let mut s = TileStats::default();
        for y in r.y0..r.y1 {
            for x in r.x0..r.x1 {
                for c in self.buffer.iter_at(x, y) {
                    s.add(&self.contribution(c), 1.0);
                }
                s.occl += self.occl_px[(y * self.width + x) as usize];
            }
        }
        s
    }

    fn pixel_of(&self, x: f32, y: f32) -> Option<(u32, u32)> {
        if x >= 0.0 && y >= 0.0 && x < self.width as f32 && y < self.height as f32 {
            Some((
                (x as u32).min(self.width - 1),
                (y as u32).min(self.height - 1),
            ))
        } else {
            None
        }
    }

    fn insert_front(&mut self, c: Crosshair) {
        let Some((px, py)) = self.pixel_of(c.x, c.y) else {
            return;
        };
        let leaf = self.tiling.leaf_at(px, py);
        let add = self.contribution(&c);
        self.tiling.add_to_tile(leaf, &add, 1.0);
        if let Some(old) = self.buffer.push_front(px, py, c) {
            let sub = self.contribution(&old);
            self.tiling.add_to_tile(leaf, &sub, -1.0);
        }
    }

    fn record_occlusion(&mut self, px: u32, py: u32, now: f64) {
        let w = self.weight(now);
        self.occl_px[(py * self.width + px) as usize] += w;
        let leaf = self.tiling.leaf_at(px, py);
        self.tiling.add_to_tile(
            leaf,
            &TileStats {
                occl: w,
                ..Default::default()
            },
            1.0,
        );
    }

    fn state(&mut self, t: f64) -> Arc<SceneState> {
        let (s, held) = self.states.at(&self.tracer, t);
        if let Held::New { previous } = held {
            let first = previous.is_none();
            let same_camera = previous.is_some_and(|old| old.camera.same_view(&s.camera));
            if !same_camera {
                self.camera_since = t;
                if !first {
                    self.view_changed_at = t;
                }
            }
        }
        s
    }

    /// Trace its samples on the GPU tracer `rays` (`None`: the CPU tracer). Its
    /// decisions stay on the CPU: each visit's samples depend on the last visit's, so
    /// a crosshair is one batch and an initiating sample another.
    pub fn with_gpu_rays(mut self, rays: Option<Arc<GpuRays>>) -> Self {
        self.rays = rays;
        self
    }

    /// The samples at `points`, all in `state`, on the sampler's tracer.
    fn trace_points(&mut self, state: &SceneState, points: &[[f32; 2]]) -> Vec<Sample> {
        let t0 = Instant::now();
        let got = match &self.rays {
            None => points
                .iter()
                .map(|p| self.tracer.sample(state, p[0], p[1]))
                .collect(),
            Some(r) => batch::trace_points(&self.tracer, Some(r), state, points),
        };
        self.trace_s += t0.elapsed().as_secs_f64();
        got
    }

    /// Count and stream a sample traced at `(x, y, t)`.
    fn record(&mut self, x: f32, y: f32, t: f64, s: Sample) -> Sample {
        self.counters.rays += 1;
        self.stream.push(StreamSample { x, y, t, sample: s });
        s
    }

    fn trace(&mut self, state: &SceneState, x: f32, y: f32, t: f64) -> Sample {
        let s = match self.trace_points(state, &[[x, y]]).first() {
            Some(s) => *s,
            None => self.tracer.sample(state, x, y),
        };
        self.record(x, y, t, s)
    }

    /// Trace a full crosshair for the completion `done` in the tile `rect` (which sets
    /// its arms), with its probe if it has one ([`complete_crosshair`]); `old` is the
    /// earlier sample of the same point `(luminance, time)` for the temporal gradient.
    fn trace_crosshair(
        &mut self,
        state: &SceneState,
        done: Completion,
        rect: Rect,
        t: f64,
        old: Option<(f32, f64)>,
    ) -> Crosshair {
        let (w, h) = (self.width, self.height);
        let arms = self.params.arms(rect);
        // The points `complete_crosshair` traces, in its order, traced as one batch.
        let on_screen = |x: f32, y: f32| x >= 0.0 && y >= 0.0 && x < w as f32 && y < h as f32;
        let cross = crosshair_points(done.at, arms);
        let cross = if self.pixel_draws.is_empty() {
            cross
        } else {
            stratified_arms(cross, (w, h), self.seed, counter(&mut self.pixel_draws))
        };
        let points: Vec<[f32; 2]> = (done.probe.iter().copied())
            .chain(
                cross
                    .iter()
                    .enumerate()
                    .filter(|&(k, &(x, y))| k == 0 || on_screen(x, y))
                    .map(|(_, &p)| p),
            )
            .map(|(x, y)| [x, y])
            .collect();
        let mut got = self.trace_points(state, &points).into_iter();
        let c = complete_crosshair(w, h, done, cross, arms, t, old, |sx, sy| {
            let s = got
                .next()
                .unwrap_or_else(|| self.tracer.sample(state, sx, sy));
            self.record(sx, sy, t, s)
        });
        self.counters.crosshair_samples += 5;
        c
    }

    /// Whether the oldest crosshair at a pixel stays where it is instead of being
    /// reprojected: it cannot have moved (see `skip_static_reprojection`).
    fn keeps_in_place(&mut self, px: u32, py: u32) -> bool {
        if !self.params.skip_static_reprojection {
            return false;
        }
        let since = if self.params.reproject_only_moving {
            f64::NEG_INFINITY
        } else {
            self.camera_since
        };
        let keep = self
            .buffer
            .iter_at(px, py)
            .next()
            .is_some_and(|c| c.velocity == Vec3::ZERO && c.t >= since);
        if keep {
            self.counters.static_kept += 1;
        }
        keep
    }

    /// Reproject one crosshair taken from the tile; returns the rays it used.
    fn reproject(&mut self, state: &SceneState, mut c: Crosshair, now: f64) {
        self.counters.reprojected += 1;
        let cam = state.camera;
        let dt = (now - c.t) as f32;
        let moved: [Vec3; 5] = std::array::from_fn(|k| c.p[k] + c.velocity * dt);
        let Some((x, y, _)) = cam.project(moved[0]) else {
            self.counters.offscreen += 1;
            return;
        };
        let Some((px, py)) = self.pixel_of(x, y) else {
            self.counters.offscreen += 1;
            return;
        };
        // Occlusion ray from the reprojected center toward the eye.
        let t0 = Instant::now();
        let occluded = self.tracer.occluded(state, moved[0], cam.eye);
        self.trace_s += t0.elapsed().as_secs_f64();
        self.counters.rays += 1;
        self.counters.occlusion_rays += 1;
        if occluded {
            self.counters.occluded += 1;
            self.record_occlusion(px, py, now);
            let rect = self.tiling.node(self.tiling.leaf_at(px, py)).rect;
            let fresh = self.trace_crosshair(state, Completion::at((x, y)), rect, now, Some((c.lum[0], c.t)));
            self.insert_front(fresh);
            self.since_adjust += 1;
            return;
        }
        // Spatial gradients from the neighbours' new positions.
        let grad = |k: usize| -> f32 {
            match cam.project(moved[k]) {
                Some((nx, ny, _)) => {
                    let d = ((nx - x).powi(2) + (ny - y).powi(2)).sqrt().max(0.25);
                    (c.lum[0] - c.lum[k]).abs() / d
                }
                None => (c.lum[0] - c.lum[k]).abs(),
            }
        };
        c.gx = (grad(1) + grad(2)) * 0.5;
        c.gy = (grad(3) + grad(4)) * 0.5;
        if let Some(gt) = self.temporal_gradient(&c, moved[0], &cam, (x, y), (px, py), now) {
            c.gt = gt;
        }
        c.x = x;
        c.y = y;
        c.p = moved;
        // The crosshair keeps its time: reprojection moves information, it does not
        // refresh it. It goes to the back of its new queue, replacing an older one.
        let leaf = self.tiling.leaf_at(px, py);
        if self.buffer.len_at(px, py) == self.buffer.depth() {
            match self.buffer.iter_at(px, py).last() {
                Some(back) if back.t < c.t => {
                    let old = self.buffer.pop_back(px, py).expect("full queue");
                    let sub = self.contribution(&old);
                    self.tiling.add_to_tile(leaf, &sub, -1.0);
                }
                _ => return,
            }
        }
        let add = self.contribution(&c);
        self.tiling.add_to_tile(leaf, &add, 1.0);
        let _ = self.buffer.push_back(px, py, c);
    }

    /// The temporal gradient of crosshair `c`, reprojected to `(x, y)` (pixel `(px,
    /// py)`, its centre at `centre` now), against the newest crosshair there; `None`
    /// where there is none to compare with.
    ///
    /// The paper divides by that sample's age; we divide by the time between the two
    /// samples, over which the difference arose: a very recent newest sample otherwise
    /// inflates the gradient without bound. With `same_surface_gradients`, only where
    /// that crosshair saw the same surface point (within a pixel and 5% in depth, both
    /// moved to now): a crosshair traced there under an earlier camera saw another
    /// surface, and their difference measures camera motion, which the reconstructor
    /// undoes by reprojecting.
    fn temporal_gradient(
        &self,
        c: &Crosshair,
        centre: Vec3,
        cam: &CameraFrame,
        (x, y): (f32, f32),
        (px, py): (u32, u32),
        now: f64,
    ) -> Option<f32> {
        let n = self.buffer.newest(px, py)?;
        let same = !self.params.same_surface_gradients || {
            let z = (centre - cam.eye).dot(cam.forward);
            cam.project(n.p[0] + n.velocity * (now - n.t) as f32)
                .is_some_and(|(nx, ny, nz)| {
                    (nx - x).abs() <= 1.0 && (ny - y).abs() <= 1.0 && (nz - z).abs() <= 0.05 * z
                })
        };
        let dt = (n.t - c.t).abs().max(MIN_GRADIENT_DT);
        same.then(|| ((c.lum[0] - n.lum[0]).abs() as f64 / dt) as f32)
    }

    /// The reprojection step of a visit to `leaf`: `reprojections_per_visit` random
    /// pixels of the tile give up their oldest crosshair, which is reprojected to `now`
    /// (the tiling does not change meanwhile, so each one's tile is `leaf`).
    fn reproject_in(&mut self, state: &SceneState, leaf: u32, now: f64) {
        let rect = self.tiling.node(leaf).rect;
        for _ in 0..self.params.reprojections_per_visit {
            let (x, y) = rect.random_point(&mut self.rng);
            let (px, py) = (x as u32, y as u32);
            if self.keeps_in_place(px, py) {
                continue;
            }
            if let Some(c) = self.buffer.pop_front(px, py) {
                let sub = self.contribution(&c);
                self.tiling.add_to_tile(leaf, &sub, -1.0);
                self.reproject(state, c, now);
            }
        }
    }

    fn visit(&mut self, leaf: u32, now: f64) {
        let state = self.state(now);
        self.counters.visits += 1;
        let rect = self.tiling.node(leaf).rect;
        if let Some(p) = self.tiling.node_mut(leaf).pending.take() {
            let at = p.follow(&state, now);
            let done = completion_point(&self.params, &state.camera, &at, rect, now, self.width, self.height);
            let c = self.trace_crosshair(&state, done, rect, now, Some((p.lum, p.t)));
            self.insert_front(c);
            self.since_adjust += 1;
        }
        if self.params.reprojection {
            self.reproject_in(&state, leaf, now);
        }
        // The tiling may not have changed during the visit; the leaf is still a tile.
        let (x, y) = self.initiating_point(rect);
        let s = self.trace(&state, x, y, now);
        self.counters.initiating_samples += 1;
        let leaf_now = self.tiling.leaf_at(x as u32, y as u32);
        self.tiling.node_mut(leaf_now).pending = Some(Pending {
            x,
            y,
            t: now,
            lum: s.luminance,
            hit_point: s.hit_point,
            velocity: s.velocity,
            anchor: s.anchor,
        });
    }

    /// Where a new crosshair starts in `rect`: uniformly at random, or with
    /// [`SamplerParams::stratified_positions`] a uniformly random pixel and the next
    /// point of that pixel's own R2 sequence (a pure function of seed, pixel and count).
    fn initiating_point(&mut self, rect: Rect) -> (f32, f32) {
        if self.pixel_draws.is_empty() {
            return rect.random_point(&mut self.rng);
        }
        let draws = counter(&mut self.pixel_draws);
        stratified_in(rect, &mut self.rng, self.seed, self.width, draws)
    }

    /// The initial spatially gridded, co-temporal crosshairs (resumable: the budget may
    /// run out part way).
    fn initialize(&mut self) {
        let sp = self.params.init_spacing;
        let (nx, ny) = (self.width.div_ceil(sp), self.height.div_ceil(sp));
        let now = self.clock.start;
        let state = self.state(now);
        while self.init_cursor < nx * ny {
            if self.next_sample + 5 > self.budget_end {
                return;
            }
            let (gx, gy) = (self.init_cursor % nx, self.init_cursor / nx);
            let (x, y) = (
                (gx * sp + sp / 2).min(self.width - 1),
                (gy * sp + sp / 2).min(self.height - 1),
            );
            let t = self.clock.sample_time(self.next_sample);
            let before = self.counters.rays;
            // The grid cell the crosshair stands for is its tile.
            let (x0, y0) = (x.saturating_sub(sp / 2), y.saturating_sub(sp / 2));
            let cell = Rect {
                x0,
                y0,
                x1: x0 + sp,
                y1: y0 + sp,
            };
            let at = Completion::at((x as f32 + 0.5, y as f32 + 0.5));
            let c = self.trace_crosshair(&state, at, cell, t, None);
            self.insert_front(c);
            self.next_sample += self.counters.rays - before;
            self.init_cursor += 1;
        }
        self.initialized = true;
    }

    /// Run every visit the budget allows up to time `t`.
    pub fn run_until(&mut self, t: f64) {
        let t_start = Instant::now();
        self.budget_end = self.clock.samples_until(t);
        if !self.initialized {
            self.initialize();
        }
        let max_cost = max_rays_per_visit(&self.params);
        while self.initialized && self.next_sample + max_cost <= self.budget_end {
            let now = self.clock.sample_time(self.next_sample);
            if now - self.t_ref > REBASE_AFTER_S {
                self.rebase(now);
            }
            let tiling = &self.tiling;
            let k = choose_tile(tiling.len() as u32, self.params.tile_choices, &mut self.rng, |k| {
                tiling.node(tiling.leaves()[k]).pending.map(|p| p.t)
            });
            let leaf = self.tiling.leaves()[k];
            let before = self.counters.rays;
            self.visit(leaf, now);
            self.next_sample += self.counters.rays - before;
            if self.since_adjust >= self.params.chunk {
                self.since_adjust = 0;
                self.adjust(now);
            }
        }
        self.total_s += t_start.elapsed().as_secs_f64();
    }

    fn rebase(&mut self, now: f64) {
        let f = (-self.params.decay * (now - self.t_ref)).exp();
        self.tiling.scale_weights(f);
        for o in &mut self.occl_px {
            *o *= f;
        }
        self.t_ref = now;
    }

    /// Tell the sampler how many samples each pixel's still-region history holds, so
    /// that a tile's variance counts as what its pixels' means still lack
    /// ([`SamplerParams::discount_converged`]; a count map of the wrong size is
    /// ignored). Until it is first called every pixel counts as unconverged.
    pub fn set_history_counts(&mut self, counts: &[f32]) {
        let (w, h) = (self.width as usize, self.height as usize);
        if counts.len() != w * h {
            return;
        }
        let stride = w + 1;
        // Row 0 and column 0 stay zero and every other entry is written below, so a
        // table of the right size is reused as it is: zeroing it again cost as much as
        // filling it (docs/performance.md, session 34).
        if self.unconverged.len() != stride * (h + 1) {
            self.unconverged.clear();
            self.unconverged.resize(stride * (h + 1), 0.0);
        }
        // A row's terms first, in vector form (a division each), then its running sums.
        let mut terms = vec![0.0f64; w];
        for (y, counts) in counts.chunks_exact(w).enumerate() {
            for (t, &n) in terms.iter_mut().zip(counts) {
                *t = 1.0 / (1.0 + n as f64);
            }
            let (above, this) = self.unconverged[y * stride..(y + 2) * stride].split_at_mut(stride);
            let mut row = 0.0;
            for x in 0..w {
                row += terms[x];
                this[x + 1] = above[x + 1] + row;
            }
        }
        for i in 0..self.tiling.leaves().len() {
            self.note_unconverged(self.tiling.leaves()[i]);
        }
    }

    /// The mean of `1 / (1 + n)` over `r`, from the summed-area table (which must be set).
    fn unconverged_in(&self, r: Rect) -> f64 {
        let stride = self.width as usize + 1;
        let at = |x: u32, y: u32| self.unconverged[y as usize * stride + x as usize];
        let sum = at(r.x1, r.y1) - at(r.x0, r.y1) - at(r.x1, r.y0) + at(r.x0, r.y0);
        (sum / r.area() as f64).max(0.0)
    }

    /// Keep tile `node`'s unconverged fraction, if there is a history count map.
    fn note_unconverged(&mut self, node: u32) {
        if self.unconverged.is_empty() {
            return;
        }
        let i = node as usize;
        if self.unconverged_of.len() <= i {
            self.unconverged_of.resize(i + 1, 0.0);
        }
        self.unconverged_of[i] = self.unconverged_in(self.tiling.node(node).rect);
    }

    /// The raw terms `(v, u, o)` of one tile's error.
    fn error_terms(&self, leaf: u32, mean_empty: f64, w_now: f64) -> (f64, f64, f64) {
        let b = self.params.depth as f64;
        let n = self.tiling.node(leaf);
        let s = n.rect.area() as f64;
        let mut v = n.stats.variance().max(self.v_prior);
        if !self.unconverged.is_empty() {
            v *= self.unconverged_of[leaf as usize];
        }
        // Undersampling compares empty *fractions* of the tile's and the image's slots.
        // The paper compares counts (empty slots in the tile against the mean per tile);
        // with counts every large tile looks undersampled, so large uniform tiles are
        // split as soon as they are merged and the tiling cannot coarsen where the image
        // is flat.
        let empty = (s * b - n.stats.count).max(0.0) / (s * b);
        let u = if empty > 0.0 {
            1.0 - (self.params.undersampling_m * mean_empty / empty).min(1.0)
        } else {
            0.0
        };
        let o = n.stats.occl / w_now / (s * b);
        (v, u, o)
    }

    fn error_context(&self, now: f64) -> (f64, f64) {
        let total = self.tiling.total();
        let capacity = self.width as f64 * self.height as f64 * self.params.depth as f64;
        let mean_empty = (capacity - total.count).max(0.0) / capacity;
        (mean_empty, self.weight(now))
    }

    /// Recompute the sums `(Σv, Σu, Σo)` over all tiles that normalise tile error.
    fn refresh_error_sums(&mut self, now: f64) {
        let (me, w) = self.error_context(now);
        let mut sums = (0.0, 0.0, 0.0);
        let tau = self.params.new_view_prior_s;
        if tau > 0.0 {
            // Until a tile's own samples say otherwise, assume the image's mean variance
            // there, fading as the view stays put (a still view concentrates samples
            // where the variance is known to be).
            let leaves = self.tiling.leaf_nodes();
            let mean: f64 = leaves.map(|(_, n)| n.stats.variance()).sum::<f64>()
                / self.tiling.len().max(1) as f64;
            // Only a change of view: a run that starts still concentrates its samples
            // from the start, as before.
            let still = (now - self.view_changed_at).max(0.0);
            self.v_prior = mean * (-still / tau).exp();
        }
        for (l, _) in self.tiling.leaf_nodes() {
            let (v, u, o) = self.error_terms(l, me, w);
            sums.0 += v;
            sums.1 += u;
            sums.2 += o;
        }
        self.error_sums = sums;
        self.error_sums_tiles = self.tiling.len();
    }

    /// Tile error `E = s·(κ v/Σv + λ u/Σu + (1−κ−λ) o/Σo)`.
    fn error(&self, leaf: u32, mean_empty: f64, w_now: f64) -> f64 {
        let p = &self.params;
        let (v, u, o) = self.error_terms(leaf, mean_empty, w_now);
        let (sv, su, so) = self.error_sums;
        let (kappa, lambda) = if p.occlusion_term {
            (p.kappa, p.lambda)
        } else {
            (1.0 - p.lambda, p.lambda)
        };
        let norm = |x: f64, sum: f64| if sum > 0.0 { x / sum } else { 0.0 };
        let s = self.tiling.node(leaf).rect.area() as f64;
        s * (kappa * norm(v, sv) + lambda * norm(u, su) + (1.0 - kappa - lambda) * norm(o, so))
    }

    /// Image-wide inputs of gain control: age-weighted mean spatial gradient
    /// `(Gx + Gy)/2`, temporal gradient `Gt`, and age-weighted mean sample age `T`.
    pub fn gain_inputs(&self, now: f64) -> (f64, f64, f64) {
        let total = self.tiling.total();
        let (gx, gy, gt) = total.gradients();
        (0.5 * (gx + gy), gt, total.weighted_age(now))
    }

    /// Gain control: the tile count for which `dC/ds · S = i · dC/dt · T`, i.e. tiles of
    /// width `S = i·Gt·T/Gs`, clamped to `[min_tiles, max_tiles]`.
    fn gain_target(&self, now: f64) -> f64 {
        let (gs, gt, age) = self.gain_inputs(now);
        let pixels = self.width as f64 * self.height as f64;
        let hi = self.max_tiles() as f64;
        // A display smaller than `min_tiles` tiles of the finest size holds fewer tiles
        // than the floor asks for; the ceiling (what the pixels can hold) wins.
        let lo = (self.params.min_tiles as f64).min(hi);
        if gs <= 1e-9 {
            return lo; // a flat image needs no adaptation
        }
        let s = self.params.gain_i * gt * age / gs; // tile width in pixels
        if s <= 1e-9 {
            return hi; // static: adapt as finely as allowed
        }
        (pixels / (s * s)).clamp(lo, hi)
    }

    fn split_tile(&mut self, leaf: u32) {
        // The first child's statistics come from the buffer (a scan bounded by the
        // tile's area); the second's are the remainder.
        let r = self.tiling.node(leaf).rect;
        let half = if r.width() >= r.height() {
            Rect {
                x1: r.x0 + r.width() / 2,
                ..r
            }
        } else {
            Rect {
                y1: r.y0 + r.height() / 2,
                ..r
            }
        };
        let s = self.stats_of(half);
        let (a, b) = self.tiling.split(leaf, |_| s);
        self.note_unconverged(a);
        self.note_unconverged(b);
        self.counters.splits += 1;
    }

    fn grow_uniform(&mut self, n: usize) {
        while self.tiling.len() < n {
            // Split the largest tile: a near-uniform grid.
            let Some(&l) = self
                .tiling
                .leaves()
                .iter()
                .filter(|&&l| self.tiling.splittable(l, self.params.min_tile_side))
                .max_by_key(|&&l| self.tiling.node(l).rect.area())
            else {
                break;
            };
            self.split_tile(l);
        }
    }

    /// The candidates of one adjustment, from `ADJUST_CANDIDATES` random tiles: the
    /// splittable tiles by error, largest first, and the mergeable pairs by their summed
    /// error, smallest first (each once).
    fn adjustment_candidates(&mut self, now: f64) -> (Ranked, Ranked) {
        let min_side = self.params.min_tile_side;
        let (me, w) = self.error_context(now);
        let n_leaves = self.tiling.len();
        let mut splits: Ranked = Vec::with_capacity(ADJUST_CANDIDATES);
        let mut pairs: Ranked = Vec::with_capacity(ADJUST_CANDIDATES);
        // The candidates are drawn first and their nodes (and then their parents) asked
        // of the cache, so that their misses overlap instead of queueing one after
        // another (docs/performance.md, session 34); the same draws as one at a time.
        let mut drawn = [0u32; ADJUST_CANDIDATES];
        let drawn = &mut drawn[..ADJUST_CANDIDATES.min(n_leaves * 2)];
        for d in drawn.iter_mut() {
            *d = self.tiling.leaves()[self.rng.below(n_leaves as u32) as usize];
            self.tiling.prefetch_node(*d);
        }
        for &l in drawn.iter() {
            let parent = self.tiling.node(l).parent;
            if parent != NONE {
                self.tiling.prefetch_node(parent);
            }
        }
        for &l in drawn.iter() {
            let e = self.error(l, me, w);
            if self.tiling.splittable(l, min_side) {
                splits.push((e, l));
            }
            let parent = self.tiling.node(l).parent;
            if parent != NONE && self.tiling.mergeable(parent) {
                let c = self.tiling.node(parent).children;
                let sib = if c == l { c + 1 } else { c };
                pairs.push((e + self.error(sib, me, w), parent));
            }
        }
        splits.sort_by(|a, b| b.0.total_cmp(&a.0));
        splits.dedup_by_key(|x| x.1);
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
        pairs.dedup_by_key(|x| x.1);
        (splits, pairs)
    }

    /// After a chunk of crosshairs: steer the tile count, then balance tile errors.
    ///
    /// Bounded work: candidates for splitting and merging come from a random subset of
    /// `ADJUST_CANDIDATES` tiles, and the sums that normalise tile error are refreshed
    /// only every [`error_sums_every`] adjustments or when the tile count has moved by
    /// more than 10%; at most `max_adjust_ops` splits and merges happen.
    fn adjust(&mut self, now: f64) {
        self.counters.adjustments += 1;
        let p = self.params;
        if p.uniform_tiling {
            return;
        }
        if p.gain_control {
            let target = self.gain_target(now);
            self.target_tiles =
                p.gain_smoothing * self.target_tiles + (1.0 - p.gain_smoothing) * target;
        }
        let stale = self.tiling.len().abs_diff(self.error_sums_tiles) * 10 > self.error_sums_tiles;
        if self.counters.adjustments % error_sums_every(self.tiling.len()) == 1 || stale {
            self.refresh_error_sums(now);
        }
        let (splits, pairs) = self.adjustment_candidates(now);
        let mut splits = splits.into_iter().peekable();
        let mut pairs = pairs.into_iter().peekable();
        let mut ops = 0;
        while ops < p.max_adjust_ops {
            // Drop candidates that earlier operations of this adjustment invalidated.
            while splits
                .peek()
                .is_some_and(|&(_, l)| self.tiling.node(l).leaf_slot == NONE)
            {
                splits.next();
            }
            while pairs
                .peek()
                .is_some_and(|&(_, n)| !self.tiling.mergeable(n))
            {
                pairs.next();
            }
            let n = self.tiling.len() as f64;
            if n < self.target_tiles - 0.5 {
                let Some((_, l)) = splits.next() else { break };
                self.split_tile(l);
                ops += 1;
            } else if n > self.target_tiles + 0.5 {
                let Some((_, parent)) = pairs.next() else {
                    break;
                };
                self.tiling.merge(parent);
                self.note_unconverged(parent);
                self.counters.merges += 1;
                ops += 1;
            } else {
                match (splits.peek().copied(), pairs.peek().copied()) {
                    (Some((emax, l)), Some((epair, parent)))
                        if emax > p.balance_ratio * epair
                            && self.tiling.node(l).parent != parent =>
                    {
                        splits.next();
                        pairs.next();
                        self.tiling.merge(parent);
                self.note_unconverged(parent);
                        self.counters.merges += 1;
                        self.split_tile(l);
                        ops += 2;
                    }
                    _ => break,
                }
            }
        }
    }

    /// Real-time mode: ask the cache for what taking in something at `(x, y)` reads,
    /// in two steps a few visits apart (`late`: the second, which reads what the first
    /// asked for): the pixel's queue and tile first, then the deep-buffer slot and the
    /// tile's node. The controller's visits land at scattered pixels, and each waited
    /// on several misses in turn (docs/performance.md, session 34).
    pub fn prefetch_visit(&self, x: f32, y: f32, late: bool) {
        let Some((px, py)) = self.pixel_of(x, y) else {
            return;
        };
        if late {
            self.buffer.prefetch_front_slot(px, py);
            self.tiling.prefetch_node(self.tiling.leaf_at(px, py));
        } else {
            self.buffer.prefetch_queue(px, py);
            self.tiling.prefetch_leaf_at(px, py);
        }
    }

    /// Real-time mode: take in a crosshair traced elsewhere (by a sampling thread) at
    /// time `now`, then adjust the tiling after every chunk, as a visit would.
    /// `rays` is what tracing it cost.
    pub fn ingest_crosshair(&mut self, c: Crosshair, rays: u64, now: f64) {
        if now - self.t_ref > REBASE_AFTER_S {
            self.rebase(now);
        }
        self.counters.rays += rays;
        self.counters.crosshair_samples += 5;
        self.next_sample += rays;
        self.insert_front(c);
        self.since_adjust += 1;
        if self.since_adjust >= self.params.chunk {
            self.since_adjust = 0;
            self.adjust(now);
        }
    }

    /// Real-time mode: look at the view at `now`, as a visit does before it traces. The
    /// controller's sampler traces nothing itself, so without this it would never see
    /// the camera move, and the prior a change of view sets
    /// ([`SamplerParams::new_view_prior_s`]) would never hold live.
    pub fn observe_view(&mut self, now: f64) {
        let _ = self.state(now);
    }

    /// Real-time mode: an initiating sample traced elsewhere becomes the pending
    /// crosshair of the tile it lies in (replacing what was pending there).
    pub fn ingest_pending(&mut self, p: Pending) {
        self.counters.rays += 1;
        self.counters.initiating_samples += 1;
        self.next_sample += 1;
        self.counters.visits += 1;
        let Some((px, py)) = self.pixel_of(p.x, p.y) else {
            return;
        };
        let leaf = self.tiling.leaf_at(px, py);
        self.tiling.node_mut(leaf).pending = Some(p);
    }

    /// Real-time mode: clear the pending crosshair at `(x, y)` if it is still the one
    /// initiated at time `t` (a sampling thread completed it).
    pub fn clear_pending(&mut self, x: f32, y: f32, t: f64) {
        let Some((px, py)) = self.pixel_of(x, y) else {
            return;
        };
        let leaf = self.tiling.leaf_at(px, py);
        let n = self.tiling.node_mut(leaf);
        if n.pending.is_some_and(|p| p.t == t && p.x == x && p.y == y) {
            n.pending = None;
        }
    }

    /// Real-time mode: the reprojection step of a visit to the tile containing pixel
    /// `(px, py)` at time `now` (`reprojections_per_visit` crosshairs, occlusion rays
    /// traced on the calling thread). Replacement crosshairs go to the stream.
    pub fn reproject_visit(&mut self, px: u32, py: u32, now: f64) {
        if !self.params.reprojection || px >= self.width || py >= self.height {
            return;
        }
        let state = self.state(now);
        let leaf = self.tiling.leaf_at(px, py);
        let before = self.counters.rays;
        self.reproject_in(&state, leaf, now);
        self.next_sample += self.counters.rays - before;
        if self.since_adjust >= self.params.chunk {
            self.since_adjust = 0;
            self.adjust(now);
        }
    }

    /// Check the tiling against the deep buffer (tests; expensive).
    pub fn validate(&self) -> Result<(), MethodError> {
        let f = |r: Rect| self.stats_of(r);
        self.tiling.validate(Some(&f), 1e-6)?;
        if self.unconverged.is_empty() {
            return Ok(());
        }
        for &l in self.tiling.leaves() {
            let (kept, want) = (self.unconverged_of[l as usize], self.unconverged_in(self.tiling.node(l).rect));
            if kept.to_bits() != want.to_bits() {
                return Err(MethodError::Inconsistent {
                    what: "sampler",
                    why: format!("tile {l} keeps unconverged fraction {kept}, its pixels give {want}"),
                });
            }
        }
        Ok(())
    }

    /// Samples (rays) used so far.
    pub fn samples_used(&self) -> u64 {
        self.next_sample
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_error_sums_wait_longer_only_past_four_thousand_tiles() {
        // Up to 4,096 tiles (every evaluation at 256×256) the pass runs every 32
        // adjustments, as it always did; past that it costs what the candidates do.
        for tiles in [1, 1024, 4096, 4223] {
            assert_eq!(error_sums_every(tiles), ERROR_SUMS_EVERY, "{tiles} tiles");
        }
        assert_eq!(error_sums_every(14_400), 112);
        assert_eq!(error_sums_every(32_400), 253);
    }
}
