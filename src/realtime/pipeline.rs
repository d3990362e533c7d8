//! The pipeline: thread set-up, the image thread (reconstruction at the display rate),
//! and the statistics.
//!
//! Threads and what flows between them:
//!
//! ```text
//!  sampling ×N ──crosshairs, initiating samples──► controller (Sampler: deep buffer,
//!      ▲                                            tiling, gain control, reprojection)
//!      └──── tile snapshot (Arc, ~1 ms) ◄───────────┘   │ samples + tiling (Arc)
//!                                                       ▼
//!                                                 image thread: Reconstructor at the
//!                                                 display rate ──► latest Frame (Arc)
//!                                                       ▼
//!                                   display (window / headless) presents at each refresh
//! ```
//!
//! Traditional frameless and framed have no controller: their sampling threads send
//! pixels (or rows) straight to the image thread.

use std::{
    collections::VecDeque,
    sync::{
        atomic::{AtomicBool, AtomicU64, Ordering},
        Arc, Mutex,
    },
    thread::JoinHandle,
    time::{Duration, Instant},
};

use crossbeam_channel::{bounded, Receiver, Sender};
use glam::Vec3;

use super::{
    clock::WallClock, controller, pixel_locks::PixelLocks, sampling, RealtimeError, RtConfig,
    RtMethod,
};
use crate::{
    image::Image, methods::adaptive::tiling::Tiling, reconstruction::Reconstructor,
    trace::StreamSample, trace::Tracer,
};

/// One displayed image.
pub struct Frame {
    /// Increases with every new image.
    pub seq: u64,
    /// Linear RGB.
    pub image: Image,
    /// Scene time it shows.
    pub time: f64,
    /// Mean age of the information in it, seconds.
    pub mean_age: f64,
    /// The tiling it was reconstructed with (adaptive only; for visualisations).
    pub tiling: Option<Arc<Tiling>>,
}

/// A lock that survives a panicking holder: the data are plain values, always valid.
pub(crate) fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// State shared by every thread of one pipeline.
pub(crate) struct Shared {
    pub tracer: Arc<Tracer>,
    pub clock: WallClock,
    pub config: RtConfig,
    pub stop: AtomicBool,
    pub locks: PixelLocks,
    /// Shaded samples delivered to the image thread's input.
    pub samples: AtomicU64,
    /// Every ray traced (samples plus occlusion rays).
    pub rays: AtomicU64,
    /// Nanoseconds sampling threads spent tracing (summed over threads).
    pub busy_ns: AtomicU64,
    /// Visits whose reprojection step the controller ran, and skipped (behind).
    pub reprojected_visits: AtomicU64,
    pub skipped_reprojections: AtomicU64,
    pub tiles: AtomicU64,
    pub snapshot: Mutex<Arc<controller::TileSnapshot>>,
    pub snapshot_seq: AtomicU64,
    pub tiling: Mutex<Option<Arc<Tiling>>>,
    pub framed_job: Mutex<Arc<sampling::FrameJob>>,
    pub latest: Mutex<Option<Arc<Frame>>>,
    pub image_stats: Mutex<ImageThreadStats>,
}

impl Shared {
    pub fn stopped(&self) -> bool {
        self.stop.load(Ordering::Relaxed)
    }
}

/// What the image thread measured.
#[derive(Clone, Debug, Default)]
pub(crate) struct ImageThreadStats {
    pub images: u64,
    pub build_ms: Vec<f64>,
    pub ages: Vec<f64>,
    pub recon_rate: f64,
    pub ring_capacity: usize,
    pub rebuilds: u64,
}

