//! TAA / temporal upsampling: what a practitioner uses today, at the same budget.
//!
//! Framed and double-buffered at 60 Hz (like `framed-60hz`) at the reduced resolution
//! the budget allows (at most `R/60` samples per frame), each frame jittered by a
//! Halton(2, 3) sub-pixel offset of its grid. Per display pixel: the current frame's
//! estimate is the bilinear interpolation of the jittered low-resolution samples; the
//! history is the previous output fetched with a Catmull–Rom filter at the pixel's
//! position in the previous frame (motion vectors from the ray tracer: the hit point
//! moved back by its velocity, projected with the previous camera), clamped to the
//! YCoCg bounding box of the 3×3 low-resolution samples around the pixel, and rejected
//! when it
//! falls off screen or its depth disagrees with the previous frame's depth there by more
//! than `DEPTH_TOLERANCE` (a disocclusion). Output = lerp(history, current, `ALPHA`).

use glam::Vec3;
use rayon::prelude::*;

use super::{
    framed::reduced_grid, sixty_per_second, Budget, Displayed, Method, MethodContext,
    MethodError, MethodInfo,
};
use crate::{clock::TIME_EPS, image::Image, scene::CameraFrame, trace::Sample};

/// `taa`.
pub const TAA: MethodInfo = MethodInfo {
    name: "taa",
    description: "60 Hz at reduced resolution, Halton jitter, reprojected clamped history, blend 0.1",
    budget: Budget::Rate,
    check_rate: |_, rate| sixty_per_second("taa", rate),
    build: |ctx| Ok(Box::new(Taa::new(ctx)?)),
};

/// Weight of the current frame in the exponential blend (the usual ≈ 0.1).
pub const ALPHA: f32 = 0.1;
/// Relative depth difference beyond which history is rejected as disoccluded.
pub const DEPTH_TOLERANCE: f32 = 0.05;
/// Length of the Halton jitter sequence.
pub const JITTER_PERIOD: u64 = 16;

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

/// The TAA renderer.
pub struct Taa {
    ctx: MethodContext,
    grid: (u32, u32),
    next_frame: u64,
    output: Image,
    depth: Vec<f32>,
    prev_camera: Option<CameraFrame>,
    front_time: Option<f64>,
    history_time: Vec<f64>,
    samples: u64,
    trace_s: f64,
    /// History rejections (off-screen or disocclusion), for tests and statistics.
    pub rejections: u64,
}

impl Taa {
    /// Create for one run.
    pub fn new(ctx: &MethodContext) -> Result<Self, MethodError> {
        let (w, h) = ctx.tracer.size();
        sixty_per_second("taa", ctx.clock.rate)?;
        let per_frame = (ctx.clock.rate / 60.0).floor();
        Ok(Self {
            ctx: ctx.clone(),
            grid: reduced_grid(w, h, per_frame as u64),
            next_frame: 0,
            output: Image::new(w, h),
            depth: vec![f32::INFINITY; (w * h) as usize],
            prev_camera: None,
            front_time: None,
            history_time: vec![ctx.clock.start; (w * h) as usize],
            samples: 0,
            trace_s: 0.0,
            rejections: 0,
        })
    }

    fn frame_start(&self, j: u64) -> f64 {
        self.ctx.clock.start + j as f64 / 60.0
    }

