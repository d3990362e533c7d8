//! The adaptive space-time reconstructor (paper §5, §6.2; SPEC §4).
//!
//! The reconstructor keeps its own deep buffer: a temporally ordered ring of the `N`
//! most recent samples the sampler traced. At each display refresh (time `t`) it
//!
//! 1. reprojects every sample to the current view: world point `hit_point + velocity ·
//!    (t − t_sample)` projected by the current camera (misses carry a far hit point,
//!    1e6 along their ray, so only camera rotation moves them). There is no depth test:
//!    stale samples behind newly visible surfaces are suppressed by the temporal filter
//!    only, as in the paper;
//! 2. looks up the filter of the tile containing the reprojected pixel (extents from the
//!    tile's local sample rate and gradients, [`filter::extents`]) and the splat scale
//!    of that pixel (from the previous refresh's coverage map);
//! 3. splats it: a Gaussian `w = exp(−½((dx/e_x)² + (dy/e_y)² + (age/e_t)²))` over
//!    the pixels whose centers lie within `spatial_cutoff · scale` sigmas (and at most
//!    `max_radius` pixels) — the splat scale widens the footprint (the paper's point
//!    size), not the kernel, so a wide splat only matters where no nearer sample
//!    outweighs it; samples older than `temporal_cutoff · e_t` are skipped;
//! 4. divides accumulated weighted color by accumulated weight; pixels no sample
//!    reached (accumulated weight below `MIN_WEIGHT` = 1e-24: holes) are filled from the coarsest-necessary level of a 2×2 pull
//!    pyramid of the same sums (a wider box pass: the weighted mean of the nearest
//!    block that has samples), so a hole never shows black unless nothing at all was
//!    sampled yet;
//! 5. updates the splat scale map from the coverage (samples reaching each pixel):
//!    fewer than `undersampled` → ×`grow`, more than `oversampled` → ×`shrink`,
//!    clamped to `scale_bounds`.
//!
//! Splatting runs in parallel over horizontal bands of rows; each band visits the
//! samples touching it in ring order and writes only its own pixels, so every pixel's
//! sums are formed in the same order whatever the thread count (bit-identical images).

pub mod filter;

use std::collections::VecDeque;

use glam::Vec3;
use rayon::prelude::*;

use crate::{
    image::Image,
    methods::adaptive::{sampler::StreamSample, tiling::Tiling},
    scene::CameraFrame,
};
pub use filter::{Extents, FilterBounds};

/// Parameters of the reconstructor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReconParams {
    /// Ring capacity as a multiple of the pixel count (paper: N = 400K at 256×256 ≈ 6).
    pub ring_factor: f64,
    /// Reproject samples to the current view (off: splat where they were traced).
    pub reproject: bool,
    /// A fixed filter for every sample instead of the adaptive one (ablation).
    pub fixed_filter: Option<Extents>,
    /// Clamps of the adaptive filter.
    pub bounds: FilterBounds,
    /// Spatial footprint radius in sigmas.
    pub spatial_cutoff: f32,
    /// Samples older than this many temporal sigmas get no weight.
    pub temporal_cutoff: f32,
    /// Largest footprint radius, pixels (bounds the cost of one splat).
    pub max_radius: f32,
    /// A pixel reached by fewer samples than this is undersampled.
    pub undersampled: u32,
    /// A pixel reached by more samples than this is oversampled.
    pub oversampled: u32,
    /// Splat scale factor applied where undersampled.
    pub grow: f32,
    /// Splat scale factor applied where oversampled.
    pub shrink: f32,
    /// Range of the per-pixel splat scale (multiplies the footprint radius, not the
    /// kernel). The lower bound 1 never cuts the kernel inside `spatial_cutoff` sigmas:
    /// growth widens splats to cover sparse regions, shrinking returns them.
    pub scale_bounds: (f32, f32),
}

impl ReconParams {
    /// The paper's reconstructor: reprojection, adaptive filter, adaptive splat size.
    pub fn paper() -> Self {
        Self {
            ring_factor: 6.0,
            reproject: true,
            fixed_filter: None,
            bounds: FilterBounds::default(),
            spatial_cutoff: 2.5,
            temporal_cutoff: 3.0,
            max_radius: 24.0,
            undersampled: 4,
            oversampled: 32,
            grow: 4.0,
            shrink: 0.7,
            scale_bounds: (1.0, 16.0),
        }
    }

    /// Ablation: samples splat where they were traced.
    pub fn no_reprojection() -> Self {
        Self {
            reproject: false,
            ..Self::paper()
        }
    }

