//! TAA as shipped today: a temporal upsampler modelled on FSR 2, at the budget of
//! `framed-60hz`.
//!
//! Frames are rendered every 1/60 s at the reduced resolution the budget allows (at most
//! `R/60` samples), jittered by Halton(2, 3) within a low-resolution cell, and traced at
//! the frame's start; a frame is shown at the first refresh at or after it completes.
//! Unlike a fixed exponential blend (history·0.9 + current·0.1, which never gets below
//! the noise of about ten frames), every jittered sample is accumulated into a
//! full-resolution history through a small Gaussian kernel around its sub-pixel position,
//! and each history pixel keeps its accumulated weight: the blend
//! `(history·w_hist + Σ g·c) / (w_hist + Σ g)` with `w_hist = min(weight, cap)` is a running
//! mean, so a still scene converges like a supersampled image (error ∝ 1/√N) until the
//! cap. History is reprojected with the tracer's motion vectors, rejected on
//! disocclusion (depth), clamped to the current neighbourhood in YCoCg, and its cap is
//! lowered where things move or the clamp had to pull it far. Pixels that no sample of
//! this frame reaches keep their reprojected history; where there is too little of
//! either, the display mixes in the bilinearly upsampled current frame.
//!
//! All of that display side is [`TaaHistory`], which the real-time `taa`
//! (`realtime::taa`) folds its frames into too; [`Taa`] adds the simulated clock's
//! frames and budget.

use glam::Vec3;
use rayon::prelude::*;

use super::{
    framed::{reduced_grid, GBuffer, GSample},
    sixty_per_second, FRAME_HZ,
    Budget, Displayed, Method, MethodContext, MethodError, MethodInfo,
};
use crate::{
    clock::TIME_EPS,
    image::Image,
    scene::CameraFrame,
    trace::{batch, Sample, SceneState, Tracer},
};

/// `taa`.
pub const TAA: MethodInfo = MethodInfo {
    name: "taa",
    description: "temporal upsampler (FSR 2-like): jittered 60 Hz low-res samples accumulated into a weighted full-res history",
    budget: Budget::Rate,
    check_rate: |_, rate| sixty_per_second("taa", rate),
    build: |ctx| Ok(Box::new(Taa::new(ctx, TaaParams::default())?)),
};

/// Radical inverse of `i` in base `b` (Halton sequence).
pub fn halton(mut i: u64, b: u64) -> f32 {
    let (mut f, mut r) = (1.0f64, 0.0f64);
    while i > 0 {
        f /= b as f64;
        r += f * (i % b) as f64;
        i /= b;
    }
    r as f32
}

pub(crate) fn to_ycocg(c: Vec3) -> Vec3 {
    Vec3::new(
        0.25 * c.x + 0.5 * c.y + 0.25 * c.z,
        0.5 * c.x - 0.5 * c.z,
        -0.25 * c.x + 0.5 * c.y - 0.25 * c.z,
    )
}

pub(crate) fn from_ycocg(c: Vec3) -> Vec3 {
    Vec3::new(c.x + c.y - c.z, c.x + c.z, c.x - c.y - c.z)
}

fn catmull_rom_weights(f: f32) -> [f32; 4] {
    let (f2, f3) = (f * f, f * f * f);
    [
        -0.5 * f3 + f2 - 0.5 * f,
        1.5 * f3 - 2.5 * f2 + 1.0,
        -1.5 * f3 + 2.0 * f2 + 0.5 * f,
        0.5 * f3 - 0.5 * f2,
    ]
}

/// Catmull–Rom (bicubic) fetch at continuous pixel coordinates (edges clamped).
pub fn catmull_rom(img: &Image, x: f32, y: f32) -> Vec3 {
    let (u, v) = (x - 0.5, y - 0.5);
    let (x0, y0) = (u.floor() as i64, v.floor() as i64);
    let (wx, wy) = (
        catmull_rom_weights(u - x0 as f32),
        catmull_rom_weights(v - y0 as f32),
    );
    let (w, h) = (img.width as i64, img.height as i64);
    let mut c = Vec3::ZERO;
    for (j, wyj) in wy.iter().enumerate() {
        let yy = (y0 - 1 + j as i64).clamp(0, h - 1) as u32;
        for (i, wxi) in wx.iter().enumerate() {
            let xx = (x0 - 1 + i as i64).clamp(0, w - 1) as u32;
            c += img.get(xx, yy) * (wxi * wyj);
        }
    }
    c.max(Vec3::ZERO)
}

