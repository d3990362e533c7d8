//! Low-density fill (pull-push): a pixel whose accumulated weight is below
//! [`ReconParams::fill_weight`](super::ReconParams::fill_weight) is completed from a
//! smooth interpolation of its neighbourhood.
//!
//! Where samples are sparse (a region the camera has just turned to) the Gaussian of
//! the nearest sample dominates every pixel around it, so the image is a patchwork of
//! flat cells, and holes take the flat mean of a pyramid block. Here a pixel with
//! weight `W < W₀` shows `(Σw·c + (W₀ − W)·ĉ) / W₀`, where `ĉ` is the pull-push
//! interpolation of its surroundings (Gortler et al. 1996, "The Lumigraph", §3.4):
//!
//! - **pull:** each coarser level is the 2×2 box mean of the finer one, weighted by
//!   coverage `α = min(W/W₀, 1)`, its own coverage the sum of its children's capped
//!   at 1;
//! - **push:** from the coarsest level down, each pixel keeps `α` of its own colour
//!   and takes `1 − α` from the bilinear interpolation of the coarser level.
//!
//! Pixels with `W ≥ W₀` are left as they are. `W₀ = 1` is one fresh sample at the
//! pixel's centre (docs/performance.md, "Tuning records", has the choice).

use glam::Vec3;
use rayon::{iter::Either, prelude::*};

use super::{
    splat::{channel_row, MIN_WEIGHT},
    Reconstructor,
};

/// Channels of a pyramid level: premultiplied red, green, blue, age, and coverage `α`.
pub(super) const CH: usize = 5;
/// Rows per task of the last push.
const PUSH_ROWS: usize = 16;
/// Index of the coverage channel.
const ALPHA: usize = 4;

/// One pyramid level, one run of `w` floats per channel in each row (as the
/// accumulators), so that every pass below is a loop over contiguous floats.
#[derive(Debug, Default)]
pub(super) struct Level {
    w: usize,
    h: usize,
    v: Vec<f32>,
}

/// The pyramid's levels, finest first, and scratch space for the push: each coarse
/// row interpolated along x at the finer level's columns, computed once for the (up
/// to four) fine rows that read it.
#[derive(Debug, Default)]
pub(super) struct Pyramid {
    levels: Vec<Level>,
    up: Vec<f32>,
}

impl Pyramid {
    /// The last push from the first level into a `w × h` image whose accumulators are
    /// `acc` (rows of stride `cs`), at coverage weight `w0`; `None` for an image of
    /// one pixel (no levels).
    pub(super) fn last_push<'a>(
        &'a self,
        acc: &'a [f32],
        cs: usize,
        (w, h): (usize, usize),
        w0: f32,
    ) -> Option<LastPush<'a>> {
        let coarse = self.levels.first()?;
        let full = Full { acc, cs, w, h, w0 };
        let xt = taps(w, coarse.w);
        Some(LastPush { full, coarse, xt })
    }

    /// The levels of a `w × h` display (the display's size fixes them; every value is
    /// rewritten at each fill).
    fn levels_for(w: usize, h: usize) -> Vec<Level> {
        let (mut lw, mut lh) = (w, h);
        let mut levels = Vec::new();
        while lw > 1 || lh > 1 {
            (lw, lh) = (lw.div_ceil(2), lh.div_ceil(2));
            levels.push(Level::new(lw, lh));
        }
        levels
    }

    /// Allocate the levels of a `w × h` display now, backed with memory
    /// ([`super::Reconstructor::prepare`]).
    pub(super) fn prepare(&mut self, w: usize, h: usize) {
        if self.levels.is_empty() {
            self.levels = Self::levels_for(w, h);
        }
        for l in &mut self.levels {
            super::lanes::touch(&mut l.v);
        }
    }
}

impl Level {
    fn new(w: usize, h: usize) -> Self {
        Self {
            w,
            h,
            v: vec![0.0; CH * w * h],
        }
    }

    fn row(&self, y: usize) -> &[f32] {
        &self.v[y * CH * self.w..(y + 1) * CH * self.w]
    }
}

