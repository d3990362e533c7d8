//! Accumulators carried from one refresh to the next, so that a refresh splats only
//! the samples that arrived since the previous one.
//!
//! Re-splatting the ring at every refresh makes a refresh cost the ring times the
//! footprints: each sample is splatted once per refresh for as long as its temporal
//! weight lasts, about thirty times on the kitchen's windows. Here a sample is
//! splatted once, at the first refresh after it arrives, with the footprint of that
//! refresh's filter; what it added stays in the accumulators and is carried to later
//! refreshes:
//!
//! - **decayed**: every sum is multiplied by `e^(−Δ/τ)` per `Δ` seconds, `τ` a multiple
//!   ([`super::ReconParams::decay_scale`]) of the temporal extent `e_t` of the pixel's
//!   tile, so the temporal filter is exponential in a sample's age instead of the
//!   ring's Gaussian (the weighted age channel grows by `Δ·w` as well);
//! - **moved**: each pixel's sums go to where the surface they show is seen at the new
//!   refresh: its geometry (depth in the previous view, sub-pixel offset, velocity) is
//!   unprojected by the previous camera, moved by its velocity and projected by the
//!   new one. Pixels landing together keep the nearest (merged when within the
//!   visibility tolerance);
//! - **cut** where a new sample lands in front of them (something came in front), or
//!   at another depth than moving ones (placed by extrapolation, they give way to what
//!   a ray saw). A new sample behind still carried sums was seen through them (traced
//!   from an earlier view): with the visibility pass, still carried sums are fronts
//!   that hide it.
//!
//! The coverage that drives the splat scale is carried too, decayed over
//! `temporal_cutoff · τ`, so that it counts about the samples of the window the sums
//! hold (over `temporal_cutoff · e_t`, the ring's window, it counted samples whose
//! weight was long gone: kitchen Interactive 100K FLIP 0.1652 against 0.1628).
//!
//! A refresh then costs the new samples' splats plus a few passes over the pixels,
//! whatever the ring's length: the ring only holds samples until their first refresh.

use std::mem::take;

use glam::Vec3;
use rayon::prelude::*;
use rustc_hash::FxHashMap as HashMap;

use super::{
    carry_edits::CarryEdits,
    filter_table::Lookup,
    lanes::{fast_exp_neg, prefetch, Lanes, LANES, PREFETCH_AHEAD},
    place::Projector,
    ring::field,
    splat::{behind_front, CHANNELS, MIN_WEIGHT},
    Reconstructor,
};
use crate::{
    scene::CameraFrame,
    trace::{Anchor, SceneState},
};

/// Where a pixel's carried sums lie: the surface point they show.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Geo {
    /// Depth along the view direction of the refresh it belongs to; infinite: none.
    pub(super) z: f32,
    /// Where the pixel's sums lie, from its centre, pixels: their sub-pixel position
    /// survives moves to the nearest pixel, so that slow motion is not rounded away.
    pub(super) ox: f32,
    pub(super) oy: f32,
    /// World velocity of the point.
    pub(super) v: Vec3,
}

impl Geo {
    pub(super) const NONE: Geo = Geo {
        z: f32::INFINITY,
        ox: 0.0,
        oy: 0.0,
        v: Vec3::ZERO,
    };

    /// What the cut leaves as a pixel's next geometry while no sample it offered
    /// had a finite depth: none, but not [`Geo::NONE`], which says untouched.
    const PENDING: Geo = Geo {
        ox: f32::NAN,
        ..Geo::NONE
    };

    fn is_some(&self) -> bool {
        self.z.is_finite()
    }

    /// Whether this is exactly [`Geo::NONE`] (samples' offsets are never NaN).
    fn is_untouched(&self) -> bool {
        self.z == f32::INFINITY && self.ox == 0.0
    }

    /// The depth this geometry hides what lies behind at: its own where it is still
    /// (moving geometry is placed by extrapolation and hides nothing), infinite
    /// otherwise. [`Carried::still_z`] keeps it for every pixel.
    pub(super) fn still_z(&self) -> f32 {
        if self.v == Vec3::ZERO {
            self.z
        } else {
            f32::INFINITY
        }
    }
}

/// Neighbours searched for the geometry of a pixel that holds sums but got no sample
/// of its own (a footprint reached it): rings up to this distance, pixels.
const BORROW_RADIUS: i32 = 2;

/// The state carried between refreshes.
pub(super) struct Carried {
    /// The accumulators of the previous refresh (the layout of `Reconstructor::acc`),
    /// swapped with them at each refresh.
    prev: Vec<f32>,
    /// Each pixel's geometry after the previous refresh, and the one the sums moved
    /// with the view land on (every pixel's [`Geo::NONE`] between refreshes).
    pub(super) geo: Vec<Geo>,
    next_geo: Vec<Geo>,
    /// [`Geo::still_z`] of each pixel's geometry, kept wherever the geometry is set:
    /// the carried fronts read four bytes a pixel, not the geometry's twenty-four
    /// (the fronts' pass over every pixel took 2.0 of a 41.5 ms image at 1280×720,
    /// performance.md, session 46).
    still_z: Vec<f32>,
    /// The decayed coverage being moved (`Reconstructor::cover` holds the current).
    next_cover: Vec<f32>,
    /// Time and camera of the previous refresh.
    last: Option<(f64, CameraFrame)>,
    /// Samples pushed since the previous refresh.
    pub(super) pending: usize,
    /// Pixels whose geometry moved at the last refresh (some may no longer).
    moving: Vec<u32>,
    /// What the surface a moving pixel's sums show is fixed to (where it is known),
    /// so that with exact motion the sums go where that point is, not where its
    /// velocity takes it.
    anchor: HashMap<u32, Anchor>,
    /// Where each new sample lands (reused).
    ahead: Vec<Ahead>,
    /// The same, with their indices, in the cut's order (reused), and where each
    /// group of pixels starts in it.
    in_order: Vec<(u32, Ahead)>,
    group_starts: Vec<u32>,
    /// Where each pixel's sums go when the view moves (reused; empty until then).
    dests: Vec<Dest>,
    /// The previous refresh re-splatted the ring: the next carried refresh starts
    /// from nothing and places the whole live ring as new.
    pub(super) restart: bool,
    /// The view of the previous refresh, carried or not.
    view: Option<CameraFrame>,
    /// What the last carry did, listed for a GPU that keeps the sums (`None`: not
    /// listed).
    pub(super) edits: Option<CarryEdits>,
}

impl Carried {
    /// Back the zeroed sums with memory now ([`Reconstructor::prepare`]).
    pub(super) fn prepare(&mut self) {
        super::lanes::touch(&mut self.prev);
        super::lanes::touch(&mut self.next_cover);
    }

    pub(super) fn new(n: usize, acc_len: usize) -> Self {
        Self {
            prev: vec![0.0; acc_len],
            geo: vec![Geo::NONE; n],
            next_geo: vec![Geo::NONE; n],
            still_z: vec![f32::INFINITY; n],
            next_cover: vec![0.0; n],
            last: None,
            pending: 0,
            moving: Vec::new(),
            anchor: HashMap::default(),
            ahead: Vec::new(),
            in_order: Vec::new(),
            group_starts: Vec::new(),
            dests: Vec::new(),
            restart: false,
            view: None,
            edits: None,
        }
    }
}

/// Where a new sample lands at a refresh: its pixel (`u32::MAX`: off the image or
/// behind the eye) and its depth, negated where the sample moves (a depth on the
/// image is positive). Eight bytes: the cut's sort and its bands stream these, and a
/// velocity in each (most are none) more than tripled what they moved.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Ahead {
    q: u32,
    signed_z: f32,
}

impl Ahead {
    const OFF: Ahead = Ahead {
        q: u32::MAX,
        signed_z: 0.0,
    };

    fn new(q: usize, z: f32, moves: bool) -> Self {
        Ahead {
            q: q as u32,
            signed_z: if moves { -z } else { z },
        }
    }

    fn is_on(self) -> bool {
        self.q != u32::MAX
    }

    fn z(self) -> f32 {
        self.signed_z.abs()
    }

    fn moves(self) -> bool {
        self.signed_z.is_sign_negative()
    }
}

/// Where one pixel's sums go at a refresh: the pixel its point is seen in now, with
/// its geometry there.
struct Move {
    /// The pixel, and its column and row.
    to: usize,
    tx: usize,
    ty: usize,
    geo: Geo,
}

/// Where one pixel's sums go when they move with the view: the pixel `(tx, ty)`
/// (`tx == u32::MAX`: nowhere) and their geometry there.
#[derive(Clone, Copy)]
struct Dest {
    tx: u32,
    ty: u32,
    geo: Geo,
}

