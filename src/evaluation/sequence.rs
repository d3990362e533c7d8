//! One method rendered as an image sequence (`frameless render`): what the display
//! shows at every refresh, as PNG files (as displayed) or OpenEXR files (linear, before
//! the display clamps and quantizes), with the run's statistics. The method is held
//! to the same rules as in an evaluation, but nothing is compared.

use std::{path::Path, sync::Arc, time::Instant};

use serde::Serialize;

use super::{EvalConfig, EvalError, Progress};
use crate::{
    image::{write_png_rgb8_fast, ImageFormat},
    methods::{Method, MethodContext, MethodKind},
    output::OutputDir,
    scene::{CameraPath, Scene},
    trace::{batch, TraceOptions, Tracer},
};

/// Most frames one sequence may have.
pub const MAX_FRAMES: u64 = 100_000;

/// Settings of one sequence.
#[derive(Clone, Debug)]
pub struct SequenceConfig {
    /// How the user named the scene (for `stats.json`).
    pub scene_name: String,
    /// Camera path overriding the scene camera.
    pub camera_path: Option<CameraPath>,
    /// The method.
    pub method: MethodKind,
    /// Sample budget, samples per second.
    pub rate: f64,
    /// First displayed refresh, seconds of scene time.
    pub start: f64,
    /// Length of the sequence, seconds.
    pub duration: f64,
    /// Sampling before the first refresh, seconds.
    pub warmup: f64,
    /// The display: size and refresh rate.
    pub display: crate::settings::DisplayGroup,
    /// How samples are traced: seed, depth, texture filter.
    pub quality: crate::settings::QualityGroup,
    /// File format of the frames.
    pub format: ImageFormat,
    /// The GPUs the reconstructor runs on and the samples are traced on; the CPU by
    /// default.
    pub devices: crate::gpu::Devices,
}

/// `stats.json` of a sequence.
#[derive(Clone, Debug, Serialize)]
pub struct SequenceStats {
    /// Scene as named by the user.
    pub scene: String,
    /// The method.
    pub method: MethodKind,
    /// Sample budget.
    pub rate: f64,
    /// Display width.
    pub width: u32,
    /// Display height.
    pub height: u32,
    /// First refresh.
    pub start: f64,
    /// Length, seconds.
    pub duration: f64,
    /// Warm-up, seconds.
    pub warmup: f64,
    /// Refresh rate, Hz.
    pub refresh_hz: f64,
    /// Frames written.
    pub frames: u64,
    /// Samples traced.
    pub samples: u64,
    /// Seconds spent tracing.
    pub trace_s: f64,
    /// Mean over frames of the mean information age, seconds.
    pub mean_age_s: f64,
    /// Wall-clock seconds of the whole sequence.
    pub wall_s: f64,
    /// Method-specific statistics.
    pub extra: Option<serde_json::Value>,
    /// Where the reconstructor ran (the GPU given, else the CPU).
    pub recon: crate::reconstruction::device::ReconUsed,
    /// Where the samples were traced (the GPU given, else the CPU).
    pub trace: crate::gpu::DeviceUsed,
    /// Why the GPU tracer stopped part way, after which the CPU traced the rest.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub trace_failure: Option<String>,
}

impl SequenceConfig {
    /// Display width and height.
    pub fn size(&self) -> (u32, u32) {
        let crate::settings::Size(w, h) = self.display.size;
        (w, h)
    }

    /// Number of frames.
    pub fn frames(&self) -> u64 {
        (self.duration * self.display.refresh_hz + 1e-9)
            .floor()
            .max(1.0) as u64
    }

    /// Check the settings: the ranges, and the same checks as an evaluation of this
    /// method (e.g. a rate too low for a framed method to finish one frame).
    pub fn validate(&self) -> Result<(), EvalError> {
        use crate::{limits, settings::Setting};
        let bad = |setting, why: String| Err(EvalError::config(setting, why));
        if let Err(why) = limits::check_duration(self.duration) {
            return bad(Setting::Duration, why.to_string());
        }
        if let Err(why) = limits::check_warmup(self.warmup) {
            return bad(Setting::Warmup, why.to_string());
        }
        if let Err(why) = limits::check_refresh_hz(self.display.refresh_hz) {
            return bad(Setting::RefreshHz, why.to_string());
        }
        let frames = self.frames();
        if frames > MAX_FRAMES {
            return bad(
                Setting::Duration,
                format!(
                    "gives {frames} frames, more than {MAX_FRAMES}: shorten it or lower the \
                     refresh rate"
                ),
            );
        }
        EvalConfig {
            scene_name: self.scene_name.clone(),
            camera_path: None,
            start: self.start,
            duration: self.duration,
            rates: vec![self.rate],
            methods: vec![self.method],
            warmup: self.warmup,
            display: self.display,
            quality: self.quality,
            reference: crate::settings::ReferenceGroup {
                ideal_spp: 1,
                ..crate::settings::ReferenceGroup::uncached()
            },
            strip_frames: Vec::new(),
            flip_every: 1,
            devices: crate::gpu::Devices::default(),
        }
        .validate()
    }
}