impl Pyramid {
    /// The first level of the pyramid of a `w × h` image (made if missing) for the
    /// resolve to pull into: its width, and its rows in runs of `rows`, one per band
    /// of `2 · rows` image rows; with `pull` false (or no level: a single pixel)
    /// `None` for every band.
    pub(super) fn first_rows(
        &mut self,
        w: usize,
        h: usize,
        rows: usize,
        pull: bool,
    ) -> (
        usize,
        impl IndexedParallelIterator<Item = Option<&mut [f32]>>,
    ) {
        if pull && self.levels.is_empty() {
            self.levels = Self::levels_for(w, h);
        }
        match self.levels.first_mut().filter(|_| pull) {
            Some(first) => (
                first.w,
                Either::Left(first.v.par_chunks_mut(rows * CH * first.w).map(Some)),
            ),
            None => (
                0,
                Either::Right(rayon::iter::repeat_n((), h.div_ceil(2 * rows)).map(|_| None)),
            ),
        }
    }
}

impl Reconstructor {
    /// Complete the pixels whose accumulated weight is below `w0` from the pull-push
    /// interpolation.
    ///
    /// The full-resolution level is never stored: its coverage and colours are
    /// recomputed a row at a time from the accumulators (and the resolved image)
    /// where the first pull and the last push need them. With `pulled` the resolve
    /// has pulled the first level already ([`Pyramid::first_rows`]). With
    /// `defer_last` the last push, into the image, is left to whoever reads the
    /// image next, a row at a time ([`Pyramid::last_push`], with the weight kept in
    /// [`Reconstructor::pending_push`]).
    pub(super) fn pull_push(&mut self, w0: f32, pulled: bool, defer_last: bool) {
        let Pyramid { mut levels, mut up } = std::mem::take(&mut self.pull);
        let (w, h) = (self.width as usize, self.height as usize);
        if levels.is_empty() {
            levels = Pyramid::levels_for(w, h);
        }
        if let Some(first) = levels.first_mut().filter(|_| !pulled) {
            self.full(w0)
                .pull_into(first, &self.image.pixels, &self.age);
        }
        pull_levels(&mut levels);
        push_levels(&mut levels, &mut up);
        self.pull = Pyramid { levels, up };
        if defer_last {
            self.pending_push = Some(w0);
        } else if let Some(last) = self.pull.last_push(&self.acc, self.cs, (w, h), w0) {
            last.image(&mut self.image.pixels, &mut self.age);
        }
    }

    /// The full-resolution level at coverage weight `w0`.
    fn full(&self, w0: f32) -> Full<'_> {
        Full {
            acc: &self.acc,
            cs: self.cs,
            w: self.width as usize,
            h: self.height as usize,
            w0,
        }
    }
}

/// The full-resolution level, recomputed a row at a time from the accumulators
/// (`acc`, rows of stride `cs`) of a `w × h` image and the coverage weight `w0`.
struct Full<'a> {
    acc: &'a [f32],
    cs: usize,
    w: usize,
    h: usize,
    w0: f32,
}

