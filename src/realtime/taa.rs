//! The real-time temporal upsampler (`taa`, FSR 2-like) and `taa-warp`.
//!
//! Sampling threads trace jittered low-resolution frames, row by row, each frame at
//! the scene time it started (as the real-time [`framed`](super::framed) does with
//! full-resolution frames). The frame's resolution is what the threads' measured
//! throughput allows at the display rate, as the evaluation's `taa` sizes its frames
//! from the sample budget: dynamic resolution, the way engines drive FSR 2. The image
//! thread folds every completed frame into the full-resolution history with the
//! evaluation's own accumulation ([`TaaHistory`]) and shows the result; `taa-warp`
//! also warps it at every refresh to the camera of that moment (the evaluation's
//! [`Warp`]: display-side, no rays).

use std::{
    sync::{
        atomic::{AtomicU32, AtomicU64, Ordering},
        Arc, Mutex,
    },
    time::Instant,
};

use crossbeam_channel::{bounded, Receiver, Sender};

use super::{
    config::RealtimeError,
    shared::{
        lock, sampled_ages, take_queued, Assembly, BuildAt, Built, ImageBuilder, MethodInfo,
        Pooled, Shared, Shown, Spawner, Turns,
    },
};
use crate::{
    methods::{
        framed::reduced_grid,
        late_warp::Warp,
        taa::{
            frame_jitter, jitter_period, jittered_position, trace_jittered_row, JitteredFrame,
            TaaHistory, TaaParams,
        },
    },
    trace::{
        batch::{self, GpuRays},
        Sample, SceneState, Tracer,
    },
};

/// `taa`'s description.
pub(crate) const METHOD: MethodInfo = MethodInfo {
    name: "taa",
    about: "temporal upsampler (FSR 2-like): jittered low-res frames sized to the display rate, accumulated into a full-res history",
    // The image thread folds one frame per period (the period grows with the fold
    // time, see `FOLD_HEADROOM`); the sampling threads fill the cores and the OS
    // shares them.
    default_sampling_threads: |cores| cores,
    extra_threads: |_| 0,
    check_size: super::shared::display_only,
    overlays: &[],
    traces_on_gpu: true,
    start: |sp, _| start_with(sp, Shown::AsBuilt),
};

/// `taa-warp`'s description.
pub(crate) const TAA_WARP: MethodInfo = MethodInfo {
    name: "taa-warp",
    about: "taa, its image warped to the camera at every refresh (depth + object motion, no rays)",
    default_sampling_threads: |cores| cores,
    extra_threads: |_| 0,
    check_size: super::shared::display_only,
    overlays: &[],
    traces_on_gpu: true,
    start: |sp, _| start_with(sp, Shown::Warped),
};

/// Share of the frame budget by which the measured throughput must move before the
/// frame's resolution follows: a resized grid changes the jitter sequence's period and
/// so breaks its even coverage of the pixel, so throughput noise must not resize it
/// every frame.
const RESIZE_BAND: f64 = 0.2;

/// Weight of the newest measurement in the smoothed throughput and fold time.
const SMOOTHING: f64 = 0.25;

/// A frame lasts at least this many times as long as the image thread takes to fold
/// one, so that folding keeps up with the frames and still leaves time to copy (and
/// warp) the image for the display.
const FOLD_HEADROOM: f64 = 1.25;

/// One frame being traced: its scene state, grid and jitter; rows handed out in order,
/// each to exactly one thread (the atomic counter).
struct FrameJob {
    id: u64,
    time: f64,
    state: Arc<SceneState>,
    grid: (u32, u32),
    jitter: (f32, f32),
    started: Instant,
    next_row: AtomicU32,
}

/// What the sampling threads share besides the frame: how big the next frame is.
struct Frames {
    current: Arc<FrameJob>,
    /// Samples per second the threads trace, smoothed over frames.
    rate: Option<f64>,
    /// Seconds the image thread takes to fold a frame, smoothed (`f64` bits; 0: none
    /// folded yet).
    fold_s: Arc<AtomicU64>,
}

