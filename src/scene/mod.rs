//! The scene model: everything that can be seen, evaluable at any continuous time `t`.
//!
//! A [`Scene`] is immutable once loaded. Geometry hangs off a flat transform hierarchy
//! ([`Node`]s with `u32` parent indices); a node is either a static matrix (AFF `xs`) or an
//! animated keyframe track (AFF `x`). Loaders and built-in scenes fill the same model, so
//! the tracer never knows where a scene came from.

pub mod aff;
pub mod animation;
pub mod builtin;
pub mod camera;
pub mod camera_path;
pub mod error;
pub mod gltf;
pub mod limits;
mod loader;
pub mod material;
pub mod obj;
pub mod texture;

use std::path::PathBuf;

use glam::{Mat4, Vec2, Vec3};

pub use animation::{KeyframeTrack, RotationSpline, TcbKey, VectorSpline};
pub use camera::{Camera, CameraFrame, CameraTrack};
pub use camera_path::CameraPath;
pub use error::SceneError;
pub use material::Material;
pub use texture::Texture;

/// Index of a [`Node`] in [`Scene::nodes`].
pub type NodeId = u32;
/// Index of a [`Material`] in [`Scene::materials`].
pub type MaterialId = u32;
/// Index of a [`Texture`] in [`Scene::textures`].
pub type TextureId = u32;
/// Index of a [`KeyframeTrack`] in [`Scene::tracks`].
pub type TrackId = u32;

/// How a node transforms its subtree relative to its parent.
#[derive(Clone, Debug)]
pub enum NodeKind {
    /// A fixed matrix (AFF `xs`).
    Static(Mat4),
    /// A keyframed transform `T(t)·R(t)·S(t)` (AFF `x name`); `None` means no keyframes
    /// were given, which the format defines as the identity.
    Animated {
        /// The node's name as written in the file (names need not be unique).
        name: String,
        /// The resolved keyframe track, if any.
        track: Option<TrackId>,
    },
    /// A glTF node driven by animation samplers, evaluated exactly as glTF specifies.
    Sampled(Box<gltf::NodeAnimation>),
}

/// One node of the transform hierarchy.
#[derive(Clone, Debug)]
pub struct Node {
    /// Parent node, `None` for a child of the world.
    pub parent: Option<NodeId>,
    /// What the node does to its subtree.
    pub kind: NodeKind,
}

/// A triangle with optional per-vertex normals and texture coordinates, in the space of
/// its node.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangle {
    /// Vertex positions, counter-clockwise seen from the front.
    pub p: [Vec3; 3],
    /// Per-vertex shading normals; `None` means use the geometric normal.
    pub n: Option<[Vec3; 3]>,
    /// Per-vertex texture coordinates.
    pub uv: Option<[Vec2; 3]>,
    /// Material (which also names the texture, if any).
    pub material: MaterialId,
}

/// A sphere (AFF `s`). A negative radius in the file means only the inside is visible;
/// the tracer shades both sides, so the sign is kept only for fidelity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    /// Center.
    pub center: Vec3,
    /// Radius (absolute value is used for intersection).
    pub radius: f32,
    /// Material.
    pub material: MaterialId,
}

/// A truncated cone or cylinder without end caps (AFF `c`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cone {
    /// Center of the base disc.
    pub base: Vec3,
    /// Radius at the base.
    pub base_radius: f32,
    /// Center of the apex disc.
    pub apex: Vec3,
    /// Radius at the apex.
    pub apex_radius: f32,
    /// Material.
    pub material: MaterialId,
}

/// A triangle whose vertices are keyframed (AFF `tpa`): linear interpolation between
/// keys, clamped at both ends, normals renormalised.
#[derive(Clone, Debug, PartialEq)]
pub struct AnimatedTriangle {
    /// Key times, ascending.
    pub times: Vec<f32>,
    /// Per key: the three vertex positions.
    pub positions: Vec<[Vec3; 3]>,
    /// Per key: the three vertex normals.
    pub normals: Vec<[Vec3; 3]>,
    /// Material.
    pub material: MaterialId,
    /// The node whose transform applies, `None` for world space.
    pub node: Option<NodeId>,
}