    /// Trace frame `j` (jittered low-resolution grid) and fold it into the history.
    fn render_frame(&mut self, j: u64, t: f64) {
        let tracer = self.ctx.tracer.clone();
        let (w, h) = tracer.size();
        let (gw, gh) = self.grid;
        let state = tracer.state_at(t);
        let cam = state.camera;
        let k = j % JITTER_PERIOD + 1;
        let (jx, jy) = (halton(k, 2), halton(k, 3));
        let (sx, sy) = (w as f32 / gw as f32, h as f32 / gh as f32);
        let t0 = std::time::Instant::now();
        let low: Vec<Sample> = (0..gw * gh)
            .into_par_iter()
            .map(|q| {
                tracer.sample(
                    &state,
                    ((q % gw) as f32 + jx) * sx,
                    ((q / gw) as f32 + jy) * sy,
                )
            })
            .collect();
        self.trace_s += t0.elapsed().as_secs_f64();
        self.samples += (gw * gh) as u64;
        // Current estimate at each display pixel: bilinear over the jittered grid, and the
        // nearest low-resolution sample for motion and depth.
        let at = |x: f32, y: f32| -> (Vec3, &Sample) {
            let u = (x / sx - jx).clamp(0.0, gw as f32 - 1.0);
            let v = (y / sy - jy).clamp(0.0, gh as f32 - 1.0);
            let (x0, y0) = (u.floor() as u32, v.floor() as u32);
            let (x1, y1) = ((x0 + 1).min(gw - 1), (y0 + 1).min(gh - 1));
            let (fx, fy) = (u - x0 as f32, v - y0 as f32);
            let s = |i: u32, j: u32| &low[(j * gw + i) as usize];
            let c = s(x0, y0)
                .color
                .lerp(s(x1, y0).color, fx)
                .lerp(s(x0, y1).color.lerp(s(x1, y1).color, fx), fy);
            let near = s(
                if fx < 0.5 { x0 } else { x1 },
                if fy < 0.5 { y0 } else { y1 },
            );
            (c, near)
        };
        let current: Vec<(Vec3, Vec3, Vec3, f32)> = (0..w * h)
            .into_par_iter()
            .map(|q| {
                let (x, y) = ((q % w) as f32 + 0.5, (q / w) as f32 + 0.5);
                let (c, s) = at(x, y);
                (
                    c,
                    s.hit_point,
                    s.velocity,
                    if s.hit { s.depth } else { f32::INFINITY },
                )
            })
            .collect();
        let dt = self.prev_camera.map(|_| (1.0 / 60.0) as f32).unwrap_or(0.0);
        let prev = self.prev_camera;
        let history = &self.output;
        let prev_depth = &self.depth;
        let results: Vec<(Vec3, bool)> = (0..w * h)
            .into_par_iter()
            .map(|q| {
                let (c, p, vel, depth) = current[q as usize];
                let Some(pc) = prev else { return (c, true) };
                // Motion vector: how the point under this pixel moved on screen since the
                // previous frame (the point is the nearest low-resolution sample's, so only
                // its displacement, not its position, applies to the pixel).
                let Some((cx, cy, _)) = cam.project(p) else {
                    return (c, true);
                };
                let Some((ox, oy, pd)) = pc.project(p - vel * dt) else {
                    return (c, true);
                };
                let (px, py) = (
                    (q % w) as f32 + 0.5 + (ox - cx),
                    (q / w) as f32 + 0.5 + (oy - cy),
                );
                if !(px >= 0.0 && py >= 0.0 && px < w as f32 && py < h as f32) {
                    return (c, true);
                }
                let stored =
                    prev_depth[((py as u32).min(h - 1) * w + (px as u32).min(w - 1)) as usize];
                let disoccluded = if depth.is_finite() {
                    // Compare view depth of this point in the previous frame with what the
                    // previous frame saw there.
                    !stored.is_finite() || (stored - pd).abs() > DEPTH_TOLERANCE * pd.max(1e-6)
                } else {
                    stored.is_finite()
                };
                if disoccluded {
                    return (c, true);
                }
                // Neighbourhood clamp in YCoCg over the 3×3 low-resolution samples around
                // the pixel (the current frame's own samples, not their interpolation:
                // the interpolated neighbourhood moves with the jitter and makes the
                // clamp flicker).
                let (x, y) = ((q % w) as f32 + 0.5, (q / w) as f32 + 0.5);
                let (gi, gj) = (
                    ((x / sx - jx).round() as i32).clamp(0, gw as i32 - 1),
                    ((y / sy - jy).round() as i32).clamp(0, gh as i32 - 1),
                );
                let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
                for dj in -1i32..=1 {
                    for di in -1i32..=1 {
                        let (ni, nj) = (
                            (gi + di).clamp(0, gw as i32 - 1) as u32,
                            (gj + dj).clamp(0, gh as i32 - 1) as u32,
                        );
                        let n = to_ycocg(low[(nj * gw + ni) as usize].color);
                        lo = lo.min(n);
                        hi = hi.max(n);
                    }
                }
                let hist = from_ycocg(to_ycocg(catmull_rom(history, px, py)).clamp(lo, hi));
                (hist.lerp(c, ALPHA), false)
            })
            .collect();
        for (q, (c, rejected)) in results.into_iter().enumerate() {
            self.output.pixels[q] = c;
            if rejected {
                self.rejections += 1;
                self.history_time[q] = t;
            } else {
                // Exponential blend: information age follows the same recurrence.
                self.history_time[q] += ALPHA as f64 * (t - self.history_time[q]);
            }
        }
        // View depth (along the camera axis) of what each display pixel shows.
        self.depth = current
            .iter()
            .map(|&(_, p, _, d)| {
                if d.is_finite() {
                    cam.project(p).map_or(f32::INFINITY, |(_, _, z)| z)
                } else {
                    f32::INFINITY
                }
            })
            .collect();
        self.prev_camera = Some(cam);
        self.front_time = Some(t);
    }
}

impl Method for Taa {
    fn display(&mut self, t: f64) -> Displayed<'_> {
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
        let age = if self.front_time.is_some() {
            self.history_time.iter().map(|s| t - s).sum::<f64>() / self.history_time.len() as f64
        } else {
            t - self.ctx.clock.start
        };
        Displayed {
            image: &self.output,
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn halton_and_ycocg() {
        assert_eq!(halton(1, 2), 0.5);
        assert_eq!(halton(2, 2), 0.25);
        assert!((halton(1, 3) - 1.0 / 3.0).abs() < 1e-7);
        let c = Vec3::new(0.2, 0.5, 0.9);
        assert!((from_ycocg(to_ycocg(c)) - c).length() < 1e-6);
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