impl Dest {
    const NONE: Dest = Dest {
        tx: u32::MAX,
        ty: u32::MAX,
        geo: Geo::NONE,
    };

    /// Where `mover` takes the sums of pixel `(x, y)` of weight `weight`, with its
    /// geometry in `geo` (borrowed from its neighbours' where it has none).
    #[inline(always)]
    fn of(mover: &Mover, geo: &[Geo], weight: f32, x: usize, y: usize, keep: f32) -> Dest {
        if !holds(weight) {
            return Dest::NONE;
        }
        let g = geo[y * mover.w + x];
        let g = if g.is_some() {
            Some(g)
        } else {
            borrow(geo, mover.w, mover.h, x, y, keep)
        };
        match g.and_then(|g| mover.target(x, y, g)) {
            Some(m) => Dest {
                tx: m.tx as u32,
                ty: m.ty as u32,
                geo: m.geo,
            },
            None => Dest::NONE,
        }
    }

    /// The move, on an image `w` pixels wide (`None`: nowhere).
    fn landing(self, w: usize) -> Option<Move> {
        (self.tx != u32::MAX).then(|| {
            let (tx, ty) = (self.tx as usize, self.ty as usize);
            Move {
                to: ty * w + tx,
                tx,
                ty,
                geo: self.geo,
            }
        })
    }
}

/// What moving the sums of one refresh needs: the map from a point seen through
/// `(px, py)` of the previous view at depth `z` to the current view, as affine
/// functions of `(px, py)` (the ray `corner + px·du + py·dv` dotted with the previous
/// forward axis and the current projection's axes), so that a pixel costs a few
/// multiply-adds and one division.
struct Mover {
    w: usize,
    h: usize,
    dt: f32,
    /// The view is the previous one: still points stay where they are.
    same_view: bool,
    /// Rows: the previous forward axis, then the current forward, `u` and `v` axes;
    /// each `[at corner, per px, per py]`.
    aff: [[f32; 3]; 4],
    /// The previous eye minus the current, and the axes it is dotted with.
    eye_shift: Vec3,
    axes: [Vec3; 3],
    ou: f32,
    ov: f32,
}

impl Mover {
    fn new(w: usize, h: usize, dt: f32, cam0: &CameraFrame, camera: &CameraFrame) -> Self {
        let p = Projector::new(camera);
        let axes = [p.forward, p.u, p.v];
        let row = |a: Vec3| [cam0.corner.dot(a), cam0.du.dot(a), cam0.dv.dot(a)];
        Self {
            w,
            h,
            dt,
            same_view: cam0.same_view(camera),
            aff: [row(cam0.forward), row(axes[0]), row(axes[1]), row(axes[2])],
            eye_shift: cam0.eye - p.eye,
            axes,
            ou: p.ou,
            ov: p.ov,
        }
    }

    /// Where the sums of pixel `(x, y)` with geometry `g` land (`None`: behind the
    /// eye, or off the image).
    #[inline(always)]
    fn target(&self, x: usize, y: usize, g: Geo) -> Option<Move> {
        if self.same_view && g.v == Vec3::ZERO {
            return Some(Move {
                to: y * self.w + x,
                tx: x,
                ty: y,
                geo: g,
            });
        }
        let (px, py) = (x as f32 + 0.5 + g.ox, y as f32 + 0.5 + g.oy);
        let a = |k: usize| {
            let [c, dx, dy] = self.aff[k];
            dy.mul_add(py, dx.mul_add(px, c))
        };
        let s = g.z / a(0);
        // The eye's shift (and the point's motion) along each current axis.
        let e = self.eye_shift + g.v * self.dt;
        let [ef, eu, ev] = self.axes.map(|ax| e.dot(ax));
        let nz = s.mul_add(a(1), ef);
        let iz = 1.0 / nz;
        let nx = s.mul_add(a(2), eu) * iz - self.ou;
        let ny = s.mul_add(a(3), ev) * iz - self.ov;
        let (tx, ty) = pixel_at(nx, ny, nz, self.w, self.h)?;
        Some(Move {
            to: ty * self.w + tx,
            tx,
            ty,
            geo: Geo {
                z: nz,
                ox: nx - tx as f32 - 0.5,
                oy: ny - ty as f32 - 0.5,
                v: g.v,
            },
        })
    }
}

impl Reconstructor {
    /// Samples placed at this refresh when carrying: those pushed since the previous
    /// one (the ring holds at most its capacity of them).
    pub(super) fn pending_start(&self) -> Option<usize> {
        let c = self.carried.as_ref()?;
        if c.restart {
            return Some(0);
        }
        Some(self.ring.len() - c.pending.min(self.ring.len()))
    }

    /// Decay and move the previous refresh's accumulators, geometry and coverage into
    /// place for a refresh at `t` seen by `camera`, then cut them where the new
    /// samples (from logical ring index `start`) disagree. With `late`, a refresh on
    /// the CPU, the decay of a view that holds is left to the splat's band pass
    /// ([`LateDecay`]).
    pub(super) fn carry_over(&mut self, t: f64, camera: &CameraFrame, start: usize, late: bool) {
        self.flush_late_decay();
        let Some(mut c) = self.carried.take() else {
            return;
        };
        if let Some(e) = &mut c.edits {
            e.clear();
        }
        if std::mem::take(&mut c.restart) {
            self.acc.fill(0.0);
            self.cover.fill(0.0);
            c.geo.fill(Geo::NONE);
            c.still_z.fill(f32::INFINITY);
            c.moving.clear();
            c.anchor.clear();
            c.last = None;
        }
        if let Some((t0, cam0)) = c.last {
            let dt = (t - t0).max(0.0) as f32;
            let decay = self.tile_decay(dt);
            if !self.params.reproject || cam0.same_view(camera) {
                if let Some(e) = &mut c.edits {
                    e.complete = true;
                    e.dt = dt;
                    e.decay.clone_from(&decay);
                }
                self.carry_in_place(&mut c, (dt, &decay, late), camera);
            } else {
                self.carry_moved(&mut c, dt, &decay, &cam0, camera);
            }
        }
        if self.params.reproject {
            self.cut_and_place(&mut c, t, camera, start..self.ring.len());
        }
        c.last = Some((t, *camera));
        c.pending = 0;
        #[cfg(test)]
        c.check_still_z();
        self.carried = Some(c);
    }

    /// `[e^(−Δ/τ), e^(−Δ/(temporal_cutoff · τ))]` of every tile: the decay of the
    /// sums and of the coverage over `dt`.
    fn tile_decay(&self, dt: f32) -> Vec<[f32; 2]> {
        let tc = self.params.temporal_cutoff;
        let tau = self.params.decay_scale;
        self.tiles
            .iter()
            .map(|f| {
                [
                    fast_exp_neg(-dt * f.inv_et / tau),
                    fast_exp_neg(-dt * f.inv_et / (tc * tau)),
                ]
            })
            .collect()
    }

    /// The view is the previous refresh's: every pixel's sums decay where they are,
    /// row by row, and only those of moving surfaces move.
    #[inline(never)]
    fn carry_in_place(
        &mut self,
        c: &mut Carried,
        (dt, decay, late): (f32, &[[f32; 2]], bool),
        camera: &CameraFrame,
    ) {
        let (w, cs) = (self.width as usize, self.cs);
        // Where a GPU keeps the sums (it lists the carry to replay) and gives back only
        // which pixels hold some, the sums here are those weights alone: the carry
        // decides from them, and a weight of 1 decayed still holds, so the GPU's
        // replay is the only decay needed.
        let holds_only = c.edits.is_some() && self.holds_only_back();
        if !holds_only {
            self.ensure_lookup();
            if late && c.edits.is_none() {
                let flags = std::mem::take(&mut self.late_flags);
                self.late_decay = Some(LateDecay::new(decay, dt, flags, self.cover.len()));
            } else {
                // Rows are independent: in parallel, each row decayed as a whole.
                self.acc
                    .par_chunks_mut(CHANNELS * cs)
                    .zip(self.cover.par_chunks_mut(w))
                    .zip(self.lookup.par_chunks(w))
                    .for_each(|((row, cover), lookup)| {
                        decay_row(row, cover, cs, lookup, decay, dt)
                    });
            }
        }
        if self.params.reproject {
            self.move_listed(c, dt, camera);
        }
    }

