//! Keyframe splines of BART: Kochanek–Bartels (TCB) Hermite curves for translation and
//! scale, squad on quaternions with TCB tangents in log space for rotation.
//!
//! Semantics follow `AFF_FORMAT.md` (from BART's `kbsplpos.c`/`kbsplrot.c`): with `n` keys
//! there are `n − 3` segments between keys `1 ..= n − 2`; the first and last key only
//! shape the end tangents, and time is clamped to `[t_1, t_{n−2}]`. Degenerate data
//! (repeated or decreasing key times) never produces NaN: zero-length segments evaluate to
//! their start key and non-positive tangent scales fall back to 1.

use glam::{Mat4, Quat, Vec3, Vec4};

/// One key of a TCB spline: time, value, tension, continuity, bias.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TcbKey<T> {
    /// Key time in seconds.
    pub time: f32,
    /// Value at the key.
    pub value: T,
    /// Tension: 1 tightens the curve at the key, −1 slackens it.
    pub tension: f32,
    /// Continuity: 0 is smooth, ±1 makes a corner.
    pub continuity: f32,
    /// Bias: −1 leans the tangent toward the next key, +1 toward the previous.
    pub bias: f32,
}

impl<T> TcbKey<T> {
    /// A Catmull–Rom key: tension, continuity and bias zero.
    pub fn catmull_rom(time: f32, value: T) -> Self {
        Self {
            time,
            value,
            tension: 0.0,
            continuity: 0.0,
            bias: 0.0,
        }
    }
}

/// Minimum number of keys of a translation, rotation or scale track.
pub const MIN_SPLINE_KEYS: usize = 4;

/// Tangent scale `2·(t2 − t1)/(span)` with a safe fallback for degenerate spans.
fn adjust(seg: f32, span: f32) -> f32 {
    if span > 0.0 && seg >= 0.0 && (2.0 * seg / span).is_finite() {
        2.0 * seg / span
    } else {
        1.0
    }
}