/// The upsampler's parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TaaParams {
    /// Standard deviation of the Gaussian accumulation kernel, display pixels. The ideal
    /// image is a box average over each pixel (σ ≈ 0.29 px); 0.3 px matches that spread
    /// (a converged pixel is no blurrier than the ideal) while every position in the
    /// pixel, corners included (weight ≈ 0.06), still gets weight, so Halton jitter
    /// covers the pixel.
    pub kernel_sigma: f32,
    /// Kernel cut-off radius, display pixels: 1 px, beyond 3σ, where the Gaussian is below 1 %.
    pub kernel_radius: f32,
    /// History weight cap where nothing moves, in units of a sample at a pixel's centre.
    /// 64 samples' worth: an error of ~1/8 of one sample's, and the same count as the
    /// ideal images of the evaluation; at 400K samples/s on 256×256 (≈0.1 samples per
    /// pixel per frame) it is reached after ~10 s, so a still view keeps improving.
    pub max_weight: f32,
    /// Cap once the pixel moves `motion_full_px` or more per frame. Every reprojection
    /// resamples (and slightly blurs) the history and shading changes with the view, so
    /// a moving pixel remembers ~8 samples (≈100 frames at 0.1 samples/pixel/frame, but
    /// then it is new samples that sharpen it).
    pub moving_weight: f32,
    /// On-screen motion (display pixels per frame) at which the cap reaches
    /// `moving_weight`; in between it falls linearly. Sub-pixel drift barely blurs.
    pub motion_full_px: f32,
    /// Relative view-depth difference beyond which the previous frame saw another surface
    /// (a disocclusion): 5 %, as `taa`. A depth between those of the previous samples
    /// around the point also passes: a surface seen edge-on changes depth by more than
    /// any tolerance from one sample to the next, and testing only against the nearest
    /// depths rejected pixels of a still view every frame (docs/performance.md, tuning
    /// records).
    pub depth_tolerance: f32,
    /// YCoCg distance the neighbourhood clamp may move the history before the history is
    /// taken for stale (lighting changed, a cut that passed the depth test): beyond it
    /// the weight is capped at `clip_weight`.
    pub clip_distance: f32,
    /// The cap after a large clamp: a couple of samples, so new samples take over within
    /// a few frames without dropping the pixel to one noisy sample.
    pub clip_weight: f32,
    /// Accumulated weight below which the display mixes in the bilinearly upsampled
    /// current frame (for pixels just disoccluded or at the start): half a sample.
    pub display_min_weight: f32,
    /// How much the clamp box (the YCoCg min/max of this frame's 3×3 samples around the
    /// pixel) is widened about its centre where nothing moves; it narrows linearly to the
    /// plain box at `motion_full_px`. Nine samples three pixels apart cannot bound a
    /// converged pixel of sub-Nyquist detail (the checkered floor, refractions), so a
    /// still view never converged with the plain box (docs/performance.md, tuning
    /// records); widened, a gross change (a light, a cut that passes the depth test) is
    /// still caught.
    pub still_box_scale: f32,
    /// Jitter phases per display pixel: the Halton sequence repeats after
    /// `ceil(this · (W·H)/(grid))` frames. FSR 2 suggests 8 per pixel for motion; a still
    /// view needs about `max_weight` distinct positions per pixel to converge.
    pub jitter_phases_per_pixel: f32,
    /// On-screen motion in one frame, as a fraction of the display's larger side, that
    /// counts as a cut rather than motion: a quarter screen in 1/60 s is 15 screens/s.
    pub cut_motion: f32,
    /// Fraction of pixels rejected or moving a cut's distance beyond which the whole
    /// history is dropped (a cut): a third, far above what fast pans or objects reveal.
    pub cut_fraction: f32,
}

impl Default for TaaParams {
    fn default() -> Self {
        Self {
            kernel_sigma: 0.3,
            kernel_radius: 1.0,
            max_weight: 64.0,
            moving_weight: 8.0,
            motion_full_px: 2.0,
            depth_tolerance: 0.05,
            clip_distance: 0.1,
            clip_weight: 2.0,
            display_min_weight: 0.5,
            still_box_scale: 8.0,
            jitter_phases_per_pixel: 64.0,
            cut_motion: 0.25,
            cut_fraction: 0.33,
        }
    }
}