    /// With the view unchanged: the sums of the pixels listed as moving go where
    /// their surfaces are now (all taken out first, so none moves twice): where the
    /// point they show is fixed to something and the scene of this refresh is given
    /// (exact motion), exactly there; otherwise along their velocity.
    fn move_listed(&mut self, c: &mut Carried, dt: f32, camera: &CameraFrame) {
        let (w, h, cs) = (self.width as usize, self.height as usize, self.cs);
        // With the decay left to the splat, each pixel is decayed as it is read: the
        // sums taken (no landing has reached one yet) and the pixels landed in.
        let mut late = self.late_decay.take();
        let mut out = Vec::new();
        for &q in &c.moving {
            let q = q as usize;
            let (x, y) = (q % w, q / w);
            let g = c.geo[q];
            let weight = self.acc[(y * CHANNELS + 3) * cs + x];
            let weight = match &late {
                Some(l) => DecayView::new(l, &self.lookup).weight(q, weight),
                None => weight,
            };
            if g.v == Vec3::ZERO || !holds(weight) {
                continue;
            }
            let mut sums: [f32; CHANNELS] = std::array::from_fn(|ch| {
                std::mem::take(&mut self.acc[(y * CHANNELS + ch) * cs + x])
            });
            let mut cover = std::mem::take(&mut self.cover[q]);
            if let Some(l) = &late {
                let [k, kc] = l.factor(&self.lookup, q);
                (sums, cover) = (decayed_sums(sums, k, l.dt), cover * kc);
            }
            let anchor = c.anchor.remove(&(q as u32));
            out.push((x, y, g, anchor, sums, cover));
            if let Some(e) = &mut c.edits {
                e.takes.push(q as u32);
            }
            c.geo[q] = Geo::NONE;
            c.still_z[q] = f32::INFINITY;
        }
        c.moving.clear();
        let mover = Mover::new(w, h, dt, camera, camera);
        let exact = self.motion.as_deref().filter(|_| self.params.exact_motion);
        let proj = Projector::new(camera);
        let keep = self.carry_keep();
        let mut into = Target {
            acc: &mut self.acc,
            cs,
            geo: &mut c.geo,
            still_z: Some(&mut c.still_z),
            cover: &mut self.cover,
        };
        for (i, (x, y, g, anchor, sums, cover)) in out.into_iter().enumerate() {
            let m = match (anchor, exact) {
                (Some(a), Some(state)) => exact_target(state, &proj, a, g, w, h),
                _ => mover.target(x, y, g),
            };
            let Some(m) = m else {
                continue;
            };
            if let Some(l) = &mut late {
                l.decay_now(&self.lookup, &mut into, (m.to, m.tx, m.ty));
            }
            let landed = into.land(&m, sums, cover, keep);
            if let (Some(e), Some(l)) = (&mut c.edits, landed) {
                e.lands.push((i as u32, m.to as u32, l.merged));
            }
            if landed.is_some_and(|l| l.took_geometry) {
                c.moving.push(m.to as u32);
                if let Some(a) = anchor {
                    c.anchor.insert(m.to as u32, a);
                }
            }
        }
        if let Some(l) = &mut late {
            l.early.sort_unstable();
        }
        self.late_decay = late;
    }

    /// The view changed: every pixel's decayed sums move from the previous refresh's
    /// accumulators to where their surface is seen now, in pixel order.
    #[inline(never)]
    fn carry_moved(
        &mut self,
        c: &mut Carried,
        dt: f32,
        decay: &[[f32; 2]],
        cam0: &CameraFrame,
        camera: &CameraFrame,
    ) {
        let (w, h, cs) = (self.width as usize, self.height as usize, self.cs);
        self.ensure_lookup();
        std::mem::swap(&mut self.acc, &mut c.prev);
        self.acc.fill(0.0);
        c.next_cover.fill(0.0);
        c.moving.clear();
        // Moved with the view, moving sums follow their velocity.
        c.anchor.clear();
        let mover = Mover::new(w, h, dt, cam0, camera);
        let keep = self.carry_keep();
        // Where each pixel's sums go, in parallel row by row (the geometry read is
        // the previous refresh's, which nothing changes here); then they land one
        // after another in pixel order, as conflicts are settled in that order.
        let (prev, geo) = (&c.prev, &c.geo);
        c.dests.resize(w * h, Dest::NONE);
        c.dests.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            let weight = &prev[(y * CHANNELS + 3) * cs..][..w];
            for (x, d) in row.iter_mut().enumerate() {
                *d = Dest::of(&mover, geo, weight[x], x, y, keep);
            }
        });
        let mut into = Target {
            acc: &mut self.acc,
            cs,
            geo: &mut c.next_geo,
            // Every pixel's is made again below.
            still_z: None,
            cover: &mut c.next_cover,
        };
        for (y, row) in c.dests.chunks(w).enumerate() {
            for (x, d) in row.iter().enumerate() {
                let Some(m) = d.landing(w) else {
                    continue;
                };
                let q = y * w + x;
                let [k, kc] = decay[self.lookup[q].tile as usize];
                let sums = decayed(&c.prev, cs, x, y, k, dt);
                into.land_move(&m, sums, self.cover[q] * kc, keep, &mut c.moving);
            }
        }
        std::mem::swap(&mut c.geo, &mut c.next_geo);
        c.next_geo.fill(Geo::NONE);
        c.still_z
            .par_chunks_mut(w)
            .zip(c.geo.par_chunks(w))
            .for_each(|(z, g)| z.iter_mut().zip(g).for_each(|(z, g)| *z = g.still_z()));
        std::mem::swap(&mut self.cover, &mut c.next_cover);
    }

    /// `1 / (1 + depth tolerance)` of the cuts and merges: the visibility pass's, or
    /// its default without one.
    fn carry_keep(&self) -> f32 {
        let tol = self.params.visibility.unwrap_or_default().depth_tolerance;
        1.0 / (1.0 + tol)
    }

    /// For each new sample (logical ring indices from `start`, in ring order): where
    /// it lies in front of its pixel's carried sums beyond the tolerance, they are
    /// cut; where behind, it is left to the visibility pass. The pixel's geometry
    /// becomes that of its nearest new sample that is not behind.
    #[inline(never)]
    fn cut_and_place(
        &mut self,
        c: &mut Carried,
        t: f64,
        camera: &CameraFrame,
        samples: std::ops::Range<usize>,
    ) {
        let (w, h, cs) = (self.width as usize, self.height as usize, self.cs);
        let keep = self.carry_keep();
        let ring = &self.ring;
        let mut ahead = std::mem::take(&mut c.ahead);
        self.locate_new(t, camera, samples.clone(), &mut ahead);
        // Band by band of rows in parallel: a sample touches only its own pixel,
        // and each pixel sees its samples in ring order.
        let band_px = CUT_ROWS * w;
        let (mut in_order, mut starts) = (take(&mut c.in_order), take(&mut c.group_starts));
        sort_by_group(&ahead, (w * h).div_ceil(GROUP), &mut starts, &mut in_order);
        let late = self.late_decay.as_ref();
        let ctx = CutContext {
            keep,
            late: late.map(|l| DecayView::new(l, &self.lookup)),
            list_edits: c.edits.is_some(),
            w,
            cs,
            start: samples.start,
        };
        let outs: Vec<BandOut> = self
            .acc
            .par_chunks_mut(CUT_ROWS * CHANNELS * cs)
            .zip(self.cover.par_chunks_mut(band_px))
            .zip(c.geo.par_chunks_mut(band_px))
            .zip(c.still_z.par_chunks_mut(band_px))
            .enumerate()
            .map_init(
                || vec![Geo::NONE; band_px],
                |scratch, (b, (((acc, cover), geo), still_z))| {
                    let next_geo = &mut scratch[..geo.len()];
                    let (g0, g1) = (
                        b * band_px / GROUP,
                        ((b + 1) * band_px / GROUP).min(starts.len() - 1),
                    );
                    let ks = &in_order[starts[g0] as usize..starts[g1] as usize];
                    let mut band = CutBand {
                        base: b * band_px,
                        acc,
                        cover,
                        next_geo,
                        geo,
                        still_z,
                        touched: Vec::new(),
                        next_anchor: HashMap::default(),
                        out: BandOut::default(),
                    };
                    band.cut_and_offer(&ctx, ks, ring);
                    band.settle(&ctx);
                    band.out
                },
            )
            .collect();
        c.ahead = ahead;
        c.in_order = in_order;
        c.group_starts = starts;
        c.merge_bands(outs);
    }
}