/// Statistics of a pipeline run so far.
#[derive(Clone, Debug, serde::Serialize)]
pub struct PipelineStats {
    /// Method name.
    pub method: &'static str,
    /// Sampling threads.
    pub sampling_threads: usize,
    /// Threads of the reconstructor's pool.
    pub recon_threads: usize,
    /// Other threads of the pipeline (controller, image thread).
    pub other_threads: usize,
    /// Cores the OS reports.
    pub cores: usize,
    /// Wall-clock seconds since the start.
    pub seconds: f64,
    /// Shaded samples delivered (crosshair, initiating, frameless, framed samples).
    pub samples: u64,
    /// `samples / seconds`.
    pub samples_per_s: f64,
    /// Every ray, occlusion rays included (the evaluation's budget unit), per second.
    pub rays_per_s: f64,
    /// Images the image thread produced per second.
    pub images_per_s: f64,
    /// Mean wall time to build one image (drain the input, reconstruct), ms.
    pub reconstruct_ms_mean: f64,
    /// 95th percentile of the same, ms.
    pub reconstruct_ms_p95: f64,
    /// Sampling threads' tracing time per image produced, thread-milliseconds.
    pub sampling_ms_per_image: f64,
    /// Share of the sampling threads' wall time spent tracing.
    pub sampling_busy_share: f64,
    /// Mean over images of their mean information age, seconds.
    pub mean_age_s: f64,
    /// Attempts to take a pixel that another thread held.
    pub pixel_conflicts: u64,
    /// Adaptive: tiles now.
    pub tiles: u64,
    /// Adaptive: share of visits whose reprojection step ran (the controller skips it
    /// while it is behind its input).
    pub reprojected_share: f64,
    /// Adaptive: the sample rate the reconstructor's filters assume (measured), /s.
    pub recon_rate: f64,
    /// Adaptive: ring capacity.
    pub ring_capacity: usize,
}

/// A running pipeline. Dropping it stops and joins its threads.
pub struct Pipeline {
    shared: Arc<Shared>,
    handles: Vec<(&'static str, JoinHandle<()>)>,
}

impl Pipeline {
    /// Start the threads; scene time `config.start` is now.
    pub fn start(tracer: Arc<Tracer>, config: RtConfig) -> Result<Self, RealtimeError> {
        config.validate()?;
        let (w, h) = tracer.size();
        let shared = Arc::new(Shared {
            clock: WallClock::new(config.start),
            locks: PixelLocks::new(w, h),
            framed_job: Mutex::new(Arc::new(sampling::FrameJob::new(0, config.start, &tracer))),
            tracer,
            config,
            stop: AtomicBool::new(false),
            samples: AtomicU64::new(0),
            rays: AtomicU64::new(0),
            busy_ns: AtomicU64::new(0),
            reprojected_visits: AtomicU64::new(0),
            skipped_reprojections: AtomicU64::new(0),
            tiles: AtomicU64::new(1),
            snapshot: Mutex::new(Arc::new(controller::TileSnapshot::whole(w, h))),
            snapshot_seq: AtomicU64::new(0),
            tiling: Mutex::new(None),
            latest: Mutex::new(None),
            image_stats: Mutex::new(ImageThreadStats::default()),
        });
        let mut p = Pipeline {
            shared: shared.clone(),
            handles: Vec::new(),
        };
        // Channels are bounded so that a slow consumer slows its producers instead of
        // growing memory without limit; the capacities hold ~100 ms of batches.
        match config.method {
            RtMethod::Adaptive => {
                let (to_ctrl, ctrl_rx) = bounded(256);
                let (to_img, img_rx) = bounded::<Vec<StreamSample>>(256);
                p.spawn_sampling(config.sampling_threads, to_ctrl, sampling::adaptive)?;
                let s = shared.clone();
                p.spawn("controller", move || controller::run(&s, ctrl_rx, to_img))?;
                let s = shared.clone();
                p.spawn("image", move || image_thread(&s, Input::Adaptive(img_rx)))?;
            }
            RtMethod::TraditionalFrameless => {
                let (tx, rx) = bounded(256);
                p.spawn_sampling(config.sampling_threads, tx, sampling::frameless)?;
                let s = shared.clone();
                p.spawn("image", move || image_thread(&s, Input::Frameless(rx)))?;
            }
            RtMethod::Framed => {
                let (tx, rx) = bounded(1024);
                p.spawn_sampling(config.sampling_threads, tx, sampling::framed)?;
                let s = shared.clone();
                p.spawn("image", move || image_thread(&s, Input::Framed(rx)))?;
            }
        }
        Ok(p)
    }

