//! Resolving the accumulators into the image: weighted sums divided by weight, the
//! coverage map and the splat scale it drives for the next refresh, the mean age;
//! holes go to [`holes`](super::holes).
//!
//! Each band of rows is resolved as soon as it is splatted, while its sums are in the
//! cache, a row at a time through loops over independent pixels (branch-free, so that
//! they compile to vector code): the coverage (a running sum of differences, the one
//! serial loop), the scale adaptation, the quotients. With the low-density fill the
//! same pass forms the fill's first pyramid level from the quotients while they are in
//! registers, instead of reading the image back.

use std::time::{Duration, Instant};

use glam::Vec3;
use rayon::prelude::*;

use crate::scene::CameraFrame;

use super::{
    carry::DecayView,
    lanes::{small_int, LANES},
    pullpush::{any_below, premultiply, pull_row, runs_mut, CH},
    splat::{channel_row, BAND_ROWS, CHANNELS, MIN_WEIGHT},
    spread::Viewpoint,
    ReconParams, Reconstructor,
};

// The fill's first level has a row for two image rows: a band's rows pair up.
const _: () = assert!(BAND_ROWS % 2 == 0 && super::splat::SINGLE_THREAD_BAND_ROWS % 2 == 0);

/// Holes and thin pixels (weight below the fill weight) of a band.
#[derive(Clone, Copy, Default)]
struct Tally {
    holes: usize,
    thin: usize,
}

impl std::ops::Add for Tally {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        Self {
            holes: self.holes + o.holes,
            thin: self.thin + o.thin,
        }
    }
}

/// A band's rows of the per-pixel maps the resolve writes (`w` per row).
struct BandMaps<'a> {
    px: &'a mut [Vec3],
    coverage: &'a mut [u32],
    scale: &'a mut [f32],
    ages: &'a mut [f32],
    cover: &'a mut [f32],
}

/// Per-thread rows of scratch: coverage counts of one row, and two premultiplied rows
/// of the fill's first pull.
struct Scratch {
    counts: Vec<i32>,
    quotients: Vec<f32>,
    pre: Vec<f32>,
    /// A band's coverage differences of splats added over sums already made.
    added_cov: Vec<i32>,
}

impl Scratch {
    /// Rows of scratch for an image `w` pixels wide; the fill's rows if `pulled`.
    fn new(w: usize, pulled: bool) -> Self {
        Self {
            counts: vec![0; w],
            quotients: vec![0.0; 4 * w],
            pre: vec![0.0; if pulled { 2 * CH * w } else { 0 }],
            added_cov: Vec::new(),
        }
    }
}

/// What one band of the resolve reads: besides the image's width, the accumulators'
/// channel stride, the parameters and whether the sums are carried, the band's own
/// sums and coverage differences (from its first row).
struct Frame<'a> {
    w: usize,
    cs: usize,
    p: ReconParams,
    carrying: bool,
    acc: &'a [f32],
    cov: &'a [i32],
}

