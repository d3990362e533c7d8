//! The real-time adaptive method: adaptive sampling threads, controller threads that
//! each own the tiling and the deep buffer of one band of the image, and the adaptive
//! space-time reconstructor on the image thread.
//!
//! ```text
//!  sampling ×N ──crosshairs, initiating samples──► controller ×K, one per band of rows
//!      ▲             (to the band of the tile)     (Sampler: deep buffer, tiling,
//!      │                                            gain control, reprojection)
//!      └──── tile snapshots (Arc, ~1 ms) ◄──────────┘   │ samples + tiling snapshot
//!                                                       ▼
//!                                     image thread: Reconstructor at the display rate
//! ```
//!
//! A sampling thread visits a tile of the published snapshots (the bands' tiles taken
//! together): it completes the crosshair the tile's pending sample initiated, where its
//! surface point is now ([`completion_point`], as the sequential sampler; taking its
//! five pixels) and initiates the next one at a random location in the tile (taking that
//! pixel). A taken pixel means another thread is there: it picks another tile or
//! location.
//!
//! A controller holds an ordinary [`Sampler`] for its band ([`Sampler::for_region`])
//! and feeds it what the sampling threads traced there: completed crosshairs (inserted,
//! with tile statistics updated and the tiling adjusted after every chunk, exactly as
//! in a sequential visit) and initiating samples (which become their tile's pending
//! crosshair). The reprojection step of each visit runs there too, occlusion rays
//! included — but only while the controller keeps up with its input: when batches
//! queue up it skips reprojection for that batch, so that the tiling never lags behind
//! the samples (the share that ran is reported). About every millisecond it publishes
//! its tiles for the sampling threads, and at twice the display rate a snapshot of its
//! tiling for the reconstructor's filters.
//!
//! One controller takes in the samples of a few sampling threads
//! ([`THREADS_PER_CONTROLLER`]); with more threads the image is cut into bands of
//! rows, one controller each, so that no one thread touches every sample. Each band
//! adapts its own tiles and tile count; samples go to the bands in proportion to their
//! tiles, since a sampling thread draws among all tiles alike. A sampler that reprojects
//! crosshairs keeps one band (a crosshair may move anywhere in the image).
//!
//! The reconstructor's filters need the sample rate; the image builder measures it.

use std::{
    collections::VecDeque,
    sync::{
        atomic::{AtomicU32, AtomicU64, Ordering},
        Arc, Mutex,
    },
    time::{Duration, Instant},
};

use crossbeam_channel::{bounded, Receiver, RecvTimeoutError, Sender};

use super::{
    config::RealtimeError,
    shared::{lock, Built, ImageBuilder, MethodInfo, Shared, Spawner, BATCH_S},
};
use crate::{
    clock::Clock,
    methods::adaptive::{
        deep_buffer::Crosshair,
        sampler::{choose_tile, completion_point, crosshair_points, crosshair_with, stratified_in},
        tiling::{Pending, Rect},
        Sampler, SamplerParams,
    },
    reconstruction::{device::ReconUsed, Reconstructor},
    sampling::Rng,
    tiles::TilingSnapshot,
    trace::{SceneState, StateCache, StreamSample},
};

/// The adaptive method's description.
pub(crate) const METHOD: MethodInfo = MethodInfo {
    name: "adaptive",
    about: "adaptive sampler + adaptive space-time reconstructor",
    // One sampling thread per core, as the other methods: sampling threads run below
    // the controllers and the image thread, so they take only the time those leave
    // (on 2 cores, 1.3 times the samples of one thread per core but one, at the same
    // image rate; docs/performance.md).
    default_sampling_threads: |cores| cores,
    extra_threads: controllers,
    // Its buffers (deep buffer, ring) include the display check.
    check_size: |c, w, h| {
        crate::methods::adaptive::check_budget(w, h, &c.adaptive.sampler, &c.adaptive.recon)
    },
    start,
};

/// Sampling threads one controller serves. The controller alone takes in 4.7–5 times
/// what one sampling thread traces on the cheapest scene (built-in `toycar`, the
/// `controller_*` figures of `frameless bench`), and more on costlier ones.
pub const THREADS_PER_CONTROLLER: usize = 4;

/// Fewest rows in a controller's band: a band holds tiles of at least the sampler's
/// smallest side in both directions, and room to adapt them.
const MIN_BAND_ROWS: u32 = 32;

