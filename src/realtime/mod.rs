//! The real-time parallel pipeline (SPEC §7, afr-optix), the interactive viewer and
//! its headless mode.
//!
//! Scene time follows the wall clock ([`clock`]). Several sampling threads trace samples
//! concurrently, each at the current time; per-pixel exclusion ([`pixel_locks`])
//! guarantees two threads never sample the same pixel at once. For the adaptive method
//! the tiling and deep buffer live on one controller thread ([`controller`]) that owns
//! the ordinary [`Sampler`](crate::methods::adaptive::Sampler): sampling threads send it
//! their crosshairs over channels and read the tile selection it publishes as a
//! snapshot. An image thread ([`pipeline`]) reconstructs at the display rate,
//! concurrently with sampling; the display (the [`viewer`] window or the [`headless`]
//! loop) presents the newest image at every refresh and never waits for one.
//!
//! Unlike the evaluation, nothing here is deterministic: the sample count depends on
//! the machine and on scheduling.

pub mod camera;
pub mod clock;
pub mod controller;
pub mod headless;
pub mod pacing;
pub mod pipeline;
pub mod pixel_locks;
pub mod sampling;
pub mod viewer;

pub use camera::{CameraRecorder, FlyCamera};
pub use clock::WallClock;
pub use headless::{run_headless, HeadlessOptions, HeadlessStats};
pub use pipeline::{Frame, Pipeline, PipelineStats};
pub use pixel_locks::{PixelGuard, PixelLocks};
pub use viewer::{run_viewer, ViewerOptions};

use crate::{methods::adaptive::SamplerParams, reconstruction::ReconParams};

/// Errors of the real-time mode.
#[derive(Debug, thiserror::Error)]
pub enum RealtimeError {
    /// A setting is out of range.
    #[error("invalid real-time setting: {0}")]
    Config(String),
    /// A thread could not be started.
    #[error("starting the {what} thread: {source}")]
    Spawn {
        /// Which thread.
        what: &'static str,
        /// Why.
        source: std::io::Error,
    },
    /// A pipeline thread panicked (a bug).
    #[error("the {0} thread panicked")]
    Panicked(&'static str),
    /// Output could not be written.
    #[error("writing {path}: {source}")]
    Io {
        /// The file.
        path: std::path::PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The window system failed.
    #[error("window: {0}")]
    Window(String),
}

/// What the pipeline renders.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum RtMethod {
    /// Adaptive sampler + adaptive space-time reconstructor.
    Adaptive,
    /// Traditional frameless: random pixels, newest sample shown per pixel.
    TraditionalFrameless,
    /// Double-buffered framed rendering at full resolution, as fast as it goes.
    Framed,
}

impl RtMethod {
    /// All methods, in the viewer's key order (1, 2, 3).
    pub const ALL: [RtMethod; 3] = [
        RtMethod::Adaptive,
        RtMethod::TraditionalFrameless,
        RtMethod::Framed,
    ];

    /// Command-line name.
    pub fn name(self) -> &'static str {
        match self {
            RtMethod::Adaptive => "adaptive",
            RtMethod::TraditionalFrameless => "traditional-frameless",
            RtMethod::Framed => "framed",
        }
    }

    /// Parse a command-line name.
    pub fn parse(s: &str) -> Result<Self, RealtimeError> {
        Self::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| {
                RealtimeError::Config(format!(
                    "unknown method `{s}` (expected adaptive, traditional-frameless or framed)"
                ))
            })
    }
}

/// Visualisations the viewer can show instead of the image.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Visualisation {
    /// The displayed image.
    #[default]
    Image,
    /// Tile borders over the image (paper Fig. 3).
    Tiling,
    /// Per-tile gradients: Gx red, Gy green, Gt blue (Fig. 4).
    Gradients,
    /// Local sample density (Fig. 7).
    Density,
}

impl Visualisation {
    /// The next one in the cycle.
    pub fn next(self) -> Self {
        match self {
            Visualisation::Image => Visualisation::Tiling,
            Visualisation::Tiling => Visualisation::Gradients,
            Visualisation::Gradients => Visualisation::Density,
            Visualisation::Density => Visualisation::Image,
        }
    }