impl Reconstructor {
    /// The splats, then quotients, coverage, splat scale adaptation, hole filling and
    /// mean age, timed as two passes from `since`; returns when it ended
    /// (`blend_follows`: the history's blend comes next, and does the fill's last
    /// push as it reads the rows). Each band of
    /// rows is resolved as soon as it is splatted, while its sums and coverage
    /// differences are still in the cache: resolving them in a pass of its own read
    /// every pixel's sums back from memory (2 ms of a 40 ms image at 1280×720,
    /// performance.md, session 46). With `added`, only the pieces from it on are
    /// splatted, over the sums and coverage a first part of the refresh made of those
    /// before.
    pub(super) fn splat_and_resolve(
        &mut self,
        since: Instant,
        blend_follows: bool,
        camera: &CameraFrame,
        added: Option<usize>,
    ) -> Instant {
        let (w, h) = (self.width as usize, self.height as usize);
        let p = self.params;
        // With a fill weight the fill runs whenever a pixel is thin, the usual case:
        // its first level is pulled here; unused otherwise.
        let pulled = p.fill_weight > 0.0;
        // Carried sums and coverage (decayed) add to this refresh's.
        let carrying = self.carries_now();
        let (cs, rows, cstride) = (self.cs, self.band_rows, w + 1);
        let (test, keep) = (self.spread_test(), self.visibility_keep());
        let (nw, level) = self.pull.first_rows(w, h, rows / 2, pulled);
        let splats = super::splat::BandSplats {
            binned: &self.binned[added.unwrap_or(0)..self.pieces],
            rows,
            h,
            cs,
            cstride,
            front: keep.map(|k| (&self.front[..], k)),
            spread: (self.spread).view(Viewpoint::new(camera, &self.eye_ages, test)),
            carried: carrying || added.is_some(),
        };
        // The carry's decay, where it was left to this pass ([`carry::LateDecay`]):
        // each band decayed as it is brought in to be splatted.
        let late = (self.late_decay.as_ref()).map(|l| DecayView::new(l, &self.lookup));
        let bands: Vec<(Tally, Duration, Duration)> = self
            .acc
            .par_chunks_mut(rows * CHANNELS * cs)
            .zip(self.cov.par_chunks_mut(rows * cstride))
            .zip(self.image.pixels.par_chunks_mut(rows * w))
            .zip(self.coverage.par_chunks_mut(rows * w))
            .zip(self.scale.par_chunks_mut(rows * w))
            .zip(self.age.par_chunks_mut(rows * w))
            .zip(self.cover.par_chunks_mut(rows * w))
            .zip(level)
            .enumerate()
            .map_init(
                || Scratch::new(w, pulled),
                |scratch, (b, (((((((acc, cov), px), coverage), scale), ages), cover), level))| {
                    let t0 = Instant::now();
                    if let Some(l) = late {
                        l.band((&mut *acc, &mut *cover), b * rows, (w, cs));
                    }
                    let more = added.map(|_| &mut scratch.added_cov);
                    splat_band(&splats, b, (&mut *acc, &mut *cov), more);
                    let t1 = Instant::now();
                    let f = Frame {
                        w,
                        cs,
                        p,
                        carrying,
                        acc,
                        cov,
                    };
                    let maps = BandMaps {
                        px,
                        coverage,
                        scale,
                        ages,
                        cover,
                    };
                    // The band's own rows: its sums and differences start at its first.
                    let tally = f.band(0, maps, level.map(|l| (l, nw)), scratch);
                    (tally, t1 - t0, t1.elapsed())
                },
            )
            .collect();
        if let Some(l) = self.late_decay.take() {
            self.late_flags = l.into_flags();
        }
        let since = self.split_band_time(since, &bands);
        let tally = bands.iter().fold(Tally::default(), |sum, b| sum + b.0);
        self.fill_and_mean_age(tally, pulled, blend_follows);
        self.passes.lap(5, since)
    }

    /// After the bands' quotients (`tally`: their holes and thin pixels; `pulled`:
    /// whether they pulled the fill's first level), the fill of thin pixels or the
    /// holes, and the mean age where no history blends the ages after. With
    /// `defer_push` the fill's last push is left to the history's blend, which pushes
    /// each row as it reads it ([`Reconstructor::pending_push`]).
    fn fill_and_mean_age(&mut self, tally: Tally, pulled: bool, defer_push: bool) {
        let (w, h) = (self.width as usize, self.height as usize);
        let Tally { holes, thin } = tally;
        self.holes = holes;
        // The still-region history, where there is one, blends every pixel's age and
        // sums the ages shown: a sum here would be overwritten (a serial pass over
        // every pixel, a millisecond at 1280×720).
        let sum_ages = self.history.is_none();
        let age_sum = if thin > 0 {
            self.pull_push(self.params.fill_weight, pulled, defer_push);
            if sum_ages {
                self.age.iter().map(|&a| a as f64).sum()
            } else {
                0.0
            }
        } else {
            // Band order, so the sum does not depend on the thread count.
            let mut age_sum: f64 = if sum_ages {
                self.band_age_sums().iter().sum()
            } else {
                0.0
            };
            if holes > 0 {
                age_sum += self.fill_holes(self.holes * 64 > w * h);
            }
            age_sum
        };
        if sum_ages {
            self.mean_age = age_sum / (w * h).max(1) as f64;
        }
    }

    /// The wall time from `since` to now of the bands' pass, shared between the splat
    /// and the resolve as its bands' time was (their time in each, from `bands`); returns
    /// now.
    fn split_band_time(
        &mut self,
        since: Instant,
        bands: &[(Tally, Duration, Duration)],
    ) -> Instant {
        let now = Instant::now();
        let (splat, resolve) = bands.iter().fold((0.0, 0.0), |(s, r), b| {
            (s + b.1.as_secs_f64(), r + b.2.as_secs_f64())
        });
        let wall = (now - since).as_secs_f64();
        let share = if splat + resolve > 0.0 {
            splat / (splat + resolve)
        } else {
            0.5
        };
        self.passes.add(4, wall * share);
        self.passes.add(5, wall * (1.0 - share));
        now
    }

