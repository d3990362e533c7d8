//! glTF animation: samplers evaluated exactly as the specification's appendix C says,
//! the animated nodes they drive, gathering every animation's channels by target node,
//! and baking animated world transforms into keyframe tracks for the camera and lights,
//! which this renderer moves along tracks rather than through nodes.

use std::collections::HashMap;

use ::gltf::json;
use glam::{Mat4, Quat, Vec3, Vec4};
use json::validation::Checked;

use super::container::Doc;
use crate::scene::{
    animation::{KeyframeTrack, RotationSpline, TcbKey, VectorSpline},
    error::SamplerError,
    NodeId, Scene, SceneError,
};

/// Rate at which animated camera and light nodes are sampled into keyframe tracks, Hz.
const BAKE_RATE: f32 = 120.0;

/// Most samples in one baked track.
const MAX_BAKE_SAMPLES: usize = 20_000;

/// How a glTF animation sampler interpolates between keys.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interpolation {
    /// The value of the latest key at or before `t`.
    Step,
    /// Linear interpolation; spherical (slerp) for rotations.
    Linear,
    /// Cubic Hermite spline with explicit in- and out-tangents per key.
    CubicSpline,
}

/// Which node property a sampler drives; decides how values are interpolated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SamplerTarget {
    /// Translation, a 3-vector.
    Translation,
    /// Rotation, a unit quaternion `(x, y, z, w)`.
    Rotation,
    /// Scale, a 3-vector.
    Scale,
}

/// One glTF animation sampler bound to a node property.
///
/// Values are stored as 4-vectors (`w = 0` for translation and scale; `(x, y, z, w)` for
/// rotations) so one evaluator serves all three properties.
#[derive(Clone, Debug, PartialEq)]
pub struct Sampler {
    target: SamplerTarget,
    interpolation: Interpolation,
    times: Vec<f32>,
    values: Vec<Vec4>,
}

impl Sampler {
    /// Build a sampler. `values` holds one value per key, or for
    /// [`Interpolation::CubicSpline`] three per key (in-tangent, value, out-tangent).
    /// Key times must be finite and non-decreasing, values finite, and there must be at
    /// least one key; the error says what is wrong.
    pub fn new(
        target: SamplerTarget,
        interpolation: Interpolation,
        times: Vec<f32>,
        values: Vec<Vec4>,
    ) -> Result<Self, SamplerError> {
        if times.is_empty() {
            return Err(SamplerError::NoKeys);
        }
        if let Some(i) = times.iter().position(|t| !t.is_finite()) {
            return Err(SamplerError::NonFiniteTime(i));
        }
        if let Some(i) = times.windows(2).position(|w| w[1] < w[0]) {
            return Err(SamplerError::DecreasingTime {
                key: i + 1,
                time: times[i + 1],
                previous: times[i],
            });
        }
        let per_key = if interpolation == Interpolation::CubicSpline {
            3
        } else {
            1
        };
        if values.len() != times.len() * per_key {
            return Err(SamplerError::ValueCount {
                values: values.len(),
                keys: times.len(),
                expected: times.len() * per_key,
            });
        }
        if let Some(i) = values.iter().position(|v| !v.is_finite()) {
            return Err(SamplerError::NonFiniteValue(i));
        }
        Ok(Self {
            target,
            interpolation,
            times,
            values,
        })
    }

    /// The property this sampler drives.
    pub fn target(&self) -> SamplerTarget {
        self.target
    }

    /// The interpolation mode.
    pub fn interpolation(&self) -> Interpolation {
        self.interpolation
    }

    /// Key times, seconds.
    pub fn times(&self) -> &[f32] {
        &self.times
    }

