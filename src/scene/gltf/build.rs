//! The walk over the node hierarchy that builds the [`Scene`]: which nodes are shown,
//! each node's static or animated transform, and the meshes, cameras and lights hanging
//! off them, collected here and placed once every node exists (the defaults need the
//! scene's bounds). [`Build`] carries what the other parts share while the walk runs.

use std::collections::HashMap;
use std::path::Path;

use ::gltf::json;
use glam::{Mat4, Quat, Vec3, Vec4};

use super::{
    animation::{self, NodeAnimation},
    container::Doc,
};
use crate::scene::{
    loader::{default_light, empty_scene, world_bounds},
    AnimationRange, Group, MaterialId, Node, NodeId, NodeKind, Scene, SceneError, TextureId,
};

/// A node that holds a camera.
#[derive(Clone, Copy, Debug)]
pub(super) struct CameraNode {
    /// The scene node made of it.
    pub id: NodeId,
    /// Its glTF node index.
    pub node: usize,
    /// Its glTF camera index.
    pub camera: usize,
}

/// Scene construction from a parsed document.
pub(super) struct Build<'a> {
    pub(super) doc: &'a Doc,
    pub(super) scene: Scene,
    /// Scene material of each glTF material index used so far (`None`: no material).
    pub(super) materials: HashMap<Option<usize>, MaterialId>,
    /// Scene texture of each glTF image used so far.
    pub(super) textures: HashMap<usize, TextureId>,
    /// Warnings already printed, so that each is printed once.
    warnings: Vec<String>,
    /// Triangles emitted so far, against [`MAX_TRIANGLES`](crate::scene::loader::MAX_TRIANGLES).
    pub(super) triangles: usize,
}

impl<'a> Build<'a> {
    pub(super) fn new(doc: &'a Doc, path: &Path) -> Self {
        Self {
            doc,
            scene: empty_scene(path),
            materials: HashMap::new(),
            textures: HashMap::new(),
            warnings: Vec::new(),
            triangles: 0,
        }
    }

    pub(super) fn warn(&mut self, message: String) {
        if !self.warnings.contains(&message) {
            eprintln!("warning: {}: {message}", self.doc.file);
            self.warnings.push(message);
        }
    }

    pub(super) fn run(&mut self, camera_name: Option<&str>) -> Result<(), SceneError> {
        let doc = self.doc;
        let root = &doc.root;
        let doc = self.doc;
        let mut channels = animation::collect_channels(doc, &mut |m| self.warn(m))?;
        let roots = self.scene_roots()?;

        // Depth-first, parents before children; glTF node index → scene node id.
        let mut ids: Vec<Option<NodeId>> = vec![None; root.nodes.len()];
        let mut cameras: Vec<CameraNode> = Vec::new();
        let mut lights: Vec<(NodeId, usize)> = Vec::new();
        let mut range: Option<(f32, f32)> = None;
        let mut stack: Vec<(usize, Option<NodeId>)> =
            roots.into_iter().rev().map(|i| (i, None)).collect();
        while let Some((gi, parent)) = stack.pop() {
            let node = root.nodes.get(gi).ok_or_else(|| {
                doc.invalid(format!(
                    "node {gi} does not exist ({} defined)",
                    root.nodes.len()
                ))
            })?;
            if ids[gi].is_some() {
                return Err(doc.invalid(format!(
                    "node {gi} ({}) is reached twice: a node may have only one parent, and no cycles",
                    doc.node_name(gi)
                )));
            }
            let kind = node_kind(doc, gi, node, channels.remove(&gi), &mut range)?;
            let id = self.scene.nodes.len() as NodeId;
            self.scene.nodes.push(Node { parent, kind });
            ids[gi] = Some(id);
            if let Some(mesh) = node.mesh {
                let tris = self.mesh(mesh.value(), gi)?;
                if !tris.is_empty() {
                    self.scene.groups.push(Group {
                        node: Some(id),
                        triangles: tris,
                        ..Default::default()
                    });
                }
            }
            if let Some(c) = node.camera {
                cameras.push(CameraNode {
                    id,
                    node: gi,
                    camera: c.value(),
                });
            }
            if let Some(l) = node
                .extensions
                .as_ref()
                .and_then(|e| e.khr_lights_punctual.as_ref())
            {
                lights.push((id, l.light.value()));
            }
            for child in node.children.iter().flatten().rev() {
                stack.push((child.value(), Some(id)));
            }
        }
        if let Some((a, b)) = range {
            let start = a.min(0.0);
            if b > start {
                self.scene.animation = Some(AnimationRange {
                    start,
                    end: b,
                    frames: ((b - start) * 30.0).round().clamp(1.0, u32::MAX as f32) as u32,
                });
            }
        }
        let bounds = world_bounds(&self.scene, 0.0);
        self.camera(&cameras, camera_name, bounds)?;
        self.lights(&lights, bounds)?;
        if self.scene.lights.is_empty() {
            self.scene
                .lights
                .push(default_light(&self.scene.camera.base));
        }
        Ok(())
    }

