//! Late warp: what VR and game engines do for low latency (Oculus ATW/ASW, NVIDIA
//! Reflex 2 Frame Warp), at the same budget.
//!
//! Rendering is exactly `framed-60hz` (double-buffered, a frame every 1/60 s at the
//! reduced resolution `R/60` allows, upscaled bilinearly). At every display refresh the
//! newest completed frame is reprojected to the camera at the refresh time. This runs on
//! the display side, as in practice (a compositor or the scan-out path): it reads the
//! frame's G-buffer and traces no rays, so it costs nothing of the sample budget.
//!
//! [`Warp`] is the reprojection, reusable for any frame that comes with a [`GBuffer`]
//! (e.g. a TAA output warped the same way):
//! - A hit moves as a point: traced at `t_f` at world position `X` with world velocity
//!   `v`, it is predicted at `X + v·(t − t_f)` at display time `t` (space-warp) and
//!   projected with the camera at `t`. A miss (background) is a direction, not a point:
//!   it moves with the camera rotation only.
//! - Forward splat with a depth test (nearest view depth at `t` wins) into the display.
//!   The frame is low resolution and upscaled, so the warp moves the *upscaled* image
//!   pixel by pixel, each pixel by the motion of the grid sample whose cell holds it:
//!   each sample's footprint (≈ the upscale ratio) moves rigidly and keeps the smooth
//!   bilinear colours inside it. The G-buffer is not interpolated: interpolating hit
//!   points across a silhouette invents points in mid-air that land anywhere.
//! - Holes (disocclusions, the edge the camera turns towards, gaps where the image
//!   stretches) take the mean of their valid 8-neighbours, growing inward from the
//!   hole's border: the nearest valid neighbour, without ghosts of an older image.
//!
//! With a still camera and a static scene every motion is exactly zero and the warp is
//! the identity: `late-warp` shows what `framed-60hz` shows.

use glam::Vec3;
use rayon::prelude::*;

use super::{
    framed::{Framed, GBuffer, GSample},
    sixty_per_second, Budget, Displayed, Method, MethodContext, MethodError, MethodInfo,
};
use crate::{image::Image, scene::CameraFrame};

/// `late-warp`.
pub const LATE_WARP: MethodInfo = MethodInfo {
    name: "late-warp",
    description: "framed-60hz, newest frame reprojected to the camera at each refresh (depth + object motion; display-side, no rays)",
    budget: Budget::Rate,
    check_rate: |_, rate| sixty_per_second("late-warp", rate),
    build: |ctx| Ok(Box::new(LateWarp::new(ctx)?)),
};

/// Display-side reprojection of a frame to another time and camera, with its buffers.
pub struct Warp {
    out: Image,
    depth: Vec<f32>,
    filled: Vec<bool>,
    /// Each grid sample's screen motion (kept across warps: no allocation per refresh).
    moves: Vec<Option<(f32, f32, f32)>>,
    /// The holes of the current and the next pass of the hole filling, and which
    /// holes are in one (kept across warps).
    hole_list: Vec<usize>,
    next_holes: Vec<usize>,
    queued: Vec<bool>,
    /// A pass's fills, applied together at its end (kept across warps).
    fills: Vec<(usize, Vec3)>,
    /// Display pixels that no warped pixel reached in the last warp (filled from
    /// neighbours).
    pub holes: u64,
}

/// Where a grid sample moves on screen: `(dx, dy, view depth at the new camera)`, the
/// depth infinite for a miss; `None` when it ends up behind the eye.
fn motion(s: &GSample, dt: f32, from: &CameraFrame, to: &CameraFrame) -> Option<(f32, f32, f32)> {
    if s.hit {
        let (x0, y0, _) = from.project(s.hit_point)?;
        let (x1, y1, z) = to.project(s.hit_point + s.velocity * dt)?;
        Some((x1 - x0, y1 - y0, z))
    } else {
        // Infinitely far: only the view direction matters, so the eye's own motion
        // (parallax) does not move it.
        let d = (s.hit_point - from.eye).normalize_or_zero();
        let (x0, y0, _) = from.project(from.eye + d)?;
        let (x1, y1, _) = to.project(to.eye + d)?;
        Some((x1 - x0, y1 - y0, f32::INFINITY))
    }
}