impl Reconstructor {
    /// Where each new sample (logical ring indices `samples`, up to the ring's end)
    /// lands at the refresh at `t` seen by `camera`, into `ahead`, in parallel: found
    /// first, so that the cut can ask for the pixels of samples ahead of it (they are
    /// at random: one miss after another otherwise). The ring is read a run of
    /// physical slots at a time, as slices, so that no sample pays for finding its slot
    /// and each field is read in one stream.
    fn locate_new(
        &self,
        t: f64,
        camera: &CameraFrame,
        samples: std::ops::Range<usize>,
        ahead: &mut Vec<Ahead>,
    ) {
        debug_assert_eq!(samples.end, self.ring.len());
        let proj = Projector::new(camera);
        // Where the place pass put them, if it placed these samples this refresh.
        let located = (self.located_from == Some(samples.start)
            && self.located.len() == samples.len())
        .then_some(&self.located[..]);
        let to = LocateTo {
            ring: &self.ring,
            proj: &proj,
            t,
            w: self.width as usize,
            h: self.height as usize,
        };
        ahead.clear();
        ahead.resize(samples.len(), Ahead::OFF);
        let [r0, r1] = self.ring.runs(samples.start);
        let (a0, a1) = ahead.split_at_mut(r0.len());
        for (run, out, k0) in [(r0.start, a0, 0), (r1.start, a1, r0.len())] {
            out.par_chunks_mut(LOCATE_CHUNK)
                .enumerate()
                .for_each(|(c, out)| {
                    let (p, k) = (run + c * LOCATE_CHUNK, k0 + c * LOCATE_CHUNK);
                    to.run(p, located.map(|l| &l[k..k + out.len()]), out);
                });
        }
    }
}

/// Samples per task of [`Reconstructor::locate_new`].
const LOCATE_CHUNK: usize = 1 << 13;

/// What [`Reconstructor::locate_new`] reads: the ring, the view's projector, the
/// refresh's time and the image's size.
struct LocateTo<'a> {
    ring: &'a super::ring::Ring,
    proj: &'a Projector,
    t: f64,
    w: usize,
    h: usize,
}

impl LocateTo<'_> {
    /// Where the samples of physical slots `p..p + out.len()` land, into `out`: as
    /// `located` says where given, else projected by their velocity.
    fn run(&self, p: usize, located: Option<&[[f32; 3]]>, out: &mut [Ahead]) {
        use field::*;
        let n = out.len();
        let f = |k: usize| &self.ring.f[k][p..p + n];
        let (vx, vy, vz) = (f(VX), f(VY), f(VZ));
        let v = |j: usize| Vec3::new(vx[j], vy[j], vz[j]);
        let (w, h) = (self.w, self.h);
        let land = |(x, y, z): (f32, f32, f32), v: Vec3| match pixel_at(x, y, z, w, h) {
            Some((px, py)) => Ahead::new(py * w + px, z, v != Vec3::ZERO),
            None => Ahead::OFF,
        };
        if let Some(l) = located {
            for (j, (a, l)) in out.iter_mut().zip(l).enumerate() {
                *a = land((l[0], l[1], l[2]), v(j));
            }
            return;
        }
        let (hx, hy, hz, ts) = (f(HX), f(HY), f(HZ), &self.ring.t[p..p + n]);
        for (j, a) in out.iter_mut().enumerate() {
            let dt = (self.t - ts[j]) as f32;
            let hit = Vec3::new(hx[j], hy[j], hz[j]);
            let v = v(j);
            *a = land(self.proj.project(hit + v * dt), v);
        }
    }
}

/// Pixels per group of the cut's order: a few cache lines of geometry, so that a
/// band's samples in group order stream through the band's arrays.
const GROUP: usize = 8;
/// Rows per band of the parallel cut.
const CUT_ROWS: usize = 16;
// So that no group straddles two bands.
const _: () = assert!(CUT_ROWS % GROUP == 0);

/// The entries of `ahead` (samples off the image left out), with their indices, into
/// `sorted`, ordered stably by group of [`GROUP`] pixels (`groups` of them): so each
/// pixel's in ring order. `starts[g]` is where group `g` starts, `starts[groups]` the
/// end. A counting sort.
fn sort_by_group(
    ahead: &[Ahead],
    groups: usize,
    starts: &mut Vec<u32>,
    sorted: &mut Vec<(u32, Ahead)>,
) {
    let group = |a: &Ahead| a.q as usize / GROUP;
    starts.clear();
    starts.resize(groups + 2, 0);
    for a in ahead.iter().filter(|a| a.is_on()) {
        starts[group(a) + 2] += 1;
    }
    for g in 2..starts.len() {
        starts[g] += starts[g - 1];
    }
    sorted.resize(starts[groups + 1] as usize, (0, Ahead::OFF));
    for (k, a) in ahead.iter().enumerate().filter(|(_, a)| a.is_on()) {
        let slot = &mut starts[group(a) + 1];
        sorted[*slot as usize] = (k as u32, *a);
        *slot += 1;
    }
    starts.truncate(groups + 1);
}

/// What every band of the cut reads.
struct CutContext<'a> {
    keep: f32,
    /// The decay left to the splat, which the weights read here are put through.
    late: Option<DecayView<'a>>,
    /// List the pixels cut and settled ([`CarryEdits::cuts`], [`CarryEdits::settled`]).
    list_edits: bool,
    w: usize,
    cs: usize,
    /// Logical ring index of the sample of index 0.
    start: usize,
}

/// What a band of the cut leaves for [`Carried::merge_bands`].
#[derive(Default)]
struct BandOut {
    /// `(index in ahead, pixel)` of each moving sample, in order.
    moving: Vec<(u32, u32)>,
    /// Pixels whose carried geometry moved (their anchors go), and the anchors of
    /// those whose new geometry moves.
    unanchored: Vec<u32>,
    anchored: Vec<(u32, Anchor)>,
    /// The pixels cut, and those whose geometry was settled with their fronts, when
    /// listed.
    cuts: Vec<u32>,
    settled: Vec<(u32, f32)>,
}

/// One band of rows of the cut: its rows of the accumulators (from pixel `base`'s
/// row), and its pixels' coverage and next geometry.
struct CutBand<'a> {
    /// The band's first pixel.
    base: usize,
    acc: &'a mut [f32],
    cover: &'a mut [f32],
    /// The geometry being built, [`Geo::NONE`] until a new sample lands (so that the
    /// cut finds the pixels it touches first without a pass over them all), and again
    /// once settled. A scratch band per thread, not a band of an image-sized array:
    /// the array's band was a refresh cold, and each sample's first visit a cache miss
    /// (the cut took a third longer at 640×480 and 1280×720).
    next_geo: &'a mut [Geo],
    /// The carried geometry: read while the band's samples are cut, then settled;
    /// and its [`Geo::still_z`].
    geo: &'a mut [Geo],
    still_z: &'a mut [f32],
    /// The pixels new samples landed on, each once, and the anchors of their nearest
    /// new samples where those move.
    touched: Vec<u32>,
    next_anchor: HashMap<u32, Anchor>,
    out: BandOut,
}

