//! The camera: the perspective camera chosen by name or depth-first order, placed by its
//! node's world transform at `t = 0` and following the node when it is animated, or a
//! default view of the scene's bounds when the file has none.

use ::gltf::json;
use glam::{Mat4, Vec3};
use json::validation::Checked;

use super::build::Build;
use crate::scene::{loader::default_camera, Camera, CameraTrack, NodeId, SceneError};

impl Build<'_> {
    pub(super) fn camera(
        &mut self,
        cameras: &[(NodeId, usize, usize)],
        wanted: Option<&str>,
        bounds: Option<(Vec3, Vec3)>,
    ) -> Result<(), SceneError> {
        let doc = self.doc;
        let mut chosen = None;
        for &(id, gi, ci) in cameras {
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
                    chosen = Some((id, gi, p.clone()));
                    break;
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
        let Some((id, gi, p)) = chosen else {
            if let Some(w) = wanted {
                let names: Vec<String> = cameras
                    .iter()
                    .map(|&(_, gi, ci)| {
                        let node = doc.node_name(gi);
                        match doc.root.cameras.get(ci).and_then(|c| c.name.clone()) {
                            Some(c) => format!("{node} ({c})"),
                            None => node,
                        }
                    })
                    .collect();
                return Err(doc.invalid(format!(
                    "no camera named `{w}` in the scene (cameras: {})",
                    if names.is_empty() {
                        "none".to_string()
                    } else {
                        names.join(", ")
                    }
                )));
            }
            self.scene.camera = CameraTrack {
                base: default_camera(bounds),
                track: None,
                resolution: None,
            };
            return Ok(());
        };
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
}

/// Eye, look-at point and up of a camera node's world matrix (looking down −Z, up +Y).
fn view_of(m: Mat4) -> (Vec3, Vec3, Vec3) {
    let eye = m.transform_point3(Vec3::ZERO);
    let dir = m.transform_vector3(Vec3::NEG_Z).normalize_or(Vec3::NEG_Z);
    let up = m.transform_vector3(Vec3::Y).normalize_or(Vec3::Y);
    (eye, eye + dir, up)
}