/// Controller threads for `sampling_threads` sampling threads.
pub fn controllers(sampling_threads: usize) -> usize {
    sampling_threads.div_ceil(THREADS_PER_CONTROLLER).max(1)
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

/// How often the sampling threads' snapshot is republished.
const SNAPSHOT_EVERY: Duration = Duration::from_millis(1);

/// How often a controller passes the samples it took in on to the image thread.
const PASS_ON_EVERY: Duration = Duration::from_millis(2);

/// What one band's controller publishes.
struct BandPublished {
    /// The band's pixels.
    rect: Rect,
    /// The band's tile selection the sampling threads read.
    snapshot: Mutex<Arc<TileSnapshot>>,
    /// Bumped with every new snapshot of this band.
    seq: AtomicU64,
    /// A snapshot of the band's tiling (image coordinates) for the reconstructor's
    /// filters; `None` until the controller has a sampler.
    tiling: Mutex<Option<Arc<TilingSnapshot>>>,
}

/// What the controllers publish for the other threads of the method.
struct Published {
    bands: Vec<BandPublished>,
    /// Bumped with every new snapshot of any band, so that readers lock only when one
    /// changed.
    snapshot_seq: AtomicU64,
    /// The reconstructor's still-region history counts after its newest image, with
    /// a number that grows with every map, for
    /// [`crate::methods::adaptive::SamplerParams::discount_converged`] (the
    /// evaluation passes them after every refresh too); each controller reads its
    /// band's rows of a map it has not seen.
    history_counts: Mutex<(u64, Vec<f32>)>,
    /// Crosshair centres each pixel has had, for
    /// [`crate::methods::adaptive::SamplerParams::stratified_positions`]
    /// (empty when off); relaxed counters: two threads drawing the same index at once
    /// only repeat one position.
    pixel_draws: Vec<AtomicU32>,
    /// Visits whose reprojection step a controller ran, and skipped (behind).
    reprojected_visits: AtomicU64,
    skipped_reprojections: AtomicU64,
    /// History count maps the controllers passed to their samplers.
    history_maps: AtomicU64,
}

impl Published {
    /// Nothing published yet: one tile per band, nothing pending.
    fn new(s: &Shared) -> Self {
        let (w, h) = s.tracer.size();
        let c = &s.config;
        let bands = bands(w, h, controllers(c.sampling_threads), &c.adaptive.sampler);
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
            pixel_draws: if s.config.adaptive.sampler.stratified_positions {
                (0..w as usize * h as usize)
                    .map(|_| AtomicU32::new(0))
                    .collect()
            } else {
                Vec::new()
            },
        }
    }

    /// Publish band `b`'s tiles, held by `sampler`, for the sampling threads.
    fn snapshot(&self, b: usize, sampler: &Sampler) {
        let band = &self.bands[b];
        *lock(&band.snapshot) = Arc::new(TileSnapshot::of(sampler));
        band.seq.fetch_add(1, Ordering::Release);
        self.snapshot_seq.fetch_add(1, Ordering::Release);
    }

    /// Publish band `b`'s tiling for the reconstructor.
    fn tiling(&self, b: usize, sampler: &Sampler) {
        let mut t = sampler.tiling().snapshot();
        let (ox, oy) = sampler.origin();
        for tile in &mut t.tiles {
            tile.rect = tile.rect.offset(ox, oy);
        }
        *lock(&self.bands[b].tiling) = Some(Arc::new(t));
    }

    /// Every band's tiling together; `None` until each has one.
    fn whole_tiling(&self) -> Option<TilingSnapshot> {
        let mut tiles = Vec::new();
        for band in &self.bands {
            tiles.extend_from_slice(&lock(&band.tiling).as_ref()?.tiles);
        }
        Some(TilingSnapshot { tiles })
    }

    /// Tiles in all bands' newest snapshots.
    fn tiles(&self) -> usize {
        self.bands
            .iter()
            .map(|b| lock(&b.snapshot).rects.len())
            .sum()
    }
}

fn start(sp: &mut Spawner<'_>) -> Result<Box<dyn ImageBuilder>, RealtimeError> {
    let s = sp.shared().clone();
    let recon = reconstructor(&s)?;
    let published = Arc::new(Published::new(&s));
    // Channels are bounded so that a slow consumer slows its producers instead of
    // growing memory without limit. A controller's holds about 32 ms of batches from
    // every sampling thread; the image thread's about half a second of every
    // controller's messages (one per `PASS_ON_EVERY`), divided among the controllers.
    let (to_img, img_rx) = bounded(256);
    let (mut to_ctrl, mut ctrl_rx) = (Vec::new(), Vec::new());
    for _ in &published.bands {
        let (tx, rx) = bounded(32 * s.config.sampling_threads.max(1));
        to_ctrl.push(tx);
        ctrl_rx.push(rx);
    }
    let (s1, p1) = (s.clone(), published.clone());
    sp.sampling_threads(to_ctrl, move |i, tx| sample(&s1, &p1, i, tx))?;
    for (b, rx) in ctrl_rx.into_iter().enumerate() {
        let (s2, p2, tx) = (s.clone(), published.clone(), to_img.clone());
        sp.spawn("controller", move || control(&s2, &p2, b, rx, tx))?;
    }
    Ok(Box::new(Builder {
        s,
        published,
        rx: img_rx,
        recon,
        rate_window: VecDeque::new(),
        live_limit: None,
        figures: ImageFigures::default(),
    }))
}

/// The image builder's reconstructor, on the run's GPU when it has one: refused before
/// any thread starts where the adapter is too small for the display's buffers.
fn reconstructor(s: &Shared) -> Result<Box<Reconstructor>, RealtimeError> {
    let (w, h) = s.tracer.size();
    // The filters' rate is measured and set at every image ([`Builder::build`]).
    let mut r = Box::new(Reconstructor::new(w, h, 1.0, s.config.adaptive.recon));
    if let Some(gpu) = &s.config.adaptive.gpu {
        r.use_gpu(gpu.clone()).map_err(|e| RealtimeError::Gpu {
            method: METHOD.name,
            why: e.to_string(),
        })?;
    }
    Ok(r)
}

/// One band's tile selection as the sampling threads read it.
struct TileSnapshot {
    /// The tiles (image coordinates).
    rects: Vec<Rect>,
    /// Each tile's pending crosshair.
    pending: Vec<Option<Pending>>,
}

impl TileSnapshot {
    /// One tile, nothing pending.
    fn whole(rect: Rect) -> Self {
        Self {
            rects: vec![rect],
            pending: vec![None],
        }
    }

