//! Framed, double-buffered rendering.
//!
//! Frame `j` starts at `start + j·D`, sees the scene as it is at its start, completes at
//! `start + (j+1)·D` and is shown from the first refresh at or after completion until
//! the next frame is shown. Three variants:
//! - `framed-60hz`: `D = 1/60 s`, at most `R/60` samples per frame at reduced resolution
//!   (aspect kept), upscaled bilinearly;
//! - `framed-full`: one sample per display pixel, `D = W·H/R`;
//! - `full-res-60hz`: one sample per display pixel, `D = 1/60 s`, i.e. its own budget
//!   `W·H·60` whatever rate was asked.
//!
//! Each frame samples pixel centers (of its own grid): no antialiasing, as in the paper.
//!
//! On request ([`Framed::keep_gbuffer`]) the front frame also keeps what each of its
//! samples hit ([`GBuffer`]), for display-side reprojection (`late-warp`); that changes
//! neither the rays traced nor the images.

use rayon::prelude::*;

use super::{
    any_rate, one_frame_in_run, sixty_per_second, Budget, FRAME_HZ, Displayed, Method, MethodContext,
    MethodError, MethodInfo,
};
use crate::{
    clock::TIME_EPS,
    image::Image,
    scene::CameraFrame,
    trace::{
        batch::{self, GpuRays},
        Sample, SceneState, Tracer,
    },
};

/// What one grid sample of a frame hit: enough to move it to another time and camera.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GSample {
    /// World hit point at the frame's time (on a miss, a far point along the ray).
    pub hit_point: glam::Vec3,
    /// World velocity of the hit point (zero on a miss).
    pub velocity: glam::Vec3,
    /// Whether the primary ray hit anything (a miss is a direction, not a point).
    pub hit: bool,
}

impl From<&Sample> for GSample {
    fn from(s: &Sample) -> Self {
        Self {
            hit_point: s.hit_point,
            velocity: s.velocity,
            hit: s.hit,
        }
    }
}

/// A frame's geometry buffer: one [`GSample`] per cell of a grid spread over the display
/// (cell `(i, j)` traced through its centre), the time the frame saw the scene at and
/// its camera.
#[derive(Clone, Debug)]
pub struct GBuffer {
    /// Cells across and down.
    pub grid: (u32, u32),
    /// Row-major, `grid.0 × grid.1`.
    pub samples: Vec<GSample>,
    /// Scene time of the frame.
    pub time: f64,
    /// The camera the frame was traced with.
    pub camera: CameraFrame,
}

/// `framed-60hz`.
pub const FRAMED_60HZ: MethodInfo = MethodInfo {
    name: "framed-60hz",
    description:
        "double-buffered at 60 Hz, R/60 samples per frame at reduced resolution, upscaled",
    budget: Budget::Rate,
    check_rate: |_, rate| sixty_per_second("framed-60hz", rate),
    build: |ctx| Ok(Box::new(Framed::sixty_hz(ctx)?)),
};

/// `framed-full`.
pub const FRAMED_FULL: MethodInfo = MethodInfo {
    name: "framed-full",
    description: "double-buffered, one sample per pixel, frame rate R/(W*H)",
    budget: Budget::Rate,
    check_rate: |shape, rate| one_frame_in_run("framed-full", shape, rate),
    build: |ctx| Ok(Box::new(Framed::full_res(ctx)?)),
};

/// `full-res-60hz`.
pub const FULL_RES_60HZ: MethodInfo = MethodInfo {
    name: "full-res-60hz",
    description: "double-buffered full resolution at 60 Hz; budget W*H*60 regardless of the rate",
    budget: Budget::Own(|s| s.pixels() * FRAME_HZ),
    check_rate: any_rate,
    build: |ctx| Ok(Box::new(Framed::full_res_60hz(ctx)?)),
};

/// A double-buffered framed renderer.
pub struct Framed {
    ctx: MethodContext,
    grid: (u32, u32),
    duration: f64,
    next_frame: u64,
    front: Image,
    front_time: Option<f64>,
    /// `Some` when asked for: the front frame's G-buffer (empty until the first frame).
    front_gbuffer: Option<Option<GBuffer>>,
    samples: u64,
    trace_s: f64,
}

impl Framed {
    fn new(ctx: &MethodContext, grid: (u32, u32), duration: f64) -> Result<Self, MethodError> {
        let (w, h) = ctx.tracer.size();
        if !(duration.is_finite() && duration > 0.0) {
            return Err(MethodError::Parameter {
                group: "framed",
                name: "frame duration",
                why: "must be positive and finite",
            });
        }
        Ok(Self {
            ctx: ctx.clone(),
            grid,
            duration,
            next_frame: 0,
            front: Image::new(w, h),
            front_time: None,
            front_gbuffer: None,
            samples: 0,
            trace_s: 0.0,
        })
    }

