//! Gold-standard evaluation (paper §7): every method runs on the same scene,
//! display and sample budget under a simulated clock; at every refresh its displayed
//! image is compared with the ideal image of that instant.

pub mod live;
pub mod metrics;
pub mod report;
pub mod sequence;
pub mod style;
pub mod sweep;
pub mod table1;
pub mod temporal;
pub mod verdict;
pub mod video_metric;

use std::{collections::HashMap, path::PathBuf, sync::Arc, time::Instant};

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::{
    clock::{rate_label, Clock},
    gpu::{DeviceUsed, Devices},
    limits,
    methods::{
        ideal::{ideal_image, ideal_lookup},
        Method, MethodContext, MethodError, MethodKind, RunShape,
    },
    reconstruction::device::ReconUsed,
    render::cache::{IdealCache, Lookup},
    scene::{CameraPath, Scene},
    settings::{self, Setting},
    trace::{
        batch::{self, GpuRays},
        TraceOptions, Tracer,
    },
};

/// Why an evaluation could not run or write its outputs.
#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    /// A setting is out of range.
    #[error("{setting} {why}")]
    Config {
        /// The setting (the binary names its option).
        setting: Setting,
        /// What is wrong and what would do.
        why: String,
    },
    /// A method cannot run as asked.
    #[error(transparent)]
    Method(#[from] MethodError),
    /// The GPU tracer could not take the scene (`--trace gpu`).
    #[error("the GPU tracer: {0}")]
    Trace(String),
    /// A live run's pipeline failed (a thread could not start, or panicked).
    #[error("{method}: {source}")]
    Live {
        /// The real-time method.
        method: &'static str,
        /// Why.
        source: crate::realtime::RealtimeError,
    },
    /// A file could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A data file (`frames.csv`, `summary.json`) could not be read or written.
    #[error("{}: {why}", path.display())]
    Data {
        /// The file.
        path: PathBuf,
        /// What is wrong, with the line where the format says it.
        why: String,
    },
    /// A `summary.json` or `frames.csv` read back is not one a run could write.
    #[error("{}: {source}", path.display())]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        source: DataError,
    },
    /// A plot could not be drawn.
    #[error("plot {}: {why}", path.display())]
    Plot {
        /// The SVG file.
        path: PathBuf,
        /// The plotting library's message.
        why: String,
    },
    /// A method traced more samples than its budget (a bug).
    #[error("internal error: {method} used {used} samples by t = {t}, budget {budget}")]
    OverBudget {
        /// The method.
        method: MethodKind,
        /// Samples traced.
        used: u64,
        /// Display time.
        t: f64,
        /// Samples allowed by then.
        budget: u64,
    },
    /// No Table 1 animation has this name.
    #[error("unknown animation '{name}': expected one of {expected}")]
    UnknownAnimation {
        /// The name asked for.
        name: String,
        /// The names there are.
        expected: String,
    },
}

/// What is wrong with a `summary.json` or `frames.csv` read back: a setting past its
/// budget, or rows that contradict each other or the summary. Rows are counted from 1,
/// as in `frames.csv` after its header.
#[derive(Debug, thiserror::Error)]
pub enum DataError {
    /// A setting past its budget, named by its key in the file.
    #[error("{key}: {why}")]
    Setting {
        /// The key.
        key: &'static str,
        /// Which budget it breaks.
        why: String,
    },
    /// More result rows than every method at the most rates.
    #[error(
        "{rows} result rows, more than {most} (every method at {} rates)",
        limits::MAX_RATES
    )]
    ResultRows {
        /// Rows in the file.
        rows: usize,
        /// The most there can be.
        most: usize,
    },
    /// A result row whose rate is not a positive number.
    #[error("{method}: rate {rate} is not a positive number")]
    Rate {
        /// The row's method.
        method: MethodKind,
        /// Its rate.
        rate: f64,
    },
    /// Two result rows of one method and rate.
    #[error("{method} at {rate} has two result rows")]
    TwoResultRows {
        /// The method.
        method: MethodKind,
        /// The rate.
        rate: f64,
    },
    /// A frame row of a method and rate the summary has no result for.
    #[error("row {row}: {method} at {rate} has no result row in the summary")]
    NoResultRow {
        /// The frame row.
        row: usize,
        /// Its method.
        method: MethodKind,
        /// Its rate.
        rate: f64,
    },
    /// A frame row past the window.
    #[error("row {row}: frame {frame} is past the window's {refreshes} refreshes")]
    PastWindow {
        /// The frame row.
        row: usize,
        /// Its frame.
        frame: usize,
        /// Refreshes in the window.
        refreshes: usize,
    },
    /// A frame row with a value out of its range.
    #[error("row {row}: {why}")]
    OutOfRange {
        /// The frame row.
        row: usize,
        /// Which value, and its range.
        why: String,
    },
    /// Two frame rows of one method, rate and frame.
    #[error("rows {first} and {row}: {method} at {rate} frame {frame} is there twice")]
    Twice {
        /// The first row.
        first: usize,
        /// The second.
        row: usize,
        /// Their method.
        method: MethodKind,
        /// Their rate.
        rate: f64,
        /// Their frame.
        frame: usize,
    },
}

impl EvalError {
    /// An I/O error on `path`.
    pub fn io(path: &std::path::Path, source: std::io::Error) -> Self {
        EvalError::Io {
            path: path.to_path_buf(),
            source,
        }
    }

    pub(crate) fn config(setting: Setting, why: impl ToString) -> Self {
        EvalError::Config {
            setting,
            why: why.to_string(),
        }
    }
}

/// Settings of one evaluation run. What every command shares is held as its group
/// ([`settings`]'s), so an option added to a group reaches the evaluation with no
/// field here.
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
    /// Sample budgets to evaluate, samples per second.
    pub rates: Vec<f64>,
    /// Methods to evaluate.
    pub methods: Vec<MethodKind>,
    /// Seconds every method runs before the first evaluated refresh.
    pub warmup: f64,
    /// The display: size and refresh rate.
    pub display: settings::DisplayGroup,
    /// How samples are traced, ideal images included: seed, depth, texture filter.
    pub quality: settings::QualityGroup,
    /// The ideal images: samples per pixel (≥ 16 for the paper's protocol) and cache.
    pub reference: settings::ReferenceGroup,
    /// Frames at which image strips are saved (indices into the window).
    pub strip_frames: Vec<usize>,
    /// FLIP is computed on every n-th frame (it costs more than tracing a frame at the
    /// paper's rates); RMS and PSNR on every frame.
    pub flip_every: usize,
    /// The GPUs the adaptive methods reconstruct on and the methods that trace in
    /// batches and the ideal images are traced on, each acquired once for the whole
    /// run; the CPU, the reference, by default.
    pub devices: Devices,
}

