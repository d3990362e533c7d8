//! The real-time parallel pipeline (as the OptiX adaptive frameless renderer runs it),
//! the interactive viewer and its headless mode.
//!
//! Scene time follows the wall clock ([`clock`]). Several sampling threads trace samples
//! concurrently, each at the current time; per-pixel exclusion ([`pixel_locks`])
//! guarantees two threads never sample the same pixel at once. An image thread
//! ([`pipeline`]) builds images at the display rate, concurrently with sampling; the
//! display (the [`viewer`] window or the [`headless`] loop) presents the newest image at
//! every refresh and never waits for one.
//!
//! Each real-time method is one file or folder: [`adaptive`] (the adaptive sampler,
//! whose tiling and deep buffer live on controller threads each owning the ordinary
//! [`Sampler`](crate::methods::adaptive::Sampler) of a band, and the adaptive
//! reconstructor), [`frameless`] (traditional frameless), [`framed`] (double-buffered
//! frames, and their late warp) and [`taa`] (the temporal upsampler, and its late
//! warp). Each describes itself in one constant (name, default threads, overlays, how
//! it starts with its own settings) that the [`registry`] maps its [`RtMethod`] variant
//! to; the registry also makes [`RtSettings`], a variant per method holding that
//! method's own settings. [`RtConfig`] holds only what every method shares. Adding a
//! method is its file and a line in the registry (and the file's `mod` line here).
//!
//! Files depend downwards only: `error`, `clock`, `machine` (CPU time and load of the
//! machine), `camera`, `pixel_locks` ← `config` (the shared settings) ← `pacing`,
//! `shared` (what all threads of a pipeline share; the interface of a method) ← the
//! method files ← `registry` ← `pipeline` ← `headless`, `viewer`, `record` (every
//! refresh of a window kept with its scan-out time, for the live evaluation) ← this
//! file, which only declares and re-exports.
//!
//! Unlike the evaluation, nothing here is deterministic: the sample count depends on
//! the machine and on scheduling.

pub mod adaptive;
pub mod camera;
pub mod clock;
pub mod config;
mod error;
pub mod framed;
pub mod frameless;
pub mod headless;
pub mod machine;
pub mod pacing;
pub mod pipeline;
pub mod pixel_locks;
#[cfg(test)]
mod probe;
pub mod record;
pub mod registry;
mod shared;
pub mod taa;
pub mod viewer;

pub use adaptive::{AdaptiveArgs, AdaptiveSettings, AdaptiveTuning};
pub use camera::{CameraRecorder, FlyCamera};
pub use clock::WallClock;
pub use config::{RealtimeError, RtConfig};
pub use headless::{run_headless, HeadlessOptions, HeadlessStats};
pub use pipeline::{Frame, Pipeline, PipelineStats};
pub use pixel_locks::{PixelGuard, PixelLocks};
pub use registry::{RtMethod, RtSettings, Visualisation};
pub use shared::{MethodSettings, NoSettings, Overlay, Overlays};
pub use viewer::{run_viewer, ViewerOptions};