impl Warp {
    /// Buffers for a `width × height` display.
    pub fn new(width: u32, height: u32) -> Self {
        let n = (width * height) as usize;
        Self {
            out: Image::new(width, height),
            depth: vec![f32::INFINITY; n],
            filled: vec![false; n],
            moves: Vec::new(),
            hole_list: Vec::new(),
            next_holes: Vec::new(),
            queued: vec![false; n],
            fills: Vec::new(),
            holes: 0,
        }
    }

    /// `image` (display resolution, the frame as it would be shown) reprojected from the
    /// frame's time and camera (in `gbuffer`) to display time `t` and `camera`.
    pub fn apply(&mut self, image: &Image, gbuffer: &GBuffer, t: f64, camera: &CameraFrame) -> &Image {
        let (w, h) = (image.width, image.height);
        debug_assert_eq!((w, h), (self.out.width, self.out.height));
        let (gw, gh) = gbuffer.grid;
        let dt = (t - gbuffer.time) as f32;
        gbuffer
            .samples
            .par_iter()
            .map(|s| motion(s, dt, &gbuffer.camera, camera))
            .collect_into_vec(&mut self.moves);
        let moves = &self.moves;
        self.depth.fill(f32::INFINITY);
        self.filled.fill(false);
        let (cx, cy) = (gw as f32 / w as f32, gh as f32 / h as f32);
        for y in 0..h {
            let j = (((y as f32 + 0.5) * cy) as u32).min(gh - 1);
            for x in 0..w {
                let i = (((x as f32 + 0.5) * cx) as u32).min(gw - 1);
                let Some((dx, dy, z)) = moves[(j * gw + i) as usize] else {
                    continue;
                };
                let (tx, ty) = (
                    (x as f32 + 0.5 + dx).floor(),
                    (y as f32 + 0.5 + dy).floor(),
                );
                if !(tx >= 0.0 && ty >= 0.0 && tx < w as f32 && ty < h as f32) {
                    continue;
                }
                let q = (ty as u32 * w + tx as u32) as usize;
                // Strictly nearer wins, so the first of equals stays: with no motion every
                // pixel lands on itself and the warp is the identity.
                if !self.filled[q] || z < self.depth[q] {
                    self.filled[q] = true;
                    self.depth[q] = z;
                    self.out.pixels[q] = image.pixels[(y * w + x) as usize];
                }
            }
        }
        self.fill_holes();
        &self.out
    }

    /// The last warp's result.
    pub fn image(&self) -> &Image {
        &self.out
    }

    /// Each hole takes the mean of its valid 8-neighbours, pass after pass, so holes
    /// close from their border inward with the nearest valid colours. Sets `holes`.
    ///
    /// Each pass visits only its frontier (the holes next to a pixel valid at the start
    /// of the pass: those next to the previous pass's fills), so the work is linear in
    /// the holes: a camera turn that uncovers a band 80 pixels wide took 80 passes over
    /// every hole (90 ms on a 256² kitchen). Every hole gets the same value as from
    /// passes over all holes: its neighbours are read as they were when its pass began,
    /// in the same order.
    fn fill_holes(&mut self) {
        let (w, h) = (self.out.width as i64, self.out.height as i64);
        let neighbours = move |q: usize| {
            let (x, y) = (q as i64 % w, q as i64 / w);
            ((y - 1).max(0)..=(y + 1).min(h - 1)).flat_map(move |ny| {
                ((x - 1).max(0)..=(x + 1).min(w - 1)).map(move |nx| (ny * w + nx) as usize)
            })
        };
        let mut frontier = std::mem::take(&mut self.hole_list);
        let mut next = std::mem::take(&mut self.next_holes);
        frontier.clear();
        self.queued.clear();
        self.queued.resize(self.filled.len(), false);
        let mut holes = 0;
        for q in 0..self.filled.len() {
            if !self.filled[q] {
                holes += 1;
                if neighbours(q).any(|p| self.filled[p]) {
                    self.queued[q] = true;
                    frontier.push(q);
                }
            }
        }
        self.holes = holes;
        let mut fills = std::mem::take(&mut self.fills);
        // Holes with no valid pixel anywhere around never join a frontier and keep
        // what the buffer holds.
        while !frontier.is_empty() {
            fills.clear();
            for &q in &frontier {
                let (mut sum, mut n) = (Vec3::ZERO, 0u32);
                for p in neighbours(q) {
                    if self.filled[p] {
                        sum += self.out.pixels[p];
                        n += 1;
                    }
                }
                fills.push((q, sum / n as f32));
            }
            for &(q, c) in &fills {
                self.out.pixels[q] = c;
                self.filled[q] = true;
            }
            next.clear();
            for &(q, _) in &fills {
                for p in neighbours(q) {
                    if !self.filled[p] && !self.queued[p] {
                        self.queued[p] = true;
                        next.push(p);
                    }
                }
            }
            std::mem::swap(&mut frontier, &mut next);
        }
        self.hole_list = frontier;
        self.next_holes = next;
        self.fills = fills;
    }
}