impl CutBand<'_> {
    /// The band's samples (with their indices in the cut, by group of pixels, each
    /// pixel's in ring order): where one lies in
    /// front of its pixel's carried sums beyond the tolerance they are cut; where
    /// behind, it is left to the visibility pass; the nearest not behind is offered as
    /// the pixel's geometry.
    fn cut_and_offer(
        &mut self,
        ctx: &CutContext<'_>,
        ks: &[(u32, Ahead)],
        ring: &super::ring::Ring,
    ) {
        let (w, cs, base) = (ctx.w, ctx.cs, self.base);
        // A pixel's row in the band, and its column.
        let row_col = |q: usize| ((q - base) / w, (q - base) % w);
        for (j, &(k, a)) in ks.iter().enumerate() {
            if let Some((_, a)) = ks.get(j + PREFETCH_AHEAD) {
                let (q, (ry, px)) = (a.q as usize, row_col(a.q as usize));
                prefetch(self.geo, q - base);
                prefetch(self.next_geo, q - base);
                prefetch(self.acc, (ry * CHANNELS + 3) * cs + px);
            }
            let (q, z) = (a.q as usize, a.z());
            let (ry, px) = row_col(q);
            let i = ctx.start + k as usize;
            let v = if a.moves() {
                ring.velocity_of(i)
            } else {
                Vec3::ZERO
            };
            let at = |ch: usize| (ry * CHANNELS + ch) * cs + px;
            let g = self.geo[q - base];
            let weight = ctx
                .late
                .map_or(self.acc[at(3)], |l| l.weight(q, self.acc[at(3)]));
            let held = g.is_some() && holds(weight);
            // Carried sums of a moving surface were placed by extrapolation: a new
            // sample at another depth wins over them either way. Still ones are
            // exact: a new sample behind them was seen through them (traced from an
            // earlier view, or what was in front has gone since), and is left to the
            // visibility pass while they decay.
            let still = g.v == Vec3::ZERO;
            if held && still && behind_front(g.z, z, ctx.keep) {
                continue;
            }
            let cut = held && (behind_front(z, g.z, ctx.keep) || behind_front(g.z, z, ctx.keep));
            if cut {
                // Something came in front.
                for ch in 0..CHANNELS {
                    self.acc[at(ch)] = 0.0;
                }
                self.cover[q - base] = 0.0;
                if ctx.list_edits {
                    self.out.cuts.push(q as u32);
                }
            }
            // Splats are centred on pixel centres; sums carried here keep their
            // position. (The sample's own sub-pixel position would scatter
            // neighbouring pixels' sums apart at the next move.)
            let (ox, oy) = if held && !cut {
                (g.ox, g.oy)
            } else {
                (0.0, 0.0)
            };
            // The nearest new sample of a pixel gives its geometry (the one the
            // visibility pass keeps), set once every sample has been tested against
            // the carried one.
            self.offer(q, k, Geo { z, ox, oy, v }, || ring.anchor_of(i));
        }
    }

    /// A new sample (index `k` of the cut) of geometry `g` lands in pixel `q`: it
    /// becomes the pixel's next geometry if it is the nearest yet, with its anchor
    /// where it moves. A pixel's first sample finds [`Geo::NONE`] there, and leaves
    /// at least [`Geo::PENDING`].
    fn offer(&mut self, q: usize, k: u32, g: Geo, anchor: impl FnOnce() -> Anchor) {
        let i = q - self.base;
        if self.next_geo[i].is_untouched() {
            self.touched.push(q as u32);
            self.next_geo[i] = Geo::PENDING;
        }
        let nearest = self.next_geo[i];
        if g.z < nearest.z {
            // Anchors are kept for moving geometry only.
            if nearest.v != Vec3::ZERO {
                self.next_anchor.remove(&(q as u32));
            }
            if g.v != Vec3::ZERO {
                self.next_anchor.insert(q as u32, anchor());
            }
            self.next_geo[i] = g;
        }
        if g.v != Vec3::ZERO {
            self.out.moving.push((k, q as u32));
        }
    }

    /// Every pixel of the band new samples landed on takes its nearest one's
    /// geometry (its next one is none again); the anchors to drop and keep go to the
    /// merge. Where edits are listed, so does each such pixel with its front depth
    /// after the carry, as [`lower_fronts`] lowers none to it, while its geometry and
    /// weight are at hand.
    fn settle(&mut self, ctx: &CutContext<'_>) {
        let (w, cs) = (ctx.w, ctx.cs);
        if ctx.list_edits {
            self.out.settled.reserve(self.touched.len());
        }
        for &q in &self.touched {
            let i = q as usize - self.base;
            if self.geo[i].v != Vec3::ZERO {
                self.out.unanchored.push(q);
            }
            let g = self.next_geo[i];
            let g = if g.is_some() { g } else { Geo::NONE };
            if g.v != Vec3::ZERO {
                if let Some(a) = self.next_anchor.remove(&q) {
                    self.out.anchored.push((q, a));
                }
            }
            self.geo[i] = g;
            self.still_z[i] = g.still_z();
            self.next_geo[i] = Geo::NONE;
            if ctx.list_edits {
                let weight = self.acc[((i / w) * CHANNELS + 3) * cs + i % w];
                let mut front = [f32::INFINITY];
                lower_fronts(&mut front, &[g.still_z()], &[weight]);
                self.out.settled.push((q, front[0]));
            }
        }
    }
}

impl Carried {
    /// How many pixels hold sums of moving surfaces.
    #[cfg(test)]
    pub(super) fn moving_count(&self) -> usize {
        self.moving.len()
    }

    /// Every pixel's kept [`Geo::still_z`] is its geometry's.
    #[cfg(test)]
    fn check_still_z(&self) {
        let wrong = (self.geo.iter().zip(&self.still_z))
            .position(|(g, z)| g.still_z().to_bits() != z.to_bits());
        assert_eq!(wrong, None, "a kept still depth is not its geometry's");
    }

    /// The bands' anchors and moving pixels, the moving ones in the order of their
    /// samples (as one pass over the samples lists them). A pixel's old anchor goes
    /// before its new one comes.
    fn merge_bands(&mut self, outs: Vec<BandOut>) {
        let mut moving = Vec::new();
        let mut anchored = Vec::new();
        for o in outs {
            if let Some(e) = &mut self.edits {
                e.cuts.extend_from_slice(&o.cuts);
                e.settled.extend_from_slice(&o.settled);
            }
            for q in o.unanchored {
                self.anchor.remove(&q);
            }
            anchored.extend(o.anchored);
            moving.extend(o.moving);
        }
        self.anchor.extend(anchored);
        moving.sort_unstable_by_key(|&(k, _)| k);
        self.moving.extend(moving.into_iter().map(|(_, q)| q));
    }
}

impl Reconstructor {
    /// Whether this refresh carries the previous one's sums.
    pub(super) fn carries_now(&self) -> bool {
        self.carried.is_some() && !self.resplat
    }

    /// Whether a refresh seen by `camera` re-splats the ring instead of carrying: with
    /// [`super::ReconParams::resplat_moving_view`], when the view is not the previous
    /// refresh's. Notes the view for the next refresh.
    pub(super) fn resplats_at(&mut self, camera: &CameraFrame) -> bool {
        let resplats = self.will_resplat(camera);
        if let Some(c) = &mut self.carried {
            c.view = Some(*camera);
        }
        resplats
    }

    /// Whether a refresh seen by `camera` will re-splat the ring
    /// ([`Reconstructor::resplats_at`], which notes the view; this does not).
    pub(super) fn will_resplat(&self, camera: &CameraFrame) -> bool {
        let p = self.params;
        let moved =
            (self.carried.as_ref()).is_some_and(|c| c.view.is_some_and(|v| !v.same_view(camera)));
        p.resplat_moving_view && p.reproject && moved
    }

    /// Whether a refresh seen by `camera` restarts the carried sums: the view holds
    /// after refreshes that re-splatted the ring, so it places, splats and cuts the
    /// whole live ring, the costliest refresh there is.
    pub fn restarts_at(&self, camera: &CameraFrame) -> bool {
        self.carried
            .as_ref()
            .is_some_and(|c| c.restart && c.view.is_some_and(|v| v.same_view(camera)))
    }

    /// After a refresh that re-splatted the ring: the next carried refresh starts
    /// from nothing, placing the whole live ring (a re-splat whose sums it carries on).
    pub(super) fn restart_carry(&mut self) {
        if let Some(c) = &mut self.carried {
            c.restart = true;
        }
    }
}

/// Where the sums of geometry `g`, showing the point fixed by `anchor`, land in the
/// view of `proj` (`w × h` pixels) with the scene `state`: where that point is seen
/// (`None`: its instance left the scene, it is behind the eye or off the image).
fn exact_target(
    state: &SceneState,
    proj: &Projector,
    anchor: Anchor,
    g: Geo,
    w: usize,
    h: usize,
) -> Option<Move> {
    let (x, y, z) = proj.project(state.anchor_position(&anchor)?);
    let (tx, ty) = pixel_at(x, y, z, w, h)?;
    Some(Move {
        to: ty * w + tx,
        tx,
        ty,
        geo: Geo {
            z,
            ox: x - tx as f32 - 0.5,
            oy: y - ty as f32 - 0.5,
            v: g.v,
        },
    })
}

/// The geometry for a pixel at `(x, y)` that holds sums but got no sample of its own:
/// that of the nearest pixel around it that has some (rings of growing distance, each
/// in row order), its offset that of `(x, y)`'s own centre, if every geometry within
/// [`BORROW_RADIUS`] lies within the depth tolerance (`keep`) of it. Beside a depth
/// edge the sums may show either surface, and moving them with the wrong one would
/// paint it over the other: they are dropped instead (`None`).
fn borrow(geo: &[Geo], w: usize, h: usize, x: usize, y: usize, keep: f32) -> Option<Geo> {
    let r = BORROW_RADIUS as usize;
    let around = |r: usize| {
        (
            x.saturating_sub(r)..=(x + r).min(w - 1),
            y.saturating_sub(r)..=(y + r).min(h - 1),
        )
    };
    // The depth range over every neighbour first: straight loops over the rows.
    let (mut near, mut far) = (f32::INFINITY, 0f32);
    let (xs, ys) = around(r);
    for ny in ys {
        for g in &geo[ny * w + xs.start()..=ny * w + xs.end()] {
            if g.is_some() {
                near = near.min(g.z);
                far = far.max(g.z);
            }
        }
    }
    if near == f32::INFINITY || behind_front(near, far, keep) {
        return None;
    }
    // Then the nearest: the first of each ring in row order (the centre has none).
    let ring = |r: usize| {
        let (xs, ys) = around(r);
        ys.flat_map(move |ny| xs.clone().map(move |nx| (nx, ny)))
            .filter(move |&(nx, ny)| nx.abs_diff(x).max(ny.abs_diff(y)) == r)
            .map(|(nx, ny)| geo[ny * w + nx])
            .find(Geo::is_some)
    };
    let g = (1..=r).find_map(ring)?;
    Some(Geo {
        ox: 0.0,
        oy: 0.0,
        ..g
    })
}

