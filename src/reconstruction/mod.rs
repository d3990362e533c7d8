//! The adaptive space-time reconstructor (paper §5, §6.2; SPEC §4).
//!
//! The reconstructor keeps its own deep buffer: a ring of the `N` most recent samples
//! the sampler traced, in the order they were pushed. At each display refresh (time
//! `t`) it
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
//!    the pixels whose centers lie within `spatial_cutoff · scale` sigmas along x and
//!    along y (a box, at most `max_radius` pixels from the sample) — the splat scale
//!    widens the footprint (the paper's point size), not the kernel, so a wide splat
//!    only matters where no nearer sample outweighs it; samples older than
//!    `temporal_cutoff · e_t` are skipped;
//! 4. divides accumulated weighted color by accumulated weight; pixels no sample
//!    reached (accumulated weight below `MIN_WEIGHT` = 1e-24: holes) are filled from
//!    the coarsest-necessary level of a 2×2 pull pyramid of the same sums (a wider box
//!    pass: the weighted mean of the nearest block that has samples), so a hole never
//!    shows black unless nothing at all was sampled yet;
//! 5. updates the splat scale map from the coverage (samples whose footprint covers
//!    each pixel): fewer than `undersampled` → ×`grow`, more than `oversampled` →
//!    ×`shrink`, clamped to `scale_bounds`.
//!
//! How a refresh stays cheap (the same images as evaluating the above directly, up to
//! f32 rounding: `tests::fast_path_matches_direct_evaluation`):
//!
//! - **Stale cut.** Samples older than `temporal_cutoff ·` (largest `e_t` of any tile)
//!   fail step 3 wherever they land, so they are skipped before reprojection: `push`
//!   keeps the running largest time at the end of every block of 256 pushes
//!   (non-decreasing whatever order samples come in), and a binary search finds the
//!   blocks that are stale as a whole. With the camera moving (BART kitchen) this skips
//!   about 70% of the ring.
//! - **Filters per tile.** Each refresh computes one filter per tile (with the
//!   constants a splat needs) and a per-pixel `(tile, scale)` lookup of 8 bytes, so a
//!   sample finds both in one load from a table that fits a core's L2 cache (256×256).
//!   [`Reconstructor::filter_map`] is built from the table on request.
//! - **A struct-of-arrays ring, placed in blocks.** The ring ([`ring::Ring`]) keeps
//!   one array per field. Samples go through each stage a block of 64 at a time:
//!   reprojection in vector code over the hit point, velocity and time arrays; the
//!   pixel lookups, independent loads in flight together; the temporal cull,
//!   footprint and temporal weight of every lane in vector code (float bounds turned
//!   into integers without saturating conversions); then a list of survivors, and
//!   only they read their color and are binned. No branch depends on a sample until
//!   the survivors' loop.
//! - **Vector splats.** Accumulators are cells of 8 aligned pixels × 5 channels (weighted
//!   r, g, b, weight, weighted age), one 256-bit vector per channel. A splat computes
//!   the Gaussian column weights of the cells it touches (8 lanes at a time, zero
//!   outside its footprint, branch-free fast exp), multiplies them by its colour once,
//!   and adds `(g_x·c)·g_y` to each row with one fused multiply-add per channel and
//!   cell. Coverage comes from corner differences, four per splat and band.
//! - **No allocation per refresh**: bins, accumulators and the pull pyramid are
//!   reused; a few holes read memoised block sums around them instead of a whole
//!   pyramid (the same sums added in the same order, so the same image).
//!
//! Splatting runs in parallel over horizontal bands of rows (16 rows with several
//! threads, 64 on one); each band visits the samples touching it in ring order and
//! writes only its own pixels, and every weight is computed from offsets to the
//! splat's own first row and column, so every pixel's sums are formed from the same
//! terms in the same order whatever the thread count (bit-identical images).

pub mod filter;
pub mod ring;

use std::{collections::HashMap, sync::OnceLock};

use glam::Vec3;
use rayon::prelude::*;

use crate::{image::Image, scene::CameraFrame, tiles::TilingSnapshot, trace::StreamSample};
pub use filter::{Extents, FilterBounds};
use ring::field;
pub use ring::Ring;

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
    /// Samples older than this many temporal sigmas get no weight. Default 2.5, the
    /// spatial cutoff: the kernel's support is cut at the same
    /// number of sigmas in space and time, so a dropped sample weighs at most
    /// e^(−3.125) ≈ 4.4% of a fresh one at the same place. (3 sigmas changed the
    /// Table 1 RMS by at most 0.1 of 255 and cost 12% more per refresh: README.)
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
            temporal_cutoff: 2.5,
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

/// `e^x` for `x ≤ 0` (relative error below 1e-5, growing with |x| from rounding `x·log2 e`
/// in f32; 0 below −87): `2^(x·log2 e)` split into an exponent and a degree-6 polynomial
/// of the fraction. Deterministic and much cheaper than `f32::exp` in the splat loop.
///
/// Branch-free and without float→int conversion (the integer part is rounded by adding
/// 1.5·2²³, which leaves it in the low mantissa bits), so that loops over lanes of it
/// compile to vector instructions.
#[inline(always)]
pub fn fast_exp_neg(x: f32) -> f32 {
    const MAGIC: f32 = 12_582_912.0; // 1.5 · 2^23
    let v = x.max(-87.0) * std::f32::consts::LOG2_E;
    let r = v + MAGIC;
    let fi = r - MAGIC; // v rounded to the nearest integer, |fi| ≤ 126
    let f = v - fi; // [−½, ½]
                    // 2^f on [−½, ½]: Taylor coefficients ln2^k/k! (truncation error < 1e-8), Horner
                    // steps fused.
    let p = 0.000_154_035_3f32
        .mul_add(f, 0.001_333_355_8)
        .mul_add(f, 0.009_618_129)
        .mul_add(f, 0.055_504_11)
        .mul_add(f, 0.240_226_5)
        .mul_add(f, std::f32::consts::LN_2)
        .mul_add(f, 1.0);
    // fi + 127 ∈ [1, 127]: a normal power of two.
    let bits = r
        .to_bits()
        .wrapping_sub(MAGIC.to_bits())
        .wrapping_add(127)
        .wrapping_shl(23);
    let e = p * f32::from_bits(bits);
    if x < -87.0 {
        0.0
    } else {
        e
    }
}

/// The integer value of `v`, which must be an integer of magnitude below 2²²: `v` plus
/// 1.5·2²³ holds it in the low mantissa bits. Unlike `as`, which saturates and maps
/// NaN to 0, this compiles to two vector instructions per 8 lanes (and gives some
/// value, not undefined behaviour, for other `v`).
#[inline(always)]
fn small_int(v: f32) -> i32 {
    const MAGIC: f32 = 12_582_912.0; // 1.5 · 2^23
    (v + MAGIC).to_bits().wrapping_sub(MAGIC.to_bits()) as i32
}

/// Lanes of the vectorised splat loops (one 256-bit register of f32).
const LANES: usize = 8;
type Lanes = [f32; LANES];
/// `1, 2, …, LANES`: lane `l`'s index plus one. Lane indices are added as `(o − 1) +
/// (l + 1)` (exact for small integers): with a `0` in the table, the compiler drops
/// that lane's addition and assembles the vector lane by lane.
const LANE_INDEX_1: Lanes = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0];

