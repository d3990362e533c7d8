//! The carried accumulators' trip to the GPU and back ([`super::super::carry`]).
//!
//! The carry step (decay, move, cut) is decided on the CPU, which holds the geometry
//! it needs; the GPU adds the new splats onto what was carried. A refresh uploads the
//! carried sums with the carried coverage in the accumulators' per-pixel layout where
//! the GPU cannot replay the CPU's carry on the sums it kept ([`super::carry`]), and
//! with the visibility pass the initial front depths; it reads the final sums and
//! coverage back, before any fill, so that the CPU's next carry starts from them.
//!
//! Where only which pixels hold sums comes back ([`SumsBack::Holds`]) and the view
//! holds, little changes from one refresh to the next: the mask is compared with the
//! last one word by word ([`HoldsKept`]), and only the weights whose bit changed, or
//! that the CPU's carry edited since, are written. Those pixels, with the ones the
//! carry edited next, are the only ones whose initial front depth can change, so a
//! refresh uploads those alone ([`FrontsIn::Changes`], kept on the GPU by
//! [`super::fronts`]) instead of every pixel's.

use rayon::prelude::*;

use super::{SumsBack, PER_PIXEL};
use crate::reconstruction::{
    carry_edits::CarryEdits,
    splat::{channel_row, CHANNELS},
};

/// The carried sums a carrying refresh uploads: the CPU's planar accumulators `acc`
/// (channel stride `cs`) of a `w`-wide image and its coverage `cover`, packed on the
/// way into per-pixel runs of the weighted red, green, blue, weight, weighted age and
/// coverage (the GPU accumulators' layout, [`PER_PIXEL`] floats).
pub(in crate::reconstruction) struct CarriedSums<'a> {
    pub(in crate::reconstruction) acc: &'a [f32],
    pub(in crate::reconstruction) cs: usize,
    pub(in crate::reconstruction) w: usize,
    pub(in crate::reconstruction) cover: &'a [f32],
}

/// What a carrying refresh uploads besides the sums (which go first, see
/// [`CarriedSums`]).
pub(in crate::reconstruction) struct CarriedIn<'a> {
    /// With the visibility pass: the initial front depths as the shaders store them
    /// (see `front_bits`).
    pub(in crate::reconstruction) front: Option<FrontsIn<'a>>,
}