impl AnimatedTriangle {
    /// Positions, normals and per-vertex velocities (in node space) at time `t`.
    pub fn eval(&self, t: f32) -> ([Vec3; 3], [Vec3; 3], [Vec3; 3]) {
        let n = self.times.len();
        let zero = [Vec3::ZERO; 3];
        // Key normals in data need not be unit length (museum's are about 0.001).
        let unit = |ns: [Vec3; 3]| ns.map(|v| v.normalize_or(Vec3::Y));
        if n == 1 || t <= self.times[0] {
            return (self.positions[0], unit(self.normals[0]), zero);
        }
        if t >= self.times[n - 1] {
            return (self.positions[n - 1], unit(self.normals[n - 1]), zero);
        }
        // First key strictly after t; n >= 2 and times[0] < t < times[n-1] here.
        let k = self.times.partition_point(|&k| k <= t).clamp(1, n - 1);
        let (t0, t1) = (self.times[k - 1], self.times[k]);
        let dt = t1 - t0;
        let u = if dt > 0.0 {
            ((t - t0) / dt).clamp(0.0, 1.0)
        } else {
            1.0
        };
        let mut p = [Vec3::ZERO; 3];
        let mut nn = [Vec3::ZERO; 3];
        let mut v = [Vec3::ZERO; 3];
        for i in 0..3 {
            let (a, b) = (self.positions[k - 1][i], self.positions[k][i]);
            p[i] = a.lerp(b, u);
            nn[i] = self.normals[k - 1][i]
                .lerp(self.normals[k][i], u)
                .normalize_or(Vec3::Y);
            v[i] = if dt > 0.0 { (b - a) / dt } else { Vec3::ZERO };
        }
        (p, nn, v)
    }
}

/// Geometry attached to one node (or to the world when `node` is `None`).
#[derive(Clone, Debug, Default)]
pub struct Group {
    /// The innermost node above this geometry.
    pub node: Option<NodeId>,
    /// Triangles (polygons are stored triangulated).
    pub triangles: Vec<Triangle>,
    /// Spheres.
    pub spheres: Vec<Sphere>,
    /// Cones and cylinders.
    pub cones: Vec<Cone>,
}

impl Group {
    /// Number of primitives in the group.
    pub fn len(&self) -> usize {
        self.triangles.len() + self.spheres.len() + self.cones.len()
    }
    /// Whether the group holds no primitive.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// A point light with hard shadows.
#[derive(Clone, Debug)]
pub struct Light {
    /// Position (the animation's origin when `track` is set).
    pub position: Vec3,
    /// Linear RGB intensity.
    pub color: Vec3,
    /// Keyframe track whose translation moves the light (AFF `la`), if any.
    pub track: Option<TrackId>,
    /// The name an animation refers to (AFF `la name`).
    pub name: Option<String>,
}

/// The animation range declared by the scene (AFF `a start end frames`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AnimationRange {
    /// First time, seconds.
    pub start: f32,
    /// Last time, seconds (inclusive).
    pub end: f32,
    /// Number of frames the authors intended.
    pub frames: u32,
}

/// An animated scene, evaluable at any time.
#[derive(Clone, Debug, Default)]
pub struct Scene {
    /// Human-readable name (built-in name or file stem).
    pub name: String,
    /// Where the scene came from, if a file.
    pub source: Option<PathBuf>,
    /// Transform hierarchy, parents before children.
    pub nodes: Vec<Node>,
    /// Keyframe tracks, referenced by nodes, lights and the camera.
    pub tracks: Vec<KeyframeTrack>,
    /// Geometry, one group per distinct innermost node.
    pub groups: Vec<Group>,
    /// Triangles with animated vertices.
    pub animated_triangles: Vec<AnimatedTriangle>,
    /// Materials.
    pub materials: Vec<Material>,
    /// Textures.
    pub textures: Vec<Texture>,
    /// Point lights.
    pub lights: Vec<Light>,
    /// The camera and its animation.
    pub camera: CameraTrack,
    /// Color of rays that hit nothing.
    pub background: Vec3,
    /// Global ambient light (AFF `am`), multiplies each material's ambient color.
    pub ambient: Vec3,
    /// The declared animation range, if any.
    pub animation: Option<AnimationRange>,
}

/// Transform of a node chain at a time, with its time derivative and visibility.
#[derive(Clone, Copy, Debug)]
pub struct NodeState {
    /// Local-to-world matrix at `t`.
    pub matrix: Mat4,
    /// d(matrix)/dt, by a central difference; multiplies local points into velocities.
    pub velocity: Mat4,
    /// False when a visibility track (on this node or an ancestor) hides the subtree.
    pub visible: bool,
}

