//! Adaptive frameless rendering (Dayal et al. 2005): the closed-loop sampler over a K-D
//! tiling of a temporally deep buffer. The display is the adaptive space-time
//! reconstructor ([`crate::reconstruction`]) fed by the sampler's stream, with filters
//! from the sampler's tiling; the reported mean age is the pixel mean of the
//! weight-averaged sample age of the reconstruction.

pub mod deep_buffer;
pub mod outputs;
pub mod params;
pub mod sampler;
pub mod tiling;
pub mod vis;

use std::sync::Arc;

use super::{Budget, RunShape, Displayed, Method, MethodContext, MethodError, MethodInfo};
use crate::{
    reconstruction::{ReconParams, Reconstructor},
    trace::Tracer,
};
pub use params::SamplerParams;
pub use sampler::Sampler;

/// Whether the sampler's deep buffer and the reconstructor's ring fit the run budgets
/// ([`crate::limits`]) on a `width × height` display, before either is allocated.
pub fn check_budget(
    width: u32,
    height: u32,
    sampler: &SamplerParams,
    recon: &ReconParams,
) -> Result<(), crate::limits::LimitError> {
    deep_buffer::DeepBuffer::check_budget(width, height, sampler.depth)?;
    Reconstructor::check_budget(width, height, recon)
}

/// [`check_budget`] at a run's display size: checked when an evaluation's settings
/// are, before any work.
fn fits(shape: &RunShape, sampler: SamplerParams, recon: ReconParams) -> Result<(), MethodError> {
    check_budget(shape.width, shape.height, &sampler, &recon).map_err(MethodError::Budget)
}

/// `adaptive`: ours, the paper's method that keeps converging where the view is still.
pub const ADAPTIVE: MethodInfo = MethodInfo {
    name: "adaptive",
    description: "adaptive frameless (ours): closed-loop sampler over a K-D tiling of a deep buffer, space-time reconstruction with a still-region history",
    budget: Budget::Rate,
    check_rate: |shape, _| fits(shape, SamplerParams::ours(), ReconParams::realtime()),
    build: |ctx| Ok(Box::new(Adaptive::new(ctx, SamplerParams::ours())?)),
};

/// `adaptive-paper`: the paper's sampler and reconstructor, as published.
pub const ADAPTIVE_PAPER: MethodInfo = MethodInfo {
    name: "adaptive-paper",
    description: "adaptive frameless as in the paper: every crosshair reprojected, no history",
    budget: Budget::Rate,
    check_rate: |shape, _| fits(shape, SamplerParams::paper(), ReconParams::paper()),
    build: |ctx| {
        Ok(Box::new(Adaptive::with_reconstructor(
            ctx,
            SamplerParams::paper(),
            ReconParams::paper(),
        )?))
    },
};

/// `adaptive-no-reprojection`: the ablation of paper Fig. 8, of the paper's method
/// (ours reprojects no crosshair).
pub const ADAPTIVE_NO_REPROJECTION: MethodInfo = MethodInfo {
    name: "adaptive-no-reprojection",
    description: "adaptive frameless as in the paper without reprojection in the sampler (the paper's Fig. 8 ablation)",
    budget: Budget::Rate,
    check_rate: |shape, _| fits(shape, SamplerParams::no_reprojection(), ReconParams::paper()),
    build: |ctx| {
        Ok(Box::new(Adaptive::with_reconstructor(
            ctx,
            SamplerParams::no_reprojection(),
            ReconParams::paper(),
        )?))
    },
};

/// `adaptive-no-history`: ours without the still-region history.
pub const ADAPTIVE_NO_HISTORY: MethodInfo = MethodInfo {
    name: "adaptive-no-history",
    description: "adaptive frameless without the reconstructor's still-region history",
    budget: Budget::Rate,
    check_rate: |shape, _| fits(shape, SamplerParams::ours(), ReconParams::paper()),
    build: |ctx| {
        Ok(Box::new(Adaptive::with_reconstructor(
            ctx,
            SamplerParams::ours(),
            ReconParams::paper(),
        )?))
    },
};

/// `adaptive-no-reproj-recon`: the reconstructor splats samples where they were traced.
pub const ADAPTIVE_NO_REPROJ_RECON: MethodInfo = MethodInfo {
    name: "adaptive-no-reproj-recon",
    description: "adaptive frameless without reprojection in the reconstructor",
    budget: Budget::Rate,
    check_rate: |shape, _| fits(shape, SamplerParams::ours(), ReconParams::no_reprojection()),
    build: |ctx| {
        Ok(Box::new(Adaptive::with_reconstructor(
            ctx,
            SamplerParams::ours(),
            ReconParams::no_reprojection(),
        )?))
    },
};