/// The methods `frameless eval` runs when none are named: the baselines, today's
/// practice and ours, without the ablations and the paper's own adaptive method.
pub const DEFAULT_METHODS: [MethodKind; 9] = [
    MethodKind::Framed60Hz,
    MethodKind::FramedFull,
    MethodKind::FullRes60Hz,
    MethodKind::TraditionalFrameless,
    MethodKind::PointTracking,
    MethodKind::Taa,
    MethodKind::LateWarp,
    MethodKind::TaaWarp,
    MethodKind::Adaptive,
];

impl EvalConfig {
    /// The settings `frameless eval --scene <scene_name>` runs with: 256×256 at 60 Hz,
    /// 1 s from t = 0 after a 1 s warm-up, 100K, 400K and 800K samples/s,
    /// [`DEFAULT_METHODS`], seed 1, 16-spp ideal images, ray-cone texture filtering,
    /// strips at the window's quartiles, FLIP on every frame; no ideal-image cache.
    /// Change the fields for anything else.
    pub fn new(scene_name: &str) -> Self {
        let mut cfg = Self {
            scene_name: scene_name.to_string(),
            camera_path: None,
            start: 0.0,
            duration: 1.0,
            rates: settings::RATES.to_vec(),
            methods: DEFAULT_METHODS.to_vec(),
            warmup: settings::WARMUP_S,
            display: settings::DisplayGroup::default(),
            quality: settings::QualityGroup::default(),
            reference: settings::ReferenceGroup::uncached(),
            strip_frames: Vec::new(),
            flip_every: 1,
            devices: Devices::default(),
        };
        cfg.strip_frames = cfg.quartile_frames();
        cfg
    }

    /// Take the settings every run shares from their groups: the display, how samples
    /// are traced, the ideal images (the one place the command line and the Python
    /// module set them), with the image strips at the new window's quartiles.
    pub fn set_groups(
        &mut self,
        display: &settings::DisplayGroup,
        quality: &settings::QualityGroup,
        reference: &settings::ReferenceGroup,
    ) {
        self.display = *display;
        self.quality = *quality;
        self.reference = reference.clone();
        self.strip_frames = self.quartile_frames();
    }

    /// Display width and height.
    pub fn size(&self) -> (u32, u32) {
        let settings::Size(w, h) = self.display.size;
        (w, h)
    }

    /// The reconstructor the run's results come from.
    pub fn recon_used(&self) -> ReconUsed {
        self.devices.recon_used()
    }

    /// The frames at a quarter, half and three quarters of the window (the strips
    /// `frameless eval` writes).
    pub fn quartile_frames(&self) -> Vec<usize> {
        let n = self.frames();
        let mut f = vec![n / 4, n / 2, (3 * n) / 4];
        f.dedup();
        f
    }

    /// Number of evaluated refreshes.
    pub fn frames(&self) -> usize {
        refreshes(self.duration, self.display.refresh_hz)
    }

    /// The simulated clock at `rate`: sample 0 at the start of the warm-up.
    pub fn clock(&self, rate: f64) -> Clock {
        Clock {
            start: self.start - self.warmup,
            rate,
            first_refresh: self.start,
            refresh_hz: self.display.refresh_hz,
        }
    }

    /// Display time of evaluated refresh `k`.
    pub fn refresh(&self, k: usize) -> f64 {
        self.start + k as f64 / self.display.refresh_hz
    }

    /// The method runs: each method once per rate, or once for all rates when it
    /// ignores the rate.
    pub fn runs(&self) -> Vec<(MethodKind, f64)> {
        let mut runs = Vec::new();
        for m in &self.methods {
            if m.rate_independent() {
                runs.push((*m, self.rates[0]));
            } else {
                runs.extend(self.rates.iter().map(|r| (*m, *r)));
            }
        }
        runs
    }

    fn summary(
        &self,
        results: Vec<ResultRow>,
        timing: Timing,
        rays: Option<&Arc<GpuRays>>,
    ) -> Summary {
        Summary {
            scene: self.scene_name.clone(),
            width: self.display.size.0,
            height: self.display.size.1,
            refresh_hz: self.display.refresh_hz,
            start: self.start,
            duration: self.duration,
            warmup: self.warmup,
            seed: self.quality.seed,
            ideal_spp: self.reference.ideal_spp,
            camera_path: self.camera_path.is_some(),
            recon: self.recon_used(),
            trace: batch::used(rays),
            trace_failure: rays.and_then(|r| r.failure()),
            results,
            timing,
        }
    }

    /// The tracer of `scene` at the run's size, trace options and camera path.
    pub fn tracer(&self, scene: Arc<Scene>) -> Arc<Tracer> {
        Arc::new(
            Tracer::new(
                scene,
                self.display.size.0,
                self.display.size.1,
                TraceOptions::from(&self.quality),
            )
            .with_camera_path(self.camera_path.clone()),
        )
    }

    /// What the methods' budget rules need to know of this run.
    pub fn shape(&self) -> RunShape {
        RunShape {
            width: self.display.size.0,
            height: self.display.size.1,
            refresh_hz: self.display.refresh_hz,
            ideal_spp: self.reference.ideal_spp,
            seconds: self.warmup + self.duration,
        }
    }