    /// Keep the front frame's [`GBuffer`] from now on (same rays, same images).
    pub fn keep_gbuffer(mut self) -> Self {
        self.front_gbuffer = Some(None);
        self
    }

    /// The front frame's G-buffer, once a frame is shown and if [`Self::keep_gbuffer`]
    /// asked for it.
    pub fn front_gbuffer(&self) -> Option<&GBuffer> {
        self.front_gbuffer.as_ref().and_then(|g| g.as_ref())
    }

    /// The image shown now (the front frame, upscaled).
    pub fn front(&self) -> &Image {
        &self.front
    }

    /// `framed-60hz`: the largest grid of the display's aspect with at most R/60 samples.
    pub fn sixty_hz(ctx: &MethodContext) -> Result<Self, MethodError> {
        let (w, h) = ctx.tracer.size();
        sixty_per_second("framed-60hz", ctx.clock.rate)?;
        let per_frame = (ctx.clock.rate / FRAME_HZ).floor();
        Self::new(ctx, reduced_grid(w, h, per_frame as u64), 1.0 / FRAME_HZ)
    }

    /// `framed-full`: one sample per pixel, frame time W·H/R.
    pub fn full_res(ctx: &MethodContext) -> Result<Self, MethodError> {
        let (w, h) = ctx.tracer.size();
        Self::new(ctx, (w, h), (w as f64 * h as f64) / ctx.clock.rate)
    }

    /// `full-res-60hz`: one sample per pixel at 60 Hz (budget W·H·60).
    pub fn full_res_60hz(ctx: &MethodContext) -> Result<Self, MethodError> {
        let (w, h) = ctx.tracer.size();
        Self::new(ctx, (w, h), 1.0 / FRAME_HZ)
    }

    /// Samples in one frame.
    pub fn samples_per_frame(&self) -> u64 {
        self.grid.0 as u64 * self.grid.1 as u64
    }

    /// Frame resolution.
    pub fn grid(&self) -> (u32, u32) {
        self.grid
    }

    /// Seconds per frame.
    pub fn frame_duration(&self) -> f64 {
        self.duration
    }

    fn frame_start(&self, j: u64) -> f64 {
        self.ctx.clock.start + j as f64 * self.duration
    }

    /// The refresh at which frame `j` is first shown.
    pub fn shown_at(&self, j: u64) -> f64 {
        self.ctx
            .clock
            .first_refresh_at_or_after(self.frame_start(j + 1))
    }

    fn render_frame(&mut self, t: f64) {
        let t0 = std::time::Instant::now();
        let tracer = &self.ctx.tracer;
        let state = tracer.state_at(t);
        let (gw, gh) = self.grid;
        let (w, h) = tracer.size();
        let samples = trace_grid(tracer, self.ctx.rays.as_deref(), &state, (gw, gh));
        if let Some(gbuffer) = &mut self.front_gbuffer {
            *gbuffer = Some(GBuffer {
                grid: (gw, gh),
                samples: samples.iter().map(GSample::from).collect(),
                time: t,
                camera: state.camera,
            });
        }
        let small: Vec<glam::Vec3> = samples.iter().map(|s| s.color).collect();
        self.trace_s += t0.elapsed().as_secs_f64();
        self.front = upscale(
            &Image {
                width: gw,
                height: gh,
                pixels: small,
            },
            w,
            h,
        );
    }
}

/// The largest `gw × gh ≤ n` grid with (about) the aspect of `w × h`, within `w × h`.
pub fn reduced_grid(w: u32, h: u32, n: u64) -> (u32, u32) {
    let aspect = w as f64 / h as f64;
    // Never wider than the budget: at one row per frame (a very wide display) the
    // aspect-true width would exceed it.
    let gw = ((n as f64 * aspect).sqrt().floor() as u64).clamp(1, (w as u64).min(n.max(1)));
    let gh = (n / gw).clamp(1, h as u64);
    (gw as u32, gh as u32)
}

/// Bilinear upscaling (texel centers aligned, edges clamped).
pub fn upscale(src: &Image, w: u32, h: u32) -> Image {
    if src.width == w && src.height == h {
        return src.clone();
    }
    let (sw, sh) = (src.width as f32, src.height as f32);
    let mut out = Image::new(w, h);
    out.pixels
        .par_chunks_mut(w as usize)
        .enumerate()
        .for_each(|(y, row)| {
            let v = ((y as f32 + 0.5) * sh / h as f32 - 0.5).clamp(0.0, sh - 1.0);
            let (y0, fy) = (v.floor() as u32, v.fract());
            let y1 = (y0 + 1).min(src.height - 1);
            for (x, px) in row.iter_mut().enumerate() {
                let u = ((x as f32 + 0.5) * sw / w as f32 - 0.5).clamp(0.0, sw - 1.0);
                let (x0, fx) = (u.floor() as u32, u.fract());
                let x1 = (x0 + 1).min(src.width - 1);
                let a = src.get(x0, y0).lerp(src.get(x1, y0), fx);
                let b = src.get(x0, y1).lerp(src.get(x1, y1), fx);
                *px = a.lerp(b, fy);
            }
        });
    out
}

