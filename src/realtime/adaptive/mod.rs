//! The real-time adaptive method: adaptive sampling threads, controller threads that
//! each own the tiling and the deep buffer of one band of the image, and the adaptive
//! space-time reconstructor on the image thread.
//!
//! ```text
//!  sampling ×N ──crosshairs, initiating samples──► controller ×K, one per band of rows
//!      ▲             (to the band of the tile)     (Sampler: deep buffer, tiling,
//!      │                                            gain control, reprojection)
//!      └──── tile snapshots (Arc, ~1 ms) ◄──────────┘   │ samples + tiling snapshot
//!                                                       ▼
//!                                     image thread: Reconstructor at the display rate
//! ```
//!
//! A sampling thread visits a tile of the published snapshots (the bands' tiles taken
//! together): it completes the crosshair the tile's pending sample initiated, its
//! temporal gradient measured where its surface point is now
//! ([`completion_point`](crate::methods::adaptive::sampler::completion_point), as the
//! sequential sampler; taking its five pixels) and initiates the next one at a random
//! location in the tile (taking that pixel). A taken pixel means another thread is
//! there: it picks another tile or location.
//!
//! A controller holds an ordinary [`Sampler`](crate::methods::adaptive::Sampler) for
//! its band ([`Sampler::for_region`](crate::methods::adaptive::Sampler::for_region))
//! and feeds it what the sampling threads traced there: completed crosshairs (inserted,
//! with tile statistics updated and the tiling adjusted after every chunk, exactly as
//! in a sequential visit) and initiating samples (which become their tile's pending
//! crosshair). The reprojection step of each visit runs there too, occlusion rays
//! included — but only while the controller keeps up with its input: when batches
//! queue up it skips reprojection for that batch, so that the tiling never lags behind
//! the samples (the share that ran is reported). About every millisecond it publishes
//! its tiles for the sampling threads, and at twice the display rate a snapshot of its
//! tiling for the reconstructor's filters.
//!
//! One controller takes in the samples of a few sampling threads
//! ([`THREADS_PER_CONTROLLER`]); with more threads the image is cut into bands of
//! rows, one controller each, so that no one thread touches every sample. Each band
//! adapts its own tiles and tile count; samples go to the bands in proportion to their
//! tiles, since a sampling thread draws among all tiles alike. A sampler that reprojects
//! crosshairs keeps one band (a crosshair may move anywhere in the image).
//!
//! The reconstructor's filters need the sample rate; the image builder measures it.

mod bench;
mod builder;
mod controller;
mod overlays;
mod published;
mod sampling;
pub mod settings;
#[cfg(test)]
mod tests;

use std::sync::Arc;

use crossbeam_channel::bounded;

pub use bench::{controller_bench, ControllerBench};
pub use published::{bands, controllers, controllers_for, THREADS_PER_CONTROLLER};
pub use settings::{AdaptiveArgs, AdaptiveSettings, AdaptiveTuning};

use crate::realtime::{
    config::RealtimeError,
    shared::{ImageBuilder, MethodInfo, Pooled, Spawner},
};
use builder::Builder;
use published::Published;

/// The adaptive method's description.
pub(crate) const METHOD: MethodInfo<AdaptiveSettings> = MethodInfo {
    name: settings::NAME,
    about: "adaptive sampler + adaptive space-time reconstructor",
    // One sampling thread per core, as the other methods: sampling threads run below
    // the controllers and the image thread, so they take only the time those leave
    // (on 2 cores, 1.3 times the samples of one thread per core but one, at the same
    // image rate; docs/performance.md).
    default_sampling_threads: |cores| cores,
    extra_threads: controllers_for,
    overlays: overlays::OVERLAYS,
    traces_on_gpu: true,
    // Its buffers (deep buffer, ring) include the display check.
    check_size: |_, a, w, h| crate::methods::adaptive::check_budget(w, h, &a.sampler, &a.recon),
    start,
};

fn start(
    sp: &mut Spawner<'_>,
    settings: &AdaptiveSettings,
) -> Result<Box<dyn ImageBuilder>, RealtimeError> {
    let s = sp.shared().clone();
    // The reconstructor first: a GPU too small for the display is refused before any
    // thread starts.
    let recon = builder::reconstructor(&s, settings)?;
    let published = Arc::new(Published::new(&s, settings.clone()));
    // Channels are bounded so that a slow consumer slows its producers instead of
    // growing memory without limit. A controller's holds about 32 ms of batches from
    // every sampling thread; the image thread's about half a second of every
    // controller's messages (one per `controller::PASS_ON_EVERY`), divided among the controllers.
    let (to_img, img_rx) = bounded(256);
    let (mut to_ctrl, mut ctrl_rx) = (Vec::new(), Vec::new());
    for _ in &published.bands {
        let (tx, rx) = bounded(32 * s.config.sampling_threads.max(1));
        to_ctrl.push(tx);
        ctrl_rx.push(rx);
    }
    // Before the first thread starts the pipeline's clock.
    let samplers = controller::band_samplers(&s, &published)?;
    let (s1, p1) = (s.clone(), published.clone());
    sp.sampling_threads(to_ctrl, move |i, tx| sampling::sample(&s1, &p1, i, tx))?;
    for (band, rx) in samplers.into_iter().enumerate().zip(ctrl_rx) {
        let (s2, p2, tx) = (s.clone(), published.clone(), to_img.clone());
        sp.spawn("controller", move || {
            controller::control(&s2, &p2, band, rx, tx)
        })?;
    }
    // The builder owns its reconstructor, on the settings' device, and the pool the
    // reconstructor splats on.
    let builder = Builder::new(s.clone(), published, img_rx, recon);
    Ok(Box::new(Pooled::new(&s.config, builder)))
}
