//! The settings of one pipeline run (and its errors, from `error.rs`): the vocabulary every file of the
//! real-time mode shares, below the methods and the pipeline. Which methods exist and
//! what each needs is the registry's business (the parent module), not this file's.

use super::adaptive::settings::AdaptiveSettings;
pub use super::{error::RealtimeError, RtMethod};

/// Settings of one pipeline run.
#[derive(Clone, Debug)]
pub struct RtConfig {
    /// What to render.
    pub method: RtMethod,
    /// Sampling threads (besides the method's other threads and the image thread).
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
    /// The adaptive method's own settings (read by it alone).
    pub adaptive: AdaptiveSettings,
}

impl RtConfig {
    /// Check that a `width × height` display fits the run budgets ([`crate::limits`])
    /// with this method's buffers, before any thread allocates them.
    pub fn check_size(&self, width: u32, height: u32) -> Result<(), RealtimeError> {
        (self.method.info().check_size)(self, width, height)
            .map_err(|e| RealtimeError::Config(e.to_string()))
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
        if let Err(why) = crate::limits::check_refresh_hz(self.refresh_hz) {
            return Err(RealtimeError::Config(format!("refresh rate {why}")));
        }
        if !self.start.is_finite() {
            return Err(RealtimeError::Config("start time must be finite".into()));
        }
        self.adaptive.validate()
    }
}