/// Step of the central difference used for velocities, seconds.
pub const VELOCITY_DT: f32 = 0.5e-3;

impl Scene {
    /// Local-to-parent matrix of one node at time `t`.
    pub fn node_local(&self, id: NodeId, t: f32) -> Mat4 {
        match &self.nodes[id as usize].kind {
            NodeKind::Static(m) => *m,
            NodeKind::Animated { track, .. } => match track {
                Some(tr) => self.tracks[*tr as usize].matrix(t),
                None => Mat4::IDENTITY,
            },
            NodeKind::Sampled(anim) => anim.matrix(t),
        }
    }

    /// Local-to-world matrix of a node at time `t`.
    pub fn node_world(&self, id: NodeId, t: f32) -> Mat4 {
        let mut m = self.node_local(id, t);
        let mut cur = self.nodes[id as usize].parent;
        while let Some(p) = cur {
            m = self.node_local(p, t) * m;
            cur = self.nodes[p as usize].parent;
        }
        m
    }

    /// Whether a node's subtree is visible at time `t`.
    pub fn node_visible(&self, id: NodeId, t: f32) -> bool {
        let mut cur = Some(id);
        while let Some(n) = cur {
            if let NodeKind::Animated {
                track: Some(tr), ..
            } = &self.nodes[n as usize].kind
            {
                if !self.tracks[*tr as usize].visible(t) {
                    return false;
                }
            }
            cur = self.nodes[n as usize].parent;
        }
        true
    }

    /// Whether a node, or any of its ancestors, is animated.
    pub fn node_is_animated(&self, id: NodeId) -> bool {
        let mut cur = Some(id);
        while let Some(n) = cur {
            if matches!(
                &self.nodes[n as usize].kind,
                NodeKind::Animated { track: Some(_), .. } | NodeKind::Sampled(_)
            ) {
                return true;
            }
            cur = self.nodes[n as usize].parent;
        }
        false
    }

    /// Full state of a node at time `t`.
    pub fn node_state(&self, id: NodeId, t: f32) -> NodeState {
        let matrix = self.node_world(id, t);
        let velocity = if self.node_is_animated(id) {
            let a = self.node_world(id, t - VELOCITY_DT);
            let b = self.node_world(id, t + VELOCITY_DT);
            (b - a) * (0.5 / VELOCITY_DT)
        } else {
            Mat4::ZERO
        };
        NodeState {
            matrix,
            velocity,
            visible: self.node_visible(id, t),
        }
    }

    /// Position and color of every light at time `t`.
    pub fn lights_at(&self, t: f32) -> Vec<(Vec3, Vec3)> {
        self.lights
            .iter()
            .map(|l| {
                let p = match l.track {
                    Some(tr) => self.tracks[tr as usize]
                        .translation
                        .as_ref()
                        .map_or(l.position, |s| s.eval(t)),
                    None => l.position,
                };
                (p, l.color)
            })
            .collect()
    }

    /// The camera at time `t`.
    pub fn camera_at(&self, t: f32) -> Camera {
        self.camera.at(t, &self.tracks)
    }

    /// Total number of primitives (triangles, spheres, cones, animated triangles).
    pub fn primitive_count(&self) -> usize {
        self.groups.iter().map(Group::len).sum::<usize>() + self.animated_triangles.len()
    }

    /// A sensible time window for the scene: its declared animation range, clamped to the
    /// range where its camera keys are valid, or `[0, 10]` seconds when nothing is declared.
    pub fn time_range(&self) -> (f32, f32) {
        match self.animation {
            Some(a) if a.end > a.start => (a.start, a.end),
            _ => (0.0, 10.0),
        }
    }
}

/// Load a scene from a built-in name or a file path (`.aff`, `.gltf`/`.glb`, `.obj`),
/// checked against the [`limits`].
pub fn load(arg: &str) -> Result<Scene, SceneError> {
    if let Some(s) = builtin::load(arg) {
        return Ok(s);
    }
    let path = std::path::Path::new(arg);
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    // Every loader checks its scene against the `limits` before returning it.
    let scene = match ext.as_str() {
        "aff" => aff::load(path),
        "gltf" | "glb" => gltf::load(path),
        "obj" => obj::load(path),
        _ => Err(SceneError::UnknownFormat {
            path: path.to_path_buf(),
            builtins: builtin::NAMES.join(", "),
        }),
    }?;
    Ok(scene)
}
