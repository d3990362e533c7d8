//! Splatting: each row band accumulates the Gaussian splats binned to it, in ring
//! order, into cells of [`LANES`] aligned pixels × [`CHANNELS`], and counts coverage
//! by corner differences. Bands write disjoint rows, so they run in parallel and give
//! the same sums whatever the thread count.

use rayon::prelude::*;

use super::{
    lanes::{gauss_lanes, Lanes, LANES, PREFIX},
    Reconstructor,
};

/// Rows per band of the splat with several threads (tasks for the thread pool), and
/// per task of the resolve pass (whose fixed bands make its sums thread-independent).
/// Band heights are powers of two.
pub(super) const BAND_ROWS: usize = 16;
/// Rows per band of the splat on one thread.
pub(super) const SINGLE_THREAD_BAND_ROWS: usize = 64;

/// Accumulated channels: weighted red, green, blue, weight, weighted age.
pub(super) const CHANNELS: usize = 5;
/// Accumulators of `LANES` adjacent pixels (aligned), one vector per channel.
pub(super) type Cell = [Lanes; CHANNELS];

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
}

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
                // and at the image's edges, by
                // `reconstruction::tests::fast_path_matches_direct_evaluation`.
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

impl Reconstructor {
    /// Accumulate every band from the splats binned at this refresh, bands in parallel.
    pub(super) fn splat(&mut self) {
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
}
