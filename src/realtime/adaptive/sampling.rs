//! The adaptive method's sampling threads: each visits tiles of the published
//! snapshots at the current time, completing and initiating crosshairs, and sends what
//! it traced in batches to the controllers of the visited tiles' bands.

use std::{
    sync::{atomic::Ordering, Arc},
    time::Instant,
};

use crossbeam_channel::Sender;

use super::published::{Published, TileSnapshot};
use crate::{
    methods::adaptive::{
        deep_buffer::Crosshair,
        sampler::{
            choose_tile, complete_crosshair, completion_point, crosshair_points, stratified_arms,
            stratified_in, Completion,
        },
        tiling::{Pending, Rect},
    },
    realtime::shared::{lock, Shared, Turns, BATCH_S},
    sampling::Rng,
    trace::{
        batch::{self, GpuRays},
        Sample, SceneState, StateCache, StreamSample,
    },
};

/// A sampling thread's copy of the bands' snapshots, with when it last initiated a
/// crosshair in each tile (the snapshot's own pending crosshairs until then), for
/// [`choose_tile`].
pub(super) struct View {
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
pub(super) enum Visit {
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
pub(super) struct Batch {
    pub(super) visits: Vec<Visit>,
    pub(super) stream: Vec<StreamSample>,
}

impl Batch {
    /// A crosshair initiated at `(x, y)` at `now` by `sample`: the sample goes to the
    /// stream and the crosshair waits for its arms.
    fn initiated(&mut self, x: f32, y: f32, now: f64, sample: Sample) {
        self.stream.push(StreamSample {
            x,
            y,
            t: now,
            sample,
        });
        self.visits.push(Visit::Initiated(Pending {
            x,
            y,
            t: now,
            lum: sample.luminance,
            hit_point: sample.hit_point,
            velocity: sample.velocity,
            anchor: sample.anchor,
        }));
    }
}

/// Visits in a batch before it is sent.
pub(super) const BATCH_VISITS: usize = 256;

/// A sampling thread: visits at the current time, batched for the controllers of
/// the visited tiles' bands.
pub(super) fn sample(s: &Shared, published: &Published, thread: u64, tx: Vec<Sender<Batch>>) {
    if let Some(rays) = &s.config.rays {
        // A few threads feed the GPU, each a batch at a time.
        if thread < batch::GPU_FEEDERS {
            sample_on_gpu(s, published, rays, thread, tx);
        }
        return;
    }
    let tracer = &s.tracer;
    let mut rng = Rng::new(&[s.config.seed, 0x5a3b1e, thread]);
    let mut states = StateCache::new();
    let mut view = View::new(published);
    let mut out = Outbox::new(tx);
    let mut turns = Turns::new();
    while !s.stopped() {
        turns.between(s);
        view.refresh(published);
        let now = s.clock.now();
        let state = states.at_ahead(tracer, now, s.view_ahead.seconds()).0;
        let choices = published.settings.sampler.tile_choices;
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
            if !complete(s, published, &state, p, rect, now, batch) {
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
pub(super) fn complete(
    s: &Shared,
    published: &Published,
    state: &SceneState,
    p: Pending,
    rect: Rect,
    now: f64,
    batch: &mut Batch,
) -> bool {
    let sampler = &published.settings.sampler;
    let tracer = &s.tracer;
    let (w, h) = tracer.size();
    let at = p.follow(state, now);
    let done = completion_point(sampler, &state.camera, &at, rect, now, w, h);
    let arms = sampler.arms(rect);
    let points = crosshair_in(published, s.config.seed, (w, h), done.at, arms);
    let cross = points.map(|(x, y)| (x.floor() as i64, y.floor() as i64));
    let Some(guard) = s.locks.try_lock_many(&cross) else {
        return false;
    };
    let mut rays = 0;
    let stream = &mut batch.stream;
    let mut trace = |x: f32, y: f32| {
        rays += 1;
        let sample = tracer.sample(state, x, y);
        stream.push(StreamSample {
            x,
            y,
            t: now,
            sample,
        });
        sample
    };
    let old = Some((p.lum, p.t));
    let c = complete_crosshair(w, h, done, points, arms, now, old, &mut trace);
    drop(guard);
    batch.visits.push(Visit::Completed {
        crosshair: c,
        rays,
        pending: p,
    });
    true
}

/// The points of a crosshair at `at` with arms `arms`, each arm's end at its pixel's
/// next stratified point where positions are stratified.
fn crosshair_in(
    published: &Published,
    seed: u64,
    size: (u32, u32),
    at: (f32, f32),
    arms: (f32, f32),
) -> [(f32, f32); 5] {
    let cross = crosshair_points(at, arms);
    let draws = &published.pixel_draws;
    if draws.is_empty() {
        return cross;
    }
    stratified_arms(cross, size, seed, |p| {
        draws[p].fetch_add(1, Ordering::Relaxed)
    })
}

/// Initiate a crosshair at a random place in tile `rect` into `batch` (a few tries
/// for a pixel no other thread holds); whether it did.
pub(super) fn initiate(
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
        batch.initiated(x, y, now, sample);
        return true;
    }
    false
}

/// Visits of one GPU batch, at most (about six samples each).
const GPU_VISITS: usize = 4096;

/// A visit of a GPU batch, planned before its samples are traced: where they start in
/// the batch's points.
enum Planned {
    /// Complete `pending` as `done` says with a crosshair of `points` (its samples from
    /// `first` on, the probe's first where there is one).
    Complete {
        band: usize,
        pending: Pending,
        done: Completion,
        points: [(f32, f32); 5],
        arms: (f32, f32),
        first: usize,
    },
    /// Initiate a crosshair at `(x, y)`.
    Initiate {
        band: usize,
        x: f32,
        y: f32,
        first: usize,
    },
}

/// A sampling thread of a run with a GPU tracer (one of [`batch::GPU_FEEDERS`], as
/// the CPU's sampling threads run side by side): it plans the visits of up to
/// [`GPU_VISITS`] tiles at the current time as the CPU threads choose them (each tile
/// at most once a batch), traces all their samples in one batch, and sends the
/// visits as the CPU threads do. No visit of a batch depends on another's samples:
/// the crosshairs it completes were initiated by earlier batches.
fn sample_on_gpu(
    s: &Shared,
    published: &Published,
    rays: &GpuRays,
    thread: u64,
    tx: Vec<Sender<Batch>>,
) {
    let tracer = &s.tracer;
    let mut rng = Rng::new(&[s.config.seed, 0x5a3b1e, thread]);
    let mut states = StateCache::new();
    let mut view = View::new(published);
    let mut out = Outbox::new(tx);
    while !s.stopped() {
        view.refresh(published);
        let now = s.clock.now();
        let state = states.at_ahead(tracer, now, s.view_ahead.seconds()).0;
        let (plans, points) = plan_visits(s, published, &mut view, &state, now, &mut rng);
        let t0 = Instant::now();
        let got = batch::trace_points(tracer, Some(rays), &state, &points);
        out.busy += t0.elapsed().as_secs_f64();
        let mut bands: Vec<usize> = plans
            .iter()
            .map(|p| fill(s, p, &got, now, &mut out))
            .collect();
        bands.sort_unstable();
        bands.dedup();
        for b in bands {
            if !out.send_due(s, b) {
                return;
            }
        }
    }
}

/// The visits of one GPU batch and the points they trace.
fn plan_visits(
    s: &Shared,
    published: &Published,
    view: &mut View,
    state: &SceneState,
    now: f64,
    rng: &mut Rng,
) -> (Vec<Planned>, Vec<[f32; 2]>) {
    let sampler = &published.settings.sampler;
    let (w, h) = s.tracer.size();
    let on_screen = |x: f32, y: f32| x >= 0.0 && y >= 0.0 && x < w as f32 && y < h as f32;
    let draws = &published.pixel_draws;
    let (mut plans, mut points) = (Vec::new(), Vec::new());
    for _ in 0..GPU_VISITS.min(view.len()) {
        let k = choose_tile(view.len() as u32, sampler.tile_choices, rng, |k| {
            let (b, i) = view.locate(k);
            view.last[b][i]
        });
        let (b, i) = view.locate(k);
        if view.last[b][i] == Some(now) {
            continue; // visited in this batch: its pending crosshair is taken
        }
        let rect = view.snaps[b].rects[i];
        if let Some(p) = view.snaps[b].pending[i] {
            let at = p.follow(state, now);
            let done = completion_point(sampler, &state.camera, &at, rect, now, w, h);
            let arms = sampler.arms(rect);
            let first = points.len();
            if let Some((x, y)) = done.probe {
                points.push([x, y]);
            }
            let cross = crosshair_in(published, s.config.seed, (w, h), done.at, arms);
            for (j, (x, y)) in cross.into_iter().enumerate() {
                if j == 0 || on_screen(x, y) {
                    points.push([x, y]);
                }
            }
            plans.push(Planned::Complete {
                band: b,
                pending: p,
                done,
                points: cross,
                arms,
                first,
            });
        }
        let (x, y) = if draws.is_empty() {
            rect.random_point(rng)
        } else {
            stratified_in(rect, rng, s.config.seed, w, |p| {
                draws[p].fetch_add(1, Ordering::Relaxed)
            })
        };
        plans.push(Planned::Initiate {
            band: b,
            x,
            y,
            first: points.len(),
        });
        points.push([x, y]);
        view.last[b][i] = Some(now);
    }
    (plans, points)
}

/// Put the visit `plan` with its samples (from `got`) into its band's batch, as
/// [`complete`] and [`initiate`] do; its band.
fn fill(s: &Shared, plan: &Planned, got: &[Sample], now: f64, out: &mut Outbox) -> usize {
    let (w, h) = s.tracer.size();
    match *plan {
        Planned::Complete {
            band,
            pending,
            done,
            points,
            arms,
            first,
        } => {
            let batch = &mut out.batches[band];
            let mut next = first;
            let take = |x: f32, y: f32| {
                let sample = got.get(next).copied().unwrap_or_default();
                next += 1;
                batch.stream.push(StreamSample {
                    x,
                    y,
                    t: now,
                    sample,
                });
                sample
            };
            let old = Some((pending.lum, pending.t));
            let c = complete_crosshair(w, h, done, points, arms, now, old, take);
            batch.visits.push(Visit::Completed {
                crosshair: c,
                rays: (next - first) as u32,
                pending,
            });
            band
        }
        Planned::Initiate { band, x, y, first } => {
            let sample = got.get(first).copied().unwrap_or_default();
            out.batches[band].initiated(x, y, now, sample);
            band
        }
    }
}

/// A sampling thread's batches, one per band, and its tracing time since they last went.
pub(super) struct Outbox {
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

#[cfg(test)]
#[path = "sampling_tests.rs"]
mod tests;
