//! Punctual lights (`KHR_lights_punctual`), converted to this renderer's lights without
//! falloff: point and spot lights deliver their illuminance at a reference distance from
//! the scene's center, directional lights become distant point lights.

use ::gltf::json;
use glam::Vec3;
use json::validation::Checked;

use super::build::Build;
use crate::scene::{Light, NodeId, SceneError};

impl Build<'_> {
    pub(super) fn lights(
        &mut self,
        lights: &[(NodeId, usize)],
        bounds: Option<(Vec3, Vec3)>,
    ) -> Result<(), SceneError> {
        use json::extensions::scene::khr_lights_punctual::Type as L;
        let doc = self.doc;
        let defined = doc
            .root
            .extensions
            .as_ref()
            .and_then(|e| e.khr_lights_punctual.as_ref())
            .map_or(&[][..], |l| &l.lights[..]);
        let (center, radius) = bounds.map_or((Vec3::ZERO, 1.0), |(lo, hi)| {
            ((lo + hi) * 0.5, ((hi - lo).length() * 0.5).max(1e-3))
        });
        for &(id, li) in lights {
            let l = defined.get(li).ok_or_else(|| {
                doc.invalid(format!(
                    "light {li} does not exist ({} defined)",
                    defined.len()
                ))
            })?;
            let color = Vec3::from(l.color) * l.intensity;
            if !color.is_finite() {
                return Err(doc.invalid(format!("light {li}: color or intensity is not finite")));
            }
            let m = self.scene.node_world(id, 0.0);
            let (color, position) = match l.type_ {
                Checked::Valid(L::Directional) => {
                    let dir = m.transform_vector3(Vec3::NEG_Z).normalize_or(Vec3::NEG_Z);
                    (color, center - dir * (1000.0 * radius))
                }
                Checked::Valid(L::Point | L::Spot) => {
                    let p = m.transform_point3(Vec3::ZERO);
                    let d = (p - center).length().max(0.25 * radius);
                    (color / (d * d), p)
                }
                Checked::Invalid => return Err(doc.invalid(format!("light {li}: invalid type"))),
            };
            let directional = matches!(l.type_, Checked::Valid(L::Directional));
            let name = l.name.clone().unwrap_or_else(|| format!("light {li}"));
            let track = if self.scene.node_is_animated(id) && !directional {
                super::animation::bake(&mut self.scene, id, &name, false)
            } else {
                None
            };
            self.scene.lights.push(Light {
                position,
                color,
                track,
                name: Some(name),
            });
        }
        Ok(())
    }
}
