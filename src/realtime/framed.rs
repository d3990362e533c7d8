//! The real-time framed method: double-buffered frames at full resolution, as fast as
//! the machine goes. Sampling threads take rows of the current frame (traced at the
//! frame's start time, through pixel centres, as the evaluation's
//! [`Framed`](crate::methods::framed::Framed) does); the thread that finds the rows
//! exhausted starts the next frame at the current time. The image thread assembles the
//! rows and shows the newest complete frame.
//!
//! `late-warp` is the same frames, each also keeping what every pixel hit, and the
//! newest complete one reprojected at every refresh to the camera and time shown (the
//! evaluation's [`Warp`]: depth and object motion, display-side, no rays): the
//! practitioners' low-latency answer, live beside frameless.
//!
//! With a GPU tracer (`--trace gpu`) one sampling thread traces each whole frame as one
//! batch at its start time (one scene state, so one dispatch) and hands its rows on as
//! the CPU's threads do.

use std::{
    sync::{
        atomic::{AtomicU32, Ordering},
        Arc, Mutex,
    },
    time::Instant,
};

use crossbeam_channel::{bounded, Receiver, Sender};
use glam::Vec3;

use super::{
    config::RealtimeError,
    shared::{
        lock, take_queued, Assembly, BuildAt, Built, ImageBuilder, MethodInfo, Pooled, Shared,
        Shown, Spawner, Turns,
    },
};
use crate::{
    image::Image,
    methods::{
        framed::{trace_row_samples, GBuffer, GSample},
        late_warp::Warp,
    },
    scene::CameraFrame,
    trace::{
        batch::{self, GpuRays},
        SceneState, Tracer,
    },
};

/// The framed method's description.
pub(crate) const METHOD: MethodInfo = MethodInfo {
    name: "framed-full",
    about: "double-buffered frames at full resolution, as fast as they go",
    // Nothing else of it needs a core: the image thread only copies.
    default_sampling_threads: |cores| cores,
    extra_threads: |_| 0,
    check_size: super::shared::display_only,
    overlays: &[],
    traces_on_gpu: true,
    start: |sp, _| start_with(sp, Shown::AsBuilt),
};

/// The late-warp method's description.
pub(crate) const LATE_WARP: MethodInfo = MethodInfo {
    name: "late-warp",
    about: "framed, the newest frame reprojected to the camera at every refresh (depth + object motion, no rays)",
    default_sampling_threads: |cores| cores,
    extra_threads: |_| 0,
    check_size: super::shared::display_only,
    overlays: &[],
    traces_on_gpu: true,
    start: |sp, _| start_with(sp, Shown::Warped),
};

/// One frame being traced: the scene state at its start, rows handed out in order.
/// Each row goes to exactly one thread (the atomic counter), so pixels are never
/// shared.
struct FrameJob {
    id: u64,
    time: f64,
    state: Arc<SceneState>,
    next_row: AtomicU32,
}

impl FrameJob {
    /// Frame `id`, traced at `time` with the view `ahead` seconds ahead
    /// ([`Tracer::state_at_ahead`]).
    fn new(id: u64, time: f64, ahead: f64, tracer: &Tracer) -> Self {
        Self {
            id,
            time,
            state: tracer.state_at_ahead(time, ahead),
            next_row: AtomicU32::new(0),
        }
    }
}

/// A traced row of a frame.
struct Row {
    frame: u64,
    time: f64,
    camera: CameraFrame,
    y: u32,
    pixels: Vec<Vec3>,
    /// What each pixel hit (late warp only).
    hits: Vec<GSample>,
}

/// A frame being assembled: scene time, camera, image, hits.
type Building = (f64, CameraFrame, Image, Vec<GSample>);

fn start_with(sp: &mut Spawner<'_>, shown: Shown) -> Result<Box<dyn ImageBuilder>, RealtimeError> {
    let warp = shown == Shown::Warped;
    let s = sp.shared().clone();
    let job = Arc::new(Mutex::new(Arc::new(FrameJob::new(
        0,
        s.config.start,
        0.0,
        &s.tracer,
    ))));
    // Bounded, so that a slow image thread slows the sampling threads instead of
    // growing memory; ~100 ms of rows.
    let (tx, rx) = bounded(1024);
    let s1 = s.clone();
    sp.sampling_threads(tx, move |thread, tx| match &s1.config.rays {
        // The GPU traces one frame at a time: one thread feeds it.
        Some(rays) if thread == 0 => sample_on_gpu(&s1, rays, tx, shown),
        Some(_) => {}
        None => sample(&s1, &job, tx, shown),
    })?;
    let (w, h) = s.tracer.size();
    // The warp runs on the builder's own pool.
    let config = s.config.clone();
    Ok(Box::new(Pooled::new(
        &config,
        Builder {
            s: s.clone(),
            size: (w, h),
            rx,
            building: Assembly::default(),
            front: Image::new(w, h),
            front_time: (0, f64::NAN),
            front_g: None,
            warp: warp.then(|| Warp::new(w, h)),
            dropped_frames: 0,
        },
    )))
}

