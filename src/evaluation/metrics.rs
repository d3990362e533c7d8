//! Image comparison metrics, on images as displayed (8-bit RGB).

use flip_rs::{ldr_flip, RgbImage, DEFAULT_PPD};

/// PSNR reported for identical images (instead of infinity, which JSON cannot hold).
pub const PSNR_CAP_DB: f64 = 99.0;

/// Root-mean-square error over all channels, in 0–255 units.
pub fn rms(a: &[u8], b: &[u8]) -> f64 {
    assert_eq!(a.len(), b.len(), "images must have the same size");
    if a.is_empty() {
        return 0.0;
    }
    let sum: u64 = a
        .iter()
        .zip(b)
        .map(|(&x, &y)| {
            let d = x as i64 - y as i64;
            (d * d) as u64
        })
        .sum();
    (sum as f64 / a.len() as f64).sqrt()
}

/// Peak signal-to-noise ratio in dB for a given RMS (peak 255), capped at
/// [`PSNR_CAP_DB`].
pub fn psnr(rms: f64) -> f64 {
    if rms <= 0.0 {
        return PSNR_CAP_DB;
    }
    (20.0 * (255.0 / rms).log10()).min(PSNR_CAP_DB)
}

/// Temporal instability between two refreshes: mean over channels of
/// `|(shown − shown_prev) − (ideal − ideal_prev)|`, in 0–255 units. Zero when the display
/// changes exactly as the ideal does (including not at all on a still scene).
pub fn instability(shown_prev: &[u8], shown: &[u8], ideal_prev: &[u8], ideal: &[u8]) -> f64 {
    let n = shown.len();
    assert!(shown_prev.len() == n && ideal_prev.len() == n && ideal.len() == n);
    if n == 0 {
        return 0.0;
    }
    let sum: i64 = (0..n)
        .map(|i| {
            let d = shown[i] as i64 - shown_prev[i] as i64;
            let e = ideal[i] as i64 - ideal_prev[i] as i64;
            (d - e).abs()
        })
        .sum();
    sum as f64 / n as f64
}

/// Mean FLIP error (NVIDIA's LDR-FLIP, default viewing distance: 67 pixels per degree)
/// between a reference and a test image of `w × h` 8-bit RGB pixels.
pub fn flip_mean(reference: &[u8], test: &[u8], w: u32, h: u32) -> f64 {
    let r = RgbImage::new(w as usize, h as usize, reference.to_vec());
    let t = RgbImage::new(w as usize, h as usize, test.to_vec());
    match (r, t) {
        (Ok(r), Ok(t)) => {
            ldr_flip(&r, &t, DEFAULT_PPD).map_or(f64::NAN, |m| m.statistics().mean as f64)
        }
        _ => f64::NAN,
    }
}

/// The FLIP error map between a reference and a test image of `w × h` 8-bit RGB
/// pixels, one byte a pixel: the error in [0, 1] on the steps 0–[`FLIP_STEPS`], to be
/// shown with [`flip_palette`]; `None` if the images are not `w × h`. (Indices into a
/// palette, not colours: a third of the size, and FLIP's colour scale has 256 entries.)
pub fn flip_map(reference: &[u8], test: &[u8], w: u32, h: u32) -> Option<Vec<u8>> {
    let values = flip_values(reference, test, w, h)?;
    Some(
        values
            .iter()
            .map(|&v| {
                let v = if v.is_nan() { 1.0 } else { v.clamp(0.0, 1.0) };
                (v * FLIP_STEPS as f32 + 0.5) as u8
            })
            .collect(),
    )
}

/// The FLIP error of every pixel (row-major, in [0, 1]) between a reference and a test
/// image of `w × h` 8-bit RGB pixels; `None` if the images are not `w × h`.
pub fn flip_values(reference: &[u8], test: &[u8], w: u32, h: u32) -> Option<Vec<f32>> {
    let r = RgbImage::new(w as usize, h as usize, reference.to_vec()).ok()?;
    let t = RgbImage::new(w as usize, h as usize, test.to_vec()).ok()?;
    let map = ldr_flip(&r, &t, DEFAULT_PPD).ok()?;
    Some(map.pixels().to_vec())
}