impl TaaParams {
    fn check(&self) -> Result<(), MethodError> {
        let bad = |name, why| Err(MethodError::Parameter {
            group: "taa",
            name,
            why,
        });
        let pos = |v: f32| v.is_finite() && v > 0.0;
        let at_least = |v: f32, m: f32| v.is_finite() && v >= m;
        if !pos(self.cut_motion) || !pos(self.cut_fraction) {
            return bad("cut", "motion and fraction must be positive");
        }
        if !pos(self.kernel_sigma) || !pos(self.kernel_radius) {
            return bad("kernel", "sigma and radius must be positive");
        }
        if !pos(self.max_weight) || !pos(self.moving_weight) || !pos(self.clip_weight) {
            return bad("weights", "caps must be positive");
        }
        if !pos(self.motion_full_px) || !pos(self.depth_tolerance) || !pos(self.clip_distance)
        {
            return bad("thresholds", "must be positive");
        }
        if !at_least(self.still_box_scale, 1.0) {
            return bad("still_box_scale", "must be at least 1 (the plain box)");
        }
        if !at_least(self.display_min_weight, 0.0) || !at_least(self.jitter_phases_per_pixel, 1.0) {
            return bad("display", "min weight ≥ 0 and ≥ 1 jitter phase per pixel");
        }
        Ok(())
    }
}

/// The Halton sequence's period for `grid` samples per frame on a `size` display:
/// [`TaaParams::jitter_phases_per_pixel`] distinct positions per display pixel.
pub fn jitter_period(params: &TaaParams, size: (u32, u32), grid: (u32, u32)) -> u64 {
    let ratio = (size.0 as f64 * size.1 as f64) / (grid.0 as f64 * grid.1 as f64);
    (params.jitter_phases_per_pixel as f64 * ratio).ceil() as u64
}

/// The jitter of frame `j` within a low-resolution cell, in cells: Halton(2, 3).
pub fn frame_jitter(j: u64, period: u64) -> (f32, f32) {
    // Index 0 of Halton is (0, 0) for every base, which would put the first frame on
    // the cell corners; start at 1.
    let k = j % period + 1;
    (halton(k, 2), halton(k, 3))
}

/// Display coordinates of sample `(i, j)` of a `grid` frame jittered by `jitter`.
pub fn jittered_position(
    size: (u32, u32),
    grid: (u32, u32),
    jitter: (f32, f32),
    i: u32,
    j: u32,
) -> (f32, f32) {
    let (sx, sy) = (size.0 as f32 / grid.0 as f32, size.1 as f32 / grid.1 as f32);
    ((i as f32 + jitter.0) * sx, (j as f32 + jitter.1) * sy)
}

/// Row `y` of a jittered low-resolution frame, as the real-time threads trace it (the
/// evaluation traces the same positions in parallel over the whole frame).
pub fn trace_jittered_row<'a>(
    tracer: &'a Tracer,
    state: &'a SceneState,
    grid: (u32, u32),
    jitter: (f32, f32),
    y: u32,
) -> impl Iterator<Item = Sample> + 'a {
    let size = tracer.size();
    (0..grid.0).map(move |x| {
        let (px, py) = jittered_position(size, grid, jitter, x, y);
        tracer.sample(state, px, py)
    })
}

/// One traced low-resolution frame, as the history takes it.
pub struct JitteredFrame<'a> {
    /// Row-major, `grid.0 × grid.1`, sample `(i, j)` traced at
    /// [`jittered_position`]`(size, grid, jitter, i, j)`.
    pub samples: &'a [Sample],
    /// Samples across and down.
    pub grid: (u32, u32),
    /// The frame's jitter, in cells.
    pub jitter: (f32, f32),
    /// Scene time every sample was traced at.
    pub time: f64,
    /// The camera they were traced with.
    pub camera: CameraFrame,
    /// Scene time since the previous frame (unused for the first): how far back along
    /// its velocity a moving point was when the previous frame saw it.
    pub dt: f32,
}

/// One traced frame, kept for the next frame's disocclusion test.
struct LowFrame {
    camera: CameraFrame,
    jitter: (f32, f32),
    /// View depth (along the camera axis) of each low-resolution sample; ∞ on a miss.
    depth: Vec<f32>,
    /// Where each low-resolution sample was and how it moved, for a display-side warp
    /// (its grid is this frame's, which a real-time run may change between frames).
    gbuffer: GBuffer,
}