impl Full<'_> {
    /// Accumulated weights (channel 3) of row `y`.
    fn weights(&self, y: usize) -> &[f32] {
        &channel_row(self.acc, self.cs, y, 3)[..self.w]
    }

    /// Row `y`, premultiplied, into `out` (`CH · w`).
    fn row(&self, y: usize, px: &[Vec3], age: &[f32], out: &mut [f32]) {
        let r = y * self.w..(y + 1) * self.w;
        premultiplied_row(self.weights(y), self.w0, &px[r.clone()], &age[r], out)
    }

    /// The first pull: `first` the coverage-weighted 2×2 mean of the image `px` of
    /// ages `age`.
    fn pull_into(&self, first: &mut Level, px: &[Vec3], age: &[f32]) {
        let (w, nw) = (self.w, first.w);
        first.v.par_chunks_mut(CH * nw).enumerate().for_each_init(
            || vec![0f32; 2 * CH * w],
            |rows, (by, out)| {
                let (r0, r1) = rows.split_at_mut(CH * w);
                self.row(2 * by, px, age, r0);
                if 2 * by + 1 < self.h {
                    self.row(2 * by + 1, px, age, r1);
                } else {
                    r1.fill(0.0);
                }
                pull_row(r0, r1, w, out, nw);
            },
        );
    }

    /// The last push into row `y` (`px`, `age`) from the coarse rows above and below
    /// it interpolated along x (four channels of `w` floats each), the second of
    /// weight `ty` (a row that holds a pixel below coverage: [`LastPush::row`] skips
    /// the others): the row is computed whole, in
    /// vector code, and its covered pixels kept as they were, each pixel with the same
    /// operations as [`upsampled`] and [`push_row`] apply to a whole level (the same
    /// bits). Live, about a third of the pixels are below coverage, scattered: a
    /// branch per pixel mispredicted often, and the pixel-at-a-time push cost about
    /// 2 ms of a 1280x720 image.
    fn push_into_row(
        &self,
        y: usize,
        (from, ty): ([&[f32]; 2], f32),
        px: &mut [Vec3],
        age: &mut [f32],
    ) {
        let w = self.w;
        let weight = self.weights(y);
        // Every slice exactly `w` long: no bounds checks, so the loop is vector code.
        let plane = |k: usize, c: usize| &from[k][c * w..][..w];
        let (t, b) = (
            [0, 1, 2, 3].map(|c| plane(0, c)),
            [0, 1, 2, 3].map(|c| plane(1, c)),
        );
        let (px, age) = (&mut px[..w], &mut age[..w]);
        for x in 0..w {
            let (cw, p, a) = (weight[x], px[x], age[x]);
            // `cw ≥ w0` gives `q = 1` (division is monotonic and `w0 / w0 = 1`), so a
            // covered pixel is kept.
            let q = (cw / self.w0).min(1.0);
            let keep = q >= 1.0;
            let hole = cw < MIN_WEIGHT;
            let alpha = if hole { 0.0 } else { q };
            let pushed = |c: usize, v: f32| {
                let interpolated = t[c][x] + (b[c][x] - t[c][x]) * ty;
                let own = if hole { 0.0 } else { v * q };
                own + (1.0 - alpha) * interpolated
            };
            let v = [pushed(0, p.x), pushed(1, p.y), pushed(2, p.z), pushed(3, a)];
            px[x] = if keep { p } else { Vec3::new(v[0], v[1], v[2]) };
            age[x] = if keep { a } else { v[3] };
        }
    }
}

/// The last push of the fill, from the first level into the full-resolution image,
/// a row at a time: only pixels below full coverage change. It can be done as a pass
/// of its own ([`LastPush::image`]) or row by row by the next pass to read the image
/// ([`LastPush::row`]), so that a row is pushed while that pass has it in the cache.
pub(super) struct LastPush<'a> {
    full: Full<'a>,
    coarse: &'a Level,
    /// The column taps of the full resolution on the first level.
    xt: Vec<(usize, usize, f32)>,
}

/// A task's coarse rows interpolated along x, by coarse row index (`usize::MAX`:
/// none), for [`LastPush::row`]: consecutive rows read the same coarse rows, so each
/// is interpolated once per run of rows rather than once per row.
pub(super) struct PushRows {
    rows: [(usize, Vec<f32>); 2],
}

impl Default for PushRows {
    fn default() -> Self {
        Self {
            rows: [(usize::MAX, Vec::new()), (usize::MAX, Vec::new())],
        }
    }
}