impl Frames {
    /// The frame after `done`, whose rows just ran out, sized to the display rate.
    fn next(&mut self, done: &FrameJob, s: &Shared, params: &TaaParams) -> Arc<FrameJob> {
        let tracer = &s.tracer;
        let size = tracer.size();
        let traced = (done.grid.0 * done.grid.1) as f64;
        let measured = traced / done.started.elapsed().as_secs_f64().max(1e-6);
        let rate = match self.rate {
            Some(r) => r + SMOOTHING * (measured - r),
            None => measured,
        };
        self.rate = Some(rate);
        // One frame per refresh, as the evaluation's `taa`, unless the image thread
        // cannot fold them that fast: every fold costs the same whatever the frame's
        // size, so then fewer, larger frames carry the same samples. (On this
        // project's loaded 2-core machine a fold of 256×256 took 35–50 ms, two to
        // three refreshes.)
        let fold_s = f64::from_bits(self.fold_s.load(Ordering::Relaxed));
        let period = (1.0 / s.config.refresh_hz).max(FOLD_HEADROOM * fold_s);
        let want = rate * period;
        let grid = if (want - traced).abs() > RESIZE_BAND * traced {
            reduced_grid(size.0, size.1, want.max(1.0) as u64)
        } else {
            done.grid
        };
        let id = done.id + 1;
        let time = s.clock.now();
        Arc::new(FrameJob {
            id,
            time,
            state: tracer.state_at_ahead(time, s.view_ahead.seconds()),
            grid,
            jitter: frame_jitter(id, jitter_period(params, size, grid)),
            started: Instant::now(),
            next_row: AtomicU32::new(0),
        })
    }
}

/// A traced row of a frame.
struct Row {
    job: Arc<FrameJob>,
    y: u32,
    samples: Vec<Sample>,
}

fn start_with(sp: &mut Spawner<'_>, shown: Shown) -> Result<Box<dyn ImageBuilder>, RealtimeError> {
    let s = sp.shared().clone();
    let params = TaaParams::default();
    let size = s.tracer.size();
    let history = TaaHistory::new(size, params, s.config.start)
        .map_err(|e| RealtimeError::Config(e.to_string()))?;
    // Nothing is measured yet: the first frame is a sixteenth of the pixels, small
    // enough to be quick on any machine, and the next is sized from it.
    let grid = reduced_grid(size.0, size.1, (size.0 as u64 * size.1 as u64 / 16).max(1));
    let first = FrameJob {
        id: 0,
        time: s.config.start,
        state: s.tracer.state_at(s.config.start),
        grid,
        jitter: frame_jitter(0, jitter_period(&params, size, grid)),
        started: Instant::now(),
        next_row: AtomicU32::new(0),
    };
    let fold_s = Arc::new(AtomicU64::new(0f64.to_bits()));
    let frames = Arc::new(Mutex::new(Frames {
        current: Arc::new(first),
        rate: None,
        fold_s: fold_s.clone(),
    }));
    // Bounded, so that a slow image thread slows the sampling threads instead of
    // growing memory.
    let (tx, rx) = bounded(1024);
    let s1 = s.clone();
    sp.sampling_threads(tx, move |thread, tx| match &s1.config.rays {
        // The GPU traces one frame at a time: one thread feeds it.
        Some(rays) if thread == 0 => sample_on_gpu(&s1, &frames, &params, rays, tx),
        Some(_) => {}
        None => sample(&s1, &frames, &params, tx),
    })?;
    // Folds and warps run on the builder's own pool.
    let config = s.config.clone();
    Ok(Box::new(Pooled::new(
        &config,
        Builder {
            s,
            rx,
            building: Assembly::default(),
            folded: None,
            fold_s,
            history,
            warp: (shown == Shown::Warped).then(|| Warp::new(size.0, size.1)),
            dropped_frames: 0,
        },
    )))
}

/// A sampling thread: rows of the current frame until stopped.
fn sample(s: &Shared, frames: &Mutex<Frames>, params: &TaaParams, tx: Sender<Row>) {
    let tracer: &Tracer = &s.tracer;
    let mut turns = Turns::new();
    while !s.stopped() {
        turns.between(s);
        let cur = lock(frames).current.clone();
        let y = cur.next_row.fetch_add(1, Ordering::Relaxed);
        if y >= cur.grid.1 {
            let mut f = lock(frames);
            if f.current.id == cur.id {
                let next = f.next(&cur, s, params);
                f.current = next;
            }
            continue;
        }
        let t0 = Instant::now();
        let samples: Vec<Sample> =
            trace_jittered_row(tracer, &cur.state, cur.grid, cur.jitter, y).collect();
        s.traced(samples.len() as u64, t0.elapsed());
        if tx
            .send(Row {
                job: cur,
                y,
                samples,
            })
            .is_err()
        {
            return;
        }
    }
}

