//! The history's blend over the reconstruction: each pixel's history clamped to the
//! box of the reconstructed colours of the 3×3 pixels around it, then blended over
//! it. Row by row, in planes (struct of arrays) and without branches, so that the
//! loops over a row's pixels compile to vector code; each pixel sees the same
//! operations in the same order as it would on its own.

use glam::Vec3;
use rayon::prelude::*;

use super::{refs, AccumMut, HistoryParams, Refs, EMPTY_RANGE};
use crate::image::Image;
use crate::reconstruction::lanes::lane_sum;

/// How far outside its box, in parts of the box's reach (its slack), a history's mean
/// may lie and still count as kept by the clamp (it is shown clamped all the same): a
/// mean the clamp moved lies on its box's edge, and a box that moved by a rounding
/// since would otherwise cut it again, and the CPU and the GPU, whose boxes differ by
/// roundings, would disagree about it.
pub(crate) const CLAMP_ROUNDING: f32 = 1e-4;

/// Rows of a band of the history's blend.
pub(super) const BLEND_ROWS: usize = 16;

/// Planes of a row's slot, `width` values each: its colour (red, green, blue), then
/// the lowest and the highest colour over each pixel and its two row neighbours.
const ROW_PLANES: usize = 9;

/// `a.min(b)` as glam's: `b` unless `a < b` (and so for NaN and signed zeros).
#[inline(always)]
fn min(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

/// `a.max(b)` as glam's: `b` unless `a > b`.
#[inline(always)]
fn max(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

/// The planes ([`ROW_PLANES`]) of the row `px` into `slot`.
fn row_planes(px: &[Vec3], slot: &mut [f32]) {
    let w = px.len();
    let (colour, range) = slot.split_at_mut(3 * w);
    let (lo, hi) = range.split_at_mut(3 * w);
    let (r, gb) = colour.split_at_mut(w);
    let (g, b) = gb.split_at_mut(w);
    for (x, c) in px.iter().enumerate() {
        (r[x], g[x], b[x]) = (c.x, c.y, c.z);
    }
    for c in 0..3 {
        let plane = &colour[c * w..][..w];
        row_range(plane, &mut lo[c * w..][..w], &mut hi[c * w..][..w]);
    }
}

/// Each value's lowest and highest over itself and its two neighbours in `v`.
fn row_range(v: &[f32], lo: &mut [f32], hi: &mut [f32]) {
    let w = v.len();
    let at = |x: usize| {
        let (a, b) = (v[x.saturating_sub(1)], v[(x + 1).min(w - 1)]);
        (min(min(v[x], a), b), max(max(v[x], a), b))
    };
    (lo[0], hi[0]) = at(0);
    if w < 3 {
        (lo[w - 1], hi[w - 1]) = at(w - 1);
        return;
    }
    let inner = lo[1..w - 1].iter_mut().zip(&mut hi[1..w - 1]);
    for (((l, h), &c), (&a, &b)) in inner.zip(&v[1..]).zip(v.iter().zip(&v[2..])) {
        (*l, *h) = (min(min(c, a), b), max(max(c, a), b));
    }
    (lo[w - 1], hi[w - 1]) = at(w - 1);
}

/// Clamp each pixel's history in `acc` to the box of the reconstruction `image` around
/// it, then blend it over `image` at time `t`, bands of [`BLEND_ROWS`] rows in
/// parallel, each colour shown at its block's reference in `refs` where it is within
/// roundings of it ([`refs`]); `edges` and `rolling` are scratch. Each row is first made final by
/// `finish(scratch, y, pixels, ages)`, once. Returns the pixels the clamp cut and the
/// sum of the shown ages (row by row, each in pixel order).
pub(super) fn blend_image<S: Default + Send>(
    (acc, refs): (&mut super::Accum, &Refs),
    (edges, rolling): (&mut Vec<f32>, &mut Vec<f32>),
    (t, p): (f64, &HistoryParams),
    (image, age): (&mut Image, &mut [f32]),
    finish: &(impl Fn(&mut S, usize, &mut [Vec3], &mut [f32]) + Sync),
) -> (u64, f64) {
    let (w, h) = (image.width as usize, image.height as usize);
    let bands = h.div_ceil(BLEND_ROWS);
    let slot = ROW_PLANES * w;
    // The 3×3 neighbourhood's range, separably: each pixel's range over its row
    // neighbours, then over the ranges of the rows above, at and below (the same
    // minima and maxima). A band computes its rows' ranges as it goes, before
    // blending them; the rows next to it are blended by other bands, so their
    // ranges (and the rows, made final) are taken first.
    edges.resize(2 * bands * slot, 0.0);
    edges
        .par_chunks_mut(2 * slot)
        .zip(image.pixels.par_chunks_mut(BLEND_ROWS * w))
        .zip(age.par_chunks_mut(BLEND_ROWS * w))
        .enumerate()
        .for_each_init(S::default, |scratch, (b, ((e, px), age))| {
            let (first, last) = e.split_at_mut(slot);
            let (y0, last_row) = (b * BLEND_ROWS, px.len() / w - 1);
            let mut made = |r: usize| {
                let row = r * w..(r + 1) * w;
                finish(scratch, y0 + r, &mut px[row.clone()], &mut age[row]);
            };
            made(0);
            if last_row > 0 {
                made(last_row);
            }
            row_planes(&px[..w], first);
            row_planes(&px[last_row * w..], last);
        });
    rolling.resize(3 * bands * slot, 0.0);
    let edges = &edges[..];
    let rows: Vec<Vec<(u64, f64)>> = image
        .pixels
        .par_chunks_mut(BLEND_ROWS * w)
        .zip(acc.runs_mut(BLEND_ROWS * w))
        .zip(age.par_chunks_mut(BLEND_ROWS * w))
        .zip(rolling.par_chunks_mut(3 * slot))
        .enumerate()
        .map_init(S::default, |scratch, (b, (((out, acc), age), rolling))| {
            let band = BandRows {
                b,
                bands,
                w,
                edges,
                refs,
            };
            band.blend((out, acc, age), rolling, (t, p), (scratch, finish))
        })
        .collect();
    let rows = rows.iter().flatten();
    let cuts = rows.clone().map(|r| r.0).sum::<u64>();
    (cuts, rows.map(|r| r.1).sum())
}

/// Band `b` of `bands` of `w`-pixel rows, and the planes of every band's first and
/// last row.
struct BandRows<'a> {
    b: usize,
    bands: usize,
    w: usize,
    edges: &'a [f32],
    refs: &'a Refs,
}

impl BandRows<'_> {
    /// Blend the band's rows `out` (its history `acc`, ages `age`), its row planes
    /// made as it goes in `rolling`, each row but the first and the last (made final
    /// with the edges) first made final by `finish`; each row's cuts and sum of shown
    /// ages.
    fn blend<S>(
        &self,
        (out, mut acc, age): (&mut [Vec3], AccumMut, &mut [f32]),
        rolling: &mut [f32],
        (t, p): (f64, &HistoryParams),
        (scratch, finish): (&mut S, &impl Fn(&mut S, usize, &mut [Vec3], &mut [f32])),
    ) -> Vec<(u64, f64)> {
        let (b, w) = (self.b, self.w);
        let slot = ROW_PLANES * w;
        let edge = |k: usize| &self.edges[k * slot..][..slot];
        let rows = out.len() / w;
        let mut slots: Vec<&mut [f32]> = rolling.chunks_mut(slot).collect();
        // Slot 1 holds this row's planes, 2 the next row's; the row above's is slot 0
        // or, for a band's first row, the previous band's edge.
        row_planes(&out[..w], slots[1]);
        let mut per_row = Vec::with_capacity(rows);
        let mut planes = RowOut::default();
        for r in 0..rows {
            let next_own = r + 1 < rows;
            if next_own {
                let next = (r + 1) * w..(r + 2) * w;
                if r + 2 < rows {
                    let y = b * BLEND_ROWS + r + 1;
                    finish(scratch, y, &mut out[next.clone()], &mut age[next.clone()]);
                }
                row_planes(&out[next], slots[2]);
            }
            let above: &[f32] = match (r, b) {
                (0, 0) => slots[1],
                (0, _) => edge(2 * b - 1),
                _ => slots[0],
            };
            let below: &[f32] = match (next_own, b + 1 < self.bands) {
                (true, _) => slots[2],
                (false, true) => edge(2 * b + 2),
                (false, false) => slots[1],
            };
            let row = r * w..(r + 1) * w;
            per_row.push(blend_row(
                ([above, slots[1], below], self.refs.row(b * BLEND_ROWS + r)),
                &mut out[row.clone()],
                acc.sub(row.clone()),
                &mut age[row],
                (t, p),
                &mut planes,
            ));
            slots.rotate_left(1);
        }
        per_row
    }
}

