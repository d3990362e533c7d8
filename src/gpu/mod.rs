//! The GPU device shared by every GPU stage: the reconstructor (`--recon`) and the
//! tracer (`--trace`). A bottom-layer module, so that both `trace` and
//! `reconstruction` reach it without importing each other.
//!
//! With the `gpu` feature (the default) this is wgpu's adapter and device
//! ([`GpuContext`]); without it, a [`GpuContext`] that cannot exist and a
//! `GpuError::NotBuilt`, so that callers compile unchanged and `gpu` choices fail
//! with a clear message.

use std::{fmt, sync::Arc};

use serde::{Deserialize, Serialize};

use crate::settings::ReconDevice;

#[cfg(feature = "gpu")]
mod context;

#[cfg(feature = "gpu")]
pub use context::{GpuContext, GpuError};

/// The device a GPU-capable stage used, as results record it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct DeviceUsed {
    /// `cpu` or `gpu`.
    pub device: String,
    /// The adapter's name, driver and kind (`None` on the CPU).
    pub adapter: Option<String>,
}

impl DeviceUsed {
    /// The CPU.
    pub fn cpu() -> Self {
        Self {
            device: "cpu".into(),
            adapter: None,
        }
    }
}

impl fmt::Display for DeviceUsed {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.adapter {
            Some(a) => write!(f, "{} ({a})", self.device),
            None => f.write_str(&self.device),
        }
    }
}

/// The GPUs a run works on, each acquired once for the whole run from its
/// [`DevicesGroup`](crate::settings::DevicesGroup) (`--recon`, `--trace`); `None` is
/// the CPU, the reference. The default is the CPU for both.
#[derive(Clone, Debug, Default)]
pub struct Devices {
    /// The GPU the adaptive methods reconstruct on.
    pub recon: Option<Arc<GpuContext>>,
    /// The GPU samples, and the ideal images, are traced on.
    pub trace: Option<Arc<GpuContext>>,
}

impl Devices {
    /// What results record of the reconstructor's device.
    pub fn recon_used(&self) -> DeviceUsed {
        self.recon
            .as_ref()
            .map_or_else(DeviceUsed::cpu, |g| g.used())
    }

    /// What results record of the tracer's device.
    pub fn trace_used(&self) -> DeviceUsed {
        self.trace
            .as_ref()
            .map_or_else(DeviceUsed::cpu, |g| g.used())
    }
}

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

    /// Whether the adapter is a software one.
    pub fn is_software(&self) -> bool {
        match *self {}
    }

    /// What results record of it.
    pub fn used(&self) -> DeviceUsed {
        match *self {}
    }
}

/// Why no GPU could be had.
#[cfg(not(feature = "gpu"))]
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// This build has no GPU support.
    #[error("this build has no GPU support (built without the 'gpu' feature); run on the CPU")]
    NotBuilt,
}

/// The GPU device `choice` asks for: `Ok(None)` for `cpu`, and for `auto` where there
/// is no hardware adapter (or, without the `gpu` feature, no GPU support); an error
/// for `gpu` where there is no adapter at all.
pub fn acquire(choice: ReconDevice) -> Result<Option<Arc<GpuContext>>, GpuError> {
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