    /// The value at time `t`, held constant outside the key range. Rotations come back
    /// normalised (a degenerate result becomes the identity).
    pub fn eval(&self, t: f32) -> Vec4 {
        let times = &self.times;
        let n = times.len();
        let cubic = self.interpolation == Interpolation::CubicSpline;
        let key = |k: usize| {
            if cubic {
                self.values[3 * k + 1]
            } else {
                self.values[k]
            }
        };
        let v = if t.is_nan() || t <= times[0] {
            key(0)
        } else if t >= times[n - 1] {
            key(n - 1)
        } else {
            // first < t < last, so the first key after t exists and is not key 0.
            let k1 = times.partition_point(|&x| x <= t);
            let k0 = k1 - 1;
            if self.holds(k0, k1) {
                // Exactly the key, not a blend that differs from it in the last bit:
                // a camera held between two equal keys is then the same view throughout.
                return self.finish(key(k0));
            }
            let dt = times[k1] - times[k0];
            let u = ((t - times[k0]) / dt).clamp(0.0, 1.0);
            match self.interpolation {
                Interpolation::Step => key(k0),
                Interpolation::Linear if self.target == SamplerTarget::Rotation => {
                    slerp(key(k0), key(k1), u)
                }
                Interpolation::Linear => key(k0).lerp(key(k1), u),
                Interpolation::CubicSpline => {
                    let (v0, b0) = (self.values[3 * k0 + 1], self.values[3 * k0 + 2]);
                    let (a1, v1) = (self.values[3 * k1], self.values[3 * k1 + 1]);
                    let (u2, u3) = (u * u, u * u * u);
                    v0 * (2.0 * u3 - 3.0 * u2 + 1.0)
                        + b0 * (dt * (u3 - 2.0 * u2 + u))
                        + v1 * (-2.0 * u3 + 3.0 * u2)
                        + a1 * (dt * (u3 - u2))
                }
            }
        };
        self.finish(v)
    }

    /// Whether a blend from key `k0` to key `k1` rests on one value: the same value,
    /// and for a cubic spline no tangent between them (a step is its key anyway).
    fn holds(&self, k0: usize, k1: usize) -> bool {
        match self.interpolation {
            Interpolation::Step => false,
            Interpolation::Linear => self.values[k0] == self.values[k1],
            Interpolation::CubicSpline => {
                let v = &self.values;
                v[3 * k0 + 1] == v[3 * k1 + 1]
                    && v[3 * k0 + 2] == Vec4::ZERO
                    && v[3 * k1] == Vec4::ZERO
            }
        }
    }

    /// A value as the target takes it: rotations normalised (a degenerate one becomes
    /// the identity).
    fn finish(&self, v: Vec4) -> Vec4 {
        if self.target == SamplerTarget::Rotation {
            v.try_normalize().unwrap_or(Vec4::W)
        } else {
            v
        }
    }
}

/// The glTF specification's slerp: along the shorter arc, with a linear fallback where
/// the two rotations (nearly) coincide and the formula divides by zero.
fn slerp(a: Vec4, b: Vec4, u: f32) -> Vec4 {
    let d = a.dot(b);
    let s = if d < 0.0 { -1.0 } else { 1.0 };
    let angle = d.abs().min(1.0).acos();
    let sin = angle.sin();
    if sin < 1e-6 {
        return a.lerp(b * s, u);
    }
    a * (((1.0 - u) * angle).sin() / sin) + b * (s * (u * angle).sin() / sin)
}

/// A node whose transform glTF animation channels drive: its rest TRS and the samplers
/// that override parts of it.
#[derive(Clone, Debug, PartialEq)]
pub struct NodeAnimation {
    /// The glTF node's name, or `node N` when it has none.
    pub name: String,
    /// Rest translation, used when no translation sampler is set.
    pub translation: Vec3,
    /// Rest rotation, used when no rotation sampler is set.
    pub rotation: Quat,
    /// Rest scale, used when no scale sampler is set.
    pub scale: Vec3,
    /// Translation sampler.
    pub translation_sampler: Option<Sampler>,
    /// Rotation sampler.
    pub rotation_sampler: Option<Sampler>,
    /// Scale sampler.
    pub scale_sampler: Option<Sampler>,
}

impl NodeAnimation {
    /// Translation at time `t`.
    pub fn translation_at(&self, t: f32) -> Vec3 {
        self.translation_sampler
            .as_ref()
            .map_or(self.translation, |s| s.eval(t).truncate())
    }

    /// Rotation at time `t` (unit quaternion).
    pub fn rotation_at(&self, t: f32) -> Quat {
        let q = self
            .rotation_sampler
            .as_ref()
            .map_or(Vec4::from(self.rotation), |s| s.eval(t));
        Quat::from_vec4(q.try_normalize().unwrap_or(Vec4::W))
    }

    /// Scale at time `t`.
    pub fn scale_at(&self, t: f32) -> Vec3 {
        self.scale_sampler
            .as_ref()
            .map_or(self.scale, |s| s.eval(t).truncate())
    }

