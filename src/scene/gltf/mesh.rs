//! Meshes: each primitive's vertex attributes and indices turned into triangles of its
//! node, following the specification's vertex order for strips and fans and dropping
//! what has no surface to ray trace.

use ::gltf::json;
use json::validation::Checked;

use super::build::Build;
use crate::scene::{loader::MAX_TRIANGLES, SceneError, Triangle};

/// A primitive's vertex attributes, each checked to have one value per position.
struct Vertices {
    positions: Vec<glam::Vec3>,
    normals: Option<Vec<glam::Vec3>>,
    uvs: Option<Vec<glam::Vec2>>,
}

impl Build<'_> {
    /// Triangles of a mesh, in the space of its node.
    pub(super) fn mesh(&mut self, index: usize, node: usize) -> Result<Vec<Triangle>, SceneError> {
        use json::mesh::Mode;
        let doc = self.doc;
        let mesh = doc.root.meshes.get(index).ok_or_else(|| {
            doc.invalid(format!(
                "node {node}: mesh {index} does not exist ({} defined)",
                doc.root.meshes.len()
            ))
        })?;
        let mut out = Vec::new();
        for (pi, prim) in mesh.primitives.iter().enumerate() {
            let ctx = format!("mesh {index} primitive {pi}");
            let mode = match prim.mode {
                Checked::Valid(m) => m,
                Checked::Invalid => return Err(doc.invalid(format!("{ctx}: invalid mode"))),
            };
            if !matches!(
                mode,
                Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
            ) {
                self.warn(format!(
                    "{ctx}: {mode:?} primitives have no surface and are skipped"
                ));
                continue;
            }
            let (positions, normals) = self.positions_and_normals(prim, &ctx)?;
            let nv = positions.len();
            let material_index = prim.material.map(|m| m.value());
            let material = self.material(material_index, &ctx)?;
            let vertices = Vertices {
                uvs: self.texcoords(prim, material_index, nv, &ctx)?,
                positions,
                normals,
            };
            let indices = match prim.indices {
                Some(i) => Some(doc.indices(i.value(), &format!("{ctx} indices"), nv)?),
                None => None,
            };
            let n = indices.as_ref().map_or(nv, Vec::len);
            let tri_count = match mode {
                Mode::Triangles => n / 3,
                _ => n.saturating_sub(2),
            };
            if self.triangles + tri_count > MAX_TRIANGLES {
                return Err(doc.invalid(format!(
                    "{ctx}: the scene expands to more than {MAX_TRIANGLES} triangles"
                )));
            }
            let at = |k: usize| indices.as_ref().map_or(k, |ix| ix[k] as usize);
            for k in 0..tri_count {
                let v = match mode {
                    Mode::Triangles => [at(3 * k), at(3 * k + 1), at(3 * k + 2)],
                    // glTF 2.0 §3.7.2.1: strip p_i = {v_i, v_{i+(1+i%2)}, v_{i+(2−i%2)}},
                    // fan p_i = {v_{i+1}, v_{i+2}, v_0}.
                    Mode::TriangleStrip => [at(k), at(k + 1 + k % 2), at(k + 2 - k % 2)],
                    _ => [at(k + 1), at(k + 2), at(0)],
                };
                if v[0] == v[1] || v[1] == v[2] || v[0] == v[2] {
                    continue;
                }
                out.push(Triangle {
                    p: v.map(|i| vertices.positions[i]),
                    n: vertices.normals.as_ref().map(|ns| v.map(|i| ns[i])),
                    uv: vertices.uvs.as_ref().map(|uv| v.map(|i| uv[i])),
                    material,
                });
            }
            self.triangles += tri_count;
        }
        Ok(out)
    }

    /// The positions of primitive `prim` (`ctx` names it) and its normals, if it has
    /// them.
    fn positions_and_normals(
        &self,
        prim: &json::mesh::Primitive,
        ctx: &str,
    ) -> Result<(Vec<glam::Vec3>, Option<Vec<glam::Vec3>>), SceneError> {
        use json::mesh::Semantic;
        let doc = self.doc;
        let attr = |s: Semantic| prim.attributes.get(&Checked::Valid(s)).map(|i| i.value());
        let pos_index = attr(Semantic::Positions)
            .ok_or_else(|| doc.invalid(format!("{ctx}: no POSITION attribute")))?;
        let positions = doc.vec3s(pos_index, &format!("{ctx} POSITION"))?;
        if let Some((i, &p)) = positions
            .iter()
            .enumerate()
            .find(|(_, &p)| !crate::scene::limits::coordinate_ok(p))
        {
            return Err(doc.invalid(crate::scene::limits::coordinate_message(
                &format!("{ctx} POSITION accessor {pos_index} element {i}"),
                p,
            )));
        }
        let nv = positions.len();
        let normals = match attr(Semantic::Normals) {
            Some(i) => {
                let n = doc.vec3s(i, &format!("{ctx} NORMAL"))?;
                if n.len() != nv {
                    return Err(
                        doc.invalid(format!("{ctx}: {} normals for {nv} positions", n.len()))
                    );
                }
                Some(n)
            }
            None => None,
        };
        Ok((positions, normals))
    }

    /// The texture coordinates of primitive `prim` (`ctx` names it, `nv` positions) that
    /// its material's base colour reads, if it has them.
    fn texcoords(
        &self,
        prim: &json::mesh::Primitive,
        material_index: Option<usize>,
        nv: usize,
        ctx: &str,
    ) -> Result<Option<Vec<glam::Vec2>>, SceneError> {
        use json::mesh::Semantic;
        let doc = self.doc;
        let attr = |s: Semantic| prim.attributes.get(&Checked::Valid(s)).map(|i| i.value());
        let set = material_index
            .and_then(|m| doc.root.materials.get(m))
            .and_then(|m| m.pbr_metallic_roughness.base_color_texture.as_ref())
            .map_or(0, |t| t.tex_coord);
        let uvs = match attr(Semantic::TexCoords(set)) {
            Some(i) => {
                let ctx = format!("{ctx} TEXCOORD_{set}");
                let uv = doc.texcoords(i, &ctx)?;
                if uv.len() != nv {
                    return Err(doc.invalid(format!(
                        "{ctx}: {} texture coordinates for {nv} positions",
                        uv.len()
                    )));
                }
                Some(uv)
            }
            None => None,
        };
        Ok(uvs)
    }
}