/// Accumulated weight below which a pixel counts as a hole: far splat tails reach
/// f32's denormal range, where `Σw·c / Σw` loses all precision.
const MIN_WEIGHT: f32 = 1e-24;
/// Samples per task of the parallel splat preparation (with more than one thread).
const PREP_CHUNK: usize = 16384;
/// Rows per band of the splat with several threads (tasks for the thread pool), and
/// per task of the resolve pass (whose fixed bands make its sums thread-independent).
/// Band heights are powers of two.
const BAND_ROWS: usize = 16;
/// Rows per band of the splat on one thread.
const SINGLE_THREAD_BAND_ROWS: usize = 64;
/// Widest footprint in pixels along x (`2·max_radius + 1` is clamped to it).
const MAX_SPAN: usize = 128;
/// Accumulated channels: weighted red, green, blue, weight, weighted age.
const CHANNELS: usize = 5;
/// Accumulators of `LANES` adjacent pixels (aligned), one vector per channel.
type Cell = [Lanes; CHANNELS];
/// Relative margin of the stale-prefix cut over the per-sample temporal cutoff, far
/// above f32 rounding of `age / e_t`, so the cut never drops a sample that the
/// per-sample test would keep.
const STALE_MARGIN: f64 = 1e-3;

/// A tile's filter at one refresh, with the per-sample constants derived from it.
#[derive(Clone, Copy, Debug)]
struct TileFilter {
    /// `[e_x, e_y, e_t]`.
    e: [f32; 3],
    inv_et: f32,
    /// `½/e_x²`, `½/e_y²`.
    ax: f32,
    ay: f32,
    /// Footprint radii at splat scale 1: `spatial_cutoff · e_x`, `· e_y`.
    cx: f32,
    cy: f32,
}

impl TileFilter {
    fn new(e: [f32; 3], spatial_cutoff: f32) -> Self {
        Self {
            e,
            inv_et: 1.0 / e[2],
            ax: 0.5 / (e[0] * e[0]),
            ay: 0.5 / (e[1] * e[1]),
            cx: spatial_cutoff * e[0],
            cy: spatial_cutoff * e[1],
        }
    }
}

/// A sample prepared for splatting at one refresh.
#[derive(Clone, Copy, Debug)]
struct Splat {
    x: f32,
    y: f32,
    /// `½/σx²`, `½/σy²`.
    ax: f32,
    ay: f32,
    /// Temporal weight × (red, green, blue, 1, age).
    c: [f32; CHANNELS],
    /// Inclusive pixel bounding box of the footprint (clipped to the image).
    x0: u16,
    x1: u16,
    y0: u16,
    y1: u16,
}

/// `camera.project` with the per-view constants hoisted: `x = (d·u)/z − corner·u` with
/// `u = du/|du|²` (the same map, rounded differently).
#[derive(Clone, Copy, Debug)]
struct Projector {
    eye: Vec3,
    forward: Vec3,
    u: Vec3,
    v: Vec3,
    ou: f32,
    ov: f32,
}

impl Projector {
    fn new(c: &CameraFrame) -> Self {
        let u = c.du / c.du.length_squared();
        let v = c.dv / c.dv.length_squared();
        Self {
            eye: c.eye,
            forward: c.forward,
            u,
            v,
            ou: c.corner.dot(u),
            ov: c.corner.dot(v),
        }
    }

    /// Pixel coordinates, and whether the point is in front of the eye (only then are
    /// the coordinates meaningful).
    #[inline(always)]
    fn project(&self, p: Vec3) -> (f32, f32, bool) {
        let d = p - self.eye;
        let z = d.dot(self.forward);
        let iz = 1.0 / z;
        (
            d.dot(self.u) * iz - self.ou,
            d.dot(self.v) * iz - self.ov,
            z > 1e-6,
        )
    }
}

/// A sample placed at one refresh by the tests' direct evaluation: where it lands, its
/// filter, temporal weight argument and footprint ([`bin_piece`] computes the same
/// lane-wise).
#[cfg(test)]
#[derive(Clone, Copy, Debug)]
struct Placed {
    x: f32,
    y: f32,
    age: f32,
    /// `age / e_t` (at most `temporal_cutoff`).
    a: f32,
    filter: TileFilter,
    x0: i32,
    x1: i32,
    y0: i32,
    y1: i32,
}

/// What a sample needs of the pixel it lands in. Eight bytes, so that the table of a
/// 256×256 image stays in a core's L2 cache: samples land in scattered pixels.
#[derive(Clone, Copy, Debug)]
struct Lookup {
    /// Index of the pixel's tile in the filter table.
    tile: u32,
    /// The pixel's splat scale.
    scale: f32,
}

/// Where a sample lands at one refresh, before its filter is known.
#[derive(Clone, Copy, Debug, Default)]
struct Located {
    x: f32,
    y: f32,
    age: f32,
    /// The pixel it lands in, clamped to the image.
    pixel: u32,
    /// In front of the eye, at finite coordinates.
    ok: bool,
}

/// Samples located before their pixels are looked up in [`bin_piece`]: the lookups
/// of a whole block are then independent loads in flight together, instead of each
/// waiting behind the unpredictable cull branch of the previous sample.
const LOCATE_BLOCK: usize = 64;

/// What placing a sample needs at one refresh.
struct Placer<'a> {
    t: f64,
    proj: Option<Projector>,
    width: i32,
    height: i32,
    lookup: &'a [Lookup],
    tiles: &'a [TileFilter],
    temporal_cutoff: f32,
    /// Footprint radius bound.
    max_r: f32,
}

