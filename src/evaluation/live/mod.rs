//! The live evaluation (`frameless live`): which method shows the best images on this
//! machine, in real time, at equal wall-clock time. Each real-time method runs through
//! the same pipeline as `frameless view --headless`, paying for its own control,
//! reconstruction and warping out of the same cores; every refresh of a window is
//! recorded as displayed with its scan-out time ([`crate::realtime::record`]) and then
//! scored against the ideal image of that instant, like `frameless eval`.
//!
//! The window is on `eval`'s refresh grid: refresh `j` is scanned out at scene time
//! `start + j / refresh_hz`, after a warm-up of whole refreshes from `start − warmup`,
//! so the ideal images are the ones `eval` caches for the same window. Ideal images are
//! made before the first run and scoring happens between runs, so neither competes with
//! a method for the cores. Runs repeat in alternation (A B C A B C …) and each metric is
//! reported as the median over the repeats with its range.

mod builds;
mod report;

pub use report::{markdown, read_summary, rewrite, write_all};

use std::{sync::Arc, time::Instant};

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::{metrics, temporal, EvalError, Progress};
use crate::{
    gpu::Devices,
    limits,
    realtime::{
        machine,
        record::{self, LiveFigures, Recording, Window},
        AdaptiveArgs, AdaptiveSettings, AdaptiveTuning, RtConfig, RtMethod, RtSettings,
    },
    reconstruction::device::ReconUsed,
    render::cache::{self, IdealCache, Lookup},
    scene::{CameraPath, Scene},
    settings::{self, Setting},
    trace::{batch, TraceOptions, Tracer},
};

/// Most repeats of each method.
pub const MAX_REPEAT: usize = 100;

/// Settings of a live evaluation. What every command shares is held as its group
/// ([`settings`]'s), as [`EvalConfig`](crate::evaluation::EvalConfig) holds it.
#[derive(Clone, Debug)]
pub struct LiveConfig {
    /// How the user named the scene (for reports).
    pub scene_name: String,
    /// Camera path overriding the scene camera.
    pub camera_path: Option<CameraPath>,
    /// Scene time of the first recorded refresh.
    pub start: f64,
    /// Wall seconds recorded per run.
    pub seconds: f64,
    /// Wall seconds each run goes before its window (rounded up to whole refreshes, at
    /// least one).
    pub warmup: f64,
    /// The real-time methods, run in this order.
    pub methods: Vec<RtMethod>,
    /// Runs of each method, in alternation.
    pub repeat: usize,
    /// Cores the methods size their threads for (default: the machine's).
    pub cores: usize,
    /// The image build's threads, where not the cores' default (half of them).
    pub recon_threads: Option<usize>,
    /// Whether the sampling threads trace a moving view ahead
    /// ([`RtConfig::view_ahead`]); on by default.
    pub view_ahead: bool,
    /// The adaptive method's options, as `view` takes them (image budget, ring, largest
    /// splat radius); nothing asked for by default.
    pub adaptive: AdaptiveArgs,
    /// The display: size and refresh rate.
    pub display: settings::DisplayGroup,
    /// How samples are traced, the ideal images' included: seed (of the methods'
    /// random choices too), depth, texture filter.
    pub quality: settings::QualityGroup,
    /// The ideal images: samples per pixel and cache.
    pub reference: settings::ReferenceGroup,
    /// The GPUs the adaptive reconstructor runs on and the methods' samples are traced
    /// on (a GPU tracer made for each run's tracer), acquired once for every run; the
    /// CPU, the reference, by default.
    pub devices: Devices,
}

impl LiveConfig {
    /// The settings `frameless live --scene <scene_name>` runs with: 256×256 at 60 Hz,
    /// 3 s from t = 0 after 1 s of warm-up, every real-time method once, threads for
    /// this machine's cores, seed 1, 16-spp ideal images, ray-cone texture filtering,
    /// no ideal-image cache.
    pub fn new(scene_name: &str) -> Self {
        Self {
            scene_name: scene_name.to_string(),
            camera_path: None,
            start: 0.0,
            seconds: 3.0,
            warmup: 1.0,
            methods: RtMethod::ALL.to_vec(),
            repeat: 1,
            cores: machine::cores(),
            recon_threads: None,
            view_ahead: true,
            adaptive: AdaptiveArgs::default(),
            display: settings::DisplayGroup::default(),
            quality: settings::QualityGroup::default(),
            reference: settings::ReferenceGroup::uncached(),
            devices: Devices::default(),
        }
    }

    /// Take the settings every run shares from their groups (as
    /// [`EvalConfig::set_groups`](crate::evaluation::EvalConfig::set_groups)).
    pub fn set_groups(
        &mut self,
        display: &settings::DisplayGroup,
        quality: &settings::QualityGroup,
        reference: &settings::ReferenceGroup,
    ) {
        self.display = *display;
        self.quality = *quality;
        self.reference = reference.clone();
    }

