//! Point tracking (Martin et al. 2002): a framed ray tracer whose rays target the hit
//! points of the previous frame, with a three-frame temporal blend for display.
//!
//! Frames are full resolution and double-buffered like `framed-full` (frame time
//! `W·H/R`, scene as at the frame's start, shown from the first refresh at or after
//! completion). Before frame `j` is traced, the hit points cached by frame `j − 1` are
//! moved by their velocity to the frame's time and projected with its camera; a pixel
//! that receives points fires its ray at the one nearest the eye (the paper: farther
//! points are more likely to be occluded), a pixel that receives none fires through its
//! center. The display averages the last three frames (`point-tracking`) or shows the
//! newest (`point-tracking-no-blend`).
//!
//! Statistics: the share of pixels receiving 0, 1, 2, 3, 4+ points, and the time cost of
//! a tracked frame relative to plain ray tracing of the same frame (each frame is traced
//! a second time through pixel centers for that comparison only; those rays are neither
//! shown nor counted against the budget).

use std::{collections::VecDeque, time::Instant};

use glam::Vec3;
use serde::Serialize;

use super::{one_frame_in_run, Budget, Displayed, Method, MethodContext, MethodInfo};
use crate::{clock::TIME_EPS, image::Image, trace::batch};

/// `point-tracking`.
pub const POINT_TRACKING: MethodInfo = MethodInfo {
    name: "point-tracking",
    description:
        "framed full resolution, rays aimed at the previous frame's hit points, last 3 frames averaged",
    budget: Budget::Rate,
    check_rate: |shape, rate| one_frame_in_run("point-tracking", shape, rate),
    build: |ctx| Ok(Box::new(PointTracking::new(ctx, true))),
};

/// `point-tracking-no-blend`.
pub const POINT_TRACKING_NO_BLEND: MethodInfo = MethodInfo {
    name: "point-tracking-no-blend",
    description: "point tracking showing only the newest frame",
    budget: Budget::Rate,
    check_rate: |shape, rate| one_frame_in_run("point-tracking-no-blend", shape, rate),
    build: |ctx| Ok(Box::new(PointTracking::new(ctx, false))),
};

/// What point tracking measured over a run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct PointTrackingStats {
    /// Frames with a previous frame to track from.
    pub tracked_frames: u64,
    /// Pixels that received 0, 1, 2, 3 and 4 or more reprojected points, summed.
    pub histogram: [u64; 5],
    /// The same, counting only pixels whose ray hit geometry (rays into the background
    /// leave no point to track, so a view with sky has that many zero-point pixels).
    pub histogram_geometry: [u64; 5],
    /// Seconds spent reprojecting cached points.
    pub reproject_s: f64,
    /// Seconds spent tracing the tracked rays.
    pub tracked_trace_s: f64,
    /// Seconds spent tracing the same frames through pixel centers (comparison only).
    pub plain_trace_s: f64,
}

impl PointTrackingStats {
    /// Shares of pixels with 0, 1, 2, 3, 4+ points.
    pub fn shares(&self) -> [f64; 5] {
        let total: u64 = self.histogram.iter().sum();
        self.histogram.map(|c| c as f64 / total.max(1) as f64)
    }

    /// Shares among pixels showing geometry.
    pub fn shares_geometry(&self) -> [f64; 5] {
        let total: u64 = self.histogram_geometry.iter().sum();
        self.histogram_geometry
            .map(|c| c as f64 / total.max(1) as f64)
    }

    /// Cost of point tracking (reprojection + tracking) over plain ray tracing.
    pub fn cost_ratio(&self) -> f64 {
        (self.reproject_s + self.tracked_trace_s) / self.plain_trace_s.max(1e-12)
    }
}

#[derive(Clone, Copy)]
struct Cached {
    p: Vec3,
    velocity: Vec3,
}

/// The point-tracking renderer.
pub struct PointTracking {
    ctx: MethodContext,
    blend: bool,
    duration: f64,
    next_frame: u64,
    cache: Vec<Option<Cached>>,
    cache_time: f64,
    frames: VecDeque<(Image, f64)>,
    front: Image,
    front_info: Option<f64>,
    samples: u64,
    stats: PointTrackingStats,
}

impl PointTracking {
    /// Create for one run; `blend` averages the last three frames.
    pub fn new(ctx: &MethodContext, blend: bool) -> Self {
        let (w, h) = ctx.tracer.size();
        Self {
            ctx: ctx.clone(),
            blend,
            duration: (w as f64 * h as f64) / ctx.clock.rate,
            next_frame: 0,
            cache: Vec::new(),
            cache_time: 0.0,
            frames: VecDeque::new(),
            front: Image::new(w, h),
            front_info: None,
            samples: 0,
            stats: PointTrackingStats::default(),
        }
    }

    /// Statistics so far.
    pub fn stats(&self) -> PointTrackingStats {
        self.stats
    }

    fn frame_start(&self, j: u64) -> f64 {
        self.ctx.clock.start + j as f64 * self.duration
    }