/// Sums of pixel `(x, y)` of accumulators `src` (channel stride `cs`) decayed by `k`
/// over `dt` (the weighted age grows by `dt` per unit weight first).
fn decayed(src: &[f32], cs: usize, x: usize, y: usize, k: f32, dt: f32) -> [f32; CHANNELS] {
    decayed_sums(
        std::array::from_fn(|ch| src[(y * CHANNELS + ch) * cs + x]),
        k,
        dt,
    )
}

/// One row of accumulators (`CHANNELS` runs of `cs` floats) and its coverage decayed
/// by the factors of each pixel's tile (`lookup` into `decay`: sums, coverage) over
/// `dt` (the weighted age grows by `dt` per unit weight first), [`LANES`] pixels at a
/// time: their factors gathered once, then every plane in vector code.
pub(super) fn decay_row(
    row: &mut [f32],
    cover: &mut [f32],
    cs: usize,
    lookup: &[Lookup],
    decay: &[[f32; 2]],
    dt: f32,
) {
    let w = cover.len();
    let (r, rest) = row.split_at_mut(cs);
    let (g, rest) = rest.split_at_mut(cs);
    let (b, rest) = rest.split_at_mut(cs);
    let (wp, ap) = rest.split_at_mut(cs);
    let planes = [
        &mut r[..w],
        &mut g[..w],
        &mut b[..w],
        &mut wp[..w],
        &mut ap[..w],
    ];
    let mut spans = DecaySpans { planes, cover };
    let whole = w - w % LANES;
    for x in (0..whole).step_by(LANES) {
        let l: &[Lookup; LANES] = lookup[x..x + LANES].try_into().unwrap();
        let [k, kc] = gather_decay(l, decay);
        spans.decay::<LANES>(x, &k, &kc, dt);
    }
    for x in whole..w {
        let [k, kc] = decay[lookup[x].tile as usize];
        spans.decay::<1>(x, &[k], &[kc], dt);
    }
}

/// The sum and coverage factors of `LANES` pixels from their tiles.
#[inline(always)]
fn gather_decay(lookup: &[Lookup; LANES], decay: &[[f32; 2]]) -> [Lanes; 2] {
    let (mut k, mut kc) = ([0f32; LANES], [0f32; LANES]);
    for (l, p) in lookup.iter().enumerate() {
        [k[l], kc[l]] = decay[p.tile as usize];
    }
    [k, kc]
}

/// One row's five accumulator planes (weighted r, g, b, weight, weighted age) and its
/// coverage, decayed a span at a time.
struct DecaySpans<'a> {
    planes: [&'a mut [f32]; CHANNELS],
    cover: &'a mut [f32],
}

impl DecaySpans<'_> {
    /// Pixels `x..x + N` decayed by `k` (sums) and `kc` (coverage) over `dt`.
    #[inline(always)]
    fn decay<const N: usize>(&mut self, x: usize, k: &[f32; N], kc: &[f32; N], dt: f32) {
        let [r, g, b, wp, ap] = &mut self.planes;
        let (wp, ap) = (span::<N>(wp, x), span::<N>(ap, x));
        for l in 0..N {
            ap[l] = k[l] * dt.mul_add(wp[l], ap[l]);
            wp[l] *= k[l];
        }
        for p in [r, g, b] {
            let p = span::<N>(p, x);
            for l in 0..N {
                p[l] *= k[l];
            }
        }
        let c = span::<N>(self.cover, x);
        for l in 0..N {
            c[l] *= kc[l];
        }
    }
}

/// `p[x..x + N]` as an array.
#[inline(always)]
fn span<const N: usize>(p: &mut [f32], x: usize) -> &mut [f32; N] {
    (&mut p[x..x + N]).try_into().unwrap()
}

/// The carry's decay of a refresh on the CPU that keeps its view, left for the splat's
/// band pass to apply as it brings each band of sums into the cache: decayed in a pass
/// of its own, every pixel's sums and coverage went to memory and back (about 3 ms of
/// a 1280×720 image live). Until then every step that reads the sums reads them
/// decayed, with the same operations: the moves decay what they take and the pixels
/// they land in (those are decayed at once and flagged, and the band pass leaves
/// them), and the cut and the fronts read each weight times its pixel's factor.
pub(super) struct LateDecay {
    /// `[sums, coverage]` factor of each tile ([`Reconstructor::tile_decay`]).
    factors: Vec<[f32; 2]>,
    dt: f32,
    /// The pixels decayed already, in pixel order once the moves are done.
    early: Vec<u32>,
    /// Whether each pixel is decayed already.
    flags: Vec<bool>,
    /// The least and the largest sums factor of any tile.
    k_range: (f32, f32),
}

/// A [`LateDecay`] with the per-pixel tile lookup it reads its factors through.
#[derive(Clone, Copy)]
pub(super) struct DecayView<'a> {
    late: &'a LateDecay,
    lookup: &'a [Lookup],
}

impl LateDecay {
    /// `flags`: those of the last one ([`LateDecay::into_flags`]), or none yet.
    fn new(factors: &[[f32; 2]], dt: f32, mut flags: Vec<bool>, pixels: usize) -> Self {
        flags.resize(pixels, false);
        let k = factors.iter().map(|f| f[0]);
        let k_range = (
            k.clone().fold(f32::INFINITY, f32::min),
            k.fold(0.0, f32::max),
        );
        Self {
            factors: factors.to_vec(),
            dt,
            early: Vec::new(),
            flags,
            k_range,
        }
    }

    /// Its per-pixel flags, all cleared, for the next one: allocating and zeroing
    /// them at every refresh cost more than clearing the few it set.
    pub(super) fn into_flags(mut self) -> Vec<bool> {
        for &q in &self.early {
            self.flags[q as usize] = false;
        }
        self.flags
    }

    /// `[sums, coverage]` factor of pixel `q`.
    fn factor(&self, lookup: &[Lookup], q: usize) -> [f32; 2] {
        self.factors[lookup[q].tile as usize]
    }

    /// Decay pixel `q` at `(x, y)` of `into` now (a landing's pixel, before the sums
    /// land), unless it is already.
    fn decay_now(
        &mut self,
        lookup: &[Lookup],
        into: &mut Target,
        (q, x, y): (usize, usize, usize),
    ) {
        if std::mem::replace(&mut self.flags[q], true) {
            return;
        }
        self.early.push(q as u32);
        let [k, kc] = self.factor(lookup, q);
        let sums = decayed(into.acc, into.cs, x, y, k, self.dt);
        for (ch, v) in sums.into_iter().enumerate() {
            into.acc[(y * CHANNELS + ch) * into.cs + x] = v;
        }
        into.cover[q] *= kc;
    }
}

impl<'a> DecayView<'a> {
    pub(super) fn new(late: &'a LateDecay, lookup: &'a [Lookup]) -> Self {
        Self { late, lookup }
    }

    /// Pixel `q`'s weight `raw` as decayed.
    fn weight(self, q: usize, raw: f32) -> f32 {
        if self.late.flags[q] {
            raw
        } else {
            self.late.factor(self.lookup, q)[0] * raw
        }
    }

    /// The rows from `y0` of a band (`acc`: rows of `CHANNELS` runs of `cs` floats;
    /// `cover`: rows of `w`) decayed, but for the pixels decayed already.
    pub(super) fn band(
        self,
        (acc, cover): (&mut [f32], &mut [f32]),
        y0: usize,
        (w, cs): (usize, usize),
    ) {
        let rows = cover.len() / w;
        let early = &self.late.early;
        let (q0, q1) = (y0 * w, (y0 + rows) * w);
        let first = |p: usize| early.partition_point(|&q| (q as usize) < p);
        let run = &early[first(q0)..first(q1)];
        let at = |q: usize, ch: usize| ((q / w - y0) * CHANNELS + ch) * cs + q % w;
        let kept: Vec<([f32; CHANNELS], f32)> = run
            .iter()
            .map(|&q| {
                let q = q as usize;
                (std::array::from_fn(|ch| acc[at(q, ch)]), cover[q - q0])
            })
            .collect();
        let (factors, dt) = (&self.late.factors, self.late.dt);
        for r in 0..rows {
            let lookup = &self.lookup[(y0 + r) * w..][..w];
            let row = &mut acc[r * CHANNELS * cs..][..CHANNELS * cs];
            decay_row(row, &mut cover[r * w..][..w], cs, lookup, factors, dt);
        }
        for (&q, (sums, c)) in run.iter().zip(kept) {
            let q = q as usize;
            for (ch, v) in sums.into_iter().enumerate() {
                acc[at(q, ch)] = v;
            }
            cover[q - q0] = c;
        }
    }
}