    /// Display width and height.
    pub fn size(&self) -> (u32, u32) {
        let settings::Size(w, h) = self.display.size;
        (w, h)
    }

    /// Refreshes recorded per run.
    pub fn frames(&self) -> usize {
        ((self.seconds * self.display.refresh_hz) + 1e-9)
            .floor()
            .max(1.0) as usize
    }

    /// Refreshes of warm-up before the window.
    pub fn warmup_refreshes(&self) -> u64 {
        ((self.warmup * self.display.refresh_hz) - 1e-9)
            .ceil()
            .max(1.0) as u64
    }

    /// Scan-out time of recorded refresh `j`, scene seconds.
    pub fn refresh(&self, j: usize) -> f64 {
        self.start + j as f64 / self.display.refresh_hz
    }

    /// The pipeline settings of `method`.
    pub fn rt_config(&self, method: RtMethod) -> RtConfig {
        let mut c = RtConfig::for_cores(method, self.cores);
        if let Some(n) = self.recon_threads {
            c.recon_threads = n;
        }
        c.refresh_hz = self.display.refresh_hz;
        c.seed = self.quality.seed;
        c.view_ahead = self.view_ahead;
        c.start = self.start - self.warmup_refreshes() as f64 / self.display.refresh_hz;
        c
    }

    /// `method`'s own settings: its defaults with the adaptive options asked for, and
    /// the run's GPU.
    pub fn rt_settings(&self, method: RtMethod) -> RtSettings {
        let mut s = method.settings();
        if let RtSettings::Adaptive(a) = &mut s {
            self.adaptive.apply(a);
        }
        s.use_gpu(self.devices.recon.clone());
        s
    }

    /// The adaptive method's settings with the options asked for (no GPU).
    fn adaptive_settings(&self) -> AdaptiveSettings {
        let mut a = AdaptiveSettings::default();
        self.adaptive.apply(&mut a);
        a
    }

    /// The adaptive settings the runs go with, if adaptive is one of the methods.
    pub fn adaptive_tuning(&self) -> Option<AdaptiveTuning> {
        self.methods
            .contains(&RtMethod::Adaptive)
            .then(|| self.adaptive_settings().tuning())
    }

    /// Bytes a run holds: the images it recorded (at most one a refresh) and the ideal
    /// images of the window, 8-bit RGB each.
    pub fn run_bytes(&self) -> u64 {
        2 * self.frames() as u64 * self.display.size.0 as u64 * self.display.size.1 as u64 * 3
    }

    /// Check the settings before any work; the error names the option.
    pub fn validate(&self) -> Result<(), EvalError> {
        let bad = |setting, why: String| Err(EvalError::config(setting, why));
        let checks = [
            (Setting::Warmup, limits::check_warmup(self.warmup)),
            (Setting::Seconds, limits::check_duration(self.seconds)),
            (
                Setting::Start,
                limits::check_start(self.start, self.warmup, self.seconds),
            ),
        ];
        for (setting, check) in checks {
            if let Err(why) = check {
                return bad(setting, why.to_string());
            }
        }
        if let Err(why) = limits::check_display(self.display.size.0, self.display.size.1) {
            return bad(Setting::Size, why.to_string());
        }
        if let Err(why) = limits::check_refresh_hz(self.display.refresh_hz) {
            return bad(Setting::RefreshHz, why.to_string());
        }
        if self.methods.is_empty() {
            return bad(Setting::Methods, "lists no method".into());
        }
        for (i, m) in self.methods.iter().enumerate() {
            if self.methods[..i].contains(m) {
                return bad(Setting::Methods, format!("lists {} twice", m.name()));
            }
        }
        if !(1..=MAX_REPEAT).contains(&self.repeat) {
            return bad(
                Setting::Repeat,
                format!("{} must be in 1..={MAX_REPEAT}", self.repeat),
            );
        }
        if self.reference.ideal_spp == 0 {
            return bad(Setting::IdealSpp, "must be at least 1".into());
        }
        // Refused even where adaptive does not run: an option out of range is a mistake.
        if let Err(e) = RtSettings::Adaptive(self.adaptive_settings()).validate() {
            let why = match e {
                crate::realtime::RealtimeError::Config(why) => why,
                e => e.to_string(),
            };
            return bad(Setting::Adaptive, why);
        }
        for &m in &self.methods {
            // Only the thread counts of a method's defaults depend on the cores, so an
            // error of these is the cores' (`--threads`), not the method's.
            if let Err(e) = RtConfig::for_cores(m, self.cores).validate() {
                return bad(
                    Setting::Threads,
                    format!("{}: for {}, {e}", self.cores, m.name()),
                );
            }
            let (c, s) = (self.rt_config(m), self.rt_settings(m));
            let check = c
                .validate()
                .and_then(|()| s.validate())
                .and_then(|()| s.check_size(&c, self.display.size.0, self.display.size.1));
            if let Err(e) = check {
                return bad(Setting::Methods, format!("{}: {e}", m.name()));
            }
        }
        let why = "a run holds the images it shows and the ideal images of its window; \
                   record fewer seconds or lower the refresh rate or the size";
        if let Err(e) = limits::check_buffer("live recording", self.run_bytes(), why) {
            return bad(Setting::Seconds, e.to_string());
        }
        Ok(())
    }
}