    /// Where each pixel's ray goes: the nearest reprojected point's position, or `None`
    /// for the pixel center; also the number of points per pixel.
    pub fn targets(&self, t: f64) -> (Vec<Option<(f32, f32)>>, Vec<u32>) {
        let tracer = &self.ctx.tracer;
        let (w, h) = tracer.size();
        let cam = tracer.state_at(t).camera;
        let dt = (t - self.cache_time) as f32;
        let n = (w * h) as usize;
        let mut best: Vec<Option<(f32, f32, f32)>> = vec![None; n];
        let mut count = vec![0u32; n];
        for c in self.cache.iter().flatten() {
            let Some((x, y, depth)) = cam.project(c.p + c.velocity * dt) else {
                continue;
            };
            if !(x >= 0.0 && y >= 0.0 && x < w as f32 && y < h as f32) {
                continue;
            }
            let q = (y as u32).min(h - 1) * w + (x as u32).min(w - 1);
            count[q as usize] += 1;
            if best[q as usize].is_none_or(|(_, _, d)| depth < d) {
                best[q as usize] = Some((x, y, depth));
            }
        }
        (
            best.into_iter()
                .map(|b| b.map(|(x, y, _)| (x, y)))
                .collect(),
            count,
        )
    }

    fn render_frame(&mut self, t: f64) {
        let tracer = self.ctx.tracer.clone();
        let (w, h) = tracer.size();
        let state = tracer.state_at(t);
        let t0 = Instant::now();
        let (targets, counts) = self.targets(t);
        let tracked = !self.cache.is_empty();
        if tracked {
            self.stats.reproject_s += t0.elapsed().as_secs_f64();
            self.stats.tracked_frames += 1;
            for &c in &counts {
                self.stats.histogram[(c as usize).min(4)] += 1;
            }
        }
        let t1 = Instant::now();
        let rays = self.ctx.rays.as_deref();
        let points: Vec<[f32; 2]> = targets
            .iter()
            .enumerate()
            .map(|(q, tg)| {
                let (x, y) =
                    tg.unwrap_or(((q as u32 % w) as f32 + 0.5, (q as u32 / w) as f32 + 0.5));
                [x, y]
            })
            .collect();
        let samples = batch::trace_points(&tracer, rays, &state, &points);
        let traced = t1.elapsed().as_secs_f64();
        if tracked {
            for (c, s) in counts.iter().zip(&samples) {
                if s.hit {
                    self.stats.histogram_geometry[(*c as usize).min(4)] += 1;
                }
            }
            self.stats.tracked_trace_s += traced;
            let t2 = Instant::now();
            let centres: Vec<[f32; 2]> = (0..w * h)
                .map(|q| [(q % w) as f32 + 0.5, (q / w) as f32 + 0.5])
                .collect();
            let plain: f32 = batch::trace_points(&tracer, rays, &state, &centres)
                .iter()
                .map(|s| s.luminance)
                .sum();
            std::hint::black_box(plain);
            self.stats.plain_trace_s += t2.elapsed().as_secs_f64();
        }
        self.cache = samples
            .iter()
            .map(|s| {
                s.hit.then_some(Cached {
                    p: s.hit_point,
                    velocity: s.velocity,
                })
            })
            .collect();
        self.cache_time = t;
        let img = Image {
            width: w,
            height: h,
            pixels: samples.iter().map(|s| s.color).collect(),
        };
        self.frames.push_back((img, t));
        while self.frames.len() > if self.blend { 3 } else { 1 } {
            self.frames.pop_front();
        }
        let k = self.frames.len() as f32;
        let mut front = Image::new(w, h);
        for (img, _) in &self.frames {
            for (o, p) in front.pixels.iter_mut().zip(&img.pixels) {
                *o += *p / k;
            }
        }
        self.front = front;
        self.front_info =
            Some(self.frames.iter().map(|(_, t)| t).sum::<f64>() / self.frames.len() as f64);
    }
}

impl Method for PointTracking {
    fn display(&mut self, t: f64) -> Displayed<'_> {
        let clock = self.ctx.clock;
        // Every completed frame is traced: each one's hit points guide the next.
        while clock.first_refresh_at_or_after(self.frame_start(self.next_frame + 1)) <= t + TIME_EPS
        {
            let start = self.frame_start(self.next_frame);
            self.render_frame(start);
            self.next_frame += 1;
            self.samples += self.front.pixels.len() as u64;
        }
        let info = self.front_info.unwrap_or(clock.start);
        Displayed {
            image: &self.front,
            mean_age: t - info,
        }
    }

    fn samples_used(&self) -> u64 {
        self.samples
    }

    fn trace_seconds(&self) -> f64 {
        self.stats.tracked_trace_s + self.stats.plain_trace_s
    }

    fn extra_stats(&self) -> Option<serde_json::Value> {
        let s = self.stats;
        Some(serde_json::json!({
            "tracked_frames": s.tracked_frames,
            "points_per_pixel_share": { "0": s.shares()[0], "1": s.shares()[1], "2": s.shares()[2], "3": s.shares()[3], "4+": s.shares()[4] },
            "points_per_pixel_share_geometry": {
                "0": s.shares_geometry()[0], "1": s.shares_geometry()[1], "2": s.shares_geometry()[2],
                "3": s.shares_geometry()[3], "4+": s.shares_geometry()[4]
            },
            "cost_ratio_vs_plain": s.cost_ratio(),
            "reproject_s": s.reproject_s,
            "tracked_trace_s": s.tracked_trace_s,
            "plain_trace_s": s.plain_trace_s,
        }))
    }
}