/// A sampling thread: rows of the current frame until stopped.
fn sample(s: &Shared, job: &Mutex<Arc<FrameJob>>, tx: Sender<Row>, shown: Shown) {
    let warp = shown == Shown::Warped;
    let tracer = &s.tracer;
    let (w, h) = tracer.size();
    let mut turns = Turns::new();
    while !s.stopped() {
        turns.between(s);
        let cur = lock(job).clone();
        let y = cur.next_row.fetch_add(1, Ordering::Relaxed);
        if y >= h {
            let mut j = lock(job);
            if j.id == cur.id {
                let (now, ahead) = (s.clock.now(), s.view_ahead.seconds());
                *j = Arc::new(FrameJob::new(cur.id + 1, now, ahead, tracer));
            }
            continue;
        }
        let t0 = Instant::now();
        let (pixels, hits): (Vec<Vec3>, Vec<GSample>) = if warp {
            trace_row_samples(tracer, &cur.state, (w, h), y)
                .map(|s| (s.color, GSample::from(&s)))
                .unzip()
        } else {
            (
                trace_row_samples(tracer, &cur.state, (w, h), y)
                    .map(|s| s.color)
                    .collect(),
                Vec::new(),
            )
        };
        s.traced(w as u64, t0.elapsed());
        if tx
            .send(Row {
                frame: cur.id,
                time: cur.time,
                camera: cur.state.camera,
                y,
                pixels,
                hits,
            })
            .is_err()
        {
            return;
        }
    }
}

/// The sampling thread of a run with a GPU tracer: whole frames, each traced as one
/// batch through pixel centres at the time it starts, then handed on row by row.
fn sample_on_gpu(s: &Shared, rays: &GpuRays, tx: Sender<Row>, shown: Shown) {
    let tracer = &s.tracer;
    let (w, h) = tracer.size();
    let points: Vec<[f32; 2]> = (0..h)
        .flat_map(|y| (0..w).map(move |x| [x as f32 + 0.5, y as f32 + 0.5]))
        .collect();
    let mut id = 0u64;
    while !s.stopped() {
        let time = s.clock.now();
        let state = tracer.state_at_ahead(time, s.view_ahead.seconds());
        let t0 = Instant::now();
        let got = batch::trace_points(tracer, Some(rays), &state, &points);
        s.traced(got.len() as u64, t0.elapsed());
        for (y, row) in got.chunks(w as usize).enumerate() {
            let hits = match shown {
                Shown::Warped => row.iter().map(GSample::from).collect(),
                _ => Vec::new(),
            };
            let sent = tx.send(Row {
                frame: id,
                time,
                camera: state.camera,
                y: y as u32,
                pixels: row.iter().map(|s| s.color).collect(),
                hits,
            });
            if sent.is_err() {
                return;
            }
        }
        id += 1;
    }
}

/// The image thread's side: frames assembled from their rows, the newest complete one
/// shown (the front buffer).
struct Builder {
    s: Arc<Shared>,
    size: (u32, u32),
    rx: Receiver<Row>,
    /// Frames being assembled.
    building: Assembly<Building>,
    front: Image,
    /// Id and scene time of the frame shown (NaN: none yet).
    front_time: (u64, f64),
    /// Late warp: the front frame's hits and camera, and the warp's buffers.
    front_g: Option<GBuffer>,
    warp: Option<Warp>,
    /// Frames (whole or in part) traced but never shown.
    dropped_frames: u64,
}

impl ImageBuilder for Builder {
    fn stats(&self) -> Vec<(&'static str, serde_json::Value)> {
        vec![("dropped_frames", self.dropped_frames.into())]
    }

    fn build(&mut self, at: BuildAt) -> Option<Built> {
        let (w, h) = self.size;
        // Frames completed in this build before a newer one: traced, never shown.
        let (mut dropped, mut replaced) = (0u64, false);
        let warp = self.warp.is_some();
        for row in take_queued(&self.rx) {
            let new = || {
                let hits = if warp {
                    vec![GSample::default(); (w * h) as usize]
                } else {
                    Vec::new()
                };
                (row.time, row.camera, Image::new(w, h), hits)
            };
            let put = |f: &mut Building| {
                let y = row.y as usize * w as usize;
                f.2.pixels[y..y + w as usize].copy_from_slice(&row.pixels);
                if warp {
                    f.3[y..y + w as usize].copy_from_slice(&row.hits);
                }
            };
            let Some((ft, camera, img, hits)) = self.building.add(row.frame, h, new, put) else {
                continue;
            };
            let id = row.frame;
            if id >= self.front_time.0 || self.front_time.1.is_nan() {
                dropped += replaced as u64;
                replaced = true;
                self.front = img;
                self.front_time = (id, ft);
                if warp {
                    self.front_g = Some(GBuffer {
                        grid: (w, h),
                        samples: hits,
                        time: ft,
                        camera,
                    });
                }
            } else {
                dropped += 1;
            }
        }
        dropped += self.building.take_abandoned();
        self.dropped_frames += dropped;
        let n = self.front.pixels.len();
        // The warp moves what the frame saw to where it will be at the refresh the
        // image is meant for; it adds no new information, so the age stays the
        // frame's, measured from the time it shows.
        let (image, view_time, t) = match (&mut self.warp, &self.front_g) {
            (Some(warp), Some(g)) => {
                let t = at.shown;
                let camera = self.s.tracer.state_at(t).camera;
                (warp.apply(&self.front, g, t, &camera).clone(), t, t)
            }
            _ => (self.front.clone(), self.front_time.1, at.now),
        };
        let age = (t - self.front_time.1) as f32;
        // The sampling threads trace the view as far ahead as the frame is old when
        // it is shown.
        self.s.view_ahead.shown_after(at.shown - self.front_time.1);
        Some(Built {
            image,
            mean_age: t - self.front_time.1,
            overlays: None,
            ages: super::shared::sampled_ages(n, |_| age),
            view_time,
        })
    }
}