impl LastPush<'_> {
    /// The whole image (`px`, `age`), bands of rows in parallel.
    fn image(&self, image: &mut [Vec3], ages: &mut [f32]) {
        let w = self.full.w;
        image
            .par_chunks_mut(PUSH_ROWS * w)
            .zip(ages.par_chunks_mut(PUSH_ROWS * w))
            .enumerate()
            .for_each_init(PushRows::default, |rows, (b, (px, age))| {
                for (r, (px, age)) in px.chunks_mut(w).zip(age.chunks_mut(w)).enumerate() {
                    self.row(rows, b * PUSH_ROWS + r, px, age);
                }
            });
    }

    /// Row `y` of the image (`px`, `age`); `rows` keeps the coarse rows read.
    pub(super) fn row(&self, rows: &mut PushRows, y: usize, px: &mut [Vec3], age: &mut [f32]) {
        if !any_below(self.full.weights(y), self.full.w0) {
            return;
        }
        let (t0, t1, ty) = tap(y, self.coarse.h);
        let (a, b) = self.coarse_rows(rows, t0, t1);
        self.full.push_into_row(y, ([a, b], ty), px, age);
    }

    /// Coarse rows `t0` and `t1` interpolated along x, made where `rows` lacks them.
    fn coarse_rows<'r>(
        &self,
        rows: &'r mut PushRows,
        t0: usize,
        t1: usize,
    ) -> (&'r [f32], &'r [f32]) {
        let w = self.full.w;
        for want in [t0, t1] {
            if rows.rows.iter().any(|(k, _)| *k == want) {
                continue;
            }
            // Replace the one not wanted (rows only move down, so it is not needed again
            // in this run).
            let slot = rows
                .rows
                .iter()
                .position(|(k, _)| *k != t0 && *k != t1)
                .unwrap_or(0);
            let (k, v) = &mut rows.rows[slot];
            v.resize(4 * w, 0.0);
            upsample_row(self.coarse, want, &self.xt, v);
            *k = want;
        }
        let find = |want: usize| rows.rows.iter().position(|(k, _)| *k == want).unwrap_or(0);
        let (i0, i1) = (find(t0), find(t1));
        (&rows.rows[i0].1, &rows.rows[i1].1)
    }
}

/// Whether any of `weights` is below `w0`: a fold without early exit, so that a run of
/// [`super::lanes::LANES`] compiles to one vector comparison.
#[inline(always)]
pub(super) fn any_below(weights: &[f32], w0: f32) -> bool {
    weights.iter().fold(false, |any, &cw| any | (cw < w0))
}

/// Pull: each level above the first the coverage-weighted 2×2 mean of the finer one,
/// its coverage the children's summed and capped at 1.
fn pull_levels(levels: &mut [Level]) {
    for k in 1..levels.len() {
        let (finer, rest) = levels.split_at_mut(k);
        let (prev, next) = (&finer[k - 1], &mut rest[0]);
        let nw = next.w;
        let zeros = vec![0f32; CH * prev.w];
        next.v
            .par_chunks_mut(CH * nw)
            .enumerate()
            .for_each(|(by, out)| {
                let r1 = if 2 * by + 1 < prev.h {
                    prev.row(2 * by + 1)
                } else {
                    &zeros
                };
                pull_row(prev.row(2 * by), r1, prev.w, out, nw);
            });
    }
}

/// Push, coarsest first, down to the first level: each level keeps `α` of its own
/// colour and takes `1 − α` from the bilinear interpolation of the (complete)
/// coarser one.
fn push_levels(levels: &mut [Level], up: &mut Vec<f32>) {
    if let Some(top) = levels.last_mut() {
        let a = top.v[ALPHA];
        if a > 0.0 {
            let k = 1.0 / a;
            for c in 0..CH {
                top.v[c] *= k;
            }
        }
    }
    for k in (1..levels.len()).rev() {
        let (finer, coarser) = levels.split_at_mut(k);
        let (coarse, fine) = (&coarser[0], &mut finer[k - 1]);
        let fw = fine.w;
        let up = upsampled(coarse, fw, up);
        fine.v
            .par_chunks_mut(CH * fw)
            .enumerate()
            .for_each(|(y, row)| {
                let (y0, y1, ty) = tap(y, coarse.h);
                let (vals, alpha) = row.split_at_mut(4 * fw);
                push_row(vals, alpha, up_row(up, y0, fw), up_row(up, y1, fw), ty, fw);
                alpha.fill(1.0);
            });
    }
}

/// Premultiplied `(r, g, b, age, α)` of a row of pixels of accumulated weights
/// `weight`, colours `px` and ages `age`, with coverage `α = min(cw / w0, 1)`, into
/// `out` (one run per channel); a hole (below `MIN_WEIGHT`) has no colour, so no
/// coverage.
fn premultiplied_row(weight: &[f32], w0: f32, px: &[Vec3], age: &[f32], out: &mut [f32]) {
    let w = weight.len();
    // Every slice exactly `w` long, so that the loop has no bounds checks and compiles
    // to vector code.
    let (px, age) = (&px[..w], &age[..w]);
    let [r, g, b, ag, al] = runs_mut(out, w);
    for x in 0..w {
        let p = px[x];
        let v = premultiply(weight[x], w0, [p.x, p.y, p.z, age[x]]);
        (r[x], g[x], b[x], ag[x], al[x]) = (v[0], v[1], v[2], v[3], v[4]);
    }
}