/// One recorded refresh's measurements.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct LiveFrameRow {
    /// The method.
    pub method: RtMethod,
    /// Which run of the method (1, 2, …).
    pub repeat: usize,
    /// Refresh index in the window.
    pub frame: usize,
    /// Scan-out time: the scene time of the refresh that showed the image.
    pub time: f64,
    /// Scene time the image shows (`None`: nothing on screen yet).
    pub shown_time: Option<f64>,
    /// Whether this refresh showed a new image.
    pub new_image: bool,
    /// RMS error against the ideal image at `time`, 0–255 units.
    pub rms: f64,
    /// PSNR, dB.
    pub psnr: f64,
    /// Mean FLIP error.
    pub flip: f64,
    /// Temporal instability, as `eval`'s (`None` on the first refresh).
    pub instability: Option<f64>,
    /// Mean age of the information on screen at scan-out, seconds: the image's age when
    /// built plus the time from its build to this refresh (`None`: no information).
    pub age_s: Option<f64>,
    /// Sustained error of the 100 ms ending here, as `eval`'s (`None` before a full
    /// window, and in files written before it was measured).
    #[serde(default)]
    pub sustained: Option<f64>,
    /// Transient error of the same 100 ms, as `eval`'s.
    #[serde(default)]
    pub transient: Option<f64>,
}

/// A run's or a method's figures: image quality against the ideal, and what the run
/// got of the machine.
#[derive(Clone, Copy, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct Scores {
    /// Mean RMS error, 0–255.
    pub rms: f64,
    /// Mean PSNR, dB.
    pub psnr: f64,
    /// Mean FLIP.
    pub flip: f64,
    /// Mean temporal instability, 0–255.
    pub instability: f64,
    /// Mean information age at scan-out, seconds (`None`: no information shown).
    pub age_s: Option<f64>,
    /// Mean sustained error, 0–255 (`None`: not measured; see `evaluation::temporal`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sustained: Option<f64>,
    /// Mean transient error, 0–255.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub transient: Option<f64>,
    /// The run's live figures.
    #[serde(flatten)]
    pub live: LiveFigures,
}

const SCORE_FIELDS: usize = 14;

impl Scores {
    fn fields(&self) -> [Option<f64>; SCORE_FIELDS] {
        let l = &self.live;
        [
            Some(self.rms),
            Some(self.psnr),
            Some(self.flip),
            Some(self.instability),
            self.age_s,
            Some(l.samples_per_s),
            Some(l.images_per_s),
            Some(l.late_refreshes as f64),
            l.machine_share,
            l.others_share,
            l.load_average_before,
            l.others_load_before,
            self.sustained,
            self.transient,
        ]
    }

    fn from_fields(f: [Option<f64>; SCORE_FIELDS]) -> Self {
        let v = |i: usize| f[i].unwrap_or(f64::NAN);
        Scores {
            rms: v(0),
            psnr: v(1),
            flip: v(2),
            instability: v(3),
            age_s: f[4],
            sustained: f[12],
            transient: f[13],
            live: LiveFigures {
                samples_per_s: v(5),
                images_per_s: v(6),
                late_refreshes: f[7].map_or(0, |x| x.round() as u64),
                machine_share: f[8],
                others_share: f[9],
                load_average_before: f[10],
                others_load_before: f[11],
            },
        }
    }

    /// Field by field over `runs`: the median (the mean of the middle two for an even
    /// count), the least and the largest.
    fn spread(runs: &[Scores]) -> (Scores, Scores, Scores) {
        let mut med = [None; SCORE_FIELDS];
        let mut lo = [None; SCORE_FIELDS];
        let mut hi = [None; SCORE_FIELDS];
        for i in 0..SCORE_FIELDS {
            let mut v: Vec<f64> = runs.iter().filter_map(|r| r.fields()[i]).collect();
            if v.is_empty() {
                continue;
            }
            v.sort_by(f64::total_cmp);
            let n = v.len();
            med[i] = Some(0.5 * (v[(n - 1) / 2] + v[n / 2]));
            lo[i] = Some(v[0]);
            hi[i] = Some(v[n - 1]);
        }
        (
            Scores::from_fields(med),
            Scores::from_fields(lo),
            Scores::from_fields(hi),
        )
    }
}