/// Locate the segment for time `t`: returns `(i1, u)` with the segment from key `i1` to
/// `i1 + 1` and `u ∈ [0, 1]`. `times.len()` must be at least 4.
fn locate(times: &[f32], t: f32) -> (usize, f32) {
    let n = times.len();
    let (lo, hi) = (times[1], times[n - 2]);
    // Clamp first; NaN-safe because max/min ignore NaN in favour of the bound.
    let t = t.max(lo).min(hi.max(lo));
    let mut i1 = n - 3;
    for i in 1..=n - 3 {
        if t < times[i + 1] {
            i1 = i;
            break;
        }
    }
    let dt = times[i1 + 1] - times[i1];
    let u = if dt > 0.0 {
        ((t - times[i1]) / dt).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (i1, u)
}

/// A Kochanek–Bartels spline of 3-vectors (translation or scale).
#[derive(Clone, Debug, PartialEq)]
pub struct VectorSpline {
    keys: Vec<TcbKey<Vec3>>,
    times: Vec<f32>,
}

impl VectorSpline {
    /// Build from keys in file order; needs at least [`MIN_SPLINE_KEYS`] keys.
    pub fn new(keys: Vec<TcbKey<Vec3>>) -> Option<Self> {
        if keys.len() < MIN_SPLINE_KEYS {
            return None;
        }
        let times = keys.iter().map(|k| k.time).collect();
        Some(Self { keys, times })
    }

    /// The keys as given.
    pub fn keys(&self) -> &[TcbKey<Vec3>] {
        &self.keys
    }

    /// Value at time `t` (clamped to the valid range).
    pub fn eval(&self, t: f32) -> Vec3 {
        let (i1, u) = locate(&self.times, t);
        let k = &self.keys;
        let (k0, k1, k2, k3) = (&k[i1 - 1], &k[i1], &k[i1 + 1], &k[i1 + 2]);
        let (p0, p1, p2, p3) = (k0.value, k1.value, k2.value, k3.value);
        let seg = k2.time - k1.time;
        let adj0 = adjust(seg, k2.time - k0.time);
        let adj1 = adjust(seg, k3.time - k1.time);
        let (t1, c1, b1) = (k1.tension, k1.continuity, k1.bias);
        let (t2, c2, b2) = (k2.tension, k2.continuity, k2.bias);
        let tout = 0.5
            * adj0
            * (1.0 - t1)
            * ((1.0 + c1) * (1.0 + b1) * (p1 - p0) + (1.0 - c1) * (1.0 - b1) * (p2 - p1));
        let tin = 0.5
            * adj1
            * (1.0 - t2)
            * ((1.0 - c2) * (1.0 + b2) * (p2 - p1) + (1.0 + c2) * (1.0 - b2) * (p3 - p2));
        let d = p2 - p1;
        let c2v = 3.0 * d - 2.0 * tout - tin;
        let c3v = -2.0 * d + tout + tin;
        p1 + u * (tout + u * (c2v + u * c3v))
    }
}

/// Quaternion logarithm of a unit quaternion, as a pure-vector quaternion's vector part.
fn qlog(q: Quat) -> Vec3 {
    let v = Vec3::new(q.x, q.y, q.z);
    let s = v.length();
    if s < 1e-7 {
        return Vec3::ZERO;
    }
    let theta = s.atan2(q.w);
    v * (theta / s)
}

/// Quaternion exponential of a pure-vector quaternion.
fn qexp(v: Vec3) -> Quat {
    let theta = v.length();
    if theta < 1e-7 {
        return Quat::from_xyzw(v.x, v.y, v.z, 1.0).normalize();
    }
    let s = theta.sin() / theta;
    Quat::from_xyzw(v.x * s, v.y * s, v.z * s, theta.cos())
}

/// Spherical linear interpolation without the shortest-path flip (squad needs the raw
/// great arc between its control quaternions).
fn slerp_raw(a: Quat, b: Quat, u: f32) -> Quat {
    if a == b {
        // Exactly `a`, so that a rotation held between equal keys does not change in
        // its last bits from one moment to the next.
        return a;
    }
    let d = Vec4::from(a).dot(Vec4::from(b)).clamp(-1.0, 1.0);
    let theta = d.acos();
    if theta.abs() < 1e-5 {
        return Quat::from_vec4(Vec4::from(a).lerp(Vec4::from(b), u)).normalize();
    }
    let s = theta.sin();
    let wa = ((1.0 - u) * theta).sin() / s;
    let wb = (u * theta).sin() / s;
    Quat::from_vec4(Vec4::from(a) * wa + Vec4::from(b) * wb).normalize()
}

/// A rotation spline: axis–angle keys turned into quaternions, interpolated with squad.
#[derive(Clone, Debug, PartialEq)]
pub struct RotationSpline {
    keys: Vec<TcbKey<Quat>>,
    times: Vec<f32>,
}

impl RotationSpline {
    /// Build from keys `(time, axis, angle in degrees, t, c, b)`. The axis is normalised
    /// (BART's code does not; a non-unit quaternion is not a rotation). Consecutive
    /// quaternions are sign-flipped to keep their dot product non-negative.
    pub fn new(keys: Vec<TcbKey<(Vec3, f32)>>) -> Option<Self> {
        if keys.len() < MIN_SPLINE_KEYS {
            return None;
        }
        let mut out: Vec<TcbKey<Quat>> = Vec::with_capacity(keys.len());
        for k in &keys {
            let (axis, deg) = k.value;
            let axis = axis.normalize_or(Vec3::Y);
            let mut q = Quat::from_axis_angle(axis, deg.to_radians());
            if let Some(prev) = out.last() {
                if Vec4::from(prev.value).dot(Vec4::from(q)) < 0.0 {
                    q = -q;
                }
            }
            out.push(TcbKey {
                time: k.time,
                value: q,
                tension: k.tension,
                continuity: k.continuity,
                bias: k.bias,
            });
        }
        let times = out.iter().map(|k| k.time).collect();
        Some(Self { keys: out, times })
    }

    /// Rotation at time `t` (clamped to the valid range).
    pub fn eval(&self, t: f32) -> Quat {
        let (i1, u) = locate(&self.times, t);
        let k = &self.keys;
        let (k0, k1, k2, k3) = (&k[i1 - 1], &k[i1], &k[i1 + 1], &k[i1 + 2]);
        let (q0, q1, q2, q3) = (k0.value, k1.value, k2.value, k3.value);
        let seg = k2.time - k1.time;
        let adj0 = adjust(seg, k2.time - k0.time);
        let adj1 = adjust(seg, k3.time - k1.time);
        // Log-space differences seen from q1 and q2: (P1−P0) ↔ −log(q1⁻¹q0), etc.
        let g10 = qlog(q1.conjugate() * q0);
        let g12 = qlog(q1.conjugate() * q2);
        let g21 = qlog(q2.conjugate() * q1);
        let g23 = qlog(q2.conjugate() * q3);
        let (t1, c1, b1) = (k1.tension, k1.continuity, k1.bias);
        let (t2, c2, b2) = (k2.tension, k2.continuity, k2.bias);
        let tout = 0.5
            * adj0
            * (1.0 - t1)
            * ((1.0 + c1) * (1.0 + b1) * (-g10) + (1.0 - c1) * (1.0 - b1) * g12);
        let tin = 0.5
            * adj1
            * (1.0 - t2)
            * ((1.0 - c2) * (1.0 + b2) * (-g21) + (1.0 + c2) * (1.0 - b2) * g23);
        let a = q1 * qexp(0.5 * (tout - g12));
        let b = q2 * qexp(-0.5 * (tin + g21));
        let p = slerp_raw(q1, q2, u);
        let s = slerp_raw(a, b, u);
        slerp_raw(p, s, 2.0 * u * (1.0 - u))
    }
}

/// All keyframes of one name (AFF `k name { ... }`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct KeyframeTrack {
    /// The name the track animates.
    pub name: String,
    /// Translation spline.
    pub translation: Option<VectorSpline>,
    /// Rotation spline.
    pub rotation: Option<RotationSpline>,
    /// Scale spline.
    pub scale: Option<VectorSpline>,
    /// Visibility keys `(time, visible)`, in file order.
    pub visibility: Vec<(f32, bool)>,
}