/// The upsampler's display side: the full-resolution history that jittered
/// low-resolution frames are folded into, and the image it shows. The evaluation's
/// [`Taa`] and the real-time pipeline's `taa` both accumulate through it; they differ
/// only in who traces the frames and when.
pub struct TaaHistory {
    params: TaaParams,
    size: (u32, u32),
    /// Accumulated mean colour per display pixel (where the weight is 0: the upsampled
    /// current frame, so that filtered fetches next to it stay sensible).
    history: Image,
    weight: Vec<f32>,
    /// Weighted mean time of the samples in each history pixel.
    info_time: Vec<f64>,
    output: Image,
    output_time: Vec<f64>,
    prev: Option<LowFrame>,
    rejections: u64,
    cuts: u64,
}

impl TaaHistory {
    /// An empty history for a `size` display whose information dates from `start`.
    pub fn new(size: (u32, u32), params: TaaParams, start: f64) -> Result<Self, MethodError> {
        params.check()?;
        let (w, h) = size;
        let n = (w * h) as usize;
        Ok(Self {
            params,
            size,
            history: Image::new(w, h),
            weight: vec![0.0; n],
            info_time: vec![start; n],
            output: Image::new(w, h),
            output_time: vec![start; n],
            prev: None,
            rejections: 0,
            cuts: 0,
        })
    }

    /// The image shown after the last frame folded in.
    pub fn output(&self) -> &Image {
        &self.output
    }

    /// Scene time of the information in each displayed pixel (weighted by what it
    /// holds).
    pub fn output_times(&self) -> &[f64] {
        &self.output_time
    }

    /// Mean age at display time `t` of what is shown; `None` before the first frame.
    pub fn mean_age(&self, t: f64) -> Option<f64> {
        self.prev.as_ref().map(|_| {
            self.output_time.iter().map(|s| t - s).sum::<f64>() / self.output_time.len() as f64
        })
    }

    /// Where the samples of the newest frame were (none before the first frame).
    pub fn shown_gbuffer(&self) -> Option<&GBuffer> {
        self.prev.as_ref().map(|f| &f.gbuffer)
    }

    /// Scene time of the newest frame folded in.
    pub fn newest_time(&self) -> Option<f64> {
        self.prev.as_ref().map(|f| f.gbuffer.time)
    }

    /// Pixels whose history was rejected (off screen or disoccluded) so far.
    pub fn rejections(&self) -> u64 {
        self.rejections
    }

    /// Frames taken for camera cuts (all history dropped) so far.
    pub fn cuts(&self) -> u64 {
        self.cuts
    }

    /// Fold one traced frame into the history and make the image shown after it.
    pub fn accumulate(&mut self, frame: JitteredFrame<'_>) {
        let p = self.params;
        let (w, h) = self.size;
        let JitteredFrame {
            samples: low,
            grid: (gw, gh),
            jitter: (jx, jy),
            time: t,
            camera: cam,
            dt,
        } = frame;
        let low_depth: Vec<f32> = low
            .iter()
            .map(|s| {
                if s.hit {
                    cam.project(s.hit_point).map_or(f32::INFINITY, |(_, _, z)| z)
                } else {
                    f32::INFINITY
                }
            })
            .collect();
        let fold = Fold {
            p,
            size: (w, h),
            low,
            grid: (gw, gh),
            jitter: (jx, jy),
            scale: (w as f32 / gw as f32, h as f32 / gh as f32),
            t,
            cam,
            dt,
            cut_motion: p.cut_motion * w.max(h) as f32,
            inv_2s2: 1.0 / (2.0 * p.kernel_sigma * p.kernel_sigma),
            history: &self.history,
            hist_weight: &self.weight,
            hist_time: &self.info_time,
        };
        let compute = |prev: Option<&LowFrame>| -> Vec<Px> {
            (0..w * h)
                .into_par_iter()
                .map(|q| fold.pixel(q, prev))
                .collect()
        };
        let mut results = compute(self.prev.as_ref());
        // A camera cut (or a jump as good as one): most of the screen lost its history
        // or moved by a large part of it; history that passed the per-pixel tests there
        // is coincidence (a wall seen behind a sphere from the old view), so start over,
        // as engines do when told of a cut.
        let cut_like = results.iter().filter(|px| px.cut_like).count();
        if cut_like as f32 > p.cut_fraction * results.len() as f32 {
            results = compute(None);
            for px in &mut results {
                px.rejected = true;
            }
            self.cuts += 1;
        }
        for (q, px) in results.into_iter().enumerate() {
            self.history.pixels[q] = px.hist;
            self.weight[q] = px.weight;
            self.info_time[q] = px.time;
            self.output.pixels[q] = px.shown;
            self.output_time[q] = px.shown_time;
            self.rejections += px.rejected as u64;
        }
        self.prev = Some(LowFrame {
            camera: cam,
            jitter: (jx, jy),
            depth: low_depth,
            gbuffer: GBuffer {
                grid: (gw, gh),
                samples: low.iter().map(GSample::from).collect(),
                time: t,
                camera: cam,
            },
        });
    }
}