/// Sums `s` decayed by `k` over `dt`, with the operations of [`decay_row`].
fn decayed_sums(s: [f32; CHANNELS], k: f32, dt: f32) -> [f32; CHANNELS] {
    let mut out = s.map(|v| v * k);
    out[4] = k * dt.mul_add(s[3], s[4]);
    out
}

/// The accumulators, geometry and coverage that carried sums land in.
struct Target<'a> {
    acc: &'a mut [f32],
    cs: usize,
    geo: &'a mut [Geo],
    /// The geometry's [`Geo::still_z`], where it is kept as the geometry lands
    /// (`None`: made afresh after every landing).
    still_z: Option<&'a mut [f32]>,
    cover: &'a mut [f32],
}

impl Target<'_> {
    /// [`Target::land`] the sums of move `m`; if they stayed and move, `m.to` is
    /// listed in `moving`.
    fn land_move(
        &mut self,
        m: &Move,
        sums: [f32; CHANNELS],
        cover: f32,
        keep: f32,
        moving: &mut Vec<u32>,
    ) {
        if self.land(m, sums, cover, keep).is_some() && m.geo.v != Vec3::ZERO {
            moving.push(m.to as u32);
        }
    }

    /// Sums `sums` with coverage `cover` arrive by move `m`: an
    /// empty pixel takes them; otherwise the nearer wins, and both merge within the
    /// depth tolerance (`keep`). How they stayed (`None`: they did not).
    fn land(&mut self, m: &Move, sums: [f32; CHANNELS], cover: f32, keep: f32) -> Option<Landed> {
        let (to, tx, ty, g) = (m.to, m.tx, m.ty, m.geo);
        let at = |ch: usize| (ty * CHANNELS + ch) * self.cs + tx;
        let old = self.geo[to];
        let mut merge = false;
        if holds(self.acc[at(3)]) {
            if behind_front(old.z, g.z, keep) {
                return None;
            }
            merge = !behind_front(g.z, old.z, keep);
        }
        for (ch, &v) in sums.iter().enumerate() {
            let d = &mut self.acc[at(ch)];
            *d = if merge { *d + v } else { v };
        }
        let c = &mut self.cover[to];
        *c = if merge { *c + cover } else { cover };
        let took_geometry = !(merge && old.z <= g.z);
        if took_geometry {
            self.geo[to] = g;
            if let Some(z) = &mut self.still_z {
                z[to] = g.still_z();
            }
        }
        Some(Landed {
            merged: merge,
            took_geometry,
        })
    }
}

/// How carried sums stayed where they landed.
#[derive(Clone, Copy)]
struct Landed {
    /// Added to the sums the pixel held (else they replaced them).
    merged: bool,
    /// The pixel took their geometry.
    took_geometry: bool,
}

impl Reconstructor {
    /// With the visibility pass: each pixel's front depth, the nearest `z_front` of the
    /// splats binned at this refresh that land in it ([`super::splat::front_band`])
    /// and, when carrying (after the carry), of the still geometry carried there
    /// ([`carried_fronts`]), bands in parallel.
    pub(super) fn front_depths(&mut self) {
        if self.visibility_keep().is_none() {
            return;
        }
        let (w, h) = (self.width as usize, self.height as usize);
        let (binned, rows) = (&self.binned[..self.pieces], self.band_rows);
        let carried = self.carried.as_deref().filter(|_| self.carries_now());
        let sums = (&self.acc[..], w, self.cs);
        let late = (self.late_decay.as_ref()).map(|l| DecayView::new(l, &self.lookup));
        self.front.resize(h * w, f32::INFINITY);
        self.front
            .par_chunks_mut(rows * w)
            .enumerate()
            .for_each_init(Vec::new, |weights, (b, front)| {
                match (carried, late) {
                    (Some(c), Some(l)) => {
                        late_carried_fronts(c, (sums, l, weights), b * rows, front)
                    }
                    (Some(c), None) => carried_fronts(c, sums, b * rows, front),
                    (None, _) => front.fill(f32::INFINITY),
                }
                super::splat::front_band(binned, b, b * rows, w, front);
            });
        match self.front_spread() {
            Some(ratio) => {
                let footprint = self.spread_test().2.is_some();
                self.spread.apply(&mut self.front, w, ratio, footprint)
            }
            None => self.spread.clear(),
        }
    }
}

/// With the visibility pass, the carried geometry of still surfaces is a front too
/// (moving ones are placed by extrapolation, and do not hide what new samples show),
/// so that a new sample seen through what is carried (traced from an earlier view) is
/// not splatted over it: the fronts of `out`'s rows (from row `y0`, `w` pixels each)
/// start from it where the accumulators `acc` (channel stride `cs`) hold sums, else
/// from none. The new splats' fronts are lowered into them after
/// ([`Reconstructor::front_depths`]): a minimum, so the order does not matter.
pub(super) fn carried_fronts(
    c: &Carried,
    (acc, w, cs): (&[f32], usize, usize),
    y0: usize,
    out: &mut [f32],
) {
    for (r, row) in out.chunks_mut(w).enumerate() {
        let (y, q) = (y0 + r, (y0 + r) * w);
        row.fill(f32::INFINITY);
        let weight = &acc[(y * CHANNELS + 3) * cs..][..w];
        lower_fronts(row, &c.still_z[q..q + w], weight);
    }
}

