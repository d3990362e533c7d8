//! Gold-standard evaluation (paper §7, SPEC §6): every method runs on the same scene,
//! display and sample budget under a simulated clock; at every refresh its displayed
//! image is compared with the ideal image of that instant.

pub mod metrics;
pub mod report;
pub mod table1;

use std::{path::PathBuf, sync::Arc, time::Instant};

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::{
    clock::Clock,
    methods::{ideal::ideal_image, MethodContext, MethodKind},
    render::cache::IdealCache,
    scene::{CameraPath, Scene},
    trace::{TraceOptions, Tracer},
};

/// Settings of one evaluation run.
#[derive(Clone, Debug)]
pub struct EvalConfig {
    /// How the user named the scene (for reports).
    pub scene_name: String,
    /// Camera path overriding the scene camera.
    pub camera_path: Option<CameraPath>,
    /// First evaluated refresh, seconds of scene time.
    pub start: f64,
    /// Length of the evaluated window, seconds.
    pub duration: f64,
    /// Display width.
    pub width: u32,
    /// Display height.
    pub height: u32,
    /// Sample budgets to evaluate, samples per second.
    pub rates: Vec<f64>,
    /// Methods to evaluate.
    pub methods: Vec<MethodKind>,
    /// Seed of every random choice.
    pub seed: u64,
    /// Samples per pixel of the ideal images (≥ 16 for the paper's protocol).
    pub ideal_spp: u32,
    /// Seconds every method runs before the first evaluated refresh.
    pub warmup: f64,
    /// Display refresh rate, Hz.
    pub refresh_hz: f64,
    /// Reflection/refraction depth limit.
    pub max_depth: u32,
    /// Ideal-image cache directory (`None`: no cache).
    pub cache_dir: Option<PathBuf>,
    /// Frames at which image strips are saved (indices into the window).
    pub strip_frames: Vec<usize>,
    /// FLIP is computed on every n-th frame (it costs more than tracing a frame at the
    /// paper's rates); RMS and PSNR on every frame.
    pub flip_every: usize,
}

impl EvalConfig {
    /// Number of evaluated refreshes.
    pub fn frames(&self) -> usize {
        ((self.duration * self.refresh_hz) + 1e-9).floor().max(1.0) as usize
    }

    /// Check the settings; the error says what is wrong and how to fix it.
    pub fn validate(&self) -> Result<(), String> {
        let finite_pos = |v: f64| v.is_finite() && v > 0.0;
        if !self.start.is_finite() {
            return Err("--start must be a finite number".into());
        }
        if !finite_pos(self.duration) || self.duration > 3600.0 {
            return Err(format!(
                "--duration {} must be in (0, 3600] seconds",
                self.duration
            ));
        }
        if !(self.warmup.is_finite() && self.warmup >= 0.0) {
            return Err(format!("--warmup {} must be ≥ 0", self.warmup));
        }
        if !finite_pos(self.refresh_hz) {
            return Err("refresh rate must be positive".into());
        }
        if self.rates.is_empty() {
            return Err("no rates given".into());
        }
        if self.methods.is_empty() {
            return Err("no methods given".into());
        }
        if self.flip_every == 0 {
            return Err("--flip-every must be at least 1".into());
        }
        if self.ideal_spp == 0 {
            return Err("--ideal-spp must be at least 1".into());
        }
        let pixels = self.width as f64 * self.height as f64;
        for &r in &self.rates {
            if !finite_pos(r) {
                return Err(format!(
                    "rate {r} must be a positive number of samples per second"
                ));
            }
            if r > 1e10 {
                return Err(format!("rate {r} is absurd (more than 1e10 samples/s)"));
            }
            for m in &self.methods {
                match m {
                    MethodKind::FramedFull if pixels / r > self.warmup + self.duration => {
                        return Err(format!(
                            "rate {} is too low for framed-full: one {}x{} frame takes {:.2} s, longer than warm-up + duration ({:.2} s)",
                            report::rate_label(r), self.width, self.height, pixels / r, self.warmup + self.duration
                        ));
                    }
                    MethodKind::PointTracking | MethodKind::PointTrackingNoBlend
                        if pixels / r > self.warmup + self.duration =>
                    {
                        return Err(format!(
                            "rate {} is too low for point tracking: one {}x{} frame takes {:.2} s, longer than warm-up + duration ({:.2} s)",
                            report::rate_label(r), self.width, self.height, pixels / r, self.warmup + self.duration
                        ));
                    }
                    MethodKind::Framed60Hz | MethodKind::Taa if r < 60.0 => {
                        return Err(format!("rate {r} is too low for framed-60hz: it needs at least 60 samples/s (one per frame)"));
                    }
                    _ => {}
                }
            }
        }
        Ok(())
    }
}

