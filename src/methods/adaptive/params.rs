//! Parameters of the adaptive frameless sampler, with the paper's defaults where the
//! paper gives them and documented choices where it does not.

use crate::methods::MethodError;
use crate::tiles::Rect;

/// Most [`SamplerParams::tile_choices`].
pub const MAX_TILE_CHOICES: u32 = 64;

/// Every knob of the adaptive sampler.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SamplerParams {
    /// Deep buffer depth `b`: crosshairs kept per pixel (paper: 4).
    pub depth: usize,
    /// Crosshairs reprojected per tile visit `r` (paper: 5).
    pub reprojections_per_visit: usize,
    /// Crosshairs completed between tiling adjustments (paper: 25).
    pub chunk: usize,
    /// Decay rate of sample weights with age, per second: weight `exp(−decay·age)`
    /// (paper: 3.47, i.e. a half-life of 0.2 s).
    pub decay: f64,
    /// Weight κ of the variance term in tile error (paper: unspecified; ours 0.7).
    pub kappa: f64,
    /// Weight λ of the undersampling term (paper: unspecified; ours 0.1: the term
    /// counts empty slots, which large tiles always have, and the tile size factor `s`
    /// of the error multiplies it again). The occlusion term gets `1 − κ − λ`.
    pub lambda: f64,
    /// Undersampling threshold `m`: a tile's empty slots must exceed `m` times the mean
    /// to count (paper: unspecified; ours 4).
    pub undersampling_m: f64,
    /// Gain constant `i` weighing temporal against spatial change in gain control
    /// (paper: unspecified; ours 0.25, chosen so that the BART kitchen with its camera
    /// moving keeps a few hundred tiles while still views reach the maximum).
    pub gain_i: f64,
    /// Fewest tiles gain control may ask for.
    pub min_tiles: usize,
    /// Most tiles, as a fraction of the pixel count (tiles are at least a few pixels).
    pub max_tiles_per_pixel: f64,
    /// Smallest tile side that may still be split, pixels.
    pub min_tile_side: u32,
    /// Most splits plus merges per tiling adjustment (bounded work).
    pub max_adjust_ops: usize,
    /// Stop balancing when the largest tile error is within this factor of the
    /// smallest sibling pair's summed error.
    pub balance_ratio: f64,
    /// Smoothing of the tile-count target between adjustments (0 = jump, → 1 = slow).
    pub gain_smoothing: f64,
    /// Spacing of the initial grid of crosshairs, pixels ("spatially gridded,
    /// cotemporal" initialisation).
    pub init_spacing: u32,
    /// Ablation: reproject crosshairs in the sampler.
    pub reprojection: bool,
    /// Leave crosshairs that cannot have moved where they are: zero velocity and a
    /// camera unchanged since they were traced. Their reprojection is the identity, so
    /// its occlusion ray (one sample of the budget) is spent only to detect a
    /// moving occluder, which the tile's temporal gradient already draws samples to.
    /// Not in the paper (which reprojects every crosshair): under a fixed view it frees
    /// about a quarter of the budget for colour samples, but a moving occluder in front
    /// of static crosshairs then draws fewer samples (docs/results/table1). On in
    /// [`SamplerParams::ours`], off in [`SamplerParams::paper`].
    pub skip_static_reprojection: bool,
    /// Reproject only crosshairs of moving surfaces (non-zero velocity); still ones stay
    /// where they are even while the camera moves, as without reprojection, and age
    /// out. Where the camera moves, reprojecting every crosshair spends an occlusion
    /// ray on each to move samples that the reconstructor reprojects anyway, and with
    /// our reconstructor that budget pays more as new samples (docs/performance.md,
    /// tuning records). Not in the paper. On in [`SamplerParams::ours`].
    pub reproject_only_moving: bool,
    /// Measure a tile's temporal gradient where the initiating sample's surface point
    /// has moved to (camera and object motion) instead of at the same pixel position
    /// ([`super::sampler::completion_point`]): a point still inside the tile is
    /// completed there; a still point the view carried out of the tile is probed where
    /// it is now with one more ray, and the crosshair traced where it started, so that
    /// the tile keeps its samples (completed where the point went, a visit's samples
    /// drifted downstream of the view's motion, and the edge a turn brings in got its
    /// initiating samples alone). The temporal gradient then measures change on the
    /// surface rather than camera motion, which the reconstructor undoes by
    /// reprojecting samples, so filters stay longer and sharper while the camera moves.
    /// Not in the paper (measured: docs/performance.md, tuning records; the probe:
    /// docs/methods.md).
    pub follow_surface: bool,
    /// Give a reprojected crosshair a new temporal gradient only from the newest
    /// crosshair at its destination that saw the same surface point (both moved to
    /// now: within a pixel on screen and 5% in depth). The paper compares with that
    /// crosshair whatever it saw, which under a moving camera is usually another
    /// surface, so the gradient measured the camera's motion and kept temporal filters
    /// short in a still scene. Not in the paper (measured: docs/performance.md, tuning
    /// records).
    pub same_surface_gradients: bool,
    /// Place each new crosshair's centre in its pixel by a per-pixel low-discrepancy
    /// sequence (the R2 sequence from a per-pixel random start, indexed by how many the
    /// pixel has had) instead of uniformly at random: the pixel stays a uniform choice
    /// within the tile, but the samples a still pixel gathers cover it evenly, so its
    /// history converges faster on edges and textures. Not in the paper (measured:
    /// docs/performance.md, tuning records).
    pub stratified_positions: bool,
    /// Weigh a tile's variance term by how far its pixels are from converged: by the
    /// tile's mean of `1 / (1 + n)`, `n` the samples in a pixel's still-region history
    /// (the reconstructor's, passed in by the method after every refresh:
    /// [`super::Sampler::set_history_counts`]). The error of a pixel's mean falls as
    /// `1/n`; without this, a still view keeps concentrating samples on edges that have
    /// long converged while moving or newly seen regions, which have no history, wait.
    /// Not in the paper (measured: docs/performance.md, tuning records).
    pub discount_converged: bool,
    /// After a change of view, every tile's variance term is at least the image's mean
    /// tile variance × `exp(−(time since the view last changed) / new_view_prior_s)`
    /// (0: off; a run's first view is not a change, so a camera that never moves
    /// samples as without it). A tile the camera has just revealed holds few samples and shows no
    /// variance yet, so the tiling would neither split it nor send it samples until
    /// chance did; with the prior it is treated as an average tile until its own
    /// samples say otherwise. The prior fades once the view stays put, so a still view
    /// concentrates its samples as before; a run's start does not count as a change,
    /// and the prior fades, because each alternative cost still views (measured:
    /// docs/performance.md, tuning records). Not in the paper. Ours 0.25 s.
    pub new_view_prior_s: f64,
    /// Crosshair arm length as a fraction of the width (the ±x arms) and height (the ±y
    /// arms) of the tile the crosshair is traced for, at least one pixel (0: the
    /// paper's arms, one pixel). The arms' samples go to the reconstructor like the
    /// centre's: with one-pixel arms five of every six samples a visit traces sit in a
    /// plus sign three pixels wide, and while the view changes the image has a fifth
    /// as many distinct places sampled. Arms spanning the tile spread them over it,
    /// and the gradients they measure are the tile's, which is the scale at which the
    /// reconstruction filter and the tiling use them. Not in the paper.
    pub arm_fraction: f32,
    /// Tiles drawn per visit, uniformly at random; the one whose last crosshair is the
    /// oldest (or that has none) is visited (1: the paper's single uniform draw). Every
    /// tile is still visited at the same rate, but at more even intervals: with one
    /// draw the gaps between visits to a tile are exponential, so while the view
    /// changes some tiles go several refreshes without a fresh sample while others
    /// get two in one. Drawing several evens the gaps towards a round robin in
    /// random order, which is what a fast camera needs: every part of the image fresh
    /// at about the same age. Not in the paper. Ours 4 (1, 2, 3, 4, 6, 12 and 32
    /// measured on museum3 and museum4 with their own cameras: docs/methods.md).
    pub tile_choices: u32,
    /// Ablation: closed-loop gain control (off: the tile count stays at `fixed_tiles`).
    pub gain_control: bool,
    /// Ablation: include the occlusion term (off: its weight goes to variance).
    pub occlusion_term: bool,
    /// Ablation: uniform tiling (no splits or merges driven by error; a fixed grid).
    pub uniform_tiling: bool,
    /// Tile count used without gain control (and the initial target).
    pub fixed_tiles: usize,
}

