//! The reconstructor's cost per image at live sample rates: a stream of new samples
//! between refreshes, as the real-time image thread feeds it, with the camera turning
//! so that every refresh moves what it carries.

use std::time::Instant;

use glam::Vec3;
use serde::Serialize;

use crate::{
    realtime::machine::process_cpu_seconds,
    reconstruction::{
        device::{GpuContext, GpuError, ReconUsed},
        PassTimes, ReconParams, Reconstructor, RingSample,
    },
    sampling::Rng,
    scene::{Camera, CameraFrame},
};

/// A display size with the sample rate and refresh rate it is measured at.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct LiveCase {
    /// Display width.
    pub width: u32,
    /// Display height.
    pub height: u32,
    /// Samples per second: about what traditional frameless traces at this size on
    /// this project's 2-core machine (docs/results/live), the most a live image
    /// thread is fed there.
    pub rate: f64,
    /// Images per second.
    pub refresh_hz: f64,
}

/// The sizes `frameless bench` measures: the live cases' sizes and rates, and 1080p.
pub const LIVE_CASES: [LiveCase; 4] = [
    LiveCase {
        width: 256,
        height: 256,
        rate: 1.0e6,
        refresh_hz: 60.0,
    },
    LiveCase {
        width: 640,
        height: 480,
        rate: 3.0e6,
        refresh_hz: 30.0,
    },
    LiveCase {
        width: 1280,
        height: 720,
        rate: 4.0e6,
        refresh_hz: 30.0,
    },
    LiveCase {
        width: 1920,
        height: 1080,
        rate: 4.0e6,
        refresh_hz: 30.0,
    },
];

