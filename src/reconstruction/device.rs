//! Where the reconstructor runs: `--recon cpu|gpu|auto`.

use std::{fmt, str::FromStr};

use serde::{Deserialize, Serialize};

/// Which reconstructor a run asks for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ReconDevice {
    /// The CPU reconstructor, the reference.
    #[default]
    Cpu,
    /// The compute-shader reconstructor on any adapter, a software one included; an
    /// error where there is none.
    Gpu,
    /// A hardware GPU adapter where there is one, the CPU otherwise.
    Auto,
}

impl ReconDevice {
    /// Every choice, in the order the help lists them.
    pub const ALL: [ReconDevice; 3] = [Self::Cpu, Self::Gpu, Self::Auto];

    /// The name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Self::Cpu => "cpu",
            Self::Gpu => "gpu",
            Self::Auto => "auto",
        }
    }
}

impl fmt::Display for ReconDevice {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for ReconDevice {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|d| d.name() == s)
            .ok_or_else(|| format!("unknown reconstructor '{s}': expected cpu, gpu or auto"))
    }
}

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