    fn of(sampler: &Sampler) -> Self {
        let t = sampler.tiling();
        let (ox, oy) = sampler.origin();
        let leaves = t.leaves();
        Self {
            rects: leaves
                .iter()
                .map(|&l| t.node(l).rect.offset(ox, oy))
                .collect(),
            pending: leaves
                .iter()
                .map(|&l| t.node(l).pending.map(|p| p.moved(ox as f32, oy as f32)))
                .collect(),
        }
    }
}

/// A sampling thread's copy of the bands' snapshots, with when it last initiated a
/// crosshair in each tile (the snapshot's own pending crosshairs until then), for
/// [`choose_tile`].
struct View {
    snaps: Vec<Arc<TileSnapshot>>,
    seqs: Vec<u64>,
    last: Vec<Vec<Option<f64>>>,
    /// Where each band's tiles start in the numbering of all tiles, and their count.
    starts: Vec<usize>,
    /// The `snapshot_seq` the copy is of.
    seq: u64,
}

impl View {
    fn new(published: &Published) -> Self {
        let k = published.bands.len();
        let mut v = Self {
            snaps: Vec::with_capacity(k),
            seqs: vec![u64::MAX; k],
            last: vec![Vec::new(); k],
            starts: vec![0; k + 1],
            seq: u64::MAX,
        };
        for band in &published.bands {
            v.snaps.push(lock(&band.snapshot).clone());
        }
        v.refresh(published);
        v
    }

    /// Take in the bands' snapshots that changed since the last call.
    fn refresh(&mut self, published: &Published) {
        let seq = published.snapshot_seq.load(Ordering::Acquire);
        if seq == self.seq {
            return;
        }
        self.seq = seq;
        for (b, band) in published.bands.iter().enumerate() {
            let bseq = band.seq.load(Ordering::Acquire);
            if bseq != self.seqs[b] {
                self.seqs[b] = bseq;
                self.snaps[b] = lock(&band.snapshot).clone();
                let last = &mut self.last[b];
                last.clear();
                last.extend(self.snaps[b].pending.iter().map(|p| p.map(|p| p.t)));
            }
            self.starts[b + 1] = self.starts[b] + self.snaps[b].rects.len();
        }
    }

    /// Tiles in all bands.
    fn len(&self) -> usize {
        self.starts[self.snaps.len()]
    }

    /// Band and index in it of tile `k` of all tiles.
    fn locate(&self, k: usize) -> (usize, usize) {
        let b = self.starts[1..].iter().position(|&e| k < e).unwrap_or(0);
        (b, k - self.starts[b])
    }
}

/// What a sampling thread did on one visit.
#[derive(Clone)]
enum Visit {
    /// It completed the crosshair `pending` initiated.
    Completed {
        crosshair: Crosshair,
        rays: u32,
        pending: Pending,
    },
    /// It initiated a crosshair.
    Initiated(Pending),
}

/// A batch for the controller.
#[derive(Clone, Default)]
struct Batch {
    visits: Vec<Visit>,
    stream: Vec<StreamSample>,
}

/// Visits in a batch before it is sent.
const BATCH_VISITS: usize = 256;

/// A sampling thread: visits at the current time, batched for the controllers of
/// the visited tiles' bands.
fn sample(s: &Shared, published: &Published, thread: u64, tx: Vec<Sender<Batch>>) {
    let tracer = &s.tracer;
    let mut rng = Rng::new(&[s.config.seed, 0x5a3b1e, thread]);
    let mut states = StateCache::new();
    let mut view = View::new(published);
    let mut out = Outbox::new(tx);
    while !s.stopped() {
        view.refresh(published);
        let now = s.clock.now();
        let state = states.at(tracer, now).0;
        let choices = s.config.adaptive.sampler.tile_choices;
        let k = choose_tile(view.len() as u32, choices, &mut rng, |k| {
            let (b, i) = view.locate(k);
            view.last[b][i]
        });
        let (b, i) = view.locate(k);
        let snap = &view.snaps[b];
        let rect = snap.rects[i];
        let batch = &mut out.batches[b];
        let t0 = Instant::now();
        if let Some(p) = snap.pending[i] {
            if !complete(s, &state, p, rect, now, batch) {
                continue; // another thread is at this crosshair: visit another tile
            }
        }
        if initiate(s, published, &state, rect, now, &mut rng, batch) {
            view.last[b][i] = Some(now);
        }
        out.busy += t0.elapsed().as_secs_f64();
        if !out.send_due(s, b) {
            return;
        }
    }
}

/// Complete the crosshair `p` initiated in tile `rect`, where its surface point is
/// at `now`, into `batch`; `false` if another thread holds one of its pixels.
fn complete(
    s: &Shared,
    state: &SceneState,
    p: Pending,
    rect: Rect,
    now: f64,
    batch: &mut Batch,
) -> bool {
    let tracer = &s.tracer;
    let (w, h) = tracer.size();
    let sampler = &s.config.adaptive.sampler;
    let at = p.follow(state, now);
    let (px, py) = completion_point(sampler, &state.camera, &at, rect, now, w, h);
    let arms = sampler.arms(rect);
    let cross = crosshair_points((px, py), arms).map(|(x, y)| (x.floor() as i64, y.floor() as i64));
    let Some(guard) = s.locks.try_lock_many(&cross) else {
        return false;
    };
    let mut rays = 0;
    let stream = &mut batch.stream;
    let c = crosshair_with(w, h, (px, py), arms, now, Some((p.lum, p.t)), |x, y| {
        rays += 1;
        let sample = tracer.sample(state, x, y);
        stream.push(StreamSample {
            x,
            y,
            t: now,
            sample,
        });
        sample
    });
    drop(guard);
    batch.visits.push(Visit::Completed {
        crosshair: c,
        rays,
        pending: p,
    });
    true
}

