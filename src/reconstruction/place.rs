//! Placing samples at one refresh: the stale cut, reprojection to the current view,
//! the filter table lookups, the temporal cull and footprints, lane-wise in blocks of
//! [`LOCATE_BLOCK`] samples, and binning of the survivors' [`Splat`]s into row bands.

use glam::Vec3;
use rayon::prelude::*;

#[cfg(test)]
use super::RingSample;
use super::{
    filter_table::{Lookup, TileFilter},
    lanes::{fast_exp_neg, small_int},
    plan::RefreshPlan,
    ring::{field, Ring},
    splat::{Splat, BAND_ROWS, OUTSIDE, SINGLE_THREAD_BAND_ROWS},
    Reconstructor,
};
use crate::{scene::CameraFrame, trace::SceneState};

/// Samples per task of the parallel splat preparation (with more than one thread).
const PREP_CHUNK: usize = 16384;

/// Widest footprint in pixels along x (`2·max_radius + 1` is clamped to it).
const MAX_SPAN: usize = 128;

/// Relative margin of the stale-prefix cut over the per-sample temporal cutoff, far
/// above f32 rounding of `age / e_t`, so the cut never drops a sample that the
/// per-sample test would keep.
pub(super) const STALE_MARGIN: f64 = 1e-3;

/// `camera.project` with the per-view constants hoisted: `x = (d·u)/z − corner·u` with
/// `u = du/|du|²` (the same map, rounded differently).
#[derive(Clone, Copy, Debug)]
pub(super) struct Projector {
    pub(super) eye: Vec3,
    pub(super) forward: Vec3,
    pub(super) u: Vec3,
    pub(super) v: Vec3,
    pub(super) ou: f32,
    pub(super) ov: f32,
}