impl Default for SamplerParams {
    fn default() -> Self {
        Self::ours()
    }
}

impl SamplerParams {
    /// The paper's configuration (with our choices for the unspecified constants).
    pub const fn paper() -> Self {
        Self {
            depth: 4,
            reprojections_per_visit: 5,
            chunk: 25,
            decay: 3.47,
            kappa: 0.7,
            lambda: 0.1,
            undersampling_m: 4.0,
            gain_i: 0.25,
            min_tiles: 16,
            max_tiles_per_pixel: 1.0 / 64.0,
            min_tile_side: 2,
            max_adjust_ops: 8,
            balance_ratio: 2.0,
            gain_smoothing: 0.9,
            init_spacing: 4,
            reprojection: true,
            skip_static_reprojection: false,
            reproject_only_moving: false,
            follow_surface: false,
            same_surface_gradients: false,
            stratified_positions: false,
            discount_converged: false,
            new_view_prior_s: 0.0,
            arm_fraction: 0.0,
            tile_choices: 1,
            gain_control: true,
            occlusion_term: true,
            uniform_tiling: false,
            fixed_tiles: 256,
        }
    }

    /// Ours (`adaptive`): the paper's, except that no crosshair is reprojected
    /// ([`SamplerParams::reprojection`] off: with the reconstructor's reprojection and
    /// visibility pass it did not pay, see docs/methods.md; with it turned back on,
    /// crosshairs that cannot have moved stay in place,
    /// [`SamplerParams::skip_static_reprojection`], only moving ones are reprojected,
    /// [`SamplerParams::reproject_only_moving`], and reprojected ones measure change
    /// only against the same surface, [`SamplerParams::same_surface_gradients`]),
    /// pending crosshairs follow their surface ([`SamplerParams::follow_surface`]),
    /// crosshair centres are stratified
    /// per pixel ([`SamplerParams::stratified_positions`]), converged pixels draw
    /// fewer samples ([`SamplerParams::discount_converged`]), a new view's tiles
    /// count as average until sampled ([`SamplerParams::new_view_prior_s`]) and
    /// crosshair arms span half their tile ([`SamplerParams::arm_fraction`]) and
    /// visits go to the least recently visited of four random tiles
    /// ([`SamplerParams::tile_choices`]).
    pub const fn ours() -> Self {
        let mut p = Self::paper();
        p.skip_static_reprojection = true;
        p.reproject_only_moving = true;
        p.follow_surface = true;
        p.same_surface_gradients = true;
        p.stratified_positions = true;
        p.discount_converged = true;
        p.new_view_prior_s = 0.25;
        p.arm_fraction = 0.5;
        p.reprojection = false;
        p.tile_choices = 4;
        p
    }