/// The planes of the rows above, at and below one row.
type Around<'a> = [&'a [f32]; 3];

/// What the blend makes of one row's pixels, in planes (reused row after row): the
/// colour shown, the age shown, whether the clamp moved the history, and the
/// luminance it moved it to.
#[derive(Default)]
struct RowOut {
    colour: [Vec<f32>; 3],
    shown: Vec<f64>,
    moved: Vec<bool>,
    luminance: Vec<f32>,
}

/// Plane `k` of a row slot of `w`-pixel rows.
fn plane(slot: &[f32], k: usize, w: usize) -> &[f32] {
    &slot[k * w..][..w]
}

/// Clamp and blend one row's history `acc` over the reconstruction `out`, given the
/// planes of the rows around it; returns the pixels cut and the sum of the shown ages
/// (in pixel order).
fn blend_row(
    (around, refs): (Around, [&[f32]; 3]),
    out: &mut [Vec3],
    mut acc: AccumMut,
    age: &mut [f32],
    (t, p): (f64, &HistoryParams),
    o: &mut RowOut,
) -> (u64, f64) {
    let w = out.len();
    o.colour.iter_mut().for_each(|c| c.resize(w, 0.0));
    o.shown.resize(w, 0.0);
    o.moved.resize(w, false);
    o.luminance.resize(w, 0.0);
    for c in 0..3 {
        clamp_plane(around, c, &mut acc, o, p);
    }
    blend_planes(around, &mut acc, age, o, (t, p));
    shown_exact(&mut o.colour, refs);
    let c = &o.colour;
    for (x, px) in out.iter_mut().enumerate() {
        *px = Vec3::new(c[0][x], c[1][x], c[2][x]);
    }
    for (a, &s) in age.iter_mut().zip(&o.shown) {
        *a = s as f32;
    }
    (cut_moved(&mut acc, o), lane_sum(&o.shown))
}