/// Render the sequence as the folder `out` (`frame_NNNNN.png` or `.exr`, and
/// `stats.json`). The
/// files are written into a temporary sibling folder that replaces `out` only when the
/// sequence is complete (see [`OutputDir`]), so `out` never mixes frames of two runs.
pub fn render_sequence(
    scene: Arc<Scene>,
    cfg: &SequenceConfig,
    out: &Path,
    progress: &dyn Progress,
) -> Result<SequenceStats, EvalError> {
    cfg.validate()?;
    let (w, h) = cfg.size();
    let mut ctx = method_context(scene, cfg);
    ctx.rays = batch::open(cfg.devices.trace.clone(), &ctx.tracer)
        .map_err(|e| EvalError::Trace(e.to_string()))?;
    let rays = ctx.rays.clone();
    let mut m = cfg.method.build(&ctx)?;
    let staging = OutputDir::begin(out).map_err(|e| EvalError::io(out, e))?;
    let frames = cfg.frames();
    let t0 = Instant::now();
    let ages = write_frames(cfg, m.as_mut(), staging.path(), progress)?;
    let stats = SequenceStats {
        scene: cfg.scene_name.clone(),
        method: cfg.method,
        rate: cfg.rate,
        width: w,
        height: h,
        start: cfg.start,
        duration: cfg.duration,
        warmup: cfg.warmup,
        refresh_hz: cfg.display.refresh_hz,
        frames,
        samples: m.samples_used(),
        trace_s: m.trace_seconds(),
        mean_age_s: ages / frames as f64,
        wall_s: t0.elapsed().as_secs_f64(),
        extra: m.extra_stats(),
        recon: cfg.devices.recon_used(),
        trace: batch::used(rays.as_ref()),
        trace_failure: rays.and_then(|r| r.failure()),
    };
    let p = staging.path().join("stats.json");
    // Numbers and strings always serialise.
    let json = serde_json::to_string_pretty(&stats).expect("stats serialise");
    std::fs::write(&p, json).map_err(|e| EvalError::io(&p, e))?;
    staging.commit().map_err(|e| EvalError::io(out, e))?;
    Ok(stats)
}

/// What the method of a sequence runs with: the tracer and the simulated clock (on the
/// CPU tracer: [`render_sequence`] opens the GPU's, which can fail).
pub fn method_context(scene: Arc<Scene>, cfg: &SequenceConfig) -> MethodContext {
    let tracer = Arc::new(
        Tracer::new(
            scene,
            cfg.display.size.0,
            cfg.display.size.1,
            TraceOptions::from(&cfg.quality),
        )
        .with_camera_path(cfg.camera_path.clone()),
    );
    MethodContext {
        tracer,
        clock: crate::clock::Clock {
            start: cfg.start - cfg.warmup,
            rate: cfg.rate,
            first_refresh: cfg.start,
            refresh_hz: cfg.display.refresh_hz,
        },
        seed: cfg.quality.seed,
        ideal_spp: crate::settings::IDEAL_SPP,
        ideal_cache: None,
        gpu: cfg.devices.recon.clone(),
        rays: None,
    }
}

/// Write what `m` displays at every refresh into `dir`; the sum of the displayed
/// images' mean ages.
fn write_frames(
    cfg: &SequenceConfig,
    m: &mut dyn Method,
    dir: &Path,
    progress: &dyn Progress,
) -> Result<f64, EvalError> {
    let (w, h) = cfg.size();
    let frames = cfg.frames();
    // Progress in samples (the first refresh traces the whole warm-up), at least one a
    // refresh.
    let budget = (cfg.rate * (cfg.warmup + cfg.duration)) as u64;
    progress.total(budget.max(frames));
    let mut ages = 0.0;
    let (mut used, mut counted) = (0, 0);
    for k in 0..frames {
        let t = cfg.start + k as f64 / cfg.display.refresh_hz;
        let shown = m.display(t);
        ages += shown.mean_age;
        let p = dir.join(format!("frame_{k:05}.{}", cfg.format.extension()));
        match cfg.format {
            ImageFormat::Png => write_png_rgb8_fast(&p, w, h, &shown.image.to_rgb8()),
            ImageFormat::Exr => shown.image.save_exr(&p),
        }
        .map_err(|e| EvalError::io(&p, e))?;
        let now = m.samples_used();
        let units = now.saturating_sub(used).max(1);
        used = now;
        counted += units;
        progress.advance("rendering", units);
    }
    progress.advance("rendering", budget.saturating_sub(counted));
    Ok(ages)
}
