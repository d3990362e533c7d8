//! Rendering methods compared by the evaluation: one file per method, one enum naming
//! them all. Adding a method means a new file, a variant of [`MethodKind`] and one arm in
//! [`MethodKind::build`].
//!
//! A method is driven by the simulated [`Clock`]: it may trace the samples the budget
//! allows up to a display time and must then say what the display shows at that time.

pub mod adaptive;
pub mod framed;
pub mod frameless;
pub mod ideal;
pub mod point_tracking;
pub mod taa;

use std::sync::Arc;

use crate::{clock::Clock, image::Image, trace::Tracer};

/// The methods `frameless eval --methods` accepts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum MethodKind {
    /// The gold standard: zero delay, stratified supersampling.
    Ideal,
    /// Framed, double-buffered at 60 Hz, reduced resolution, upscaled.
    Framed60Hz,
    /// Framed, double-buffered, one sample per display pixel, frame rate R/(W·H).
    FramedFull,
    /// Framed full resolution at 60 Hz with its own budget W·H·60 (whatever the rate).
    FullRes60Hz,
    /// Bishop et al.: random pixel order, newest sample per pixel.
    TraditionalFrameless,
    /// Adaptive frameless rendering (the paper's method).
    Adaptive,
    /// Adaptive without reprojection in the sampler (paper Fig. 8's ablation).
    AdaptiveNoReprojection,
    /// Adaptive whose sampler leaves crosshairs that cannot have moved in place (no
    /// occlusion ray spent on them; not in the paper).
    AdaptiveKeepStatic,
    /// Adaptive whose reconstructor splats samples where they were traced.
    AdaptiveNoReprojRecon,
    /// Adaptive whose reconstructor uses a fixed, non-adaptive filter.
    AdaptiveFixedFilter,
    /// Point tracking (Martin et al. 2002) with the three-frame blend.
    PointTracking,
    /// Point tracking without the blend.
    PointTrackingNoBlend,
    /// TAA / temporal upsampling at 60 Hz.
    Taa,
}

