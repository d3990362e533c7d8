//! The camera: the perspective camera chosen by name or depth-first order, placed by its
//! node's world transform at `t = 0` and following the node when it is animated, or a
//! default view of the scene's bounds when the file has none.

use ::gltf::json;
use glam::{Mat4, Vec3};
use json::validation::Checked;

use super::build::{Build, CameraNode};
use crate::scene::{loader::default_camera, Camera, CameraTrack, SceneError};

impl Build<'_> {
    pub(super) fn camera(
        &mut self,
        cameras: &[CameraNode],
        wanted: Option<&str>,
        bounds: Option<(Vec3, Vec3)>,
    ) -> Result<(), SceneError> {
        let doc = self.doc;
        let Some((c, p)) = self.choose_camera(cameras, wanted)? else {
            if let Some(w) = wanted {
                return Err(no_camera_named(self, cameras, w));
            }
            self.scene.camera = CameraTrack {
                base: default_camera(bounds),
                track: None,
                resolution: None,
            };
            return Ok(());
        };
        let (id, gi) = (c.id, c.node);
        if !(p.yfov.is_finite() && p.yfov > 0.0) {
            return Err(doc.invalid(format!(
                "node {gi}: camera yfov {} is not a positive angle",
                p.yfov
            )));
        }
        let m = self.scene.node_world(id, 0.0);
        let (eye, at, up) = view_of(m);
        let hither = if p.znear.is_finite() && p.znear > 0.0 {
            p.znear
        } else {
            1e-3
        };
        let base = Camera {
            eye,
            at,
            up,
            fov_y_deg: p.yfov.to_degrees(),
            hither,
        };
        let track = if self.scene.node_is_animated(id) {
            super::animation::bake(&mut self.scene, id, "camera", true)
        } else {
            None
        };
        self.scene.camera = CameraTrack {
            base,
            track,
            resolution: None,
        };
        Ok(())
    }

    /// The first perspective camera of `cameras` (the one named `wanted`, if given)
    /// with its projection; others are skipped with a warning.
    fn choose_camera(
        &mut self,
        cameras: &[CameraNode],
        wanted: Option<&str>,
    ) -> Result<Option<(CameraNode, json::camera::Perspective)>, SceneError> {
        let doc = self.doc;
        for &c in cameras {
            let (gi, ci) = (c.node, c.camera);
            let cam = doc.root.cameras.get(ci).ok_or_else(|| {
                doc.invalid(format!(
                    "node {gi}: camera {ci} does not exist ({} defined)",
                    doc.root.cameras.len()
                ))
            })?;
            let label = cam.name.clone().unwrap_or_else(|| format!("camera {ci}"));
            if let Some(w) = wanted {
                if doc.root.nodes[gi].name.as_deref() != Some(w) && cam.name.as_deref() != Some(w) {
                    continue;
                }
            }
            match (&cam.perspective, cam.type_) {
                (Some(p), Checked::Valid(json::camera::Type::Perspective) | Checked::Invalid) => {
                    return Ok(Some((c, p.clone())));
                }
                _ if wanted.is_some() => {
                    return Err(doc.invalid(format!(
                        "camera `{label}` is not a perspective camera (only pinhole cameras are supported)"
                    )));
                }
                _ => self.warn(format!(
                    "{label} is not a perspective camera and is ignored"
                )),
            }
        }
        Ok(None)
    }
}

/// The error of a camera asked for by name that the scene does not have; it lists the
/// cameras there are.
fn no_camera_named(b: &Build<'_>, cameras: &[CameraNode], w: &str) -> SceneError {
    let doc = b.doc;
    let names: Vec<String> = cameras
        .iter()
        .map(|c| {
            let node = doc.node_name(c.node);
            match doc.root.cameras.get(c.camera).and_then(|c| c.name.clone()) {
                Some(c) => format!("{node} ({c})"),
                None => node,
            }
        })
        .collect();
    doc.invalid(format!(
        "no camera named `{w}` in the scene (cameras: {})",
        if names.is_empty() {
            "none".to_string()
        } else {
            names.join(", ")
        }
    ))
}

/// Eye, look-at point and up of a camera node's world matrix (looking down −Z, up +Y).
fn view_of(m: Mat4) -> (Vec3, Vec3, Vec3) {
    let eye = m.transform_point3(Vec3::ZERO);
    let dir = m.transform_vector3(Vec3::NEG_Z).normalize_or(Vec3::NEG_Z);
    let up = m.transform_vector3(Vec3::Y).normalize_or(Vec3::Y);
    (eye, eye + dir, up)
}
