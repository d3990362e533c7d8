//! Interactive camera control and camera-path recording (in the camera-path CSV format).

use glam::{Quat, Vec3};

use crate::scene::{Camera, CameraPath};

/// A first-person camera: position, view direction and the world's up direction (taken
/// from the scene camera, since BART scenes are not all Y-up).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FlyCamera {
    /// Eye position.
    pub eye: Vec3,
    /// Unit view direction.
    pub forward: Vec3,
    /// Unit world up.
    pub world_up: Vec3,
    /// Vertical field of view, degrees.
    pub fov_y_deg: f32,
    /// Near plane.
    pub hither: f32,
    /// Distance `at` is placed in front of the eye (the scene camera's own).
    pub focus: f32,
}

impl FlyCamera {
    /// Start from a scene camera.
    pub fn from_camera(c: &Camera) -> Self {
        let (forward, _, _) = c.basis();
        Self {
            eye: c.eye,
            forward,
            world_up: c.up.normalize_or(Vec3::Y),
            fov_y_deg: c.fov_y_deg,
            hither: c.hither,
            focus: (c.at - c.eye).length().max(1e-3),
        }
    }

    /// The view.
    pub fn camera(&self) -> Camera {
        Camera {
            eye: self.eye,
            at: self.eye + self.forward * self.focus,
            up: self.world_up,
            fov_y_deg: self.fov_y_deg,
            hither: self.hither,
        }
    }

    fn right(&self) -> Vec3 {
        self.forward
            .cross(self.world_up)
            .try_normalize()
            .unwrap_or_else(|| self.forward.any_orthonormal_vector())
    }

    /// Move by `(right, up, forward)` distances in the camera's frame.
    pub fn translate(&mut self, right: f32, up: f32, forward: f32) {
        let r = self.right();
        self.eye += r * right + self.world_up * up + self.forward * forward;
    }

    /// Turn by `yaw` (about world up, positive to the left... i.e. counter-clockwise
    /// seen from above) and `pitch` (positive up), radians. Pitch stops short of the
    /// poles so the view never flips.
    pub fn rotate(&mut self, yaw: f32, pitch: f32) {
        let f = Quat::from_axis_angle(self.world_up, yaw) * self.forward;
        let elevation = f.dot(self.world_up).clamp(-1.0, 1.0).asin();
        let max = 85f32.to_radians();
        let p = (elevation + pitch).clamp(-max, max) - elevation;
        let r = f
            .cross(self.world_up)
            .try_normalize()
            .unwrap_or_else(|| f.any_orthonormal_vector());
        self.forward = (Quat::from_axis_angle(r, p) * f).normalize_or(self.forward);
    }
}

/// Records the view at each display refresh as a camera path.
#[derive(Clone, Debug, Default)]
pub struct CameraRecorder {
    keys: Vec<(f32, Camera)>,
}

impl CameraRecorder {
    /// Nothing recorded.
    pub fn new() -> Self {
        Self::default()
    }

    /// Record the view at scene time `t`. Times are rounded to the tracer's 1 ms
    /// quantum, so that a replay (which evaluates the camera at quantized times) sees
    /// exactly the recorded view at each recorded time; a record at or before the last
    /// one is dropped (rows must increase).
    pub fn record(&mut self, t: f64, camera: Camera) {
        let t = crate::trace::Tracer::quantize(t) as f64 * crate::trace::TIME_QUANTUM;
        let t = t as f32;
        if self.keys.last().is_some_and(|(lt, _)| t <= *lt) {
            return;
        }
        self.keys.push((t, camera));
    }

    /// Records so far.
    pub fn len(&self) -> usize {
        self.keys.len()
    }

    /// Whether nothing was recorded.
    pub fn is_empty(&self) -> bool {
        self.keys.is_empty()
    }

    /// The recording as a camera path (`None` if empty).
    pub fn path(&self) -> Option<CameraPath> {
        (!self.keys.is_empty()).then(|| CameraPath {
            keys: self.keys.clone(),
        })
    }

    /// The camera-path CSV text `frameless eval --camera-path` replays.
    pub fn to_csv(&self) -> Option<String> {
        self.path().map(|p| p.to_csv())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fly_camera_round_trips_and_moves() {
        let c = Camera {
            eye: Vec3::new(0.0, 1.0, 5.0),
            at: Vec3::new(0.0, 1.0, 0.0),
            up: Vec3::Y,
            fov_y_deg: 45.0,
            hither: 1e-3,
        };
        let mut f = FlyCamera::from_camera(&c);
        assert!((f.camera().at - c.at).length() < 1e-5);
        f.translate(0.0, 0.0, 1.0);
        assert!((f.eye - Vec3::new(0.0, 1.0, 4.0)).length() < 1e-5);
        f.rotate(std::f32::consts::FRAC_PI_2, 0.0);
        assert!((f.forward - Vec3::new(-1.0, 0.0, 0.0)).length() < 1e-5);
        f.rotate(0.0, 10.0);
        assert!(f.forward.dot(Vec3::Y) < 1.0 - 1e-3, "pitch is clamped");
    }
}