/// Channel `c` of each pixel's mean clamped into its widened 3×3 box, in
/// `o.colour[c]`, and whether that moved it (`o.moved`, or-ed over the channels).
fn clamp_plane(around: Around, c: usize, acc: &mut AccumMut, o: &mut RowOut, p: &HistoryParams) {
    let w = acc.count.len();
    let plane = |s, k| plane(s, k, w);
    let [a, m, b] = around;
    let lows = (plane(a, 3 + c), plane(m, 3 + c), plane(b, 3 + c));
    let highs = (plane(a, 6 + c), plane(m, 6 + c), plane(b, 6 + c));
    let means = &acc.mean[c][..w];
    let (clamped, moved) = (&mut o.colour[c][..w], &mut o.moved[..w]);
    let (scale, tolerance) = (0.5 * p.box_scale, p.tolerance);
    for x in 0..w {
        let lo = min(min(lows.0[x], lows.1[x]), lows.2[x]);
        let hi = max(max(highs.0[x], highs.1[x]), highs.2[x]);
        let (mid, half) = ((lo + hi) * 0.5, (hi - lo) * scale);
        let slack = half + tolerance;
        let mean = means[x];
        clamped[x] = min(max(mean, mid - slack), mid + slack);
        // Written so that a NaN mean is moved.
        let kept = (clamped[x] - mean).abs() <= slack * CLAMP_ROUNDING;
        let differs = !kept;
        moved[x] = if c == 0 { differs } else { moved[x] | differs };
    }
}