    /// `n` sampling threads running `f(shared, thread index, sender)`, each with a
    /// clone of `tx` (dropped here, so the channel closes when they all end).
    fn spawn_sampling<T: Send + 'static>(
        &mut self,
        n: usize,
        tx: Sender<T>,
        f: fn(&Shared, u64, Sender<T>),
    ) -> Result<(), RealtimeError> {
        for i in 0..n {
            let (s, tx) = (self.shared.clone(), tx.clone());
            self.spawn("sampling", move || f(&s, i as u64, tx))?;
        }
        Ok(())
    }

    fn spawn(
        &mut self,
        what: &'static str,
        f: impl FnOnce() + Send + 'static,
    ) -> Result<(), RealtimeError> {
        let h = std::thread::Builder::new()
            .name(format!("frameless-{what}"))
            .spawn(f)
            .map_err(|source| {
                self.shared.stop.store(true, Ordering::Relaxed);
                RealtimeError::Spawn { what, source }
            })?;
        self.handles.push((what, h));
        Ok(())
    }

    /// The newest image, if any yet.
    pub fn latest(&self) -> Option<Arc<Frame>> {
        lock(&self.shared.latest).clone()
    }

    /// The pipeline's clock.
    pub fn clock(&self) -> WallClock {
        self.shared.clock
    }

    /// The tracer (set its live camera to move the view).
    pub fn tracer(&self) -> &Arc<Tracer> {
        &self.shared.tracer
    }

    /// The settings.
    pub fn config(&self) -> &RtConfig {
        &self.shared.config
    }

    /// Statistics so far.
    pub fn stats(&self) -> PipelineStats {
        let s = &self.shared;
        let seconds = s.clock.elapsed().max(1e-9);
        let img = lock(&s.image_stats).clone();
        let samples = s.samples.load(Ordering::Relaxed);
        let busy = s.busy_ns.load(Ordering::Relaxed) as f64 * 1e-9;
        let mean = |v: &[f64]| {
            if v.is_empty() {
                0.0
            } else {
                v.iter().sum::<f64>() / v.len() as f64
            }
        };
        let mut sorted = img.build_ms.clone();
        sorted.sort_by(|a, b| a.total_cmp(b));
        let p95 = sorted
            .get(((sorted.len() as f64 - 1.0) * 0.95).max(0.0) as usize)
            .copied()
            .unwrap_or(0.0);
        let (rv, sv) = (
            s.reprojected_visits.load(Ordering::Relaxed),
            s.skipped_reprojections.load(Ordering::Relaxed),
        );
        let cfg = &s.config;
        PipelineStats {
            method: cfg.method.name(),
            sampling_threads: cfg.sampling_threads,
            recon_threads: cfg.recon_threads,
            other_threads: if cfg.method == RtMethod::Adaptive {
                2
            } else {
                1
            },
            cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
            seconds,
            samples,
            samples_per_s: samples as f64 / seconds,
            rays_per_s: s.rays.load(Ordering::Relaxed) as f64 / seconds,
            images_per_s: img.images as f64 / seconds,
            reconstruct_ms_mean: mean(&img.build_ms),
            reconstruct_ms_p95: p95,
            sampling_ms_per_image: if img.images > 0 {
                busy * 1e3 / img.images as f64
            } else {
                0.0
            },
            sampling_busy_share: busy / (seconds * cfg.sampling_threads as f64),
            mean_age_s: mean(&img.ages),
            pixel_conflicts: s.locks.conflicts(),
            tiles: s.tiles.load(Ordering::Relaxed),
            reprojected_share: if rv + sv > 0 {
                rv as f64 / (rv + sv) as f64
            } else {
                0.0
            },
            recon_rate: img.recon_rate,
            ring_capacity: img.ring_capacity,
        }
    }

