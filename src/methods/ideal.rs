//! The gold standard: the exact image at each refresh time, antialiased by stratified
//! supersampling, with zero delay. Not a contender; viewable as a method.

use super::{any_rate, Budget, Displayed, Method, MethodContext, MethodInfo};
use crate::{
    image::Image,
    render::cache::{self, Lookup},
};

/// `ideal`: every refresh supersampled, held to no budget.
pub const IDEAL: MethodInfo = MethodInfo {
    name: "ideal",
    description: "zero delay, stratified supersampling (the reference)",
    budget: Budget::Unbounded(|s| s.pixels() * s.ideal_spp as f64 * s.refresh_hz),
    check_rate: any_rate,
    build: |ctx| Ok(Box::new(Ideal::new(ctx))),
};

/// The ideal renderer.
pub struct Ideal {
    ctx: MethodContext,
    image: Image,
    samples: u64,
    trace_s: f64,
}

impl Ideal {
    /// Create for one run.
    pub fn new(ctx: &MethodContext) -> Self {
        let (w, h) = ctx.tracer.size();
        Self {
            ctx: ctx.clone(),
            image: Image::new(w, h),
            samples: 0,
            trace_s: 0.0,
        }
    }
}

/// Render (or fetch from the cache) the ideal image at time `t`, on the run's tracer.
pub fn ideal_image(ctx: &MethodContext, t: f64) -> Image {
    ideal_lookup(ctx, t).0
}

/// [`ideal_image`], and what the cache found (`Miss` without a cache).
pub fn ideal_lookup(ctx: &MethodContext, t: f64) -> (Image, Lookup) {
    cache::ideal_image(
        ctx.ideal_cache.as_deref(),
        &ctx.tracer,
        ctx.rays.as_deref(),
        t,
        ctx.ideal_spp,
        ctx.seed,
    )
}

impl Method for Ideal {
    fn display(&mut self, t: f64) -> Displayed<'_> {
        let t0 = std::time::Instant::now();
        self.image = ideal_image(&self.ctx, t);
        self.trace_s += t0.elapsed().as_secs_f64();
        self.samples += self.image.pixels.len() as u64 * self.ctx.ideal_spp as u64;
        Displayed {
            image: &self.image,
            mean_age: 0.0,
        }
    }
    fn samples_used(&self) -> u64 {
        self.samples
    }
    fn trace_seconds(&self) -> f64 {
        self.trace_s
    }
}
