//! Choosing a filter (paper §5.1): space-time extents from the local sample rate and the
//! local gradients.
//!
//! Convention: an *extent* is the standard deviation (sigma) of the Gaussian kernel in
//! that dimension, `w = exp(−½((dx/e_x)² + (dy/e_y)² + (age/e_t)²))`. The paper's volume
//! constraint `e_x·e_y·e_t = V_s` is applied to these sigmas.

/// Space-time extents of a Gaussian filter: standard deviations in pixels (`ex`, `ey`)
/// and seconds (`et`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Extents {
    /// Sigma along x, pixels.
    pub ex: f64,
    /// Sigma along y, pixels.
    pub ey: f64,
    /// Sigma in time (sample age), seconds.
    pub et: f64,
}

/// Clamps applied when choosing extents.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FilterBounds {
    /// Floor of `|G_x|` and `|G_y|` (luminance per pixel), so that a flat region gives a
    /// finite filter instead of an infinite or NaN one.
    pub min_gradient_xy: f64,
    /// Floor of `|G_t|` (luminance per second).
    pub min_gradient_t: f64,
    /// Range of `e_x` and `e_y`, pixels.
    pub extent_xy: (f64, f64),
    /// Range of `e_t`, seconds.
    pub extent_t: (f64, f64),
    /// Range of the sample volume `V_s`, pixel²·seconds (guards against a zero rate).
    pub volume: (f64, f64),
}

impl Default for FilterBounds {
    /// Gradient floors 1e-3 (a flat static region then gets equal extents in pixels and
    /// seconds: `e_x = e_y = e_t = ∛V_s`); `e_x, e_y ∈ [0.4, 8]` px (0.4 px sigma is the
    /// narrowest kernel that, cut at 2.5 sigma, still reaches the pixel containing the
    /// sample); `e_t ∈ [1/240, 2]` s (a quarter of a 60 Hz refresh to two seconds).
    fn default() -> Self {
        Self {
            min_gradient_xy: 1e-3,
            min_gradient_t: 1e-3,
            extent_xy: (0.4, 8.0),
            extent_t: (1.0 / 240.0, 2.0),
            volume: (1e-9, 1e9),
        }
    }
}

/// Local sample rate `R_l` (samples per pixel per second) of a tile of `tile_area`
/// pixels when the sampler spends `rate` samples per second choosing each of `tiles`
/// tiles uniformly: `R_l = R / (|tiles| · area)`.
pub fn local_rate(rate: f64, tiles: usize, tile_area: u32) -> f64 {
    rate / (tiles.max(1) as f64 * tile_area.max(1) as f64)
}

/// The paper's closed form: extents spanning equal expected color change in each
/// dimension (`e_x·G_x = e_y·G_y = e_t·G_t`) with volume `e_x·e_y·e_t = V_s`.
///
/// Gradients are taken in absolute value and floored (`bounds.min_gradient_*`); the
/// extents are then clamped to `bounds`, and the volume lost or gained by clamping is
/// redistributed (equally in log space) over the dimensions not at the bound in the
/// needed direction, so the volume constraint holds whenever the clamps allow it.
pub fn extents(v_s: f64, gx: f64, gy: f64, gt: f64, bounds: &FilterBounds) -> Extents {
    extents_in(v_s, gx, gy, gt, bounds, &bounds.logs())
}

/// The logarithms of a [`FilterBounds`]' extent ranges, `[x, y, t]`, worked out once
/// for a whole table of tiles (six of the thirteen logarithms and exponentials a tile's
/// extents would otherwise take).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LogBounds {
    lo: [f64; 3],
    hi: [f64; 3],
}

impl FilterBounds {
    /// The logarithms of the extent ranges, for [`extents_in`].
    pub fn logs(&self) -> LogBounds {
        LogBounds {
            lo: [
                self.extent_xy.0.ln(),
                self.extent_xy.0.ln(),
                self.extent_t.0.ln(),
            ],
            hi: [
                self.extent_xy.1.ln(),
                self.extent_xy.1.ln(),
                self.extent_t.1.ln(),
            ],
        }
    }
}