/// One display pixel after a frame is folded in.
struct Px {
    hist: Vec3,
    weight: f32,
    time: f64,
    shown: Vec3,
    shown_time: f64,
    rejected: bool,
    cut_like: bool,
}

/// Where a pixel's surface was in the previous frame's display, and how far it moved.
#[derive(Clone, Copy)]
struct Reprojected {
    x: f32,
    y: f32,
    motion: f32,
}

/// One frame being folded into the history: the frame, and the history as it was
/// before it (read by every pixel at once).
struct Fold<'a> {
    p: TaaParams,
    size: (u32, u32),
    low: &'a [Sample],
    grid: (u32, u32),
    jitter: (f32, f32),
    /// Display pixels per grid cell, across and down.
    scale: (f32, f32),
    t: f64,
    cam: CameraFrame,
    dt: f32,
    /// Motion, in pixels, past which a pixel counts towards a camera cut.
    cut_motion: f32,
    /// 1 / (2σ²) of the splat kernel.
    inv_2s2: f32,
    history: &'a Image,
    hist_weight: &'a [f32],
    hist_time: &'a [f64],
}

/// Index of grid cell `(i, j)` of a `gw × gh` grid, clamped to the grid.
fn cell_in((gw, gh): (u32, u32), i: i64, j: i64) -> usize {
    (j.clamp(0, gh as i64 - 1) * gw as i64 + i.clamp(0, gw as i64 - 1)) as usize
}