/// The largest value of [`flip_map`]; the value above it is white (a strip's gaps).
pub const FLIP_STEPS: u8 = 254;

/// The colours of [`flip_map`]'s values as 256 RGB triples: FLIP's magma scale (black
/// for no perceived difference, through purple and red, to pale yellow for the
/// largest), and white for 255.
pub fn flip_palette() -> Vec<u8> {
    let mut p: Vec<u8> = (0..=FLIP_STEPS as usize)
        .flat_map(|i| {
            let c = flip_rs::MAGMA[(i * 255 + FLIP_STEPS as usize / 2) / FLIP_STEPS as usize];
            c.map(crate::image::quantize)
        })
        .collect();
    p.extend([255, 255, 255]);
    p
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rms_and_psnr_on_known_images() {
        let a = vec![0u8; 12];
        let mut b = vec![0u8; 12];
        assert_eq!(rms(&a, &b), 0.0);
        assert_eq!(psnr(0.0), PSNR_CAP_DB);
        // One channel off by 12 among 12 values: RMS = sqrt(144/12) = sqrt(12).
        b[5] = 12;
        assert!((rms(&a, &b) - 12f64.sqrt()).abs() < 1e-12);
        // All channels off by 255: RMS 255, PSNR 0 dB.
        let c = vec![255u8; 12];
        assert_eq!(rms(&a, &c), 255.0);
        assert!(psnr(255.0).abs() < 1e-12);
        // RMS 25.5 is 20 dB.
        assert!((psnr(25.5) - 20.0).abs() < 1e-9);
    }

    #[test]
    fn flip_map_is_zero_where_images_agree() {
        let (w, h) = (16, 8);
        let a: Vec<u8> = (0..w * h * 3).map(|i| (i * 7 % 251) as u8).collect();
        let same = flip_map(&a, &a, w, h).expect("a map");
        assert_eq!(same.len(), (w * h) as usize);
        assert!(same.iter().all(|&v| v == 0), "{same:?}");
        let mut b = a.clone();
        for v in &mut b[..w as usize * 3 * 4] {
            *v = 255 - *v;
        }
        let diff = flip_map(&a, &b, w, h).expect("a map");
        let top: u64 = diff[..w as usize * 4].iter().map(|&v| v as u64).sum();
        assert!(top > 10 * w as u64 * 4, "inverted rows show: {diff:?}");
        assert!(diff.iter().all(|&v| v <= FLIP_STEPS));
        assert!(flip_map(&a, &b, w + 1, h).is_none());
        let palette = flip_palette();
        assert_eq!(palette.len(), 256 * 3);
        assert_eq!(&palette[..3], &[0, 0, 4], "magma starts near black");
        assert_eq!(&palette[255 * 3..], &[255, 255, 255]);
    }

    #[test]
    fn instability_counts_only_change_the_ideal_does_not_have() {
        let a = vec![10u8, 20, 30];
        let b = vec![12u8, 20, 27];
        // The display changes exactly as the ideal: no flicker.
        assert_eq!(instability(&a, &b, &a, &b), 0.0);
        // The ideal is still, the display changes by 2 and 3: mean 5/3.
        assert!((instability(&a, &b, &a, &a) - 5.0 / 3.0).abs() < 1e-12);
        // The display is still while the ideal changes: lag counts too.
        assert!((instability(&a, &a, &a, &b) - 5.0 / 3.0).abs() < 1e-12);
    }

    #[test]
    fn flip_is_zero_for_identical_and_positive_otherwise() {
        let a: Vec<u8> = (0..16 * 16 * 3).map(|i| (i * 7 % 256) as u8).collect();
        assert_eq!(flip_mean(&a, &a, 16, 16), 0.0);
        let b: Vec<u8> = a.iter().map(|v| v.wrapping_add(40)).collect();
        assert!(flip_mean(&a, &b, 16, 16) > 0.01);
    }
}
