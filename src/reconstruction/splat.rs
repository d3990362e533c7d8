//! Splatting: each row band accumulates the Gaussian splats binned to it, in ring
//! order, into planar rows (one run of pixels per channel), and counts coverage by
//! corner differences. Bands write disjoint rows, so they run in parallel and give the
//! same sums whatever the thread count.

use super::{
    lanes::{gauss_lanes, prefetch, Lanes, LANES, PREFETCH_AHEAD, PREFIX},
    Reconstructor,
};

/// Rows per band of the splat and the resolve with several threads (tasks for the
/// thread pool), and of the mean age's sums, whose bands are fixed so that their sum
/// does not depend on the thread count. Band heights are powers of two.
pub(super) const BAND_ROWS: usize = 16;
/// Rows per band of the splat on one thread.
pub(super) const SINGLE_THREAD_BAND_ROWS: usize = 32;

/// Accumulated channels: weighted red, green, blue, weight, weighted age.
pub(super) const CHANNELS: usize = 5;

/// Accumulated weight below which a pixel counts as a hole: far splat tails reach
/// f32's denormal range, where `Σw·c / Σw` loses all precision.
pub(super) const MIN_WEIGHT: f32 = 1e-24;

/// Floats per channel in one accumulator row: the width rounded up to whole [`LANES`]
/// plus one more run of them, so that `LANES` floats from any pixel of the row stay
/// within the channel (a footprint's last lanes, past its last column, add `+0` there).
pub(super) fn channel_stride(width: usize) -> usize {
    width.div_ceil(LANES) * LANES + LANES
}

/// A sample prepared for splatting at one refresh.
#[derive(Clone, Copy, Debug)]
pub(super) struct Splat {
    pub(super) x: f32,
    pub(super) y: f32,
    /// `½/σx²`, `½/σy²`.
    pub(super) ax: f32,
    pub(super) ay: f32,
    /// Temporal weight × (red, green, blue, 1, age).
    pub(super) c: [f32; CHANNELS],
    /// Inclusive pixel bounding box of the footprint (clipped to the image).
    pub(super) x0: u16,
    pub(super) x1: u16,
    pub(super) y0: u16,
    pub(super) y1: u16,
    /// Depth in the current view (the visibility pass only).
    pub(super) z: f32,
    /// The depth it gives its landing pixel as a front depth: `z`, or infinite when
    /// it sets none (too old, or no visibility pass).
    pub(super) z_front: f32,
    /// The pixel it lands in, [`OUTSIDE`] when that is off the image.
    pub(super) pixel: u32,
}

/// [`Splat::pixel`] of a sample that lands off the image.
pub(super) const OUTSIDE: u32 = u32::MAX;

/// Add one splat to the rows `by0..by1` of a band's accumulators (rows of
/// `CHANNELS · cs` floats, see [`channel_stride`]) and count it in the band's coverage
/// corner differences `cov` (rows of `cstride`).
///
/// Each row of the footprint goes in runs of `LANES` columns from its first column,
/// unaligned: a footprint up to `LANES` wide is one vector operation per channel and
/// row. Lanes past the last column carry weight 0 (adding `+0` leaves every sum as it
/// is). Each pixel gets `(g_x·c)·g_y` added with one rounding, its weights taken from
/// offsets to the footprint's first column and first row, so the sum is the same
/// whichever band computes it.
#[inline(always)]
fn splat_one(
    s: &Splat,
    by0: usize,
    by1: usize,
    cs: usize,
    acc: &mut [f32],
    cstride: usize,
    cov: &mut [i32],
) {
    let (x0, x1) = (s.x0 as usize, s.x1 as usize);
    let runs = (x1 - x0) / LANES + 1;
    let y0 = (s.y0 as usize).max(by0);
    let y1 = (s.y1 as usize + 1).min(by1);
    let rs = CHANNELS * cs;
    // The rows of this band from the footprint's first, offset to its first column.
    let rows = &mut acc[(y0 - by0) * rs + x0..(y1 - by0) * rs];
    let cols = Cols {
        s,
        by: s.y0 as f32 + 0.5 - s.y,
        // Small integers become floats through `u32`: from `usize` (`u64`) the
        // conversion costs a branch and several instructions on x86-64.
        o0: (y0 - s.y0 as usize) as u32 as f32,
        bx: x0 as u32 as f32 + 0.5 - s.x,
        // Columns of the last run within the footprint.
        last: (x1 - x0) % LANES + 1,
        runs,
    };
    match runs {
        1 => cols.add::<1>(rows, y1 - y0, cs),
        2 => cols.add::<2>(rows, y1 - y0, cs),
        3 => cols.add::<3>(rows, y1 - y0, cs),
        _ => cols.add_any(rows, y1 - y0, cs),
    }
    // Coverage corners within the band (made per-row differences in `BandSplats::band`).
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
    /// `y` offset of the footprint's first row's center from the splat.
    by: f32,
    /// The band's first row of the footprint, relative to the footprint's first row.
    o0: f32,
    /// `x` offset of the footprint's first pixel center from the splat.
    bx: f32,
    /// Columns of the last run of `LANES` within the footprint (1 to `LANES`).
    last: usize,
    /// Runs of `LANES` columns it takes.
    runs: usize,
}