impl Fold<'_> {
    fn cell(&self, i: i64, j: i64) -> usize {
        cell_in(self.grid, i, j)
    }

    /// Display pixel `q` with this frame folded in, reprojecting from `prev` if any.
    fn pixel(&self, q: u32, prev: Option<&LowFrame>) -> Px {
        let (p, t) = (self.p, self.t);
        let (w, _) = self.size;
        let ((sx, sy), (jx, jy)) = (self.scale, self.jitter);
        let (x, y) = ((q % w) as f32 + 0.5, (q / w) as f32 + 0.5);
        // Grid coordinates of the pixel centre: sample (i, j) sits at (i, j).
        let (u, v) = (x / sx - jx, y / sy - jy);
        let (sum, wsum) = self.kernel(x, y);
        let up = self.upsampled(u, v);
        let (ni, nj) = (u.round() as i64, v.round() as i64);
        let near = &self.low[self.cell(ni, nj)];

        // History: where this pixel's surface was in the previous frame.
        let mut rejected = false;
        let reprojected = prev.and_then(|pf| self.reproject(near, (x, y), pf));
        if prev.is_some() && reprojected.is_none() {
            rejected = true;
        }
        let (mut hist_c, mut w_hist, mut t_hist) = (Vec3::ZERO, 0.0f32, t);
        if let Some(r) = reprojected {
            (hist_c, w_hist, t_hist) = self.rectified_history(r, (ni, nj));
        }
        let total = w_hist + wsum;
        let (hist, time) = if total > 0.0 {
            (
                (hist_c * w_hist + sum) / total,
                (t_hist * w_hist as f64 + t * wsum as f64) / total as f64,
            )
        } else {
            (up, t)
        };
        // Too little accumulated: lean on the upsampled frame for the display.
        let fill = (p.display_min_weight - total).max(0.0);
        let (shown, shown_time) = if fill > 0.0 {
            let all = total + fill;
            (
                (hist * total + up * fill) / all,
                (time * total as f64 + t * fill as f64) / all as f64,
            )
        } else {
            (hist, time)
        };
        Px {
            hist,
            weight: total.min(p.max_weight),
            time,
            shown,
            shown_time,
            rejected,
            cut_like: rejected || reprojected.is_some_and(|r| r.motion > self.cut_motion),
        }
    }

    /// This frame's samples under the kernel around display point `(x, y)`: the
    /// weighted colour sum and the weight.
    fn kernel(&self, x: f32, y: f32) -> (Vec3, f32) {
        let ((sx, sy), (jx, jy), (gw, gh)) = (self.scale, self.jitter, self.grid);
        let (mut sum, mut wsum) = (Vec3::ZERO, 0.0f32);
        let r = self.p.kernel_radius;
        let (i0, i1) = (
            ((x - r) / sx - jx).ceil() as i64,
            ((x + r) / sx - jx).floor() as i64,
        );
        let (j0, j1) = (
            ((y - r) / sy - jy).ceil() as i64,
            ((y + r) / sy - jy).floor() as i64,
        );
        for gj in j0.max(0)..=j1.min(gh as i64 - 1) {
            for gi in i0.max(0)..=i1.min(gw as i64 - 1) {
                let (dx, dy) = ((gi as f32 + jx) * sx - x, (gj as f32 + jy) * sy - y);
                let d2 = dx * dx + dy * dy;
                if d2 <= r * r {
                    let g = (-d2 * self.inv_2s2).exp();
                    sum += self.low[(gj * gw as i64 + gi) as usize].color * g;
                    wsum += g;
                }
            }
        }
        (sum, wsum)
    }

    /// Bilinear upsampling of this frame at grid point `(u, v)`: the fallback where
    /// little is known.
    fn upsampled(&self, u: f32, v: f32) -> Vec3 {
        let (gw, gh) = self.grid;
        let (uc, vc) = (u.clamp(0.0, gw as f32 - 1.0), v.clamp(0.0, gh as f32 - 1.0));
        let (x0, y0) = (uc.floor() as i64, vc.floor() as i64);
        let (fx, fy) = (uc - x0 as f32, vc - y0 as f32);
        let c = |i, j| self.low[self.cell(i, j)].color;
        c(x0, y0)
            .lerp(c(x0 + 1, y0), fx)
            .lerp(c(x0, y0 + 1).lerp(c(x0 + 1, y0 + 1), fx), fy)
    }

    /// Where the surface of `near`, the sample nearest display point `(x, y)`, was in
    /// the previous frame `pf`; `None` when off screen or disoccluded.
    fn reproject(&self, near: &Sample, (x, y): (f32, f32), pf: &LowFrame) -> Option<Reprojected> {
        let p = self.p;
        let (w, h) = self.size;
        let (cx, cy, _) = self.cam.project(near.hit_point)?;
        let (ox, oy, pd) = pf.camera.project(near.hit_point - near.velocity * self.dt)?;
        // The nearest sample's displacement, not its position, applies to
        // the pixel.
        let (px, py) = (x + ox - cx, y + oy - cy);
        if !(px >= 0.0 && py >= 0.0 && px < w as f32 && py < h as f32) {
            return None;
        }
        // Disoccluded unless some previous sample around where the point was saw
        // it (any of 3×3: at an edge the nearest one may lie across it, and a
        // still view must not reject; only 2×2 rejected sphere rims every few
        // frames). What slips through at a cut is caught by the cut test below.
        // The previous frame's own grid: a real-time run resizes it.
        let pgrid = pf.gbuffer.grid;
        let (psx, psy) = (w as f32 / pgrid.0 as f32, h as f32 / pgrid.1 as f32);
        let (pu, pv) = (
            (ox / psx - pf.jitter.0).round() as i64,
            (oy / psy - pf.jitter.1).round() as i64,
        );
        let pd = if near.hit { pd } else { f32::INFINITY };
        let (mut lo_d, mut hi_d, mut seen) = (f32::INFINITY, 0.0f32, false);
        for dj in -1..=1 {
            for di in -1..=1 {
                let d = pf.depth[cell_in(pgrid, pu + di, pv + dj)];
                seen |= if pd.is_finite() {
                    (d - pd).abs() <= p.depth_tolerance * pd.max(1e-6)
                } else {
                    !d.is_finite()
                };
                if d.is_finite() {
                    lo_d = lo_d.min(d);
                    hi_d = hi_d.max(d);
                }
            }
        }
        // A surface seen edge-on (a table's front edge, the floor far off)
        // changes depth faster than any tolerance from one sample to the
        // next: between the depths around it, the point was on screen too.
        seen |= pd >= lo_d && pd <= hi_d;
        if !seen {
            return None;
        }
        Some(Reprojected {
            x: px,
            y: py,
            motion: (ox - cx).hypot(oy - cy),
        })
    }

    /// The history at `r`, clamped to this frame's samples around grid cell
    /// `(ni, nj)`: its colour, its weight (capped by how much the pixel moved) and its
    /// time.
    fn rectified_history(&self, r: Reprojected, (ni, nj): (i64, i64)) -> (Vec3, f32, f64) {
        let p = self.p;
        let (w, h) = self.size;
        let (bx, by) = (
            ((r.x - 0.5).round() as u32).min(w - 1),
            ((r.y - 0.5).round() as u32).min(h - 1),
        );
        let b = (by * w + bx) as usize;
        let raw = catmull_rom(self.history, r.x, r.y);
        // Rectify: clamp to the YCoCg box of this frame's 3×3 samples around
        // the pixel (the samples, not their interpolation, which moves with
        // the jitter).
        let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
        for dj in -1..=1 {
            for di in -1..=1 {
                let n = to_ycocg(self.low[self.cell(ni + di, nj + dj)].color);
                lo = lo.min(n);
                hi = hi.max(n);
            }
        }
        let s = (r.motion / p.motion_full_px).clamp(0.0, 1.0);
        let scale = p.still_box_scale + (1.0 - p.still_box_scale) * s;
        let (mid, half) = ((lo + hi) * 0.5, (hi - lo) * 0.5 * scale);
        let (lo, hi) = (mid - half, mid + half);
        let y_raw = to_ycocg(raw);
        let y_clamped = y_raw.clamp(lo, hi);
        let mut cap = p.max_weight + (p.moving_weight - p.max_weight) * s;
        if (y_raw - y_clamped).length() > p.clip_distance {
            cap = cap.min(p.clip_weight);
        }
        (from_ycocg(y_clamped), self.hist_weight[b].min(cap), self.hist_time[b])
    }
}