/// Where the clamp moved a history (`o.colour`: its clamped mean) its count falls to
/// the clamped count; then each history blended over the reconstructed colour (the
/// middle row's planes), into `o.colour` and `o.shown`.
fn blend_planes(
    [_, m, _]: Around,
    acc: &mut AccumMut,
    age: &[f32],
    o: &mut RowOut,
    (t, p): (f64, &HistoryParams),
) {
    let w = acc.count.len();
    let (k, kd) = (p.recon_weight, p.recon_weight as f64);
    let [sr, sg, sb] = &mut acc.mean;
    let (sr, sg, sb) = (&mut sr[..w], &mut sg[..w], &mut sb[..w]);
    let (count, time_sum, age) = (&mut acc.count[..w], &mut acc.time_sum[..w], &age[..w]);
    let [cr, cg, cb] = &mut o.colour;
    let (cr, cg, cb) = (&mut cr[..w], &mut cg[..w], &mut cb[..w]);
    let (moved, luminance, shown) = (&mut o.moved[..w], &mut o.luminance[..w], &mut o.shown[..w]);
    let (mr, mg, mb) = (&m[..w], &m[w..][..w], &m[2 * w..][..w]);
    for x in 0..w {
        let n0 = count[x];
        let mv = moved[x] && n0 > 0.0;
        moved[x] = mv;
        let nc = n0.min(p.clamped_count);
        let n = if mv { nc } else { n0 };
        let (r, g, b) = (cr[x], cg[x], cb[x]);
        luminance[x] = crate::trace::luminance(Vec3::new(r, g, b));
        let ts = if mv {
            time_sum[x] / n0 as f64 * nc as f64
        } else {
            time_sum[x]
        };
        // Only a cut history changes (its mean to the clamped one, which is the mean
        // where the clamp kept it), so only it is stored: the stores compile to masked
        // ones, and the others are not written back to memory.
        if mv {
            (sr[x], sg[x], sb[x], count[x], time_sum[x]) = (r, g, b, n, ts);
        }
        // `(col · k + mean · n) / (k + n)`, written as the mean moved towards the
        // reconstruction: where that differs from a converged mean by a rounding, the
        // move is under half a rounding and the mean is shown as it is.
        let f = k / (k + n);
        let show = |col: f32, m: f32| {
            let blended = m + (col - m) * f;
            if n0 > 0.0 {
                blended
            } else {
                col
            }
        };
        (cr[x], cg[x], cb[x]) = (show(mr[x], r), show(mg[x], g), show(mb[x], b));
        let a = age[x] as f64;
        let hist_age = if n > 0.0 { t - ts / n as f64 } else { 0.0 };
        let blended = (a * kd + hist_age * n as f64) / (k + n) as f64;
        shown[x] = if n0 > 0.0 { blended } else { a };
    }
}

/// Each colour of a row shown at its block's reference colour where it is within
/// roundings of it (`refs`: one per [`refs::BLOCK`] pixels).
fn shown_exact(colour: &mut [Vec<f32>; 3], refs: [&[f32]; 3]) {
    for (c, r) in colour.iter_mut().zip(refs) {
        // Whole blocks as fixed-length runs (vector code), then the row's last pixels.
        let mut blocks = c.chunks_exact_mut(refs::BLOCK);
        for (c, &r) in (&mut blocks).zip(r) {
            let c: &mut [f32; refs::BLOCK] = c.try_into().unwrap();
            *c = c.map(|v| refs::exact(v, r));
        }
        if let Some(&r) = r.last() {
            for v in blocks.into_remainder() {
                *v = refs::exact(*v, r);
            }
        }
    }
}