/// One run of one method.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct LiveRun {
    /// The method.
    pub method: RtMethod,
    /// Which run of the method (1, 2, …).
    pub repeat: usize,
    /// Its scores and figures.
    pub scores: Scores,
    /// Sampling threads the method ran.
    pub sampling_threads: usize,
    /// Why its figures may be low: other work before it or during it.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
    /// The pipeline's own figures over the whole run, warm-up included, as `frameless
    /// view --headless` reports them under `pipeline`.
    pub pipeline: serde_json::Value,
}

/// One method over its runs.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct LiveRow {
    /// The method.
    pub method: RtMethod,
    /// Runs measured.
    pub runs: usize,
    /// The median of each figure over the runs.
    pub median: Scores,
    /// The least of each figure.
    pub min: Scores,
    /// The largest of each figure.
    pub max: Scores,
    /// Runs that carry a warning.
    pub warnings: usize,
}

/// Where the time of a live evaluation went.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct LiveTiming {
    /// Rendering or loading ideal images.
    pub ideal_s: f64,
    /// Ideal images served from the cache.
    pub ideal_cache_hits: usize,
    /// Running the methods (warm-ups and windows).
    pub live_s: f64,
    /// Scoring the recorded refreshes.
    pub metrics_s: f64,
    /// Writing reports, plots and strips.
    pub output_s: f64,
}

/// `summary.json` of a live evaluation.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct LiveSummary {
    /// Scene as named by the user.
    pub scene: String,
    /// Display width.
    pub width: u32,
    /// Display height.
    pub height: u32,
    /// Refresh rate, Hz.
    pub refresh_hz: f64,
    /// Scene time of the first recorded refresh.
    pub start: f64,
    /// Wall seconds recorded per run.
    pub seconds: f64,
    /// Warm-up per run, seconds (whole refreshes).
    pub warmup: f64,
    /// Seed.
    pub seed: u64,
    /// Ideal samples per pixel.
    pub ideal_spp: u32,
    /// A camera path file was used (true) or the scene camera (false).
    pub camera_path: bool,
    /// The reconstructor the adaptive method ran on (summaries written before it was
    /// recorded were all made on the CPU).
    #[serde(default = "ReconUsed::cpu")]
    pub recon: ReconUsed,
    /// The tracer of the methods' samples (summaries written before it was recorded
    /// were all traced on the CPU). Each run's `stats` says whether its GPU tracer
    /// failed part way (`trace_failure`).
    #[serde(default = "crate::gpu::DeviceUsed::cpu")]
    pub trace: crate::gpu::DeviceUsed,
    /// The adaptive method's settings, where it ran (summaries written before they
    /// were recorded ran its defaults of then).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub adaptive: Option<AdaptiveTuning>,
    /// Whether the sampling threads traced a moving view ahead (summaries written
    /// before it existed: they did not).
    #[serde(default)]
    pub view_ahead: bool,
    /// Runs of each method.
    pub repeat: usize,
    /// Cores of the machine.
    pub machine_cores: usize,
    /// Cores the methods sized their threads for.
    pub cores: usize,
    /// Per method: medians and ranges, in the order run.
    pub results: Vec<LiveRow>,
    /// Every run, in the order run.
    pub runs: Vec<LiveRun>,
    /// Cost of the evaluation.
    pub timing: LiveTiming,
}

/// Strip images at one refresh, 8-bit RGB: the ideal image, and each method's as its
/// median run (by mean RMS) showed it.
pub struct LiveStrip {
    /// Refresh index in the window.
    pub frame: usize,
    /// The ideal image at the refresh's scan-out time.
    pub ideal: Vec<u8>,
    /// Each method's image, in the evaluation's method order.
    pub shown: Vec<(RtMethod, Vec<u8>)>,
}

/// Everything a live evaluation produced.
pub struct LiveOutput {
    /// The summary.
    pub summary: LiveSummary,
    /// Every recorded refresh's measurements.
    pub frames: Vec<LiveFrameRow>,
    /// Image strips at the window's quartiles.
    pub strips: Vec<LiveStrip>,
}

/// What one scored run keeps besides its rows: the images of the strip frames.
struct Scored {
    run: LiveRun,
    rows: Vec<LiveFrameRow>,
    strip_images: Vec<Vec<u8>>,
}