/// The temporal upsampler under the simulated clock: a frame every 1/60 s at the
/// resolution the rate allows.
pub struct Taa {
    ctx: MethodContext,
    grid: (u32, u32),
    jitter_period: u64,
    next_frame: u64,
    history: TaaHistory,
    samples: u64,
    trace_s: f64,
}

impl Taa {
    /// Create for one run.
    pub fn new(ctx: &MethodContext, params: TaaParams) -> Result<Self, MethodError> {
        let size = ctx.tracer.size();
        let history = TaaHistory::new(size, params, ctx.clock.start)?;
        sixty_per_second("taa", ctx.clock.rate)?;
        let per_frame = (ctx.clock.rate / FRAME_HZ).floor();
        let grid = reduced_grid(size.0, size.1, per_frame as u64);
        Ok(Self {
            ctx: ctx.clone(),
            grid,
            jitter_period: jitter_period(&params, size, grid),
            next_frame: 0,
            history,
            samples: 0,
            trace_s: 0.0,
        })
    }

    fn frame_start(&self, j: u64) -> f64 {
        self.ctx.clock.start + j as f64 / FRAME_HZ
    }

    /// Trace frame `j` at time `t` and fold it into the history.
    fn render_frame(&mut self, j: u64, t: f64) {
        let tracer = self.ctx.tracer.clone();
        let size = tracer.size();
        let (gw, gh) = self.grid;
        let state = tracer.state_at(t);
        let jitter = frame_jitter(j, self.jitter_period);
        let t0 = std::time::Instant::now();
        let points: Vec<[f32; 2]> = (0..gw * gh)
            .map(|q| {
                let (x, y) = jittered_position(size, self.grid, jitter, q % gw, q / gw);
                [x, y]
            })
            .collect();
        let low = batch::trace_points(&tracer, self.ctx.rays.as_deref(), &state, &points);
        self.trace_s += t0.elapsed().as_secs_f64();
        self.samples += (gw * gh) as u64;
        self.history.accumulate(JitteredFrame {
            samples: &low,
            grid: self.grid,
            jitter,
            time: t,
            camera: state.camera,
            dt: (1.0 / FRAME_HZ) as f32,
        });
    }

    /// Pixels whose history was rejected (off screen or disoccluded), for tests.
    pub fn rejections(&self) -> u64 {
        self.history.rejections()
    }