    /// Check the settings; the error says what is wrong and how to fix it.
    pub fn validate(&self) -> Result<(), EvalError> {
        let bad = |setting, why: String| Err(EvalError::config(setting, why));
        let times = [
            (Setting::Warmup, limits::check_warmup(self.warmup)),
            (Setting::Duration, limits::check_duration(self.duration)),
            (
                Setting::Start,
                limits::check_start(self.start, self.warmup, self.duration),
            ),
        ];
        for (option, check) in times {
            if let Err(why) = check {
                return bad(option, why.to_string());
            }
        }
        if let Err(why) = limits::check_refresh_hz(self.display.refresh_hz) {
            return bad(Setting::RefreshHz, why.to_string());
        }
        if self.rates.is_empty() {
            return bad(Setting::Rates, "lists no rate".into());
        }
        if self.methods.is_empty() {
            return bad(Setting::Methods, "lists no method".into());
        }
        // Rows, files and plot series are keyed by method and by rate label: a repeat
        // would be run twice and overwrite itself.
        for (i, m) in self.methods.iter().enumerate() {
            if self.methods[..i].contains(m) {
                return bad(Setting::Methods, format!("lists {m} twice"));
            }
        }
        if let Err(why) = limits::check_rate_count(self.rates.len()) {
            return bad(Setting::Rates, why.to_string());
        }
        let mut labels: HashMap<String, f64> = HashMap::with_capacity(self.rates.len());
        for &r in &self.rates {
            let label = rate_label(r);
            if let Some(&q) = labels.get(&label) {
                let why = if q == r {
                    format!("lists {label} twice")
                } else {
                    format!(
                        "{q} and {r} would both be labelled {label} (rates must differ in their first three digits)"
                    )
                };
                return bad(Setting::Rates, why.to_string());
            }
            labels.insert(label, r);
        }
        if self.flip_every == 0 {
            return bad(Setting::FlipEvery, "must be at least 1".into());
        }
        if let Err(why) = limits::check_ideal_spp(self.reference.ideal_spp) {
            return bad(Setting::IdealSpp, why.to_string());
        }
        if let Err(why) = limits::check_max_depth(self.quality.max_depth) {
            return bad(Setting::MaxDepth, why.to_string());
        }
        if let Err(why) = limits::check_display(self.display.size.0, self.display.size.1) {
            return bad(Setting::Size, why.to_string());
        }
        let shape = self.shape();
        for &r in &self.rates {
            if let Err(why) = limits::check_rate(r, shape.seconds) {
                return bad(Setting::Rates, why.to_string());
            }
            for m in &self.methods {
                (m.info().check_rate)(&shape, r)?;
            }
        }
        Ok(())
    }
}

/// One displayed frame's measurements.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct FrameRow {
    /// The method.
    pub method: MethodKind,
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
    /// real change does not. (Read from files written as `flicker` too.)
    #[serde(alias = "flicker")]
    pub instability: Option<f64>,
    /// Mean age of the displayed information, seconds.
    pub age_s: f64,
    /// Sustained error of the 100 ms ending here, 0–255: the averaged display against
    /// the averaged ideal ([`temporal`]; `None` before a full window, and in files
    /// written before it was measured).
    #[serde(default)]
    pub sustained: Option<f64>,
    /// Transient error of the same 100 ms, 0–255: the error's fluctuation about that
    /// average ([`temporal`]).
    #[serde(default)]
    pub transient: Option<f64>,
}

/// Aggregates of one method at one rate.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct ResultRow {
    /// The method.
    pub method: MethodKind,
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
    /// Mean temporal instability (see [`FrameRow::instability`]). (Read from files
    /// written as `flicker_mean` too.)
    #[serde(alias = "flicker_mean")]
    pub instability_mean: f64,
    /// Mean sustained error over the frames that have one (see [`FrameRow::sustained`];
    /// `None` where none has, as in summaries written before it was measured).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sustained_mean: Option<f64>,
    /// Mean transient error (see [`FrameRow::transient`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub transient_mean: Option<f64>,
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
    /// Ideal images served from the cache (entries that passed every check).
    pub ideal_cache_hits: usize,
    /// Cache entries found but not served (wrong key, checksum, size or format), whose
    /// images were rendered again and the entries rewritten.
    #[serde(default)]
    pub ideal_cache_rejected: usize,
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
    /// The reconstructor the adaptive methods ran on (summaries written before it was
    /// recorded were all made on the CPU).
    #[serde(default = "ReconUsed::cpu")]
    pub recon: ReconUsed,
    /// The tracer of the samples and the ideal images (summaries written before it was
    /// recorded were all traced on the CPU).
    #[serde(default = "DeviceUsed::cpu")]
    pub trace: DeviceUsed,
    /// Why the GPU tracer stopped part way, after which the CPU traced the rest.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub trace_failure: Option<String>,
    /// Per method and rate.
    pub results: Vec<ResultRow>,
    /// Cost of the run.
    pub timing: Timing,
}

/// The largest RMS or instability of 0–255 RGB images, 255·√3 (√3 written out: `sqrt`
/// is not `const`), with room for rounding.
const MOST_RMS: f64 = 255.0 * 1.732_050_807_568_877_2 + 1e-6;

impl FrameRow {
    /// What in the row no run writes: a time outside the scene times a run may touch,
    /// an error that is negative, not finite or past its largest value (RMS and
    /// instability over 0–255 RGB: at most 255·√3; FLIP at most 1), a PSNR outside what
    /// those RMS values give, or an age that is neither NaN (nothing shown yet) nor a
    /// finite time.
    pub fn out_of_range(&self) -> Option<String> {
        let within = |v: f64, hi: f64| v.is_finite() && (0.0..=hi).contains(&v);
        if !(self.time.is_finite() && self.time.abs() <= limits::MAX_SCENE_TIME_S) {
            return Some(format!(
                "time {} is not a scene time a run reaches",
                self.time
            ));
        }
        if !within(self.rms, MOST_RMS) || !self.instability.is_none_or(|v| within(v, MOST_RMS)) {
            return Some("an RMS or instability outside [0, 255·√3]".into());
        }
        if ![self.sustained, self.transient]
            .iter()
            .all(|v| v.is_none_or(|v| within(v, 255.0)))
        {
            return Some("a sustained or transient error outside [0, 255]".into());
        }
        if !self.flip.is_none_or(|v| within(v, 1.0)) {
            return Some("a FLIP outside [0, 1]".into());
        }
        // `frames.csv` rounds PSNR to 4 decimals, so a capped value may read a little over.
        let psnr = metrics::psnr(MOST_RMS) - 1e-3..=metrics::PSNR_CAP_DB + 1e-3;
        if !psnr.contains(&self.psnr) {
            return Some(format!(
                "PSNR {} outside the {:.2} to {} dB that RMS values give",
                self.psnr,
                psnr.start(),
                metrics::PSNR_CAP_DB
            ));
        }
        if !(self.age_s.is_nan() || (self.age_s.is_finite() && self.age_s.abs() <= 1e6)) {
            return Some(format!("age {} is not a time", self.age_s));
        }
        None
    }
}

/// What a result row says of its frame rows, computed from them.
struct FrameMeans {
    frames: usize,
    rms_mean: f64,
    psnr_mean: f64,
    flip_mean: f64,
    flip_frames: usize,
    instability_mean: f64,
    age_mean_s: f64,
    sustained_mean: Option<f64>,
    transient_mean: Option<f64>,
}

