//! Lag told apart from flicker. A per-refresh error (RMS, FLIP) cannot say whether a
//! display is wrong because it shows the scene late or because it shimmers around the
//! right picture, and a viewer sees the two differently: the eye integrates light over
//! roughly a tenth of a second, so what persists through that time is seen as the
//! picture (and a late or smeared picture as lag), while what changes within it is seen
//! as flicker and dust.
//!
//! So each refresh's error is judged over the [`EYE_WINDOW_S`] that end at it: the last
//! `n` refreshes ([`window_refreshes`]). With `e_j = D_j − I_j` the displayed minus the
//! ideal image at refresh `j` (8-bit values, per pixel and channel) and `ē` its mean
//! over the window (a box filter, the same for display and ideal, so `ē` is the
//! averaged display minus the averaged ideal):
//!
//! - **sustained** = `√(mean over pixels and channels of ē²)`: the averaged display
//!   against the averaged ideal. A display that lags or smears keeps its error from one
//!   refresh to the next, so it stays in the average.
//! - **transient** = `√(mean over pixels, channels and the window's refreshes of (e_j −
//!   ē)²)`: what the average takes away, the error's own fluctuation within the window.
//!   Flicker and noise that changes every refresh live here.
//!
//! The two split the window's mean squared error exactly: `sustained² + transient²` is
//! the mean of `RMS²` over the window's refreshes. A refresh with fewer than `n`
//! refreshes of the window before it has neither.

use rayon::prelude::*;

/// How long the eye integrates, seconds: the window over which [`split`] averages.
pub const EYE_WINDOW_S: f64 = 0.1;

/// The refreshes in [`EYE_WINDOW_S`] at `refresh_hz` (6 at 60 Hz), at least one.
pub fn window_refreshes(refresh_hz: f64) -> usize {
    let n = (EYE_WINDOW_S * refresh_hz).round();
    if n.is_finite() && n >= 1.0 {
        n as usize
    } else {
        1
    }
}

/// One window's error, in 0–255 units, split as the module says.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Split {
    /// The averaged display against the averaged ideal: lag, smear, lasting bias.
    pub sustained: f64,
    /// The error's fluctuation about that average within the window: flicker, dust.
    pub transient: f64,
}

/// The split of the window made of the displayed images `shown` and the ideal images
/// `ideal` of the same refreshes, in order; every image the same size.
pub fn split<S: AsRef<[u8]>>(shown: &[S], ideal: &[S]) -> Split {
    let n = shown.len();
    assert!(n > 0 && ideal.len() == n, "a window of matching images");
    let len = shown[0].as_ref().len();
    assert!(
        shown.iter().chain(ideal).all(|s| s.as_ref().len() == len),
        "images of one size"
    );
    if len == 0 {
        return Split {
            sustained: 0.0,
            transient: 0.0,
        };
    }
    // Integer sums: exact, so the two parts add up to the window's mean squared error
    // with no rounding between them.
    let (sq_mean, spread) = (0..len)
        .map(|i| {
            let (mut s, mut s2) = (0i64, 0i64);
            for (d, id) in shown.iter().zip(ideal) {
                let e = d.as_ref()[i] as i64 - id.as_ref()[i] as i64;
                s += e;
                s2 += e * e;
            }
            // n²·ē² and n²·mean((e − ē)²), both whole numbers.
            ((s * s) as u128, (n as i64 * s2 - s * s) as u128)
        })
        .fold((0u128, 0u128), |a, b| (a.0 + b.0, a.1 + b.1));
    let scale = (n * n) as f64 * len as f64;
    Split {
        sustained: (sq_mean as f64 / scale).sqrt(),
        transient: (spread as f64 / scale).sqrt(),
    }
}

/// The split at every refresh of a run whose displayed images are `shown` and ideal
/// images `ideal`, each over the `n` refreshes ending at it; `None` where fewer than
/// `n` refreshes have been shown.
pub fn per_refresh<S: AsRef<[u8]> + Sync>(
    shown: &[S],
    ideal: &[S],
    n: usize,
) -> Vec<Option<Split>> {
    assert_eq!(
        shown.len(),
        ideal.len(),
        "a displayed image per ideal image"
    );
    let n = n.max(1);
    (0..shown.len())
        .into_par_iter()
        .map(|k| (k + 1 >= n).then(|| split(&shown[k + 1 - n..=k], &ideal[k + 1 - n..=k])))
        .collect()
}

