//! The real-time traditional frameless method (Bishop et al. 1994): sampling threads
//! trace random pixels through their centres, each at the current time, and the image
//! thread shows the newest sample of every pixel ([`NewestSamples`], as the evaluation's
//! [`Traditional`](crate::methods::frameless::Traditional) does). It runs no thread of
//! its own besides: the image thread only copies.

use std::{sync::Arc, time::Instant};

use crossbeam_channel::{bounded, Receiver, Sender};
use glam::Vec3;

use super::{
    config::RealtimeError,
    shared::{
        take_queued, BuildAt, Built, ImageBuilder, MethodInfo, Shared, Spawner, Turns, BATCH_S,
    },
};
use crate::{
    image::Image,
    methods::frameless::NewestSamples,
    sampling::Rng,
    trace::{
        batch::{self, GpuRays},
        StateCache,
    },
};

/// The traditional frameless method's description.
pub(crate) const METHOD: MethodInfo = MethodInfo {
    name: "traditional-frameless",
    about: "random pixels, the newest sample shown at every pixel",
    // Nothing else of it needs a core: the image thread only copies.
    default_sampling_threads: |cores| cores,
    extra_threads: |_| 0,
    check_size: super::shared::display_only,
    overlays: &[],
    traces_on_gpu: true,
    start: |sp, _| start(sp),
};

/// Traced pixels: index (row-major), colour, time.
type Batch = Vec<(u32, Vec3, f64)>;

fn start(sp: &mut Spawner<'_>) -> Result<Box<dyn ImageBuilder>, RealtimeError> {
    let s = sp.shared().clone();
    // Bounded, so that a slow image thread slows the sampling threads instead of
    // growing memory: ~100 ms of the CPU's small batches, or two of each GPU feeder's
    // large ones (256 of those were 33 M samples, over half a second at 1080p).
    let queue = if s.config.rays.is_some() {
        2 * batch::GPU_FEEDERS as usize
    } else {
        256
    };
    let (tx, rx) = bounded(queue);
    let s1 = s.clone();
    sp.sampling_threads(tx, move |i, tx| sample(&s1, i, tx))?;
    let (w, h) = s.tracer.size();
    Ok(Box::new(Builder {
        s: s.clone(),
        rx,
        newest: NewestSamples::new(w, h, f64::NAN),
        on_every_core: s.config.rays.is_some(),
    }))
}