/// Run the live evaluation (no files written; see [`write_all`]).
pub fn run(
    scene: Arc<Scene>,
    cfg: &LiveConfig,
    progress: &dyn Progress,
) -> Result<LiveOutput, EvalError> {
    cfg.validate()?;
    let n = cfg.frames();
    let runs = cfg.methods.len() * cfg.repeat;
    // Progress in refreshes: each ideal image, each refresh a run goes through
    // (warm-up included) and each one scored.
    let per_run = cfg.warmup_refreshes() + 2 * n as u64;
    progress.total(n as u64 + runs as u64 * per_run);
    let mut timing = LiveTiming::default();
    let ideal = ideal_images(&scene, cfg, &mut timing, progress)?;
    let strip_frames = quartiles(n);
    let mut scored: Vec<Scored> = Vec::with_capacity(runs);
    for repeat in 1..=cfg.repeat {
        for &method in &cfg.methods {
            let msg = format!("{} (run {repeat} of {})", method.name(), cfg.repeat);
            let t0 = Instant::now();
            let (rec, warnings) = record_run(&scene, cfg, method, progress)?;
            timing.live_s += t0.elapsed().as_secs_f64();
            progress.advance(&msg, cfg.warmup_refreshes() + n as u64);
            let t1 = Instant::now();
            let rows = score(cfg, method, repeat, &rec, &ideal);
            timing.metrics_s += t1.elapsed().as_secs_f64();
            progress.advance(&msg, n as u64);
            scored.push(Scored {
                run: LiveRun {
                    method,
                    repeat,
                    scores: scores_of(&rows, rec.figures),
                    sampling_threads: rec.pipeline.sampling_threads,
                    warnings,
                    pipeline: serde_json::to_value(&rec.pipeline).expect("plain figures serialise"),
                },
                strip_images: strip_frames
                    .iter()
                    .map(|&j| displayed(&rec, j, cfg).to_vec())
                    .collect(),
                rows,
            });
        }
    }
    Ok(assemble(cfg, scored, &ideal, &strip_frames, timing))
}

/// The refreshes at a quarter, half and three quarters of the window.
fn quartiles(n: usize) -> Vec<usize> {
    let mut f = vec![n / 4, n / 2, (3 * n) / 4];
    f.dedup();
    f
}

/// The tracer every run and the ideal images use, new for each so that no run finds
/// scene states another left in its cache.
fn tracer(scene: &Arc<Scene>, cfg: &LiveConfig) -> Arc<Tracer> {
    let options = TraceOptions::from(&cfg.quality);
    Arc::new(
        Tracer::new(
            scene.clone(),
            cfg.display.size.0,
            cfg.display.size.1,
            options,
        )
        .with_camera_path(cfg.camera_path.clone()),
    )
}

/// The ideal image of every refresh of the window, as displayed, on the run's tracer
/// (`--trace`): the GPU's ideals are cached apart from the CPU's.
fn ideal_images(
    scene: &Arc<Scene>,
    cfg: &LiveConfig,
    timing: &mut LiveTiming,
    progress: &dyn Progress,
) -> Result<Vec<Vec<u8>>, EvalError> {
    let t0 = Instant::now();
    let tracer = tracer(scene, cfg);
    let rays = batch::open(cfg.devices.trace.clone(), &tracer)
        .map_err(|e| EvalError::Trace(e.to_string()))?;
    let cache = match &cfg.reference.cache() {
        Some(dir) => Some(
            IdealCache::new(dir, &tracer, cfg.camera_path.as_ref())
                .map_err(|e| EvalError::io(dir, e))?
                .for_tracer(&batch::used(rays.as_ref())),
        ),
        None => None,
    };
    let mut ideal = Vec::with_capacity(cfg.frames());
    for j in 0..cfg.frames() {
        let t = cfg.refresh(j);
        let (image, lookup) = cache::ideal_image(
            cache.as_ref(),
            &tracer,
            rays.as_deref(),
            t,
            cfg.reference.ideal_spp,
            cfg.quality.seed,
        );
        timing.ideal_cache_hits += usize::from(matches!(lookup, Lookup::Hit));
        ideal.push(image.to_rgb8());
        progress.step("ideal images");
    }
    timing.ideal_s = t0.elapsed().as_secs_f64();
    Ok(ideal)
}

/// Other processes' share of the machine during a run above which its figures are
/// called into doubt.
const OTHERS_SHARE_WARNING: f64 = 0.2;