impl Cols<'_> {
    /// `g_x · c` of run `j` (lane weights zero past the footprint).
    #[inline(always)]
    fn weighted(&self, j: usize) -> [Lanes; CHANNELS] {
        let g = gauss_lanes(self.s.ax, self.bx, (j * LANES) as u32 as f32);
        let keep = &PREFIX[if j + 1 == self.runs { self.last } else { LANES }];
        let mut out = [[0f32; LANES]; CHANNELS];
        for (o, &c) in out.iter_mut().zip(&self.s.c) {
            for l in 0..LANES {
                o[l] = g[l] * (keep[l] * c);
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

    /// Footprints of `R` runs, `nrows` rows of `CHANNELS · cs` floats from the first
    /// column: the products `g_x·c` stay in registers over the rows.
    #[inline(always)]
    fn add<const R: usize>(&self, rows: &mut [f32], nrows: usize, cs: usize) {
        let mut gxc = [[[0f32; LANES]; CHANNELS]; R];
        for (j, g) in gxc.iter_mut().enumerate() {
            *g = self.weighted(j);
        }
        let rs = CHANNELS * cs;
        // One bounds check for the splat, not one per row and channel: the last row's
        // last channel's lanes end within `rows`.
        assert!(nrows >= 1 && (nrows - 1) * rs + (CHANNELS - 1) * cs + R * LANES <= rows.len());
        for k in 0..nrows.div_ceil(LANES) {
            let gy = self.row_weights(k);
            let n = (nrows - k * LANES).min(LANES);
            for (i, &gy) in gy[..n].iter().enumerate() {
                let r = (k * LANES + i) * rs;
                for ch in 0..CHANNELS {
                    for (j, gxc) in gxc.iter().enumerate() {
                        let o = r + ch * cs + j * LANES;
                        // SAFETY: the row `k·LANES + i < nrows`, the channel `ch <
                        // CHANNELS` and the run `j < R`, so `o + LANES ≤ (nrows − 1)·rs
                        // + (CHANNELS − 1)·cs + R·LANES ≤ rows.len()` by the assertion
                        // above: `o..o + LANES` lies within `rows`, which is borrowed
                        // mutably, so `d` is the only reference to those floats while
                        // it lives; `[f32; LANES]` has the alignment of `f32`.
                        // Exercised against direct evaluation, footprints of one to
                        // many runs and at the image's edges, by
                        // `reconstruction::tests::fast_path_matches_direct_evaluation`.
                        let d = unsafe { &mut *rows.as_mut_ptr().add(o).cast::<Lanes>() };
                        for l in 0..LANES {
                            d[l] = gxc[ch][l].mul_add(gy, d[l]);
                        }
                    }
                }
            }
        }
    }

    /// Wider footprints: the same sums, a run at a time over the rows.
    #[inline(always)]
    fn add_any(&self, rows: &mut [f32], nrows: usize, cs: usize) {
        let rs = CHANNELS * cs;
        for j in 0..self.runs {
            let gxc = self.weighted(j);
            for k in 0..nrows.div_ceil(LANES) {
                let gy = self.row_weights(k);
                let n = (nrows - k * LANES).min(LANES);
                for (i, &gy) in gy[..n].iter().enumerate() {
                    for (ch, gxc) in gxc.iter().enumerate() {
                        let o = (k * LANES + i) * rs + ch * cs + j * LANES;
                        let d: &mut Lanes = (&mut rows[o..o + LANES]).try_into().unwrap();
                        for l in 0..LANES {
                            d[l] = gxc[l].mul_add(gy, d[l]);
                        }
                    }
                }
            }
        }
    }
}

/// Whether `s` is in front of, or within the tolerance of, the nearest recent sample
/// that landed in its pixel (`front`: the image's front depths; `keep`: `1 / (1 +
/// tolerance)`); while the fronts are spread, as their test says ([`HidesSplat`]).
#[inline(always)]
fn visible<V: HidesSplat>(s: &Splat, (front, spread): (&[f32], Option<V>), keep: f32) -> bool {
    if s.pixel == OUTSIDE {
        return true;
    }
    let f = front[s.pixel as usize];
    match spread {
        Some(v) => !v.hides(s, f, keep),
        None => !behind_front(f, s.z, keep),
    }
}

/// The visibility pass's rule, for splats, the history and the tests: a point at
/// depth `z` lies behind a pixel's front depth `front` beyond the tolerance (`keep`:
/// `1 / (1 + tolerance)`). Depths are never NaN here (a sample that projects to NaN is
/// culled before it is placed).
#[inline(always)]
pub(super) fn behind_front(front: f32, z: f32, keep: f32) -> bool {
    front < z * keep
}

/// The front depths of rows `by0..by1` (`front`, rows of `w`) lowered to the nearest
/// `z_front` of the splats that land there among those binned to the band.
pub(super) fn front_band(
    binned: &[Vec<Vec<Splat>>],
    b: usize,
    by0: usize,
    w: usize,
    front: &mut [f32],
) {
    let (p0, p1) = (by0 * w, by0 * w + front.len());
    for s in binned.iter().flat_map(|c| c[b].iter()) {
        let p = s.pixel as usize;
        if (p0..p1).contains(&p) {
            let d = &mut front[p - p0];
            *d = d.min(s.z_front);
        }
    }
}

/// What every band's splats read: the splats binned at this refresh by band of `rows`
/// rows (of an image `h` rows high, accumulators of channel stride `cs`, coverage
/// differences in rows of `cstride`), the front depths of
/// [`Reconstructor::front_depths`] and `1 / (1 + tolerance)` with the visibility pass,
/// and whether the accumulators hold carried sums.
/// A visibility test of splats beside their pixels' fronts (the moving view's spread
/// fronts, `spread.rs`): whether it hides splat `s`, landing in the image in a pixel
/// whose front is `front` (`keep`: `1 / (1 + tolerance)`).
pub(super) trait HidesSplat: Copy {
    fn hides(&self, s: &Splat, front: f32, keep: f32) -> bool;
}

pub(super) struct BandSplats<'a, V: HidesSplat> {
    pub(super) binned: &'a [Vec<Vec<Splat>>],
    pub(super) rows: usize,
    pub(super) h: usize,
    pub(super) cs: usize,
    pub(super) cstride: usize,
    pub(super) front: Option<(&'a [f32], f32)>,
    /// While the fronts are spread, what their test reads besides.
    pub(super) spread: Option<V>,
    pub(super) carried: bool,
}

impl<V: HidesSplat> BandSplats<'_, V> {
    /// Accumulate band `b` into its rows `acc` and coverage differences `cov` from the
    /// splats binned to it, in ring order, over what `acc` holds when carried (else
    /// from zero); with the front depths, only the splats [`visible`] there.
    #[inline(never)]
    pub(super) fn band(&self, b: usize, acc: &mut [f32], cov: &mut [i32]) {
        let (cs, cstride) = (self.cs, self.cstride);
        if !self.carried {
            acc.fill(0.0);
        }
        cov.fill(0);
        let by0 = b * self.rows;
        let by1 = (by0 + self.rows).min(self.h);
        match self.front {
            Some((front, keep)) => {
                for list in self.binned.iter().map(|c| &c[b]) {
                    for (i, s) in list.iter().enumerate() {
                        // Landing pixels are random within the band: ask for the front
                        // depth some splats ahead so the misses overlap.
                        if let Some(a) = list.get(i + PREFETCH_AHEAD) {
                            prefetch(front, a.pixel as usize);
                        }
                        if visible(s, (front, self.spread), keep) {
                            splat_one(s, by0, by1, cs, acc, cstride, cov);
                        }
                    }
                }
            }
            None => {
                for s in self.binned.iter().flat_map(|c| c[b].iter()) {
                    splat_one(s, by0, by1, cs, acc, cstride, cov);
                }
            }
        }
        // Corner differences → per-row differences (`+1` at `x0`, `−1` past `x1`).
        for r in 1..by1 - by0 {
            let (prev, row) = cov[(r - 1) * cstride..(r + 1) * cstride].split_at_mut(cstride);
            for (d, &p) in row.iter_mut().zip(prev.iter()) {
                *d += p;
            }
        }
    }
}

impl Reconstructor {
    /// Channel `ch` of the accumulated sums of pixel `(x, y)`.
    #[inline(always)]
    pub(super) fn sum_at(&self, x: usize, y: usize, ch: usize) -> f32 {
        channel_row(&self.acc, self.cs, y, ch)[x]
    }
}

/// Channel `ch` of the sums of row `y` (`cs` floats: the row's pixels, then padding),
/// in accumulators of channel stride `cs` (a free function, for callers that hold
/// other fields of the reconstructor mutably).
#[inline(always)]
pub(super) fn channel_row(acc: &[f32], cs: usize, y: usize, ch: usize) -> &[f32] {
    &acc[(y * CHANNELS + ch) * cs..][..cs]
}