    /// Roots of the scene to show.
    fn scene_roots(&self) -> Result<Vec<usize>, SceneError> {
        let root = &self.doc.root;
        let chosen = match root.scene {
            Some(s) => Some(root.scenes.get(s.value()).ok_or_else(|| {
                self.doc.invalid(format!(
                    "default scene {} does not exist ({} defined)",
                    s.value(),
                    root.scenes.len()
                ))
            })?),
            None => root.scenes.first(),
        };
        Ok(match chosen {
            Some(s) => s.nodes.iter().map(|n| n.value()).collect(),
            None => {
                let mut is_child = vec![false; root.nodes.len()];
                for n in &root.nodes {
                    for c in n.children.iter().flatten() {
                        if let Some(f) = is_child.get_mut(c.value()) {
                            *f = true;
                        }
                    }
                }
                (0..root.nodes.len()).filter(|&i| !is_child[i]).collect()
            }
        })
    }
}

/// The transform of glTF node `gi`, checked finite: sampled where `channels` animate
/// it (widening `range` to their keys), else static.
fn node_kind(
    doc: &Doc,
    gi: usize,
    node: &json::Node,
    channels: Option<animation::Channels>,
    range: &mut Option<(f32, f32)>,
) -> Result<NodeKind, SceneError> {
    let check = |what: &str, m: &[f32]| {
        if m.iter().all(|v| v.is_finite()) {
            Ok(())
        } else {
            Err(doc.invalid(format!("node {gi}: {what} is not finite")))
        }
    };
    check("matrix", &node.matrix.unwrap_or([0.0; 16]))?;
    check("translation", &node.translation.unwrap_or([0.0; 3]))?;
    check("rotation", &node.rotation.map_or([0.0; 4], |q| q.0))?;
    check("scale", &node.scale.unwrap_or([0.0; 3]))?;
    Ok(match channels {
        Some(ch) => {
            let (translation, rotation, scale) = node_trs(node);
            for s in [&ch.translation, &ch.rotation, &ch.scale]
                .into_iter()
                .flatten()
            {
                let (a, b) = (s.times()[0], s.times()[s.times().len() - 1]);
                *range = Some(range.map_or((a, b), |(x, y)| (x.min(a), y.max(b))));
            }
            NodeKind::Sampled(Box::new(NodeAnimation {
                name: doc.node_name(gi),
                translation,
                rotation,
                scale,
                translation_sampler: ch.translation,
                rotation_sampler: ch.rotation,
                scale_sampler: ch.scale,
            }))
        }
        None => NodeKind::Static(node_matrix(node)),
    })
}

/// A node's local transform as written (matrix, or TRS with defaults).
fn node_trs(n: &json::Node) -> (Vec3, Quat, Vec3) {
    match n.matrix {
        Some(m) => {
            let (s, r, t) = Mat4::from_cols_array(&m).to_scale_rotation_translation();
            // A singular matrix has no decomposition: keep what is finite.
            let r = if r.is_finite() { r } else { Quat::IDENTITY };
            let s = if s.is_finite() { s } else { Vec3::ONE };
            (t, r, s)
        }
        None => (
            n.translation.map_or(Vec3::ZERO, Vec3::from),
            n.rotation.map_or(Quat::IDENTITY, |q| {
                Quat::from_vec4(Vec4::from(q.0).try_normalize().unwrap_or(Vec4::W))
            }),
            n.scale.map_or(Vec3::ONE, Vec3::from),
        ),
    }
}

/// A node's local matrix, exactly as written when it is given as one.
fn node_matrix(n: &json::Node) -> Mat4 {
    match n.matrix {
        Some(m) => Mat4::from_cols_array(&m),
        None => {
            let (t, r, s) = node_trs(n);
            Mat4::from_scale_rotation_translation(s, r, t)
        }
    }
}