/// The luminance range of each history the clamp moved (empty where it kept
/// nothing); how many it moved.
fn cut_moved(acc: &mut AccumMut, o: &RowOut) -> u64 {
    let mut cuts = 0;
    // Few pixels move in a refresh: a block is looked into only if an or over its
    // flags (a vector reduction) finds one. A plain filter compiled to a pass that
    // stored every pixel's range back, bringing the whole cell array in (about 2 ms
    // of a 1280x720 image).
    for (b, block) in o.moved.chunks(MOVED_BLOCK).enumerate() {
        if !block.iter().fold(false, |any, &m| any | m) {
            continue;
        }
        for (i, _) in block.iter().enumerate().filter(|(_, &m)| m) {
            let x = b * MOVED_BLOCK + i;
            let l = o.luminance[x];
            acc.cell[x].range = if acc.count[x] > 0.0 {
                (l, l)
            } else {
                EMPTY_RANGE
            };
            cuts += 1;
        }
    }
    cuts
}

/// Pixels whose moved flags [`cut_moved`] tests at once.
const MOVED_BLOCK: usize = 64;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{reconstruction::history::Accum, sampling::Rng, trace::luminance};
    use std::sync::atomic::{AtomicU32, Ordering};

    /// One pixel's history, as the blend's reference.
    struct PixelHistory {
        mean: Vec3,
        time_sum: f64,
        count: f32,
        range: (f32, f32),
    }

    impl PixelHistory {
        /// The mean clamped into the box (as shown); whether that cut the history.
        fn clamp_to(&mut self, lo: Vec3, hi: Vec3, p: &HistoryParams) -> (Vec3, bool) {
            let (mid, half) = ((lo + hi) * 0.5, (hi - lo) * (0.5 * p.box_scale));
            let slack = half + Vec3::splat(p.tolerance);
            let clamped = self.mean.clamp(mid - slack, mid + slack);
            let kept = (clamped - self.mean)
                .abs()
                .cmple(slack * CLAMP_ROUNDING)
                .all();
            if kept {
                return (clamped, false);
            }
            let n = self.count.min(p.clamped_count);
            let mean_t = self.time_sum / self.count as f64;
            self.count = n;
            self.mean = clamped;
            self.time_sum = mean_t * n as f64;
            let l = luminance(clamped);
            self.range = if n > 0.0 { (l, l) } else { EMPTY_RANGE };
            (clamped, true)
        }

        fn blend_over(&self, mean: Vec3, out: &mut Vec3, age: f32, t: f64, k: f32) -> f64 {
            let n = self.count;
            *out = mean + (*out - mean) * (k / (k + n));
            let hist_age = if n > 0.0 {
                t - self.time_sum / n as f64
            } else {
                0.0
            };
            (age as f64 * k as f64 + hist_age * n as f64) / (k + n) as f64
        }
    }

    /// The blend pixel by pixel, each pixel's 3×3 box taken from `image` as it was.
    fn reference(
        acc: &mut Accum,
        (t, p): (f64, &HistoryParams),
        image: &mut Image,
        age: &mut [f32],
    ) -> (u64, f64) {
        let (w, h) = (image.width as usize, image.height as usize);
        let before = image.pixels.clone();
        let at = |x: usize, y: usize| before[y * w + x];
        let (mut cuts, mut rows) = (0, Vec::new());
        for y in 0..h {
            // The shown ages of the row, summed in the blend's order.
            let mut shown_row = Vec::with_capacity(w);
            for x in 0..w {
                let q = y * w + x;
                let shown = if acc.count[q] > 0.0 {
                    let ys = [y.saturating_sub(1), y, (y + 1).min(h - 1)];
                    let xs = [x.saturating_sub(1), x, (x + 1).min(w - 1)];
                    let row = |y| {
                        let [a, m, b] = xs.map(|x| at(x, y));
                        (m.min(a).min(b), m.max(a).max(b))
                    };
                    let [ra, rm, rb] = ys.map(row);
                    let (lo, hi) = (ra.0.min(rm.0).min(rb.0), ra.1.max(rm.1).max(rb.1));
                    let mut px = PixelHistory {
                        mean: Vec3::new(acc.mean[0][q], acc.mean[1][q], acc.mean[2][q]),
                        time_sum: acc.time_sum[q],
                        count: acc.count[q],
                        range: acc.cell[q].range,
                    };
                    let (mean, cut) = px.clamp_to(lo, hi, p);
                    cuts += cut as u64;
                    let shown =
                        px.blend_over(mean, &mut image.pixels[q], age[q], t, p.recon_weight);
                    (acc.mean[0][q], acc.mean[1][q], acc.mean[2][q]) = px.mean.into();
                    (acc.time_sum[q], acc.count[q]) = (px.time_sum, px.count);
                    acc.cell[q].range = px.range;
                    shown
                } else {
                    age[q] as f64
                };
                age[q] = shown as f32;
                shown_row.push(shown);
            }
            rows.push(lane_sum(&shown_row));
        }
        (cuts, rows.into_iter().sum())
    }

    /// A `w × h` history and reconstruction: some pixels empty, some histories
    /// far from the reconstruction (clamped), some with few samples.
    fn case(w: u32, h: u32, seed: u64) -> (Accum, Image, Vec<f32>) {
        let n = (w * h) as usize;
        let mut rng = Rng::new(&[seed]);
        let mut acc = Accum::new(n);
        let mut image = Image::new(w, h);
        let mut age = vec![0f32; n];
        for (q, a) in age.iter_mut().enumerate() {
            image.pixels[q] = Vec3::new(rng.uniform(), rng.uniform(), rng.uniform());
            *a = rng.uniform() * 0.3;
            let count = match rng.uniform() {
                u if u < 0.2 => 0.0,
                u if u < 0.3 => 0.5,
                u => (u * 40.0).floor(),
            };
            let mean = match rng.uniform() {
                u if u < 0.7 => image.pixels[q],
                _ => Vec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * 3.0,
            };
            if count > 0.0 {
                for c in 0..3 {
                    acc.mean[c][q] = mean[c];
                }
                acc.time_sum[q] = (1.0 + rng.uniform() as f64) * count as f64;
                acc.count[q] = count;
                acc.cell[q].range = (0.1, 0.9);
            }
        }
        (acc, image, age)
    }

    #[test]
    fn the_planar_blend_is_the_per_pixel_blend_bit_for_bit() {
        let params = [
            HistoryParams::default(),
            HistoryParams {
                recon_weight: 2.5,
                clamped_count: 0.0,
                ..Default::default()
            },
        ];
        let sizes = [(1, 1), (1, 40), (7, 3), (9, 17), (37, 33), (64, 16)];
        let mut clamped = 0;
        for (k, p) in params.iter().enumerate() {
            for (seed, &(w, h)) in sizes.iter().enumerate() {
                let (mut acc, mut image, mut age) = case(w, h, seed as u64);
                let (mut acc2, mut image2, mut age2) = (acc.clone(), image.clone(), age.clone());
                let (mut edges, mut rolling) = (Vec::new(), Vec::new());
                // Each row is made final once, before the blend reads it: here halved
                // and aged by one (the reference does so to the whole image first).
                let made = |px: &mut [Vec3], age: &mut [f32]| {
                    px.iter_mut()
                        .for_each(|p| *p = *p * 0.5 + Vec3::splat(0.125));
                    age.iter_mut().for_each(|a| *a += 1.0);
                };
                let seen: Vec<AtomicU32> = (0..h).map(|_| AtomicU32::new(0)).collect();
                let finish = |_: &mut (), y: usize, px: &mut [Vec3], age: &mut [f32]| {
                    seen[y].fetch_add(1, Ordering::Relaxed);
                    made(px, age);
                };
                // No block has a reference: each colour is the blend's own.
                let refs = Refs::new(w as usize, h as usize);
                let got = blend_image(
                    (&mut acc, &refs),
                    (&mut edges, &mut rolling),
                    (2.0, p),
                    (&mut image, &mut age),
                    &finish,
                );
                made(&mut image2.pixels, &mut age2);
                let want = reference(&mut acc2, (2.0, p), &mut image2, &mut age2);
                let at = format!("{w}×{h}, params {k}");
                let once = seen.iter().all(|n| n.load(Ordering::Relaxed) == 1);
                assert!(once, "{at}: each row made final once");
                clamped += want.0;
                assert_eq!(got.0, want.0, "{at}");
                assert_eq!(got.1.to_bits(), want.1.to_bits(), "{at}");
                let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&age), bits(&age2), "{at}");
                assert_eq!(bits(&acc.count), bits(&acc2.count), "{at}");
                for c in 0..3 {
                    assert_eq!(bits(&acc.mean[c]), bits(&acc2.mean[c]), "{at}");
                    let ch = |im: &Image| im.pixels.iter().map(|v| v[c]).collect::<Vec<_>>();
                    assert_eq!(bits(&ch(&image)), bits(&ch(&image2)), "{at}");
                }
                let tb = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(tb(&acc.time_sum), tb(&acc2.time_sum), "{at}");
                let ranges = |a: &Accum| {
                    a.cell
                        .iter()
                        .map(|c| (c.range.0.to_bits(), c.range.1.to_bits()))
                        .collect::<Vec<_>>()
                };
                assert_eq!(ranges(&acc), ranges(&acc2), "{at}");
            }
        }
        assert!(clamped > 100, "{clamped} clamped");
    }

    /// A history the clamp left on its box's edge, whose box then moved by a rounding,
    /// is kept (shown clamped); one a display code outside is cut.
    #[test]
    fn a_history_a_rounding_outside_its_box_is_kept() {
        let p = HistoryParams::default();
        let grey = 0.5f32;
        // The box of a flat image is its colour widened by the tolerance.
        let edge = grey + p.tolerance;
        let cases = [
            (edge, 0),
            (f32::from_bits(edge.to_bits() + 1), 0),
            (edge + 1e-6, 0),
            (edge + 1.0 / 255.0, 1),
        ];
        for (mean, want) in cases {
            let (w, h) = (3, 2);
            let n = (w * h) as usize;
            let mut acc = Accum::new(n);
            let mut image = Image::new(w, h);
            image.pixels.fill(Vec3::splat(grey));
            let q = 4;
            for c in 0..3 {
                acc.mean[c][q] = mean;
            }
            (acc.count[q], acc.time_sum[q]) = (4.0, 4.0);
            let mut age = vec![0f32; n];
            let (mut edges, mut rolling) = (Vec::new(), Vec::new());
            let refs = Refs::new(w as usize, h as usize);
            let (cuts, _) = blend_image(
                (&mut acc, &refs),
                (&mut edges, &mut rolling),
                (2.0, &p),
                (&mut image, &mut age),
                &|_: &mut (), _, _: &mut [Vec3], _: &mut [f32]| {},
            );
            assert_eq!(cuts, want, "mean {mean}");
            let k = p.recon_weight;
            let count = if want == 0 {
                4.0
            } else {
                p.clamped_count.min(4.0)
            };
            assert_eq!(acc.count[q], count, "mean {mean}");
            let shown = (edge * count + grey * k) / (count + k);
            assert!(
                (image.pixels[q].x - shown).abs() < 1e-6,
                "mean {mean}: shown clamped"
            );
        }
    }
}