impl Placer<'_> {
    /// Where a sample at `(x, y)` (in front of the eye if `front`), traced `dt`
    /// seconds ago, lands (without branches on the data, see [`LOCATE_BLOCK`]).
    #[inline(always)]
    fn located(&self, x: f32, y: f32, front: bool, dt: f64) -> Located {
        // The filter and scale are those of the pixel the sample lands in, clamped to
        // the image, so a sample just outside still lights the border within its
        // footprint (a NaN coordinate clamps too; `ok` discards it).
        let (w, h) = (self.width, self.height);
        // Clamped as floats (`max` first, so NaN becomes 0), then floored: integers
        // within the image, which `small_int` converts exactly in vector code.
        let px = small_int(x.max(0.0).min((w - 1) as f32).floor()) as u32;
        let py = small_int(y.max(0.0).min((h - 1) as f32).floor()) as u32;
        Located {
            x,
            y,
            age: dt.max(0.0) as f32,
            pixel: py * w as u32 + px,
            ok: front & x.is_finite() & y.is_finite(),
        }
    }

    /// Reproject `s`: where it lands and in which pixel.
    #[cfg(test)]
    fn locate(&self, s: &RingSample) -> Located {
        let dt = self.t - s.t;
        let (x, y, front) = match &self.proj {
            Some(p) => p.project(s.hit_point + s.velocity * dt as f32),
            None => (s.x, s.y, true),
        };
        self.located(x, y, front, dt)
    }

    /// [`Placer::located`] for the samples at physical indices `p0..p0 + n` of
    /// `ring` (the same arithmetic in the same order as `Placer::locate`), one array
    /// per field so that it compiles to vector code. A sample that is not `ok` gets a
    /// NaN age, which fails the temporal cull just as `ok == false` does.
    #[inline(always)]
    fn locate_block(&self, ring: &Ring, p0: usize, n: usize, b: &mut Block) {
        use field::*;
        let ts = &ring.t[p0..p0 + n];
        let f = |k: usize| &ring.f[k][p0..p0 + n];
        let mut put = |i: usize, l: Located| {
            b.x[i] = l.x;
            b.y[i] = l.y;
            b.age[i] = if l.ok { l.age } else { f32::NAN };
            b.pixel[i] = l.pixel;
        };
        match &self.proj {
            Some(p) => {
                let (hx, hy, hz, vx, vy, vz) = (f(HX), f(HY), f(HZ), f(VX), f(VY), f(VZ));
                for i in 0..n {
                    let dt = self.t - ts[i];
                    let hit = Vec3::new(hx[i], hy[i], hz[i]);
                    let vel = Vec3::new(vx[i], vy[i], vz[i]);
                    let (x, y, front) = p.project(hit + vel * dt as f32);
                    put(i, self.located(x, y, front, dt));
                }
            }
            None => {
                let (sx, sy) = (f(X), f(Y));
                for i in 0..n {
                    put(i, self.located(sx[i], sy[i], true, self.t - ts[i]));
                }
            }
        }
    }

    /// Place one sample.
    #[cfg(test)]
    fn place(&self, s: &RingSample) -> Option<Placed> {
        let l = self.locate(s);
        self.finish(&l, self.lookup[l.pixel as usize])
    }

    /// The filter, temporal cull and footprint of a located sample.
    #[cfg(test)]
    fn finish(&self, l: &Located, look: Lookup) -> Option<Placed> {
        let f = self.tiles[look.tile as usize];
        let a = l.age * f.inv_et;
        if !(l.ok && a <= self.temporal_cutoff) {
            return None;
        }
        let (rx, ry) = self.radii(&f, look.scale);
        self.footprint(l.x, l.y, l.age, a, f, rx, ry)
    }

    /// Footprint radii of a sample landing in a pixel of tile filter `f` and splat scale
    /// `scale`.
    #[inline(always)]
    fn radii(&self, f: &TileFilter, scale: f32) -> (f32, f32) {
        // Not `f32::min`, whose NaN handling costs three instructions: neither side
        // is NaN.
        let min = |a: f32, b: f32| if a < b { a } else { b };
        (min(f.cx * scale, self.max_r), min(f.cy * scale, self.max_r))
    }

    /// Inclusive pixel bounds `[x0, x1, y0, y1]` of a footprint of radii `rx`, `ry`
    /// around `(x, y)`, clamped to the image as floats (pixel k's center is k + 0.5).
    /// For finite inputs these are integers, within the image when the footprint is not
    /// empty (`x0 <= x1 && y0 <= y1`), where the conversions to integers are exact.
    #[inline(always)]
    fn bounds(&self, x: f32, y: f32, rx: f32, ry: f32) -> [f32; 4] {
        let (w, h) = ((self.width - 1) as f32, (self.height - 1) as f32);
        [
            (x - 0.5 - rx).ceil().max(0.0),
            (x - 0.5 + rx).floor().min(w),
            (y - 0.5 - ry).ceil().max(0.0),
            (y - 0.5 + ry).floor().min(h),
        ]
    }

    /// The footprint of a sample landing at `(x, y)` that passed the temporal cull.
    #[cfg(test)]
    #[allow(clippy::too_many_arguments)]
    fn footprint(
        &self,
        x: f32,
        y: f32,
        age: f32,
        a: f32,
        f: TileFilter,
        rx: f32,
        ry: f32,
    ) -> Option<Placed> {
        let [x0, x1, y0, y1] = self.bounds(x, y, rx, ry);
        if !(x0 <= x1 && y0 <= y1) {
            return None;
        }
        Some(Placed {
            x,
            y,
            age,
            a,
            filter: f,
            x0: x0 as i32,
            x1: x1 as i32,
            y0: y0 as i32,
            y1: y1 as i32,
        })
    }
}

/// One block of samples in [`bin_piece`], one array per field.
struct Block {
    x: [f32; LOCATE_BLOCK],
    y: [f32; LOCATE_BLOCK],
    /// NaN where the sample is not `ok` (see [`Located`]).
    age: [f32; LOCATE_BLOCK],
    pixel: [u32; LOCATE_BLOCK],
    /// The landing pixel's [`Lookup`], one array per field.
    tile: [u32; LOCATE_BLOCK],
    inv_et: [f32; LOCATE_BLOCK],
    rx: [f32; LOCATE_BLOCK],
    ry: [f32; LOCATE_BLOCK],
    /// Temporal weight `exp(−½ (age / e_t)²)`.
    wt: [f32; LOCATE_BLOCK],
    /// Red, green and blue times the temporal weight.
    wc: [[f32; LOCATE_BLOCK]; 3],
    /// Footprint (inclusive pixel bounds; meaningful for kept samples only).
    x0: [i32; LOCATE_BLOCK],
    x1: [i32; LOCATE_BLOCK],
    y0: [i32; LOCATE_BLOCK],
    y1: [i32; LOCATE_BLOCK],
    /// 1 where the sample passes the temporal cull and reaches a pixel.
    keep: [u32; LOCATE_BLOCK],
    /// Indices of those samples.
    kept: [u8; LOCATE_BLOCK],
}

impl Block {
    fn new() -> Box<Self> {
        Box::new(Self {
            x: [0.0; LOCATE_BLOCK],
            y: [0.0; LOCATE_BLOCK],
            age: [0.0; LOCATE_BLOCK],
            pixel: [0; LOCATE_BLOCK],
            tile: [0; LOCATE_BLOCK],
            inv_et: [0.0; LOCATE_BLOCK],
            rx: [0.0; LOCATE_BLOCK],
            ry: [0.0; LOCATE_BLOCK],
            wt: [0.0; LOCATE_BLOCK],
            wc: [[0.0; LOCATE_BLOCK]; 3],
            x0: [0; LOCATE_BLOCK],
            x1: [0; LOCATE_BLOCK],
            y0: [0; LOCATE_BLOCK],
            y1: [0; LOCATE_BLOCK],
            keep: [0; LOCATE_BLOCK],
            kept: [0; LOCATE_BLOCK],
        })
    }
}

/// Gaussian weights `exp(−a·(b + k)²)` of the lanes `k = o + l`. One loop over
/// independent lanes, which compiles to vector code.
#[inline(always)]
fn gauss_lanes(a: f32, b: f32, o: f32) -> Lanes {
    let mut out = [0f32; LANES];
    let o1 = o - 1.0;
    for l in 0..LANES {
        let d = b + (o1 + LANE_INDEX_1[l]);
        out[l] = fast_exp_neg(-a * d * d);
    }
    out
}

/// `PREFIX[n][l]` is 1 for lanes `l < n`, else 0: masks lanes outside a footprint by a
/// multiplication (the weights are finite), which stays vector code where a comparison
/// of small integers became per-lane scalar code.
const PREFIX: [Lanes; LANES + 1] = {
    let mut t = [[0f32; LANES]; LANES + 1];
    let mut n = 0;
    while n <= LANES {
        let mut l = 0;
        while l < n {
            t[n][l] = 1.0;
            l += 1;
        }
        n += 1;
    }
    t
};

