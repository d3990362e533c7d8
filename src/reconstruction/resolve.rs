//! Resolving the accumulators into the image: weighted sums divided by weight, the
//! coverage map and the splat scale it drives for the next refresh, the mean age;
//! holes go to [`holes`](super::holes).

use glam::Vec3;
use rayon::prelude::*;

use super::{
    splat::{BAND_ROWS, CHANNELS},
    Reconstructor,
};

/// Accumulated weight below which a pixel counts as a hole: far splat tails reach
/// f32's denormal range, where `Σw·c / Σw` loses all precision.
pub(super) const MIN_WEIGHT: f32 = 1e-24;

impl Reconstructor {
    /// Quotients, coverage, splat scale adaptation, hole filling, mean age.
    pub(super) fn resolve(&mut self) {
        let (w, h) = (self.width as usize, self.height as usize);
        let (rs, cs, cstride) = (CHANNELS * self.cs, self.cs, w + 1);
        let p = self.params;
        // Carried coverage (decayed) adds to this refresh's (unread without carrying).
        let carrying = self.carries_now();
        let per_band: Vec<(usize, usize, f64)> = self
            .image
            .pixels
            .par_chunks_mut(BAND_ROWS * w)
            .zip(self.coverage.par_chunks_mut(BAND_ROWS * w))
            .zip(self.scale.par_chunks_mut(BAND_ROWS * w))
            .zip(self.age.par_chunks_mut(BAND_ROWS * w))
            .zip(self.acc.par_chunks(BAND_ROWS * rs))
            .zip(self.cov.par_chunks(BAND_ROWS * cstride))
            .zip(self.cover.par_chunks_mut(BAND_ROWS * w))
            .map(|((((((px, coverage), scale), ages), acc), cov), cover)| {
                let (mut holes, mut thin, mut age) = (0usize, 0usize, 0f64);
                for (r, ((((px, coverage), scale), ages), cover)) in px
                    .chunks_mut(w)
                    .zip(coverage.chunks_mut(w))
                    .zip(scale.chunks_mut(w))
                    .zip(ages.chunks_mut(w))
                    .zip(cover.chunks_mut(w))
                    .enumerate()
                {
                    let sums = &acc[r * rs..(r + 1) * rs];
                    let ch = |c: usize| &sums[c * cs..c * cs + w];
                    let (sr, sg, sb, sw, sa) = (ch(0), ch(1), ch(2), ch(3), ch(4));
                    let cov = &cov[r * cstride..(r + 1) * cstride];
                    let mut count = 0i32;
                    for x in 0..w {
                        let (cr, cg, cb, cw, ca) = (sr[x], sg[x], sb[x], sw[x], sa[x]);
                        count += cov[x];
                        let n = if carrying {
                            cover[x] += count as f32;
                            cover[x].round() as u32
                        } else {
                            count as u32
                        };
                        coverage[x] = n;
                        let s = &mut scale[x];
                        if n < p.undersampled {
                            *s *= p.grow;
                        } else if n > p.oversampled {
                            *s *= p.shrink;
                        }
                        *s = s.clamp(p.scale_bounds.0, p.scale_bounds.1);
                        thin += (cw < p.fill_weight) as usize;
                        if cw >= MIN_WEIGHT {
                            px[x] = Vec3::new(cr / cw, cg / cw, cb / cw);
                            ages[x] = ca / cw;
                            age += (ca / cw) as f64;
                        } else {
                            holes += 1;
                        }
                    }
                }
                (holes, thin, age)
            })
            .collect();
        // Band order, so the sum does not depend on the thread count.
        let mut age_sum: f64 = per_band.iter().map(|b| b.2).sum();
        let holes: usize = per_band.iter().map(|b| b.0).sum();
        let thin: usize = per_band.iter().map(|b| b.1).sum();
        self.holes = holes;
        if thin > 0 {
            age_sum = self.pull_push(p.fill_weight);
        } else if holes > 0 {
            age_sum += self.fill_holes(self.holes * 64 > w * h);
        }
        self.mean_age = age_sum / (w * h).max(1) as f64;
    }
}