fn frame_means(rows: &[FrameRow]) -> FrameMeans {
    let mean = |f: fn(&FrameRow) -> f64| rows.iter().map(f).sum::<f64>() / rows.len() as f64;
    let flips: Vec<f64> = rows.iter().filter_map(|r| r.flip).collect();
    let instabilities: Vec<f64> = rows.iter().filter_map(|r| r.instability).collect();
    FrameMeans {
        frames: rows.len(),
        rms_mean: mean(|r| r.rms),
        psnr_mean: mean(|r| r.psnr),
        flip_mean: flips.iter().sum::<f64>() / flips.len().max(1) as f64,
        flip_frames: flips.len(),
        instability_mean: instabilities.iter().sum::<f64>() / instabilities.len().max(1) as f64,
        age_mean_s: mean(|r| r.age_s),
        sustained_mean: temporal::mean_of(rows.iter().map(|r| r.sustained)),
        transient_mean: temporal::mean_of(rows.iter().map(|r| r.transient)),
    }
}

impl ResultRow {
    /// Where the row says other than its frame rows `rows` (a method at one rate): a
    /// frame count or a mean that is not theirs. A file can be edited, so its
    /// aggregates are only taken when its rows give them.
    pub fn disagrees_with(&self, rows: &[FrameRow]) -> Option<String> {
        let m = frame_means(rows);
        if (self.frames, self.flip_frames) != (m.frames, m.flip_frames) {
            return Some(format!(
                "frames {} and flip_frames {}, but {} frame rows with {} FLIP values",
                self.frames, self.flip_frames, m.frames, m.flip_frames
            ));
        }
        // Summed in the same order, so equal but for a last bit where a mean is rounded.
        let same = |a: f64, b: f64| {
            (a.is_nan() && b.is_nan()) || (a - b).abs() <= 1e-9 * a.abs().max(b.abs()).max(1.0)
        };
        let means = [
            ("rms_mean", self.rms_mean, m.rms_mean),
            ("psnr_mean", self.psnr_mean, m.psnr_mean),
            ("flip_mean", self.flip_mean, m.flip_mean),
            (
                "instability_mean",
                self.instability_mean,
                m.instability_mean,
            ),
            ("age_mean_s", self.age_mean_s, m.age_mean_s),
        ];
        let nan = f64::NAN;
        let temporal = [
            ("sustained_mean", self.sustained_mean, m.sustained_mean),
            ("transient_mean", self.transient_mean, m.transient_mean),
        ]
        .map(|(k, a, b)| (k, a.unwrap_or(nan), b.unwrap_or(nan)));
        let (key, said, is) = means
            .into_iter()
            .chain(temporal)
            .find(|&(_, a, b)| !same(a, b))?;
        Some(format!(
            "{key} {said} is not the mean of its {} frame rows ({is})",
            m.frames
        ))
    }
}

/// Refreshes in a window of `duration` seconds at `refresh_hz` (at least one).
fn refreshes(duration: f64, refresh_hz: f64) -> usize {
    ((duration * refresh_hz) + 1e-9).floor().max(1.0) as usize
}

impl Summary {
    /// Check a summary read from a file that anyone can edit against the run budgets
    /// and for rows that contradict each other; the error says what is wrong.
    pub fn check(&self) -> Result<(), DataError> {
        let setting = |key: &'static str| move |why: String| DataError::Setting { key, why };
        let limit = |key| move |e: limits::LimitError| setting(key)(e.to_string());
        limits::check_display(self.width, self.height).map_err(limit("size"))?;
        limits::check_refresh_hz(self.refresh_hz).map_err(limit("refresh_hz"))?;
        limits::check_warmup(self.warmup).map_err(limit("warmup"))?;
        limits::check_duration(self.duration).map_err(limit("duration"))?;
        limits::check_start(self.start, self.warmup, self.duration).map_err(limit("start"))?;
        limits::check_ideal_spp(self.ideal_spp).map_err(limit("ideal_spp"))?;
        let most = MethodKind::ALL.len() * limits::MAX_RATES;
        if self.results.len() > most {
            return Err(DataError::ResultRows {
                rows: self.results.len(),
                most,
            });
        }
        let mut rates = std::collections::HashSet::new();
        let mut cells = std::collections::HashSet::new();
        for r in &self.results {
            if !(r.rate.is_finite() && r.rate > 0.0) {
                return Err(DataError::Rate {
                    method: r.method,
                    rate: r.rate,
                });
            }
            rates.insert(r.rate.to_bits());
            if !cells.insert((r.method, r.rate.to_bits())) {
                return Err(DataError::TwoResultRows {
                    method: r.method,
                    rate: r.rate,
                });
            }
        }
        limits::check_rate_count(rates.len()).map_err(limit("results"))
    }

    /// Evaluated refreshes of the run it summarises.
    pub fn frames(&self) -> usize {
        refreshes(self.duration, self.refresh_hz)
    }

    /// Check per-frame rows against the summary: each of a method and rate it has
    /// a result row for, within its window, once. The error names the row (1-based,
    /// as in `frames.csv` after its header).
    pub fn check_frames(&self, frames: &[FrameRow]) -> Result<(), DataError> {
        let cells: std::collections::HashSet<(MethodKind, u64)> = self
            .results
            .iter()
            .map(|r| (r.method, r.rate.to_bits()))
            .collect();
        let n = self.frames();
        let mut seen = HashMap::with_capacity(frames.len());
        for (i, f) in frames.iter().enumerate() {
            let row = i + 1;
            if !cells.contains(&(f.method, f.rate.to_bits())) {
                return Err(DataError::NoResultRow {
                    row,
                    method: f.method,
                    rate: f.rate,
                });
            }
            if f.frame >= n {
                return Err(DataError::PastWindow {
                    row,
                    frame: f.frame,
                    refreshes: n,
                });
            }
            if let Some(why) = f.out_of_range() {
                return Err(DataError::OutOfRange { row, why });
            }
            if let Some(first) = seen.insert((f.method, f.rate.to_bits(), f.frame), row) {
                return Err(DataError::Twice {
                    first,
                    row,
                    method: f.method,
                    rate: f.rate,
                    frame: f.frame,
                });
            }
        }
        Ok(())
    }
}

/// Everything a run produced.
pub struct EvalOutput {
    /// The summary.
    pub summary: Summary,
    /// Every frame's measurements.
    pub frames: Vec<FrameRow>,
    /// Strip images: the ideal image and each method's at a few frames of each rate.
    pub strips: Vec<Strip>,
    /// The strip frames' linear images, when asked for ([`RunOptions::linear_strips`]).
    pub linear: Vec<LinearImage>,
}