/// A sampling thread: a random pixel (taken, traced through its centre at the current
/// time, released), over and over.
fn sample(s: &Shared, thread: u64, tx: Sender<Batch>) {
    if let Some(rays) = &s.config.rays {
        // A few threads feed the GPU, each a batch at a time.
        if thread < batch::GPU_FEEDERS {
            sample_on_gpu(s, rays, thread, tx);
        }
        return;
    }
    let tracer = &s.tracer;
    let (w, h) = tracer.size();
    let n = w * h;
    let mut rng = Rng::new(&[s.config.seed, 0xf4a3e1, thread]);
    let mut states = StateCache::new();
    let mut batch = Vec::with_capacity(1024);
    let mut sent = Instant::now();
    let mut busy = std::time::Duration::ZERO;
    let mut turns = Turns::new();
    while !s.stopped() {
        turns.between(s);
        let now = s.clock.now();
        let state = states.at_ahead(tracer, now, s.view_ahead.seconds()).0;
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
        busy += t0.elapsed();
        if batch.len() >= 1024 || sent.elapsed().as_secs_f64() > BATCH_S {
            s.traced(batch.len() as u64, std::mem::take(&mut busy));
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

/// Pixels of one GPU batch, at most: a sixteenth of a 1080p display, so that a batch's
/// samples share an instant no older than a fraction of a refresh on a GPU that
/// traces tens of millions of samples a second.
const GPU_BATCH: u32 = 1 << 17;

/// A sampling thread of a run with a GPU tracer (one of [`batch::GPU_FEEDERS`]):
/// batches of random pixels, each batch traced at the time it was drawn (one scene
/// state, so one dispatch).
fn sample_on_gpu(s: &Shared, rays: &GpuRays, thread: u64, tx: Sender<Batch>) {
    let tracer = &s.tracer;
    let (w, h) = tracer.size();
    let n = w * h;
    let per_batch = (n / 4).clamp(1, GPU_BATCH);
    let mut rng = Rng::new(&[s.config.seed, 0xf4a3e1, thread]);
    let mut states = StateCache::new();
    while !s.stopped() {
        let now = s.clock.now();
        let state = states.at_ahead(tracer, now, s.view_ahead.seconds()).0;
        let pixels: Vec<u32> = (0..per_batch).map(|_| rng.below(n)).collect();
        let points: Vec<[f32; 2]> = pixels
            .iter()
            .map(|&p| [(p % w) as f32 + 0.5, (p / w) as f32 + 0.5])
            .collect();
        let t0 = Instant::now();
        let got = batch::trace_colours(tracer, Some(rays), &state, &points);
        s.traced(got.len() as u64, t0.elapsed());
        let batch: Batch = pixels.iter().zip(got).map(|(&p, c)| (p, c, now)).collect();
        if tx.send(batch).is_err() {
            return;
        }
    }
}

/// The image thread's side: the newest sample per pixel. Pixels not sampled yet have
/// no information time and do not count in the mean age.
struct Builder {
    s: Arc<Shared>,
    rx: Receiver<Batch>,
    newest: NewestSamples,
    /// Build on every core: with a GPU tracer, whose few feeding threads mostly wait
    /// for it, a refresh brings hundreds of thousands of samples and the cores are
    /// free. With the CPU tracer the sampling threads hold every core, and a build
    /// split over them waits for its slowest part: one thread then (1920×1080 on 2
    /// cores: 8.5–9.7 ms a build on one, 14–18 ms on two; docs/performance.md).
    on_every_core: bool,
}

impl ImageBuilder for Builder {
    fn build(&mut self, at: BuildAt) -> Option<Built> {
        // Each sample is shown where it was traced: nothing to show as it will be.
        let t = at.now;
        let batches: Vec<Batch> = take_queued(&self.rx).collect();
        let samples: usize = batches.iter().map(Vec::len).sum();
        let (image, mean_age) = if self.on_every_core && samples >= EVERY_CORE_FROM {
            self.newest.set_batches(&batches);
            let image = copy_image(&self.newest.image);
            (image, self.newest.mean_age_on_every_core(t))
        } else {
            for &(p, c, ts) in batches.iter().flatten() {
                self.newest.set(p, c, ts);
            }
            (self.newest.image.clone(), self.newest.mean_age(t))
        };
        let n = self.newest.image.pixels.len();
        // As far ahead as a sample's first refresh, not the pixels' mean age: the
        // pixels are shown as traced, so a view extrapolated further, where a pixel
        // lingers for many refreshes on a slow scene, only misplaces them (the
        // kitchen's Interactive at 166–194 ms ahead, RMS 51.04–53.69 against
        // 46.99–50.76 traced where it is).
        self.s.view_ahead.build_led_by(at.shown - t);
        Some(Built {
            image,
            mean_age,
            overlays: None,
            ages: super::shared::sampled_ages(n, |i| (t - self.newest.info_time(i)) as f32),
            // Each pixel is seen from the camera of its own sample.
            view_time: f64::NAN,
        })
    }
}

/// Samples a refresh brings from which a build with a GPU tracer runs on every core:
/// below it (a software GPU driver, which traces on the same cores), the threads'
/// start costs more than they save (640×480 on lavapipe: 4.0 ms a build on 2 threads,
/// 0.9 on one).
const EVERY_CORE_FROM: usize = 1 << 16;

/// A copy of `image`, made on every thread (25 MB at 1920×1080 at every refresh).
fn copy_image(image: &Image) -> Image {
    use rayon::prelude::*;
    let mut pixels = Vec::new();
    image
        .pixels
        .par_iter()
        .copied()
        .collect_into_vec(&mut pixels);
    Image { pixels, ..*image }
}