impl Method for Framed {
    fn display(&mut self, t: f64) -> Displayed<'_> {
        // Frames shown by `t`: only the newest needs rendering, but all were traced.
        let mut newest = None;
        while self.shown_at(self.next_frame) <= t + TIME_EPS {
            newest = Some(self.next_frame);
            self.next_frame += 1;
            self.samples += self.samples_per_frame();
        }
        if let Some(j) = newest {
            let start = self.frame_start(j);
            self.render_frame(start);
            self.front_time = Some(start);
        }
        let info = self.front_time.unwrap_or(self.ctx.clock.start);
        Displayed {
            image: &self.front,
            mean_age: t - info,
        }
    }

    fn samples_used(&self) -> u64 {
        self.samples
    }
    fn trace_seconds(&self) -> f64 {
        self.trace_s
    }
}

/// Row `y` of a `grid` of cells spread over the tracer's image, traced through the
/// cells' centres in one scene state: the colours, left to right. Used by [`Framed`] and
/// by the real-time framed method (whose grid is the image's).
pub fn trace_row<'a>(
    tracer: &'a Tracer,
    state: &'a SceneState,
    grid: (u32, u32),
    y: u32,
) -> impl Iterator<Item = glam::Vec3> + 'a {
    trace_row_samples(tracer, state, grid, y).map(|s| s.color)
}

/// Every sample of a `grid` frame in `state`, row-major, as [`trace_row_samples`]
/// traces each row: on the GPU tracer `rays` in one batch where there is one.
pub fn trace_grid(
    tracer: &Tracer,
    rays: Option<&GpuRays>,
    state: &SceneState,
    grid: (u32, u32),
) -> Vec<Sample> {
    let (gw, gh) = grid;
    let Some(rays) = rays else {
        return (0..gh)
            .into_par_iter()
            .flat_map_iter(|y| trace_row_samples(tracer, state, grid, y))
            .collect();
    };
    let (w, h) = tracer.size();
    let (sx, sy) = (w as f32 / gw as f32, h as f32 / gh as f32);
    let points: Vec<[f32; 2]> = (0..gh)
        .flat_map(|y| (0..gw).map(move |x| [(x as f32 + 0.5) * sx, (y as f32 + 0.5) * sy]))
        .collect();
    batch::trace_points(tracer, Some(rays), state, &points)
}

/// [`trace_row`] with everything the tracer returned, not only the colours.
pub fn trace_row_samples<'a>(
    tracer: &'a Tracer,
    state: &'a SceneState,
    grid: (u32, u32),
    y: u32,
) -> impl Iterator<Item = Sample> + 'a {
    let (w, h) = tracer.size();
    let (gw, gh) = grid;
    let (sx, sy) = (w as f32 / gw as f32, h as f32 / gh as f32);
    (0..gw).map(move |x| tracer.sample(state, (x as f32 + 0.5) * sx, (y as f32 + 0.5) * sy))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reduced_grids_fit_the_budget() {
        let (w, h) = reduced_grid(256, 256, 6666);
        assert_eq!((w, h), (81, 82));
        assert!(w * h <= 6666);
        assert_eq!(reduced_grid(256, 256, 1_000_000), (256, 256));
        assert_eq!(reduced_grid(256, 128, 2), (2, 1));
        assert_eq!(reduced_grid(256, 256, 1), (1, 1));
        // Extreme aspect ratios: one row (or column) still fits the budget.
        assert_eq!(reduced_grid(4096, 1, 1667), (1667, 1));
        let (w, h) = reduced_grid(1, 4096, 1667);
        assert!(w * h <= 1667 && w >= 1, "{w}x{h}");
        for (w, h, n) in [(4096, 2, 1667), (2048, 1, 100), (4096, 1, 1)] {
            let (gw, gh) = reduced_grid(w, h, n);
            assert!(gw as u64 * gh as u64 <= n, "{w}x{h} at {n}: {gw}x{gh}");
        }
    }

    #[test]
    fn upscale_of_constant_is_constant() {
        let src = Image {
            width: 2,
            height: 3,
            pixels: vec![glam::Vec3::splat(0.25); 6],
        };
        let up = upscale(&src, 7, 5);
        assert!(up
            .pixels
            .iter()
            .all(|p| (*p - glam::Vec3::splat(0.25)).length() < 1e-6));
    }
}