/// Progress reporting hooks. Work is counted in units whose cost is about even (an
/// evaluation counts rays: a refresh of a method costs the samples it traced, which
/// is the whole warm-up for the first one, and an ideal image its pixels × spp), so
/// that done/total is a fair share of the time.
pub trait Progress: Sync {
    /// Set the total number of units.
    fn total(&self, n: u64);
    /// `n` units done, with a message saying what is being worked on.
    fn advance(&self, msg: &str, n: u64);
    /// One unit done.
    fn step(&self, msg: &str) {
        self.advance(msg, 1);
    }
    /// Something the user should know while the work goes on (a run measured on a
    /// busy machine); it is also in the results. Ignored unless implemented.
    fn warn(&self, _msg: &str) {}
}

/// No progress reporting.
pub struct Silent;
impl Progress for Silent {
    fn total(&self, _: u64) {}
    fn advance(&self, _: &str, _: u64) {}
}

/// Options of [`run_with`] that change what is kept, not what is measured.
#[derive(Clone, Copy, Debug, Default)]
pub struct RunOptions {
    /// Keep the linear (unclamped, unquantized) images of the strip frames, the ideal's
    /// and every method's, for HDR output ([`EvalOutput::linear`]). The ideal images of
    /// those frames are rendered again, since the cache holds them as displayed.
    pub linear_strips: bool,
    /// Make the ideal images from this refresh on, then wrap around. Runs of one
    /// evaluation that share a cold cache at the same time (a sweep's shards) start at
    /// different refreshes, so each renders its part and reads the rest from the cache
    /// instead of all rendering all; the results do not depend on the order.
    pub first_ideal: usize,
}

/// A strip frame's image before display quantization.
#[derive(Clone, Debug)]
pub struct LinearImage {
    /// The method that showed it, or [`MethodKind::Ideal`] for the ideal image.
    pub method: MethodKind,
    /// The rate column (`None` for the ideal image, which has none).
    pub rate: Option<f64>,
    /// Frame index in the window.
    pub frame: usize,
    /// The linear image.
    pub image: crate::image::Image,
}

/// Strip images at one rate and frame, as displayed (8-bit RGB).
#[derive(Clone, Debug, PartialEq)]
pub struct Strip {
    /// The rate column.
    pub rate: f64,
    /// Frame index in the window.
    pub frame: usize,
    /// The ideal image of that frame.
    pub ideal: Vec<u8>,
    /// Each method's displayed image, in the run's method order.
    pub shown: Vec<(MethodKind, Vec<u8>)>,
}

impl Strip {
    /// A strip with the ideal image and no method's yet.
    pub fn new(rate: f64, frame: usize, ideal: Vec<u8>) -> Strip {
        Strip {
            rate,
            frame,
            ideal,
            shown: Vec::new(),
        }
    }

    /// The panels left to right, each with the method that shows it: the ideal image
    /// ([`MethodKind::Ideal`]) first, then the methods'.
    pub fn panels(&self) -> impl Iterator<Item = (MethodKind, &[u8])> {
        std::iter::once((MethodKind::Ideal, self.ideal.as_slice()))
            .chain(self.shown.iter().map(|(m, rgb)| (*m, rgb.as_slice())))
    }
}

/// One method's displayed images over the window, and what it cost.
struct Shown {
    /// Per refresh: the displayed image (8-bit RGB) and its mean information age.
    frames: Vec<(Vec<u8>, f64)>,
    /// The linear images of the frames asked for, by frame index.
    linear: Vec<(usize, crate::image::Image)>,
    samples: u64,
    extra: Option<serde_json::Value>,
    effective_rate: f64,
    /// Progress units reported while showing.
    counted: u64,
}

/// Run an evaluation (no files written; see [`report::write_all`]).
pub fn run(
    scene: Arc<Scene>,
    cfg: &EvalConfig,
    progress: &dyn Progress,
) -> Result<EvalOutput, EvalError> {
    run_with(scene, cfg, progress, RunOptions::default())
}

/// [`run`], keeping what `options` asks for besides the measurements.
pub fn run_with(
    scene: Arc<Scene>,
    cfg: &EvalConfig,
    progress: &dyn Progress,
    options: RunOptions,
) -> Result<EvalOutput, EvalError> {
    cfg.validate()?;
    let tracer = cfg.tracer(scene);
    let rays = batch::open(cfg.devices.trace.clone(), &tracer)
        .map_err(|e| EvalError::Trace(e.to_string()))?;
    let cache = open_cache(cfg, &tracer, &batch::used(rays.as_ref()))?;
    let n = cfg.frames();
    let runs = cfg.runs();
    let units = Units {
        cfg,
        cache: cache.as_deref(),
        pixels: cfg.display.size.0 as u64 * cfg.display.size.1 as u64,
        shape: cfg.shape(),
    };
    progress.total(
        (0..n).map(|k| units.ideal(k)).sum::<u64>()
            + runs.iter().map(|&(k, r)| units.run(k, r)).sum::<u64>(),
    );
    let mut timing = Timing::default();
    let ctx_for = |rate: f64| MethodContext {
        tracer: tracer.clone(),
        clock: cfg.clock(rate),
        seed: cfg.quality.seed,
        ideal_spp: cfg.reference.ideal_spp,
        ideal_cache: cache.clone(),
        gpu: cfg.devices.recon.clone(),
        rays: rays.clone(),
    };
    refuse_early(cfg, &ctx_for(cfg.rates[0]))?;
    let ideal = ideal_images(
        cfg,
        &ctx_for(cfg.rates[0]),
        options.first_ideal,
        &mut timing,
        &|k| units.ideal(k),
        progress,
    );
    // Strip frames past the window are left out.
    let strip_frames: Vec<usize> = cfg
        .strip_frames
        .iter()
        .copied()
        .filter(|&k| k < n)
        .collect();
    let strips = ideal_strips(cfg, &strip_frames, &ideal);
    let keep_linear: &[usize] = if options.linear_strips {
        &strip_frames
    } else {
        &[]
    };
    let mut out = Collected {
        frames: Vec::new(),
        results: Vec::new(),
        strips,
        linear: linear_ideals(cfg, &ctx_for(cfg.rates[0]), keep_linear, &mut timing),
    };
    for (kind, rate) in runs {
        let run = MethodRun {
            kind,
            rate,
            keep_linear,
            ideal: &ideal,
        };
        run.evaluate(cfg, &ctx_for(rate), &units, &mut timing, &mut out, progress)?;
    }
    Ok(EvalOutput {
        summary: cfg.summary(out.results, timing, rays.as_ref()),
        frames: out.frames,
        strips: out.strips,
        linear: out.linear,
    })
}

