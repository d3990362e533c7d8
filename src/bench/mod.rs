//! Throughput benchmarks of the tracer (`frameless bench`).
//!
//! Rays go in random pixel order — the access pattern of a frameless sampler, which is
//! less coherent than scanline order — through a 256×256 view of the scene at its start
//! time. Each figure is the best of a few timed repetitions, to damp machine noise.

use std::{collections::BTreeMap, sync::Arc, time::Instant};

use rayon::prelude::*;
use serde::Serialize;

mod live_recon;

pub use live_recon::{live_image_ms, live_report, LiveCase, LiveFigure, LiveReport, LIVE_CASES};

use crate::{
    gpu::DeviceUsed,
    reconstruction::device::{GpuContext, ReconUsed},
    sampling::Rng,
    trace::Tracer,
};

/// Timed reconstructor refreshes at 256×256 per repetition of the ray measurements.
const RECON_REPEATS_PER_REPEAT: usize = 5;

/// Benchmark settings.
#[derive(Clone, Debug)]
pub struct BenchOptions {
    /// Rays per repetition.
    pub rays: usize,
    /// Timed repetitions (the best is reported).
    pub repeats: usize,
    /// Seed of the pixel order.
    pub seed: u64,
    /// The GPU the reconstruction figures are measured on, where the reconstructor's
    /// parameters allow it (`None`: the CPU).
    pub gpu: Option<Arc<GpuContext>>,
}