/// Add one splat to the rows `by0..by1` of a band's accumulators (`gpr` cells per row)
/// and count it in the band's coverage corner differences `cov` (rows of `cstride`).
///
/// Columns go in the aligned groups of `LANES` that the footprint touches; lanes
/// outside it carry weight 0 (adding `+0` leaves every sum as it is), so each group is
/// one vector operation per channel on one [`Cell`]. Each pixel gets
/// `(g_x·c)·g_y` added with one rounding, its weights taken from offsets to the
/// footprint's first group and first row, so the sum is the same whichever band
/// computes it.
#[inline(always)]
fn splat_one(
    s: &Splat,
    by0: usize,
    by1: usize,
    gpr: usize,
    acc: &mut [Cell],
    cstride: usize,
    cov: &mut [i32],
) {
    let (x0, x1) = (s.x0 as usize, s.x1 as usize);
    let g0 = x0 / LANES;
    let groups = x1 / LANES - g0 + 1;
    let y0 = (s.y0 as usize).max(by0);
    let y1 = (s.y1 as usize + 1).min(by1);
    // The rows of this band, `gpr` cells each, from the footprint's first.
    let rows = &mut acc[(y0 - by0) * gpr..(y1 - by0) * gpr];
    let cols = Cols {
        s,
        g0,
        by: s.y0 as f32 + 0.5 - s.y,
        // Small integers become floats through `u32`: from `usize` (`u64`) the
        // conversion costs a branch and several instructions on x86-64.
        o0: (y0 - s.y0 as usize) as u32 as f32,
        bx: (g0 * LANES) as u32 as f32 + 0.5 - s.x,
        // The footprint's first column within the first group, and its last within
        // the last group.
        lo: x0 % LANES,
        hi: x1 % LANES,
        groups,
    };
    match groups {
        1 => cols.add::<1>(rows, y1 - y0, gpr),
        2 => cols.add::<2>(rows, y1 - y0, gpr),
        3 => cols.add::<3>(rows, y1 - y0, gpr),
        4 => cols.add::<4>(rows, y1 - y0, gpr),
        _ => cols.add_any(groups, rows, y1 - y0, gpr),
    }
    // Coverage corners within the band (made per-row differences in `splat_band`).
    let r0 = (y0 - by0) * cstride;
    cov[r0 + x0] += 1;
    cov[r0 + x1 + 1] -= 1;
    if y1 < by1 {
        let r1 = (y1 - by0) * cstride;
        cov[r1 + x0] -= 1;
        cov[r1 + x1 + 1] += 1;
    }
}

/// The columns and rows of one splat within one band.
struct Cols<'a> {
    s: &'a Splat,
    /// First group of `LANES` columns.
    g0: usize,
    /// `y` offset of the footprint's first row's center from the splat.
    by: f32,
    /// The band's first row of the footprint, relative to the footprint's first row.
    o0: f32,
    /// `x` offset of the first group's first pixel center from the splat.
    bx: f32,
    /// The footprint's first column within the first group, last within the last.
    lo: usize,
    hi: usize,
    /// Groups of `LANES` columns it touches.
    groups: usize,
}

impl Cols<'_> {
    /// `g_x · c` of group `j` (lane weights zero outside the footprint).
    #[inline(always)]
    fn weighted(&self, j: usize) -> Cell {
        let g = gauss_lanes(self.s.ax, self.bx, (j * LANES) as u32 as f32);
        // Lanes before the first column (first group) and after the last (last group).
        let first = if j == 0 { self.lo } else { 0 };
        let last = if j + 1 == self.groups {
            self.hi
        } else {
            LANES - 1
        };
        let (skip, keep) = (&PREFIX[first], &PREFIX[last + 1]);
        let mut out = [[0f32; LANES]; CHANNELS];
        for (o, &c) in out.iter_mut().zip(&self.s.c) {
            for l in 0..LANES {
                o[l] = g[l] * ((keep[l] - skip[l]) * c);
            }
        }
        out
    }

    /// Row weights `g_y` of the `k`-th run of `LANES` rows of the band's part of the
    /// footprint, from offsets to the footprint's first row.
    #[inline(always)]
    fn row_weights(&self, k: usize) -> Lanes {
        let o = self.o0 + (k * LANES) as u32 as f32;
        gauss_lanes(self.s.ay, self.by, o)
    }

    /// Footprints of `G` groups, `nrows` rows of `gpr` cells: the products `g_x·c`
    /// stay in registers over the rows.
    #[inline(always)]
    fn add<const G: usize>(&self, rows: &mut [Cell], nrows: usize, gpr: usize) {
        let mut gxc = [[[0f32; LANES]; CHANNELS]; G];
        for (j, g) in gxc.iter_mut().enumerate() {
            *g = self.weighted(j);
        }
        // One bounds check for the splat, not one per row: the last row's groups end
        // within `rows`, and every earlier row's end before them.
        assert!(self.g0 + G <= gpr && nrows * gpr <= rows.len());
        // Rows by index, not `chunks(gpr)`: a chunk iterator divides by its length.
        for k in 0..nrows.div_ceil(LANES) {
            let gy = self.row_weights(k);
            let n = (nrows - k * LANES).min(LANES);
            for (i, &gy) in gy[..n].iter().enumerate() {
                let o = (k * LANES + i) * gpr + self.g0;
                // SAFETY: the row `r = k·LANES + i < nrows` and `g0 + G ≤ gpr`, so
                // `o + G = r·gpr + g0 + G ≤ nrows·gpr ≤ rows.len()` by the assertion
                // above: `o..o + G` lies within `rows`, which is borrowed mutably, so
                // `cells` is the only reference to those cells while it lives;
                // `[Cell; G]` has the alignment of `Cell`.
                // Exercised against direct evaluation, footprints of one to many groups
                // and at the image's edges, by `tests::fast_path_matches_direct_evaluation`.
                let cells = unsafe { &mut *rows.as_mut_ptr().add(o).cast::<[Cell; G]>() };
                for (cell, gxc) in cells.iter_mut().zip(&gxc) {
                    for (d, gxc) in cell.iter_mut().zip(gxc) {
                        for l in 0..LANES {
                            d[l] = gxc[l].mul_add(gy, d[l]);
                        }
                    }
                }
            }
        }
    }

    /// Wider footprints: the same sums, a group at a time over the rows.
    #[inline(always)]
    fn add_any(&self, groups: usize, rows: &mut [Cell], nrows: usize, gpr: usize) {
        for j in 0..groups {
            let gxc = self.weighted(j);
            let c = self.g0 + j;
            for k in 0..nrows.div_ceil(LANES) {
                let gy = self.row_weights(k);
                let n = (nrows - k * LANES).min(LANES);
                for (i, &gy) in gy[..n].iter().enumerate() {
                    let cell = &mut rows[(k * LANES + i) * gpr + c];
                    for (d, gxc) in cell.iter_mut().zip(&gxc) {
                        for l in 0..LANES {
                            d[l] = gxc[l].mul_add(gy, d[l]);
                        }
                    }
                }
            }
        }
    }
}