/// One measured case.
#[derive(Clone, Debug, Serialize)]
pub struct LiveFigure {
    /// Size and rates.
    #[serde(flatten)]
    pub case: LiveCase,
    /// Ring capacity, samples per pixel.
    pub ring_spp: f64,
    /// New samples per image.
    pub new_per_image: usize,
    /// Samples the reconstructor placed per timed image (mean).
    pub placed_per_image: f64,
    /// Median milliseconds of one image over the timed refreshes.
    pub ms_median: f64,
    /// Median milliseconds of taking a refresh's new samples in (`Reconstructor::push`,
    /// one at a time, as the real-time image thread does before it builds), not part
    /// of `ms_median`.
    pub take_in_ms_median: f64,
    /// Mean CPU milliseconds of one timed image over the whole process: every thread's
    /// (the reconstructor's pool and, on a GPU, its driver's; a software adapter's
    /// include the GPU's own work). Against `ms_median` it says how much of a GPU
    /// image's time is CPU work and how much waiting. `None` where the system does not
    /// say (not Linux).
    pub cpu_ms_mean: Option<f64>,
    /// Whether the camera turned between images (every carried pixel moves).
    pub turning: bool,
    /// Where the refreshes ran: the CPU, or the GPU adapter in words (on a GPU the
    /// filters, the carry and the history's plan still run on the CPU; `pass_ms`
    /// says how long each part took).
    pub recon: ReconUsed,
    /// Mean milliseconds of each step of a timed image, by name.
    pub pass_ms: Vec<(&'static str, f64)>,
    /// FNV-1a hash of the last image's pixel bits, with the splat scales for the next
    /// refresh and the history's counts, then `/` and the hash of its pixel ages: two
    /// builds that make the same images (and the same state behind them) print the
    /// same first hash; the ages are figures beside the image, not part of it.
    pub image_hash: String,
}

/// FNV-1a over the bits of every pixel's channels, then of its splat scale and
/// history count; and FNV-1a over the bits of the pixel ages.
fn state_hash(r: &mut Reconstructor) -> String {
    let fnv = |values: &mut dyn Iterator<Item = f32>| {
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        for c in values {
            for b in c.to_bits().to_le_bytes() {
                h = (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3);
            }
        }
        h
    };
    let scale = r.splat_scale().to_vec();
    let pixels = r.image().pixels.iter().flat_map(|p| p.to_array());
    let counts = r.history_counts().unwrap_or(&[]);
    let image = fnv(&mut pixels.chain(scale).chain(counts.iter().copied()));
    let ages = fnv(&mut r.pixel_ages().iter().copied());
    format!("{image:016x}/{ages:08x}", ages = ages as u32)
}

/// Yaw per second of the bench camera, radians: about a quarter of a pixel per
/// refresh at 640×480 and 30 Hz, so every carried pixel moves.
const YAW_PER_S: f32 = 0.03;

/// The bench camera at time `t`: looking at a plane from 5 units, turning slowly if
/// `turning`.
fn camera_at(t: f64, width: u32, height: u32, turning: bool) -> CameraFrame {
    let a = if turning { YAW_PER_S * t as f32 } else { 0.0 };
    Camera {
        eye: Vec3::new(0.0, 0.0, 5.0),
        at: Vec3::new(5.0 * a.sin(), 0.0, 5.0 - 5.0 * a.cos()),
        up: Vec3::Y,
        fov_y_deg: 60.0,
        hither: 1e-3,
    }
    .frame(width, height)
}

/// Where the bench ray through `(x, y)` of `cam` meets the tilted plane `z = 0.2·x`.
fn plane_hit(cam: &CameraFrame, x: f32, y: f32) -> Vec3 {
    let d = cam.direction(x, y);
    let n = Vec3::new(-0.2, 0.0, 1.0);
    let s = -cam.eye.dot(n) / d.dot(n);
    cam.eye + d * s.max(0.1)
}

/// The `per` samples traced during refresh period `i` of `case` into `batch`, evenly in
/// time, at random pixels of the bench camera's plane.
fn traced_during(
    i: usize,
    per: usize,
    case: LiveCase,
    turning: bool,
    rng: &mut Rng,
    batch: &mut Vec<RingSample>,
) {
    let (w, h) = (case.width, case.height);
    batch.clear();
    for k in 0..per {
        let t = (i as f64 + (k + 1) as f64 / per as f64) / case.refresh_hz;
        let cam = camera_at(t, w, h, turning);
        let (x, y) = (rng.uniform() * w as f32, rng.uniform() * h as f32);
        batch.push(RingSample {
            x,
            y,
            t,
            color: Vec3::new(rng.uniform(), rng.uniform(), rng.uniform()),
            hit_point: plane_hit(&cam, x, y),
            velocity: Vec3::ZERO,
            anchor: Default::default(),
        });
    }
}

/// Milliseconds per image of `params`' reconstructor at `case`, its ring holding
/// `ring_spp` samples per pixel: one second of refreshes to warm up (filling the ring),
/// then `images` timed refreshes, each after the samples traced since the previous
/// one were pushed (pushing timed apart), the camera turning if `turning`. The tiling
/// is the bench fixture's. With `gpu`, the refreshes run on that GPU (the CPU's parts on
/// the calling thread's pool); an error if it cannot take this size, or if a refresh
/// failed on it (a figure partly measured on the CPU would not be the GPU's).
pub fn live_image_ms(
    case: LiveCase,
    ring_spp: f64,
    params: ReconParams,
    images: usize,
    turning: bool,
    gpu: Option<std::sync::Arc<GpuContext>>,
) -> Result<LiveFigure, GpuError> {
    let (w, h) = (case.width, case.height);
    let mut r = Reconstructor::new(
        w,
        h,
        case.rate,
        ReconParams {
            ring_factor: ring_spp,
            ..params
        },
    );
    if let Some(ctx) = gpu {
        r.use_gpu(ctx)?;
    }
    let tiling = super::synthetic_tiling(w, h, 1);
    let mut rng = Rng::new(&[2, 0x11fe]);
    let per = (case.rate / case.refresh_hz).round() as usize;
    let warm = case.refresh_hz.ceil() as usize;
    let mut times = Vec::with_capacity(images);
    let mut take_in = Vec::with_capacity(images);
    let mut batch = Vec::new();
    let mut placed = 0usize;
    let mut warm_passes = PassTimes::default();
    let mut cpu_s = Some(0.0);
    for i in 0..warm + images.max(1) {
        let t1 = (i + 1) as f64 / case.refresh_hz;
        traced_during(i, per, case, turning, &mut rng, &mut batch);
        let t0 = Instant::now();
        r.push_all(&batch);
        if i >= warm {
            take_in.push(t0.elapsed().as_secs_f64() * 1e3);
        }
        let cam = camera_at(t1, w, h, turning);
        if i == warm {
            warm_passes = r.pass_times().clone();
        }
        let (t0, cpu0) = (Instant::now(), process_cpu_seconds());
        std::hint::black_box(r.reconstruct(t1, &cam, &tiling));
        if i >= warm {
            times.push(t0.elapsed().as_secs_f64() * 1e3);
            placed += r.placed();
            let used = cpu0.zip(process_cpu_seconds()).map(|(a, b)| b - a);
            cpu_s = cpu_s.zip(used).map(|(s, u)| s + u);
        }
    }
    #[cfg(feature = "gpu")]
    if let Some(why) = r.gpu_failure() {
        return Err(GpuError::Failed(format!(
            "a {w}x{h} refresh of `bench --live-recon` fell back to the CPU: {why}"
        )));
    }
    times.sort_by(f64::total_cmp);
    take_in.sort_by(f64::total_cmp);
    Ok(LiveFigure {
        case,
        ring_spp,
        new_per_image: per,
        placed_per_image: placed as f64 / times.len() as f64,
        ms_median: times[times.len() / 2],
        take_in_ms_median: take_in[take_in.len() / 2],
        cpu_ms_mean: cpu_s.map(|s| s * 1e3 / times.len() as f64),
        turning,
        recon: r.used(),
        pass_ms: r.pass_times().since(&warm_passes).mean_ms(),
        image_hash: state_hash(&mut r),
    })
}

/// What `frameless bench --live-recon` measures, on one thread, with the real-time
/// reconstructor ([`ReconParams::realtime`]): it carries its sums while the view holds
/// and re-splats the ring while the view moves, so both are measured; and, for
/// comparison, sums carried (moved) with the moving view too.
#[derive(Clone, Debug, Serialize)]
pub struct LiveReport {
    /// Each live size, the camera still (only moving things move what is carried).
    pub sizes_still: Vec<LiveFigure>,
    /// Each live size, the camera turning: the ring is re-splatted at every image.
    pub sizes_turning: Vec<LiveFigure>,
    /// Each live size, the camera turning, the sums moved with the view
    /// (`resplat_moving_view` off).
    pub sizes_turning_carried: Vec<LiveFigure>,
    /// 640×480 with the ring growing from 0.5 to 4 samples per pixel, new samples
    /// fixed, the camera still.
    pub ring_growth_still: Vec<LiveFigure>,
    /// The same, the camera turning (re-splatted).
    pub ring_growth_turning: Vec<LiveFigure>,
    /// The same, the camera turning, the sums moved with the view.
    pub ring_growth_turning_carried: Vec<LiveFigure>,
    /// On a GPU, the figures it could not measure (a buffer over the adapter's limits,
    /// a refresh that fell back to the CPU) and why: left out of the tables above,
    /// never measured on the CPU in their place.
    pub not_measured: Vec<(String, String)>,
}

impl LiveReport {
    /// Each table with its title, in the order `frameless bench` prints them.
    pub fn sections(&self) -> [(&'static str, &[LiveFigure]); 6] {
        [
            (
                "real-time reconstructor, camera still (carried), 1 thread",
                &self.sizes_still,
            ),
            ("camera turning (the ring re-splatted)", &self.sizes_turning),
            (
                "camera turning, sums moved with the view (resplat_moving_view off)",
                &self.sizes_turning_carried,
            ),
            (
                "ring growing, camera still (carried)",
                &self.ring_growth_still,
            ),
            (
                "ring growing, camera turning (re-splatted)",
                &self.ring_growth_turning,
            ),
            (
                "ring growing, camera turning, sums moved with the view",
                &self.ring_growth_turning_carried,
            ),
        ]
    }
}

/// Ring sizes of the ring-growth tables, samples per pixel.
const RING_SPPS: [f64; 4] = [0.5, 1.0, 2.0, 4.0];

/// Measure a [`LiveReport`] on a pool of one thread, `images` timed images per figure,
/// calling `progress` with a line before each figure; on `gpu` if given, where a figure
/// the GPU cannot measure is left out and listed with the reason.
pub fn live_report(
    images: usize,
    gpu: Option<std::sync::Arc<GpuContext>>,
    mut progress: impl FnMut(&str),
) -> LiveReport {
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("one-thread pool");
    let realtime = ReconParams::realtime();
    let carried = ReconParams {
        resplat_moving_view: false,
        ..realtime
    };
    let spp = realtime.ring_factor;
    let mut not_measured = Vec::new();
    let mut run = |case: LiveCase, spp: f64, p: ReconParams, turning: bool| {
        let what = format!(
            "{}x{}, ring {spp} per pixel, camera {}{}",
            case.width,
            case.height,
            if turning { "turning" } else { "still" },
            if p.resplat_moving_view {
                ""
            } else {
                ", sums moved with the view"
            },
        );
        progress(&what);
        one.install(|| live_image_ms(case, spp, p, images, turning, gpu.clone()))
            .map_err(|e| not_measured.push((what, e.to_string())))
            .ok()
    };
    // Each of `cases` with its ring, the figures the device could measure.
    let mut each = |cases: &mut dyn Iterator<Item = (LiveCase, f64)>, p, turning| {
        cases
            .filter_map(|(c, s)| run(c, s, p, turning))
            .collect::<Vec<_>>()
    };
    let sizes = || LIVE_CASES.iter().map(|&c| (c, spp));
    let growth = || RING_SPPS.iter().map(|&s| (LIVE_CASES[1], s));
    let sizes_still = each(&mut sizes(), realtime, false);
    let sizes_turning = each(&mut sizes(), realtime, true);
    let sizes_turning_carried = each(&mut sizes(), carried, true);
    let ring_growth_still = each(&mut growth(), realtime, false);
    let ring_growth_turning = each(&mut growth(), realtime, true);
    let ring_growth_turning_carried = each(&mut growth(), carried, true);
    LiveReport {
        sizes_still,
        sizes_turning,
        sizes_turning_carried,
        ring_growth_still,
        ring_growth_turning,
        ring_growth_turning_carried,
        not_measured,
    }
}