/// The mean of the values present, `None` if there are none (a run shorter than one
/// window, or a file written before these errors were measured).
pub fn mean_of(values: impl Iterator<Item = Option<f64>>) -> Option<f64> {
    let (sum, count) = values
        .flatten()
        .fold((0.0, 0usize), |(s, c), v| (s + v, c + 1));
    (count > 0).then(|| sum / count as f64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::evaluation::metrics::rms;

    const W: usize = 64;
    const H: usize = 8;

    /// A vertical grating whose period is the image's width, shifted `shift` pixels
    /// to the right: smooth, so that a small move changes every pixel a little.
    fn grating(shift: f64) -> Vec<u8> {
        let mut im = Vec::with_capacity(W * H * 3);
        for _y in 0..H {
            for x in 0..W {
                let phase = std::f64::consts::TAU * (x as f64 - shift) / W as f64;
                let v = (128.0 + 100.0 * phase.sin()).round() as u8;
                im.extend([v, v, v / 2 + 20]);
            }
        }
        im
    }

    #[test]
    fn the_window_is_a_tenth_of_a_second() {
        assert_eq!(window_refreshes(60.0), 6);
        assert_eq!(window_refreshes(30.0), 3);
        assert_eq!(window_refreshes(144.0), 14);
        assert_eq!(window_refreshes(1.0), 1);
        assert_eq!(window_refreshes(f64::NAN), 1);
    }

    #[test]
    fn a_frozen_display_under_motion_is_sustained_error_not_transient() {
        // The grating moves half a pixel a refresh; the display froze on the first.
        let ideal: Vec<Vec<u8>> = (0..60).map(|k| grating(0.5 * k as f64)).collect();
        let shown: Vec<Vec<u8>> = (0..60).map(|_| grating(0.0)).collect();
        let n = window_refreshes(60.0);
        let splits = per_refresh(&shown, &ideal, n);
        assert!(splits[..n - 1].iter().all(Option::is_none));
        let first = splits[n - 1].expect("a full window");
        let last = splits[59].expect("a full window");
        // Half a second on, the display is almost half a period behind: all lag.
        assert!(last.sustained > 100.0, "{last:?}");
        assert!(last.transient < 0.1 * last.sustained, "{last:?}");
        // The lag grows, and so does the sustained part; the transient part is the
        // ideal's own change within 100 ms, which does not.
        assert!(last.sustained > 5.0 * first.sustained, "{first:?} {last:?}");
        assert!(
            (last.transient - first.transient).abs() < 0.1 * first.transient,
            "{first:?} {last:?}"
        );
        // `instability` counts this lag at the rate the scene moves, the same on the
        // last refresh as on the first.
        let inst = |k: usize| {
            super::super::metrics::instability(&shown[k - 1], &shown[k], &ideal[k - 1], &ideal[k])
        };
        assert!(
            (inst(59) - inst(n - 1)).abs() < 0.2 * inst(n - 1),
            "{} {}",
            inst(n - 1),
            inst(59)
        );
    }

    #[test]
    fn a_flickering_display_over_a_still_scene_is_transient_error_not_sustained() {
        // The scene stands still; the display alternates between two images whose
        // average is the ideal (each value ±20 about it).
        let still = grating(3.0);
        let ideal: Vec<Vec<u8>> = (0..60).map(|_| still.clone()).collect();
        let up: Vec<u8> = still.iter().map(|&v| v + 20).collect();
        let down: Vec<u8> = still.iter().map(|&v| v - 20).collect();
        let shown: Vec<Vec<u8>> = (0..60)
            .map(|k| if k % 2 == 0 { up.clone() } else { down.clone() })
            .collect();
        let splits: Vec<Split> = per_refresh(&shown, &ideal, window_refreshes(60.0))
            .into_iter()
            .flatten()
            .collect();
        assert_eq!(splits.len(), 55);
        for s in splits {
            assert!(s.sustained < 1e-9, "{s:?}");
            assert!((s.transient - 20.0).abs() < 1e-9, "{s:?}");
        }
    }

    #[test]
    fn noise_is_mostly_transient_and_the_parts_add_up_to_the_window_mse() {
        // Noise drawn anew every refresh: the eye's average removes most of it.
        let ideal: Vec<Vec<u8>> = (0..6).map(|k| grating(0.5 * k as f64)).collect();
        let shown: Vec<Vec<u8>> = ideal
            .iter()
            .enumerate()
            .map(|(k, im)| {
                im.iter()
                    .enumerate()
                    .map(|(i, &v)| {
                        let r = crate::sampling::rng::hash(&[7, k as u64, i as u64]);
                        (v as i64 + (r % 41) as i64 - 20).clamp(0, 255) as u8
                    })
                    .collect()
            })
            .collect();
        let s = split(&shown, &ideal);
        assert!(s.transient > 2.0 * s.sustained, "{s:?}");
        let mse: f64 = shown
            .iter()
            .zip(&ideal)
            .map(|(d, i)| rms(i, d).powi(2))
            .sum::<f64>()
            / 6.0;
        let parts = s.sustained.powi(2) + s.transient.powi(2);
        assert!((parts - mse).abs() < 1e-9 * mse, "{parts} against {mse}");
    }

    #[test]
    fn a_display_equal_to_the_ideal_has_no_error_of_either_kind() {
        let ideal: Vec<Vec<u8>> = (0..10).map(|k| grating(k as f64)).collect();
        let splits = per_refresh(&ideal, &ideal, 6);
        assert_eq!(splits.iter().flatten().count(), 5);
        for s in splits.into_iter().flatten() {
            assert_eq!(
                s,
                Split {
                    sustained: 0.0,
                    transient: 0.0
                }
            );
        }
    }
}