    /// Ablation: a non-adaptive filter, `e_x = e_y = 1` px, `e_t = 0.1` s everywhere
    /// (adaptive splat size still widens it where samples are sparse).
    pub fn fixed_filter() -> Self {
        Self {
            fixed_filter: Some(Extents {
                ex: 1.0,
                ey: 1.0,
                et: 0.1,
            }),
            ..Self::paper()
        }
    }
}

impl Default for ReconParams {
    fn default() -> Self {
        Self::paper()
    }
}

/// One sample of the reconstructor's deep buffer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RingSample {
    /// Sub-pixel position where it was traced.
    pub x: f32,
    /// Sub-pixel position where it was traced.
    pub y: f32,
    /// Time it was traced.
    pub t: f64,
    /// Its color.
    pub color: Vec3,
    /// World point of the primary hit (far point along the ray for a miss).
    pub hit_point: Vec3,
    /// World velocity of the hit point.
    pub velocity: Vec3,
}

impl From<&StreamSample> for RingSample {
    fn from(s: &StreamSample) -> Self {
        Self {
            x: s.x,
            y: s.y,
            t: s.t,
            color: s.sample.color,
            hit_point: s.sample.hit_point,
            velocity: s.sample.velocity,
        }
    }
}

/// A sample prepared for splatting at one refresh.
#[derive(Clone, Copy, Debug)]
struct Splat {
    x: f32,
    y: f32,
    /// Temporal weight factor.
    wt: f32,
    /// `½/σx²`, `½/σy²`.
    ax: f32,
    ay: f32,
    age: f32,
    color: [f32; 3],
    /// Inclusive pixel bounding box of the footprint (clipped to the image).
    x0: u16,
    x1: u16,
    y0: u16,
    y1: u16,
}

/// `e^x` for `x ≤ 0` (relative error below 1e-5, growing with |x| from rounding `x·log2 e` in f32; 0 below −87): `2^(x·log2 e)` split
/// into an exponent and a degree-6 polynomial of the fraction. Deterministic and much
/// cheaper than `f32::exp` in the splat loop.
#[inline(always)]
pub fn fast_exp_neg(x: f32) -> f32 {
    if x < -87.0 {
        return 0.0;
    }
    let v = x * std::f32::consts::LOG2_E;
    let fi = v.round();
    let f = v - fi; // [−½, ½]
                    // 2^f on [−½, ½]: Taylor coefficients ln2^k/k! (truncation error < 1e-8).
    let p = 1.0
        + f * (std::f32::consts::LN_2
            + f * (0.240_226_5
                + f * (0.055_504_11
                    + f * (0.009_618_129 + f * (0.001_333_355_8 + f * 0.000_154_035_3)))));
    let bits = ((fi as i32 + 127) as u32) << 23;
    p * f32::from_bits(bits)
}

/// Accumulated weight below which a pixel counts as a hole: far splat tails reach
/// f32's denormal range, where `Σw·c / Σw` loses all precision.
const MIN_WEIGHT: f32 = 1e-24;
/// Samples per task of the parallel splat preparation.
const PREP_CHUNK: usize = 16384;
/// Rows per band of the parallel splat.
const BAND_ROWS: usize = 8;
/// Widest footprint in pixels along x (`2·max_radius + 1` is clamped to it).
const MAX_SPAN: usize = 128;

/// The adaptive reconstructor.
pub struct Reconstructor {
    params: ReconParams,
    width: u32,
    height: u32,
    rate: f64,
    capacity: usize,
    ring: VecDeque<RingSample>,
    filters: Vec<[f32; 3]>,
    scale: Vec<f32>,
    coverage: Vec<u32>,
    accum: Vec<[f32; 6]>,
    /// Splats of the last refresh: per chunk of the ring (in ring order), per band.
    binned: Vec<Vec<Vec<Splat>>>,
    image: Image,
    mean_age: f64,
    holes: usize,
}

impl Reconstructor {
    /// A reconstructor for a `width × height` display fed by a sampler spending `rate`
    /// samples per second (the `R` of the local rate `R_l`).
    pub fn new(width: u32, height: u32, rate: f64, params: ReconParams) -> Self {
        let n = (width * height) as usize;
        let capacity = ((params.ring_factor * n as f64).round() as usize).max(1);
        Self {
            params,
            width,
            height,
            rate,
            capacity,
            ring: VecDeque::with_capacity(capacity.min(1 << 24)),
            filters: vec![[1.0, 1.0, 1.0]; n],
            scale: vec![params.scale_bounds.0.max(1e-3); n],
            coverage: vec![0; n],
            accum: vec![[0.0; 6]; n],
            binned: Vec::new(),
            image: Image::new(width, height),
            mean_age: 0.0,
            holes: n,
        }
    }