impl MethodKind {
    /// Every method, in report order.
    pub const ALL: &'static [MethodKind] = &[
        MethodKind::Ideal,
        MethodKind::Framed60Hz,
        MethodKind::FramedFull,
        MethodKind::FullRes60Hz,
        MethodKind::TraditionalFrameless,
        MethodKind::Adaptive,
        MethodKind::AdaptiveNoReprojection,
        MethodKind::AdaptiveKeepStatic,
        MethodKind::AdaptiveNoReprojRecon,
        MethodKind::AdaptiveFixedFilter,
        MethodKind::PointTracking,
        MethodKind::PointTrackingNoBlend,
        MethodKind::Taa,
    ];

    /// Command-line name.
    pub fn name(self) -> &'static str {
        match self {
            MethodKind::Ideal => "ideal",
            MethodKind::Framed60Hz => "framed-60hz",
            MethodKind::FramedFull => "framed-full",
            MethodKind::FullRes60Hz => "full-res-60hz",
            MethodKind::TraditionalFrameless => "traditional-frameless",
            MethodKind::Adaptive => "adaptive",
            MethodKind::AdaptiveNoReprojection => "adaptive-no-reprojection",
            MethodKind::AdaptiveKeepStatic => "adaptive-keep-static",
            MethodKind::AdaptiveNoReprojRecon => "adaptive-no-reproj-recon",
            MethodKind::AdaptiveFixedFilter => "adaptive-fixed-filter",
            MethodKind::PointTracking => "point-tracking",
            MethodKind::PointTrackingNoBlend => "point-tracking-no-blend",
            MethodKind::Taa => "taa",
        }
    }

    /// One-line description (shown by `frameless eval --help`).
    pub fn description(self) -> &'static str {
        match self {
            MethodKind::Ideal => "zero delay, stratified supersampling (the reference)",
            MethodKind::Framed60Hz => {
                "double-buffered at 60 Hz, R/60 samples per frame at reduced resolution, upscaled"
            }
            MethodKind::FramedFull => "double-buffered, one sample per pixel, frame rate R/(W*H)",
            MethodKind::FullRes60Hz => {
                "double-buffered full resolution at 60 Hz; budget W*H*60 regardless of the rate"
            }
            MethodKind::TraditionalFrameless => {
                "random pixel order, each sample at its own time, newest sample per pixel"
            }
            MethodKind::Adaptive => {
                "adaptive frameless: closed-loop sampler over a K-D tiling of a deep buffer"
            }
            MethodKind::AdaptiveNoReprojection => {
                "adaptive frameless without reprojection in the sampler"
            }
            MethodKind::AdaptiveKeepStatic => {
                "adaptive frameless; the sampler does not reproject crosshairs that cannot have moved"
            }
            MethodKind::AdaptiveNoReprojRecon => {
                "adaptive frameless without reprojection in the reconstructor"
            }
            MethodKind::AdaptiveFixedFilter => {
                "adaptive frameless with a fixed reconstruction filter (1 px, 0.1 s)"
            }
            MethodKind::PointTracking => {
                "framed full resolution, rays aimed at the previous frame's hit points, last 3 frames averaged"
            }
            MethodKind::PointTrackingNoBlend => "point tracking showing only the newest frame",
            MethodKind::Taa => {
                "60 Hz at reduced resolution, Halton jitter, reprojected clamped history, blend 0.1"
            }
        }
    }

    /// Parse a command-line name.
    pub fn parse(s: &str) -> Result<Self, String> {
        Self::ALL
            .iter()
            .copied()
            .find(|m| m.name() == s)
            .ok_or_else(|| {
                format!(
                    "unknown method `{s}`; methods are: {}",
                    Self::ALL
                        .iter()
                        .map(|m| m.name())
                        .collect::<Vec<_>>()
                        .join(", ")
                )
            })
    }

    /// Whether the method ignores the sample rate (so one run serves every rate).
    pub fn rate_independent(self) -> bool {
        matches!(self, MethodKind::Ideal | MethodKind::FullRes60Hz)
    }

    /// Build the method for one evaluation run.
    pub fn build(self, ctx: &MethodContext) -> Result<Box<dyn Method>, String> {
        Ok(match self {
            MethodKind::Ideal => Box::new(ideal::Ideal::new(ctx)),
            MethodKind::Framed60Hz => Box::new(framed::Framed::sixty_hz(ctx)?),
            MethodKind::FramedFull => Box::new(framed::Framed::full_res(ctx)?),
            MethodKind::FullRes60Hz => Box::new(framed::Framed::full_res_60hz(ctx)?),
            MethodKind::TraditionalFrameless => Box::new(frameless::Traditional::new(ctx)),
            MethodKind::Adaptive => Box::new(adaptive::Adaptive::new(
                ctx,
                adaptive::SamplerParams::paper(),
            )?),
            MethodKind::AdaptiveNoReprojection => Box::new(adaptive::Adaptive::new(
                ctx,
                adaptive::SamplerParams::no_reprojection(),
            )?),
            MethodKind::AdaptiveKeepStatic => Box::new(adaptive::Adaptive::new(ctx, {
                let mut p = adaptive::SamplerParams::paper();
                p.skip_static_reprojection = true;
                p
            })?),
            MethodKind::AdaptiveNoReprojRecon => Box::new(adaptive::Adaptive::with_reconstructor(
                ctx,
                adaptive::SamplerParams::paper(),
                crate::reconstruction::ReconParams::no_reprojection(),
            )?),
            MethodKind::AdaptiveFixedFilter => Box::new(adaptive::Adaptive::with_reconstructor(
                ctx,
                adaptive::SamplerParams::paper(),
                crate::reconstruction::ReconParams::fixed_filter(),
            )?),
            MethodKind::PointTracking => Box::new(point_tracking::PointTracking::new(ctx, true)),
            MethodKind::PointTrackingNoBlend => {
                Box::new(point_tracking::PointTracking::new(ctx, false))
            }
            MethodKind::Taa => Box::new(taa::Taa::new(ctx)?),
        })
    }
}

/// Everything a method needs to run.
#[derive(Clone)]
pub struct MethodContext {
    /// The tracer (scene, image size, camera).
    pub tracer: Arc<Tracer>,
    /// The simulated clock with this run's sample rate.
    pub clock: Clock,
    /// Seed of every random choice.
    pub seed: u64,
    /// Samples per pixel of ideal images.
    pub ideal_spp: u32,
    /// Where ideal images are cached, if anywhere.
    pub ideal_cache: Option<Arc<crate::render::cache::IdealCache>>,
}

/// What the display shows at one refresh.
pub struct Displayed<'a> {
    /// The displayed image (linear; the evaluation clamps and quantizes it).
    pub image: &'a Image,
    /// Mean over pixels of (display time − time the pixel's information was sampled).
    pub mean_age: f64,
}

/// A rendering method under the simulated clock.
pub trait Method: Send {
    /// Trace whatever the budget allows up to display time `t` (non-decreasing across
    /// calls) and return what the display shows then.
    fn display(&mut self, t: f64) -> Displayed<'_>;
    /// Samples traced so far.
    fn samples_used(&self) -> u64;
    /// Wall-clock seconds spent tracing rays so far (the rest of a method's time is
    /// its own overhead).
    fn trace_seconds(&self) -> f64;
    /// Method-specific statistics for the summary (e.g. point tracking's histogram).
    fn extra_stats(&self) -> Option<serde_json::Value> {
        None
    }
}

/// Mean age of per-pixel information times at display time `t`.
pub fn mean_age(info_time: &[f64], t: f64) -> f64 {
    if info_time.is_empty() {
        return 0.0;
    }
    info_time.iter().map(|&s| t - s).sum::<f64>() / info_time.len() as f64
}
