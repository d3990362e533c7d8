//! The visibility pass's fronts spread while the view moves
//! ([`super::Visibility::moving_view_spread`]): a near surface the view has just
//! brought in has few samples yet, and a far surface seen before shows through it
//! where they have not landed. Each pixel's front also becomes the ratio times the
//! nearest of its eight neighbours', and a far sample behind that is hidden, but only
//! where the view's motion since the sample was traced moved it across the near
//! surface: the point at the near depth on the ray it was traced along now lies at
//! least [`super::Visibility::spread_parallax`] pixels from it. A far sample with less
//! parallax was traced past the near surface's edge, where it still is, and shows what
//! is beside it (the sky above a horizon of grass, the floor beside a table), however
//! the view turned since.

use std::collections::VecDeque;

use glam::Vec3;
use rayon::prelude::*;

use super::splat::{behind_front, HidesSplat, Splat};
use crate::scene::CameraFrame;

/// The spread fronts' state, kept across refreshes so its allocations are reused.
#[derive(Default)]
pub(super) struct Spread {
    /// Each pixel's own front, before the spread.
    own: Vec<f32>,
    /// The rows' nearest fronts over each pixel and its two row neighbours.
    minima: Vec<f32>,
    /// The fronts were spread at the last refresh (else `own` is stale).
    active: bool,
    /// With a footprint's spread ([`super::Visibility::footprint_spread`]): the own
    /// fronts' nearest over blocks of 2×2, 4×4, … pixels, level by level.
    levels: Vec<FrontLevel>,
    /// Pixels a row.
    width: usize,
}

/// A level of the own fronts' pyramid: each block's nearest front.
#[derive(Default)]
struct FrontLevel {
    w: usize,
    near: Vec<f32>,
}

impl Spread {
    /// Lower each of the fronts (`w` pixels a row) to `ratio` times the nearest of
    /// its eight neighbours' (`ratio` ≥ 1, so a pixel's own front is never raised),
    /// keeping the own fronts: a near surface's front reaches the pixels around where
    /// its samples landed. A separable minimum through the rows' three-pixel minima,
    /// rows in parallel; the result does not depend on the bands.
    pub(super) fn apply(&mut self, front: &mut [f32], w: usize, ratio: f32, footprint: bool) {
        self.active = true;
        self.own.clear();
        self.own.extend_from_slice(front);
        self.width = w;
        self.levels.clear();
        if w == 0 || front.is_empty() {
            return;
        }
        if footprint {
            self.pyramid(front.len() / w);
        }
        self.minima.resize(front.len(), f32::INFINITY);
        self.minima
            .par_chunks_mut(w)
            .zip(front.par_chunks(w))
            .for_each(|(m, row)| row_minima(row, m));
        let (minima, rows) = (&self.minima[..], front.len() / w);
        front.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            let near = |dy: usize| &minima[dy * w..(dy + 1) * w];
            let (up, down) = (near(y.saturating_sub(1)), near((y + 1).min(rows - 1)));
            for (((f, a), b), c) in row.iter_mut().zip(up).zip(near(y)).zip(down) {
                *f = f.min(ratio * a.min(*b).min(*c));
            }
        });
    }

    /// The own fronts of the last spread.
    #[cfg(test)]
    pub(super) fn own_fronts(&self) -> &[f32] {
        &self.own
    }

    /// The own fronts' pyramid over an image `h` rows high: level after level, each
    /// block the nearest of the four below it (those inside the level), until one
    /// block is left (the GPU's pull pyramid's levels).
    fn pyramid(&mut self, h: usize) {
        let (mut w, mut h) = (self.width, h);
        while w > 1 || h > 1 {
            let (nw, nh) = (w.div_ceil(2), h.div_ceil(2));
            let below = self.levels.last().map_or(&self.own[..], |l| &l.near[..]);
            let mut near = vec![f32::INFINITY; nw * nh];
            near.par_chunks_mut(nw).enumerate().for_each(|(y, row)| {
                for dy in (2 * y..(2 * y + 2).min(h)).map(|r| &below[r * w..(r + 1) * w]) {
                    for (x, n) in row.iter_mut().enumerate() {
                        *n = n.min(dy[2 * x]);
                        if 2 * x + 1 < w {
                            *n = n.min(dy[2 * x + 1]);
                        }
                    }
                }
            });
            self.levels.push(FrontLevel { w: nw, near });
            (w, h) = (nw, nh);
        }
    }

    /// No spread at this refresh.
    pub(super) fn clear(&mut self) {
        self.active = false;
    }

    /// The view a splat's test reads, if the fronts were spread at this refresh.
    pub(super) fn view<'a>(&'a self, at: Viewpoint<'a>) -> Option<SpreadView<'a>> {
        self.active.then_some(SpreadView {
            own: &self.own,
            width: self.width,
            levels: &self.levels,
            at,
        })
    }
}