/// A strip at every rate and every one of `frames`, each with its ideal image.
fn ideal_strips(cfg: &EvalConfig, frames: &[usize], ideal: &[Vec<u8>]) -> Vec<Strip> {
    cfg.rates
        .iter()
        .flat_map(|&rate| frames.iter().map(move |&k| (rate, k)))
        .map(|(rate, k)| Strip::new(rate, k, ideal[k].clone()))
        .collect()
}

/// The ideal-image cache of the run, if it asks for one, for the images `used` traces.
fn open_cache(
    cfg: &EvalConfig,
    tracer: &Tracer,
    used: &DeviceUsed,
) -> Result<Option<Arc<IdealCache>>, EvalError> {
    Ok(match &cfg.reference.cache() {
        Some(dir) => Some(Arc::new(
            IdealCache::new(dir, tracer, cfg.camera_path.as_ref())
                .map_err(|e| EvalError::io(dir, e))?
                .for_tracer(used),
        )),
        None => None,
    })
}

/// How much work an evaluation's parts are, in rays, for progress.
struct Units<'a> {
    cfg: &'a EvalConfig,
    cache: Option<&'a IdealCache>,
    pixels: u64,
    shape: RunShape,
}

impl Units<'_> {
    /// The ideal image of refresh `k`. A cached one costs a read, counted as one sample
    /// per pixel; whether it is cached is known (up to a rare rejected entry) from its
    /// file.
    fn ideal(&self, k: usize) -> u64 {
        let cfg = self.cfg;
        match self.cache {
            Some(c)
                if c.entry_path(cfg.refresh(k), cfg.reference.ideal_spp, cfg.quality.seed)
                    .is_file() =>
            {
                self.pixels
            }
            _ => self.pixels * cfg.reference.ideal_spp as u64,
        }
    }

    /// A method's run at `rate`. A refresh costs its samples and, besides, work over
    /// every pixel (its image, the metrics); on a 2-core machine that work was worth
    /// about one ray a pixel.
    fn run(&self, kind: MethodKind, rate: f64) -> u64 {
        let rate = kind.info().budget.effective_rate(&self.shape, rate);
        (rate * self.shape.seconds) as u64 + self.cfg.frames() as u64 * self.pixels
    }
}

/// The linear ideal images of the refreshes `keep` (none unless HDR strips are asked
/// for), rendered again since the cache holds them as displayed.
fn linear_ideals(
    cfg: &EvalConfig,
    ctx: &MethodContext,
    keep: &[usize],
    timing: &mut Timing,
) -> Vec<LinearImage> {
    let mut linear = Vec::new();
    if !keep.is_empty() {
        let t0 = Instant::now();
        for &k in keep {
            linear.push(LinearImage {
                method: MethodKind::Ideal,
                rate: None,
                frame: k,
                image: ideal_image(ctx, cfg.refresh(k)),
            });
        }
        timing.ideal_s += t0.elapsed().as_secs_f64();
    }
    linear
}

/// What the runs have produced so far.
struct Collected {
    frames: Vec<FrameRow>,
    results: Vec<ResultRow>,
    strips: Vec<Strip>,
    linear: Vec<LinearImage>,
}

/// One method's run at one rate.
struct MethodRun<'a> {
    kind: MethodKind,
    rate: f64,
    /// Refreshes whose linear images are kept.
    keep_linear: &'a [usize],
    /// The ideal image of every refresh, as displayed.
    ideal: &'a [Vec<u8>],
}

impl MethodRun<'_> {
    /// Run the method, measure what it showed and add its rows, results, strip panels
    /// and linear images to `out`.
    fn evaluate(
        &self,
        cfg: &EvalConfig,
        ctx: &MethodContext,
        units: &Units<'_>,
        timing: &mut Timing,
        out: &mut Collected,
        progress: &dyn Progress,
    ) -> Result<(), EvalError> {
        let (kind, rate) = (self.kind, self.rate);
        let mut method = kind.build(ctx)?;
        let tm = Instant::now();
        let mut shown = show(cfg, kind, rate, method.as_mut(), self.keep_linear, progress)?;
        warn_of_gpu_failure(kind, rate, &shown, progress);
        // Methods may trace less than their budget; the total counted the budget.
        progress.advance(
            kind.name(),
            units.run(kind, rate).saturating_sub(shown.counted),
        );
        timing.methods_s += tm.elapsed().as_secs_f64();
        timing.trace_s += method.trace_seconds();
        let tq = Instant::now();
        let metrics = measure(cfg, &shown.frames, self.ideal);
        timing.metrics_s += tq.elapsed().as_secs_f64();
        // A rate-independent method's one run fills every rate column.
        let columns = if kind.rate_independent() {
            cfg.rates.clone()
        } else {
            vec![rate]
        };
        for r in &columns {
            for (k, image) in &shown.linear {
                out.linear.push(LinearImage {
                    method: kind,
                    rate: Some(*r),
                    frame: *k,
                    image: image.clone(),
                });
            }
        }
        shown.linear.clear();
        for r in columns {
            let rows = frame_rows(cfg, kind, r, &shown, &metrics);
            out.results.push(aggregate(kind, r, &rows, &shown));
            for s in out.strips.iter_mut().filter(|s| s.rate == r) {
                s.shown.push((kind, shown.frames[s.frame].0.clone()));
            }
            out.frames.extend(rows);
        }
        Ok(())
    }
}

/// With a GPU, build each method once, so that one whose reconstructor the GPU cannot
/// run fails before the ideal images are made rather than after.
fn refuse_early(cfg: &EvalConfig, ctx: &MethodContext) -> Result<(), EvalError> {
    if ctx.gpu.is_some() {
        for kind in &cfg.methods {
            kind.build(ctx)?;
        }
    }
    Ok(())
}

/// Tell the user if a method's GPU reconstructor was given up during its run (its
/// statistics say so, [`Method::extra_stats`]; the rest of the run was the CPU's).
fn warn_of_gpu_failure(kind: MethodKind, rate: f64, shown: &Shown, progress: &dyn Progress) {
    let why = shown
        .extra
        .as_ref()
        .and_then(|e| e.get("gpu_failure")?.as_str());
    if let Some(why) = why {
        progress.warn(&format!(
            "{kind} at {}: the GPU reconstructor failed, the rest ran on the CPU: {why}",
            rate_label(rate)
        ));
    }
}

