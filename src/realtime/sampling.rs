//! The sampling threads' loops, one per method.
//!
//! Every thread samples at the current time: it reads the wall clock before each visit
//! (pixel, row) and traces with the scene state of that instant (quantized to 1 ms and
//! shared through the tracer's cache). Results go out in batches of about a
//! millisecond, so that channel traffic stays small next to tracing.

use std::{
    sync::{atomic::Ordering, Arc},
    time::Instant,
};

use crossbeam_channel::Sender;
use glam::Vec3;

use super::{controller::Visit, pipeline::Shared};
use crate::{
    methods::adaptive::{sampler::crosshair_with, tiling::Pending},
    sampling::Rng,
    trace::{SceneState, StateCache, StreamSample, Tracer},
};

/// Longest a batch is held before it is sent, seconds.
const BATCH_S: f64 = 1e-3;

/// A batch for the controller.
#[derive(Default)]
pub(crate) struct AdaptiveBatch {
    pub visits: Vec<Visit>,
    pub stream: Vec<StreamSample>,
}

/// Adaptive sampling: visit a tile of the published snapshot chosen uniformly at
/// random; complete the crosshair it initiated (taking its five pixels), and initiate
/// the next one at a random location in the tile (taking that pixel). A taken pixel
/// means another thread is there: pick another tile / location.
pub(crate) fn adaptive(s: &Shared, thread: u64, tx: Sender<AdaptiveBatch>) {
    let tracer = &s.tracer;
    let (w, h) = tracer.size();
    let mut rng = Rng::new(&[s.config.seed, 0x5a3b1e, thread]);
    let mut states = StateCache::new();
    let mut snap_seq = u64::MAX;
    let mut snap = super::pipeline::lock(&s.snapshot).clone();
    let mut batch = AdaptiveBatch::default();
    let mut sent = Instant::now();
    let mut busy = 0.0f64;
    while !s.stopped() {
        let seq = s.snapshot_seq.load(Ordering::Acquire);
        if seq != snap_seq {
            snap = super::pipeline::lock(&s.snapshot).clone();
            snap_seq = seq;
        }
        let now = s.clock.now();
        let state = states.at(tracer, now).0;
        let k = rng.below(snap.rects.len() as u32) as usize;
        let rect = snap.rects[k];
        let t0 = Instant::now();
        if let Some(p) = snap.pending[k] {
            let (cx, cy) = (p.x.floor() as i64, p.y.floor() as i64);
            let cross = [
                (cx, cy),
                (cx + 1, cy),
                (cx - 1, cy),
                (cx, cy + 1),
                (cx, cy - 1),
            ];
            let Some(guard) = s.locks.try_lock_many(&cross) else {
                continue; // another thread is at this crosshair: visit another tile
            };
            let mut rays = 0;
            let stream = &mut batch.stream;
            let c = crosshair_with(w, h, p.x, p.y, now, Some((p.lum, p.t)), |x, y| {
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
            let (x, y) = rect.random_point(&mut rng);
            let Some(guard) = s.locks.try_lock(x as u32, y as u32) else {
                continue;
            };
            let sample = tracer.sample(&state, x, y);
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
    let _ = w.max(h);
}

/// Traditional frameless: a random pixel (taken, traced through its center at the
/// current time, released), over and over; the image thread shows the newest sample of
/// every pixel.
pub(crate) fn frameless(s: &Shared, thread: u64, tx: Sender<Vec<(u32, Vec3, f64)>>) {
    let tracer = &s.tracer;
    let (w, h) = tracer.size();
    let n = w * h;
    let mut rng = Rng::new(&[s.config.seed, 0xf4a3e1, thread]);
    let mut states = StateCache::new();
    let mut batch = Vec::with_capacity(1024);
    let mut sent = Instant::now();
    let mut busy = 0.0f64;
    while !s.stopped() {
        let now = s.clock.now();
        let state = states.at(tracer, now).0;
        let t0 = Instant::now();
        for _ in 0..16 {
            let p = rng.below(n);
            let Some(guard) = s.locks.try_lock(p % w, p / w) else {
                continue; // taken: another pixel
            };
            let c = tracer
                .sample(&state, (p % w) as f32 + 0.5, (p / w) as f32 + 0.5)
                .color;
            drop(guard);
            batch.push((p, c, now));
        }
        busy += t0.elapsed().as_secs_f64();
        if batch.len() >= 1024 || sent.elapsed().as_secs_f64() > BATCH_S {
            let k = batch.len() as u64;
            s.samples.fetch_add(k, Ordering::Relaxed);
            s.rays.fetch_add(k, Ordering::Relaxed);
            s.busy_ns.fetch_add((busy * 1e9) as u64, Ordering::Relaxed);
            busy = 0.0;
            if tx
                .send(std::mem::replace(&mut batch, Vec::with_capacity(1024)))
                .is_err()
            {
                return;
            }
            sent = Instant::now();
        }
    }
}

/// One framed frame being traced: the scene state at its start, rows handed out in
/// order. Each row goes to exactly one thread (the atomic counter), so pixels are
/// never shared.
pub(crate) struct FrameJob {
    pub id: u64,
    pub time: f64,
    pub state: Arc<SceneState>,
    pub next_row: std::sync::atomic::AtomicU32,
}

impl FrameJob {
    pub fn new(id: u64, time: f64, tracer: &Tracer) -> Self {
        Self {
            id,
            time,
            state: tracer.state_at(time),
            next_row: std::sync::atomic::AtomicU32::new(0),
        }
    }
}

/// A traced row of a framed frame.
pub(crate) struct FramedRow {
    pub frame: u64,
    pub time: f64,
    pub y: u32,
    pub pixels: Vec<Vec3>,
}

/// Framed, double-buffered: threads take rows of the current frame (traced at the
/// frame's start time); the thread that finds the rows exhausted starts the next frame
/// at the current time. The image thread shows the newest complete frame.
pub(crate) fn framed(s: &Shared, _thread: u64, tx: Sender<FramedRow>) {
    let tracer = &s.tracer;
    let (w, h) = tracer.size();
    while !s.stopped() {
        let job = super::pipeline::lock(&s.framed_job).clone();
        let y = job.next_row.fetch_add(1, Ordering::Relaxed);
        if y >= h {
            let mut cur = super::pipeline::lock(&s.framed_job);
            if cur.id == job.id {
                *cur = Arc::new(FrameJob::new(job.id + 1, s.clock.now(), tracer));
            }
            continue;
        }
        let t0 = Instant::now();
        let pixels: Vec<Vec3> = (0..w)
            .map(|x| {
                tracer
                    .sample(&job.state, x as f32 + 0.5, y as f32 + 0.5)
                    .color
            })
            .collect();
        s.busy_ns
            .fetch_add(t0.elapsed().as_nanos() as u64, Ordering::Relaxed);
        s.samples.fetch_add(w as u64, Ordering::Relaxed);
        s.rays.fetch_add(w as u64, Ordering::Relaxed);
        if tx
            .send(FramedRow {
                frame: job.id,
                time: job.time,
                y,
                pixels,
            })
            .is_err()
        {
            return;
        }
    }
}