/// [`carried_fronts`] with the decay left to the splat (`late`): each row's weights
/// decayed first, into `weights`. Only whether a weight holds sums matters here, so a
/// weight that holds even at the least factor of any tile is kept as it is, one that
/// does not even at the largest becomes 0 (a product is monotonic in each factor),
/// in vector code; only the few in between, and the pixels decayed already, look up
/// their own factor.
fn late_carried_fronts(
    c: &Carried,
    ((acc, w, cs), late, weights): ((&[f32], usize, usize), DecayView<'_>, &mut Vec<f32>),
    y0: usize,
    out: &mut [f32],
) {
    weights.resize(w, 0.0);
    let (k_min, k_max) = late.late.k_range;
    for (r, row) in out.chunks_mut(w).enumerate() {
        let (y, q) = (y0 + r, (y0 + r) * w);
        row.fill(f32::INFINITY);
        let raw = &acc[(y * CHANNELS + 3) * cs..][..w];
        let flags = &late.late.flags[q..q + w];
        // Whether weight `v` holds at every factor, and whether it needs its own.
        let decide = |v: f32, early: bool| {
            let (sure, never) = (holds(v * k_min), !holds(v * k_max));
            (sure, early | !(sure | never))
        };
        let mut unsure = false;
        for ((d, &v), &early) in weights.iter_mut().zip(raw).zip(flags) {
            let (sure, own) = decide(v, early);
            *d = if sure { v } else { 0.0 };
            unsure |= own;
        }
        if unsure {
            for (x, (d, &v)) in weights.iter_mut().zip(raw).enumerate() {
                if decide(v, flags[x]).1 {
                    *d = late.weight(q + x, v);
                }
            }
        }
        lower_fronts(row, &c.still_z[q..q + w], weights);
    }
}

impl Reconstructor {
    /// The decay left to the splat ([`LateDecay`]) applied to every pixel now, if one
    /// is pending (a refresh whose splat did not run).
    pub(super) fn flush_late_decay(&mut self) {
        if let Some(l) = self.late_decay.take() {
            let (w, cs) = (self.width as usize, self.cs);
            let view = DecayView::new(&l, &self.lookup);
            view.band((&mut self.acc, &mut self.cover), 0, (w, cs));
            self.late_flags = l.into_flags();
        }
    }

    /// [`carried_fronts`] over no new splat, as the shaders store it
    /// ([`super::gpu::carried::front_bit`]), into `bits`: each row lowered a few pixels
    /// at a time on the stack, so that no image of f32 fronts is filled, lowered and
    /// read again on the way (the GPU's initial front depths).
    #[cfg(feature = "gpu")]
    pub(super) fn carried_front_bits(&self, bits: &mut Vec<u32>) {
        bits.resize(self.cover.len(), 0);
        let (w, cs) = (self.width as usize, self.cs);
        let Some(c) = &self.carried else {
            bits.fill(0);
            return;
        };
        bits.par_chunks_mut(w)
            .zip(c.still_z.par_chunks(w))
            .enumerate()
            .for_each(|(y, (row, z))| {
                lowered_front_bits(row, z, &self.acc[(y * CHANNELS + 3) * cs..][..w]);
            });
    }
}

/// The front bits of [`Reconstructor::carried_front_bits`] brought up to date in
/// `kept`, which held them for the carried state of the last refresh, where only the
/// pixels `settled` (with their fronts now) and `dirty` (any order, repeats allowed)
/// may have changed since (their weight's holding or their geometry): the dirty ones
/// recomputed by the same rule, and each listed in `changes` as `[pixel, bits]` where
/// it differs.
#[cfg(feature = "gpu")]
pub(super) fn changed_front_bits(
    c: &Carried,
    (acc, w, cs): (&[f32], usize, usize),
    (settled, dirty): (&[(u32, f32)], impl Iterator<Item = u32>),
    kept: &mut [u32],
    changes: &mut Vec<[u32; 2]>,
) {
    changes.clear();
    for &(q, z) in settled {
        let bits = super::gpu::carried::front_bit(z);
        if kept[q as usize] != bits {
            kept[q as usize] = bits;
            changes.push([q, bits]);
        }
    }
    for q in dirty {
        let p = q as usize;
        let weight = acc[((p / w) * CHANNELS + 3) * cs + p % w];
        let mut bits = [0];
        lowered_front_bits(&mut bits, &c.still_z[p..p + 1], &[weight]);
        if kept[p] != bits[0] {
            kept[p] = bits[0];
            changes.push([q, bits[0]]);
        }
    }
}

/// The bits ([`super::gpu::carried::front_bit`]) of fronts that start infinite and are
/// lowered by [`lower_fronts`] to `still_z` where `weight` holds sums.
#[cfg(feature = "gpu")]
pub(super) fn lowered_front_bits(bits: &mut [u32], still_z: &[f32], weight: &[f32]) {
    for ((b, g), wt) in bits
        .chunks_mut(LANES)
        .zip(still_z.chunks(LANES))
        .zip(weight.chunks(LANES))
    {
        let mut front = [f32::INFINITY; LANES];
        let front = &mut front[..b.len()];
        lower_fronts(front, g, wt);
        for (b, &z) in b.iter_mut().zip(&*front) {
            *b = super::gpu::carried::front_bit(z);
        }
    }
}

/// Fronts `front` lowered to the depths of still geometry `still_z` ([`Geo::still_z`],
/// infinite where none or moving) of the pixels whose `weight` holds sums, [`LANES`]
/// pixels at a time without branches. (A front is never NaN: it starts infinite and
/// is lowered to depths, so lowering it to an infinite one leaves it as it was.)
pub(super) fn lower_fronts(front: &mut [f32], still_z: &[f32], weight: &[f32]) {
    for ((f, z), wt) in front
        .chunks_mut(LANES)
        .zip(still_z.chunks(LANES))
        .zip(weight.chunks(LANES))
    {
        for l in 0..f.len() {
            let lowered = f[l].min(z[l]);
            f[l] = if holds(wt[l]) { lowered } else { f[l] };
        }
    }
}

/// Whether an accumulated weight holds sums (a NaN weight does not).
fn holds(weight: f32) -> bool {
    weight >= MIN_WEIGHT
}

/// The pixel a point at `(x, y)` and depth `z` in front of the eye lies in, on a
/// `w × h` image.
fn pixel_at(x: f32, y: f32, z: f32, w: usize, h: usize) -> Option<(usize, usize)> {
    let inside = z > 1e-6 && x >= 0.0 && y >= 0.0 && x < w as f32 && y < h as f32;
    inside.then_some((x as usize, y as usize))
}

#[cfg(test)]
#[path = "carry_cut_tests.rs"]
mod cut_tests;

#[cfg(test)]
mod order_tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// The cut's order is a stable sort by group of pixels of the samples on the
        /// image, and the starts bound each group's run.
        #[test]
        fn the_cut_visits_samples_by_group_each_pixel_in_ring_order(
            pixels in prop::collection::vec((0u32..37, 0u32..11, any::<bool>()), 0..300),
        ) {
            let w = 37;
            let groups = (w * 11usize).div_ceil(GROUP);
            let ahead: Vec<Ahead> = pixels
                .iter()
                .map(|&(px, py, on)| if on { Ahead::new(py as usize * w + px as usize, 1.0, px % 3 == 0) } else { Ahead::OFF })
                .collect();
            let group = |a: &Ahead| a.q as usize / GROUP;
            let mut want: Vec<(u32, Ahead)> = ahead.iter().copied().enumerate()
                .filter(|(_, a)| a.is_on())
                .map(|(k, a)| (k as u32, a))
                .collect();
            want.sort_by_key(|(_, a)| group(a));
            let (mut starts, mut sorted) = (Vec::new(), Vec::new());
            sort_by_group(&ahead, groups, &mut starts, &mut sorted);
            prop_assert_eq!(&sorted, &want);
            prop_assert_eq!(starts.len(), groups + 1);
            for g in 0..groups {
                let run = &sorted[starts[g] as usize..starts[g + 1] as usize];
                prop_assert!(run.iter().all(|(_, a)| group(a) == g));
            }
        }
    }
}

#[cfg(test)]
mod locate_tests {
    use super::*;
    use crate::{
        reconstruction::{ReconParams, RingSample},
        scene::Camera,
    };

    /// Where the sample of logical index `i` lands, one sample at a time: its pixel,
    /// depth and velocity.
    fn one(r: &Reconstructor, t: f64, proj: &Projector, i: usize) -> (u32, f32, Vec3) {
        let s = r.ring.get(i).unwrap();
        let dt = (t - s.t) as f32;
        let (x, y, z) = proj.project(s.hit_point + s.velocity * dt);
        match pixel_at(x, y, z, r.width as usize, r.height as usize) {
            Some((px, py)) => ((py * r.width as usize + px) as u32, z, s.velocity),
            None => (u32::MAX, 0.0, Vec3::ZERO),
        }
    }

    #[test]
    fn new_samples_land_where_each_projects_across_the_ring_wrap_and_chunks() {
        let (w, h) = (100u32, 100u32);
        let params = ReconParams {
            ring_factor: 2.0,
            ..ReconParams::realtime()
        };
        let mut r = Reconstructor::new(w, h, 1e6, params);
        let cam = Camera {
            eye: Vec3::new(0.0, 0.0, 3.0),
            at: Vec3::ZERO,
            up: Vec3::Y,
            fov_y_deg: 60.0,
            hither: 1e-3,
        }
        .frame(w, h);
        let mut rng = crate::sampling::Rng::new(&[7]);
        let mut u = || rng.uniform() * 2.0 - 1.0;
        // Past the capacity (20 000), so that the live samples wrap around the slots.
        for k in 0..27_000 {
            r.push(RingSample {
                x: 0.0,
                y: 0.0,
                t: k as f64 * 1e-4,
                color: Vec3::ONE,
                hit_point: Vec3::new(u() * 1.5, u() * 1.5, u()),
                velocity: if k % 3 == 0 {
                    Vec3::new(u(), u(), u())
                } else {
                    Vec3::ZERO
                },
                anchor: Default::default(),
            });
        }
        let (t, proj, n) = (2.8, Projector::new(&cam), r.ring.len());
        let mut ahead = Vec::new();
        for start in [0, 5, 12_345, n - 3, n] {
            r.located_from = None;
            r.locate_new(t, &cam, start..n, &mut ahead);
            assert_eq!(ahead.len(), n - start);
            for (k, a) in ahead.iter().enumerate() {
                let want = one(&r, t, &proj, start + k);
                assert_eq!(
                    (a.q, a.z().to_bits(), a.moves()),
                    (want.0, want.1.to_bits(), want.2 != Vec3::ZERO),
                    "start {start}, sample {k}"
                );
                if a.is_on() {
                    assert_eq!(r.ring.velocity_of(start + k), want.2);
                }
            }
            // Where the place pass located them, that is read instead.
            r.located = (start..n)
                .map(|i| [(i % w as usize) as f32 + 0.5, 7.5, i as f32 + 1.0])
                .collect();
            r.located_from = Some(start);
            r.locate_new(t, &cam, start..n, &mut ahead);
            for (k, a) in ahead.iter().enumerate() {
                let i = start + k;
                let moves = r.ring.velocity_of(i) != Vec3::ZERO;
                assert_eq!(
                    (a.q as usize, a.z(), a.moves()),
                    (7 * w as usize + i % w as usize, i as f32 + 1.0, moves)
                );
            }
        }
    }
}