/// The ideal image of every refresh of the window, as displayed (8-bit RGB), made
/// from refresh `first` on.
fn ideal_images(
    cfg: &EvalConfig,
    ctx: &MethodContext,
    first: usize,
    timing: &mut Timing,
    units: &dyn Fn(usize) -> u64,
    progress: &dyn Progress,
) -> Vec<Vec<u8>> {
    let t0 = Instant::now();
    let n = cfg.frames();
    let first = first % n.max(1);
    let mut ideal = vec![Vec::new(); n];
    for k in (first..n).chain(0..first) {
        let t = cfg.refresh(k);
        let cost = units(k);
        let (image, lookup) = ideal_lookup(ctx, t);
        match lookup {
            Lookup::Hit => timing.ideal_cache_hits += 1,
            Lookup::Rejected(_) => timing.ideal_cache_rejected += 1,
            Lookup::Miss => {}
        }
        ideal[k] = image.to_rgb8();
        progress.advance("ideal images", cost);
    }
    timing.ideal_s = t0.elapsed().as_secs_f64();
    ideal
}

/// A frame's RMS, FLIP, instability and sustained and transient errors, as `measure`
/// gives them.
type FrameMetrics = (f64, Option<f64>, Option<f64>, Option<temporal::Split>);

/// One method's frames at rate column `rate`.
fn frame_rows(
    cfg: &EvalConfig,
    kind: MethodKind,
    rate: f64,
    shown: &Shown,
    metrics: &[FrameMetrics],
) -> Vec<FrameRow> {
    shown
        .frames
        .iter()
        .zip(metrics)
        .enumerate()
        .map(|(k, ((_, age), (rms, flip, unsteady, split)))| FrameRow {
            method: kind,
            rate,
            frame: k,
            time: cfg.refresh(k),
            rms: *rms,
            psnr: metrics::psnr(*rms),
            flip: *flip,
            instability: *unsteady,
            age_s: *age,
            sustained: split.map(|s| s.sustained),
            transient: split.map(|s| s.transient),
        })
        .collect()
}

/// Ask `method` what it displays at every refresh of the window, holding it to its
/// budget.
fn show(
    cfg: &EvalConfig,
    kind: MethodKind,
    rate: f64,
    method: &mut dyn Method,
    keep_linear: &[usize],
    progress: &dyn Progress,
) -> Result<Shown, EvalError> {
    let n = cfg.frames();
    let budget = kind.info().budget;
    let effective_rate = budget.effective_rate(&cfg.shape(), rate);
    let budget_clock = cfg.clock(effective_rate);
    let mut frames: Vec<(Vec<u8>, f64)> = Vec::with_capacity(n);
    let pixels = cfg.display.size.0 as u64 * cfg.display.size.1 as u64;
    let mut linear = Vec::new();
    let mut counted = 0;
    let mut used = 0;
    for k in 0..n {
        let t = cfg.refresh(k);
        let d = method.display(t);
        frames.push((d.image.to_rgb8(), d.mean_age));
        if keep_linear.contains(&k) {
            linear.push((k, d.image.clone()));
        }
        if budget.enforced() && method.samples_used() > budget_clock.samples_until(t) {
            return Err(EvalError::OverBudget {
                method: kind,
                used: method.samples_used(),
                t,
                budget: budget_clock.samples_until(t),
            });
        }
        let now = method.samples_used();
        let units = now.saturating_sub(used) + pixels;
        used = now;
        counted += units;
        progress.advance(kind.name(), units);
    }
    Ok(Shown {
        frames,
        linear,
        counted,
        samples: method.samples_used(),
        extra: method.extra_stats(),
        effective_rate,
    })
}

/// Per frame: RMS, FLIP (on every `flip_every`-th frame) and temporal instability
/// (from the second frame on), and the sustained and transient errors (from the first
/// full eye window on), computed in parallel.
fn measure(cfg: &EvalConfig, shown: &[(Vec<u8>, f64)], ideal: &[Vec<u8>]) -> Vec<FrameMetrics> {
    let (w, h) = cfg.size();
    let images: Vec<&[u8]> = shown.iter().map(|(rgb, _)| &rgb[..]).collect();
    let ideals: Vec<&[u8]> = ideal.iter().map(|i| &i[..]).collect();
    let splits = temporal::per_refresh(
        &images,
        &ideals,
        temporal::window_refreshes(cfg.display.refresh_hz),
    );
    shown
        .par_iter()
        .zip(ideal.par_iter())
        .enumerate()
        .map(|(k, ((rgb, _), id))| {
            let flip = (k % cfg.flip_every == 0).then(|| metrics::flip_mean(id, rgb, w, h));
            let instability =
                (k > 0).then(|| metrics::instability(&shown[k - 1].0, rgb, &ideal[k - 1], id));
            (metrics::rms(id, rgb), flip, instability)
        })
        .zip(splits)
        .map(|((rms, flip, instability), split)| (rms, flip, instability, split))
        .collect()
}

