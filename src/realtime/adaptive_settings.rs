//! The adaptive method's own settings of a real-time run: its sampler, its
//! reconstructor and where that runs, and how long a build may take. The generic
//! [`RtConfig`](super::RtConfig) holds them as one field and never reads them.

use std::sync::Arc;

use super::error::RealtimeError;
use crate::{
    methods::adaptive::SamplerParams,
    reconstruction::{device::GpuContext, ReconParams},
};

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
            gpu: None,
        }
    }
}

impl AdaptiveSettings {
    /// Check ranges.
    pub fn validate(&self) -> Result<(), RealtimeError> {
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
