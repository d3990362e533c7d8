//! Materials: the metallic–roughness model mapped onto this renderer's Phong materials
//! (the mapping is spelled out in the module documentation of [`super`]), and the
//! base-color images they reference, found in buffer views, `data:` URIs or files.

use std::path::PathBuf;

use ::gltf::json;
use glam::Vec3;
use json::validation::Checked;

use super::{
    build::Build,
    container::{percent_decode, Doc},
};
use crate::scene::{loader::decode_image, Material, MaterialId, SceneError, Texture, TextureId};

impl Build<'_> {
    /// The scene material for a glTF material index (`None`: the default material).
    pub(super) fn material(
        &mut self,
        index: Option<usize>,
        ctx: &str,
    ) -> Result<MaterialId, SceneError> {
        if let Some(&id) = self.materials.get(&index) {
            return Ok(id);
        }
        let doc = self.doc;
        let m = match index {
            None => Material::default(),
            Some(i) => {
                let gm = doc.root.materials.get(i).ok_or_else(|| {
                    doc.invalid(format!(
                        "{ctx}: material {i} does not exist ({} defined)",
                        doc.root.materials.len()
                    ))
                })?;
                let texture = match &gm.pbr_metallic_roughness.base_color_texture {
                    Some(info) => Some(self.texture(info.index.value(), &format!("material {i}"))?),
                    None => None,
                };
                let mut m = convert_material(gm);
                if m.diffuse.is_nan()
                    || m.specular.is_nan()
                    || m.ambient.is_nan()
                    || m.shininess.is_nan()
                {
                    return Err(doc.invalid(format!("material {i} has non-finite factors")));
                }
                m.texture = texture;
                m
            }
        };
        self.scene.materials.push(m);
        let id = (self.scene.materials.len() - 1) as MaterialId;
        self.materials.insert(index, id);
        Ok(id)
    }

    fn texture(&mut self, index: usize, ctx: &str) -> Result<TextureId, SceneError> {
        let doc = self.doc;
        let tex = doc.root.textures.get(index).ok_or_else(|| {
            doc.invalid(format!(
                "{ctx}: texture {index} does not exist ({} defined)",
                doc.root.textures.len()
            ))
        })?;
        let image = tex.source.value();
        if let Some(&id) = self.textures.get(&image) {
            return Ok(id);
        }
        let t = doc.image(image, &format!("{ctx} texture {index}"))?;
        self.scene.textures.push(t);
        let id = (self.scene.textures.len() - 1) as TextureId;
        self.textures.insert(image, id);
        Ok(id)
    }
}

impl Doc {
    /// Decode image `index` into a texture.
    fn image(&self, index: usize, ctx: &str) -> Result<Texture, SceneError> {
        let img = self.root.images.get(index).ok_or_else(|| {
            self.invalid(format!(
                "{ctx}: image {index} does not exist ({} defined)",
                self.root.images.len()
            ))
        })?;
        let what = format!("image {index}");
        let (bytes, name, path) = match (&img.uri, img.buffer_view) {
            (Some(uri), _) => {
                let bytes = self.read_uri(uri, &what)?;
                if uri.starts_with("data:") {
                    (bytes, what.clone(), PathBuf::from(&self.file))
                } else {
                    let name = uri.rsplit('/').next().unwrap_or(uri).to_string();
                    let path = self.dir.join(percent_decode(uri).unwrap_or_default());
                    (bytes, name, path)
                }
            }
            (None, Some(view)) => (
                self.view_bytes(view.value(), &format!("{ctx}: {what}"))?
                    .to_vec(),
                img.name.clone().unwrap_or_else(|| what.clone()),
                PathBuf::from(&self.file),
            ),
            (None, None) => {
                return Err(self.invalid(format!("{ctx}: {what} has neither uri nor bufferView")))
            }
        };
        decode_image(&name, &bytes).map_err(|source| SceneError::Texture {
            path,
            source,
            context: Some(format!("{what} of {}", self.file)),
        })
    }
}

/// Map a metallic–roughness material to Phong (see the module documentation).
fn convert_material(gm: &json::Material) -> Material {
    let pbr = &gm.pbr_metallic_roughness;
    let [r, g, b, alpha] = pbr.base_color_factor.0;
    let base = Vec3::new(r, g, b);
    let metallic = pbr.metallic_factor.0.clamp(0.0, 1.0);
    let rough = pbr.roughness_factor.0.clamp(0.0, 1.0);
    let ext = gm.extensions.as_ref();
    let mut transmission = ext
        .and_then(|e| e.transmission.as_ref())
        .map_or(0.0, |t| t.transmission_factor.0.clamp(0.0, 1.0))
        * (1.0 - metallic);
    let mut ior = ext.and_then(|e| e.ior.as_ref()).map_or(1.5, |i| i.ior.0);
    if gm.alpha_mode == Checked::Valid(json::material::AlphaMode::Blend) {
        let see_through = (1.0 - alpha).clamp(0.0, 1.0);
        if see_through > transmission {
            transmission = see_through;
            ior = 1.0;
        }
    }
    let gloss = (1.0 - rough) * (1.0 - rough);
    let f0 = Vec3::splat(0.04).lerp(base, metallic);
    let diffuse = base * (1.0 - metallic) * (1.0 - transmission) + base * metallic * (1.0 - gloss);
    let r4 = rough.powi(4);
    let shininess = if r4 > 0.0 {
        (2.0 / r4 - 2.0).clamp(1.0, 10000.0)
    } else {
        10000.0
    };
    Material {
        ambient: diffuse * 0.1 + Vec3::from(gm.emissive_factor.0),
        diffuse,
        specular: f0 * gloss,
        shininess,
        transmission,
        ior,
        texture: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn material_mapping() {
        let gm: json::Material = serde_json::from_str(
            r#"{"pbrMetallicRoughness":{"baseColorFactor":[1,0.5,0.25,1],"metallicFactor":0,"roughnessFactor":1}}"#,
        )
        .unwrap();
        let m = convert_material(&gm);
        assert!((m.diffuse - Vec3::new(1.0, 0.5, 0.25)).length() < 1e-6);
        assert_eq!(m.specular, Vec3::ZERO);
        assert_eq!(m.shininess, 1.0);
        let gm: json::Material = serde_json::from_str(
            r#"{"pbrMetallicRoughness":{"baseColorFactor":[0.9,0.8,0.7,1],"metallicFactor":1,"roughnessFactor":0}}"#,
        )
        .unwrap();
        let m = convert_material(&gm);
        assert!((m.specular - Vec3::new(0.9, 0.8, 0.7)).length() < 1e-6);
        assert_eq!(m.diffuse, Vec3::ZERO);
        assert_eq!(m.shininess, 10000.0);
    }
}