impl Default for BenchOptions {
    fn default() -> Self {
        Self {
            rays: 1 << 19,
            repeats: 3,
            seed: 1,
            gpu: None,
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
    /// One reconstructor refresh, 400K samples at 256×256, one thread, ms.
    pub reconstruct_ms_1t: f64,
    /// One reconstructor refresh, 400K samples at 256×256, all threads, ms.
    pub reconstruct_ms_all: f64,
    /// One reconstructor refresh, 6 × 512² samples at 512×512, all threads, ms.
    pub reconstruct_ms_512_all: f64,
    /// One reconstructor refresh, 6 × 1024² samples at 1024×1024, all threads, ms.
    pub reconstruct_ms_1024_all: f64,
    /// One refresh of the real-time reconstructor (history and fill) at 640×480 with
    /// half a sample per pixel, one thread, ms ([`reconstruct_realtime_ms`]).
    pub reconstruct_realtime_640_ms_1t: f64,
    /// The same at 256×256, one thread, ms.
    pub reconstruct_realtime_256_ms_1t: f64,
    /// Milliseconds of one reconstructor refresh on this scene after the adaptive sampler
    /// has run 1 s at 400K samples/s (ring of 400K real samples and the real tiling),
    /// one thread.
    pub reconstruct_scene_ms_1t: f64,
    /// The same on all threads.
    pub reconstruct_scene_ms_all: f64,
    /// Real-time adaptive's controllers against one sampling thread on this scene
    /// ([`crate::realtime::adaptive::controller_bench`], 2 s recorded from `time`), as
    /// many as the pipeline runs for `threads` cores...
    pub controllers: usize,
    /// ...samples per second they take in together when fed the recorded batches...
    pub controller_samples_per_s: f64,
    /// ...samples per second of tracing time of the one sampling thread...
    pub controller_tracing_samples_per_s_1t: f64,
    /// ...and their ratio: the sampling threads the controllers keep up with.
    pub controller_margin: f64,
    /// Where the `reconstruct_*` figures were measured: the CPU, or the GPU and its
    /// adapter (then their `1t`/`all` thread counts are the CPU side's only).
    pub recon: ReconUsed,
    /// Per `reconstruct_*` figure that could not be measured on the GPU (it is then
    /// `null`): why.
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub recon_notes: BTreeMap<&'static str, String>,
    /// Where `gpu_trace` was measured (`--trace`): the CPU (then there is no
    /// `gpu_trace`), or the GPU and its adapter. The `primary_*` and `shaded_*`
    /// figures above are the CPU tracer's either way.
    pub trace: DeviceUsed,
    /// The GPU tracer's figures, with `--trace gpu` (or `auto` on a hardware GPU).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gpu_trace: Option<GpuTraceFigures>,
}

/// The GPU tracer's figures of `frameless bench --trace gpu`: each batch is uploaded,
/// traced in one dispatch and read back, and all of that is timed.
#[derive(Clone, Debug, Serialize)]
pub struct GpuTraceFigures {
    /// Primary rays (closest hit, no shading) per second, millions.
    pub primary_mrays_per_s: f64,
    /// Fully shaded samples (shadows, reflection, refraction) per second, millions;
    /// each is one primary ray.
    pub shaded_msamples_per_s: f64,
    /// Secondary rays (shadow rays, reflections, refractions) traced per second while
    /// shading, millions.
    pub secondary_mrays_per_s: f64,
    /// Secondary rays per shaded sample.
    pub secondary_per_sample: f64,
    /// Whether the adapter is a software one (such as lavapipe): the figures are then
    /// the CPU's speed under a driver, not a GPU's.
    pub software: bool,
    /// Samples per pixel of the ideal images timed below (`settings::IDEAL_SPP`).
    pub ideal_spp: u32,
    /// Seconds of one ideal image at the bench's size on the GPU tracer
    /// (`render::still::render_gpu`), one run after the figures above.
    pub ideal_s_gpu: f64,
    /// The same image on the CPU tracer, all threads (`render::still::render`).
    pub ideal_s_cpu: f64,
    /// Where the GPU tracer's time went in the best timed call of the primary rays,
    /// of the shaded samples, and in the ideal image: uploads, the wait for the GPU,
    /// the read-back on the CPU.
    #[cfg(feature = "gpu")]
    pub split: GpuTraceSplit,
}

/// [`GpuTraceFigures::split`].
#[cfg(feature = "gpu")]
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct GpuTraceSplit {
    /// The primary rays' best call.
    pub primary: crate::trace::gpu::GpuTraceTimes,
    /// The shaded samples' best call.
    pub shaded: crate::trace::gpu::GpuTraceTimes,
    /// The ideal image.
    pub ideal: crate::trace::gpu::GpuTraceTimes,
}

/// Measure the GPU tracer on `tracer`'s scene at `time` with `opts`' rays and
/// repetitions (the best is kept, after one untimed warm-up of each).
#[cfg(feature = "gpu")]
pub fn gpu_trace_figures(
    tracer: &Tracer,
    time: f64,
    opts: &BenchOptions,
    ctx: Arc<GpuContext>,
) -> Result<GpuTraceFigures, crate::trace::gpu::GpuTraceError> {
    let software = ctx.is_software();
    let mut gpu = crate::trace::gpu::GpuTracer::new(ctx, tracer)?;
    let (w, h) = tracer.size();
    let state = tracer.state_at(time);
    let pts: Vec<[f32; 2]> = random_pixel_order(w, h, opts.rays, opts.seed)
        .into_iter()
        .map(|(x, y)| [x, y])
        .collect();
    let shaded_pts = &pts[..pts.len() / 4];
    let mut timed = |primary: bool, pts: &[[f32; 2]]| -> Result<(f64, u64, _), _> {
        let mut best = f64::INFINITY;
        let mut secondary = 0;
        let mut split = Default::default();
        for _ in 0..opts.repeats.max(1) + 1 {
            let before = gpu.times();
            let t = Instant::now();
            let got = if primary {
                gpu.primary_hits(tracer, &state, pts)?
            } else {
                gpu.trace(tracer, &state, pts)?
            };
            let s = t.elapsed().as_secs_f64();
            if s < best {
                best = s;
                split = gpu.times().since(&before);
            }
            secondary = got.iter().map(|s| s.secondary_rays as u64).sum();
        }
        Ok::<_, crate::trace::gpu::GpuTraceError>((best.max(1e-9), secondary, split))
    };
    let (primary_s, _, primary_split) = timed(true, &pts)?;
    let (shaded_s, secondary, shaded_split) = timed(false, shaded_pts)?;
    let spp = crate::settings::IDEAL_SPP;
    let before = gpu.times();
    let t = Instant::now();
    std::hint::black_box(crate::render::still::render_gpu(
        &mut gpu, tracer, time, spp, opts.seed,
    )?);
    let ideal_s_gpu = t.elapsed().as_secs_f64();
    let split = GpuTraceSplit {
        primary: primary_split,
        shaded: shaded_split,
        ideal: gpu.times().since(&before),
    };
    let t = Instant::now();
    std::hint::black_box(crate::render::still::render(
        tracer,
        time,
        spp,
        opts.seed,
        &|_| {},
    ));
    let ideal_s_cpu = t.elapsed().as_secs_f64();
    Ok(GpuTraceFigures {
        primary_mrays_per_s: pts.len() as f64 / primary_s / 1e6,
        shaded_msamples_per_s: shaded_pts.len() as f64 / shaded_s / 1e6,
        secondary_mrays_per_s: secondary as f64 / shaded_s / 1e6,
        secondary_per_sample: secondary as f64 / shaded_pts.len().max(1) as f64,
        software,
        ideal_spp: spp,
        ideal_s_gpu,
        ideal_s_cpu,
        split,
    })
}

/// A reconstructor at `width × height` with a full ring of `n` synthetic samples:
/// random positions over the view of the `reconstruct_bench` camera, hit points at
/// random depths, slow random velocities, random colors, traced at rate `n` per second
/// over the second before time 1; and a tiling split evenly into tiles of about 256
/// pixels, each with its own synthetic gradients (`|G_x| = 0.05·g`, `|G_y| = 0.05·(1 − g)`
/// per pixel, `|G_t|` up to 0.5 per second, `g` uniform: the range of the gradients the
/// sampler measures on `toycar`). Returns the reconstructor, camera and tiling.
///
/// Its work per refresh (about 130K samples within the temporal cutoff, footprints of
/// 31 pixels on average) is somewhat above that of real runs at 400K samples/s
/// (`examples/recon_probe` prints these statistics for the fixture and for scenes).
pub fn reconstruct_fixture(
    width: u32,
    height: u32,
    n: usize,
    seed: u64,
) -> (
    crate::reconstruction::Reconstructor,
    crate::scene::CameraFrame,
    crate::tiles::TilingSnapshot,
) {
    reconstruct_fixture_with(
        width,
        height,
        n,
        seed,
        crate::reconstruction::ReconParams::paper(),
    )
}

/// [`reconstruct_fixture`] with other reconstructor parameters (its ring still holds
/// exactly the `n` samples).
pub fn reconstruct_fixture_with(
    width: u32,
    height: u32,
    n: usize,
    seed: u64,
    params: crate::reconstruction::ReconParams,
) -> (
    crate::reconstruction::Reconstructor,
    crate::scene::CameraFrame,
    crate::tiles::TilingSnapshot,
) {
    use crate::{
        reconstruction::{ReconParams, Reconstructor, RingSample},
        scene::Camera,
    };
    use glam::Vec3;
    let camera = Camera {
        eye: Vec3::new(0.0, 0.0, 5.0),
        at: Vec3::ZERO,
        up: Vec3::Y,
        fov_y_deg: 60.0,
        hither: 1e-3,
    }
    .frame(width, height);
    let rate = n as f64;
    let mut rng = Rng::new(&[seed, 0x7ec0]);
    let mut r = Reconstructor::new(
        width,
        height,
        rate,
        ReconParams {
            ring_factor: n as f64 / (width as f64 * height as f64),
            ..params
        },
    );
    for i in 0..n {
        let x = rng.uniform() * width as f32;
        let y = rng.uniform() * height as f32;
        let depth = 2.0 + 6.0 * rng.uniform();
        let v = Vec3::new(rng.uniform() - 0.5, rng.uniform() - 0.5, 0.0) * 0.2;
        r.push(RingSample {
            x,
            y,
            t: i as f64 / rate,
            color: Vec3::new(rng.uniform(), rng.uniform(), rng.uniform()),
            hit_point: camera.eye + camera.direction(x, y) * depth,
            velocity: v,
            anchor: Default::default(),
        });
    }
    let tiling = fixture_tiling(width, height, &mut rng);
    (r, camera, tiling)
}

/// The bench fixture's tiling with its own random stream (seed `seed`).
pub fn synthetic_tiling(width: u32, height: u32, seed: u64) -> crate::tiles::TilingSnapshot {
    fixture_tiling(width, height, &mut Rng::new(&[seed, 0x711e]))
}

/// A tiling of `width × height` split evenly into tiles of about 256 pixels, each with
/// its own synthetic gradients drawn from `rng` (see [`reconstruct_fixture`]).
fn fixture_tiling(width: u32, height: u32, rng: &mut Rng) -> crate::tiles::TilingSnapshot {
    use crate::methods::adaptive::tiling::{TileStats, Tiling};
    let mut tiling = Tiling::new(width, height);
    let target = ((width * height) / 256).max(1) as usize;
    // Split the largest tile first, so that tiles are all about the same size.
    while tiling.len() < target {
        let leaf = *tiling
            .leaves()
            .iter()
            .rev()
            .max_by_key(|&&l| tiling.node(l).rect.area())
            .expect("a tiling has a tile");
        if !tiling.splittable(leaf, 4) {
            break;
        }
        tiling.split(leaf, |_| TileStats::default());
    }
    // Each tile gets its own gradients. (`split` gives the second child the parent's
    // statistics minus the first's, so statistics passed to `split` would leave most
    // tiles with none, i.e. the isotropic filter `∛V_s` of a flat static region.)
    let leaves = tiling.leaves().to_vec();
    for leaf in leaves {
        let g = rng.uniform() as f64;
        tiling.node_mut(leaf).stats = TileStats {
            wc: 1.0,
            wgx: 0.05 * g,
            wgy: 0.05 * (1.0 - g),
            wgt: 0.5 * rng.uniform() as f64,
            ..TileStats::default()
        };
    }
    tiling.snapshot()
}

/// Milliseconds of one reconstructor refresh on the [`reconstruct_fixture`] (best of
/// `repeats`, after `warmup` refreshes that settle the splat scale map).
pub fn reconstruct_ms(width: u32, height: u32, n: usize, warmup: usize, repeats: usize) -> f64 {
    reconstruct_ms_on(None, width, height, n, warmup, repeats).unwrap_or(f64::NAN)
}

/// Why a reconstruction figure could not be measured on the GPU.
#[derive(Debug, thiserror::Error)]
pub enum Unmeasured {
    /// The reconstructor could not take its refreshes to the GPU (a step of its
    /// parameters it lacks, a buffer over the adapter's limits).
    #[error(transparent)]
    Gpu(#[from] crate::reconstruction::device::GpuError),
    /// The GPU reconstructor failed during the measurement; the time is partly the CPU's.
    #[error("the GPU reconstructor failed: {0}")]
    Failed(String),
    /// The adaptive method could not be built on it.
    #[error(transparent)]
    Method(#[from] crate::methods::MethodError),
}

/// [`reconstruct_ms`] on `gpu` where one is given; the error says why the GPU
/// reconstructor could not measure it.
pub fn reconstruct_ms_on(
    gpu: Option<&Arc<GpuContext>>,
    width: u32,
    height: u32,
    n: usize,
    warmup: usize,
    repeats: usize,
) -> Result<f64, Unmeasured> {
    let (mut r, camera, tiling) = reconstruct_fixture(width, height, n, 1);
    use_gpu(&mut r, gpu)?;
    let ms = best_refresh_ms(&mut r, &camera, &tiling, warmup, repeats);
    on_gpu_throughout(&r, ms)
}

/// Hand `r`'s refreshes to `gpu`, if one is given.
fn use_gpu(
    r: &mut crate::reconstruction::Reconstructor,
    gpu: Option<&Arc<GpuContext>>,
) -> Result<(), Unmeasured> {
    match gpu {
        Some(g) => Ok(r.use_gpu(g.clone())?),
        None => Ok(()),
    }
}

/// `ms`, unless `r`'s GPU side failed on the way (the time is then partly the CPU's).
fn on_gpu_throughout(r: &crate::reconstruction::Reconstructor, ms: f64) -> Result<f64, Unmeasured> {
    match r.gpu_failure() {
        Some(why) => Err(Unmeasured::Failed(why.to_string())),
        None => Ok(ms),
    }
}

/// Milliseconds of one refresh of a [`reconstruct_fixture`] at time 1 (best of
/// `repeats`, after `warmup` refreshes).
fn best_refresh_ms(
    r: &mut crate::reconstruction::Reconstructor,
    camera: &crate::scene::CameraFrame,
    tiling: &crate::tiles::TilingSnapshot,
    warmup: usize,
    repeats: usize,
) -> f64 {
    let t = 1.0;
    for _ in 0..warmup {
        r.reconstruct(t, camera, tiling);
    }
    let mut best = f64::INFINITY;
    for _ in 0..repeats.max(1) {
        let t0 = Instant::now();
        std::hint::black_box(r.reconstruct(t, camera, tiling));
        best = best.min(t0.elapsed().as_secs_f64());
    }
    best * 1e3
}

/// Milliseconds of one refresh of the real-time reconstructor's parameters (the
/// still-region history and the pull-push fill, [`ReconParams::realtime`]) on the
/// [`reconstruct_fixture`] at `width × height` with half a sample per pixel, the
/// fewest an image budget lets the real-time image builder place: the work that does
/// not shrink with the samples (resolve, fill, history blend) at its largest share.
/// The history gathers the fixture's samples at the first refresh (best of `repeats`
/// after `warmup`).
///
/// [`ReconParams::realtime`]: crate::reconstruction::ReconParams::realtime
pub fn reconstruct_realtime_ms(width: u32, height: u32, warmup: usize, repeats: usize) -> f64 {
    reconstruct_realtime_ms_on(None, width, height, warmup, repeats).unwrap_or(f64::NAN)
}

/// [`reconstruct_realtime_ms`] on `gpu` where one is given; the error says why the
/// GPU reconstructor could not measure it (it may lack a step of these parameters).
pub fn reconstruct_realtime_ms_on(
    gpu: Option<&Arc<GpuContext>>,
    width: u32,
    height: u32,
    warmup: usize,
    repeats: usize,
) -> Result<f64, Unmeasured> {
    let n = (width as usize * height as usize).div_ceil(2);
    let params = crate::reconstruction::ReconParams::realtime();
    let (mut r, camera, tiling) = reconstruct_fixture_with(width, height, n, 1, params);
    use_gpu(&mut r, gpu)?;
    r.set_view_since(0.0);
    let ms = best_refresh_ms(&mut r, &camera, &tiling, warmup.max(1), repeats);
    on_gpu_throughout(&r, ms)
}

/// Milliseconds of one refresh of the `adaptive` method's reconstructor on `tracer`'s
/// scene after its sampler ran for 1 s at 400K samples/s from `time` (best of
/// `repeats`; nothing new is sampled during the timed refreshes).
pub fn reconstruct_scene_ms(tracer: &std::sync::Arc<Tracer>, time: f64, repeats: usize) -> f64 {
    reconstruct_scene_ms_on(None, tracer, time, repeats).unwrap_or(f64::NAN)
}

/// [`reconstruct_scene_ms`] on `gpu` where one is given; the error says why it could
/// not be measured.
pub fn reconstruct_scene_ms_on(
    gpu: Option<&Arc<GpuContext>>,
    tracer: &std::sync::Arc<Tracer>,
    time: f64,
    repeats: usize,
) -> Result<f64, Unmeasured> {
    use crate::methods::Method;
    let (mut m, end) = adaptive_after_one_second_on(gpu, tracer, time)?;
    let mut best = f64::INFINITY;
    for _ in 0..repeats.max(1) {
        let t0 = Instant::now();
        std::hint::black_box(m.display(end).mean_age);
        best = best.min(t0.elapsed().as_secs_f64());
    }
    on_gpu_throughout(m.reconstructor(), best * 1e3)
}

/// The `adaptive` method (paper parameters, seed 1) on `tracer`'s scene after its
/// sampler ran for 1 s at 400K samples/s from `time`, with one image displayed at the
/// end of that second; returns it and that time.
pub fn adaptive_after_one_second(
    tracer: &std::sync::Arc<Tracer>,
    time: f64,
) -> Result<(crate::methods::adaptive::Adaptive, f64), crate::methods::MethodError> {
    adaptive_after_one_second_on(None, tracer, time)
}

/// [`adaptive_after_one_second`], its reconstructor on `gpu` where one is given.
pub fn adaptive_after_one_second_on(
    gpu: Option<&Arc<GpuContext>>,
    tracer: &std::sync::Arc<Tracer>,
    time: f64,
) -> Result<(crate::methods::adaptive::Adaptive, f64), crate::methods::MethodError> {
    use crate::methods::{adaptive, Method, MethodContext};
    let ctx = MethodContext {
        tracer: tracer.clone(),
        clock: crate::clock::Clock {
            start: time,
            rate: 400_000.0,
            first_refresh: time,
            refresh_hz: 60.0,
        },
        seed: 1,
        ideal_spp: 1,
        ideal_cache: None,
        gpu: gpu.cloned(),
        rays: None,
    };
    let mut m = adaptive::Adaptive::new(&ctx, adaptive::SamplerParams::paper())?;
    let end = time + 1.0;
    m.display(end);
    Ok((m, end))
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

/// Primary rays and shaded samples per second of `tracer` at `time` on one thread and
/// on all: `[primary 1t, primary all, shaded 1t, shaded all]`.
fn tracer_rates(
    tracer: &Tracer,
    time: f64,
    opts: &BenchOptions,
    one: &rayon::ThreadPool,
) -> [f64; 4] {
    let (w, h) = tracer.size();
    let state = tracer.state_at(time);
    let pts = random_pixel_order(w, h, opts.rays, opts.seed);
    let shaded_pts = &pts[..pts.len() / 4];
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
    [p1, pa, s1, sa]
}

/// Measure the tracer. `load_s` and `build_s` are passed through to the report.
pub fn run(
    tracer: &std::sync::Arc<Tracer>,
    time: f64,
    opts: BenchOptions,
    load_s: f64,
    build_s: f64,
) -> BenchReport {
    let (w, h) = tracer.size();
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("one-thread pool");
    let [p1, pa, s1, sa] = tracer_rates(tracer, time, &opts, &one);
    let recon = recon_figures(tracer, time, &opts, &one);
    let ctrl = controller_throughput(tracer, time);
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
        reconstruct_ms_1t: recon.ms_1t,
        reconstruct_ms_all: recon.ms_all,
        reconstruct_ms_512_all: recon.ms_512_all,
        reconstruct_ms_1024_all: recon.ms_1024_all,
        reconstruct_realtime_640_ms_1t: recon.realtime_640_ms_1t,
        reconstruct_realtime_256_ms_1t: recon.realtime_256_ms_1t,
        reconstruct_scene_ms_1t: recon.scene_ms_1t,
        reconstruct_scene_ms_all: recon.scene_ms_all,
        controllers: ctrl.map_or(0, |c| c.controllers),
        controller_samples_per_s: ctrl.map_or(f64::NAN, |c| c.controller_samples_per_s),
        controller_tracing_samples_per_s_1t: ctrl.map_or(f64::NAN, |c| c.tracing_samples_per_s),
        controller_margin: ctrl.map_or(f64::NAN, |c| c.margin()),
        recon: opts.gpu.as_ref().map_or_else(ReconUsed::cpu, |g| g.used()),
        recon_notes: recon.notes,
        trace: DeviceUsed::cpu(),
        gpu_trace: None,
    }
}

/// The `reconstruct_*` figures of a [`BenchReport`], and why any is missing.
struct ReconFigures {
    ms_1t: f64,
    ms_all: f64,
    ms_512_all: f64,
    ms_1024_all: f64,
    realtime_640_ms_1t: f64,
    realtime_256_ms_1t: f64,
    scene_ms_1t: f64,
    scene_ms_all: f64,
    notes: BTreeMap<&'static str, String>,
}

/// Time the reconstructor on the fixtures and on `tracer`'s scene, on `opts.gpu` where
/// one is given; a figure the GPU reconstructor cannot measure is NaN (`null` in the
/// JSON) with a note saying why. `one` is a pool of one thread.
fn recon_figures(
    tracer: &Arc<Tracer>,
    time: f64,
    opts: &BenchOptions,
    one: &rayon::ThreadPool,
) -> ReconFigures {
    let gpu = opts.gpu.as_ref();
    let mut notes = BTreeMap::new();
    let mut figure = |name: &'static str, measured: Result<f64, Unmeasured>| {
        measured.unwrap_or_else(|why| {
            notes.insert(name, why.to_string());
            f64::NAN
        })
    };
    // A refresh takes tens of milliseconds and these machines' speed varies from one
    // second to the next: the best of several times the rays' repetitions.
    let rr = RECON_REPEATS_PER_REPEAT * opts.repeats;
    let fixture = |w, n, warmup, repeats| reconstruct_ms_on(gpu, w, w, n, warmup, repeats);
    let ms_1t = figure(
        "reconstruct_ms_1t",
        one.install(|| fixture(256, 400_000, 2, rr)),
    );
    let ms_all = figure("reconstruct_ms_all", fixture(256, 400_000, 2, rr));
    let ms_512_all = figure("reconstruct_ms_512_all", fixture(512, 6 * 512 * 512, 1, 2));
    let ms_1024_all = figure(
        "reconstruct_ms_1024_all",
        fixture(1024, 6 * 1024 * 1024, 1, 1),
    );
    let realtime_640_ms_1t = figure(
        "reconstruct_realtime_640_ms_1t",
        one.install(|| reconstruct_realtime_ms_on(gpu, 640, 480, 2, rr)),
    );
    let realtime_256_ms_1t = figure(
        "reconstruct_realtime_256_ms_1t",
        one.install(|| reconstruct_realtime_ms_on(gpu, 256, 256, 2, rr)),
    );
    let scene = || reconstruct_scene_ms_on(gpu, tracer, time, rr);
    let scene_ms_1t = figure("reconstruct_scene_ms_1t", one.install(scene));
    let scene_ms_all = figure("reconstruct_scene_ms_all", scene());
    ReconFigures {
        ms_1t,
        ms_all,
        ms_512_all,
        ms_1024_all,
        realtime_640_ms_1t,
        realtime_256_ms_1t,
        scene_ms_1t,
        scene_ms_all,
        notes,
    }
}

/// Real-time adaptive's controllers on `tracer`'s scene from `time`, as many as its
/// pipeline runs on as many cores as the current thread pool has threads
/// ([`crate::realtime::adaptive::controller_bench`]; `None` if it could not start).
pub fn controller_throughput(
    tracer: &std::sync::Arc<Tracer>,
    time: f64,
) -> Option<crate::realtime::adaptive::ControllerBench> {
    use crate::realtime::{adaptive, RtConfig, RtMethod};
    let mut config = RtConfig::for_cores(RtMethod::Adaptive, rayon::current_num_threads());
    config.start = time;
    let settings = adaptive::AdaptiveSettings::default();
    adaptive::controller_bench(tracer.clone(), config, settings, CONTROLLER_RECORD_S).ok()
}

/// Wall seconds of sampling the controller bench records.
const CONTROLLER_RECORD_S: f64 = 2.0;