    /// Per band, the sum in pixel order of the ages of the pixels that are not holes.
    fn band_age_sums(&self) -> Vec<f64> {
        let (w, cs) = (self.width as usize, self.cs);
        self.age
            .par_chunks(BAND_ROWS * w)
            .enumerate()
            .map(|(b, ages)| {
                let mut sum = 0f64;
                for (r, ages) in ages.chunks_exact(w).enumerate() {
                    let weight = &channel_row(&self.acc, cs, b * BAND_ROWS + r, 3)[..w];
                    for (&a, &cw) in ages.iter().zip(weight) {
                        if cw >= MIN_WEIGHT {
                            sum += a as f64;
                        }
                    }
                }
                sum
            })
            .collect()
    }
}

/// Splat band `b` into its sums `acc` and coverage differences `cov`; with `more`
/// (scratch), over the coverage already there instead of in place of it.
fn splat_band<V: super::splat::HidesSplat>(
    splats: &super::splat::BandSplats<V>,
    b: usize,
    (acc, cov): (&mut [f32], &mut [i32]),
    more: Option<&mut Vec<i32>>,
) {
    match more {
        Some(more) => {
            more.resize(cov.len(), 0);
            splats.band(b, acc, more);
            cov.iter_mut().zip(more.iter()).for_each(|(c, m)| *c += m);
        }
        None => splats.band(b, acc, cov),
    }
}

impl Frame<'_> {
    /// One band from image row `y0`; with `level` (its rows of the fill's first
    /// level, and that level's width) the band's first pull too.
    fn band(
        &self,
        y0: usize,
        m: BandMaps,
        mut level: Option<(&mut [f32], usize)>,
        scratch: &mut Scratch,
    ) -> Tally {
        let w = self.w;
        let rows = m.px.len() / w;
        let mut tally = Tally::default();
        for r in 0..rows {
            let span = r * w..(r + 1) * w;
            let y = y0 + r;
            self.coverage_row(
                y,
                &mut m.cover[span.clone()],
                &mut m.coverage[span.clone()],
                &mut scratch.counts,
            );
            scale_row(
                &m.coverage[span.clone()],
                &mut m.scale[span.clone()],
                &self.p,
            );
            let sums: [&[f32]; CHANNELS] =
                std::array::from_fn(|c| &channel_row(self.acc, self.cs, y, c)[..w]);
            let (px, ages) = (&mut m.px[span.clone()], &mut m.ages[span]);
            let t = match &mut level {
                None => quotients_row(
                    &sums,
                    RowOut {
                        px,
                        ages,
                        pre: None,
                    },
                    &mut scratch.quotients,
                    self.p.fill_weight,
                ),
                Some((out, nw)) => {
                    let (r0, r1) = scratch.pre.split_at_mut(CH * w);
                    let pre = if r % 2 == 0 { &mut *r0 } else { &mut *r1 };
                    let t = quotients_row(
                        &sums,
                        RowOut {
                            px,
                            ages,
                            pre: Some(pre),
                        },
                        &mut scratch.quotients,
                        self.p.fill_weight,
                    );
                    if r % 2 == 1 || r + 1 == rows {
                        if r % 2 == 0 {
                            // The image's last row, odd: no second row of children.
                            r1.fill(0.0);
                        }
                        let nw = *nw;
                        pull_row(r0, r1, w, &mut out[r / 2 * CH * nw..][..CH * nw], nw);
                    }
                    t
                }
            };
            tally = tally + t;
        }
        tally
    }

    /// Coverage of row `y` from its differences: a running sum, plus the decayed
    /// coverage carried over when carrying.
    fn coverage_row(&self, y: usize, cover: &mut [f32], coverage: &mut [u32], counts: &mut [i32]) {
        let w = self.w;
        let cov = &self.cov[y * (w + 1)..][..w];
        let mut count = 0i32;
        if !self.carrying {
            for (n, &d) in coverage.iter_mut().zip(cov) {
                count += d;
                *n = count as u32;
            }
            return;
        }
        for (n, &d) in counts.iter_mut().zip(cov) {
            count += d;
            *n = count;
        }
        for (c, &k) in cover.iter_mut().zip(&counts[..w]) {
            *c += k as f32;
        }
        // `as u32` saturates, which keeps a loop scalar: below 2²² (any real count)
        // the rounded coverage converts exactly without it.
        if cover
            .iter()
            .fold(true, |small, &c| small & (c < 4_194_000.0))
        {
            for (n, &c) in coverage.iter_mut().zip(&cover[..w]) {
                *n = small_int(c.round().max(0.0)) as u32;
            }
        } else {
            for (n, &c) in coverage.iter_mut().zip(&cover[..w]) {
                *n = c.round() as u32;
            }
        }
    }
}