/// Record one run of `method`, with warnings when the machine was busy before it (other
/// processes' tasks running or waiting above the core count) or during it (other
/// processes above [`OTHERS_SHARE_WARNING`] of the cores). The 1-minute load average is
/// recorded but not judged: it carries this evaluation's previous run, whose threads on
/// a small machine keep it above the core count for a minute.
fn record_run(
    scene: &Arc<Scene>,
    cfg: &LiveConfig,
    method: RtMethod,
    progress: &dyn Progress,
) -> Result<(Recording, Vec<String>), EvalError> {
    let window = Window {
        warmup: cfg.warmup_refreshes(),
        refreshes: cfg.frames(),
    };
    let (mut config, settings) = (cfg.rt_config(method), cfg.rt_settings(method));
    let tracer = tracer(scene, cfg);
    config.rays = batch::open(cfg.devices.trace.clone(), &tracer)
        .map_err(|e| EvalError::Trace(e.to_string()))?;
    let rec =
        record::record(tracer, config, settings, window).map_err(|source| EvalError::Live {
            method: method.name(),
            source,
        })?;
    let cores = machine::cores();
    let mut warnings = Vec::new();
    if let Some(l) = rec.figures.others_load_before.filter(|&l| l > cores as f64) {
        warnings.push(format!(
            "other processes had {l:.1} tasks running or waiting for the {cores} cores \
             before the run"
        ));
    }
    if let Some(o) = rec
        .figures
        .others_share
        .filter(|&o| o > OTHERS_SHARE_WARNING)
    {
        warnings.push(format!(
            "other processes used {:.0}% of the {cores} cores during the run",
            100.0 * o
        ));
    }
    for w in &warnings {
        progress.warn(&format!("{}: {w}", method.name()));
    }
    Ok((rec, warnings))
}

/// What refresh `j` of `rec` displayed (black before the first image).
fn displayed<'a>(rec: &'a Recording, j: usize, cfg: &LiveConfig) -> std::borrow::Cow<'a, [u8]> {
    match rec.shown[j] {
        Some(i) => std::borrow::Cow::Borrowed(&rec.images[i as usize].rgb[..]),
        None => std::borrow::Cow::Owned(vec![
            0;
            cfg.display.size.0 as usize
                * cfg.display.size.1 as usize
                * 3
        ]),
    }
}

/// Every recorded refresh scored against the ideal image of its scan-out time.
fn score(
    cfg: &LiveConfig,
    method: RtMethod,
    repeat: usize,
    rec: &Recording,
    ideal: &[Vec<u8>],
) -> Vec<LiveFrameRow> {
    let (w, h) = cfg.size();
    let shown_all: Vec<_> = (0..cfg.frames()).map(|j| displayed(rec, j, cfg)).collect();
    let shown_refs: Vec<&[u8]> = shown_all.iter().map(|s| &s[..]).collect();
    let ideal_refs: Vec<&[u8]> = ideal.iter().map(|i| &i[..]).collect();
    let n = temporal::window_refreshes(cfg.display.refresh_hz);
    let splits = temporal::per_refresh(&shown_refs, &ideal_refs[..shown_refs.len()], n);
    (0..cfg.frames())
        .into_par_iter()
        .map(|j| {
            let t = cfg.refresh(j);
            let shown = displayed(rec, j, cfg);
            let rms = metrics::rms(&ideal[j], &shown);
            let image = rec.shown[j].map(|i| &rec.images[i as usize]);
            let age = image
                .map(|im| im.mean_age + (t - im.time))
                .filter(|a| a.is_finite());
            LiveFrameRow {
                method,
                repeat,
                frame: j,
                time: t,
                shown_time: image.map(|im| im.time),
                new_image: j == 0 || rec.shown[j] != rec.shown[j - 1],
                rms,
                psnr: metrics::psnr(rms),
                flip: metrics::flip_mean(&ideal[j], &shown, w, h),
                instability: (j > 0).then(|| {
                    let prev = displayed(rec, j - 1, cfg);
                    metrics::instability(&prev, &shown, &ideal[j - 1], &ideal[j])
                }),
                age_s: age,
                sustained: splits[j].map(|s| s.sustained),
                transient: splits[j].map(|s| s.transient),
            }
        })
        .collect()
}

/// A run's means over its refreshes, with its live figures.
fn scores_of(rows: &[LiveFrameRow], live: LiveFigures) -> Scores {
    let mean = |v: Vec<f64>| {
        if v.is_empty() {
            None
        } else {
            Some(v.iter().sum::<f64>() / v.len() as f64)
        }
    };
    let all = |f: fn(&LiveFrameRow) -> Option<f64>| mean(rows.iter().filter_map(f).collect());
    Scores {
        rms: all(|r| Some(r.rms)).unwrap_or(f64::NAN),
        psnr: all(|r| Some(r.psnr)).unwrap_or(f64::NAN),
        flip: all(|r| Some(r.flip)).unwrap_or(f64::NAN),
        instability: all(|r| r.instability).unwrap_or(0.0),
        age_s: all(|r| r.age_s),
        sustained: temporal::mean_of(rows.iter().map(|r| r.sustained)),
        transient: temporal::mean_of(rows.iter().map(|r| r.transient)),
        live,
    }
}

