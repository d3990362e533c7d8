//! What a refresh does, decided once for both reconstructors: the CPU's passes and the
//! GPU's shaders carry out the same [`RefreshPlan`], so that they cannot disagree on
//! which samples a refresh places, whether it carries or re-splats, or what the
//! still-region history takes in.

use super::{history::Step, Reconstructor};
use crate::{scene::camera::CameraFrame, tiles::TilingSnapshot};

/// One refresh, planned.
pub(super) struct RefreshPlan {
    /// Display time.
    pub(super) t: f64,
    /// The view of the refresh.
    pub(super) camera: CameraFrame,
    /// The first logical ring index placed (past the stale part, within the live
    /// limit, and when carrying past what earlier refreshes placed).
    pub(super) start: usize,
    /// Whether exact motion rewrote the velocities of the placed samples (the GPU
    /// uploads them again; the CPU reads them in place).
    #[cfg_attr(not(feature = "gpu"), allow(dead_code))]
    pub(super) moved: bool,
    /// The still-region history's step, if there is a history.
    pub(super) history: Option<Step>,
}

impl Reconstructor {
    /// Plan the refresh at `t` seen by `camera` with the filters of `tiling`: the filter
    /// table, carry or re-splat ([`Reconstructor::resplats_at`]), the samples placed,
    /// exact motion, and the history's step. Every step after this reads the plan.
    /// Its time goes to the passes it serves: filters, place and history.
    pub(super) fn plan(
        &mut self,
        t: f64,
        camera: &CameraFrame,
        tiling: &TilingSnapshot,
    ) -> RefreshPlan {
        let t0 = std::time::Instant::now();
        // Whether the view moved first: it sets the filters' volume.
        self.resplat = self.resplats_at(camera);
        self.update_filters(tiling);
        let lap = self.passes.lap(0, t0);
        let start = self.live_range(t);
        let moved = self.follow_motion_if_asked(t, start);
        let lap = self.passes.lap(1, lap);
        let in_pixel_order = !self.refreshes_on_gpu();
        let history = self
            .history
            .as_mut()
            .map(|h| h.plan(t, camera, in_pixel_order));
        self.passes.lap(6, lap);
        RefreshPlan {
            t,
            camera: *camera,
            start,
            moved,
            history,
        }
    }
}