/// `framed-60hz` with its front frame warped to every refresh.
pub struct LateWarp {
    ctx: MethodContext,
    framed: Framed,
    warp: Warp,
    warps: u64,
    hole_pixels: u64,
}

impl LateWarp {
    /// Create for one run.
    pub fn new(ctx: &MethodContext) -> Result<Self, MethodError> {
        sixty_per_second("late-warp", ctx.clock.rate)?;
        let (w, h) = ctx.tracer.size();
        Ok(Self {
            ctx: ctx.clone(),
            framed: Framed::sixty_hz(ctx)?.keep_gbuffer(),
            warp: Warp::new(w, h),
            warps: 0,
            hole_pixels: 0,
        })
    }
}

impl Method for LateWarp {
    fn display(&mut self, t: f64) -> Displayed<'_> {
        let mean_age = self.framed.display(t).mean_age;
        let Some(gbuffer) = self.framed.front_gbuffer() else {
            return Displayed {
                image: self.framed.front(),
                mean_age,
            };
        };
        let camera = self.ctx.tracer.state_at(t).camera;
        self.warp.apply(self.framed.front(), gbuffer, t, &camera);
        self.warps += 1;
        self.hole_pixels += self.warp.holes;
        // Warping predicts where old information is now; it adds none, so the age is
        // the frame's.
        Displayed {
            image: self.warp.image(),
            mean_age,
        }
    }

    fn samples_used(&self) -> u64 {
        self.framed.samples_used()
    }

    fn trace_seconds(&self) -> f64 {
        self.framed.trace_seconds()
    }

    fn extra_stats(&self) -> Option<serde_json::Value> {
        let (w, h) = self.ctx.tracer.size();
        let per_warp = self.hole_pixels as f64 / self.warps.max(1) as f64;
        Some(serde_json::json!({
            "warps": self.warps,
            "hole_fraction_mean": per_warp / (w as f64 * h as f64),
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Camera;

    fn camera(at: Vec3) -> CameraFrame {
        Camera {
            eye: Vec3::ZERO,
            at,
            up: Vec3::Y,
            fov_y_deg: 60.0,
            hither: 1e-3,
        }
        .frame(16, 16)
    }

    fn gbuffer(samples: Vec<GSample>, grid: (u32, u32), cam: CameraFrame) -> GBuffer {
        GBuffer {
            grid,
            samples,
            time: 0.0,
            camera: cam,
        }
    }

    #[test]
    fn a_moving_point_lands_where_it_is_at_display_time() {
        let cam = camera(Vec3::NEG_Z);
        let p = Vec3::new(0.0, 0.0, -4.0);
        let s = GSample {
            hit_point: p,
            velocity: Vec3::new(1.0, 0.0, 0.0),
            hit: true,
        };
        let (dx, dy, z) = motion(&s, 0.5, &cam, &cam).unwrap();
        let (x0, y0, _) = cam.project(p).unwrap();
        let (x1, y1, _) = cam.project(p + Vec3::new(0.5, 0.0, 0.0)).unwrap();
        assert!((dx - (x1 - x0)).abs() < 1e-4 && (dy - (y1 - y0)).abs() < 1e-4);
        assert!(dx > 0.5 && (z - 4.0).abs() < 1e-5);
    }

    #[test]
    fn the_background_moves_with_rotation_only() {
        let (a, b) = (camera(Vec3::NEG_Z), camera(Vec3::new(0.1, 0.0, -1.0)));
        let mut b_moved = b;
        b_moved.eye += Vec3::new(5.0, 0.0, 0.0);
        let miss = GSample {
            hit_point: Vec3::new(0.0, 0.0, -1e6),
            velocity: Vec3::ZERO,
            hit: false,
        };
        let turned = motion(&miss, 0.0, &a, &b).unwrap();
        let turned_and_moved = motion(&miss, 0.0, &a, &b_moved).unwrap();
        assert!(turned.0 < -1.0, "{turned:?}");
        assert!((turned.0 - turned_and_moved.0).abs() < 1e-4);
        assert!(turned.2.is_infinite());
    }

    #[test]
    fn nearer_wins_and_holes_are_filled() {
        // A 2×1 grid over a 16×16 display: the left half (near) moves right onto the
        // far right half, which stays; the left half's old place is a hole.
        let cam = camera(Vec3::NEG_Z);
        let left = cam.direction(4.0, 8.0) * 2.0;
        let right = cam.direction(12.0, 8.0) * 10.0;
        let shift = cam.direction(12.0, 8.0) * 2.0 - left;
        let g = gbuffer(
            vec![
                GSample {
                    hit_point: left,
                    velocity: shift,
                    hit: true,
                },
                GSample {
                    hit_point: right,
                    velocity: Vec3::ZERO,
                    hit: true,
                },
            ],
            (2, 1),
            cam,
        );
        let mut image = Image::new(16, 16);
        for y in 0..16 {
            for x in 0..16 {
                image.pixels[(y * 16 + x) as usize] = if x < 8 { Vec3::X } else { Vec3::Y };
            }
        }
        let mut warp = Warp::new(16, 16);
        let out = warp.apply(&image, &g, 1.0, &cam).clone();
        assert!(out.get(12, 8).x > 0.99, "near left half covers the right");
        assert!(warp.holes > 0);
        assert!(out.pixels.iter().all(|p| (p.x + p.y - 1.0).abs() < 1e-5));
    }

    #[test]
    fn frontier_filling_matches_passes_over_every_hole() {
        // The passes the frontier replaced: every remaining hole examined in each.
        fn reference(pixels: &mut [Vec3], filled: &mut [bool], w: i64, h: i64) {
            let mut holes: Vec<usize> = (0..filled.len()).filter(|&q| !filled[q]).collect();
            loop {
                let mut fills = Vec::new();
                holes.retain(|&q| {
                    let (x, y) = (q as i64 % w, q as i64 / w);
                    let (mut sum, mut n) = (Vec3::ZERO, 0u32);
                    for ny in (y - 1).max(0)..=(y + 1).min(h - 1) {
                        for nx in (x - 1).max(0)..=(x + 1).min(w - 1) {
                            let p = (ny * w + nx) as usize;
                            if filled[p] {
                                sum += pixels[p];
                                n += 1;
                            }
                        }
                    }
                    if n > 0 {
                        fills.push((q, sum / n as f32));
                    }
                    n == 0
                });
                if fills.is_empty() {
                    break;
                }
                for (q, c) in fills {
                    pixels[q] = c;
                    filled[q] = true;
                }
            }
        }
        let (w, h) = (37u32, 23u32);
        let mut rng = crate::sampling::Rng::new(&[7]);
        for case in 0..20 {
            let mut warp = Warp::new(w, h);
            for q in 0..(w * h) as usize {
                warp.out.pixels[q] = Vec3::new(rng.uniform(), rng.uniform(), rng.uniform());
                // Scattered holes, a wide band (a turned camera) and, in one case,
                // nothing valid at all.
                let x = q as u32 % w;
                warp.filled[q] = case != 0 && rng.uniform() < 0.6 && !(x >= 5 && x < 5 + case);
            }
            let (mut pixels, mut filled) = (warp.out.pixels.clone(), warp.filled.clone());
            reference(&mut pixels, &mut filled, w as i64, h as i64);
            let before = warp.filled.iter().filter(|f| !**f).count() as u64;
            warp.fill_holes();
            assert_eq!(warp.holes, before, "case {case}");
            assert_eq!(warp.filled, filled, "case {case}");
            assert!(
                warp.out.pixels.iter().zip(&pixels).all(|(a, b)| a.to_array() == b.to_array()),
                "case {case}"
            );
        }
    }
}