    /// Stop every thread and wait for them; the final statistics.
    pub fn stop(mut self) -> Result<PipelineStats, RealtimeError> {
        let stats = self.stats();
        self.shared.stop.store(true, Ordering::Relaxed);
        let mut result = Ok(stats);
        for (what, h) in self.handles.drain(..) {
            if h.join().is_err() && result.is_ok() {
                result = Err(RealtimeError::Panicked(what));
            }
        }
        result
    }
}

impl Drop for Pipeline {
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::Relaxed);
        for (_, h) in self.handles.drain(..) {
            let _ = h.join();
        }
    }
}

/// What the image thread receives.
enum Input {
    Adaptive(Receiver<Vec<StreamSample>>),
    Frameless(Receiver<Vec<(u32, Vec3, f64)>>),
    Framed(Receiver<sampling::FramedRow>),
}

/// Method-specific image state of the image thread.
enum Builder {
    Adaptive {
        rx: Receiver<Vec<StreamSample>>,
        recon: Option<Box<Reconstructor>>,
        /// Ray counts at recent images, to measure the rate the filters assume.
        rate_window: VecDeque<(f64, u64)>,
        last_rebuild: f64,
    },
    Frameless {
        rx: Receiver<Vec<(u32, Vec3, f64)>>,
        image: Image,
        info_time: Vec<f64>,
    },
    Framed {
        rx: Receiver<sampling::FramedRow>,
        /// Frames being assembled: id, scene time, image, rows received.
        building: Vec<(u64, f64, Image, u32)>,
        front: Image,
        /// Id and scene time of the frame shown.
        front_time: (u64, f64),
    },
}

/// Reconstruct (or assemble) an image at every display refresh, concurrently with
/// sampling. When building an image takes longer than a refresh period the thread
/// starts the next one at once: images then come at a lower rate, while the display
/// keeps refreshing on time with the newest one.
fn image_thread(s: &Shared, input: Input) {
    let (w, h) = s.tracer.size();
    let mut b = match input {
        Input::Adaptive(rx) => Builder::Adaptive {
            rx,
            recon: None,
            rate_window: VecDeque::new(),
            last_rebuild: 0.0,
        },
        Input::Frameless(rx) => Builder::Frameless {
            rx,
            image: Image::new(w, h),
            info_time: vec![f64::NAN; (w * h) as usize],
        },
        Input::Framed(rx) => Builder::Framed {
            rx,
            building: Vec::new(),
            front: Image::new(w, h),
            front_time: (0, f64::NAN),
        },
    };
    // The reconstructor splats in parallel with rayon; its own pool bounds how many
    // cores that takes. Without a pool it runs on the calling thread.
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(s.config.recon_threads)
        .thread_name(|i| format!("frameless-recon-{i}"))
        .build()
        .ok();
    let period = 1.0 / s.config.refresh_hz;
    let mut k: u64 = 1;
    let mut seq = 0;
    while !s.stopped() {
        let due = s.clock.instant_at(k as f64 * period);
        let now = Instant::now();
        if due > now {
            // Sleep in short steps so that a stop request is seen promptly.
            std::thread::sleep((due - now).min(Duration::from_millis(5)));
            continue;
        }
        // Next refresh after now (skipping those we were too late for).
        k = (s.clock.elapsed() / period).floor() as u64 + 1;
        let t0 = Instant::now();
        let t = s.clock.now();
        let built = match &pool {
            Some(p) => p.install(|| build(s, &mut b, t)),
            None => build(s, &mut b, t),
        };
        let Some((image, mean_age, tiling)) = built else {
            continue;
        };
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        seq += 1;
        *lock(&s.latest) = Some(Arc::new(Frame {
            seq,
            image,
            time: t,
            mean_age,
            tiling,
        }));
        let mut st = lock(&s.image_stats);
        st.images += 1;
        st.build_ms.push(ms);
        if mean_age.is_finite() {
            st.ages.push(mean_age);
        }
        if let Builder::Adaptive { recon: Some(r), .. } = &b {
            st.ring_capacity = r.capacity();
        }
    }
}