    /// Local matrix `T(t)·R(t)·S(t)`.
    pub fn matrix(&self, t: f32) -> Mat4 {
        Mat4::from_scale_rotation_translation(
            self.scale_at(t),
            self.rotation_at(t),
            self.translation_at(t),
        )
    }
}

/// Samplers collected for one node from all animations.
#[derive(Default)]
pub(super) struct Channels {
    pub(super) translation: Option<Sampler>,
    pub(super) rotation: Option<Sampler>,
    pub(super) scale: Option<Sampler>,
}

/// Samplers of every animation, by target node.
pub(super) fn collect_channels(
    doc: &Doc,
    warn: &mut dyn FnMut(String),
) -> Result<HashMap<usize, Channels>, SceneError> {
    use json::animation::Property;
    let mut out: HashMap<usize, Channels> = HashMap::new();
    for (ai, anim) in doc.root.animations.iter().enumerate() {
        for (ci, ch) in anim.channels.iter().enumerate() {
            let ctx = format!("animation {ai} channel {ci}");
            let target = match ch.target.path {
                Checked::Valid(Property::Translation) => SamplerTarget::Translation,
                Checked::Valid(Property::Rotation) => SamplerTarget::Rotation,
                Checked::Valid(Property::Scale) => SamplerTarget::Scale,
                Checked::Valid(Property::MorphTargetWeights) => {
                    warn("morph target weight animation is ignored".into());
                    continue;
                }
                Checked::Invalid => {
                    return Err(doc.invalid(format!("{ctx}: invalid target path")));
                }
            };
            let node = ch.target.node.value();
            if node >= doc.root.nodes.len() {
                return Err(doc.invalid(format!(
                    "{ctx}: target node {node} does not exist ({} defined)",
                    doc.root.nodes.len()
                )));
            }
            let si = ch.sampler.value();
            let s = anim.samplers.get(si).ok_or_else(|| {
                doc.invalid(format!(
                    "{ctx}: sampler {si} does not exist ({} defined)",
                    anim.samplers.len()
                ))
            })?;
            let sampler = read_sampler(doc, s, target, ctx)?;
            let slot = out.entry(node).or_default();
            match target {
                SamplerTarget::Translation => slot.translation = Some(sampler),
                SamplerTarget::Rotation => slot.rotation = Some(sampler),
                SamplerTarget::Scale => slot.scale = Some(sampler),
            }
        }
    }
    Ok(out)
}

/// The sampler `s` of a channel driving `target` (`ctx` names the channel in errors):
/// its interpolation, key times and values read and checked.
fn read_sampler(
    doc: &Doc,
    s: &json::animation::Sampler,
    target: SamplerTarget,
    ctx: String,
) -> Result<Sampler, SceneError> {
    use json::animation::Interpolation as I;
    let interpolation = match s.interpolation {
        Checked::Valid(I::Step) => Interpolation::Step,
        Checked::Valid(I::Linear) => Interpolation::Linear,
        Checked::Valid(I::CubicSpline) => Interpolation::CubicSpline,
        Checked::Invalid => {
            return Err(doc.invalid(format!("{ctx}: invalid interpolation")));
        }
    };
    let (times, _) = doc.floats(
        s.input.value(),
        &format!("{ctx} input"),
        &[json::accessor::Type::Scalar],
    )?;
    let ty = if target == SamplerTarget::Rotation {
        json::accessor::Type::Vec4
    } else {
        json::accessor::Type::Vec3
    };
    let (vals, comps) = doc.floats(s.output.value(), &format!("{ctx} output"), &[ty])?;
    let values = vals
        .chunks_exact(comps)
        .map(|c| {
            if comps == 4 {
                Vec4::from_slice(c)
            } else {
                Vec3::from_slice(c).extend(0.0)
            }
        })
        .collect();
    Sampler::new(target, interpolation, times, values).map_err(|source| SceneError::Sampler {
        file: doc.file.clone(),
        context: ctx,
        source,
    })
}

