//! Where the reconstructor runs: `--recon cpu|gpu|auto`. The device itself lives in
//! [`crate::gpu`], shared with the tracer; re-exported here for the reconstructor's
//! callers.

pub use crate::gpu::{acquire, DeviceUsed as ReconUsed, GpuContext, GpuError};
pub use crate::settings::ReconDevice;