/// [`extents`] with the bounds' logarithms given (`logs` must be `bounds.logs()`): the
/// same extents, bit for bit.
pub fn extents_in(
    v_s: f64,
    gx: f64,
    gy: f64,
    gt: f64,
    bounds: &FilterBounds,
    logs: &LogBounds,
) -> Extents {
    let v = if v_s.is_finite() {
        v_s.clamp(bounds.volume.0, bounds.volume.1)
    } else {
        bounds.volume.1
    };
    let fl = |g: f64, m: f64| {
        let g = g.abs();
        if g.is_finite() {
            g.max(m)
        } else {
            1.0 / m
        }
    };
    let gx = fl(gx, bounds.min_gradient_xy);
    let gy = fl(gy, bounds.min_gradient_xy);
    let gt = fl(gt, bounds.min_gradient_t);
    // In logs: ln e_x = (ln V + ln G_y + ln G_t − 2 ln G_x)/3, etc. (no overflow).
    let (lv, lx, ly, lt) = (v.ln(), gx.ln(), gy.ln(), gt.ln());
    let mut l = [
        (lv + ly + lt - 2.0 * lx) / 3.0,
        (lv + lx + lt - 2.0 * ly) / 3.0,
        (lv + lx + ly - 2.0 * lt) / 3.0,
    ];
    let (lo, hi) = (logs.lo, logs.hi);
    for k in 0..3 {
        l[k] = l[k].clamp(lo[k], hi[k]);
    }
    for _ in 0..3 {
        let deficit = lv - (l[0] + l[1] + l[2]);
        if deficit.abs() < 1e-12 {
            break;
        }
        let free = [0, 1, 2].map(|k| {
            (deficit > 0.0 && l[k] < hi[k] - 1e-12) || (deficit < 0.0 && l[k] > lo[k] + 1e-12)
        });
        let n_free = free.iter().filter(|&&f| f).count();
        if n_free == 0 {
            break;
        }
        let share = deficit / n_free as f64;
        for k in 0..3 {
            if free[k] {
                l[k] = (l[k] + share).clamp(lo[k], hi[k]);
            }
        }
    }
    Extents {
        ex: l[0].exp(),
        ey: l[1].exp(),
        et: l[2].exp(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closed_form_holds_without_clamps() {
        let b = FilterBounds::default();
        let (v, gx, gy, gt) = (0.2, 0.02, 0.05, 0.3);
        let e = extents(v, gx, gy, gt, &b);
        assert!((e.ex * e.ey * e.et / v - 1.0).abs() < 1e-9, "{e:?}");
        assert!((e.ex * gx / (e.ey * gy) - 1.0).abs() < 1e-9);
        assert!((e.ex * gx / (e.et * gt) - 1.0).abs() < 1e-9);
    }

    #[test]
    fn clamps_keep_volume_when_possible() {
        let b = FilterBounds::default();
        // Huge temporal gradient: e_t would fall below 1/240 s.
        let e = extents(0.2, 1e-3, 1e-3, 1e4, &b);
        assert!((e.et - b.extent_t.0).abs() < 1e-12);
        assert!((e.ex * e.ey * e.et / 0.2 - 1.0).abs() < 1e-9, "{e:?}");
        // Zero and NaN gradients stay finite.
        let e = extents(0.2, 0.0, f64::NAN, 0.0, &b);
        assert!(e.ex.is_finite() && e.ey.is_finite() && e.et.is_finite());
        // Infeasible volume: everything at the upper bound.
        let e = extents(1e6, 0.0, 0.0, 0.0, &b);
        assert!((e.ex - 8.0).abs() < 1e-9 && (e.ey - 8.0).abs() < 1e-9);
        assert!((e.et - 2.0).abs() < 1e-9);
    }

    #[test]
    fn local_rate_splits_the_budget() {
        assert_eq!(local_rate(400.0, 4, 10), 10.0);
    }
}