/// Sample a node's world transform over the animation range into a keyframe track
/// (translation, and rotation when asked), for the camera and lights, which follow
/// tracks rather than nodes.
pub(super) fn bake(scene: &mut Scene, node: NodeId, name: &str, rotation: bool) -> Option<u32> {
    let range = scene.animation?;
    let (start, end) = (range.start, range.end);
    let samples = ((end - start) * BAKE_RATE)
        .ceil()
        .clamp(1.0, MAX_BAKE_SAMPLES as f32) as usize;
    let step = (end - start) / samples as f32;
    let mut tkeys = Vec::with_capacity(samples + 3);
    let mut rkeys = Vec::with_capacity(samples + 3);
    // One extra key before and after: the spline uses its end keys only for tangents.
    for i in -1..=samples as i64 + 1 {
        let t = start + step * i as f32;
        let (_, r, p) = scene.node_world(node, t).to_scale_rotation_translation();
        let (axis, angle) = r.to_axis_angle();
        tkeys.push(TcbKey::catmull_rom(t, p));
        rkeys.push(TcbKey::catmull_rom(t, (axis, angle.to_degrees())));
    }
    let track = KeyframeTrack {
        name: name.to_string(),
        translation: VectorSpline::new(tkeys),
        rotation: if rotation {
            RotationSpline::new(rkeys)
        } else {
            None
        },
        ..Default::default()
    };
    scene.tracks.push(track);
    Some((scene.tracks.len() - 1) as u32)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sampler(target: SamplerTarget, i: Interpolation, t: &[f32], v: &[Vec4]) -> Sampler {
        Sampler::new(target, i, t.to_vec(), v.to_vec()).unwrap()
    }

    #[test]
    fn step_linear_and_clamping() {
        let t = [1.0, 2.0, 4.0];
        let v = [Vec4::ZERO, Vec4::X, Vec4::X * 3.0];
        let lin = sampler(SamplerTarget::Translation, Interpolation::Linear, &t, &v);
        assert_eq!(lin.eval(0.0), Vec4::ZERO);
        assert_eq!(lin.eval(f32::NAN), Vec4::ZERO);
        assert!((lin.eval(1.5).x - 0.5).abs() < 1e-6);
        assert!((lin.eval(3.0).x - 2.0).abs() < 1e-6);
        assert_eq!(lin.eval(9.0), Vec4::X * 3.0);
        let step = sampler(SamplerTarget::Translation, Interpolation::Step, &t, &v);
        assert_eq!(step.eval(1.99), Vec4::ZERO);
        assert_eq!(step.eval(2.0), Vec4::X);
        assert_eq!(step.eval(3.99), Vec4::X);
    }

    #[test]
    fn repeated_key_times_do_not_divide_by_zero() {
        let s = sampler(
            SamplerTarget::Translation,
            Interpolation::Linear,
            &[0.0, 1.0, 1.0, 2.0],
            &[Vec4::ZERO, Vec4::X, Vec4::Y, Vec4::Z],
        );
        for t in [0.5, 1.0, 1.5] {
            assert!(s.eval(t).is_finite());
        }
        assert_eq!(s.eval(1.0), Vec4::Y);
    }

    #[test]
    fn slerp_takes_the_short_way() {
        let a = Quat::IDENTITY;
        let b = -Quat::from_rotation_y(1.0); // same rotation as +1 rad, opposite sign
        let s = sampler(
            SamplerTarget::Rotation,
            Interpolation::Linear,
            &[0.0, 1.0],
            &[Vec4::from(a), Vec4::from(b)],
        );
        let q = Quat::from_vec4(s.eval(0.5));
        assert!(q.dot(Quat::from_rotation_y(0.5)).abs() > 1.0 - 1e-6);
    }

    #[test]
    fn rejects_bad_samplers() {
        let v = [Vec4::ZERO; 2];
        assert!(Sampler::new(SamplerTarget::Scale, Interpolation::Linear, vec![], vec![]).is_err());
        assert!(Sampler::new(
            SamplerTarget::Scale,
            Interpolation::Linear,
            vec![1.0, 0.0],
            v.to_vec()
        )
        .is_err());
        assert!(Sampler::new(
            SamplerTarget::Scale,
            Interpolation::CubicSpline,
            vec![0.0, 1.0],
            v.to_vec()
        )
        .is_err());
        assert!(Sampler::new(
            SamplerTarget::Scale,
            Interpolation::Linear,
            vec![0.0, f32::NAN],
            v.to_vec()
        )
        .is_err());
    }
}