/// Each pixel's minimum over itself and its left and right neighbours (the ends over
/// the two they have), the inside as whole slices so that it runs in vector code.
fn row_minima(row: &[f32], out: &mut [f32]) {
    let n = row.len();
    if n < 2 {
        out.copy_from_slice(row);
        return;
    }
    out[0] = row[0].min(row[1]);
    out[n - 1] = row[n - 2].min(row[n - 1]);
    let inside = row[..n - 2].iter().zip(&row[1..n - 1]).zip(&row[2..]);
    for (o, ((l, c), r)) in out[1..n - 1].iter_mut().zip(inside) {
        *o = l.min(*c).min(*r);
    }
}

/// Where the eye was at each recent refresh, as offsets in seconds from the newest
/// (the samples' ages) and positions, oldest first: where the eye was when a sample
/// was traced, interpolated between refreshes.
#[derive(Clone, Debug, Default)]
pub struct EyeTrack {
    /// `(time, eye)` of the refreshes, oldest first, at most [`EyeTrack::KEPT`].
    refreshes: VecDeque<(f64, Vec3)>,
}

impl EyeTrack {
    /// Refreshes kept: at 60 Hz, about 17 seconds, beyond which a sample's eye is taken
    /// as the oldest kept.
    pub const KEPT: usize = 1024;

    /// Record the eye of the refresh at `t` (a refresh at an earlier time than the last
    /// starts the track afresh).
    pub(super) fn push(&mut self, t: f64, eye: Vec3) {
        if self.refreshes.back().is_some_and(|&(last, _)| t < last) {
            self.refreshes.clear();
        }
        if self.refreshes.len() == Self::KEPT {
            self.refreshes.pop_front();
        }
        self.refreshes.push_back((t, eye));
    }

    /// The track as `(age, eye)` relative to the newest refresh (ages ≥ 0, newest
    /// first), the form both devices interpolate.
    pub fn ages(&self) -> Vec<(f32, Vec3)> {
        let Some(&(now, _)) = self.refreshes.back() else {
            return Vec::new();
        };
        let ages = self.refreshes.iter().rev();
        ages.map(|&(t, e)| ((now - t) as f32, e)).collect()
    }
}

/// The eye at a sample's age `age` (seconds before the newest refresh) on a track of
/// `(age, eye)` newest first ([`EyeTrack::ages`]): linear between the two refreshes
/// around it, the newest's or the oldest's beyond them.
pub(super) fn eye_at(track: &[(f32, Vec3)], age: f32) -> Vec3 {
    let newer = track.partition_point(|&(a, _)| a <= age);
    match (newer.checked_sub(1).map(|i| track[i]), track.get(newer)) {
        (Some((a0, e0)), Some(&(a1, e1))) => e0 + (e1 - e0) * ((age - a0) / (a1 - a0)),
        (Some((_, e)), None) | (None, Some(&(_, e))) => e,
        (None, None) => Vec3::ZERO,
    }
}

/// The footprint's spread ([`super::Visibility::footprint_spread`]): its ratio, its
/// parallax and its reach (pixels).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct FootprintTest {
    pub(super) ratio: f32,
    pub(super) parallax: f32,
    pub(super) reach: f32,
}

/// What the parallax test needs of this refresh: its camera, the eye's track, and the
/// spread's ratio and parallax (pixels).
#[derive(Clone, Copy)]
pub(super) struct Viewpoint<'a> {
    pub(super) camera: &'a CameraFrame,
    pub(super) track: &'a [(f32, Vec3)],
    pub(super) ratio: f32,
    pub(super) parallax: f32,
    /// [`super::Visibility::footprint_spread`], its parallax and its reach.
    pub(super) footprint: Option<FootprintTest>,
}