    /// The "Adaptive no reprojection" ablation of paper Fig. 8: the paper's sampler
    /// ([`SamplerParams::paper`]) without reprojection. (Ours has none.)
    pub const fn no_reprojection() -> Self {
        let mut p = Self::paper();
        p.reprojection = false;
        p
    }

    /// The crosshair arm lengths `(±x, ±y)` in pixels for a crosshair traced for the
    /// tile `rect` ([`SamplerParams::arm_fraction`]).
    pub fn arms(&self, rect: Rect) -> (f32, f32) {
        let arm = |side: u32| (self.arm_fraction * side as f32).max(1.0);
        (arm(rect.width()), arm(rect.height()))
    }

    /// Check ranges; the message names the bad field.
    pub fn validate(&self) -> Result<(), MethodError> {
        let bad = |name: &'static str, why: &'static str| {
            Err(MethodError::Parameter {
                group: "sampler",
                name,
                why,
            })
        };
        if self.depth == 0 || self.depth > 64 {
            return bad("depth", "must be in 1..=64");
        }
        if !(self.new_view_prior_s.is_finite() && self.new_view_prior_s >= 0.0) {
            return bad("new_view_prior_s", "must be ≥ 0 seconds");
        }
        if !(0.0..=1.0).contains(&self.arm_fraction) {
            return bad("arm_fraction", "must lie in [0, 1]");
        }
        if !(1..=MAX_TILE_CHOICES).contains(&self.tile_choices) {
            return bad("tile_choices", "must lie in 1..=64");
        }
        if self.chunk == 0 {
            return bad("chunk", "must be at least 1");
        }
        if !(self.decay.is_finite() && self.decay >= 0.0) {
            return bad("decay", "must be ≥ 0");
        }
        if !(0.0..=1.0).contains(&self.kappa)
            || !(0.0..=1.0).contains(&self.lambda)
            || self.kappa + self.lambda > 1.0
        {
            return bad("kappa/lambda", "κ, λ and κ + λ must lie in [0, 1]");
        }
        if self.min_tiles == 0 || self.fixed_tiles == 0 {
            return bad("min_tiles/fixed_tiles", "must be at least 1");
        }
        if self.min_tile_side == 0 || self.init_spacing == 0 {
            return bad("min_tile_side/init_spacing", "must be at least 1");
        }
        Ok(())
    }
}