impl KeyframeTrack {
    /// `T(t)·R(t)·S(t)`, identity for missing channels.
    pub fn matrix(&self, t: f32) -> Mat4 {
        let tr = self.translation.as_ref().map_or(Vec3::ZERO, |s| s.eval(t));
        let rot = self.rotation.as_ref().map_or(Quat::IDENTITY, |s| s.eval(t));
        let sc = self.scale.as_ref().map_or(Vec3::ONE, |s| s.eval(t));
        Mat4::from_scale_rotation_translation(sc, rot, tr)
    }

    /// Visible from −∞ until the first key, then the flag of the latest key at or before
    /// `t` (by time, so out-of-order keys are handled).
    pub fn visible(&self, t: f32) -> bool {
        let mut best: Option<(f32, bool)> = None;
        for &(kt, v) in &self.visibility {
            if kt <= t && best.is_none_or(|(bt, _)| kt >= bt) {
                best = Some((kt, v));
            }
        }
        best.is_none_or(|(_, v)| v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(time: f32, v: Vec3) -> TcbKey<Vec3> {
        TcbKey::catmull_rom(time, v)
    }

    #[test]
    fn linear_data_stays_linear() {
        // Evenly spaced collinear keys: Catmull–Rom reproduces the line exactly.
        let s = VectorSpline::new(
            (0..5)
                .map(|i| key(i as f32, Vec3::splat(i as f32 * 2.0)))
                .collect(),
        )
        .unwrap();
        for t in [1.0, 1.25, 1.5, 2.0, 2.7, 3.0] {
            assert!((s.eval(t) - Vec3::splat(2.0 * t)).length() < 1e-5, "t={t}");
        }
        // Clamped outside [t1, t_{n-2}].
        assert_eq!(s.eval(-10.0), Vec3::splat(2.0));
        assert_eq!(s.eval(10.0), Vec3::splat(6.0));
    }

    #[test]
    fn hand_computed_catmull_rom_value() {
        // Keys P = 0, 0, 1, 0 at t = 0,1,2,3 (x only), TCB = 0.
        // Segment 1→2: adj0 = 2·1/2 = 1, adj1 = 1.
        // Tout = ½[(P1−P0) + (P2−P1)] = ½, Tin = ½[(P2−P1) + (P3−P2)] = 0.
        // C2 = 3·1 − 2·½ − 0 = 2, C3 = −2 + ½ + 0 = −1.5.
        // P(0.5) = 0 + ½·½ + 2·¼ − 1.5·⅛ = 0.25 + 0.5 − 0.1875 = 0.5625.
        let s = VectorSpline::new(vec![
            key(0.0, Vec3::ZERO),
            key(1.0, Vec3::ZERO),
            key(2.0, Vec3::X),
            key(3.0, Vec3::ZERO),
        ])
        .unwrap();
        assert!((s.eval(1.5).x - 0.5625).abs() < 1e-6);
        // Tension 1 at both inner keys zeroes the tangents: P(0.5) = 3·¼ − 2·⅛ = 0.5.
        let mut keys = s.keys().to_vec();
        keys[1].tension = 1.0;
        keys[2].tension = 1.0;
        let s = VectorSpline::new(keys).unwrap();
        assert!((s.eval(1.5).x - 0.5).abs() < 1e-6);
    }

    #[test]
    fn non_uniform_spacing_scales_tangents() {
        // P = 0,0,1,0 at t = 0,1,2,5: adj1 = 2·1/(5−1) = 0.5 → Tin = 0.5·½·(1 − 1) = 0.
        // Tout as before = ½ (adj0 = 1). Same curve: P(0.5) = 0.5625.
        let s = VectorSpline::new(vec![
            key(0.0, Vec3::ZERO),
            key(1.0, Vec3::ZERO),
            key(2.0, Vec3::X),
            key(5.0, Vec3::ZERO),
        ])
        .unwrap();
        assert!((s.eval(1.5).x - 0.5625).abs() < 1e-6);
        // P = 0,0,1,3 at t = 0,1,2,5: Tin = 0.5·½·((1) + (2)) = 0.75, Tout = ½.
        // C2 = 3 − 1 − 0.75 = 1.25, C3 = −2 + 0.5 + 0.75 = −0.75.
        // P(0.5) = 0.25 + 1.25·0.25 − 0.75·0.125 = 0.46875.
        let s = VectorSpline::new(vec![
            key(0.0, Vec3::ZERO),
            key(1.0, Vec3::ZERO),
            key(2.0, Vec3::X),
            key(5.0, Vec3::X * 3.0),
        ])
        .unwrap();
        assert!((s.eval(1.5).x - 0.46875).abs() < 1e-6);
    }

    #[test]
    fn degenerate_times_never_nan() {
        let s = VectorSpline::new(vec![
            key(0.0, Vec3::ZERO),
            key(0.0, Vec3::X),
            key(0.0, Vec3::Y),
            key(0.0, Vec3::Z),
            key(-1.0, Vec3::ONE),
        ])
        .unwrap();
        for t in [-1.0, 0.0, 0.5, f32::NAN] {
            assert!(s.eval(t).is_finite());
        }
    }

    fn rkey(time: f32, deg: f32) -> TcbKey<(Vec3, f32)> {
        TcbKey::catmull_rom(time, (Vec3::Y, deg))
    }

    /// Where four keys agree the splines give exactly their value at every moment,
    /// not one that differs from it in the last bit from one moment to the next (a
    /// camera that did would be a new view at every refresh).
    #[test]
    fn held_keys_give_exactly_their_value() {
        let r = RotationSpline::new((0..4).map(|i| rkey(i as f32, 37.0)).collect()).unwrap();
        let v = VectorSpline::new(
            (0..4)
                .map(|i| key(i as f32, Vec3::new(2.5, 1.2, 3.2)))
                .collect(),
        )
        .unwrap();
        let (q, p) = (r.eval(1.0), v.eval(1.0));
        for k in 0..200 {
            let t = 1.0 + k as f32 / 199.0;
            assert_eq!(r.eval(t), q, "rotation at {t}");
            assert_eq!(v.eval(t), p, "translation at {t}");
        }
    }

    #[test]
    fn constant_rate_spin_is_uniform() {
        // Keys 0, 90, 180, 270, 360, 450 degrees about +Y, one per second: a steady spin.
        let s =
            RotationSpline::new((0..6).map(|i| rkey(i as f32, 90.0 * i as f32)).collect()).unwrap();
        for t in [1.0f32, 1.5, 2.0, 2.25, 3.9] {
            let q = s.eval(t);
            let expect = Quat::from_axis_angle(Vec3::Y, (90.0 * t).to_radians());
            assert!(
                q.dot(expect).abs() > 1.0 - 1e-5,
                "t={t}: {q:?} vs {expect:?}"
            );
        }
    }

    #[test]
    fn rotation_hits_keys_and_clamps() {
        let s = RotationSpline::new(vec![
            rkey(0.0, 0.0),
            rkey(1.0, 10.0),
            rkey(2.0, 50.0),
            rkey(3.0, 60.0),
        ])
        .unwrap();
        let at = |deg: f32| Quat::from_axis_angle(Vec3::Y, deg.to_radians());
        assert!(s.eval(1.0).dot(at(10.0)).abs() > 1.0 - 1e-6);
        assert!(s.eval(2.0).dot(at(50.0)).abs() > 1.0 - 1e-6);
        assert!(s.eval(-5.0).dot(at(10.0)).abs() > 1.0 - 1e-6);
        assert!(s.eval(9.0).dot(at(50.0)).abs() > 1.0 - 1e-6);
        // About a single axis squad with TCB=0 behaves like the scalar Catmull-Rom of the
        // angle: angles 0,10,50,60 at t=0..3 → at u=½: tangents ½(10+40)=25 and ½(40+10)=25,
        // C2 = 120−50−25 = 45, C3 = −80+50 = −30: 10 + 12.5 + 11.25 − 3.75 = 30.
        let q = s.eval(1.5);
        let (axis, angle) = q.to_axis_angle();
        let signed = angle.to_degrees() * axis.y.signum();
        assert!((signed - 30.0).abs() < 0.05, "angle {signed}");
    }

    #[test]
    fn visibility_semantics() {
        let tr = KeyframeTrack {
            visibility: vec![(1.0, false), (2.0, true), (1.5, false)],
            ..Default::default()
        };
        assert!(tr.visible(0.5));
        assert!(!tr.visible(1.0));
        assert!(!tr.visible(1.7));
        assert!(tr.visible(2.0));
    }
}