/// Initiate a crosshair at a random place in tile `rect` into `batch` (a few tries
/// for a pixel no other thread holds); whether it did.
fn initiate(
    s: &Shared,
    published: &Published,
    state: &SceneState,
    rect: Rect,
    now: f64,
    rng: &mut Rng,
    batch: &mut Batch,
) -> bool {
    let (w, _) = s.tracer.size();
    let draws = &published.pixel_draws;
    for _ in 0..4 {
        let (x, y) = if draws.is_empty() {
            rect.random_point(rng)
        } else {
            stratified_in(rect, rng, s.config.seed, w, |p| {
                draws[p].fetch_add(1, Ordering::Relaxed)
            })
        };
        let Some(guard) = s.locks.try_lock(x as u32, y as u32) else {
            continue;
        };
        let sample = s.tracer.sample(state, x, y);
        drop(guard);
        batch.stream.push(StreamSample {
            x,
            y,
            t: now,
            sample,
        });
        batch.visits.push(Visit::Initiated(Pending {
            x,
            y,
            t: now,
            lum: sample.luminance,
            hit_point: sample.hit_point,
            velocity: sample.velocity,
            anchor: sample.anchor,
        }));
        return true;
    }
    false
}

/// A sampling thread's batches, one per band, and its tracing time since they last went.
struct Outbox {
    tx: Vec<Sender<Batch>>,
    batches: Vec<Batch>,
    sent: Instant,
    busy: f64,
}

impl Outbox {
    fn new(tx: Vec<Sender<Batch>>) -> Self {
        Self {
            batches: vec![Batch::default(); tx.len()],
            tx,
            sent: Instant::now(),
            busy: 0.0,
        }
    }

    /// Send what is due after a visit to band `b`: its batch alone when full, every
    /// band's when [`BATCH_S`] has passed. `false` once the controllers are gone.
    fn send_due(&mut self, s: &Shared, b: usize) -> bool {
        let full = self.batches[b].visits.len() >= BATCH_VISITS;
        if !full && self.sent.elapsed().as_secs_f64() <= BATCH_S {
            return true;
        }
        s.busy_ns
            .fetch_add((self.busy * 1e9) as u64, Ordering::Relaxed);
        self.busy = 0.0;
        let due = if full {
            b..b + 1
        } else {
            self.sent = Instant::now();
            0..self.batches.len()
        };
        for d in due {
            if self.batches[d].visits.is_empty() {
                continue;
            }
            let n = self.batches[d].stream.len() as u64;
            s.samples.fetch_add(n, Ordering::Relaxed);
            s.rays.fetch_add(n, Ordering::Relaxed);
            if self.tx[d]
                .send(std::mem::take(&mut self.batches[d]))
                .is_err()
            {
                return false;
            }
        }
        true
    }
}

/// The controller's sampler for `band` of the image: fed by the sampling threads,
/// never run on its own. The tile count's floor and fixed size are the band's share
/// of the image's.
fn controller_sampler(s: &Shared, band: Rect) -> Option<Sampler> {
    // The sampler takes its clock's start as the origin of its decay weights; the rate
    // and the refresh only pace `run_until`, the sequential budget, which is never
    // called here (the sampling threads feed the sampler). Hence no rate.
    let clock = Clock {
        start: s.config.start,
        rate: f64::NAN,
        first_refresh: s.config.start,
        refresh_hz: s.config.refresh_hz,
    };
    let (w, h) = s.tracer.size();
    let share = band.area() as f64 / (w as f64 * h as f64);
    let mut params = s.config.adaptive.sampler;
    let part = |n: usize| ((n as f64 * share).ceil() as usize).max(1);
    params.min_tiles = part(params.min_tiles);
    params.fixed_tiles = part(params.fixed_tiles);
    // Validated by the pipeline before it started.
    Sampler::for_region(s.tracer.clone(), clock, params, s.config.seed, band).ok()
}

/// What the controller did with one batch.
struct Ingested {
    /// The batch's samples and the replacement crosshairs the sampler traced.
    stream: Vec<StreamSample>,
    /// Rays the controller traced itself (reprojection).
    own_rays: u64,
    /// Visits whose reprojection step ran, and those skipped.
    reprojected: u64,
    skipped: u64,
}

/// Take one sampling thread's batch into the sampler: completed crosshairs into the
/// deep buffer and the tiles' statistics (and their reprojection step when
/// `reproject`, at `now`), initiated ones as their tiles' pending crosshairs.
///
/// Positions arrive in image coordinates and move to the sampler's region's. An image
/// position minus the region's integer corner (no greater than it) is exact in `f32`,
/// and adding the corner back gives the position again, so a pending crosshair that
/// went out in a snapshot and came back with a completed one still matches exactly.
fn ingest(sampler: &mut Sampler, batch: Batch, reproject: bool, now: f64) -> Ingested {
    let (mut own_rays, mut reprojected, mut skipped) = (0, 0, 0);
    let (ox, oy) = sampler.origin();
    let (dx, dy) = (-(ox as f32), -(oy as f32));
    for v in batch.visits {
        match v {
            Visit::Completed {
                mut crosshair,
                rays,
                pending,
            } => {
                let pending = pending.moved(dx, dy);
                sampler.clear_pending(pending.x, pending.y, pending.t);
                crosshair.x += dx;
                crosshair.y += dy;
                let t = crosshair.t;
                let (px, py) = (crosshair.x as u32, crosshair.y as u32);
                sampler.ingest_crosshair(crosshair, rays as u64, t);
                if reproject {
                    let before = sampler.counters().rays;
                    sampler.reproject_visit(px, py, now);
                    own_rays += sampler.counters().rays - before;
                    reprojected += 1;
                } else {
                    skipped += 1;
                }
            }
            Visit::Initiated(p) => sampler.ingest_pending(p.moved(dx, dy)),
        }
    }
    let mut stream = batch.stream;
    stream.extend(sampler.drain_stream()); // replacement crosshairs
    Ingested {
        stream,
        own_rays,
        reprojected,
        skipped,
    }
}