/// Place the samples at physical indices `piece` of the ring and append their splats
/// to the lists of the bands they touch, in ring order.
///
/// A block of samples goes through each stage before the next: reprojection (vector
/// code over the ring's field arrays), the pixel lookups (independent loads in flight
/// together), the temporal cull (a list of survivors, no branch per sample), and only
/// then the footprints and splats of the survivors.
#[inline(never)]
fn bin_piece(
    placer: &Placer,
    ring: &Ring,
    piece: std::ops::Range<usize>,
    out: &mut Vec<Vec<Splat>>,
    bands: usize,
    band_rows: usize,
) {
    debug_assert!(band_rows.is_power_of_two());
    let band_shift = band_rows.trailing_zeros();
    out.resize_with(bands, Vec::new);
    out.iter_mut().for_each(Vec::clear);
    let mut b = Block::new();
    let tc = placer.temporal_cutoff;
    let (cr, cg, cb) = (&ring.f[field::R], &ring.f[field::G], &ring.f[field::B]);
    let mut p0 = piece.start;
    while p0 < piece.end {
        let n = LOCATE_BLOCK.min(piece.end - p0);
        placer.locate_block(ring, p0, n, &mut b);
        for i in 0..n {
            let l = placer.lookup[b.pixel[i] as usize];
            let f = &placer.tiles[l.tile as usize];
            b.tile[i] = l.tile;
            b.inv_et[i] = f.inv_et;
            (b.rx[i], b.ry[i]) = placer.radii(f, l.scale);
        }
        // The cull, footprint, temporal weight and weighted color of every lane (the
        // arithmetic of the tests' `Placer::finish`), in vector code: reading every
        // lane's color here streams the ring's color arrays, where reading only the
        // survivors' later waits on each one's cache miss.
        let (r, g, bl) = (&cr[p0..p0 + n], &cg[p0..p0 + n], &cb[p0..p0 + n]);
        for i in 0..n {
            let a = b.age[i] * b.inv_et[i];
            let [x0, x1, y0, y1] = placer.bounds(b.x[i], b.y[i], b.rx[i], b.ry[i]);
            b.x0[i] = small_int(x0);
            b.x1[i] = small_int(x1);
            b.y0[i] = small_int(y0);
            b.y1[i] = small_int(y1);
            let wt = fast_exp_neg(-0.5 * a * a);
            b.wt[i] = wt;
            b.wc[0][i] = wt * r[i];
            b.wc[1][i] = wt * g[i];
            b.wc[2][i] = wt * bl[i];
            // A NaN age (not `ok`) fails the first test.
            b.keep[i] = ((a <= tc) & (x0 <= x1) & (y0 <= y1)) as u32;
        }
        let mut m = 0;
        for i in 0..n {
            b.kept[m] = i as u8;
            m += b.keep[i] as usize;
        }
        for &i in &b.kept[..m] {
            let i = i as usize;
            let f = &placer.tiles[b.tile[i] as usize];
            let (x0, x1, y0, y1) = (b.x0[i], b.x1[i], b.y0[i], b.y1[i]);
            let wt = b.wt[i];
            let s = Splat {
                x: b.x[i],
                y: b.y[i],
                ax: f.ax,
                ay: f.ay,
                c: [b.wc[0][i], b.wc[1][i], b.wc[2][i], wt, wt * b.age[i]],
                x0: x0 as u16,
                x1: x1 as u16,
                y0: y0 as u16,
                y1: y1 as u16,
            };
            let (b0, b1) = (y0 as usize >> band_shift, y1 as usize >> band_shift);
            for o in &mut out[b0..=b1] {
                o.push(s);
            }
        }
        p0 += n;
    }
}

/// Accumulate band `b` (of an image `h` rows high) from the splats binned to it, in
/// ring order.
#[inline(never)]
#[allow(clippy::too_many_arguments)]
fn splat_band(
    binned: &[Vec<Vec<Splat>>],
    b: usize,
    band_rows: usize,
    h: usize,
    gpr: usize,
    acc: &mut [Cell],
    cstride: usize,
    cov: &mut [i32],
) {
    acc.fill([[0.0; LANES]; CHANNELS]);
    cov.fill(0);
    let by0 = b * band_rows;
    let by1 = (by0 + band_rows).min(h);
    for s in binned.iter().flat_map(|c| c[b].iter()) {
        splat_one(s, by0, by1, gpr, acc, cstride, cov);
    }
    // Corner differences → per-row differences (`+1` at `x0`, `−1` past `x1`).
    for r in 1..by1 - by0 {
        let (prev, row) = cov[(r - 1) * cstride..(r + 1) * cstride].split_at_mut(cstride);
        for (d, &p) in row.iter_mut().zip(prev.iter()) {
            *d += p;
        }
    }
}

/// The adaptive reconstructor.
pub struct Reconstructor {
    params: ReconParams,
    width: u32,
    height: u32,
    rate: f64,
    capacity: usize,
    ring: Ring,
    /// Cut the ring's stale prefix before placing samples (off only to test the cut).
    skip_stale: bool,
    /// Filter per tile at the last refresh.
    tiles: Vec<TileFilter>,
    /// Each pixel's tile and splat scale (the scale also in `scale`, the public map),
    /// together so a sample finds both in one cache line.
    lookup: Vec<Lookup>,
    /// Per-pixel filter map, built on request from `tiles` and `tile_of`.
    filters: OnceLock<Vec<[f32; 3]>>,
    scale: Vec<f32>,
    coverage: Vec<u32>,
    /// Accumulators, `gpr` cells per row.
    acc: Vec<Cell>,
    gpr: usize,
    /// Per-row coverage differences, rows of `width + 1`.
    cov: Vec<i32>,
    /// Rows per band of the splat at the last refresh.
    band_rows: usize,
    /// Splats of the last refresh: per piece of the ring (in ring order), per band.
    /// Kept across refreshes so their allocations are reused.
    binned: Vec<Vec<Vec<Splat>>>,
    /// Pieces of `binned` filled at the last refresh.
    pieces: usize,
    /// Dense pull pyramid of the hole filling (levels 1 and up), reused.
    pyramid: Vec<(usize, usize, Vec<[f64; CHANNELS]>)>,
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
        let gpr = (width as usize).div_ceil(LANES);
        let scale0 = params.scale_bounds.0.max(1e-3);
        Self {
            params,
            width,
            height,
            rate,
            capacity,
            ring: Ring::new(capacity),
            skip_stale: true,
            tiles: vec![TileFilter::new([1.0; 3], params.spatial_cutoff)],
            lookup: vec![
                Lookup {
                    tile: 0,
                    scale: scale0,
                };
                n
            ],
            filters: OnceLock::new(),
            scale: vec![scale0; n],
            coverage: vec![0; n],
            acc: vec![[[0.0; LANES]; CHANNELS]; height as usize * gpr],
            gpr,
            cov: vec![0; height as usize * (width as usize + 1)],
            band_rows: BAND_ROWS,
            binned: Vec::new(),
            pieces: 0,
            pyramid: Vec::new(),
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
    pub fn ring(&self) -> &Ring {
        &self.ring
    }

    /// Append a sample (the oldest is dropped once the ring is full). Samples should
    /// come about in the order they were traced: any order is reconstructed the same,
    /// but the stale part of the ring is skipped only up to the first sample pushed
    /// after a recent one.
    pub fn push(&mut self, s: RingSample) {
        self.ring.push(&s);
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
        self.filters.get_or_init(|| {
            self.lookup
                .iter()
                .map(|l| self.tiles[l.tile as usize].e)
                .collect()
        })
    }

    /// Rebuild the per-tile filters and the pixel → tile map from the sampler's tiling.
    fn update_filters(&mut self, tiling: &TilingSnapshot) {
        let cut = self.params.spatial_cutoff;
        self.filters = OnceLock::new();
        self.tiles.clear();
        if let Some(e) = self.params.fixed_filter {
            self.tiles.push(TileFilter::new(
                [e.ex as f32, e.ey as f32, e.et as f32],
                cut,
            ));
            self.lookup.iter_mut().for_each(|l| l.tile = 0);
        } else {
            self.tile_filters(tiling);
        }
        for (l, &sc) in self.lookup.iter_mut().zip(&self.scale) {
            l.scale = sc;
        }
    }

    /// What placing samples at display time `t` seen by `camera` needs (filters as of
    /// the last `update_filters`).
    fn placer(&self, t: f64, camera: &CameraFrame) -> Placer<'_> {
        let p = &self.params;
        Placer {
            t,
            proj: p.reproject.then(|| Projector::new(camera)),
            width: self.width as i32,
            height: self.height as i32,
            lookup: &self.lookup,
            tiles: &self.tiles,
            temporal_cutoff: p.temporal_cutoff,
            // Within the widest span a splat handles.
            max_r: p.max_radius.min((MAX_SPAN as f32 - 1.0) * 0.5),
        }
    }

