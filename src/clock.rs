//! The simulated clock: the time base every method and the evaluation share.
//!
//! A method with budget `R` samples per second traces sample `i` at `start + i/R`; the
//! display refreshes at `refresh_hz`. `start` is the evaluated window's first refresh
//! minus a warm-up, so every method shows a steady-state image from the first evaluated
//! refresh on (a framed renderer has finished a frame, a frameless one has covered the
//! screen) instead of being judged on its empty start-up screen.

/// Time base shared by all methods of one evaluation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Clock {
    /// Time of sample 0 (seconds of scene time).
    pub start: f64,
    /// Samples per second.
    pub rate: f64,
    /// Time of the first evaluated refresh.
    pub first_refresh: f64,
    /// Display refresh rate, Hz.
    pub refresh_hz: f64,
}

/// Tolerance for "at or before" comparisons of event times, well below one sample.
pub const TIME_EPS: f64 = 1e-9;

impl Clock {
    /// Time at which sample `i` is traced.
    #[inline]
    pub fn sample_time(&self, i: u64) -> f64 {
        self.start + i as f64 / self.rate
    }

    /// Number of samples traced at or before time `t` (indices `0..n`).
    #[inline]
    pub fn samples_until(&self, t: f64) -> u64 {
        if t < self.start - TIME_EPS {
            return 0;
        }
        ((t - self.start) * self.rate + 1e-6).floor() as u64 + 1
    }

    /// Time of evaluated refresh `k` (k = 0 is the window's start).
    #[inline]
    pub fn refresh_time(&self, k: u64) -> f64 {
        self.first_refresh + k as f64 / self.refresh_hz
    }

    /// The first refresh time (on the display's grid, which extends before
    /// `first_refresh` through the warm-up) at or after `t`.
    pub fn first_refresh_at_or_after(&self, t: f64) -> f64 {
        let k = ((t - self.first_refresh) * self.refresh_hz - 1e-6).ceil();
        self.first_refresh + k / self.refresh_hz
    }
}

/// `400000` → `400K`, `1500000` → `1.5M`.
pub fn rate_label(r: f64) -> String {
    let (v, unit) = if r >= 1e6 {
        (r / 1e6, "M")
    } else if r >= 1e3 {
        (r / 1e3, "K")
    } else {
        (r, "")
    };
    let s = format!("{v:.2}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    format!("{s}{unit}")
}

/// A sample rate that does not parse.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum RateError {
    /// Not a number with an optional k/M suffix.
    #[error("`{0}` is not a rate (e.g. 400k, 1.5M, 100000)")]
    NotARate(String),
    /// Zero, negative or not finite.
    #[error("rate `{0}` must be positive")]
    NotPositive(String),
}

/// Parse `100k`, `1.5M`, `400000` into samples per second.
pub fn parse_rate(s: &str) -> Result<f64, RateError> {
    let t = s.trim();
    let (num, mul) = match t.chars().last() {
        Some('k' | 'K') => (&t[..t.len() - 1], 1e3),
        Some('m' | 'M') => (&t[..t.len() - 1], 1e6),
        _ => (t, 1.0),
    };
    let v: f64 = num.parse().map_err(|_| RateError::NotARate(s.into()))?;
    let v = v * mul;
    if !(v.is_finite() && v > 0.0) {
        return Err(RateError::NotPositive(s.into()));
    }
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hand_worked_times() {
        // 1000 samples/s from t = 0; display at 60 Hz from t = 0.5.
        let c = Clock {
            start: 0.0,
            rate: 1000.0,
            first_refresh: 0.5,
            refresh_hz: 60.0,
        };
        assert_eq!(c.sample_time(0), 0.0);
        assert!((c.sample_time(250) - 0.25).abs() < 1e-12);
        // At t = 0.0105 samples 0..=10 have been traced.
        assert_eq!(c.samples_until(0.0105), 11);
        assert_eq!(
            c.samples_until(0.010),
            11,
            "sample 10 at exactly 0.010 counts"
        );
        assert_eq!(c.samples_until(-1.0), 0);
        assert!((c.refresh_time(3) - 0.55).abs() < 1e-12);
        // Refresh grid: ..., 0.4833, 0.5, 0.5167, ...; a frame done at 0.501 shows at 0.5167.
        assert!((c.first_refresh_at_or_after(0.501) - (0.5 + 1.0 / 60.0)).abs() < 1e-12);
        // Exactly on a refresh: shown at that refresh.
        assert!((c.first_refresh_at_or_after(0.5) - 0.5).abs() < 1e-12);
        assert!((c.first_refresh_at_or_after(0.49) - 0.5).abs() < 1e-9);
        assert!((c.first_refresh_at_or_after(0.48) - (0.5 - 1.0 / 60.0)).abs() < 1e-9);
    }
}
