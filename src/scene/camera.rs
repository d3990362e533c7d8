//! Pinhole camera: a view at one instant, its animation, and ray generation.

use glam::{Mat3, Vec3};

use super::{animation::KeyframeTrack, TrackId};

/// A pinhole view at one instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position.
    pub eye: Vec3,
    /// A point the camera looks at.
    pub at: Vec3,
    /// Approximate up direction (need not be orthogonal to the view direction).
    pub up: Vec3,
    /// Full vertical field of view in degrees.
    pub fov_y_deg: f32,
    /// Near plane distance (rays start this far from the eye).
    pub hither: f32,
}

impl Default for Camera {
    fn default() -> Self {
        Self {
            eye: Vec3::new(0.0, 0.0, 5.0),
            at: Vec3::ZERO,
            up: Vec3::Y,
            fov_y_deg: 45.0,
            hither: 1e-3,
        }
    }
}

/// A camera fixed to an image size: turns continuous pixel coordinates into rays and
/// world points back into pixel coordinates.
///
/// Pixel coordinates: `x ∈ [0, W)` left to right, `y ∈ [0, H)` top to bottom; the center
/// of pixel `(i, j)` is `(i + ½, j + ½)`.
#[derive(Clone, Copy, Debug)]
pub struct CameraFrame {
    /// Eye position.
    pub eye: Vec3,
    /// Unit view direction.
    pub forward: Vec3,
    /// Unit right vector.
    pub right: Vec3,
    /// Unit up vector, orthogonal to `forward` and `right`.
    pub up: Vec3,
    /// World-space offset of one pixel step to the right on the plane at distance 1.
    pub du: Vec3,
    /// World-space offset of one pixel step down on the plane at distance 1.
    pub dv: Vec3,
    /// Direction (unnormalised) through the top-left corner of the image.
    pub corner: Vec3,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Near plane distance.
    pub hither: f32,
}

impl CameraFrame {
    /// Whether `other` sees the scene exactly as this frame does (same eye and the same
    /// rays through every pixel): what was traced with one is valid for the other.
    pub fn same_view(&self, other: &CameraFrame) -> bool {
        self.eye == other.eye
            && self.corner == other.corner
            && self.du == other.du
            && self.dv == other.dv
            && self.width == other.width
            && self.height == other.height
    }
}

impl Camera {
    /// Orthonormal basis `(forward, right, up)`, robust to degenerate input.
    pub fn basis(&self) -> (Vec3, Vec3, Vec3) {
        let forward = (self.at - self.eye).normalize_or(Vec3::NEG_Z);
        let mut right = forward.cross(self.up);
        if right.length_squared() < 1e-12 {
            // Up parallel to the view direction: pick any perpendicular.
            right = forward.any_orthonormal_vector();
        }
        let right = right.normalize();
        let up = right.cross(forward);
        (forward, right, up)
    }

    /// Fix the camera to an image size.
    pub fn frame(&self, width: u32, height: u32) -> CameraFrame {
        let (forward, right, up) = self.basis();
        let half_h = (self.fov_y_deg.clamp(1e-3, 179.0).to_radians() * 0.5).tan();
        let aspect = width as f32 / height.max(1) as f32;
        let half_w = half_h * aspect;
        let du = right * (2.0 * half_w / width.max(1) as f32);
        let dv = -up * (2.0 * half_h / height.max(1) as f32);
        let corner = forward - right * half_w + up * half_h;
        CameraFrame {
            eye: self.eye,
            forward,
            right,
            up,
            du,
            dv,
            corner,
            width,
            height,
            hither: self.hither,
        }
    }

    /// Linear interpolation of two views (used by camera paths).
    pub fn lerp(&self, other: &Camera, s: f32) -> Camera {
        // `a + (b − a)·s`, not glam's `a·(1 − s) + b·s`: where two keys agree it gives
        // the key exactly, so a camera held between equal keys is the same view at
        // every moment (a view that changes in its last bit re-splats every sample).
        let mix = |a: Vec3, b: Vec3| a + (b - a) * s;
        Camera {
            eye: mix(self.eye, other.eye),
            at: mix(self.at, other.at),
            up: mix(self.up, other.up),
            fov_y_deg: self.fov_y_deg + (other.fov_y_deg - self.fov_y_deg) * s,
            hither: self.hither + (other.hither - self.hither) * s,
        }
    }
}

impl CameraFrame {
    /// Unit direction of the ray through continuous pixel coordinates `(x, y)`.
    #[inline]
    pub fn direction(&self, x: f32, y: f32) -> Vec3 {
        (self.corner + self.du * x + self.dv * y).normalize()
    }

    /// Continuous pixel coordinates and view depth (distance along `forward`) of a world
    /// point; `None` when it is behind the eye.
    #[inline]
    pub fn project(&self, p: Vec3) -> Option<(f32, f32, f32)> {
        let d = p - self.eye;
        let z = d.dot(self.forward);
        if z <= 1e-6 {
            return None;
        }
        let q = d / z - self.corner;
        let x = q.dot(self.du) / self.du.length_squared();
        let y = q.dot(self.dv) / self.dv.length_squared();
        Some((x, y, z))
    }
}

/// The scene's camera: a static view, optionally animated by a keyframe track.
///
/// With a track (AFF `k camera`), the eye follows the translation spline and, when a
/// rotation is present, the view direction is `−Z` and up is `+Y` of the rotation.
/// Field of view and near plane stay those of the static view.
#[derive(Clone, Debug, Default)]
pub struct CameraTrack {
    /// The static view (AFF `v`).
    pub base: Camera,
    /// Keyframes, if animated.
    pub track: Option<TrackId>,
    /// Image resolution suggested by the file (AFF `resolution`).
    pub resolution: Option<(u32, u32)>,
}

impl CameraTrack {
    /// The view at time `t`.
    pub fn at(&self, t: f32, tracks: &[KeyframeTrack]) -> Camera {
        let Some(tr) = self.track.map(|i| &tracks[i as usize]) else {
            return self.base;
        };
        let mut cam = self.base;
        let dir0 = cam.at - cam.eye;
        if let Some(s) = &tr.translation {
            cam.eye = s.eval(t);
        }
        if let Some(r) = &tr.rotation {
            let m = Mat3::from_quat(r.eval(t));
            cam.at = cam.eye - m.z_axis;
            cam.up = m.y_axis;
        } else {
            cam.at = cam.eye + dir0;
        }
        cam
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn center_ray_and_projection_round_trip() {
        let cam = Camera {
            eye: Vec3::new(1.0, 2.0, 3.0),
            at: Vec3::new(1.0, 2.0, 0.0),
            up: Vec3::Y,
            fov_y_deg: 90.0,
            hither: 0.01,
        };
        let f = cam.frame(200, 100);
        let d = f.direction(100.0, 50.0);
        assert!((d - Vec3::NEG_Z).length() < 1e-6);
        // fov_y 90°: the top edge is 45° up.
        let top = f.direction(100.0, 0.0);
        assert!((top.y - top.z.abs()).abs() < 1e-5);
        // Aspect 2: the right edge is at x = 2 on the plane at distance 1.
        let r = f.direction(200.0, 50.0);
        assert!((r.x / -r.z - 2.0).abs() < 1e-5);
        let p = cam.eye + f.direction(37.5, 81.25) * 7.0;
        let (x, y, _) = f.project(p).unwrap();
        assert!((x - 37.5).abs() < 1e-3 && (y - 81.25).abs() < 1e-3);
        assert!(f.project(cam.eye + Vec3::Z).is_none());
    }
}