/// The sampling thread of a run with a GPU tracer: each frame traced whole as one batch
/// at its start time, handed on row by row, then the next sized as the CPU threads
/// size it (from the samples per second this thread traced).
fn sample_on_gpu(
    s: &Shared,
    frames: &Mutex<Frames>,
    params: &TaaParams,
    rays: &GpuRays,
    tx: Sender<Row>,
) {
    let tracer: &Tracer = &s.tracer;
    let size = tracer.size();
    while !s.stopped() {
        let cur = lock(frames).current.clone();
        let (gw, gh) = cur.grid;
        let points: Vec<[f32; 2]> = (0..gw * gh)
            .map(|q| {
                let (x, y) = jittered_position(size, cur.grid, cur.jitter, q % gw, q / gw);
                [x, y]
            })
            .collect();
        let t0 = Instant::now();
        let got = batch::trace_points(tracer, Some(rays), &cur.state, &points);
        s.traced(got.len() as u64, t0.elapsed());
        for (y, row) in got.chunks(gw as usize).enumerate() {
            let sent = tx.send(Row {
                job: cur.clone(),
                y: y as u32,
                samples: row.to_vec(),
            });
            if sent.is_err() {
                return;
            }
        }
        let mut f = lock(frames);
        let next = f.next(&cur, s, params);
        f.current = next;
    }
}

/// A frame being assembled: its job, its samples, rows received.
type Building = (Arc<FrameJob>, Vec<Sample>);

/// The image thread's side: frames assembled from their rows and folded into the
/// history in order.
struct Builder {
    s: Arc<Shared>,
    rx: Receiver<Row>,
    building: Assembly<Building>,
    /// Id and scene time of the newest frame folded in.
    folded: Option<(u64, f64)>,
    /// Shared with the sampling threads, which size frames by it.
    fold_s: Arc<AtomicU64>,
    history: TaaHistory,
    warp: Option<Warp>,
    /// Frames (whole or in part) traced but never shown.
    dropped_frames: u64,
}

impl Builder {
    fn fold(&mut self, job: &FrameJob, samples: &[Sample]) {
        let t0 = Instant::now();
        let dt = self.folded.map_or(0.0, |(_, t)| (job.time - t) as f32);
        self.history.accumulate(JitteredFrame {
            samples,
            grid: job.grid,
            jitter: job.jitter,
            time: job.time,
            camera: job.state.camera,
            dt,
        });
        self.folded = Some((job.id, job.time));
        let took = t0.elapsed().as_secs_f64();
        let old = f64::from_bits(self.fold_s.load(Ordering::Relaxed));
        let new = if old > 0.0 {
            old + SMOOTHING * (took - old)
        } else {
            took
        };
        self.fold_s.store(new.to_bits(), Ordering::Relaxed);
    }
}

impl ImageBuilder for Builder {
    fn stats(&self) -> Vec<(&'static str, serde_json::Value)> {
        vec![("dropped_frames", self.dropped_frames.into())]
    }

