//! Hole filling: pixels no splat reached take the weighted mean of the nearest block
//! of a 2×2 pull pyramid of the accumulated sums that has samples, so a hole never
//! shows black unless nothing at all was sampled yet.

use std::collections::HashMap;

use glam::Vec3;

use super::{
    splat::{CHANNELS, MIN_WEIGHT},
    Reconstructor,
};

impl Reconstructor {
    /// Accumulated sums of pixel `(x, y)` (zero for a hole).
    #[inline]
    fn sums(&self, x: usize, y: usize) -> [f64; CHANNELS] {
        if self.sum_at(x, y, 3) >= MIN_WEIGHT {
            std::array::from_fn(|c| self.sum_at(x, y, c) as f64)
        } else {
            [0.0; CHANNELS]
        }
    }

    /// Fill holes from the coarsest-necessary level of a 2×2 pull pyramid of the sums;
    /// returns the sum of the filled pixels' ages. Few holes (the usual case) read only
    /// the blocks around them; many build the whole pyramid. Both add the same values
    /// in the same order, so they give the same image.
    pub(super) fn fill_holes(&mut self, dense: bool) -> f64 {
        let (w, h) = (self.width as usize, self.height as usize);
        let mut dims = vec![(w, h)];
        while let Some(&(lw, lh)) = dims.last().filter(|d| d.0 > 1 || d.1 > 1) {
            dims.push((lw.div_ceil(2), lh.div_ceil(2)));
        }
        if dense {
            let mut pyramid = std::mem::take(&mut self.pyramid);
            pyramid.resize_with(dims.len() - 1, Default::default);
            for k in 1..dims.len() {
                let (nw, nh) = dims[k];
                let (lw, lh) = dims[k - 1];
                let (done, rest) = pyramid.split_at_mut(k - 1);
                let level = &mut rest[0];
                *level = (nw, nh, std::mem::take(&mut level.2));
                level.2.clear();
                level.2.resize(nw * nh, [0.0; CHANNELS]);
                for by in 0..nh {
                    for bx in 0..nw {
                        let mut sum = [0f64; CHANNELS];
                        for (cx, cy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                            let (x, y) = (2 * bx + cx, 2 * by + cy);
                            if x < lw && y < lh {
                                let s = if k == 1 {
                                    self.sums(x, y)
                                } else {
                                    done[k - 2].2[y * lw + x]
                                };
                                for c in 0..CHANNELS {
                                    sum[c] += s[c];
                                }
                            }
                        }
                        level.2[by * nw + bx] = sum;
                    }
                }
            }
            self.pyramid = pyramid;
        }
        let mut memo: HashMap<(usize, usize, usize), [f64; CHANNELS]> = HashMap::new();
        let mut age_sum = 0.0;
        for y in 0..h {
            for x in 0..w {
                if self.sum_at(x, y, 3) >= MIN_WEIGHT {
                    continue;
                }
                let mut out = (Vec3::ZERO, 0.0);
                for k in 1..dims.len() {
                    let s = if dense {
                        self.pyramid[k - 1].2[(y >> k) * dims[k].0 + (x >> k)]
                    } else {
                        self.block_sum(&dims, &mut memo, k, x >> k, y >> k)
                    };
                    if s[3] > 0.0 {
                        let inv = 1.0 / s[3];
                        out = (
                            Vec3::new(
                                (s[0] * inv) as f32,
                                (s[1] * inv) as f32,
                                (s[2] * inv) as f32,
                            ),
                            s[4] * inv,
                        );
                        break;
                    }
                }
                self.image.pixels[y * w + x] = out.0;
                self.age[y * w + x] = out.1 as f32;
                age_sum += out.1;
            }
        }
        age_sum
    }

    /// Sums of block `(bx, by)` of pyramid level `k` (blocks of `2^k × 2^k` pixels),
    /// added as the dense pyramid adds them.
    fn block_sum(
        &self,
        dims: &[(usize, usize)],
        memo: &mut HashMap<(usize, usize, usize), [f64; CHANNELS]>,
        k: usize,
        bx: usize,
        by: usize,
    ) -> [f64; CHANNELS] {
        if k == 0 {
            return self.sums(bx, by);
        }
        if let Some(s) = memo.get(&(k, bx, by)) {
            return *s;
        }
        let (lw, lh) = dims[k - 1];
        let mut sum = [0f64; CHANNELS];
        for (cx, cy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            let (x, y) = (2 * bx + cx, 2 * by + cy);
            if x < lw && y < lh {
                let s = self.block_sum(dims, memo, k - 1, x, y);
                for c in 0..CHANNELS {
                    sum[c] += s[c];
                }
            }
        }
        memo.insert((k, bx, by), sum);
        sum
    }
}
