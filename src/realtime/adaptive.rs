//! The real-time adaptive method: adaptive sampling threads, one controller thread that
//! owns the tiling and the deep buffer (afr-optix keeps "the hierarchy on one
//! processor"), and the adaptive space-time reconstructor on the image thread.
//!
//! ```text
//!  sampling ×N ──crosshairs, initiating samples──► controller (Sampler: deep buffer,
//!      ▲                                            tiling, gain control, reprojection)
//!      └──── tile snapshot (Arc, ~1 ms) ◄───────────┘   │ samples + tiling copy (Arc)
//!                                                       ▼
//!                                     image thread: Reconstructor at the display rate
//! ```
//!
//! A sampling thread visits a tile of the published snapshot chosen uniformly at
//! random; it completes the crosshair the tile's pending sample initiated, where its
//! surface point is now ([`completion_point`], as the sequential sampler; taking its
//! five pixels) and initiates the next one at a random location in the tile (taking that
//! pixel). A taken pixel means another thread is there: it picks another tile or
//! location.
//!
//! The controller holds an ordinary [`Sampler`] and feeds it what the sampling threads
//! traced: completed crosshairs (inserted, with tile statistics updated and the tiling
//! adjusted after every chunk, exactly as in a sequential visit) and initiating samples
//! (which become their tile's pending crosshair). The reprojection step of each visit
//! runs there too, occlusion rays included — but only while the controller keeps up
//! with its input: when batches queue up it skips reprojection for that batch, so that
//! the tiling never lags behind the samples (the share that ran is reported). About
//! every millisecond it publishes the tile selection (rectangles and pending crosshairs)
//! for the sampling threads, and at twice the display rate a copy of the tiling for the
//! reconstructor's filters.
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
        tiling::{Pending, Rect, Tiling},
        Sampler,
    },
    reconstruction::Reconstructor,
    sampling::Rng,
    trace::{StateCache, StreamSample},
};

/// The adaptive method's description.
pub(crate) const METHOD: MethodInfo = MethodInfo {
    name: "adaptive",
    about: "adaptive sampler + adaptive space-time reconstructor",
    // One sampling thread per core but one: the controller and the reconstruction
    // need the rest (measured in `docs/results/realtime/`).
    default_sampling_threads: |cores| cores.saturating_sub(1).max(1),
    extra_threads: 1, // the controller
    start,
};

/// How often the sampling threads' snapshot is republished.
const SNAPSHOT_EVERY: Duration = Duration::from_millis(1);

/// What the controller publishes for the other threads of the method.
struct Published {
    /// The tile selection the sampling threads read.
    snapshot: Mutex<Arc<TileSnapshot>>,
    /// Bumped with every new snapshot, so that readers lock only when it changed.
    snapshot_seq: AtomicU64,
    /// A copy of the tiling for the reconstructor's filters; `None` until the
    /// controller has a sampler.
    tiling: Mutex<Option<Arc<Tiling>>>,
    /// The reconstructor's still-region history counts after its newest image, for
    /// [`crate::methods::adaptive::SamplerParams::discount_converged`] (the
    /// evaluation passes them after every refresh too); taken by the controller.
    history_counts: Mutex<Option<Vec<f32>>>,
    /// Crosshair centres each pixel has had, for
    /// [`crate::methods::adaptive::SamplerParams::stratified_positions`]
    /// (empty when off); relaxed counters: two threads drawing the same index at once
    /// only repeat one position.
    pixel_draws: Vec<AtomicU32>,
}

impl Published {
    /// Nothing published yet: one tile, nothing pending.
    fn new(s: &Shared) -> Self {
        let (w, h) = s.tracer.size();
        Self {
            snapshot: Mutex::new(Arc::new(TileSnapshot::whole(w, h))),
            snapshot_seq: AtomicU64::new(0),
            tiling: Mutex::new(None),
            history_counts: Mutex::new(None),
            pixel_draws: if s.config.sampler.stratified_positions {
                (0..w as usize * h as usize)
                    .map(|_| AtomicU32::new(0))
                    .collect()
            } else {
                Vec::new()
            },
        }
    }

    /// Publish `sampler`'s tiles for the sampling threads.
    fn snapshot(&self, sampler: &Sampler) {
        *lock(&self.snapshot) = Arc::new(TileSnapshot::of(sampler));
        self.snapshot_seq.fetch_add(1, Ordering::Release);
    }
}