    /// The parameters.
    pub fn params(&self) -> &ReconParams {
        &self.params
    }

    /// Ring capacity `N`.
    pub fn capacity(&self) -> usize {
        self.capacity
    }

    /// Samples in the ring, oldest first.
    pub fn ring(&self) -> &VecDeque<RingSample> {
        &self.ring
    }

    /// Append a sample (the oldest is dropped once the ring is full). Samples must come
    /// in the order they were traced.
    pub fn push(&mut self, s: RingSample) {
        if self.ring.len() == self.capacity {
            self.ring.pop_front();
        }
        self.ring.push_back(s);
    }

    /// Append the sampler's stream.
    pub fn push_stream(&mut self, stream: &[StreamSample]) {
        for s in stream {
            self.push(RingSample::from(s));
        }
    }

    /// The last reconstructed image.
    pub fn image(&self) -> &Image {
        &self.image
    }

    /// Pixel mean of the weight-averaged sample age at the last refresh, seconds
    /// (holes take the age of the block they were filled from).
    pub fn mean_age(&self) -> f64 {
        self.mean_age
    }

    /// Pixels no sample reached at the last refresh (filled from the pyramid).
    pub fn holes(&self) -> usize {
        self.holes
    }

    /// Samples that reached each pixel at the last refresh.
    pub fn coverage(&self) -> &[u32] {
        &self.coverage
    }

    /// Per-pixel splat scale used by the next refresh.
    pub fn splat_scale(&self) -> &[f32] {
        &self.scale
    }

    /// The filter extents each pixel had at the last refresh (`[e_x, e_y, e_t]`).
    pub fn filter_map(&self) -> &[[f32; 3]] {
        &self.filters
    }

    /// Rebuild the per-pixel filter map from the sampler's tiling.
    fn update_filters(&mut self, tiling: &Tiling) {
        let w = self.width as usize;
        if let Some(e) = self.params.fixed_filter {
            let f = [e.ex as f32, e.ey as f32, e.et as f32];
            self.filters.iter_mut().for_each(|p| *p = f);
            return;
        }
        let tiles = tiling.len();
        for &l in tiling.leaves() {
            let n = tiling.node(l);
            let r = n.rect;
            let rl = filter::local_rate(self.rate, tiles, r.area());
            let (gx, gy, gt) = n.stats.gradients();
            let e = filter::extents(1.0 / rl, gx, gy, gt, &self.params.bounds);
            let f = [e.ex as f32, e.ey as f32, e.et as f32];
            let x1 = (r.x1 as usize).min(w);
            for y in r.y0 as usize..(r.y1 as usize).min(self.height as usize) {
                self.filters[y * w + r.x0 as usize..y * w + x1].fill(f);
            }
        }
    }

    /// Reconstruct the image at display time `t` seen by `camera`, with filters from
    /// `tiling` (the sampler's current tiling).
    pub fn reconstruct(&mut self, t: f64, camera: &CameraFrame, tiling: &Tiling) -> &Image {
        self.update_filters(tiling);
        self.prepare_splats(t, camera);
        self.splat();
        self.resolve();
        self.adapt_scale();
        &self.image
    }