/// Band `b`'s controller thread: its sampler's one owner.
fn control(
    s: &Shared,
    published: &Published,
    b: usize,
    rx: Receiver<Batch>,
    tx: Sender<Vec<StreamSample>>,
) {
    let Some(mut sampler) = controller_sampler(s, published.bands[b].rect) else {
        return;
    };
    let tiling_every = Duration::from_secs_f64(0.5 / s.config.refresh_hz);
    let (mut snap_at, mut tiling_at) = (Instant::now(), Instant::now() - tiling_every);
    let mut history_seen = 0;
    // Samples for the image thread, sent together every `PASS_ON_EVERY`: it drains
    // its channel once per image, and one message per batch (every sampling thread
    // sends each band a batch a millisecond) would fill it within an image's time on
    // many cores, stalling the controllers and, behind them, the sampling threads.
    let (mut out, mut out_at) = (Vec::new(), Instant::now());
    published.tiling(b, &sampler);
    while !s.stopped() {
        match rx.recv_timeout(Duration::from_millis(2)) {
            Ok(batch) => {
                // Behind: more batches are waiting than the one in hand.
                let reproject = rx.is_empty();
                let traced = batch.stream.len();
                let done = ingest(&mut sampler, batch, reproject, s.clock.now());
                let extra = (done.stream.len() - traced) as u64;
                s.samples.fetch_add(extra, Ordering::Relaxed);
                s.rays.fetch_add(done.own_rays, Ordering::Relaxed);
                published
                    .reprojected_visits
                    .fetch_add(done.reprojected, Ordering::Relaxed);
                published
                    .skipped_reprojections
                    .fetch_add(done.skipped, Ordering::Relaxed);
                if out.is_empty() {
                    out = done.stream;
                } else {
                    out.extend_from_slice(&done.stream);
                }
            }
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => return,
        }
        if !out.is_empty() && out_at.elapsed() >= PASS_ON_EVERY {
            if tx.send(std::mem::take(&mut out)).is_err() {
                return;
            }
            out_at = Instant::now();
        }
        if snap_at.elapsed() >= SNAPSHOT_EVERY {
            published.snapshot(b, &sampler);
            snap_at = Instant::now();
        }
        if tiling_at.elapsed() >= tiling_every {
            if take_history_counts(published, b, &mut sampler, &mut history_seen) {
                published.history_maps.fetch_add(1, Ordering::Relaxed);
            }
            published.tiling(b, &sampler);
            tiling_at = Instant::now();
        }
    }
}

/// Give band `b`'s sampler its rows of the newest history count map, if it is newer
/// than map `seen`; whether there was one.
fn take_history_counts(
    published: &Published,
    b: usize,
    sampler: &mut Sampler,
    seen: &mut u64,
) -> bool {
    let rows = {
        let maps = lock(&published.history_counts);
        if maps.0 == *seen || maps.1.is_empty() {
            return false;
        }
        *seen = maps.0;
        let r = published.bands[b].rect;
        let w = r.width() as usize;
        maps.1[r.y0 as usize * w..r.y1 as usize * w].to_vec()
    };
    sampler.set_history_counts(&rows);
    true
}

/// The image thread's side: the reconstructor, fed with what the controllers passed
/// on, filtered with the bands' newest tilings.
struct Builder {
    s: Arc<Shared>,
    published: Arc<Published>,
    rx: Receiver<Vec<StreamSample>>,
    recon: Box<Reconstructor>,
    /// Ray counts at recent images, to measure the rate the filters assume.
    rate_window: VecDeque<(f64, u64)>,
    /// Newest samples the reconstructor places ([`next_live_limit`]).
    live_limit: Option<usize>,
    figures: ImageFigures,
}

/// What the image builder reports ([`ImageBuilder::stats`]).
#[derive(Default)]
struct ImageFigures {
    /// The sample rate the filters assume after the newest image, and the ring's
    /// capacity.
    recon_rate: f64,
    ring_capacity: usize,
    /// Images built, those built under a live limit, and the samples they placed.
    images: u64,
    limited_images: u64,
    placed_sum: f64,
}

/// Push the newest samples of `batches` (oldest first) into `r`: as many as its ring
/// holds, and no more than the live limit (the newest samples an image places) when
/// there is one. The image thread takes samples in one at a time, and on many cores
/// more arrive between two images than it can take in and still build an image in
/// its budget; the older ones would not be placed. (They are lost to the still-region
/// history too, which gathers every sample taken in.)
fn push_newest(r: &mut Reconstructor, batches: &[Vec<StreamSample>], limit: Option<usize>) {
    let total: usize = batches.iter().map(Vec::len).sum();
    let most = limit.map_or(r.capacity(), |l| l.min(r.capacity()));
    let mut skip = total.saturating_sub(most);
    for batch in batches {
        let from = skip.min(batch.len());
        skip -= from;
        r.push_stream(&batch[from..]);
    }
}