    /// The adaptive filter of every tile of `tiling`, and the pixel → tile map.
    fn tile_filters(&mut self, tiling: &TilingSnapshot) {
        let w = self.width as usize;
        let cut = self.params.spatial_cutoff;
        let tiles = tiling.tiles.len();
        for tile in &tiling.tiles {
            let r = tile.rect;
            let rl = filter::local_rate(self.rate, tiles, r.area());
            let (gx, gy, gt) = (tile.gx, tile.gy, tile.gt);
            let e = filter::extents(1.0 / rl, gx, gy, gt, &self.params.bounds);
            let k = self.tiles.len() as u32;
            self.tiles.push(TileFilter::new(
                [e.ex as f32, e.ey as f32, e.et as f32],
                cut,
            ));
            let x1 = (r.x1 as usize).min(w);
            for y in r.y0 as usize..(r.y1 as usize).min(self.height as usize) {
                for l in &mut self.lookup[y * w + r.x0 as usize..y * w + x1] {
                    l.tile = k;
                }
            }
        }
    }

    /// Reconstruct the image at display time `t` seen by `camera`, with filters from
    /// `tiling` (the sampler's current tiling).
    pub fn reconstruct(&mut self, t: f64, camera: &CameraFrame, tiling: &TilingSnapshot) -> &Image {
        self.update_filters(tiling);
        self.prepare_splats(t, camera);
        self.splat();
        self.resolve();
        &self.image
    }

    /// Index in the ring from which samples may be within the temporal cutoff of some
    /// tile: every sample before it was pushed in a block whose largest time so far is
    /// older than `temporal_cutoff · max e_t` (with a margin), so it would fail the
    /// per-sample test `age / e_t ≤ temporal_cutoff` for every tile.
    fn live_start(&self, t: f64) -> usize {
        if !self.skip_stale {
            return 0;
        }
        let max_et = self.tiles.iter().fold(0f32, |m, f| m.max(f.e[2])) as f64;
        let tc = t - self.params.temporal_cutoff as f64 * max_et * (1.0 + STALE_MARGIN);
        self.ring.live_start(tc)
    }

    fn prepare_splats(&mut self, t: f64, camera: &CameraFrame) {
        let start = self.live_start(t);
        let threads = rayon::current_num_threads();
        // Bands only split the work (every pixel sums its splats in ring order whatever
        // the bands): on one thread tall bands duplicate fewer splats.
        let band_rows = if threads <= 1 {
            SINGLE_THREAD_BAND_ROWS
        } else {
            BAND_ROWS
        };
        self.band_rows = band_rows;
        let bands = (self.height as usize).div_ceil(band_rows);
        // The live part of the ring in pieces, in ring order. Pieces only split the
        // work: every band later sums its splats in ring order whatever the pieces.
        let runs = self.ring.runs(start);
        let live = runs[0].len() + runs[1].len();
        let chunk = if threads <= 1 {
            live.max(1)
        } else {
            PREP_CHUNK.max(live.div_ceil(4 * threads))
        };
        let pieces: Vec<std::ops::Range<usize>> = runs
            .into_iter()
            .flat_map(|r| {
                r.clone()
                    .step_by(chunk)
                    .map(move |p| p..(p + chunk).min(r.end))
            })
            .collect();
        // Taken out while the placer borrows the rest of `self`.
        let mut binned = std::mem::take(&mut self.binned);
        if binned.len() < pieces.len() {
            binned.resize_with(pieces.len(), Vec::new);
        }
        self.pieces = pieces.len();
        let placer = self.placer(t, camera);
        pieces
            .par_iter()
            .zip(binned.par_iter_mut())
            .for_each(|(piece, out)| {
                bin_piece(&placer, &self.ring, piece.clone(), out, bands, band_rows)
            });
        self.binned = binned;
    }

    fn splat(&mut self) {
        let h = self.height as usize;
        let (gpr, cstride) = (self.gpr, self.width as usize + 1);
        let binned = &self.binned[..self.pieces];
        let rows = self.band_rows;
        self.acc
            .par_chunks_mut(rows * gpr)
            .zip(self.cov.par_chunks_mut(rows * cstride))
            .enumerate()
            .for_each(|(b, (acc, cov))| splat_band(binned, b, rows, h, gpr, acc, cstride, cov));
    }

    /// Accumulated sums of pixel `(x, y)` (zero for a hole).
    #[inline]
    fn sums(&self, x: usize, y: usize) -> [f64; CHANNELS] {
        let cell = &self.acc[y * self.gpr + x / LANES];
        let l = x % LANES;
        if cell[3][l] >= MIN_WEIGHT {
            std::array::from_fn(|c| cell[c][l] as f64)
        } else {
            [0.0; CHANNELS]
        }
    }

    /// Quotients, coverage, splat scale adaptation, hole filling, mean age.
    fn resolve(&mut self) {
        let (w, h) = (self.width as usize, self.height as usize);
        let (gpr, cstride) = (self.gpr, w + 1);
        let p = self.params;
        let per_band: Vec<(usize, f64)> = self
            .image
            .pixels
            .par_chunks_mut(BAND_ROWS * w)
            .zip(self.coverage.par_chunks_mut(BAND_ROWS * w))
            .zip(self.scale.par_chunks_mut(BAND_ROWS * w))
            .zip(self.acc.par_chunks(BAND_ROWS * gpr))
            .zip(self.cov.par_chunks(BAND_ROWS * cstride))
            .map(|((((px, coverage), scale), acc), cov)| {
                let (mut holes, mut age) = (0usize, 0f64);
                for (r, ((px, coverage), scale)) in px
                    .chunks_mut(w)
                    .zip(coverage.chunks_mut(w))
                    .zip(scale.chunks_mut(w))
                    .enumerate()
                {
                    let cells = &acc[r * gpr..(r + 1) * gpr];
                    let cov = &cov[r * cstride..(r + 1) * cstride];
                    let mut count = 0i32;
                    for x in 0..w {
                        let [cr, cg, cb, cw, ca] = cells[x / LANES].map(|c| c[x % LANES]);
                        count += cov[x];
                        coverage[x] = count as u32;
                        let s = &mut scale[x];
                        if (count as u32) < p.undersampled {
                            *s *= p.grow;
                        } else if count as u32 > p.oversampled {
                            *s *= p.shrink;
                        }
                        *s = s.clamp(p.scale_bounds.0, p.scale_bounds.1);
                        if cw >= MIN_WEIGHT {
                            px[x] = Vec3::new(cr / cw, cg / cw, cb / cw);
                            age += (ca / cw) as f64;
                        } else {
                            holes += 1;
                        }
                    }
                }
                (holes, age)
            })
            .collect();
        // Band order, so the sum does not depend on the thread count.
        let mut age_sum: f64 = per_band.iter().map(|b| b.1).sum();
        let holes: usize = per_band.iter().map(|b| b.0).sum();
        self.holes = holes;
        if holes > 0 {
            age_sum += self.fill_holes(self.holes * 64 > w * h);
        }
        self.mean_age = age_sum / (w * h).max(1) as f64;
    }

