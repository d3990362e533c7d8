//! Throughput benchmarks of the tracer (`frameless bench`).
//!
//! Rays go in random pixel order — the access pattern of a frameless sampler, which is
//! less coherent than scanline order — through a 256×256 view of the scene at its start
//! time. Each figure is the best of a few timed repetitions, to damp machine noise.

use std::time::Instant;

use rayon::prelude::*;
use serde::Serialize;

use crate::{sampling::Rng, trace::Tracer};

/// Benchmark settings.
#[derive(Clone, Copy, Debug)]
pub struct BenchOptions {
    /// Rays per repetition.
    pub rays: usize,
    /// Timed repetitions (the best is reported).
    pub repeats: usize,
    /// Seed of the pixel order.
    pub seed: u64,
}

impl Default for BenchOptions {
    fn default() -> Self {
        Self {
            rays: 1 << 19,
            repeats: 3,
            seed: 1,
        }
    }
}

/// What `frameless bench --json` prints.
#[derive(Clone, Debug, Serialize)]
pub struct BenchReport {
    /// Scene name.
    pub scene: String,
    /// View width.
    pub width: u32,
    /// View height.
    pub height: u32,
    /// Scene time of the view.
    pub time: f64,
    /// Primitives in the scene.
    pub primitives: usize,
    /// Seconds spent loading the scene (parse, textures).
    pub load_s: f64,
    /// Seconds spent building acceleration structures.
    pub build_s: f64,
    /// Worker threads used for the `_all` figures.
    pub threads: usize,
    /// Primary rays (closest hit, no shading) per second on one thread, millions.
    pub primary_mrays_per_s_1t: f64,
    /// Primary rays per second on all threads, millions.
    pub primary_mrays_per_s_all: f64,
    /// Fully shaded samples (shadows, reflection, refraction) per second, all threads.
    pub shaded_samples_per_s_all: f64,
    /// Fully shaded samples per second on one thread.
    pub shaded_samples_per_s_1t: f64,
}

/// Random sub-pixel positions in random pixel order: a shuffled permutation of all
/// pixels, repeated, each with a jitter.
pub fn random_pixel_order(width: u32, height: u32, n: usize, seed: u64) -> Vec<(f32, f32)> {
    let mut rng = Rng::new(&[seed, 0xbe4c]);
    let mut pixels: Vec<u32> = (0..width * height).collect();
    let mut out = Vec::with_capacity(n);
    while out.len() < n {
        rng.shuffle(&mut pixels);
        for &p in pixels.iter().take(n - out.len()) {
            out.push((
                (p % width) as f32 + rng.uniform(),
                (p / width) as f32 + rng.uniform(),
            ));
        }
    }
    out
}

fn best_rate(repeats: usize, n: usize, mut f: impl FnMut()) -> f64 {
    let mut best = f64::INFINITY;
    for _ in 0..repeats.max(1) {
        let t = Instant::now();
        f();
        best = best.min(t.elapsed().as_secs_f64());
    }
    n as f64 / best.max(1e-9)
}

/// Measure the tracer. `load_s` and `build_s` are passed through to the report.
pub fn run(
    tracer: &Tracer,
    time: f64,
    opts: BenchOptions,
    load_s: f64,
    build_s: f64,
) -> BenchReport {
    let (w, h) = tracer.size();
    let state = tracer.state_at(time);
    let pts = random_pixel_order(w, h, opts.rays, opts.seed);
    let shaded_pts = &pts[..pts.len() / 4];
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("one-thread pool");
    let chunk = 4096;
    let primary = |pts: &[(f32, f32)]| {
        pts.par_chunks(chunk)
            .map(|c| {
                c.iter()
                    .filter(|(x, y)| tracer.primary_hit(&state, *x, *y).is_some())
                    .count()
            })
            .sum::<usize>()
    };
    let shaded = |pts: &[(f32, f32)]| {
        pts.par_chunks(chunk / 4)
            .map(|c| {
                c.iter()
                    .map(|(x, y)| tracer.sample(&state, *x, *y).luminance)
                    .sum::<f32>()
            })
            .sum::<f32>()
    };
    let p1 = one.install(|| {
        best_rate(opts.repeats, pts.len(), || {
            std::hint::black_box(primary(&pts));
        })
    });
    let pa = best_rate(opts.repeats, pts.len(), || {
        std::hint::black_box(primary(&pts));
    });
    let s1 = one.install(|| {
        best_rate(opts.repeats, shaded_pts.len(), || {
            std::hint::black_box(shaded(shaded_pts));
        })
    });
    let sa = best_rate(opts.repeats, shaded_pts.len(), || {
        std::hint::black_box(shaded(shaded_pts));
    });
    BenchReport {
        scene: tracer.scene().name.clone(),
        width: w,
        height: h,
        time,
        primitives: tracer.scene().primitive_count(),
        load_s,
        build_s,
        threads: rayon::current_num_threads(),
        primary_mrays_per_s_1t: p1 / 1e6,
        primary_mrays_per_s_all: pa / 1e6,
        shaded_samples_per_s_all: sa,
        shaded_samples_per_s_1t: s1,
    }
}