type Built = (Image, f64, Option<Arc<Tiling>>);

fn build(s: &Shared, b: &mut Builder, t: f64) -> Option<Built> {
    let (w, h) = s.tracer.size();
    match b {
        Builder::Adaptive {
            rx,
            recon,
            rate_window,
            last_rebuild,
        } => {
            let tiling = lock(&s.tiling).clone()?;
            let batches: Vec<Vec<StreamSample>> = rx.try_iter().collect();
            // The filters need the sample rate R; it is measured over the last second
            // and the reconstructor is rebuilt (keeping its ring) when the rate drifts
            // by more than 25%, at most once a second.
            let rays = s.rays.load(Ordering::Relaxed);
            let el = s.clock.elapsed();
            rate_window.push_back((el, rays));
            while rate_window.len() > 2 && el - rate_window[0].0 > 1.0 {
                rate_window.pop_front();
            }
            let (e0, r0) = rate_window[0];
            let rate = if el - e0 > 0.05 {
                (rays - r0) as f64 / (el - e0)
            } else {
                rays as f64 / el.max(1e-3)
            }
            .max(1.0);
            let stale = match recon {
                None => true,
                Some(_) => {
                    let cur = lock(&s.image_stats).recon_rate;
                    (rate / cur - 1.0).abs() > 0.25 && el - *last_rebuild > 1.0
                }
            };
            if stale {
                let mut fresh = Reconstructor::new(w, h, rate, s.config.recon);
                if let Some(old) = recon.take() {
                    for r in old.ring().iter() {
                        fresh.push(r);
                    }
                    lock(&s.image_stats).rebuilds += 1;
                }
                *recon = Some(Box::new(fresh));
                *last_rebuild = el;
                lock(&s.image_stats).recon_rate = rate;
            }
            let r = recon.as_mut()?;
            for batch in &batches {
                r.push_stream(batch);
            }
            let camera = s.tracer.state_at(t).camera;
            let img = r.reconstruct(t, &camera, &tiling.snapshot()).clone();
            Some((img, r.mean_age(), Some(tiling)))
        }
        Builder::Frameless {
            rx,
            image,
            info_time,
        } => {
            for batch in rx.try_iter() {
                for (p, c, ts) in batch {
                    image.pixels[p as usize] = c;
                    info_time[p as usize] = ts;
                }
            }
            let (mut sum, mut n) = (0.0, 0usize);
            for &ti in info_time.iter() {
                if ti.is_finite() {
                    sum += t - ti;
                    n += 1;
                }
            }
            Some((
                image.clone(),
                if n > 0 { sum / n as f64 } else { f64::NAN },
                None,
            ))
        }
        Builder::Framed {
            rx,
            building,
            front,
            front_time,
        } => {
            for row in rx.try_iter() {
                let i = match building.iter().position(|f| f.0 == row.frame) {
                    Some(i) => i,
                    None => {
                        building.push((row.frame, row.time, Image::new(w, h), 0));
                        building.len() - 1
                    }
                };
                let f = &mut building[i];
                let y = row.y as usize * w as usize;
                f.2.pixels[y..y + w as usize].copy_from_slice(&row.pixels);
                f.3 += 1;
                if f.3 == h {
                    let (id, ft, img, _) = building.swap_remove(i);
                    if id >= front_time.0 || front_time.1.is_nan() {
                        *front = img;
                        *front_time = (id, ft);
                    }
                    // Older unfinished frames can never be shown any more.
                    building.retain(|f| f.0 > id);
                }
            }
            let age = t - front_time.1;
            Some((front.clone(), age, None))
        }
    }
}