fn start(sp: &mut Spawner<'_>) -> Result<Box<dyn ImageBuilder>, RealtimeError> {
    let s = sp.shared().clone();
    let published = Arc::new(Published::new(&s));
    // Channels are bounded so that a slow consumer slows its producers instead of
    // growing memory without limit; the capacities hold ~100 ms of batches.
    let (to_ctrl, ctrl_rx) = bounded(256);
    let (to_img, img_rx) = bounded(256);
    let (s1, p1) = (s.clone(), published.clone());
    sp.sampling_threads(to_ctrl, move |i, tx| sample(&s1, &p1, i, tx))?;
    let (s2, p2) = (s.clone(), published.clone());
    sp.spawn("controller", move || control(&s2, &p2, ctrl_rx, to_img))?;
    Ok(Box::new(Builder {
        s,
        published,
        rx: img_rx,
        recon: None,
        rate_window: VecDeque::new(),
        live_limit: None,
    }))
}

/// The tile selection the sampling threads read.
struct TileSnapshot {
    /// The tiles.
    rects: Vec<Rect>,
    /// Each tile's pending crosshair.
    pending: Vec<Option<Pending>>,
}

impl TileSnapshot {
    /// One tile, nothing pending.
    fn whole(w: u32, h: u32) -> Self {
        Self {
            rects: vec![Rect {
                x0: 0,
                y0: 0,
                x1: w,
                y1: h,
            }],
            pending: vec![None],
        }
    }