    /// Fill holes from the coarsest-necessary level of a 2×2 pull pyramid of the sums;
    /// returns the sum of the filled pixels' ages. Few holes (the usual case) read only
    /// the blocks around them; many build the whole pyramid. Both add the same values
    /// in the same order, so they give the same image.
    fn fill_holes(&mut self, dense: bool) -> f64 {
        let (w, h) = (self.width as usize, self.height as usize);
        let mut dims = vec![(w, h)];
        while let Some(&(lw, lh)) = dims.last().filter(|d| d.0 > 1 || d.1 > 1) {
            dims.push((lw.div_ceil(2), lh.div_ceil(2)));
        }
        if dense {
            let mut pyramid = std::mem::take(&mut self.pyramid);
            pyramid.resize_with(dims.len() - 1, Default::default);
            for k in 1..dims.len() {
                let (nw, nh) = dims[k];
                let (lw, lh) = dims[k - 1];
                let (done, rest) = pyramid.split_at_mut(k - 1);
                let level = &mut rest[0];
                *level = (nw, nh, std::mem::take(&mut level.2));
                level.2.clear();
                level.2.resize(nw * nh, [0.0; CHANNELS]);
                for by in 0..nh {
                    for bx in 0..nw {
                        let mut sum = [0f64; CHANNELS];
                        for (cx, cy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                            let (x, y) = (2 * bx + cx, 2 * by + cy);
                            if x < lw && y < lh {
                                let s = if k == 1 {
                                    self.sums(x, y)
                                } else {
                                    done[k - 2].2[y * lw + x]
                                };
                                for c in 0..CHANNELS {
                                    sum[c] += s[c];
                                }
                            }
                        }
                        level.2[by * nw + bx] = sum;
                    }
                }
            }
            self.pyramid = pyramid;
        }
        let mut memo: HashMap<(usize, usize, usize), [f64; CHANNELS]> = HashMap::new();
        let mut age_sum = 0.0;
        for y in 0..h {
            for x in 0..w {
                if self.acc[y * self.gpr + x / LANES][3][x % LANES] >= MIN_WEIGHT {
                    continue;
                }
                let mut out = (Vec3::ZERO, 0.0);
                for k in 1..dims.len() {
                    let s = if dense {
                        self.pyramid[k - 1].2[(y >> k) * dims[k].0 + (x >> k)]
                    } else {
                        self.block_sum(&dims, &mut memo, k, x >> k, y >> k)
                    };
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
                self.image.pixels[y * w + x] = out.0;
                age_sum += out.1;
            }
        }
        age_sum
    }

    /// Sums of block `(bx, by)` of pyramid level `k` (blocks of `2^k × 2^k` pixels),
    /// added as the dense pyramid adds them.
    fn block_sum(
        &self,
        dims: &[(usize, usize)],
        memo: &mut HashMap<(usize, usize, usize), [f64; CHANNELS]>,
        k: usize,
        bx: usize,
        by: usize,
    ) -> [f64; CHANNELS] {
        if k == 0 {
            return self.sums(bx, by);
        }
        if let Some(s) = memo.get(&(k, bx, by)) {
            return *s;
        }
        let (lw, lh) = dims[k - 1];
        let mut sum = [0f64; CHANNELS];
        for (cx, cy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            let (x, y) = (2 * bx + cx, 2 * by + cy);
            if x < lw && y < lh {
                let s = self.block_sum(dims, memo, k - 1, x, y);
                for c in 0..CHANNELS {
                    sum[c] += s[c];
                }
            }
        }
        memo.insert((k, bx, by), sum);
        sum
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reconstruction::ring::TIME_BLOCK;
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
        let img = r
            .reconstruct(0.01, &c, &TilingSnapshot::whole(w, h))
            .clone();
        for px in &img.pixels {
            assert!((*px - Vec3::new(0.25, 0.5, 0.75)).abs().max_element() < 1e-6);
        }
        assert!(r.holes() > 0);
        // Splats grew where undersampled.
        assert!(r.splat_scale().iter().all(|&s| s > 1.0));
    }

    /// A reconstructor at `w × h` with `n` random samples over `span` seconds before
    /// `t = 1` (slowly moving, some behind or beside the view), samples pushed in order
    /// unless `shuffle`, and a tiling of 16 tiles with spatial gradients of every kind
    /// and the temporal gradients `gts`.
    fn random_setup(
        w: u32,
        h: u32,
        n: usize,
        span: f64,
        shuffle: bool,
        params: ReconParams,
        gts: [f64; 4],
    ) -> (Reconstructor, CameraFrame, TilingSnapshot) {
        use crate::tiles::{Rect, TileGradients};
        let c = cam(w, h);
        let mut rng = crate::sampling::Rng::new(&[11, n as u64]);
        let mut r = Reconstructor::new(w, h, n as f64 / span, params);
        let mut samples: Vec<RingSample> = (0..n)
            .map(|i| {
                let x = rng.uniform() * (w as f32 + 4.0) - 2.0;
                let y = rng.uniform() * (h as f32 + 4.0) - 2.0;
                let depth = if rng.uniform() < 0.02 {
                    -1.0
                } else {
                    1.0 + rng.uniform()
                };
                RingSample {
                    x,
                    y,
                    t: 1.0 - span + span * i as f64 / n as f64,
                    color: Vec3::new(rng.uniform(), rng.uniform(), rng.uniform()),
                    hit_point: c.eye + c.direction(x, y) * depth,
                    velocity: Vec3::new(rng.uniform() - 0.5, rng.uniform() - 0.5, 0.0) * 0.3,
                }
            })
            .collect();
        if shuffle {
            samples.swap(n / 3, n / 2);
        }
        for s in samples {
            r.push(s);
        }
        // A 4 × 4 grid of tiles.
        let mut tiling = TilingSnapshot::default();
        for k in 0..16u32 {
            let (i, j) = (k % 4, k / 4);
            let g = (k % 4) as f64 / 3.0;
            tiling.tiles.push(TileGradients {
                rect: Rect {
                    x0: w * i / 4,
                    y0: h * j / 4,
                    x1: w * (i + 1) / 4,
                    y1: h * (j + 1) / 4,
                },
                gx: 0.2 * g,
                gy: 0.2 * (1.0 - g),
                gt: gts[k as usize / 4],
            });
        }
        (r, c, tiling)
    }

    /// Static, slow and fast tiles.
    const GTS: [f64; 4] = [0.0, 0.3, 3.0, 30.0];

    /// Sums `[r, g, b, w, w·age]` and coverage per pixel by direct evaluation of the
    /// Gaussian in f64 for every sample of the ring (no stale-prefix cut, no bands), with
    /// the filters and splat scale the next refresh will use.
    fn direct(
        r: &mut Reconstructor,
        t: f64,
        c: &CameraFrame,
        tiling: &TilingSnapshot,
    ) -> Vec<([f64; 5], u32)> {
        r.update_filters(tiling);
        let placer = r.placer(t, c);
        let w = r.width as usize;
        let mut out = vec![([0f64; 5], 0u32); w * r.height as usize];
        for s in r.ring.iter() {
            let Some(q) = placer.place(&s) else { continue };
            let [ex, ey, _] = q.filter.e.map(|e| e as f64);
            for y in q.y0..=q.y1 {
                for x in q.x0..=q.x1 {
                    let dx = (x as f64 + 0.5 - q.x as f64) / ex;
                    let dy = (y as f64 + 0.5 - q.y as f64) / ey;
                    let a = q.a as f64;
                    let wgt = (-0.5 * (dx * dx + dy * dy + a * a)).exp();
                    let o = &mut out[y as usize * w + x as usize];
                    let col = s.color.as_dvec3();
                    for (k, v) in [col.x, col.y, col.z, 1.0, q.age as f64].iter().enumerate() {
                        o.0[k] += wgt * v;
                    }
                    o.1 += 1;
                }
            }
        }
        out
    }

    /// The fast path (bands, lanes, fast exp, stale cut) against direct evaluation.
    fn check_against_direct(r: &mut Reconstructor, c: &CameraFrame, tiling: &TilingSnapshot) {
        for _ in 0..3 {
            let d = direct(r, 1.0, c, tiling);
            r.reconstruct(1.0, c, tiling);
            let mut compared = 0;
            for (i, (sums, cov)) in d.iter().enumerate() {
                assert_eq!(r.coverage()[i], *cov, "coverage of pixel {i}");
                if sums[3] < 1e-20 {
                    continue;
                }
                compared += 1;
                let px = r.image().pixels[i];
                for (k, v) in px.to_array().iter().enumerate() {
                    let want = sums[k] / sums[3];
                    assert!(
                        (*v as f64 - want).abs() <= 1e-4 * (1.0 + want.abs()),
                        "pixel {i} channel {k}: {v} vs {want}"
                    );
                }
            }
            assert!(compared > d.len() / 2, "only {compared} pixels compared");
        }
    }

    #[test]
    fn fast_path_matches_direct_evaluation() {
        for params in [
            ReconParams::paper(),
            ReconParams::no_reprojection(),
            ReconParams::fixed_filter(),
        ] {
            for (w, h) in [(40, 30), (67, 41)] {
                let (mut r, c, tiling) = random_setup(w, h, 3000, 1.0, false, params, GTS);
                check_against_direct(&mut r, &c, &tiling);
            }
        }
    }

    #[test]
    fn wrapped_ring_matches_direct_evaluation() {
        // More pushes than the capacity: the live range wraps around the ring's
        // arrays, and a refresh must read it in ring order across the wrap.
        for ring_factor in [1.0, 1.7] {
            let params = ReconParams {
                ring_factor,
                ..ReconParams::paper()
            };
            let (mut r, c, tiling) = random_setup(40, 30, 3000, 1.0, false, params, GTS);
            assert_eq!(r.ring().len(), r.capacity());
            let runs = r.ring.runs(0);
            assert!(!runs[1].is_empty(), "the ring should wrap");
            check_against_direct(&mut r, &c, &tiling);
        }
    }

    #[test]
    fn out_of_order_ring_matches_direct_evaluation() {
        let (mut r, c, tiling) = random_setup(40, 30, 3000, 1.0, true, ReconParams::paper(), GTS);
        check_against_direct(&mut r, &c, &tiling);
    }

    #[test]
    fn stale_cut_never_drops_a_sample_that_counts() {
        // Ages up to 3 s against e_t of at most a fraction of that: the cut skips most
        // of the ring and must give exactly the image of the full per-sample test.
        // In order, and with two samples far apart swapped (as interleaved batches of
        // sampling threads would be, only more so).
        let run = |skip: bool, shuffle: bool| {
            let (mut r, c, tiling) = random_setup(
                48,
                32,
                6000,
                3.0,
                shuffle,
                ReconParams::paper(),
                [3.0, 10.0, 30.0, 100.0],
            );
            r.skip_stale = skip;
            let mut out = Vec::new();
            for k in 0..3 {
                r.update_filters(&tiling);
                let start = r.live_start(1.0);
                if skip && k == 0 {
                    assert!(start > 1000, "the cut skipped only {start} samples");
                    // Everything cut is beyond the cutoff of every tile.
                    let max_et = r.tiles.iter().fold(0f32, |m, f| m.max(f.e[2]));
                    for s in r.ring.iter().take(start) {
                        assert!((1.0 - s.t) as f32 > r.params.temporal_cutoff * max_et);
                    }
                }
                r.reconstruct(1.0, &c, &tiling);
                out.push((
                    r.image().clone(),
                    r.coverage().to_vec(),
                    r.mean_age(),
                    r.holes(),
                ));
            }
            out
        };
        for shuffle in [false, true] {
            let (a, b) = (run(true, shuffle), run(false, shuffle));
            for (x, y) in a.iter().zip(&b) {
                assert_eq!(x.0.pixels, y.0.pixels);
                assert_eq!(x.1, y.1);
                assert_eq!(x.2.to_bits(), y.2.to_bits());
                assert_eq!(x.3, y.3);
            }
        }
    }

    #[test]
    fn sparse_and_dense_hole_filling_agree() {
        // A narrow filter (1 px) over the last 0.3 s: most pixels are holes with 3
        // samples, few with 100.
        for n in [3, 30, 100] {
            let (mut r, c, tiling) =
                random_setup(37, 29, n, 0.3, false, ReconParams::fixed_filter(), GTS);
            r.reconstruct(1.0, &c, &tiling);
            assert!(r.holes() > 0, "{n} samples should leave holes");
            let mut ages = Vec::new();
            let mut images = Vec::new();
            for dense in [false, true] {
                ages.push(r.fill_holes(dense).to_bits());
                images.push(r.image().pixels.clone());
            }
            assert_eq!(ages[0], ages[1]);
            assert_eq!(images[0], images[1]);
            assert!(images[0].iter().all(|p| p.is_finite() && *p != Vec3::ZERO));
        }
    }

    #[test]
    fn stale_cut_follows_the_ring_as_it_wraps() {
        // A ring of 1000 samples fed 5000, one per ms, with some late arrivals: the cut
        // must stay within the ring and skip only samples older than the cutoff time.
        let mut r = Reconstructor::new(
            10,
            10,
            1000.0,
            ReconParams {
                ring_factor: 10.0,
                ..ReconParams::paper()
            },
        );
        r.tiles = vec![TileFilter::new([1.0, 1.0, 0.1], 2.5)];
        for i in 0..5000u32 {
            let t = if i % 97 == 0 {
                i as f64 * 1e-3 - 0.2
            } else {
                i as f64 * 1e-3
            };
            r.push(RingSample {
                x: 1.0,
                y: 1.0,
                t,
                color: Vec3::ONE,
                hit_point: Vec3::ZERO,
                velocity: Vec3::ZERO,
            });
            if i % 250 == 0 || i > 4990 {
                let now = i as f64 * 1e-3;
                let start = r.live_start(now);
                assert!(start <= r.ring().len());
                let tc = now - 0.3 * (1.0 + STALE_MARGIN);
                assert!(r.ring().iter().take(start).all(|s| s.t < tc), "push {i}");
                // Blocks are 256 pushes: at most two blocks' worth of stale samples stay.
                let stale = r.ring().iter().filter(|s| s.t < tc - 0.2).count();
                assert!(
                    stale <= start + 2 * TIME_BLOCK as usize,
                    "push {i}: {stale} stale, cut {start}"
                );
            }
        }
        assert_eq!(
            r.ring.block_max_t.len() as u64,
            r.ring.pushed.div_ceil(TIME_BLOCK) - r.ring.first_block
        );
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