/// The live limit for the next image, after one that placed `placed` samples under
/// `limit` and took `ms` to build, against a budget of `budget_ms` (0: no limit).
///
/// The build's cost is nearly linear in the samples placed, so the limit moves by the
/// square root of budget / time (half the step in the logarithm, against overshoot
/// from one slow image), at most halving or growing by a quarter per image; it is
/// lifted once it would reach `capacity`, and never goes below `floor`.
fn next_live_limit(
    limit: Option<usize>,
    placed: usize,
    ms: f64,
    budget_ms: f64,
    floor: usize,
    capacity: usize,
) -> Option<usize> {
    if budget_ms.is_nan() || budget_ms <= 0.0 {
        return None;
    }
    let step = (budget_ms / ms.max(1e-3)).sqrt().clamp(0.5, 1.25);
    let from = match limit {
        None if ms <= budget_ms => return None,
        None => placed,
        Some(k) => k,
    };
    let next = (from as f64 * step) as usize;
    (next < capacity).then_some(next.max(floor))
}

impl ImageBuilder for Builder {
    /// `tiles` now; `reprojected_share` of visits whose reprojection step ran (the
    /// controllers skip it while behind their input); `history_maps` the controllers
    /// received ([`crate::methods::adaptive::SamplerParams::discount_converged`]); the
    /// `recon_rate` the filters assume (measured, /s); the `ring_capacity`;
    /// `placed_mean` samples placed per image (the ring within the temporal cutoff, at
    /// most the live limit); `limited_share` of images built under a live limit
    /// ([`super::AdaptiveSettings::image_budget`]); `gpu_failure`, why the GPU reconstructor
    /// was given up, if it was (the images after it were built on the CPU).
    fn stats(&self) -> Vec<(&'static str, serde_json::Value)> {
        let p = &*self.published;
        let (rv, sv) = (
            p.reprojected_visits.load(Ordering::Relaxed),
            p.skipped_reprojections.load(Ordering::Relaxed),
        );
        let f = &self.figures;
        let per_image = |x: f64| x / f.images.max(1) as f64;
        let mut figures = vec![
            ("tiles", p.tiles().into()),
            (
                "reprojected_share",
                (rv as f64 / (rv + sv).max(1) as f64).into(),
            ),
            (
                "history_maps",
                p.history_maps.load(Ordering::Relaxed).into(),
            ),
            ("recon_rate", f.recon_rate.into()),
            ("ring_capacity", f.ring_capacity.into()),
            ("placed_mean", per_image(f.placed_sum).into()),
            ("limited_share", per_image(f.limited_images as f64).into()),
        ];
        if let Some(why) = self.recon.gpu_failure() {
            figures.push(("gpu_failure", why.into()));
        }
        figures
    }

    fn recon(&self) -> ReconUsed {
        self.recon.used()
    }

    fn build(&mut self, t: f64) -> Option<Built> {
        let t0 = Instant::now();
        let s = &*self.s;
        let (w, h) = s.tracer.size();
        let tiling = Arc::new(self.published.whole_tiling()?);
        let batches: Vec<Vec<StreamSample>> = self.rx.try_iter().collect();
        // The filters need the sample rate R, measured over the last second; a new
        // rate takes effect at the next refresh, keeping the ring, the splat scale and
        // the still-region history.
        let rays = s.rays.load(Ordering::Relaxed);
        let el = s.clock.elapsed();
        let window = &mut self.rate_window;
        window.push_back((el, rays));
        while window.len() > 2 && el - window[0].0 > 1.0 {
            window.pop_front();
        }
        let (e0, r0) = window[0];
        let rate = if el - e0 > 0.05 {
            (rays - r0) as f64 / (el - e0)
        } else {
            rays as f64 / el.max(1e-3)
        }
        .max(1.0);
        let r = &mut self.recon;
        r.set_rate(rate);
        push_newest(r, &batches, self.live_limit);
        let state = s.tracer.state_at(t);
        let camera = state.camera;
        r.set_motion(Some(state));
        r.set_live_limit(self.live_limit);
        let image = r.reconstruct(t, &camera, &tiling).clone();
        if s.config.adaptive.sampler.discount_converged {
            if let Some(counts) = r.history_counts() {
                // Each controller reads the newest; an older map none has read is
                // replaced (its buffer reused).
                let mut maps = lock(&self.published.history_counts);
                maps.0 += 1;
                maps.1.clear();
                maps.1.extend_from_slice(counts);
            }
        }
        let ages = r.pixel_ages();
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        let budget_ms = s.config.adaptive.image_budget * 1e3 / s.config.refresh_hz;
        // A floor of half a sample per pixel keeps an image where the build's
        // per-pixel work alone exceeds the budget.
        let floor = (w as usize * h as usize / 2).max(1);
        let limited = self.live_limit.is_some();
        self.live_limit = next_live_limit(
            self.live_limit,
            r.placed(),
            ms,
            budget_ms,
            floor,
            r.capacity(),
        );
        let fig = &mut self.figures;
        fig.recon_rate = rate;
        fig.ring_capacity = r.capacity();
        fig.images += 1;
        fig.limited_images += limited as u64;
        fig.placed_sum += r.placed() as f64;
        Some(Built {
            image,
            mean_age: r.mean_age(),
            tiling: Some(tiling),
            ages: super::shared::sampled_ages(ages.len(), |i| ages[i]),
            // Samples are reprojected to the camera of `t`.
            view_time: t,
        })
    }
}

/// A fresh controller sampler for every band.
fn band_samplers(s: &Shared, published: &Published) -> Result<Vec<Sampler>, RealtimeError> {
    let invalid = || RealtimeError::Config("the sampler's parameters are invalid".into());
    let bands = published.bands.iter();
    bands
        .map(|b| controller_sampler(s, b.rect).ok_or_else(invalid))
        .collect()
}