/// The first `CH` runs of `w` floats of `out`, one per channel, each exactly `w` long
/// (so that loops over them need no bounds checks).
pub(super) fn runs_mut(out: &mut [f32], w: usize) -> [&mut [f32]; CH] {
    let (r, rest) = out.split_at_mut(w);
    let (g, rest) = rest.split_at_mut(w);
    let (b, rest) = rest.split_at_mut(w);
    let (a, rest) = rest.split_at_mut(w);
    [r, g, b, a, &mut rest[..w]]
}

/// Premultiplied `(r, g, b, age, α)` of a pixel of accumulated weight `cw` and colour
/// and age `c`, with coverage `α = min(cw / w0, 1)`; a hole (below `MIN_WEIGHT`) has
/// no colour, so no coverage.
#[inline(always)]
pub(super) fn premultiply(cw: f32, w0: f32, c: [f32; 4]) -> [f32; CH] {
    // A hole's colour is whatever an earlier refresh left there: zeroed, not
    // multiplied by `α = 0`.
    // Computed for every pixel, then selected: a division under a branch keeps the
    // loop from becoming vector code.
    let hole = cw < MIN_WEIGHT;
    let q = (cw / w0).min(1.0);
    let sel = |v: f32| if hole { 0.0 } else { v };
    [
        sel(c[0] * q),
        sel(c[1] * q),
        sel(c[2] * q),
        sel(c[3] * q),
        sel(q),
    ]
}

/// One row of a coarser level (`nw` wide, `out` one run per channel) from two rows of
/// the finer one (`fw` wide; `r1` zeros below the last row): the children summed in
/// the order (0, 0), (1, 0), (0, 1), (1, 1) from zero (a missing child adds `+0`,
/// which changes no sum that starts at `+0`), scaled to coverage 1 where it exceeds 1.
pub(super) fn pull_row(r0: &[f32], r1: &[f32], fw: usize, out: &mut [f32], nw: usize) {
    for (c, o) in out.chunks_exact_mut(nw).enumerate() {
        let (a, b) = (&r0[c * fw..(c + 1) * fw], &r1[c * fw..(c + 1) * fw]);
        for ((o, a), b) in o.iter_mut().zip(a.chunks_exact(2)).zip(b.chunks_exact(2)) {
            *o = 0.0 + a[0] + a[1] + b[0] + b[1];
        }
        if fw % 2 == 1 {
            // The last coarse pixel of an odd row has one column of children.
            o[nw - 1] = 0.0 + a[fw - 1] + b[fw - 1];
        }
    }
    let (vals, alpha) = out.split_at_mut(4 * nw);
    for (bx, s) in alpha.iter_mut().enumerate() {
        let k = if *s > 1.0 { 1.0 / *s } else { 1.0 };
        for c in 0..4 {
            vals[c * nw + bx] *= k;
        }
        *s *= k;
    }
}

/// Every row of `coarse` interpolated along x at the columns of a level `fw` wide
/// (`a + (b − a)·tx` at each column's taps), four channels of `fw` floats per row, in
/// `up` (resized as needed).
fn upsampled<'a>(coarse: &Level, fw: usize, up: &'a mut Vec<f32>) -> &'a [f32] {
    let xt = taps(fw, coarse.w);
    up.resize(coarse.h * 4 * fw, 0.0);
    up.par_chunks_mut(4 * fw)
        .enumerate()
        .for_each(|(y, out)| upsample_row(coarse, y, &xt, out));
    &up[..coarse.h * 4 * fw]
}

/// Row `y` of `coarse` interpolated along x at column taps `xt` (one per fine
/// column), its four channels into `out`.
fn upsample_row(coarse: &Level, y: usize, xt: &[(usize, usize, f32)], out: &mut [f32]) {
    let row = coarse.row(y);
    let fw = xt.len();
    let halving = coarse.w == fw.div_ceil(2);
    for (c, out) in out.chunks_exact_mut(fw).take(4).enumerate() {
        let cv = &row[c * coarse.w..(c + 1) * coarse.w];
        if halving {
            upsample_halved(cv, xt, out);
        } else {
            upsample_at(cv, xt, out, 0..fw);
        }
    }
}

