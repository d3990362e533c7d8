//! The adaptive method's controller threads: each owns the ordinary sampler of one
//! band of rows, takes in the sampling threads' batches through one [`ingest`], and
//! publishes its tiles and tiling.

use std::{
    sync::atomic::Ordering,
    time::{Duration, Instant},
};

use crossbeam_channel::{Receiver, RecvTimeoutError, Sender};

use super::{
    published::Published,
    sampling::{Batch, Visit},
};
use crate::{
    clock::Clock,
    methods::adaptive::{tiling::Rect, Sampler, SamplerParams},
    realtime::{
        config::RealtimeError,
        shared::{lock, Shared},
    },
    trace::StreamSample,
};

/// How often the sampling threads' snapshot is republished, at most.
pub(super) const SNAPSHOT_EVERY: Duration = Duration::from_millis(1);

/// A snapshot copies every tile of the band (14,400 at 1280×720), and each sampling
/// thread copies it again: republished every millisecond, that took about a fifth of
/// a controller's time at 1280×720 (docs/performance.md, session 27). The next
/// snapshot waits this many times as long as the last took, so publishing costs at
/// most about 1/ratio of the controller.
pub(super) const SNAPSHOT_COST_RATIO: u32 = 20;

/// When the next snapshot is due after one that took `cost`.
pub(super) fn snapshot_interval(cost: Duration) -> Duration {
    SNAPSHOT_EVERY.max(cost * SNAPSHOT_COST_RATIO)
}

/// Visits ahead of its turn that a visit's pixel queue and tile are asked for, and
/// that its deep-buffer slot and tile node are.
const PREFETCH_EARLY: usize = 16;
const PREFETCH_LATE: usize = 8;

/// How often a controller passes the samples it took in on to the image thread.
pub(super) const PASS_ON_EVERY: Duration = Duration::from_millis(2);

/// The controller's sampler for `band` of the image: fed by the sampling threads,
/// never run on its own. The tile count's floor and fixed size are the band's share
/// of the image's.
pub(super) fn controller_sampler(
    s: &Shared,
    sampler: &SamplerParams,
    band: Rect,
) -> Option<Sampler> {
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
    let mut params = *sampler;
    let part = |n: usize| ((n as f64 * share).ceil() as usize).max(1);
    params.min_tiles = part(params.min_tiles);
    params.fixed_tiles = part(params.fixed_tiles);
    // Validated by the pipeline before it started.
    Sampler::for_region(s.tracer.clone(), clock, params, s.config.seed, band).ok()
}

/// A fresh controller sampler for every band. Made before the pipeline's clock
/// starts: at 1920×1080 one takes about 0.4 s (on 2 cores), which held up the first
/// tiling, and with it the first image, by as much (docs/performance.md, session 28).
pub(super) fn band_samplers(
    s: &Shared,
    published: &Published,
) -> Result<Vec<Sampler>, RealtimeError> {
    let invalid = || RealtimeError::Config("the sampler's parameters are invalid".into());
    let bands = published.bands.iter();
    bands
        .map(|b| controller_sampler(s, &published.settings.sampler, b.rect).ok_or_else(invalid))
        .collect()
}

/// What the controller did with one batch.
pub(super) struct Ingested {
    /// The batch's samples and the replacement crosshairs the sampler traced.
    pub(super) stream: Vec<StreamSample>,
    /// Rays the controller traced itself (reprojection).
    pub(super) own_rays: u64,
    /// Visits whose reprojection step ran, and those skipped.
    pub(super) reprojected: u64,
    pub(super) skipped: u64,
}

/// Take one sampling thread's batch into the sampler: the view at `now` first (the
/// sampler sees the camera only here: [`Sampler::observe_view`]), then completed
/// crosshairs into the deep buffer and the tiles' statistics (and their reprojection
/// step when `reproject`, at `now`), initiated ones as their tiles' pending crosshairs.
///
/// Positions arrive in image coordinates and move to the sampler's region's. An image
/// position minus the region's integer corner (no greater than it) is exact in `f32`,
/// and adding the corner back gives the position again, so a pending crosshair that
/// went out in a snapshot and came back with a completed one still matches exactly.
pub(super) fn ingest(sampler: &mut Sampler, batch: Batch, reproject: bool, now: f64) -> Ingested {
    let (mut own_rays, mut reprojected, mut skipped) = (0, 0, 0);
    sampler.observe_view(now);
    let (ox, oy) = sampler.origin();
    let (dx, dy) = (-(ox as f32), -(oy as f32));
    // Where each visit lands (a completed crosshair's centre, an initiated sample),
    // asked of the cache in two steps ahead of its turn.
    let at = |v: &Visit| match v {
        Visit::Completed { crosshair, .. } => (crosshair.x + dx, crosshair.y + dy),
        Visit::Initiated(p) => (p.x + dx, p.y + dy),
    };
    for v in batch.visits.iter().take(PREFETCH_EARLY) {
        let (x, y) = at(v);
        sampler.prefetch_visit(x, y, false);
    }
    for (j, v) in batch.visits.iter().enumerate() {
        if let Some(v) = batch.visits.get(j + PREFETCH_EARLY) {
            let (x, y) = at(v);
            sampler.prefetch_visit(x, y, false);
        }
        if let Some(v) = batch.visits.get(j + PREFETCH_LATE) {
            let (x, y) = at(v);
            sampler.prefetch_visit(x, y, true);
        }
        match *v {
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

/// Band `b`'s controller thread: `sampler`'s one owner.
pub(super) fn control(
    s: &Shared,
    published: &Published,
    (b, mut sampler): (usize, Sampler),
    rx: Receiver<Batch>,
    tx: Sender<Vec<StreamSample>>,
) {
    let tiling_every = Duration::from_secs_f64(0.5 / s.config.refresh_hz);
    let (mut snap_at, mut tiling_at) = (Instant::now(), Instant::now() - tiling_every);
    let mut snap_every = SNAPSHOT_EVERY;
    let mut history_seen = 0;
    // The band's rows of the newest history count map, copied out of the lock into
    // a buffer kept across maps: a fresh one each time was several megabytes mapped,
    // faulted in and unmapped again at 1280×720 (docs/performance.md, session 34).
    let mut history_rows = Vec::new();
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
        if snap_at.elapsed() >= snap_every {
            let t0 = Instant::now();
            published.snapshot(b, &sampler);
            snap_at = Instant::now();
            snap_every = snapshot_interval(snap_at - t0);
        }
        if tiling_at.elapsed() >= tiling_every {
            let seen = &mut history_seen;
            if take_history_counts(published, b, &mut sampler, seen, &mut history_rows) {
                published.history_maps.fetch_add(1, Ordering::Relaxed);
            }
            published.tiling(b, &sampler);
            tiling_at = Instant::now();
        }
    }
}

/// Give band `b`'s sampler its rows of the newest history count map, if it is newer
/// than map `seen`, copied through `rows`; whether there was one.
pub(super) fn take_history_counts(
    published: &Published,
    b: usize,
    sampler: &mut Sampler,
    seen: &mut u64,
    rows: &mut Vec<f32>,
) -> bool {
    {
        let maps = lock(&published.history_counts);
        if maps.0 == *seen || maps.1.is_empty() {
            return false;
        }
        *seen = maps.0;
        let r = published.bands[b].rect;
        let w = r.width() as usize;
        rows.clear();
        rows.extend_from_slice(&maps.1[r.y0 as usize * w..r.y1 as usize * w]);
    }
    sampler.set_history_counts(rows);
    true
}