    fn of(sampler: &Sampler) -> Self {
        let t = sampler.tiling();
        let leaves = t.leaves();
        Self {
            rects: leaves.iter().map(|&l| t.node(l).rect).collect(),
            pending: leaves.iter().map(|&l| t.node(l).pending).collect(),
        }
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

/// A sampling thread: visits at the current time, batched for the controller.
fn sample(s: &Shared, published: &Published, thread: u64, tx: Sender<Batch>) {
    let tracer = &s.tracer;
    let (w, h) = tracer.size();
    let mut rng = Rng::new(&[s.config.seed, 0x5a3b1e, thread]);
    let mut states = StateCache::new();
    let mut snap_seq = u64::MAX;
    let mut snap = lock(&published.snapshot).clone();
    // When this thread last initiated a crosshair in each tile of the snapshot (the
    // snapshot's own pending crosshairs until then), for `choose_tile`.
    let mut last: Vec<Option<f64>> = snap.pending.iter().map(|p| p.map(|p| p.t)).collect();
    let mut batch = Batch::default();
    let mut sent = Instant::now();
    let mut busy = 0.0f64;
    while !s.stopped() {
        let seq = published.snapshot_seq.load(Ordering::Acquire);
        if seq != snap_seq {
            snap = lock(&published.snapshot).clone();
            snap_seq = seq;
            last.clear();
            last.extend(snap.pending.iter().map(|p| p.map(|p| p.t)));
        }
        let now = s.clock.now();
        let state = states.at(tracer, now).0;
        let choices = s.config.sampler.tile_choices;
        let k = choose_tile(snap.rects.len() as u32, choices, &mut rng, |k| last[k]);
        let rect = snap.rects[k];
        let t0 = Instant::now();
        if let Some(p) = snap.pending[k] {
            let (px, py) = completion_point(
                &s.config.sampler,
                &state.camera,
                &p.follow(&state, now),
                rect,
                now,
                w,
                h,
            );
            let arms = s.config.sampler.arms(rect);
            let cross =
                crosshair_points((px, py), arms).map(|(x, y)| (x.floor() as i64, y.floor() as i64));
            let Some(guard) = s.locks.try_lock_many(&cross) else {
                continue; // another thread is at this crosshair: visit another tile
            };
            let mut rays = 0;
            let stream = &mut batch.stream;
            let c = crosshair_with(w, h, (px, py), arms, now, Some((p.lum, p.t)), |x, y| {
                rays += 1;
                let sample = tracer.sample(&state, x, y);
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
        }
        for _ in 0..4 {
            let draws = &published.pixel_draws;
            let (x, y) = if draws.is_empty() {
                rect.random_point(&mut rng)
            } else {
                stratified_in(rect, &mut rng, s.config.seed, w, |p| {
                    draws[p].fetch_add(1, Ordering::Relaxed)
                })
            };
            let Some(guard) = s.locks.try_lock(x as u32, y as u32) else {
                continue;
            };
            let sample = tracer.sample(&state, x, y);
            drop(guard);
            last[k] = Some(now);
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
            break;
        }
        busy += t0.elapsed().as_secs_f64();
        if batch.visits.len() >= 256 || sent.elapsed().as_secs_f64() > BATCH_S {
            let n = batch.stream.len() as u64;
            s.samples.fetch_add(n, Ordering::Relaxed);
            s.rays.fetch_add(n, Ordering::Relaxed);
            s.busy_ns.fetch_add((busy * 1e9) as u64, Ordering::Relaxed);
            busy = 0.0;
            if tx.send(std::mem::take(&mut batch)).is_err() {
                return;
            }
            sent = Instant::now();
        }
    }
}

/// The controller's sampler: fed by the sampling threads, never run on its own.
fn controller_sampler(s: &Shared) -> Option<Sampler> {
    // The sampler takes its clock's start as the origin of its decay weights; the rate
    // and the refresh only pace `run_until`, the sequential budget, which is never
    // called here (the sampling threads feed the sampler). Hence no rate.
    let clock = Clock {
        start: s.config.start,
        rate: f64::NAN,
        first_refresh: s.config.start,
        refresh_hz: s.config.refresh_hz,
    };
    // Validated by the pipeline before it started.
    Sampler::new(s.tracer.clone(), clock, s.config.sampler, s.config.seed).ok()
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
fn ingest(sampler: &mut Sampler, batch: Batch, reproject: bool, now: f64) -> Ingested {
    let (mut own_rays, mut reprojected, mut skipped) = (0, 0, 0);
    for v in batch.visits {
        match v {
            Visit::Completed {
                crosshair,
                rays,
                pending,
            } => {
                sampler.clear_pending(pending.x, pending.y, pending.t);
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
            Visit::Initiated(p) => sampler.ingest_pending(p),
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

/// The controller thread: the sampler's one owner.
fn control(s: &Shared, published: &Published, rx: Receiver<Batch>, tx: Sender<Vec<StreamSample>>) {
    let Some(mut sampler) = controller_sampler(s) else {
        return;
    };
    let tiling_every = Duration::from_secs_f64(0.5 / s.config.refresh_hz);
    let (mut snap_at, mut tiling_at) = (Instant::now(), Instant::now() - tiling_every);
    publish_tiling(published, &sampler);
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
                s.reprojected_visits
                    .fetch_add(done.reprojected, Ordering::Relaxed);
                s.skipped_reprojections
                    .fetch_add(done.skipped, Ordering::Relaxed);
                if tx.send(done.stream).is_err() {
                    return;
                }
            }
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => return,
        }
        if snap_at.elapsed() >= SNAPSHOT_EVERY {
            published.snapshot(&sampler);
            s.tiles
                .store(sampler.tiling().len() as u64, Ordering::Relaxed);
            snap_at = Instant::now();
        }
        if tiling_at.elapsed() >= tiling_every {
            if let Some(counts) = lock(&published.history_counts).take() {
                sampler.set_history_counts(&counts);
                s.history_maps.fetch_add(1, Ordering::Relaxed);
            }
            publish_tiling(published, &sampler);
            tiling_at = Instant::now();
        }
    }
}

fn publish_tiling(published: &Published, sampler: &Sampler) {
    *lock(&published.tiling) = Some(Arc::new(sampler.tiling().clone()));
}

/// The image thread's side: the reconstructor, fed with what the controller passed
/// on, filtered with the newest tiling copy.
struct Builder {
    s: Arc<Shared>,
    published: Arc<Published>,
    rx: Receiver<Vec<StreamSample>>,
    recon: Option<Box<Reconstructor>>,
    /// Ray counts at recent images, to measure the rate the filters assume.
    rate_window: VecDeque<(f64, u64)>,
    /// Newest samples the reconstructor places ([`next_live_limit`]).
    live_limit: Option<usize>,
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
    fn build(&mut self, t: f64) -> Option<Built> {
        let t0 = Instant::now();
        let s = &*self.s;
        let (w, h) = s.tracer.size();
        let tiling = lock(&self.published.tiling).clone()?;
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
        match &mut self.recon {
            Some(r) => r.set_rate(rate),
            None => self.recon = Some(Box::new(Reconstructor::new(w, h, rate, s.config.recon))),
        }
        let r = self.recon.as_mut()?;
        for batch in &batches {
            r.push_stream(batch);
        }
        let state = s.tracer.state_at(t);
        let camera = state.camera;
        r.set_motion(Some(state));
        r.set_live_limit(self.live_limit);
        let image = r.reconstruct(t, &camera, &tiling.snapshot()).clone();
        if s.config.sampler.discount_converged {
            if let Some(counts) = r.history_counts() {
                // The controller takes the newest; an untaken older map is replaced
                // (its buffer reused).
                let mut slot = lock(&self.published.history_counts);
                let buf = slot.get_or_insert_with(Vec::new);
                buf.clear();
                buf.extend_from_slice(counts);
            }
        }
        let ages = r.pixel_ages();
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        let budget_ms = s.config.image_budget * 1e3 / s.config.refresh_hz;
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
        {
            let mut st = lock(&s.image_stats);
            st.recon_rate = rate;
            st.ring_capacity = r.capacity();
            st.limited_images += limited as u64;
            st.placed_sum += r.placed() as f64;
        }
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

/// The controller against one sampling thread ([`controller_bench`]).
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct ControllerBench {
    /// Samples one sampling thread traced in the recording.
    pub samples: u64,
    /// Its samples per second of tracing (busy) time.
    pub tracing_samples_per_s: f64,
    /// Samples per second the controller takes in, fed the recorded batches one after
    /// another with nothing else to do.
    pub controller_samples_per_s: f64,
}

impl ControllerBench {
    /// How many sampling threads the controller could keep up with.
    pub fn margin(&self) -> f64 {
        self.controller_samples_per_s / self.tracing_samples_per_s
    }
}

/// Record what one sampling thread sends the controller for `seconds` of wall time
/// (the controller taking it in as it comes, as live), then feed the recorded batches
/// in order to a fresh controller and time only that. Real-time adaptive with
/// `config` on `tracer`'s scene and image. The replay does every visit's
/// reprojection step (live, a controller that falls behind skips it).
pub fn controller_bench(
    tracer: Arc<crate::trace::Tracer>,
    config: super::RtConfig,
    seconds: f64,
) -> Result<ControllerBench, RealtimeError> {
    let s = Arc::new(Shared::new(tracer, config));
    let published = Arc::new(Published::new(&s));
    let invalid = || RealtimeError::Config("the sampler's parameters are invalid".into());
    let mut sampler = controller_sampler(&s).ok_or_else(invalid)?;
    let mut replay = controller_sampler(&s).ok_or_else(invalid)?;
    let (tx, rx) = bounded(256);
    let (s1, p1) = (s.clone(), published.clone());
    let thread = std::thread::spawn(move || sample(&s1, &p1, 0, tx));
    let mut recorded = Vec::new();
    let t0 = Instant::now();
    while t0.elapsed().as_secs_f64() < seconds {
        let Ok(batch) = rx.recv_timeout(Duration::from_millis(50)) else {
            continue;
        };
        let now = s.clock.now();
        recorded.push((batch.clone(), now));
        ingest(&mut sampler, batch, true, now);
        published.snapshot(&sampler);
    }
    s.stop.store(true, Ordering::Relaxed);
    drop(rx);
    let _ = thread.join();
    let samples = s.samples.load(Ordering::Relaxed);
    let busy = s.busy_ns.load(Ordering::Relaxed) as f64 * 1e-9;
    let recorded_samples: usize = recorded.iter().map(|(b, _)| b.stream.len()).sum();
    let t1 = Instant::now();
    for (batch, now) in recorded {
        std::hint::black_box(ingest(&mut replay, batch, true, now).stream.len());
    }
    let controller_s = t1.elapsed().as_secs_f64();
    Ok(ControllerBench {
        samples,
        tracing_samples_per_s: samples as f64 / busy.max(1e-9),
        controller_samples_per_s: recorded_samples as f64 / controller_s.max(1e-9),
    })
}

#[cfg(test)]
mod tests {
    use super::next_live_limit;

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
