//! The adaptive method's own settings of a real-time run: its sampler, its
//! reconstructor and where that runs, and how long a build may take; their defaults,
//! their range checks, and the command-line options that set them
//! ([`AdaptiveArgs`], flattened into `frameless view` and `frameless live`), and what a
//! run records of them ([`AdaptiveTuning`]). The registry holds them as the payload of
//! `RtSettings::Adaptive`; the shared `RtConfig` never sees them.

use std::sync::Arc;

use crate::{
    methods::adaptive::SamplerParams,
    realtime::{config::RealtimeError, shared::MethodSettings},
    reconstruction::{device::GpuContext, ReconParams},
    settings::finite_f64,
};

/// The method's command-line name.
pub const NAME: &str = "adaptive";

/// The share of a refresh period an image's build aims to take, unless another is
/// asked for.
pub const IMAGE_BUDGET: f64 = 0.8;

/// The largest reconstructor ring, in multiples of the pixel count.
pub const RING_FACTOR_MAX: f64 = 64.0;

/// The range of the reconstructor's largest splat radius, pixels.
pub const MAX_RADIUS_RANGE: std::ops::RangeInclusive<f32> = 1.0..=64.0;

/// What adaptive reads of a real-time run's settings.
#[derive(Clone, Debug)]
pub struct AdaptiveSettings {
    /// The adaptive sampler's parameters.
    pub sampler: SamplerParams,
    /// The reconstructor's parameters.
    pub recon: ReconParams,
    /// The share of a refresh period an image's build aims to take. When a build
    /// takes longer, the next places only the newest samples of the ring, as many as
    /// fit ([`crate::reconstruction::Reconstructor::set_live_limit`]); 0: the whole
    /// ring always.
    pub image_budget: f64,
    /// Whether a moving view's refresh takes in the samples traced while it is built,
    /// between placing the ring and resolving it
    /// ([`crate::reconstruction::Reconstructor::reconstruct_taking_late`]), where its
    /// last part still ends before the refresh (the default); else every refresh is
    /// built from the samples in hand when it starts. On 2 cores the newest sample
    /// shown is 4–7 ms younger, and since the controllers see the view move (session
    /// 61) the images are better in alternated pairs on three of four moving cases
    /// (FLIP 3–5%) and the same on the fourth (docs/performance.md, sessions 60, 61).
    pub late_samples: bool,
    /// The GPU the reconstructor runs on (`None`: the CPU, the reference).
    pub gpu: Option<Arc<GpuContext>>,
}

impl Default for AdaptiveSettings {
    /// The paper's sampler, the real-time reconstructor ([`ReconParams::realtime`]) on
    /// the CPU, builds within [`IMAGE_BUDGET`] of a refresh period.
    fn default() -> Self {
        Self {
            sampler: SamplerParams::ours(),
            recon: ReconParams::realtime(),
            image_budget: IMAGE_BUDGET,
            late_samples: true,
            gpu: None,
        }
    }
}

impl AdaptiveSettings {
    /// What a run records of these settings.
    pub fn tuning(&self) -> AdaptiveTuning {
        AdaptiveTuning {
            image_budget: self.image_budget,
            ring_factor: self.recon.ring_factor,
            max_radius: self.recon.max_radius as f64,
            sampler_reprojection: self.sampler.reprojection,
            late_samples: self.late_samples,
        }
    }
}

/// The adaptive settings a run went with, as `frameless live` records them in its
/// `summary.json`.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AdaptiveTuning {
    /// [`AdaptiveSettings::image_budget`].
    pub image_budget: f64,
    /// The reconstructor's ring, multiples of the pixel count.
    pub ring_factor: f64,
    /// The reconstructor's largest splat radius, pixels.
    pub max_radius: f64,
    /// Whether the sampler's controllers reproject.
    pub sampler_reprojection: bool,
    /// [`AdaptiveSettings::late_samples`] (summaries from before it read as false, as
    /// they were made).
    #[serde(default)]
    pub late_samples: bool,
}

impl MethodSettings for AdaptiveSettings {
    fn use_gpu(&mut self, gpu: Option<Arc<GpuContext>>) {
        self.gpu = gpu;
    }

    fn validate(&self) -> Result<(), RealtimeError> {
        if !(self.image_budget.is_finite() && (0.0..=1.0).contains(&self.image_budget)) {
            return Err(RealtimeError::Config(format!(
                "image budget {} out of range 0..=1 (a share of the refresh period)",
                self.image_budget
            )));
        }
        let f = self.recon.ring_factor;
        if !(f.is_finite() && f > 0.0 && f <= RING_FACTOR_MAX) {
            return Err(RealtimeError::Config(format!(
                "ring factor {f} out of range (0, {RING_FACTOR_MAX}] (multiples of the pixel count)"
            )));
        }
        let r = self.recon.max_radius;
        if !MAX_RADIUS_RANGE.contains(&r) {
            return Err(RealtimeError::Config(format!(
                "largest splat radius {r} out of range [{}, {}] pixels",
                MAX_RADIUS_RANGE.start(),
                MAX_RADIUS_RANGE.end()
            )));
        }
        self.sampler
            .validate()
            .map_err(|e| RealtimeError::Config(e.to_string()))
    }
}

/// The command-line options of the adaptive method's settings; the binary flattens them
/// into `view` and `live`, and [`AdaptiveArgs::apply`] sets them, leaving the range
/// checks to [`AdaptiveSettings::validate`].
#[derive(clap::Args, Clone, Debug)]
pub struct AdaptiveArgs {
    /// Adaptive: share of a refresh period an image may take to build; when one takes
    /// longer, the next reconstructs from only the newest samples that fit (0: always
    /// the whole ring).
    #[arg(long, default_value_t = IMAGE_BUDGET, value_parser = finite_f64, allow_negative_numbers = true)]
    pub image_budget: f64,
    /// Reconstructor ring as a multiple of the pixel count [default: 2; paper: 6].
    #[arg(long, value_parser = finite_f64, allow_negative_numbers = true)]
    pub ring_factor: Option<f64>,
    /// Largest reconstruction splat radius, pixels [default: 8; paper reconstructor: 24].
    #[arg(long, value_parser = finite_f64, allow_negative_numbers = true)]
    pub max_radius: Option<f64>,
    /// No reprojection in the sampler's controller (already off in ours, which the
    /// real-time adaptive method uses).
    #[arg(long)]
    pub no_reprojection: bool,
    /// Adaptive: build a moving view's image from the samples in hand when its build
    /// starts only (default: in two parts, taking in the samples traced while it
    /// places and splats the ring).
    #[arg(long)]
    pub no_late_samples: bool,
}

impl Default for AdaptiveArgs {
    /// Nothing asked for: the method's defaults.
    fn default() -> Self {
        Self {
            image_budget: IMAGE_BUDGET,
            ring_factor: None,
            max_radius: None,
            no_reprojection: false,
            no_late_samples: false,
        }
    }
}

impl AdaptiveArgs {
    /// Set what was asked for in `settings`.
    pub fn apply(&self, settings: &mut AdaptiveSettings) {
        settings.image_budget = self.image_budget;
        settings.late_samples = !self.no_late_samples;
        if self.no_reprojection {
            settings.sampler.reprojection = false;
        }
        if let Some(f) = self.ring_factor {
            settings.recon.ring_factor = f;
        }
        if let Some(r) = self.max_radius {
            settings.recon.max_radius = r as f32;
        }
    }
}
