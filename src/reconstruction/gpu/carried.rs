//! The carried accumulators' trip to the GPU and back ([`super::super::carry`]).
//!
//! The carry step (decay, move, cut) stays on the CPU, which holds the geometry it
//! needs; the GPU only adds the new splats onto what it carried. A refresh uploads
//! the carried sums with the carried coverage in the accumulators' per-pixel layout,
//! and with the visibility pass the initial front depths; it reads the final sums and
//! coverage back, before any fill, so that the next carry starts from them.

use rayon::prelude::*;

use super::PER_PIXEL;
use crate::reconstruction::splat::{channel_row, CHANNELS};

/// What a carrying refresh uploads.
pub(in crate::reconstruction) struct CarriedIn {
    /// Per pixel: the carried weighted red, green, blue, weight, weighted age and
    /// coverage (the GPU accumulators' layout).
    pub(in crate::reconstruction) sums: Vec<f32>,
    /// With the visibility pass: each pixel's initial front depth as the shaders
    /// store it (see [`front_bits`]).
    pub(in crate::reconstruction) front: Option<Vec<u32>>,
}

/// Repack the planar CPU accumulators `acc` (channel stride `cs`) of a `w`-wide
/// image and its coverage `cover` into per-pixel runs of [`PER_PIXEL`] floats.
pub(in crate::reconstruction) fn pack(acc: &[f32], cs: usize, w: usize, cover: &[f32]) -> Vec<f32> {
    let mut out = vec![0f32; cover.len() * PER_PIXEL];
    // Rows are independent: in parallel.
    out.par_chunks_mut(w * PER_PIXEL)
        .zip(cover.par_chunks(w))
        .enumerate()
        .for_each(|(y, (rows, cover))| {
            for ch in 0..CHANNELS {
                let src = &channel_row(acc, cs, y, ch)[..w];
                for (px, &v) in rows.chunks_exact_mut(PER_PIXEL).zip(src) {
                    px[ch] = v;
                }
            }
            for (px, &c) in rows.chunks_exact_mut(PER_PIXEL).zip(cover) {
                px[CHANNELS] = c;
            }
        });
    out
}

/// The inverse of [`pack`]: the GPU's final sums into `acc`, its coverage into
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

/// Front depths as the shaders keep them: the complement of a depth's bits, so that
/// an atomic maximum keeps the nearest (positive) depth; none (infinite) is 0, as in
/// a cleared buffer, which the history also reads as none.
pub(in crate::reconstruction) fn front_bits(front: &[f32]) -> Vec<u32> {
    front
        .iter()
        .map(|&z| if z.is_finite() { !z.to_bits() } else { 0 })
        .collect()
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
    fn fronts_keep_their_order_as_bits() {
        let bits = front_bits(&[1.5, 0.25, f32::INFINITY]);
        assert!(
            bits[1] > bits[0],
            "the nearer depth is the larger complement"
        );
        assert_eq!(bits[2], 0);
    }
}