    /// Frames taken for camera cuts (all history dropped).
    pub fn cuts(&self) -> u64 {
        self.history.cuts()
    }
}

impl Method for Taa {
    fn display(&mut self, t: f64) -> Displayed<'_> {
        self.advance(t);
        let age = self
            .history
            .mean_age(t)
            .unwrap_or(t - self.ctx.clock.start);
        Displayed {
            image: self.history.output(),
            mean_age: age,
        }
    }

    fn samples_used(&self) -> u64 {
        self.samples
    }

    fn trace_seconds(&self) -> f64 {
        self.trace_s
    }
}

impl Taa {
    /// The image shown now (after the last `display`).
    pub fn output(&self) -> &Image {
        self.history.output()
    }

    /// Where the samples of the newest frame, the one shown, were (none before the
    /// first frame completes).
    pub fn shown_gbuffer(&self) -> Option<&GBuffer> {
        self.history.shown_gbuffer()
    }

    /// Render every frame that completes by display time `t`.
    fn advance(&mut self, t: f64) {
        // Frame j starts at a refresh and completes at the next one, where it is shown.
        while self
            .ctx
            .clock
            .first_refresh_at_or_after(self.frame_start(self.next_frame + 1))
            <= t + TIME_EPS
        {
            let start = self.frame_start(self.next_frame);
            self.render_frame(self.next_frame, start);
            self.next_frame += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_parameters_are_valid_and_bad_ones_are_refused() {
        assert!(TaaParams::default().check().is_ok());
        let bad = TaaParams {
            kernel_sigma: 0.0,
            ..TaaParams::default()
        };
        assert!(bad.check().is_err());
    }

    #[test]
    fn halton_and_ycocg() {
        assert_eq!(halton(1, 2), 0.5);
        assert_eq!(halton(2, 2), 0.25);
        assert!((halton(1, 3) - 1.0 / 3.0).abs() < 1e-7);
        let c = Vec3::new(0.2, 0.5, 0.9);
        assert!((from_ycocg(to_ycocg(c)) - c).length() < 1e-6);
    }

    #[test]
    fn history_takes_frames_whose_grid_changes() {
        // A real-time run resizes its frames; the disocclusion test must read the
        // previous frame on its own grid. A still view keeps its history throughout.
        use std::sync::Arc;
        let scene = Arc::new(crate::scene::builtin::load("toycar").expect("built-in scene"));
        let tracer = Tracer::new(scene, 32, 24, crate::trace::TraceOptions::default());
        let params = TaaParams::default();
        let state = tracer.state_at(0.5);
        let mut h = TaaHistory::new((32, 24), params, 0.5).unwrap();
        assert!(h.mean_age(0.5).is_none() && h.shown_gbuffer().is_none());
        let grids = [(16, 12), (32, 24), (24, 18), (32, 24), (16, 12), (20, 15)];
        for (j, &grid) in grids.iter().enumerate() {
            let jitter = frame_jitter(j as u64, jitter_period(&params, (32, 24), grid));
            let samples: Vec<Sample> = (0..grid.1)
                .flat_map(|y| trace_jittered_row(&tracer, &state, grid, jitter, y))
                .collect();
            h.accumulate(JitteredFrame {
                samples: &samples,
                grid,
                jitter,
                time: 0.5,
                camera: state.camera,
                dt: (1.0 / crate::methods::FRAME_HZ) as f32,
            });
            assert_eq!(h.shown_gbuffer().map(|g| g.grid), Some(grid));
        }
        assert_eq!(h.cuts(), 0);
        let pixels = 32 * 24 * (grids.len() as u64 - 1);
        assert!(
            h.rejections() * 20 < pixels,
            "{} of {pixels} rejected",
            h.rejections()
        );
        assert!(h.output().pixels.iter().all(|p| p.is_finite()));
        assert!(h.mean_age(0.5).is_some_and(|a| a.abs() < 1e-6));
    }

    #[test]
    fn catmull_rom_reproduces_linear_ramps() {
        let img = Image {
            width: 8,
            height: 1,
            pixels: (0..8).map(|i| Vec3::splat(i as f32 * 0.1)).collect(),
        };
        // Between texel centers 2.5 and 3.5 a ramp is exact.
        let v = catmull_rom(&img, 3.0, 0.5);
        assert!((v.x - 0.25).abs() < 1e-6, "{v:?}");
    }
}
