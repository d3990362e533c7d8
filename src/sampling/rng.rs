//! A counter-based random number generator (hash of a key), in the pbrt-v4 spirit:
//! randomness is a pure function of its coordinates.

/// SplitMix64 finaliser: a strong 64-bit mixing function.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Hash several words into one.
#[inline]
pub fn hash(words: &[u64]) -> u64 {
    let mut h = 0x9e37_79b9_7f4a_7c15u64;
    for &w in words {
        h = mix64(h ^ w.wrapping_mul(0x9e37_79b9_7f4a_7c15));
    }
    h
}

/// A uniform `f32` in `[0, 1)` from 64 random bits.
#[inline]
pub fn to_unit_f32(bits: u64) -> f32 {
    ((bits >> 40) as f32) * (1.0 / (1u64 << 24) as f32)
}

/// A small sequential generator seeded from a key; cheap to create per pixel or per
/// work item so that its stream depends only on that key.
#[derive(Clone, Debug)]
pub struct Rng {
    state: u64,
}

impl Rng {
    /// A generator whose stream is determined by `key`.
    pub fn new(key: &[u64]) -> Self {
        Self { state: hash(key) }
    }

    /// Next 64 random bits.
    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        mix64(self.state)
    }

    /// Uniform in `[0, 1)`.
    #[inline]
    pub fn uniform(&mut self) -> f32 {
        to_unit_f32(self.next_u64())
    }

    /// Uniform integer in `[0, n)` (n > 0), by multiply-shift (unbiased enough for
    /// `n` far below 2³²).
    #[inline]
    pub fn below(&mut self, n: u32) -> u32 {
        (((self.next_u64() >> 32) * n as u64) >> 32) as u32
    }

    /// Shuffle a slice in place (Fisher–Yates).
    pub fn shuffle<T>(&mut self, v: &mut [T]) {
        for i in (1..v.len()).rev() {
            let j = self.below(i as u32 + 1) as usize;
            v.swap(i, j);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deterministic_and_roughly_uniform() {
        let mut a = Rng::new(&[1, 2, 3]);
        let mut b = Rng::new(&[1, 2, 3]);
        let xs: Vec<f32> = (0..10000).map(|_| a.uniform()).collect();
        assert!(xs
            .iter()
            .zip((0..).map(|_| b.uniform()))
            .all(|(x, y)| *x == y));
        assert!(xs.iter().all(|x| (0.0..1.0).contains(x)));
        let mean = xs.iter().sum::<f32>() / xs.len() as f32;
        assert!((mean - 0.5).abs() < 0.02, "{mean}");
        assert_ne!(
            Rng::new(&[1, 2, 4]).uniform(),
            Rng::new(&[1, 2, 3]).uniform()
        );
    }
}
