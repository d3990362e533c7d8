//! Stratified sub-pixel positions for supersampling.

use super::rng::Rng;

/// `n` jittered positions in the unit square, stratified: an `m × m` jittered grid when
/// `n = m²`, otherwise `n`-rooks (one sample per row and per column stratum, columns
/// shuffled). Deterministic in `rng`.
pub fn unit_square(n: u32, rng: &mut Rng) -> Vec<(f32, f32)> {
    let n = n.max(1);
    let m = (n as f64).sqrt().round() as u32;
    if m * m == n {
        let inv = 1.0 / m as f32;
        (0..n)
            .map(|i| {
                let (ix, iy) = (i % m, i / m);
                (
                    (ix as f32 + rng.uniform()) * inv,
                    (iy as f32 + rng.uniform()) * inv,
                )
            })
            .collect()
    } else {
        let inv = 1.0 / n as f32;
        let mut cols: Vec<u32> = (0..n).collect();
        rng.shuffle(&mut cols);
        (0..n)
            .map(|i| {
                (
                    (cols[i as usize] as f32 + rng.uniform()) * inv,
                    (i as f32 + rng.uniform()) * inv,
                )
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_sample_per_stratum() {
        for n in [1u32, 4, 16, 5, 12] {
            let pts = unit_square(n, &mut Rng::new(&[n as u64]));
            assert_eq!(pts.len(), n as usize);
            let m = (n as f64).sqrt().round() as u32;
            if m * m == n {
                let mut seen = vec![false; n as usize];
                for (x, y) in pts {
                    let c = (x * m as f32) as u32 + m * (y * m as f32) as u32;
                    assert!(!seen[c as usize]);
                    seen[c as usize] = true;
                }
            } else {
                let mut cols = vec![false; n as usize];
                for (x, _) in pts {
                    let c = (x * n as f32) as usize;
                    assert!(!cols[c]);
                    cols[c] = true;
                }
            }
        }
    }
}
