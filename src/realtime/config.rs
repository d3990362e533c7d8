//! The settings every method of one pipeline run shares (and its errors, from
//! `error.rs`): the vocabulary every file of the real-time mode reads, below the
//! methods and the pipeline. Which methods exist, and the settings of each, are the
//! registry's business (`registry.rs`), not this file's.

pub use super::error::RealtimeError;

/// The settings of one pipeline run that every method shares.
#[derive(Clone, Debug)]
pub struct RtConfig {
    /// Sampling threads (besides the method's other threads and the image thread).
    pub sampling_threads: usize,
    /// Threads a method's image builds may use in parallel (the reconstructor's
    /// splatting, a warp, a fold: a pool of their own, so that building cannot take
    /// every core from sampling and the display).
    pub recon_threads: usize,
    /// Display refresh rate, Hz: the image thread builds at most this often.
    pub refresh_hz: f64,
    /// Scene time when the pipeline starts.
    pub start: f64,
    /// Seed of the threads' random choices.
    pub seed: u64,
    /// The GPU tracer of the pipeline's tracer (`--trace gpu`; `None`: the CPU). With
    /// it, the methods that can trace on it do so from one sampling thread, in batches
    /// (the GPU runs one batch at a time; more threads would only queue).
    pub rays: Option<std::sync::Arc<crate::trace::batch::GpuRays>>,
    /// Whether the sampling threads trace a moving view where the camera's past poses
    /// say it will be when what they trace is shown ([`crate::trace::Tracer::state_at_ahead`]):
    /// each method measures how long after their trace its images show its samples
    /// (`--no-view-ahead`: where the view is now).
    pub view_ahead: bool,
}

impl RtConfig {
    /// Take the settings every run shares from their groups: the refresh rate and the
    /// seed (the size is the tracer's; the tracer takes the rest of `quality`).
    pub fn set_groups(
        &mut self,
        display: &crate::settings::DisplayGroup,
        quality: &crate::settings::QualityGroup,
    ) {
        self.refresh_hz = display.refresh_hz;
        self.seed = quality.seed;
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
        Ok(())
    }
}