/// Splat scale adaptation of a row: grow where undersampled, shrink where
/// oversampled, clamped.
fn scale_row(coverage: &[u32], scale: &mut [f32], p: &ReconParams) {
    let (lo, hi) = p.scale_bounds;
    for (s, &n) in scale.iter_mut().zip(coverage) {
        // Both products computed, then selected: branch-free, so vector code.
        let (grown, shrunk) = (*s * p.grow, *s * p.shrink);
        let v = if n < p.undersampled {
            grown
        } else if n > p.oversampled {
            shrunk
        } else {
            *s
        };
        *s = v.clamp(lo, hi);
    }
}

/// Where a row of the resolve writes: pixels, ages, and with the fill the
/// premultiplied row of its first pull (`CH` runs of `w`).
struct RowOut<'a> {
    px: &'a mut [Vec3],
    ages: &'a mut [f32],
    pre: Option<&'a mut [f32]>,
}

/// The quotients of a row of sums into its pixels and ages (a hole keeps what it had:
/// the hole filling overwrites it), and with `out.pre` the row premultiplied for the
/// fill's first pull. Each step is a loop over the row's pixels through `q` (4 runs
/// of `w`: red, green, blue, age), so that the arithmetic is vector code and only the
/// last loop writes the interleaved pixels.
fn quotients_row(sums: &[&[f32]; CHANNELS], out: RowOut, q: &mut [f32], fill: f32) -> Tally {
    let w = out.px.len();
    let cw = &sums[3][..w];
    let (qr, rest) = q.split_at_mut(w);
    let (qg, rest) = rest.split_at_mut(w);
    let (qb, qa) = rest.split_at_mut(w);
    let qa = &mut qa[..w];
    // Red, green, blue, then age (channel 4).
    for (q, s) in [qr, qg, qb, qa].into_iter().zip([0, 1, 2, 4]) {
        for ((q, &s), &cw) in q.iter_mut().zip(&sums[s][..w]).zip(cw) {
            *q = s / cw;
        }
    }
    let holes = cw.iter().map(|&v| (v < MIN_WEIGHT) as u32).sum::<u32>() as usize;
    let thin = cw.iter().map(|&v| (v < fill) as u32).sum::<u32>() as usize;
    let (qr, rest) = q.split_at(w);
    let (qg, rest) = rest.split_at(w);
    let (qb, qa) = rest.split_at(w);
    let q = [qr, qg, qb, &qa[..w]];
    if let Some(pre) = out.pre {
        premultiplied(cw, &q, fill, pre);
    }
    let full = w - w % LANES;
    let runs = out
        .px
        .chunks_exact_mut(LANES)
        .zip(out.ages.chunks_exact_mut(LANES));
    for (x, (px, ages)) in (0..full).step_by(LANES).zip(runs) {
        if any_below(&cw[x..x + LANES], MIN_WEIGHT) {
            store_covered(cw, &q, x, px, ages);
        } else {
            interleave(&q, x, px);
            ages.copy_from_slice(&q[3][x..x + LANES]);
        }
    }
    store_covered(cw, &q, full, &mut out.px[full..], &mut out.ages[full..]);
    Tally { holes, thin }
}

/// The quotients `q` of the pixels from column `x` that are not holes (weight `cw`)
/// into `px` and `ages`, one at a time.
fn store_covered(cw: &[f32], q: &[&[f32]; 4], x: usize, px: &mut [Vec3], ages: &mut [f32]) {
    for (i, (p, a)) in px.iter_mut().zip(ages.iter_mut()).enumerate() {
        if cw[x + i] >= MIN_WEIGHT {
            *p = Vec3::new(q[0][x + i], q[1][x + i], q[2][x + i]);
            *a = q[3][x + i];
        }
    }
}

/// Pixels `x..x + LANES` of the planar colours `q` into `px`: the interleaving spelled
/// out on whole runs, which compiles to permutations and full stores (a plain loop
/// becomes scattered stores).
#[inline(always)]
fn interleave(q: &[&[f32]; 4], x: usize, px: &mut [Vec3]) {
    let c: [[f32; LANES]; 3] = std::array::from_fn(|k| q[k][x..x + LANES].try_into().unwrap());
    let flat: [f32; 3 * LANES] = std::array::from_fn(|i| c[i % 3][i / 3]);
    for (l, p) in px.iter_mut().enumerate() {
        *p = Vec3::new(flat[3 * l], flat[3 * l + 1], flat[3 * l + 2]);
    }
}