    fn build(&mut self, at: BuildAt) -> Option<Built> {
        // Collected first: folding borrows the whole builder.
        let rows: Vec<Row> = take_queued(&self.rx).collect();
        let mut complete: Option<Building> = None;
        let mut dropped = 0u64;
        for row in rows {
            let (gw, gh) = row.job.grid;
            let new = || (row.job.clone(), vec![Sample::default(); (gw * gh) as usize]);
            let put = |f: &mut Building| {
                let y = row.y as usize * gw as usize;
                f.1[y..y + gw as usize].copy_from_slice(&row.samples);
            };
            let Some(done) = self.building.add(row.job.id, gh, new, put) else {
                continue;
            };
            if complete.as_ref().is_none_or(|c| c.0.id < done.0.id) {
                dropped += complete.is_some() as u64;
                complete = Some(done);
            } else {
                dropped += 1;
            }
        }
        dropped += self.building.take_abandoned();
        // Only the newest frame completed since the last image is folded: the frames
        // are sized so that this is nearly always the only one, and folding a backlog
        // would put the display further behind.
        if let Some((job, samples)) = complete {
            if self.folded.is_none_or(|(id, _)| id < job.id) {
                self.fold(&job, &samples);
            } else {
                dropped += 1;
            }
        }
        self.dropped_frames += dropped;
        let (_, newest) = self.folded?;
        // The warp moves what the history holds to where it will be at the refresh
        // the image is meant for; it adds no information, so the ages stay the
        // history's, measured from the time it shows.
        let (image, view_time, t) = match (&mut self.warp, self.history.shown_gbuffer()) {
            (Some(warp), Some(g)) => {
                let t = at.shown;
                let camera = self.s.tracer.state_at(t).camera;
                (
                    warp.apply(self.history.output(), g, t, &camera).clone(),
                    t,
                    t,
                )
            }
            _ => (self.history.output().clone(), newest, at.now),
        };
        // The sampling threads trace the view as far ahead as the newest frame is old
        // when it is shown.
        self.s.view_ahead.shown_after(at.shown - newest);
        let times = self.history.output_times();
        let ages = sampled_ages(times.len(), |i| (t - times[i]) as f32);
        let mean_age = self.history.mean_age(t).unwrap_or(f64::NAN);
        Some(Built {
            image,
            mean_age,
            overlays: None,
            ages,
            view_time,
        })
    }
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use super::*;
    use crate::{
        realtime::{config::RtConfig, registry::RtMethod},
        scene::builtin,
        trace::TraceOptions,
    };

    fn shared(refresh_hz: f64) -> Shared {
        let scene = Arc::new(builtin::load("toycar").expect("built-in scene"));
        let tracer = Arc::new(Tracer::new(scene, 64, 48, TraceOptions::default()));
        let mut config = RtConfig::new(RtMethod::Taa);
        config.refresh_hz = refresh_hz;
        Shared::new(tracer, config)
    }

    /// A frame of `grid` whose rows ran out `ago` after it started.
    fn done(s: &Shared, grid: (u32, u32), ago: Duration) -> FrameJob {
        FrameJob {
            id: 3,
            time: 0.0,
            state: s.tracer.state_at(0.0),
            grid,
            jitter: (0.5, 0.5),
            started: Instant::now() - ago,
            next_row: AtomicU32::new(grid.1),
        }
    }

    /// The grid of the frame after `d`, for a fresh run whose folds take `fold_s`.
    fn next_grid(s: &Shared, d: &FrameJob, fold_s: f64) -> (u32, u32) {
        let mut frames = Frames {
            current: Arc::new(done(s, d.grid, Duration::ZERO)),
            rate: None,
            fold_s: Arc::new(AtomicU64::new(fold_s.to_bits())),
        };
        let next = frames.next(d, s, &TaaParams::default());
        assert_eq!(next.id, d.id + 1);
        next.grid
    }

    #[test]
    fn frames_last_a_refresh_or_a_fold_whichever_is_longer() {
        // Long frames, so that scheduling delays of the test are small beside them.
        let s = shared(10.0);
        let count = |g: (u32, u32)| g.0 * g.1;
        // 192 samples in 0.4 s: 480 samples/s, 48 per 0.1 s refresh.
        let slow = done(&s, (16, 12), Duration::from_millis(400));
        let g = next_grid(&s, &slow, 0.0);
        assert!((40..=48).contains(&count(g)), "{g:?}");
        // The same throughput, but a fold takes 0.4 s: frames of 0.5 s.
        let g = next_grid(&s, &slow, 0.4);
        assert!((200..=240).contains(&count(g)), "{g:?}");
        // Within the band the grid stays: 192 samples in about one refresh.
        let steady = done(&s, (16, 12), Duration::from_millis(100));
        assert_eq!(next_grid(&s, &steady, 0.0), (16, 12));
        // Fast threads: never beyond one sample per display pixel.
        let fast = done(&s, (64, 48), Duration::from_millis(1));
        assert_eq!(next_grid(&s, &fast, 0.0), (64, 48));
    }
}
