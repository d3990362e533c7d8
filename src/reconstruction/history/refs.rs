//! Reference colours, so that a flat surface is shown at exactly its value.
//!
//! A pixel's colour is a weighted mean of samples, and in f32 a weighted mean of
//! samples that are all `c` comes out a rounding or two above or below `c`. Most of
//! the time that is nothing; but scene files give colours as decimals, and a
//! decimal such as 0.3 or 0.5 is exactly half-way between two display codes (0.3 ·
//! 255 = 76.5). The ideal image, a plain mean of equal values, stays on `c` and shows
//! 77; a rounding below shows 76. On a flat wall that the adaptive sampler left
//! sparse (museum4 after its camera stops: most of its pixels without a sample, so
//! without history, of their own) a quarter of the wall's pixels were a code off, and FLIP was 20 times what showing the newest sample
//! gives.
//!
//! So each block of [`BLOCK`]×[`BLOCK`] pixels keeps the colour of a sample that
//! landed in it at the latest refresh any did, and the blend shows that colour instead
//! of what it made wherever the two differ by no more than [`TOLERANCE`] of it: a few
//! roundings, a thousandth of a display code. What is shown moves by at most that,
//! however stale the reference, so the block's colour needs no care when the view
//! moves; it only has to be a value that samples really took.

/// Side of a block of pixels that shares one reference colour. It divides the
/// history's bands ([`super::BLEND_ROWS`] rows), so that each band owns its blocks.
pub(in crate::reconstruction) const BLOCK: usize = 4;
const _: () = assert!(super::BLEND_ROWS % BLOCK == 0);

/// How far, relative to the reference, a colour is snapped to it: about 8 roundings
/// of an f32 (2⁻²³ each), where a display code is 1/255 of the range.
pub(in crate::reconstruction) const TOLERANCE: f32 = 1e-6;

/// The reference colour of every block, in planes (red, green, blue), a row of
/// blocks after another; NaN where no sample has landed yet.
pub(super) struct Refs {
    /// Pixels per row.
    width: u32,
    /// Blocks per row.
    across: usize,
    colour: [Vec<f32>; 3],
}

/// How many blocks a `width × height` image has: whole rows of them, the last
/// column and row of blocks partly outside the image.
pub(in crate::reconstruction) fn block_count(width: usize, height: usize) -> usize {
    width.div_ceil(BLOCK) * height.div_ceil(BLOCK)
}

impl Refs {
    /// The blocks of a `width × height` image, none with a reference yet.
    pub(super) fn new(width: usize, height: usize) -> Self {
        let n = block_count(width, height);
        Self {
            width: width as u32,
            across: width.div_ceil(BLOCK),
            colour: std::array::from_fn(|_| vec![f32::NAN; n]),
        }
    }

    /// The blocks of each band of `rows` pixel rows, borrowed, band after band.
    pub(super) fn bands_mut(&mut self, rows: usize) -> Vec<BandRefs<'_>> {
        let len = rows / BLOCK * self.across;
        let [r, g, b] = &mut self.colour;
        r.chunks_mut(len)
            .zip(g.chunks_mut(len))
            .zip(b.chunks_mut(len))
            .map(|((r, g), b)| BandRefs {
                across: self.across,
                width: self.width,
                colour: [r, g, b],
            })
            .collect()
    }

    /// The references of the blocks pixel row `y` lies in: one per [`BLOCK`] pixels.
    pub(super) fn row(&self, y: usize) -> [&[f32]; 3] {
        let at = y / BLOCK * self.across;
        self.colour.each_ref().map(|c| &c[at..at + self.across])
    }
}

/// The blocks of one band of rows, borrowed.
pub(super) struct BandRefs<'a> {
    across: usize,
    width: u32,
    colour: [&'a mut [f32]; 3],
}

impl BandRefs<'_> {
    /// A sample of colour `c` landed in the band's pixel `q` (from the band's first).
    #[inline]
    pub(super) fn set(&mut self, q: usize, c: glam::Vec3) {
        // A 32-bit division: a band's pixels are far fewer than 2³².
        let (y, x) = (
            (q as u32 / self.width) as usize,
            (q as u32 % self.width) as usize,
        );
        let b = y / BLOCK * self.across + x / BLOCK;
        for (plane, v) in self.colour.iter_mut().zip(c.to_array()) {
            plane[b] = v;
        }
    }
}

/// `v`, or the reference `r` where `v` is within [`TOLERANCE`] of it (never where `r`
/// is NaN or infinite: every value is within an infinite tolerance). Branch-free, for
/// the blend's vector loops.
#[inline(always)]
pub(super) fn exact(v: f32, r: f32) -> f32 {
    let within = r.abs() * TOLERANCE;
    if (v - r).abs() <= within && within < f32::INFINITY {
        r
    } else {
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn a_colour_within_roundings_of_its_blocks_reference_is_shown_as_the_reference() {
        let c = 0.3f32;
        let below = f32::from_bits(c.to_bits() - 3);
        assert_eq!(exact(below, c), c);
        assert_eq!(exact(f32::from_bits(c.to_bits() + 3), c), c);
        // A display code away is not a rounding.
        assert_eq!(exact(c - 1.0 / 255.0, c), c - 1.0 / 255.0);
        assert_eq!(exact(below, f32::NAN), below);
        assert_eq!(exact(below, f32::INFINITY), below);
        assert_eq!(exact(below, f32::NEG_INFINITY), below);
        assert_eq!(exact(f32::INFINITY, f32::INFINITY), f32::INFINITY);
        assert_eq!(exact(0.0, 0.0), 0.0);
    }

    #[test]
    fn each_band_writes_only_its_own_blocks() {
        let (w, h) = (10, 2 * super::super::BLEND_ROWS + 3);
        let mut refs = Refs::new(w, h);
        for (k, mut band) in refs
            .bands_mut(super::super::BLEND_ROWS)
            .into_iter()
            .enumerate()
        {
            band.set(9, Vec3::splat(k as f32));
        }
        for (k, y) in [0, super::super::BLEND_ROWS, 2 * super::super::BLEND_ROWS]
            .iter()
            .enumerate()
        {
            let [r, ..] = refs.row(*y);
            assert_eq!(r[9 / BLOCK], k as f32, "band {k}");
            assert!(r[0].is_nan());
        }
        let [r, ..] = refs.row(1);
        assert_eq!(r[2], 0.0, "rows 0 to 3 share a block row");
        let [r, ..] = refs.row(BLOCK);
        assert!(r[2].is_nan());
    }
}