    fn prepare_splats(&mut self, t: f64, camera: &CameraFrame) {
        let (w, h) = (self.width as i32, self.height as i32);
        let p = self.params;
        let filters = &self.filters;
        let scale = &self.scale;
        let max_r = p.max_radius.min((MAX_SPAN as f32 - 1.0) * 0.5);
        let make = |s: &RingSample| -> Option<Splat> {
            let age = (t - s.t).max(0.0);
            let (x, y) = if p.reproject {
                let world = s.hit_point + s.velocity * (t - s.t) as f32;
                let (x, y, _) = camera.project(world)?;
                (x, y)
            } else {
                (s.x, s.y)
            };
            if !(x.is_finite() && y.is_finite()) {
                return None;
            }
            // Filter and scale of the pixel the sample lands in (clamped to the image,
            // so a sample just outside still lights the border within its footprint).
            let px = (x.floor() as i64).clamp(0, w as i64 - 1) as usize;
            let py = (y.floor() as i64).clamp(0, h as i64 - 1) as usize;
            let i = py * w as usize + px;
            let [ex, ey, et] = filters[i];
            let a = age as f32 / et;
            if a > p.temporal_cutoff {
                return None;
            }
            let sc = scale[i];
            let rx = (p.spatial_cutoff * ex * sc).min(max_r);
            let ry = (p.spatial_cutoff * ey * sc).min(max_r);
            // Pixel k's center is k + 0.5.
            let x0 = ((x - 0.5 - rx).ceil() as i32).max(0);
            let x1 = ((x - 0.5 + rx).floor() as i32).min(w - 1);
            let y0 = ((y - 0.5 - ry).ceil() as i32).max(0);
            let y1 = ((y - 0.5 + ry).floor() as i32).min(h - 1);
            if x0 > x1 || y0 > y1 {
                return None;
            }
            Some(Splat {
                x,
                y,
                wt: fast_exp_neg(-0.5 * a * a),
                ax: 0.5 / (ex * ex),
                ay: 0.5 / (ey * ey),
                age: age as f32,
                color: s.color.to_array(),
                x0: x0 as u16,
                x1: x1 as u16,
                y0: y0 as u16,
                y1: y1 as u16,
            })
        };
        let bands = (h as usize).div_ceil(BAND_ROWS);
        let chunk = PREP_CHUNK.max(self.ring.len().div_ceil(64));
        let (a, b) = self.ring.as_slices();
        self.binned = a
            .par_chunks(chunk)
            .chain(b.par_chunks(chunk))
            .map(|c| {
                let cap = c.len() * 3 / (2 * bands) + 16;
                let mut out: Vec<Vec<Splat>> =
                    (0..bands).map(|_| Vec::with_capacity(cap)).collect();
                for s in c.iter().filter_map(make) {
                    let (b0, b1) = (s.y0 as usize / BAND_ROWS, s.y1 as usize / BAND_ROWS);
                    for o in &mut out[b0..=b1] {
                        o.push(s);
                    }
                }
                out
            })
            .collect();
    }

    fn splat(&mut self) {
        let w = self.width as usize;
        let binned = &self.binned;
        self.accum
            .par_chunks_mut(BAND_ROWS * w)
            .enumerate()
            .for_each(|(b, acc)| {
                acc.fill([0.0; 6]);
                let band_y0 = b * BAND_ROWS;
                let band_y1 = band_y0 + acc.len() / w; // exclusive
                let mut gx = [0f32; MAX_SPAN];
                for s in binned.iter().flat_map(|c| c[b].iter()) {
                    let (x0, x1) = (s.x0 as usize, s.x1 as usize);
                    let n = x1 - x0 + 1;
                    let gx = &mut gx[..n];
                    let mut dx = x0 as f32 + 0.5 - s.x;
                    for g in gx.iter_mut() {
                        *g = fast_exp_neg(-s.ax * dx * dx);
                        dx += 1.0;
                    }
                    let y0 = (s.y0 as usize).max(band_y0);
                    let y1 = (s.y1 as usize + 1).min(band_y1);
                    let [r, g, bl] = s.color;
                    for y in y0..y1 {
                        let dy = y as f32 + 0.5 - s.y;
                        let gy = s.wt * fast_exp_neg(-s.ay * dy * dy);
                        let c = [gy * r, gy * g, gy * bl, gy, gy * s.age];
                        let row = (y - band_y0) * w + x0;
                        for (p, &gxi) in acc[row..row + n].iter_mut().zip(gx.iter()) {
                            p[0] += gxi * c[0];
                            p[1] += gxi * c[1];
                            p[2] += gxi * c[2];
                            p[3] += gxi * c[3];
                            p[4] += gxi * c[4];
                            p[5] += 1.0;
                        }
                    }
                }
            });
        for (c, a) in self.coverage.iter_mut().zip(&self.accum) {
            *c = a[5] as u32;
        }
    }