/// The means of one method's frames at one rate.
fn aggregate(kind: MethodKind, rate: f64, rows: &[FrameRow], shown: &Shown) -> ResultRow {
    let m = frame_means(rows);
    ResultRow {
        method: kind,
        rate,
        effective_rate: shown.effective_rate,
        frames: m.frames,
        rms_mean: m.rms_mean,
        psnr_mean: m.psnr_mean,
        flip_mean: m.flip_mean,
        flip_frames: m.flip_frames,
        instability_mean: m.instability_mean,
        sustained_mean: m.sustained_mean,
        transient_mean: m.transient_mean,
        age_mean_s: m.age_mean_s,
        samples: shown.samples,
        extra: shown.extra.clone(),
    }
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

/// Make the reports of an `eval`, `table1` or `live` output folder `dir` again
/// ([`report::rewrite`], [`live::rewrite`]), each of a Table 1 folder's animations in
/// its sub-folder; the reports' paths. The folder's `summary.json` names those
/// sub-folders and anyone can edit it, so every name must be one plain folder name,
/// checked before any report is written: `../x` or `/x` would put reports outside `dir`.
pub fn rewrite_reports(dir: &std::path::Path) -> Result<Vec<PathBuf>, EvalError> {
    let path = dir.join("summary.json");
    let text = limits::read_text(&path, limits::MAX_DATA_FILE_BYTES)
        .map_err(|e| EvalError::io(&path, e))?;
    if serde_json::from_str::<live::LiveSummary>(&text).is_ok() {
        return Ok(vec![live::rewrite(dir)?]);
    }
    let Ok(table) = serde_json::from_str::<table1::TableSummary>(&text) else {
        return Ok(vec![report::rewrite(dir)?]);
    };
    let folders = table
        .animations
        .iter()
        .map(|a| {
            if plain_folder_name(&a.name) {
                return Ok(dir.join(&a.name));
            }
            Err(EvalError::Data {
                path: path.clone(),
                why: format!(
                    "animation name `{}` is not a folder name (one name, without `/` or \
                     `..`), so it names no folder of {}",
                    a.name,
                    dir.display()
                ),
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    folders.iter().map(|d| report::rewrite(d)).collect()
}

/// Whether `name` joined to a folder names an entry of that folder itself.
fn plain_folder_name(name: &str) -> bool {
    use std::path::Component;
    let mut parts = std::path::Path::new(name).components();
    matches!((parts.next(), parts.next()), (Some(Component::Normal(n)), None) if n == name)
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use crate::{
        evaluation::{self, EvalConfig, Silent},
        methods::MethodKind,
        scene::builtin,
    };

    /// A cache hit is an entry served, not a file present: files that fail their checks
    /// are counted as rejected, and the results do not change.
    #[test]
    fn cache_hits_count_only_entries_served() {
        let dir = std::env::temp_dir().join(format!("frameless-eval-hits-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let cfg = {
            let mut c = EvalConfig::new("toycar");
            c.start = 0.2;
            c.duration = 0.1;
            c.display.size = crate::settings::Size(16, 12);
            c.rates = vec![100_000.0];
            c.methods = vec![MethodKind::TraditionalFrameless];
            c.quality.seed = 5;
            c.reference.ideal_spp = 2;
            c.warmup = 0.0;
            c.display.refresh_hz = 60.0;
            c.quality.max_depth = 3;
            c.quality.texture_filter = crate::trace::TextureFilter::None;
            c.reference.set_cache(Some(dir.clone()));
            c.strip_frames = Vec::new();
            c.flip_every = 1;
            c
        };
        let n = cfg.frames();
        let scene = Arc::new(builtin::load("toycar").expect("built-in scene"));
        let run = || evaluation::run(scene.clone(), &cfg, &Silent).expect("evaluation runs");
        let timing = |o: &evaluation::EvalOutput| {
            let t = &o.summary.timing;
            (t.ideal_cache_hits, t.ideal_cache_rejected)
        };
        let first = run();
        assert_eq!(timing(&first), (0, 0));
        assert_eq!(timing(&run()), (n, 0));
        let mut entries: Vec<_> = std::fs::read_dir(&dir)
            .expect("cache folder")
            .map(|e| e.expect("entry").path())
            .collect();
        entries.sort();
        assert_eq!(entries.len(), n);
        let damaged = entries.len() / 2;
        for p in &entries[..damaged] {
            std::fs::write(p, b"present but not an image").expect("writable");
        }
        let third = run();
        assert_eq!(timing(&third), (n - damaged, damaged));
        assert_eq!(third.frames, first.frames);
        assert_eq!(timing(&run()), (n, 0), "rejected entries were rewritten");
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// `summary.json` records the reconstructor and the tracer; one written before it
    /// did reads as the CPU's, which made every result then.
    #[test]
    fn summaries_record_the_devices_and_older_ones_read_as_the_cpus() {
        use crate::reconstruction::device::ReconUsed;
        let s = EvalConfig::new("toycar").summary(Vec::new(), evaluation::Timing::default(), None);
        let mut v = serde_json::to_value(&s).expect("serialises");
        for field in ["recon", "trace"] {
            assert_eq!(
                v[field],
                serde_json::json!({"device": "cpu", "adapter": null}),
                "{field}"
            );
        }
        assert!(v.get("trace_failure").is_none(), "no failure, no field");
        let o = v.as_object_mut().expect("an object");
        o.remove("recon");
        o.remove("trace");
        let old: evaluation::Summary = serde_json::from_value(v).expect("reads");
        assert_eq!(old.recon, ReconUsed::cpu());
        assert_eq!(old.trace, crate::gpu::DeviceUsed::cpu());
        assert_eq!(old, s);
    }

    /// The registered test method runs through the whole evaluation by name and
    /// description alone: it is parsed, held to its own budget in every rate column, and
    /// shows exactly what traditional frameless shows at that budget.
    #[test]
    fn a_registered_method_runs_through_the_evaluation() {
        assert_eq!(
            MethodKind::parse("test-frameless"),
            Ok(MethodKind::TestFrameless)
        );
        let cfg = {
            let mut c = EvalConfig::new("toycar");
            c.start = 0.2;
            c.duration = 0.1;
            c.display.size = crate::settings::Size(32, 24);
            c.rates = vec![100_000.0, 400_000.0];
            c.methods = vec![MethodKind::TestFrameless, MethodKind::TraditionalFrameless];
            c.quality.seed = 5;
            c.reference.ideal_spp = 4;
            c.warmup = 0.2;
            c.display.refresh_hz = 60.0;
            c.quality.max_depth = 3;
            c.quality.texture_filter = crate::trace::TextureFilter::None;
            c.strip_frames = Vec::new();
            c.flip_every = 1;
            c
        };
        let scene = Arc::new(builtin::load("toycar").expect("built-in scene"));
        let out = evaluation::run(scene, &cfg, &Silent).expect("evaluation runs");
        let row = |m: MethodKind, r: f64| {
            out.summary
                .results
                .iter()
                .find(|x| x.method == m && x.rate == r)
                .unwrap_or_else(|| panic!("no row for {m} at {r}"))
        };
        let reference = row(MethodKind::TraditionalFrameless, 100_000.0);
        for rate in [100_000.0, 400_000.0] {
            let t = row(MethodKind::TestFrameless, rate);
            assert_eq!(t.effective_rate, 100_000.0);
            assert_eq!(t.rms_mean, reference.rms_mean);
            assert_eq!(t.samples, reference.samples);
        }
        assert_ne!(
            row(MethodKind::TraditionalFrameless, 400_000.0).rms_mean,
            reference.rms_mean,
            "the rate changes traditional frameless, so the equality above is not trivial"
        );
        let json = serde_json::to_string(&out.summary).expect("serialises");
        assert!(json.contains("\"method\":\"test-frameless\""));
    }
}