    /// Parse a name.
    pub fn parse(s: &str) -> Result<Self, RealtimeError> {
        let all = [
            Visualisation::Image,
            Visualisation::Tiling,
            Visualisation::Gradients,
            Visualisation::Density,
        ];
        all.into_iter().find(|v| v.name() == s).ok_or_else(|| {
            RealtimeError::Config(format!(
                "unknown visualisation `{s}` (expected image, tiling, gradients or density)"
            ))
        })
    }

    /// Name for the title bar.
    pub fn name(self) -> &'static str {
        match self {
            Visualisation::Image => "image",
            Visualisation::Tiling => "tiling",
            Visualisation::Gradients => "gradients",
            Visualisation::Density => "density",
        }
    }
}

/// Settings of one pipeline run.
#[derive(Clone, Copy, Debug)]
pub struct RtConfig {
    /// What to render.
    pub method: RtMethod,
    /// Sampling threads (besides the controller and image threads).
    pub sampling_threads: usize,
    /// Threads the reconstructor's parallel splatting may use (its own pool, so that
    /// reconstruction cannot take every core from sampling and the display).
    pub recon_threads: usize,
    /// Display refresh rate, Hz: the image thread reconstructs at most this often.
    pub refresh_hz: f64,
    /// Scene time when the pipeline starts.
    pub start: f64,
    /// Seed of the threads' random choices.
    pub seed: u64,
    /// The adaptive sampler's parameters.
    pub sampler: SamplerParams,
    /// The reconstructor's parameters.
    pub recon: ReconParams,
}

impl RtConfig {
    /// Defaults for `method`: for adaptive one sampling thread per core but one (the
    /// controller and the reconstruction need the rest; measured in
    /// `docs/results/realtime/`), one per core for the others,
    /// reconstruction on half the cores, the paper's sampler, and the real-time
    /// reconstructor ([`realtime_recon`]).
    pub fn new(method: RtMethod) -> Self {
        let cores = std::thread::available_parallelism().map_or(2, |n| n.get());
        Self {
            method,
            sampling_threads: match method {
                RtMethod::Adaptive => cores.saturating_sub(1).max(1),
                // Nothing else of theirs needs a core: the image thread only copies.
                RtMethod::TraditionalFrameless | RtMethod::Framed => cores,
            },
            recon_threads: (cores / 2).max(1),
            refresh_hz: 60.0,
            start: 0.0,
            seed: 1,
            sampler: SamplerParams::paper(),
            recon: realtime_recon(),
        }
    }

    /// Check ranges.
    pub fn validate(&self) -> Result<(), RealtimeError> {
        if !(1..=256).contains(&self.sampling_threads) {
            return Err(RealtimeError::Config(format!(
                "sampling threads {} out of range 1..=256",
                self.sampling_threads
            )));
        }
        if !(1..=256).contains(&self.recon_threads) {
            return Err(RealtimeError::Config(format!(
                "reconstruction threads {} out of range 1..=256",
                self.recon_threads
            )));
        }
        if !(self.refresh_hz.is_finite() && (1.0..=1000.0).contains(&self.refresh_hz)) {
            return Err(RealtimeError::Config(format!(
                "refresh rate {} Hz out of range 1..=1000",
                self.refresh_hz
            )));
        }
        if !self.start.is_finite() {
            return Err(RealtimeError::Config("start time must be finite".into()));
        }
        if !(self.recon.ring_factor.is_finite() && self.recon.ring_factor > 0.0) {
            return Err(RealtimeError::Config("ring factor must be positive".into()));
        }
        self.sampler
            .validate()
            .map_err(|e| RealtimeError::Config(e.to_string()))
    }
}

/// The real-time reconstructor: the paper's, with a ring of 2 × pixels samples. The
/// reconstructor's cost is linear in the ring; at the 6 × pixels of the paper (sized for
/// 400K samples/s) one refresh costs 20–35 ms on this project's 2-core machine, more
/// than a 60 Hz refresh, while at the 0.1–0.25 M samples/s reached here 2 × pixels
/// still holds the last 0.5–1.5 s of samples at 256×256. Splats are at most 8 px in
/// radius (paper reconstructor: 24): sparse early samples otherwise grow huge
/// footprints through the coverage-driven splat size.
pub fn realtime_recon() -> ReconParams {
    ReconParams {
        ring_factor: 2.0,
        max_radius: 8.0,
        ..ReconParams::paper()
    }
}