impl Projector {
    pub(super) fn new(c: &CameraFrame) -> Self {
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

    /// Pixel coordinates and depth along the view direction (the coordinates are
    /// meaningful only in front of the eye, `z > 1e-6`).
    #[inline(always)]
    pub(super) fn project(&self, p: Vec3) -> (f32, f32, f32) {
        let d = p - self.eye;
        let z = d.dot(self.forward);
        let iz = 1.0 / z;
        (
            d.dot(self.u) * iz - self.ou,
            d.dot(self.v) * iz - self.ov,
            z,
        )
    }
}

/// A sample placed at one refresh by the tests' direct evaluation: where it lands, its
/// filter, temporal weight argument and footprint ([`bin_piece`] computes the same
/// lane-wise).
#[cfg(test)]
#[derive(Clone, Copy, Debug)]
pub(super) struct Placed {
    pub(super) x: f32,
    pub(super) y: f32,
    pub(super) age: f32,
    /// `age / e_t` (at most `temporal_cutoff`).
    pub(super) a: f32,
    pub(super) filter: TileFilter,
    /// Depth in the current view.
    pub(super) z: f32,
    pub(super) x0: i32,
    pub(super) x1: i32,
    pub(super) y0: i32,
    pub(super) y1: i32,
}

/// Where a sample lands at one refresh, before its filter is known.
#[derive(Clone, Copy, Debug)]
struct Located {
    x: f32,
    y: f32,
    /// From the display time (the vector path takes it for the survivors alone).
    #[cfg(test)]
    age: f32,
    /// The age the temporal filter weighs: from the newest sample in hand (see
    /// [`Reconstructor::sample_lag`]).
    filter_age: f32,
    /// Depth along the current view direction (0 without reprojection).
    z: f32,
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
pub(super) struct Placer<'a> {
    t: f64,
    proj: Option<Projector>,
    width: i32,
    height: i32,
    lookup: &'a [Lookup],
    /// Each pixel's splat scale.
    scale: &'a [f32],
    tiles: &'a [TileFilter],
    temporal_cutoff: f32,
    /// When the newest sample in hand was traced ([`Reconstructor::sample_lag`]
    /// before `t`): the temporal filter measures ages from it.
    t_newest: f64,
    /// Footprint radius bound.
    max_r: f32,
    /// With the visibility pass: the largest `age / e_t` of a sample that sets front
    /// depths.
    pub(super) setter_age: Option<f32>,
}

impl Placer<'_> {
    /// Where a sample at `(x, y)` and depth `z` (in front of the eye if `front`),
    /// traced `dt` seconds ago, lands (without branches on the data, see
    /// [`LOCATE_BLOCK`]).
    #[inline(always)]
    fn located(&self, x: f32, y: f32, z: f32, front: bool, t_s: f64) -> Located {
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
            #[cfg(test)]
            age: (self.t - t_s).max(0.0) as f32,
            filter_age: (self.t_newest - t_s).max(0.0) as f32,
            z,
            pixel: py * w as u32 + px,
            ok: front & x.is_finite() & y.is_finite(),
        }
    }

    /// Reproject `s`: where it lands and in which pixel.
    #[cfg(test)]
    fn locate(&self, s: &RingSample) -> Located {
        let dt = self.t - s.t;
        let (x, y, z, front) = match &self.proj {
            Some(p) => {
                let (x, y, z) = p.project(s.hit_point + s.velocity * dt as f32);
                (x, y, z, z > 1e-6)
            }
            None => (s.x, s.y, 0.0, true),
        };
        self.located(x, y, z, front, s.t)
    }

    /// [`Placer::located`] for the samples at physical indices `p0..p0 + n` of
    /// `ring` (the same arithmetic in the same order as `Placer::locate`), one array
    /// per field so that it compiles to vector code. A sample that is not `ok` gets a
    /// NaN filter age, which fails the temporal cull just as `ok == false` does.
    #[inline(always)]
    fn locate_block(&self, ring: &Ring, p0: usize, n: usize, b: &mut Block) {
        use field::*;
        let ts = &ring.t[p0..p0 + n];
        let f = |k: usize| &ring.f[k][p0..p0 + n];
        let mut put = |i: usize, l: Located| {
            b.x[i] = l.x;
            b.y[i] = l.y;
            b.filter_age[i] = if l.ok { l.filter_age } else { f32::NAN };
            b.z[i] = l.z;
            b.pixel[i] = l.pixel;
        };
        match &self.proj {
            Some(p) => {
                let (hx, hy, hz, vx, vy, vz) = (f(HX), f(HY), f(HZ), f(VX), f(VY), f(VZ));
                for i in 0..n {
                    let dt = self.t - ts[i];
                    let hit = Vec3::new(hx[i], hy[i], hz[i]);
                    let vel = Vec3::new(vx[i], vy[i], vz[i]);
                    let (x, y, z) = p.project(hit + vel * dt as f32);
                    put(i, self.located(x, y, z, z > 1e-6, ts[i]));
                }
            }
            None => {
                let (sx, sy) = (f(X), f(Y));
                for i in 0..n {
                    put(i, self.located(sx[i], sy[i], 0.0, true, ts[i]));
                }
            }
        }
    }

    /// Place one sample.
    #[cfg(test)]
    pub(super) fn place(&self, s: &RingSample) -> Option<Placed> {
        let l = self.locate(s);
        let q = l.pixel as usize;
        self.finish(&l, self.lookup[q], self.scale[q])
    }

    /// The filter, temporal cull and footprint of a located sample.
    #[cfg(test)]
    fn finish(&self, l: &Located, look: Lookup, scale: f32) -> Option<Placed> {
        let f = self.tiles[look.tile as usize];
        let a = l.filter_age * f.inv_et;
        if !(l.ok && a <= self.temporal_cutoff) {
            return None;
        }
        let (rx, ry) = self.radii(&f, scale);
        self.footprint(l.x, l.y, l.age, a, f, rx, ry)
            .map(|p| Placed { z: l.z, ..p })
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

    /// The pixel `(x, y)` lies in, [`OUTSIDE`] off the image.
    #[inline(always)]
    pub(super) fn inside(&self, x: f32, y: f32) -> u32 {
        let (w, h) = (self.width as f32, self.height as f32);
        if x >= 0.0 && x < w && y >= 0.0 && y < h {
            (y as u32) * self.width as u32 + x as u32
        } else {
            OUTSIDE
        }
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
            z: 0.0,
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
    /// NaN where the sample is not `ok` (see [`Located`]). (The age a pixel shows,
    /// from the display time, is taken for the survivors alone, in `splat`.)
    filter_age: [f32; LOCATE_BLOCK],
    z: [f32; LOCATE_BLOCK],
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
            filter_age: [0.0; LOCATE_BLOCK],
            z: [0.0; LOCATE_BLOCK],
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
    located: &mut [[f32; 3]],
    (bands, band_rows): (usize, usize),
) {
    debug_assert!(band_rows.is_power_of_two());
    let band_shift = band_rows.trailing_zeros();
    out.resize_with(bands, Vec::new);
    out.iter_mut().for_each(Vec::clear);
    let mut b = Block::new();
    let (cr, cg, cb) = (&ring.f[field::R], &ring.f[field::G], &ring.f[field::B]);
    let mut p0 = piece.start;
    while p0 < piece.end {
        let n = LOCATE_BLOCK.min(piece.end - p0);
        placer.locate_block(ring, p0, n, &mut b);
        if !located.is_empty() {
            let at = &mut located[p0 - piece.start..][..n];
            for (i, l) in at.iter_mut().enumerate() {
                *l = [b.x[i], b.y[i], b.z[i]];
            }
        }
        b.look_up_filters(placer, n);
        b.weigh(
            placer,
            n,
            [&cr[p0..p0 + n], &cg[p0..p0 + n], &cb[p0..p0 + n]],
        );
        let m = b.list_survivors(n);
        for &i in &b.kept[..m] {
            let i = i as usize;
            let s = b.splat(placer, ring, i, p0);
            let (y0, y1) = (b.y0[i] as usize, b.y1[i] as usize);
            let (b0, b1) = (y0 >> band_shift, y1 >> band_shift);
            for o in &mut out[b0..=b1] {
                o.push(s);
            }
        }
        p0 += n;
    }
}

impl Block {
    /// Each of the first `n` lanes' tile filter and footprint radii.
    #[inline(always)]
    fn look_up_filters(&mut self, placer: &Placer, n: usize) {
        for i in 0..n {
            let q = self.pixel[i] as usize;
            let l = placer.lookup[q];
            let f = &placer.tiles[l.tile as usize];
            self.tile[i] = l.tile;
            self.inv_et[i] = f.inv_et;
            (self.rx[i], self.ry[i]) = placer.radii(f, placer.scale[q]);
        }
    }

    /// The cull, footprint, temporal weight and weighted colour (`rgb`) of every lane
    /// (the arithmetic of the tests' `Placer::finish`), in vector code: reading every
    /// lane's colour here streams the ring's colour arrays, where reading only the
    /// survivors' later waits on each one's cache miss.
    #[inline(always)]
    fn weigh(&mut self, placer: &Placer, n: usize, [r, g, bl]: [&[f32]; 3]) {
        let tc = placer.temporal_cutoff;
        for i in 0..n {
            let a = self.filter_age[i] * self.inv_et[i];
            let [x0, x1, y0, y1] = placer.bounds(self.x[i], self.y[i], self.rx[i], self.ry[i]);
            self.x0[i] = small_int(x0);
            self.x1[i] = small_int(x1);
            self.y0[i] = small_int(y0);
            self.y1[i] = small_int(y1);
            let wt = fast_exp_neg(-0.5 * a * a);
            self.wt[i] = wt;
            self.wc[0][i] = wt * r[i];
            self.wc[1][i] = wt * g[i];
            self.wc[2][i] = wt * bl[i];
            // A NaN filter age (not `ok`) fails the first test.
            self.keep[i] = ((a <= tc) & (x0 <= x1) & (y0 <= y1)) as u32;
        }
    }

    /// The lanes kept, in order, into `kept` (no branch per lane); how many.
    #[inline(always)]
    fn list_survivors(&mut self, n: usize) -> usize {
        let mut m = 0;
        for i in 0..n {
            self.kept[m] = i as u8;
            m += self.keep[i] as usize;
        }
        m
    }

    /// The splat of lane `i`, the ring's sample at physical index `p0 + i`.
    #[inline(always)]
    fn splat(&self, placer: &Placer, ring: &Ring, i: usize, p0: usize) -> Splat {
        let f = &placer.tiles[self.tile[i] as usize];
        let wt = self.wt[i];
        let mut s = Splat {
            x: self.x[i],
            y: self.y[i],
            ax: f.ax,
            ay: f.ay,
            c: [
                self.wc[0][i],
                self.wc[1][i],
                self.wc[2][i],
                wt,
                wt * (placer.t - ring.t[p0 + i]).max(0.0) as f32,
            ],
            x0: self.x0[i] as u16,
            x1: self.x1[i] as u16,
            y0: self.y0[i] as u16,
            y1: self.y1[i] as u16,
            z: 0.0,
            z_front: f32::INFINITY,
            pixel: OUTSIDE,
        };
        if let Some(max_a) = placer.setter_age {
            s.z = self.z[i];
            let a = self.filter_age[i] * self.inv_et[i];
            let still = [field::VX, field::VY, field::VZ]
                .iter()
                .all(|&k| ring.f[k][p0 + i] == 0.0);
            s.z_front = if still || a <= max_a {
                s.z
            } else {
                f32::INFINITY
            };
            s.pixel = placer.inside(self.x[i], self.y[i]);
        }
        s
    }
}

impl Reconstructor {
    /// With exact motion and the scene of this refresh given
    /// ([`Reconstructor::set_motion`]), [`Reconstructor::follow_motion`] from logical
    /// index `start`; whether it did (the scene is used by this refresh only).
    pub(super) fn follow_motion_if_asked(&mut self, t: f64, start: usize) -> bool {
        match self.motion.clone().filter(|_| self.params.exact_motion) {
            Some(state) => {
                self.follow_motion(t, &state, start);
                true
            }
            None => false,
        }
    }

    /// Rewrite the velocity of every live sample fixed to something moving so that
    /// `hit + velocity · (t − t_s)` is where its point is at `t` (a sample whose
    /// instance has left the scene gets a NaN hit point, which drops it).
    fn follow_motion(&mut self, t: f64, state: &SceneState, start: usize) {
        use field::*;
        let ring = &mut self.ring;
        let first = ring.push_index(start);
        let from = ring.moving.partition_point(|m| m.0 < first);
        let base = ring.push_index(0);
        for j in from..ring.moving.len() {
            let (k, a) = ring.moving[j];
            let p = ring.phys((k - base) as usize);
            let dt = (t - ring.t[p]) as f32;
            match state.anchor_position(&a) {
                Some(q) if dt > 0.0 => {
                    let h = Vec3::new(ring.f[HX][p], ring.f[HY][p], ring.f[HZ][p]);
                    let v = (q - h) / dt;
                    ring.f[VX][p] = v.x;
                    ring.f[VY][p] = v.y;
                    ring.f[VZ][p] = v.z;
                }
                Some(_) => {}
                None => ring.f[HX][p] = f32::NAN,
            }
        }
    }

    /// What placing samples at display time `t` seen by `camera` needs (filters as of
    /// the last `update_filters`).
    pub(super) fn placer(&self, t: f64, camera: &CameraFrame) -> Placer<'_> {
        let p = &self.params;
        Placer {
            t,
            proj: p.reproject.then(|| Projector::new(camera)),
            width: self.width as i32,
            height: self.height as i32,
            lookup: &self.lookup,
            scale: &self.scale,
            tiles: &self.tiles,
            temporal_cutoff: p.temporal_cutoff,
            t_newest: self.filter_origin_at(t),
            setter_age: p.visibility_in_use().map(|v| v.setter_age_sigmas),
            // Within the widest span a splat handles.
            max_r: self.max_footprint_radius(),
        }
    }

    /// The time the temporal filter counts ages from at `t`: [`filter_origin`], or
    /// where a refresh is built in two parts, the newest sample it expects to have
    /// once the second part takes in what arrived meanwhile.
    fn filter_origin_at(&self, t: f64) -> f64 {
        self.origin_ahead
            .map_or_else(|| filter_origin(t, &self.ring), |o| o.min(t))
    }

    /// How long before a refresh at `t` the newest sample in hand was traced (0 if
    /// none was, or one has a time after `t`). The temporal filter measures each
    /// sample's age from that sample, not from `t`: live, an image is built for the
    /// moment it is shown, a refresh or so after the newest sample it has, and a
    /// filter centred on that moment weighs every sample down (even the newest), which
    /// starved short filters and widened their splats. Where samples reach the display
    /// at once (the evaluation), the lag is nil and nothing changes.
    pub fn sample_lag(&self, t: f64) -> f64 {
        t - filter_origin(t, &self.ring)
    }

    /// Index in the ring from which samples may be within the temporal cutoff of some
    /// tile: every sample before it was pushed in a block whose largest time so far is
    /// older than `temporal_cutoff · max e_t` (with a margin), so it would fail the
    /// per-sample test `age / e_t ≤ temporal_cutoff` for every tile.
    pub(super) fn live_start(&self, t: f64) -> usize {
        if !self.skip_stale {
            return 0;
        }
        let max_et = self.tiles.iter().fold(0f32, |m, f| m.max(f.e[2])) as f64;
        let tc = self.filter_origin_at(t)
            - self.params.temporal_cutoff as f64 * max_et * (1.0 + STALE_MARGIN);
        self.ring.live_start(tc)
    }

    /// The first logical ring index a refresh at `t` places (past the stale part and
    /// within the live limit), counting the samples placed.
    pub(super) fn live_range(&mut self, t: f64) -> usize {
        let pending = self.pending_start().filter(|_| !self.resplat);
        let stale = self.live_start(t).max(pending.unwrap_or(0));
        let start = match self.live_limit {
            Some(k) => stale.max(self.ring.len().saturating_sub(k)),
            None => stale,
        };
        self.placed = self.ring.len() - start.min(self.ring.len());
        start
    }

    /// Largest footprint radius of a splat, pixels.
    pub(super) fn max_footprint_radius(&self) -> f32 {
        self.params.max_radius.min((MAX_SPAN as f32 - 1.0) * 0.5)
    }

    /// Place the live part of the ring and bin its splats by band, pieces of the ring
    /// in parallel. With a [`Reconstructor::set_live_limit`], only the newest samples
    /// of it.
    pub(super) fn prepare_splats(&mut self, plan: &RefreshPlan) {
        self.place_pieces(plan.t, &plan.camera, plan.start, false);
    }

    /// Place the ring from logical index `start` on for a refresh at `t` seen by
    /// `camera`, binned into pieces after those already binned if `append` (samples
    /// taken in while the refresh was built), else from the first.
    pub(super) fn place_pieces(
        &mut self,
        t: f64,
        camera: &CameraFrame,
        start: usize,
        append: bool,
    ) {
        self.ensure_lookup();
        let first = if append { self.pieces } else { 0 };
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
        if binned.len() < first + pieces.len() {
            binned.resize_with(first + pieces.len(), Vec::new);
        }
        self.pieces = first + pieces.len();
        // Carrying, the cut reads where each sample landed (pieces are in ring order:
        // each one's part of `located` follows the one before); it cuts only where the
        // samples are reprojected, as they are placed then.
        let record = self.carries_now() && self.params.reproject && !append;
        let mut located = std::mem::take(&mut self.located);
        located.resize(if record { live } else { 0 }, [0.0; 3]);
        let mut parts: Vec<&mut [[f32; 3]]> = Vec::with_capacity(pieces.len());
        let mut rest = &mut located[..];
        for piece in &pieces {
            let take = if record { piece.len() } else { 0 };
            let (part, tail) = rest.split_at_mut(take);
            parts.push(part);
            rest = tail;
        }
        let placer = self.placer(t, camera);
        pieces
            .par_iter()
            .zip(binned[first..].par_iter_mut())
            .zip(parts.into_par_iter())
            .for_each(|((piece, out), at)| {
                bin_piece(
                    &placer,
                    &self.ring,
                    piece.clone(),
                    out,
                    at,
                    (bands, band_rows),
                )
            });
        self.binned = binned;
        if !append {
            self.located = located;
            self.located_from = record.then_some(start);
        }
    }
}

/// The time the temporal filter counts ages from at a refresh at `t`: the newest
/// sample in `ring` ([`Reconstructor::sample_lag`] before `t`), or `t` itself if there
/// is none, or one has a time after `t` (or a NaN time).
pub(super) fn filter_origin(t: f64, ring: &Ring) -> f64 {
    let newest = ring.newest_time();
    if newest.is_finite() && newest < t {
        newest
    } else {
        t
    }
}