/// Run one sampling thread for `seconds` of wall time, its batches taken in by the
/// bands' `samplers` as they come (as live, with every reprojection step); returns the
/// samplers and each band's batches with the times they were taken in.
fn record(
    s: &Arc<Shared>,
    published: &Arc<Published>,
    mut samplers: Vec<Sampler>,
    seconds: f64,
) -> (Vec<Sampler>, Vec<Vec<(Batch, f64)>>) {
    let (tx, rx): (Vec<_>, Vec<_>) = published.bands.iter().map(|_| bounded(256)).unzip();
    let (s1, p1) = (s.clone(), published.clone());
    let thread = std::thread::spawn(move || sample(&s1, &p1, 0, tx));
    let mut recorded: Vec<Vec<(Batch, f64)>> = vec![Vec::new(); rx.len()];
    let t0 = Instant::now();
    while t0.elapsed().as_secs_f64() < seconds {
        let mut any = false;
        for (b, rx) in rx.iter().enumerate() {
            let Ok(batch) = rx.try_recv() else { continue };
            any = true;
            let now = s.clock.now();
            recorded[b].push((batch.clone(), now));
            ingest(&mut samplers[b], batch, true, now);
            published.snapshot(b, &samplers[b]);
        }
        if !any {
            std::thread::sleep(Duration::from_micros(100));
        }
    }
    s.stop.store(true, Ordering::Relaxed);
    drop(rx);
    let _ = thread.join();
    (samplers, recorded)
}

/// The controllers against one sampling thread ([`controller_bench`]).
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct ControllerBench {
    /// Controller threads (bands of the image).
    pub controllers: usize,
    /// Samples one sampling thread traced in the recording.
    pub samples: u64,
    /// Its samples per second of tracing (busy) time.
    pub tracing_samples_per_s: f64,
    /// Samples per second the controllers take in together, each fed its band's
    /// recorded batches one after another on its own thread with nothing else to do.
    pub controller_samples_per_s: f64,
}

impl ControllerBench {
    /// How many sampling threads the controllers could keep up with.
    pub fn margin(&self) -> f64 {
        self.controller_samples_per_s / self.tracing_samples_per_s
    }
}