/// One displayed frame's measurements.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct FrameRow {
    /// Method name.
    pub method: String,
    /// Requested sample rate (the table column).
    pub rate: f64,
    /// Frame index in the window.
    pub frame: usize,
    /// Display time, seconds.
    pub time: f64,
    /// RMS error, 0–255 units.
    pub rms: f64,
    /// PSNR, dB.
    pub psnr: f64,
    /// Mean FLIP error (`None` on frames where it was not computed).
    pub flip: Option<f64>,
    /// Temporal instability: mean absolute difference, in 0–255 units, between the
    /// displayed image's change since the previous refresh and the ideal image's own
    /// change (`None` on the first frame). Scintillation raises it; faithfully following
    /// real change does not.
    pub flicker: Option<f64>,
    /// Mean age of the displayed information, seconds.
    pub age_s: f64,
}

/// Aggregates of one method at one rate.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct ResultRow {
    /// Method name.
    pub method: String,
    /// Requested sample rate (the table column).
    pub rate: f64,
    /// The rate the method actually used (differs for `full-res-60hz` and `ideal`).
    pub effective_rate: f64,
    /// Frames evaluated.
    pub frames: usize,
    /// Mean RMS error.
    pub rms_mean: f64,
    /// Mean PSNR.
    pub psnr_mean: f64,
    /// Mean FLIP over the frames where it was computed.
    pub flip_mean: f64,
    /// Frames whose FLIP was computed.
    pub flip_frames: usize,
    /// Mean temporal instability (see [`FrameRow::flicker`]).
    pub flicker_mean: f64,
    /// Mean information age, seconds.
    pub age_mean_s: f64,
    /// Samples traced over warm-up and window.
    pub samples: u64,
    /// Method-specific statistics (point tracking: points-per-pixel shares, cost ratio).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub extra: Option<serde_json::Value>,
}

/// Where the time of a run went.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct Timing {
    /// Rendering or loading ideal images.
    pub ideal_s: f64,
    /// Running methods (tracing and their own bookkeeping).
    pub methods_s: f64,
    /// Of `methods_s`, the time spent tracing rays.
    pub trace_s: f64,
    /// Quantizing and comparing images (RMS, PSNR, FLIP).
    pub metrics_s: f64,
    /// Writing reports, plots and strips.
    pub output_s: f64,
    /// Ideal images found in the cache.
    pub ideal_cache_hits: usize,
}

/// `summary.json`.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Summary {
    /// Scene as named by the user.
    pub scene: String,
    /// Display width.
    pub width: u32,
    /// Display height.
    pub height: u32,
    /// Refresh rate, Hz.
    pub refresh_hz: f64,
    /// First evaluated refresh.
    pub start: f64,
    /// Window length, seconds.
    pub duration: f64,
    /// Warm-up before the window, seconds.
    pub warmup: f64,
    /// Seed.
    pub seed: u64,
    /// Ideal samples per pixel.
    pub ideal_spp: u32,
    /// Camera path file contents were used (true) or the scene camera (false).
    pub camera_path: bool,
    /// Per method and rate.
    pub results: Vec<ResultRow>,
    /// Cost of the run.
    pub timing: Timing,
}