/// The initial front depths a carrying refresh uploads.
#[derive(Clone, Copy)]
pub(in crate::reconstruction) enum FrontsIn<'a> {
    /// Every pixel's.
    All(&'a [u32]),
    /// `[pixel, bits]` where they changed since the last refresh's, which the GPU
    /// kept ([`super::GpuRecon::fronts_since`] says whether it did).
    Changes(&'a [[u32; 2]]),
}

/// The holds mask the CPU's weight plane was last set from, and the pixels whose
/// weight that changed.
#[derive(Default)]
pub(in crate::reconstruction) struct HoldsKept {
    /// The mask last unpacked (empty: none yet).
    words: Vec<u32>,
    /// The pixels whose weight the last unpack wrote (`None`: every pixel's).
    pub(in crate::reconstruction) changed: Option<Vec<u32>>,
}

/// Repack the planar CPU accumulators `acc` (channel stride `cs`) of a `w`-wide
/// image and its coverage `cover` into per-pixel runs of [`PER_PIXEL`] floats.
#[cfg(test)]
pub(in crate::reconstruction) fn pack(acc: &[f32], cs: usize, w: usize, cover: &[f32]) -> Vec<f32> {
    let mut out = Vec::new();
    pack_into(&CarriedSums { acc, cs, w, cover }, &mut out);
    out
}

/// `pack` into `out`, resized to fit: blocks of rows on every thread. `out` is
/// kept between refreshes, so that the 50 MB of a 1080p image are not allocated and
/// faulted in again each time.
pub(in crate::reconstruction) fn pack_into(c: &CarriedSums<'_>, out: &mut Vec<f32>) {
    let row = c.w * PER_PIXEL;
    out.resize(c.cover.len() * PER_PIXEL, 0.0);
    out.par_chunks_mut(row * PACK_ROWS)
        .enumerate()
        .for_each(|(i, block)| pack_rows(c, i * PACK_ROWS, block));
}

/// Rows per task of [`pack_into`].
const PACK_ROWS: usize = 8;

/// Rows `y0..` of `c` packed into `out` (whole rows of [`PER_PIXEL`] floats a pixel).
fn pack_rows(c: &CarriedSums<'_>, y0: usize, out: &mut [f32]) {
    let CarriedSums { acc, cs, w, cover } = *c;
    for (dy, rows) in out.chunks_exact_mut(w * PER_PIXEL).enumerate() {
        let y = y0 + dy;
        for ch in 0..CHANNELS {
            let src = &channel_row(acc, cs, y, ch)[..w];
            for (px, &v) in rows.chunks_exact_mut(PER_PIXEL).zip(src) {
                px[ch] = v;
            }
        }
        for (px, &c) in rows.chunks_exact_mut(PER_PIXEL).zip(&cover[y * w..][..w]) {
            px[CHANNELS] = c;
        }
    }
}

/// The inverse of `pack`: the GPU's final sums into `acc`, its coverage into
/// `cover`.
pub(in crate::reconstruction) fn unpack(
    sums: &[f32],
    acc: &mut [f32],
    cs: usize,
    w: usize,
    cover: &mut [f32],
) {
    acc.par_chunks_mut(CHANNELS * cs)
        .zip(cover.par_chunks_mut(w))
        .zip(sums.par_chunks(w * PER_PIXEL))
        .for_each(|((acc, cover), rows)| {
            for ch in 0..CHANNELS {
                let dst = &mut acc[ch * cs..][..w];
                for (d, px) in dst.iter_mut().zip(rows.chunks_exact(PER_PIXEL)) {
                    *d = px[ch];
                }
            }
            for (c, px) in cover.iter_mut().zip(rows.chunks_exact(PER_PIXEL)) {
                *c = px[CHANNELS];
            }
        });
}

/// What came back of the carried sums (`bytes`, as [`SumsBack`] says) into the CPU's
/// planar accumulators and coverage `sums` (channel stride between them) of a
/// `w`-wide image. `edited`: where the weight plane is the last mask's but for the
/// pixels this carry edited, that carry (see [`unpack_holds_since`]); `kept`, the
/// last mask.
pub(in crate::reconstruction) fn unpack_back(
    back: SumsBack,
    bytes: &[u8],
    (acc, cs, cover): (&mut [f32], usize, &mut [f32]),
    w: usize,
    (edited, kept): (Option<&CarryEdits>, &mut HoldsKept),
) {
    let mask: &[u32] = bytemuck::cast_slice(bytes);
    match (back, edited) {
        (SumsBack::All, _) => {
            unpack(bytemuck::cast_slice(bytes), acc, cs, w, cover);
            *kept = HoldsKept::default();
            return;
        }
        (SumsBack::Holds, Some(e)) if kept.words.len() == mask.len() => {
            let mut changed = kept.changed.take().unwrap_or_default();
            unpack_holds_since(mask, (acc, cs, w), (&kept.words, e), &mut changed);
            kept.changed = Some(changed);
        }
        (SumsBack::Holds, _) => {
            unpack_holds(mask, acc, cs, w);
            kept.changed = None;
        }
    }
    kept.words.clear();
    kept.words.extend_from_slice(mask);
}

/// The holds mask the GPU reads back in place of the sums (bit `i` of word `k`: pixel
/// `32k + i` of a `w`-wide image holds sums) into the weight plane of `acc` (channel
/// stride `cs`): 1 where set, 0 elsewhere. The other planes are left as they are: the
/// CPU's carry decides from the weights alone.
pub(in crate::reconstruction) fn unpack_holds(mask: &[u32], acc: &mut [f32], cs: usize, w: usize) {
    acc.par_chunks_mut(CHANNELS * cs)
        .enumerate()
        .for_each(|(y, row)| {
            for (x, wt) in row[3 * cs..][..w].iter_mut().enumerate() {
                let p = y * w + x;
                let set = mask.get(p / 32).is_some_and(|m| m >> (p % 32) & 1 == 1);
                *wt = if set { 1.0 } else { 0.0 };
            }
        });
}

/// [`unpack_holds`] where the weight plane of `acc` (channel stride `cs`, `w` wide)
/// is 1 or 0 by the mask `last` but at the pixels carry `e` edited (its takes,
/// landings and cuts): only the weights whose bit changed since `last`, 32 pixels a
/// compare, and those pixels are written, and listed in `changed`.
pub(in crate::reconstruction) fn unpack_holds_since(
    mask: &[u32],
    (acc, cs, w): (&mut [f32], usize, usize),
    (last, e): (&[u32], &CarryEdits),
    changed: &mut Vec<u32>,
) {
    let pixels = (acc.len() / (CHANNELS * cs)) * w;
    let bit = |p: usize| mask[p / 32] >> (p % 32) & 1 == 1;
    changed.clear();
    for (k, (&m, &l)) in mask.iter().zip(last).enumerate() {
        let mut diff = m ^ l;
        while diff != 0 {
            changed.push((32 * k) as u32 + diff.trailing_zeros());
            diff &= diff - 1;
        }
    }
    let lands = e.lands.iter().map(|l| &l.1);
    changed.extend(e.takes.iter().chain(lands).chain(&e.cuts));
    changed.retain(|&p| (p as usize) < pixels);
    for &p in changed.iter() {
        let p = p as usize;
        acc[((p / w) * CHANNELS + 3) * cs + p % w] = if bit(p) { 1.0 } else { 0.0 };
    }
    #[cfg(test)]
    for p in 0..pixels {
        let wt = acc[((p / w) * CHANNELS + 3) * cs + p % w];
        assert_eq!(
            wt,
            bit(p) as u32 as f32,
            "pixel {p}: the weight is not the mask's"
        );
    }
}

/// Front depths as the shaders keep them: the complement of a depth's bits, so that
/// an atomic maximum keeps the nearest (positive) depth; none (infinite) is 0, as in
/// a cleared buffer, which the history also reads as none.
#[cfg(test)]
pub(in crate::reconstruction) fn front_bits(front: &[f32]) -> Vec<u32> {
    front.iter().map(|&z| front_bit(z)).collect()
}

/// One depth of `front_bits`.
#[inline(always)]
pub(in crate::reconstruction) fn front_bit(z: f32) -> u32 {
    if z.is_finite() {
        !z.to_bits()
    } else {
        0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reconstruction::splat::channel_stride;

    #[test]
    fn packing_and_unpacking_give_back_the_planar_sums() {
        let (w, h) = (11, 3);
        let cs = channel_stride(w);
        let acc: Vec<f32> = (0..h * CHANNELS * cs).map(|i| i as f32).collect();
        let cover: Vec<f32> = (0..w * h).map(|i| 0.5 * i as f32).collect();
        let packed = pack(&acc, cs, w, &cover);
        assert_eq!(
            packed[PER_PIXEL * (w + 2) + 3],
            acc[(CHANNELS + 3) * cs + 2]
        );
        let (mut acc2, mut cover2) = (vec![0f32; acc.len()], vec![0f32; cover.len()]);
        unpack(&packed, &mut acc2, cs, w, &mut cover2);
        assert_eq!(cover2, cover);
        for y in 0..h {
            for ch in 0..CHANNELS {
                assert_eq!(
                    channel_row(&acc2, cs, y, ch)[..w],
                    channel_row(&acc, cs, y, ch)[..w]
                );
            }
        }
    }

    #[test]
    fn the_holds_mask_sets_the_weight_plane_alone() {
        // 11 × 5 pixels: the bits of a row run on across words.
        let (w, h) = (11, 5);
        let cs = channel_stride(w);
        let mut acc = vec![7.0f32; h * CHANNELS * cs];
        let holds = |p: usize| p % 3 == 0 || p == 40;
        let mut mask = vec![0u32; (w * h).div_ceil(32)];
        for p in (0..w * h).filter(|&p| holds(p)) {
            mask[p / 32] |= 1 << (p % 32);
        }
        unpack_holds(&mask, &mut acc, cs, w);
        for y in 0..h {
            for ch in 0..CHANNELS {
                for x in 0..w {
                    let v = channel_row(&acc, cs, y, ch)[x];
                    let want = match ch {
                        3 if holds(y * w + x) => 1.0,
                        3 => 0.0,
                        _ => 7.0,
                    };
                    assert_eq!(v, want, "pixel ({x}, {y}), channel {ch}");
                }
            }
        }
    }

    #[test]
    fn a_mask_since_the_last_writes_what_the_whole_mask_writes() {
        // 11 × 5 pixels from the last mask, then a carry that took, landed on and cut
        // pixels (weights 0 or the sums landed), then a new mask: only the changed
        // bits and the edited pixels are written, and listed.
        let (w, h) = (11, 5);
        let cs = channel_stride(w);
        let mask_of = |holds: &dyn Fn(usize) -> bool| {
            let mut m = vec![0u32; (w * h).div_ceil(32)];
            for p in (0..w * h).filter(|&p| holds(p)) {
                m[p / 32] |= 1 << (p % 32);
            }
            m
        };
        let last = mask_of(&|p| p % 3 == 0);
        let mask = mask_of(&|p| p % 3 == 0 && p != 9 || p == 40 || p == 7 || p == 12);
        let mut acc = vec![7.0f32; h * CHANNELS * cs];
        unpack_holds(&last, &mut acc, cs, w);
        let e = CarryEdits {
            takes: vec![3, 12],
            lands: vec![(0, 7, false), (1, 21, true)],
            cuts: vec![30],
            ..Default::default()
        };
        let weight = |p: usize| ((p / w) * CHANNELS + 3) * cs + p % w;
        for (p, wt) in [(3, 0.0), (12, 0.0), (7, 1.5), (21, 2.5), (30, 0.0)] {
            acc[weight(p)] = wt;
        }
        let mut whole = acc.clone();
        unpack_holds(&mask, &mut whole, cs, w);
        let mut changed = Vec::new();
        unpack_holds_since(&mask, (&mut acc, cs, w), (&last, &e), &mut changed);
        assert_eq!(acc, whole);
        changed.sort_unstable();
        changed.dedup();
        assert_eq!(changed, [3, 7, 9, 12, 21, 30, 40]);
    }

    #[test]
    fn fronts_keep_their_order_as_bits() {
        let bits = front_bits(&[1.5, 0.25, f32::INFINITY]);
        assert!(
            bits[1] > bits[0],
            "the nearer depth is the larger complement"
        );
        assert_eq!(bits[2], 0);
    }
}