/// `adaptive-fixed-filter`: the reconstructor's filter does not adapt.
pub const ADAPTIVE_FIXED_FILTER: MethodInfo = MethodInfo {
    name: "adaptive-fixed-filter",
    description: "adaptive frameless with a fixed reconstruction filter (1 px, 0.1 s)",
    budget: Budget::Rate,
    check_rate: |shape, _| fits(shape, SamplerParams::ours(), ReconParams::fixed_filter()),
    build: |ctx| {
        Ok(Box::new(Adaptive::with_reconstructor(
            ctx,
            SamplerParams::ours(),
            ReconParams::fixed_filter(),
        )?))
    },
};

/// The `adaptive` method of the evaluation (and its ablations).
pub struct Adaptive {
    sampler: Sampler,
    recon: Reconstructor,
    tracer: Arc<Tracer>,
}

impl Adaptive {
    /// Create for one run with the given sampler parameters and our reconstructor as
    /// `frameless live` and `view` run it ([`ReconParams::realtime`]), so that the
    /// simulated figures describe the images a person sees live.
    pub fn new(ctx: &MethodContext, params: SamplerParams) -> Result<Self, MethodError> {
        Self::with_reconstructor(ctx, params, ReconParams::realtime())
    }

    /// Create for one run with the given sampler and reconstructor parameters.
    pub fn with_reconstructor(
        ctx: &MethodContext,
        params: SamplerParams,
        recon: ReconParams,
    ) -> Result<Self, MethodError> {
        let (w, h) = ctx.tracer.size();
        Reconstructor::check_budget(w, h, &recon).map_err(MethodError::Budget)?;
        if let Some(Err((name, why))) = recon.history.map(|h| h.check()) {
            return Err(MethodError::Parameter {
                group: "reconstructor",
                name,
                why,
            });
        }
        let mut reconstructor = Reconstructor::new(w, h, ctx.clock.rate, recon);
        if let Some(gpu) = &ctx.gpu {
            // Named by the registry ([`super::MethodKind::build`]); `adaptive` when
            // built directly.
            reconstructor
                .use_gpu(gpu.clone())
                .map_err(|e| MethodError::Gpu {
                    method: ADAPTIVE.name,
                    why: e.to_string(),
                })?;
        }
        Ok(Self {
            sampler: Sampler::new(ctx.tracer.clone(), ctx.clock, params, ctx.seed)?
                .with_gpu_rays(ctx.rays.clone()),
            recon: reconstructor,
            tracer: ctx.tracer.clone(),
        })
    }

    /// The sampler (for visualisations and statistics).
    pub fn sampler(&self) -> &Sampler {
        &self.sampler
    }

    /// The reconstructor.
    pub fn reconstructor(&self) -> &Reconstructor {
        &self.recon
    }

    /// The reconstructor, for what it reads back on request (its coverage and splat
    /// scales, which a GPU keeps).
    pub fn reconstructor_mut(&mut self) -> &mut Reconstructor {
        &mut self.recon
    }
}

impl Method for Adaptive {
    fn display(&mut self, t: f64) -> Displayed<'_> {
        self.sampler.run_until(t);
        let stream = self.sampler.drain_stream();
        self.recon.push_stream(&stream);
        let state = self.tracer.state_at(t);
        let camera = state.camera;
        self.recon.set_motion(Some(state));
        self.recon.set_view_since(self.sampler.camera_since());
        self.recon
            .reconstruct(t, &camera, &self.sampler.tiling().snapshot());
        if self.sampler.params().discount_converged {
            if let Some(counts) = self.recon.history_counts() {
                self.sampler.set_history_counts(counts);
            }
        }
        Displayed {
            image: self.recon.image(),
            mean_age: self.recon.mean_age(),
        }
    }

    fn samples_used(&self) -> u64 {
        self.sampler.samples_used()
    }

    fn trace_seconds(&self) -> f64 {
        self.sampler.timing().0
    }

    /// Why the GPU reconstructor was given up during the run (its refreshes then ran
    /// on the CPU), if it was.
    fn extra_stats(&self) -> Option<serde_json::Value> {
        self.recon
            .gpu_failure()
            .map(|why| serde_json::json!({ "gpu_failure": why }))
    }
}