/// Everything a run produced.
pub struct EvalOutput {
    /// The summary.
    pub summary: Summary,
    /// Every frame's measurements.
    pub frames: Vec<FrameRow>,
    /// Strip images: `(rate, frame, [(method, 8-bit RGB)])`, ideal first.
    pub strips: Vec<(f64, usize, Vec<(String, Vec<u8>)>)>,
}

/// Progress reporting hooks.
pub trait Progress: Sync {
    /// Set the total number of steps.
    fn total(&self, n: u64);
    /// One step done, with a message.
    fn step(&self, msg: &str);
}

/// No progress reporting.
pub struct Silent;
impl Progress for Silent {
    fn total(&self, _: u64) {}
    fn step(&self, _: &str) {}
}

/// Run an evaluation (no files written; see [`report::write_all`]).
pub fn run(
    scene: Arc<Scene>,
    cfg: &EvalConfig,
    progress: &dyn Progress,
) -> Result<EvalOutput, String> {
    cfg.validate()?;
    let tracer = Arc::new(
        Tracer::new(
            scene,
            cfg.width,
            cfg.height,
            TraceOptions {
                max_depth: cfg.max_depth,
            },
        )
        .with_camera_path(cfg.camera_path.clone()),
    );
    let cache = match &cfg.cache_dir {
        Some(dir) => Some(Arc::new(
            IdealCache::new(dir, &tracer, cfg.camera_path.as_ref())
                .map_err(|e| format!("ideal cache {}: {e}", dir.display()))?,
        )),
        None => None,
    };
    let n = cfg.frames();
    let runs: Vec<(MethodKind, f64)> = {
        let mut v = Vec::new();
        for m in &cfg.methods {
            if m.rate_independent() {
                v.push((*m, cfg.rates[0]));
            } else {
                v.extend(cfg.rates.iter().map(|r| (*m, *r)));
            }
        }
        v
    };
    progress.total((n * (1 + runs.len())) as u64);
    let mut timing = Timing::default();
    let base_clock = |rate: f64| Clock {
        start: cfg.start - cfg.warmup,
        rate,
        first_refresh: cfg.start,
        refresh_hz: cfg.refresh_hz,
    };
    let ctx_for = |rate: f64| MethodContext {
        tracer: tracer.clone(),
        clock: base_clock(rate),
        seed: cfg.seed,
        ideal_spp: cfg.ideal_spp,
        ideal_cache: cache.clone(),
    };
    let refresh = |k: usize| cfg.start + k as f64 / cfg.refresh_hz;

    // Ideal images, as displayed.
    let t0 = Instant::now();
    let ideal_ctx = ctx_for(cfg.rates[0]);
    let mut ideal: Vec<Vec<u8>> = Vec::with_capacity(n);
    for k in 0..n {
        if cache
            .as_ref()
            .is_some_and(|c| c.contains(refresh(k), cfg.ideal_spp, cfg.seed))
        {
            timing.ideal_cache_hits += 1;
        }
        ideal.push(ideal_image(&ideal_ctx, refresh(k)).to_rgb8());
        progress.step("ideal images");
    }
    timing.ideal_s = t0.elapsed().as_secs_f64();

    let mut frames = Vec::new();
    let mut results = Vec::new();
    let mut strips: Vec<(f64, usize, Vec<(String, Vec<u8>)>)> = Vec::new();
    for rate in &cfg.rates {
        for &k in &cfg.strip_frames {
            if k < n {
                strips.push((*rate, k, vec![("ideal".to_string(), ideal[k].clone())]));
            }
        }
    }
    let (w, h) = (cfg.width, cfg.height);
    for (kind, rate) in runs {
        let ctx = ctx_for(rate);
        let mut method = kind.build(&ctx)?;
        let effective_rate = match kind {
            MethodKind::FullRes60Hz => w as f64 * h as f64 * 60.0,
            MethodKind::Ideal => w as f64 * h as f64 * cfg.ideal_spp as f64 * cfg.refresh_hz,
            _ => rate,
        };
        let budget_clock = base_clock(effective_rate);
        let mut shown: Vec<(Vec<u8>, f64)> = Vec::with_capacity(n);
        let tm = Instant::now();
        for k in 0..n {
            let t = refresh(k);
            let d = method.display(t);
            shown.push((d.image.to_rgb8(), d.mean_age));
            if kind != MethodKind::Ideal && method.samples_used() > budget_clock.samples_until(t) {
                return Err(format!(
                    "internal error: {} used {} samples by t = {t}, budget {}",
                    kind.name(),
                    method.samples_used(),
                    budget_clock.samples_until(t)
                ));
            }
            progress.step(kind.name());
        }
        timing.methods_s += tm.elapsed().as_secs_f64();
        timing.trace_s += method.trace_seconds();
        let tq = Instant::now();
        let metrics: Vec<(f64, Option<f64>, Option<f64>)> = shown
            .par_iter()
            .zip(ideal.par_iter())
            .enumerate()
            .map(|(k, ((rgb, _), id))| {
                let flip = (k % cfg.flip_every == 0).then(|| metrics::flip_mean(id, rgb, w, h));
                let flicker =
                    (k > 0).then(|| metrics::flicker(&shown[k - 1].0, rgb, &ideal[k - 1], id));
                (metrics::rms(id, rgb), flip, flicker)
            })
            .collect();
        timing.metrics_s += tq.elapsed().as_secs_f64();
        let rows_for: Vec<f64> = if kind.rate_independent() {
            cfg.rates.clone()
        } else {
            vec![rate]
        };
        for r in rows_for {
            let mut rows = Vec::with_capacity(n);
            for (k, ((_, age), (rms, flip, flicker))) in shown.iter().zip(&metrics).enumerate() {
                rows.push(FrameRow {
                    method: kind.name().into(),
                    rate: r,
                    frame: k,
                    time: refresh(k),
                    rms: *rms,
                    psnr: metrics::psnr(*rms),
                    flip: *flip,
                    flicker: *flicker,
                    age_s: *age,
                });
            }
            let mean =
                |f: fn(&FrameRow) -> f64| rows.iter().map(f).sum::<f64>() / rows.len() as f64;
            let flips: Vec<f64> = rows.iter().filter_map(|r| r.flip).collect();
            let flickers: Vec<f64> = rows.iter().filter_map(|r| r.flicker).collect();
            results.push(ResultRow {
                method: kind.name().into(),
                rate: r,
                effective_rate,
                frames: n,
                rms_mean: mean(|r| r.rms),
                psnr_mean: mean(|r| r.psnr),
                flip_mean: flips.iter().sum::<f64>() / flips.len().max(1) as f64,
                flip_frames: flips.len(),
                flicker_mean: flickers.iter().sum::<f64>() / flickers.len().max(1) as f64,
                age_mean_s: mean(|r| r.age_s),
                samples: method.samples_used(),
                extra: method.extra_stats(),
            });
            for (sr, k, list) in strips.iter_mut() {
                if *sr == r {
                    list.push((kind.name().into(), shown[*k].0.clone()));
                }
            }
            frames.extend(rows);
        }
    }
    let summary = Summary {
        scene: cfg.scene_name.clone(),
        width: w,
        height: h,
        refresh_hz: cfg.refresh_hz,
        start: cfg.start,
        duration: cfg.duration,
        warmup: cfg.warmup,
        seed: cfg.seed,
        ideal_spp: cfg.ideal_spp,
        camera_path: cfg.camera_path.is_some(),
        results,
        timing,
    };
    Ok(EvalOutput {
        summary,
        frames,
        strips,
    })
}

/// Share of the methods' evaluation time (running methods, metrics, output) not spent
/// tracing rays; ideal images are excluded (they are cached across runs).
pub fn overhead_fraction(t: &Timing) -> f64 {
    let total = t.methods_s + t.metrics_s + t.output_s;
    if total <= 0.0 {
        return 0.0;
    }
    ((total - t.trace_s) / total).max(0.0)
}
