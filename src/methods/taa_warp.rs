//! `taa-warp`: the temporal upsampler (`taa`) whose newest frame is warped at every
//! display refresh to the camera of the refresh time, as a late-warping engine shows a
//! TAA image. The warp is `late_warp::Warp` (depth, camera change and object velocity
//! × age; misses by rotation only; depth test; holes from neighbours). Like every late
//! warp it runs on the display side and traces no rays.

use super::{
    late_warp::Warp,
    sixty_per_second,
    taa::{Taa, TaaParams},
    Budget, Displayed, Method, MethodContext, MethodError, MethodInfo,
};

/// `taa-warp`.
pub const TAA_WARP: MethodInfo = MethodInfo {
    name: "taa-warp",
    description: "taa with its newest frame warped to the display-time camera at every refresh (display-side, no rays)",
    budget: Budget::Rate,
    check_rate: |_, rate| sixty_per_second("taa-warp", rate),
    build: |ctx| Ok(Box::new(TaaWarp::new(ctx)?)),
};

/// `taa` warped to every refresh.
pub struct TaaWarp {
    ctx: MethodContext,
    taa: Taa,
    warp: Warp,
}

impl TaaWarp {
    /// Create for one run.
    pub fn new(ctx: &MethodContext) -> Result<Self, MethodError> {
        let (w, h) = ctx.tracer.size();
        Ok(Self {
            ctx: ctx.clone(),
            taa: Taa::new(ctx, TaaParams::default())?,
            warp: Warp::new(w, h),
        })
    }
}

impl Method for TaaWarp {
    fn display(&mut self, t: f64) -> Displayed<'_> {
        let mean_age = self.taa.display(t).mean_age;
        let Some(gbuffer) = self.taa.shown_gbuffer() else {
            return Displayed {
                image: self.taa.output(),
                mean_age,
            };
        };
        let camera = self.ctx.tracer.state_at(t).camera;
        // Warping predicts where old information is now; it adds none, so the age is
        // the upsampler's.
        Displayed {
            image: self.warp.apply(self.taa.output(), gbuffer, t, &camera),
            mean_age,
        }
    }

    fn samples_used(&self) -> u64 {
        self.taa.samples_used()
    }

    fn trace_seconds(&self) -> f64 {
        self.taa.trace_seconds()
    }
}