    /// Quotients, hole filling, mean age.
    fn resolve(&mut self) {
        let (w, h) = (self.width as usize, self.height as usize);
        let mut holes = 0usize;
        let mut age_sum = 0f64;
        for (px, a) in self.image.pixels.iter_mut().zip(&self.accum) {
            if a[3] >= MIN_WEIGHT {
                *px = Vec3::new(a[0] / a[3], a[1] / a[3], a[2] / a[3]);
                age_sum += (a[4] / a[3]) as f64;
            } else {
                holes += 1;
            }
        }
        self.holes = holes;
        if holes > 0 {
            // Pull pyramid of the sums (f64), level k has blocks of 2^k × 2^k pixels.
            let mut levels: Vec<(usize, usize, Vec<[f64; 5]>)> = Vec::new();
            let base: Vec<[f64; 5]> = self
                .accum
                .iter()
                .map(|a| {
                    if a[3] >= MIN_WEIGHT {
                        [a[0], a[1], a[2], a[3], a[4]].map(|v| v as f64)
                    } else {
                        [0.0; 5]
                    }
                })
                .collect();
            levels.push((w, h, base));
            while {
                let (lw, lh, _) = levels.last().unwrap();
                *lw > 1 || *lh > 1
            } {
                let (lw, lh, prev) = levels.last().unwrap();
                let (nw, nh) = (lw.div_ceil(2), lh.div_ceil(2));
                let mut next = vec![[0f64; 5]; nw * nh];
                for y in 0..*lh {
                    for x in 0..*lw {
                        let d = &mut next[(y / 2) * nw + x / 2];
                        let s = &prev[y * lw + x];
                        for c in 0..5 {
                            d[c] += s[c];
                        }
                    }
                }
                levels.push((nw, nh, next));
            }
            for y in 0..h {
                for x in 0..w {
                    let i = y * w + x;
                    if self.accum[i][3] >= MIN_WEIGHT {
                        continue;
                    }
                    let mut out = (Vec3::ZERO, 0.0);
                    for (k, (lw, _, l)) in levels.iter().enumerate().skip(1) {
                        let s = &l[(y >> k) * lw + (x >> k)];
                        if s[3] > 0.0 {
                            let inv = 1.0 / s[3];
                            out = (
                                Vec3::new(
                                    (s[0] * inv) as f32,
                                    (s[1] * inv) as f32,
                                    (s[2] * inv) as f32,
                                ),
                                s[4] * inv,
                            );
                            break;
                        }
                    }
                    self.image.pixels[i] = out.0;
                    age_sum += out.1;
                }
            }
        }
        self.mean_age = age_sum / (w * h).max(1) as f64;
    }

    fn adapt_scale(&mut self) {
        let p = self.params;
        for (s, &c) in self.scale.iter_mut().zip(&self.coverage) {
            if c < p.undersampled {
                *s *= p.grow;
            } else if c > p.oversampled {
                *s *= p.shrink;
            }
            *s = s.clamp(p.scale_bounds.0, p.scale_bounds.1);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Camera;

    fn cam(w: u32, h: u32) -> CameraFrame {
        Camera {
            eye: Vec3::new(0.0, 0.0, 1.0),
            at: Vec3::ZERO,
            up: Vec3::Y,
            fov_y_deg: 90.0,
            hither: 1e-3,
        }
        .frame(w, h)
    }

    #[test]
    fn single_sample_fills_the_image_with_its_color() {
        let (w, h) = (16, 16);
        let c = cam(w, h);
        let mut r = Reconstructor::new(w, h, 1000.0, ReconParams::paper());
        let p = c.eye + c.direction(3.2, 5.7) * 2.0;
        r.push(RingSample {
            x: 3.2,
            y: 5.7,
            t: 0.0,
            color: Vec3::new(0.25, 0.5, 0.75),
            hit_point: p,
            velocity: Vec3::ZERO,
        });
        let img = r.reconstruct(0.01, &c, &Tiling::new(w, h)).clone();
        for px in &img.pixels {
            assert!((*px - Vec3::new(0.25, 0.5, 0.75)).abs().max_element() < 1e-6);
        }
        assert!(r.holes() > 0);
        // Splats grew where undersampled.
        assert!(r.splat_scale().iter().all(|&s| s > 1.0));
    }

    #[test]
    fn fast_exp_is_accurate() {
        for k in 0..20000 {
            let x = -(k as f32) * 0.004;
            let (a, b) = (fast_exp_neg(x), x.exp());
            assert!((a - b).abs() <= 1e-5 * b + 1e-30, "{x} {a} {b}");
        }
    }

    #[test]
    fn ring_keeps_the_newest() {
        let mut r = Reconstructor::new(
            2,
            2,
            1.0,
            ReconParams {
                ring_factor: 1.0,
                ..ReconParams::paper()
            },
        );
        for k in 0..10 {
            r.push(RingSample {
                x: 0.0,
                y: 0.0,
                t: k as f64,
                color: Vec3::ZERO,
                hit_point: Vec3::ZERO,
                velocity: Vec3::ZERO,
            });
        }
        assert_eq!(r.ring().len(), 4);
        assert_eq!(r.ring().front().unwrap().t, 6.0);
    }
}