impl<'a> Viewpoint<'a> {
    /// The viewpoint of `camera` with the eye's `track` and the tests
    /// `(ratio, parallax, footprint)` ([`super::Reconstructor::spread_test`]).
    pub(super) fn new(
        camera: &'a CameraFrame,
        track: &'a [(f32, Vec3)],
        (ratio, parallax, footprint): (f32, f32, Option<FootprintTest>),
    ) -> Self {
        Self {
            camera,
            track,
            ratio,
            parallax,
            footprint,
        }
    }

    /// How far, in pixels, the view's motion since a point was traced has moved it
    /// from the point at depth `near` on the ray it was traced along, the point now
    /// at `(x, y)` and depth `z`, traced `age` seconds ago. Infinite where that ray
    /// never reaches the near depth in front of the eye.
    pub(super) fn parallax_of(&self, (x, y, z): (f32, f32, f32), age: f32, near: f32) -> f32 {
        let c = self.camera;
        let p = c.eye + (c.corner + c.du * x + c.dv * y) * z;
        let from = eye_at(self.track, age);
        let along = (p - from).dot(c.forward);
        let reach = (near - (from - c.eye).dot(c.forward)) / along;
        if along <= 0.0 || reach.is_nan() || reach <= 0.0 {
            return f32::INFINITY;
        }
        match c.project(from + (p - from) * reach) {
            Some((nx, ny, _)) => (nx - x).hypot(ny - y),
            None => f32::INFINITY,
        }
    }
}

/// The pyramid level whose blocks (16 pixels a side) a footprint's spread first looks
/// into: small enough to stay in the cache.
const COARSE: usize = 4;

/// What a splat's visibility test reads while the fronts are spread.
#[derive(Clone, Copy)]
pub(super) struct SpreadView<'a> {
    own: &'a [f32],
    width: usize,
    levels: &'a [FrontLevel],
    at: Viewpoint<'a>,
}

impl HidesSplat for SpreadView<'_> {
    /// Whether splat `s`, landing in a pixel whose spread front is `front`, is hidden:
    /// behind its pixel's own front, or behind the spread one with the parallax
    /// that moved it there (`keep`: `1 / (1 + tolerance)`).
    #[inline(always)]
    fn hides(&self, s: &Splat, front: f32, keep: f32) -> bool {
        let p = s.pixel as usize;
        if behind_front(self.own[p], s.z, keep) {
            return true;
        }
        let age = || s.c[4] / s.c[3];
        let at = (s.x, s.y, s.z);
        if behind_front(front, s.z, keep)
            && self.at.parallax_of(at, age(), front / self.at.ratio) >= self.at.parallax
        {
            return true;
        }
        self.at
            .footprint
            .is_some_and(|f| self.footprint_hides(s, f, keep, age))
    }
}