/// Record what one sampling thread sends the controllers for `seconds` of wall time
/// (the controllers taking it in as it comes, as live), then feed each band's recorded
/// batches in order to a fresh controller, all bands at once on threads of their own,
/// and time only that. Real-time adaptive with `config` on `tracer`'s scene and image,
/// with the controllers `config.sampling_threads` would have. The replay does every
/// visit's reprojection step (live, a controller that falls behind skips it).
pub fn controller_bench(
    tracer: Arc<crate::trace::Tracer>,
    config: super::RtConfig,
    seconds: f64,
) -> Result<ControllerBench, RealtimeError> {
    let s = Arc::new(Shared::new(tracer, config));
    let published = Arc::new(Published::new(&s));
    let replay = band_samplers(&s, &published)?;
    let (_, recorded) = record(&s, &published, band_samplers(&s, &published)?, seconds);
    let samples = s.samples.load(Ordering::Relaxed);
    let busy = s.busy_ns.load(Ordering::Relaxed) as f64 * 1e-9;
    let recorded_samples: usize = recorded.iter().flatten().map(|(b, _)| b.stream.len()).sum();
    let t1 = Instant::now();
    std::thread::scope(|scope| {
        for (mut sampler, batches) in replay.into_iter().zip(recorded) {
            scope.spawn(move || {
                for (batch, now) in batches {
                    std::hint::black_box(ingest(&mut sampler, batch, true, now).stream.len());
                }
            });
        }
    });
    let controller_s = t1.elapsed().as_secs_f64();
    Ok(ControllerBench {
        controllers: published.bands.len(),
        samples,
        tracing_samples_per_s: samples as f64 / busy.max(1e-9),
        controller_samples_per_s: recorded_samples as f64 / controller_s.max(1e-9),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{
        realtime::{RtConfig, RtMethod},
        scene::builtin,
        trace::{TraceOptions, Tracer},
    };

    #[test]
    fn an_image_takes_in_only_the_samples_its_ring_holds() {
        // 8×4 pixels, ring of 2 samples per pixel: 64.
        let params = crate::reconstruction::ReconParams::realtime();
        let mut r = Reconstructor::new(8, 4, 1000.0, params);
        let cap = r.capacity();
        let stream = |from: usize, n: usize| -> Vec<StreamSample> {
            (from..from + n)
                .map(|i| StreamSample {
                    x: (i % 8) as f32 + 0.5,
                    y: (i / 8 % 4) as f32 + 0.5,
                    t: i as f64,
                    sample: Default::default(),
                })
                .collect()
        };
        // More than a ring's worth, over three batches: the newest `cap` are in it.
        let batches = vec![
            stream(0, cap),
            stream(cap, cap / 2),
            stream(cap + cap / 2, cap),
        ];
        push_newest(&mut r, &batches, None);
        let times: Vec<f64> = r.ring().iter().map(|s| s.t).collect();
        let total = 2 * cap + cap / 2;
        assert_eq!(
            times,
            ((total - cap)..total).map(|i| i as f64).collect::<Vec<_>>()
        );
        // Fewer than a ring's worth: all of them, after what was there.
        push_newest(&mut r, &[stream(total, 3)], None);
        assert_eq!(r.ring().back().unwrap().t, (total + 2) as f64);
        assert_eq!(r.ring().len(), cap);
        // Under a live limit, no more than it.
        let before = r.ring().back().unwrap().t;
        push_newest(&mut r, &[stream(total + 3, 10)], Some(4));
        let newest: Vec<f64> = r.ring().iter().map(|s| s.t).skip(cap - 5).collect();
        let from = (total + 3 + 6) as f64;
        assert_eq!(newest, [before, from, from + 1.0, from + 2.0, from + 3.0]);
    }

    #[test]
    fn bands_are_whole_rows_that_cover_the_image_once() {
        let ours = SamplerParams::ours();
        for (w, h, n, expect) in [
            (640, 480, 1, 1),
            (640, 480, 4, 4),
            (640, 481, 3, 3),
            (256, 256, 16, 8), // bands of at least 32 rows
            (64, 20, 4, 1),
        ] {
            let b = bands(w, h, n, &ours);
            assert_eq!(b.len(), expect, "{w}x{h} for {n}");
            assert_eq!((b[0].y0, b[b.len() - 1].y1), (0, h));
            for (i, r) in b.iter().enumerate() {
                assert_eq!((r.x0, r.x1), (0, w));
                assert!(r.height() >= MIN_BAND_ROWS.min(h));
                if i > 0 {
                    assert_eq!(r.y0, b[i - 1].y1);
                    assert!(r.height().abs_diff(b[i - 1].height()) <= 1);
                }
            }
        }
        // Crosshairs that reproject could leave any band.
        assert_eq!(bands(640, 480, 4, &SamplerParams::paper()).len(), 1);
        assert_eq!((controllers(1), controllers(4), controllers(15)), (1, 1, 4));
    }

    #[test]
    fn each_controller_adapts_its_own_band() {
        let (w, h) = (64, 96);
        let scene = Arc::new(builtin::toycar());
        let tracer = Arc::new(Tracer::new(scene, w, h, TraceOptions::default()));
        let mut config = RtConfig::new(RtMethod::Adaptive);
        config.sampling_threads = 2 * THREADS_PER_CONTROLLER; // two controllers
        config.start = 1.0;
        let s = Arc::new(Shared::new(tracer, config));
        let published = Arc::new(Published::new(&s));
        assert_eq!(published.bands.len(), 2);
        let samplers = band_samplers(&s, &published).unwrap();
        let (samplers, recorded) = record(&s, &published, samplers, 0.5);
        for (b, sampler) in samplers.iter().enumerate() {
            published.tiling(b, sampler);
            sampler.validate().unwrap();
            let band = published.bands[b].rect;
            assert!(!recorded[b].is_empty(), "band {b} got no batch");
            assert!(sampler.buffer().total() > 0, "band {b} holds no crosshair");
            assert!(sampler.tiling().len() > 1, "band {b} never split a tile");
            // Its crosshairs and pending samples were traced in its band.
            for (batch, _) in &recorded[b] {
                for v in &batch.visits {
                    let (x, y) = match v {
                        Visit::Completed { pending, .. } | Visit::Initiated(pending) => {
                            (pending.x, pending.y)
                        }
                    };
                    assert!(band.contains_point(x, y), "{x}, {y} outside band {b}");
                }
            }
        }
        // The reconstructor's tiling covers every pixel exactly once.
        let whole = published.whole_tiling().unwrap();
        let mut covered = vec![0u8; (w * h) as usize];
        for t in &whole.tiles {
            for y in t.rect.y0..t.rect.y1 {
                for x in t.rect.x0..t.rect.x1 {
                    covered[(y * w + x) as usize] += 1;
                }
            }
        }
        assert!(covered.iter().all(|&c| c == 1));
        assert_eq!(
            whole.tiles.len(),
            samplers.iter().map(|s| s.tiling().len()).sum::<usize>()
        );
    }

    #[test]
    fn the_live_limit_follows_the_build_time_budget() {
        let (floor, cap) = (1000, 100_000);
        // Within budget and unlimited: stays unlimited; no budget: never limited.
        assert_eq!(next_live_limit(None, 50_000, 10.0, 13.0, floor, cap), None);
        assert_eq!(
            next_live_limit(Some(5000), 5000, 90.0, 0.0, floor, cap),
            None
        );
        // Over budget: a limit below what was placed, by at most half.
        let k = next_live_limit(None, 80_000, 26.0, 13.0, floor, cap).unwrap();
        assert!((40_000..80_000).contains(&k), "{k}");
        assert_eq!(
            next_live_limit(None, 80_000, 1e6, 13.0, floor, cap),
            Some(40_000)
        );
        // Never below the floor.
        assert_eq!(
            next_live_limit(Some(1500), 1500, 1e3, 13.0, floor, cap),
            Some(floor)
        );
        // A cost linear in the samples settles near the budget: 2 ms fixed plus
        // 0.2 µs per sample, budget 13 ms (55K samples).
        let mut limit = None;
        let mut placed = cap;
        for _ in 0..60 {
            let ms = 2.0 + placed as f64 * 2e-4;
            limit = next_live_limit(limit, placed, ms, 13.0, floor, cap);
            placed = limit.unwrap_or(cap).min(cap);
        }
        let ms = 2.0 + placed as f64 * 2e-4;
        assert!((12.0..=13.5).contains(&ms), "{ms} ms with {placed}");
        // Time to spare grows it back until the limit is lifted.
        for _ in 0..60 {
            limit = next_live_limit(limit, placed, 5.0, 13.0, floor, cap);
            placed = limit.unwrap_or(cap).min(cap);
        }
        assert_eq!(limit, None);
    }
}
