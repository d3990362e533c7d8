//! Where the reconstructor runs: `--recon cpu|gpu|auto`.

use std::fmt;

use serde::{Deserialize, Serialize};

pub use crate::settings::ReconDevice;

/// The reconstructor a run used, as results record it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ReconUsed {
    /// `cpu` or `gpu`.
    pub device: String,
    /// The adapter's name, driver and kind (`None` on the CPU).
    pub adapter: Option<String>,
}

impl ReconUsed {
    /// The CPU reconstructor.
    pub fn cpu() -> Self {
        Self {
            device: "cpu".into(),
            adapter: None,
        }
    }
}

impl fmt::Display for ReconUsed {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.adapter {
            Some(a) => write!(f, "{} ({a})", self.device),
            None => f.write_str(&self.device),
        }
    }
}

#[cfg(feature = "gpu")]
pub use super::gpu::{GpuContext, GpuError};

/// A GPU device; this build has none (it was built without the `gpu` feature).
#[cfg(not(feature = "gpu"))]
#[derive(Debug)]
pub enum GpuContext {}

#[cfg(not(feature = "gpu"))]
impl GpuContext {
    /// The adapter in words.
    pub fn describe(&self) -> String {
        match *self {}
    }

    /// What results record of it.
    pub fn used(&self) -> ReconUsed {
        match *self {}
    }
}

/// Why no GPU reconstructor could be had.
#[cfg(not(feature = "gpu"))]
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// This build has no GPU reconstructor.
    #[error(
        "this build has no GPU reconstructor (built without the 'gpu' feature); reconstruct on the CPU"
    )]
    NotBuilt,
}

/// The GPU device `choice` asks for: `Ok(None)` for `cpu`, and for `auto` where there
/// is no hardware adapter (or, without the `gpu` feature, no GPU support); an error
/// for `gpu` where there is no adapter at all.
pub fn acquire(choice: ReconDevice) -> Result<Option<std::sync::Arc<GpuContext>>, GpuError> {
    #[cfg(feature = "gpu")]
    {
        GpuContext::acquire(choice)
    }
    #[cfg(not(feature = "gpu"))]
    match choice {
        ReconDevice::Gpu => Err(GpuError::NotBuilt),
        ReconDevice::Cpu | ReconDevice::Auto => Ok(None),
    }
}