impl SpreadView<'_> {
    /// Whether a front `f.ratio` times nearer than splat `s` lies in its footprint's
    /// box widened by the pixels the view's motion carried it across that front (at
    /// most `f.reach`), with that motion `f.parallax` pixels or more: a near surface
    /// whose few samples landed that far away may have slid over it since.
    fn footprint_hides(
        &self,
        s: &Splat,
        f: FootprintTest,
        keep: f32,
        age: impl Fn() -> f32,
    ) -> bool {
        // Behind a front the ratio times nearer than `near`.
        let far_behind = |near: f32| behind_front(f.ratio * near, s.z, keep);
        let wide = self.widened(s, f.reach as usize);
        // A box within the landing pixel's eight neighbours is the spread's.
        let [x0, x1, y0, y1] = wide;
        let (px, py) = (s.x as usize, s.y as usize);
        if x0 + 1 >= px && x1 <= px + 1 && y0 + 1 >= py && y1 <= py + 1 {
            return false;
        }
        // The nearest front over 16-pixel blocks around the box is at most the
        // box's: a splat nearer than the ratio times it is kept at once.
        if !far_behind(self.nearest_around(wide)) {
            return false;
        }
        let near = self.nearest_in(wide);
        if !far_behind(near) {
            return false;
        }
        let moved = self.at.parallax_of((s.x, s.y, s.z), age(), near);
        if moved < f.parallax {
            return false;
        }
        // Carried less far than the reach: only fronts that near count.
        moved >= f.reach || far_behind(self.nearest_in(self.widened(s, moved as usize)))
    }

    /// Splat `s`'s footprint box widened by `by` pixels each way, within the image.
    fn widened(&self, s: &Splat, by: usize) -> [usize; 4] {
        let h = self.own.len() / self.width;
        [
            usize::from(s.x0).saturating_sub(by),
            (usize::from(s.x1) + by).min(self.width - 1),
            usize::from(s.y0).saturating_sub(by),
            (usize::from(s.y1) + by).min(h - 1),
        ]
    }

    /// The nearest own front over the blocks of level [`COARSE`] that the box `[x0, x1,
    /// y0, y1]` touches where it spans two of them or fewer each way (so that
    /// [`SpreadView::nearest_in`] reads blocks inside them), else −∞: never farther than
    /// [`SpreadView::nearest_in`]'s.
    #[inline(always)]
    fn nearest_around(&self, [x0, x1, y0, y1]: [usize; 4]) -> f32 {
        let k = COARSE;
        let Some(l) = self.levels.get(k - 1) else {
            return f32::NEG_INFINITY;
        };
        if (x1 >> k) - (x0 >> k) > 1 || (y1 >> k) - (y0 >> k) > 1 {
            return f32::NEG_INFINITY;
        }
        let at = |x: usize, y: usize| l.near[(y >> k) * l.w + (x >> k)];
        at(x0, y0).min(at(x1, y0)).min(at(x0, y1)).min(at(x1, y1))
    }

    /// The nearest own front over the box `[x0, x1, y0, y1]` (inclusive) and the
    /// pixels around it: over the at most 2×2 blocks of the lowest level (the own
    /// fronts first) in which the box spans two blocks or fewer each way.
    fn nearest_in(&self, [mut x0, mut x1, mut y0, mut y1]: [usize; 4]) -> f32 {
        let (mut near, mut w) = (self.own, self.width);
        let mut up = self.levels.iter();
        while x1 - x0 > 1 || y1 - y0 > 1 {
            let Some(l) = up.next() else {
                break;
            };
            (near, w) = (&l.near[..], l.w);
            [x0, x1, y0, y1] = [x0, x1, y0, y1].map(|v| v >> 1);
        }
        let at = |x: usize, y: usize| near[y * w + x];
        at(x0, y0).min(at(x1, y0)).min(at(x0, y1)).min(at(x1, y1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Camera;

    fn looking(eye: Vec3, at: Vec3) -> CameraFrame {
        Camera {
            eye,
            at,
            up: Vec3::Y,
            fov_y_deg: 60.0,
            hither: 1e-3,
        }
        .frame(64, 64)
    }

    /// The parallax test's viewpoint of `camera` with the eye's `track`.
    fn viewpoint<'a>(camera: &'a CameraFrame, track: &'a [(f32, Vec3)]) -> Viewpoint<'a> {
        Viewpoint::new(camera, track, (3.0, 2.0, None))
    }

    #[test]
    fn the_eye_of_a_sample_is_interpolated_between_refreshes() {
        let mut track = EyeTrack::default();
        for k in 0..4 {
            track.push(k as f64 * 0.1, Vec3::new(k as f32, 0.0, 0.0));
        }
        let ages = track.ages();
        assert_eq!(ages.len(), 4);
        let x = |age: f32| eye_at(&ages, age).x;
        assert!((x(0.05) - 2.5).abs() < 1e-4, "{}", x(0.05));
        assert!((x(0.25) - 0.5).abs() < 1e-4, "{}", x(0.25));
        assert_eq!((x(0.0), x(-1.0), x(9.0)), (3.0, 3.0, 0.0));
        // A refresh earlier than the last starts the track afresh; it keeps a bounded
        // number of refreshes.
        track.push(0.05, Vec3::ONE);
        assert_eq!(track.ages(), vec![(0.0, Vec3::ONE)]);
        for k in 0..2 * EyeTrack::KEPT {
            track.push(1.0 + k as f64, Vec3::ZERO);
        }
        assert_eq!(track.ages().len(), EyeTrack::KEPT);
        assert_eq!(eye_at(&[], 1.0), Vec3::ZERO);
    }

    #[test]
    fn a_turn_moves_nothing_across_a_near_surface_and_a_step_aside_does() {
        // A point 10 units ahead of the eye, traced 0.1 s ago; a near surface at depth 2.
        let (eye, far, near) = (Vec3::ZERO, 10.0, 2.0);
        let camera = looking(eye, Vec3::new(0.3, 0.0, -1.0));
        let p = Vec3::new(0.5, 0.2, -far);
        let (x, y, z) = camera.project(p).unwrap();
        let parallax = |from: Vec3| {
            let track = [(0.0, eye), (0.2, from)];
            viewpoint(&camera, &track).parallax_of((x, y, z), 0.1, near * z / far)
        };
        // The view turned since (the camera looks elsewhere), the eye stayed.
        assert!(parallax(eye) < 1e-3, "{}", parallax(eye));
        // Looking straight down −z at a point 10 ahead, the eye 0.4 units to the left
        // 0.2 s ago, so 0.2 at the sample's trace: the ray from there meets depth 2 at
        // x = −0.2 + 0.2 · 2 / 10 = −0.16, which the eye now sees 0.08 units per unit
        // depth to the left of the point, 32 / tan 30° pixels per unit.
        let camera = looking(eye, -Vec3::Z);
        let p = Vec3::new(0.0, 0.0, -far);
        let (x, y, z) = camera.project(p).unwrap();
        let track = [(0.0, eye), (0.2, Vec3::new(-0.4, 0.0, 0.0))];
        let at = viewpoint(&camera, &track);
        let got = at.parallax_of((x, y, z), 0.1, near);
        let want = 0.08 * 32.0 / 30f32.to_radians().tan();
        assert!((got - want).abs() < 1e-3 * want, "{got} against {want}");
        // A near depth behind the eye at the trace is never reached.
        assert_eq!(at.parallax_of((x, y, z), 0.1, -1.0), f32::INFINITY);
    }
}

#[cfg(test)]
mod pyramid_tests {
    use super::*;

    proptest::proptest! {
        /// The nearest front over a box is the nearest over the pixels of the blocks
        /// of the lowest level in which the box spans two blocks or fewer each way
        /// (level 0: the pixels themselves), stated pixel by pixel; fronts drawn from a
        /// few depths and none.
        #[test]
        fn the_nearest_front_over_a_box_is_over_its_covering_blocks(
            w in 1usize..70,
            h in 1usize..70,
            depths in proptest::collection::vec(0usize..4, 69 * 69),
            corners in (0usize..69, 0usize..69, 0usize..69, 0usize..69),
        ) {
            let pick = [f32::INFINITY, 1.0, 2.5, 7.0];
            let own: Vec<f32> = depths[..w * h].iter().map(|&d| pick[d]).collect();
            let mut spread = Spread::default();
            let mut front = own.clone();
            spread.apply(&mut front, w, 3.0, true);
            let (x0, x1) = (corners.0.min(corners.1) % w, corners.0.max(corners.1) % w);
            let (y0, y1) = (corners.2.min(corners.3) % h, corners.2.max(corners.3) % h);
            let (x0, x1, y0, y1) = (x0.min(x1), x0.max(x1), y0.min(y1), y0.max(y1));
            let camera = crate::scene::Camera::default().frame(w as u32, h as u32);
            let at = Viewpoint::new(&camera, &[], (3.0, 2.0, None));
            let view = SpreadView { own: &spread.own, width: w, levels: &spread.levels, at };
            let mut l = 0;
            while (x1 >> l) - (x0 >> l) > 1 || (y1 >> l) - (y0 >> l) > 1 {
                l += 1;
            }
            let span = |a: usize, b: usize, n: usize| (a >> l << l)..(((b >> l) + 1) << l).min(n);
            let mut want = f32::INFINITY;
            for y in span(y0, y1, h) {
                for x in span(x0, x1, w) {
                    want = want.min(own[y * w + x]);
                }
            }
            proptest::prop_assert_eq!(view.nearest_in([x0, x1, y0, y1]), want);
            // The quick look at 16-pixel blocks never finds a farther front.
            proptest::prop_assert!(view.nearest_around([x0, x1, y0, y1]) <= want);
        }
    }
}