/// `out[x] = a + (b − a)·tx` of the taps `xt[x]` of the values `cv`, for `x` in `r`.
fn upsample_at(cv: &[f32], xt: &[(usize, usize, f32)], out: &mut [f32], r: std::ops::Range<usize>) {
    for x in r {
        let (x0, x1, tx) = xt[x];
        let (a, b) = (cv[x0], cv[x1]);
        out[x] = a + (b - a) * tx;
    }
}

/// [`upsample_at`] of every fine column, where the coarse row `cv` has half as many
/// (rounded up): away from the ends, fine column `2i` sits at coarse `i − 1/4` and
/// `2i + 1` at `i + 1/4` (exactly, in floats), so its taps are `(i − 1, i, 3/4)` and
/// `(i, i + 1, 1/4)`. Those columns are computed from the pattern, with the same
/// operations, so that the loop reads the row in order instead of gathering; the
/// end columns, where the taps clamp, from `xt`.
fn upsample_halved(cv: &[f32], xt: &[(usize, usize, f32)], out: &mut [f32]) {
    let (fw, n) = (out.len(), cv.len());
    if n < 3 {
        return upsample_at(cv, xt, out, 0..fw);
    }
    // Columns 2 to 2n − 3: pairs `(2i, 2i + 1)` for `i` in `1..n − 1`.
    let m = n - 2;
    let (below, at, above) = (&cv[..m], &cv[1..m + 1], &cv[2..m + 2]);
    for (j, pair) in out[2..2 + 2 * m].chunks_exact_mut(2).enumerate() {
        pair[0] = below[j] + (at[j] - below[j]) * 0.75;
        pair[1] = at[j] + (above[j] - at[j]) * 0.25;
    }
    upsample_at(cv, xt, out, 0..2);
    upsample_at(cv, xt, out, 2 + 2 * m..fw);
}

/// Row `y` of [`upsampled`]'s output for a fine level `fw` wide.
fn up_row(up: &[f32], y: usize, fw: usize) -> &[f32] {
    &up[y * 4 * fw..(y + 1) * 4 * fw]
}

/// Push into one fine row: each of its four channels keeps its own value plus `1 − α`
/// of the bilinear interpolation `top + (bottom − top)·ty` of the coarser level.
fn push_row(vals: &mut [f32], alpha: &[f32], top: &[f32], bottom: &[f32], ty: f32, fw: usize) {
    for c in 0..4 {
        let v = &mut vals[c * fw..(c + 1) * fw];
        let (t, b) = (&top[c * fw..(c + 1) * fw], &bottom[c * fw..(c + 1) * fw]);
        for x in 0..fw {
            let up = t[x] + (b[x] - t[x]) * ty;
            v[x] += (1.0 - alpha[x]) * up;
        }
    }
}

/// The bilinear taps of pixel `i` of a level twice as fine as one of `n` pixels (along
/// one axis): the two coarse pixels around its centre (clamped at the edges) and the
/// weight of the second.
#[inline]
fn tap(i: usize, n: usize) -> (usize, usize, f32) {
    let f = ((i as f32 + 0.5) * 0.5 - 0.5).clamp(0.0, (n - 1) as f32);
    let i0 = f as usize;
    (i0, (i0 + 1).min(n - 1), f - i0 as f32)
}

/// [`tap`] of every pixel of a row (or column) of `fine` pixels: computed once per
/// level, not once per pixel.
fn taps(fine: usize, n: usize) -> Vec<(usize, usize, f32)> {
    (0..fine).map(|i| tap(i, n)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Rng;

    #[test]
    fn the_halved_upsample_is_the_tapped_one_bit_for_bit() {
        let mut rng = Rng::new(&[3]);
        for fw in 1..80usize {
            let n = fw.div_ceil(2);
            let cv: Vec<f32> = (0..n).map(|_| rng.uniform() * 4.0 - 2.0).collect();
            let xt = taps(fw, n);
            let (mut a, mut b) = (vec![0f32; fw], vec![0f32; fw]);
            upsample_at(&cv, &xt, &mut a, 0..fw);
            upsample_halved(&cv, &xt, &mut b);
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&a), bits(&b), "{fw} columns");
        }
    }
}