/// The summary, rows and strips from every scored run.
fn assemble(
    cfg: &LiveConfig,
    scored: Vec<Scored>,
    ideal: &[Vec<u8>],
    strip_frames: &[usize],
    timing: LiveTiming,
) -> LiveOutput {
    let mut results = Vec::new();
    let mut strips: Vec<LiveStrip> = strip_frames
        .iter()
        .map(|&j| LiveStrip {
            frame: j,
            ideal: ideal[j].clone(),
            shown: Vec::new(),
        })
        .collect();
    for &m in &cfg.methods {
        let of_m: Vec<&Scored> = scored.iter().filter(|s| s.run.method == m).collect();
        let scores: Vec<Scores> = of_m.iter().map(|s| s.run.scores).collect();
        let (median, min, max) = Scores::spread(&scores);
        results.push(LiveRow {
            method: m,
            runs: of_m.len(),
            median,
            min,
            max,
            warnings: of_m.iter().filter(|s| !s.run.warnings.is_empty()).count(),
        });
        // The run whose mean RMS is the median's (the lower middle one of an even count).
        let mut by_rms = of_m.clone();
        by_rms.sort_by(|a, b| a.run.scores.rms.total_cmp(&b.run.scores.rms));
        let typical = by_rms[(by_rms.len() - 1) / 2];
        for (strip, image) in strips.iter_mut().zip(&typical.strip_images) {
            strip.shown.push((m, image.clone()));
        }
    }
    let mut runs = Vec::new();
    let mut frames = Vec::new();
    for s in scored {
        runs.push(s.run);
        frames.extend(s.rows);
    }
    LiveOutput {
        summary: LiveSummary {
            scene: cfg.scene_name.clone(),
            width: cfg.display.size.0,
            height: cfg.display.size.1,
            refresh_hz: cfg.display.refresh_hz,
            start: cfg.start,
            seconds: cfg.seconds,
            warmup: cfg.warmup_refreshes() as f64 / cfg.display.refresh_hz,
            seed: cfg.quality.seed,
            ideal_spp: cfg.reference.ideal_spp,
            camera_path: cfg.camera_path.is_some(),
            recon: cfg.devices.recon_used(),
            trace: cfg.devices.trace_used(),
            adaptive: cfg.adaptive_tuning(),
            view_ahead: cfg.view_ahead,
            repeat: cfg.repeat,
            machine_cores: machine::cores(),
            cores: cfg.cores,
            results,
            runs,
            timing,
        },
        frames,
        strips,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A run of adaptive with these pipeline figures and default scores.
    pub(super) fn a_run(pipeline: serde_json::Value) -> LiveRun {
        LiveRun {
            method: RtMethod::Adaptive,
            repeat: 1,
            scores: Scores::default(),
            sampling_threads: 1,
            warnings: Vec::new(),
            pipeline,
        }
    }

    /// The memory bound admits a 640×480 run of 10 s at 60 Hz and refuses what would
    /// not fit, before any work.
    #[test]
    fn a_ten_second_640_by_480_run_fits_the_memory_bound() {
        let mut cfg = LiveConfig::new("toycar");
        (cfg.display.size.0, cfg.display.size.1, cfg.seconds) = (640, 480, 10.0);
        assert!(cfg.validate().is_ok(), "{:?}", cfg.validate());
        assert_eq!(cfg.run_bytes(), 2 * 600 * 640 * 480 * 3);
        (cfg.display.size.0, cfg.display.size.1, cfg.seconds) = (1920, 1080, 2.8);
        assert!(cfg.validate().is_ok());
        cfg.seconds = 3.0;
        let err = cfg.validate().unwrap_err().to_string();
        assert!(err.contains("live recording"), "{err}");
    }

    /// A summary written before the reconstructor was recorded reads as the CPU's.
    #[test]
    fn committed_summaries_read_as_the_cpus() {
        let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("docs/results/live/kitchen_toycar/summary.json");
        let text = std::fs::read_to_string(&p).expect("committed summary");
        let v: serde_json::Value = serde_json::from_str(&text).expect("JSON");
        assert!(v.get("recon").is_none(), "written before `recon`");
        let s = read_summary(&p).expect("reads");
        assert_eq!(s.recon, ReconUsed::cpu());
        assert!(!s.view_ahead, "written before the view was traced ahead");
        assert!(
            markdown(&s).contains("tracer: cpu; reconstructor: cpu; the view traced where it is)")
        );
    }

    /// The heading names the tracer as well as the reconstructor.
    #[test]
    fn the_heading_names_the_tracer() {
        let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("docs/results/live/kitchen_toycar/summary.json");
        let mut s = read_summary(&p).expect("reads");
        s.trace = crate::gpu::DeviceUsed {
            device: "gpu".into(),
            adapter: Some("a test adapter".into()),
        };
        let md = markdown(&s);
        assert!(
            md.contains("tracer: gpu (a test adapter); reconstructor: cpu; the view"),
            "{md}"
        );
    }

    /// The committed 1280×720 tables say in words what held each method's new images
    /// back: adaptive's image build, longer than the period, with its largest steps.
    #[test]
    fn the_summary_names_what_held_the_new_images_back() {
        let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("docs/results/live/session37/toycar_1280x720/summary.json");
        let md = markdown(&read_summary(&p).expect("committed summary"));
        let section = md
            .split("## What held the new images back")
            .nth(1)
            .expect("a section");
        let adaptive = section
            .lines()
            .find(|l| l.starts_with("- adaptive: "))
            .expect("adaptive's line");
        assert!(
            adaptive.contains("the image build is the first bottleneck"),
            "{adaptive}"
        );
        assert!(adaptive.contains("its largest steps: "), "{adaptive}");
        let tf = section
            .lines()
            .find(|l| l.starts_with("- traditional-frameless: "))
            .expect("traditional frameless's line");
        assert!(tf.contains("keeps up"), "{tf}");
    }

    /// The window lies on `eval`'s refresh grid, after whole refreshes of warm-up.
    #[test]
    fn the_window_is_on_the_refresh_grid() {
        let mut cfg = LiveConfig::new("toycar");
        (cfg.start, cfg.warmup, cfg.display.refresh_hz) = (2.0, 0.51, 60.0);
        assert_eq!(cfg.warmup_refreshes(), 31);
        let c = cfg.rt_config(RtMethod::FramedFull);
        let first = c.start + cfg.warmup_refreshes() as f64 / cfg.display.refresh_hz;
        assert!((first - cfg.refresh(0)).abs() < 1e-12);
        assert_eq!(cfg.refresh(0), 2.0);
        cfg.warmup = 0.0;
        assert_eq!(cfg.warmup_refreshes(), 1, "at least one refresh of warm-up");
        cfg.warmup = 0.5;
        assert_eq!(cfg.warmup_refreshes(), 30);
    }

    /// `--recon-threads` sets the image build's threads of every method, and nothing
    /// else; without it they are the cores' default.
    #[test]
    fn the_build_threads_can_be_set_apart_from_the_cores() {
        let mut cfg = LiveConfig::new("toycar");
        cfg.cores = 16;
        let default = cfg.rt_config(RtMethod::Adaptive);
        assert_eq!(default.recon_threads, 8);
        cfg.recon_threads = Some(3);
        for m in [RtMethod::Adaptive, RtMethod::TraditionalFrameless] {
            let c = cfg.rt_config(m);
            assert_eq!(c.recon_threads, 3);
            assert_eq!(
                c.sampling_threads,
                RtConfig::for_cores(m, 16).sampling_threads
            );
        }
        cfg.recon_threads = Some(0);
        assert!(cfg.validate().is_err(), "no build threads is refused");
    }

    /// The adaptive options reach the adaptive runs alone, are recorded where adaptive
    /// runs, and are checked before any work.
    #[test]
    fn the_adaptive_options_reach_its_runs_and_the_summary() {
        let mut cfg = LiveConfig::new("toycar");
        let defaults = AdaptiveSettings::default().tuning();
        assert_eq!(cfg.adaptive_tuning(), Some(defaults));
        cfg.adaptive.ring_factor = Some(3.0);
        cfg.adaptive.max_radius = Some(12.0);
        cfg.adaptive.image_budget = 0.5;
        let RtSettings::Adaptive(a) = cfg.rt_settings(RtMethod::Adaptive) else {
            panic!("adaptive's settings are adaptive's");
        };
        assert_eq!(
            (a.recon.ring_factor, a.recon.max_radius, a.image_budget),
            (3.0, 12.0, 0.5)
        );
        let t = cfg.adaptive_tuning().expect("adaptive runs");
        assert_eq!(
            (t.ring_factor, t.max_radius, t.image_budget),
            (3.0, 12.0, 0.5)
        );
        assert!(cfg.validate().is_ok(), "{:?}", cfg.validate());
        cfg.adaptive.ring_factor = Some(100.0);
        let err = cfg.validate().unwrap_err().to_string();
        assert!(err.contains("ring factor 100"), "{err}");
        cfg.methods = vec![RtMethod::LateWarp];
        assert!(
            cfg.validate().is_err(),
            "refused where adaptive does not run too"
        );
        cfg.adaptive.ring_factor = None;
        assert_eq!(
            cfg.adaptive_tuning(),
            None,
            "nothing recorded without adaptive"
        );
    }
}