/// A row of weights `cw` and quotients `q` premultiplied for the fill's first pull
/// into `pre` (`CH` runs of `w`), as [`premultiply`] forms them.
fn premultiplied(cw: &[f32], q: &[&[f32]; 4], fill: f32, pre: &mut [f32]) {
    let w = cw.len();
    let q: [&[f32]; 4] = std::array::from_fn(|k| &q[k][..w]);
    let [pr, pg, pb, pa, pal] = runs_mut(pre, w);
    for x in 0..w {
        let v = premultiply(cw[x], fill, [q[0][x], q[1][x], q[2][x], q[3][x]]);
        (pr[x], pg[x], pb[x], pa[x], pal[x]) = (v[0], v[1], v[2], v[3], v[4]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Awkward sums: holes, thin and covered weights, every width's tail.
    fn sums(w: usize, seed: u32) -> Vec<Vec<f32>> {
        let mut state = seed.wrapping_mul(2_654_435_761) | 1;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state as f32 / u32::MAX as f32
        };
        let mut s: Vec<Vec<f32>> = (0..CHANNELS)
            .map(|_| (0..w).map(|_| 3.0 * next()).collect())
            .collect();
        for (x, cw) in s[3].iter_mut().enumerate() {
            *cw *= [0.0, 1e-30, 0.3, 1.0, 2.5, 1e-24][(x * 7 + seed as usize) % 6];
        }
        s
    }

    #[test]
    fn quotient_rows_match_the_pixel_by_pixel_quotients() {
        for w in [1, 3, 7, 8, 9, 16, 17, 31] {
            for seed in 0..4 {
                let s = sums(w, seed);
                let rows: [&[f32]; CHANNELS] = std::array::from_fn(|c| &s[c][..]);
                let old = Vec3::new(7.0, 8.0, 9.0);
                let (mut px, mut ages) = (vec![old; w], vec![5.0; w]);
                let (mut q, mut pre) = (vec![0.0; 4 * w], vec![0.0; CH * w]);
                let out = RowOut {
                    px: &mut px,
                    ages: &mut ages,
                    pre: Some(&mut pre),
                };
                let t = quotients_row(&rows, out, &mut q, 1.0);
                let (mut holes, mut thin) = (0, 0);
                for x in 0..w {
                    let (cw, c) = (s[3][x], |k: usize| s[k][x] / s[3][x]);
                    thin += (cw < 1.0) as usize;
                    let (p, a) = if cw >= MIN_WEIGHT {
                        (Vec3::new(c(0), c(1), c(2)), c(4))
                    } else {
                        holes += 1;
                        (old, 5.0)
                    };
                    assert_eq!(
                        px[x].to_array().map(f32::to_bits),
                        p.to_array().map(f32::to_bits)
                    );
                    assert_eq!(ages[x].to_bits(), a.to_bits());
                    let want = premultiply(cw, 1.0, [p.x, p.y, p.z, a]);
                    for (k, v) in want.iter().enumerate() {
                        assert_eq!(pre[k * w + x].to_bits(), v.to_bits(), "w {w} x {x} k {k}");
                    }
                }
                assert_eq!((t.holes, t.thin), (holes, thin));
            }
        }
    }

    #[test]
    fn carried_coverage_rounds_as_the_saturating_conversion() {
        let cov: Vec<i32> = vec![3, -1, 0, 2, -4, 1, 0, 0, 5, -5, 2];
        let w = cov.len() - 1;
        for start in [
            vec![0.4; w],
            (0..w).map(|x| x as f32 * 0.5 - 2.0).collect(),
            vec![f32::NAN; w],
            vec![5e9; w],
            vec![4_193_999.5; w],
        ] {
            let f = Frame {
                w,
                cs: 0,
                p: ReconParams::paper(),
                carrying: true,
                acc: &[],
                cov: &cov,
            };
            let (mut cover, mut coverage, mut counts) = (start.clone(), vec![0; w], vec![0; w]);
            f.coverage_row(0, &mut cover, &mut coverage, &mut counts);
            let mut count = 0;
            for x in 0..w {
                count += cov[x];
                let c = start[x] + count as f32;
                assert_eq!(cover[x].to_bits(), c.to_bits());
                assert_eq!(coverage[x], c.round() as u32, "{c}");
            }
        }
    }
}
