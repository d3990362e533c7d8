//! Adaptive frameless rendering (Dayal et al. 2005): the closed-loop sampler over a K-D
//! tiling of a temporally deep buffer. The display is the adaptive space-time
//! reconstructor ([`crate::reconstruction`]) fed by the sampler's stream, with filters
//! from the sampler's tiling; the reported mean age is the pixel mean of the
//! weight-averaged sample age of the reconstruction.

pub mod deep_buffer;
pub mod params;
pub mod sampler;
pub mod tiling;
pub mod vis;

use std::sync::Arc;

use super::{Displayed, Method, MethodContext};
use crate::{
    image::Image,
    reconstruction::{ReconParams, Reconstructor},
    trace::Tracer,
};
pub use params::SamplerParams;
pub use sampler::Sampler;

/// The `adaptive` method of the evaluation (and its ablations).
pub struct Adaptive {
    sampler: Sampler,
    recon: Reconstructor,
    tracer: Arc<Tracer>,
}

impl Adaptive {
    /// Create for one run with the given sampler parameters and the paper's
    /// reconstructor.
    pub fn new(ctx: &MethodContext, params: SamplerParams) -> Result<Self, String> {
        Self::with_reconstructor(ctx, params, ReconParams::paper())
    }

    /// Create for one run with the given sampler and reconstructor parameters.
    pub fn with_reconstructor(
        ctx: &MethodContext,
        params: SamplerParams,
        recon: ReconParams,
    ) -> Result<Self, String> {
        let (w, h) = ctx.tracer.size();
        Ok(Self {
            sampler: Sampler::new(ctx.tracer.clone(), ctx.clock, params, ctx.seed)?,
            recon: Reconstructor::new(w, h, ctx.clock.rate, recon),
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
}

/// Fill unsampled pixels from the nearest sampled one (growing rings, up to `max_r`).
pub fn fill_holes(img: &Image, sampled: &[bool], max_r: i32) -> Image {
    let (w, h) = (img.width as i32, img.height as i32);
    let mut out = img.clone();
    for y in 0..h {
        for x in 0..w {
            if sampled[(y * w + x) as usize] {
                continue;
            }
            'search: for r in 1..=max_r {
                for dy in -r..=r {
                    for dx in -r..=r {
                        if dx.abs() != r && dy.abs() != r {
                            continue;
                        }
                        let (sx, sy) = (x + dx, y + dy);
                        if sx >= 0 && sy >= 0 && sx < w && sy < h && sampled[(sy * w + sx) as usize]
                        {
                            out.pixels[(y * w + x) as usize] = img.pixels[(sy * w + sx) as usize];
                            break 'search;
                        }
                    }
                }
            }
        }
    }
    out
}

impl Method for Adaptive {
    fn display(&mut self, t: f64) -> Displayed<'_> {
        self.sampler.run_until(t);
        let stream = self.sampler.drain_stream();
        self.recon.push_stream(&stream);
        let camera = self.tracer.state_at(t).camera;
        self.recon
            .reconstruct(t, &camera, &self.sampler.tiling().snapshot());
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
}
