//! Built-in procedural scenes, so every command runs with no files:
//!
//! - `toycar` (default): static camera, a toy car driving over a textured, reflective
//!   floor among a mirror ball and a glass ball — the paper's "Toycar" situation.
//! - `room`: the camera circles through a cluttered room — the "Bart" situation.
//! - `terrain`: a walk over a finely detailed height field whose triangles and texture
//!   are smaller than a pixel in the distance — where point tracking matters.

use glam::{Mat4, Quat, Vec2, Vec3};

use super::{
    animation::{KeyframeTrack, RotationSpline, TcbKey, VectorSpline},
    AnimationRange, Camera, CameraTrack, Cone, Group, Light, Material, MaterialId, Node, NodeId,
    NodeKind, Scene, Sphere, Texture, Triangle,
};
use crate::sampling::rng::{hash, to_unit_f32};

/// Names of the built-in scenes; the first is the default.
pub const NAMES: &[&str] = &["toycar", "room", "terrain"];

/// One-line descriptions, aligned with [`NAMES`].
pub const DESCRIPTIONS: &[&str] = &[
    "static camera, toy car driving over a textured reflective floor (default)",
    "camera moving through a cluttered room",
    "walk over a finely detailed terrain (sub-pixel geometry and texture)",
];

/// Build a built-in scene by name.
pub fn load(name: &str) -> Option<Scene> {
    match name {
        "toycar" => Some(toycar()),
        "room" => Some(room()),
        "terrain" => Some(terrain()),
        _ => None,
    }
}

/// Why `arg` is taken for a built-in scene name that does not exist, with the name a
/// typo meant; `None` when it is a built-in name or looks like a file (it holds `/` or
/// `.`, or exists), which the loaders judge instead.
pub fn unknown_name(arg: &str) -> Option<String> {
    let looks_like_path =
        arg.contains('/') || arg.contains('.') || std::path::Path::new(arg).exists();
    if looks_like_path || NAMES.contains(&arg) {
        return None;
    }
    let close = NAMES
        .iter()
        .find(|n| edit_distance(n, arg) <= 2)
        .map(|n| format!(" (did you mean `{n}`?)"))
        .unwrap_or_default();
    Some(format!(
        "unknown scene `{arg}`{close}: built-in scenes are {}; or give a scene file \
         (.aff, .gltf, .glb, .obj)",
        NAMES.join(", ")
    ))
}

/// Levenshtein distance, for suggesting the name a typo meant.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut prev = row[0];
        row[0] = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let here = row[j + 1];
            row[j + 1] = (prev + usize::from(ca != cb)).min(row[j] + 1).min(here + 1);
            prev = here;
        }
    }
    row[b.len()]
}

/// Incremental construction of a scene.
struct Builder {
    scene: Scene,
}

impl Builder {
    fn new(name: &str) -> Self {
        Self {
            scene: Scene {
                name: name.to_string(),
                ambient: Vec3::ONE,
                ..Default::default()
            },
        }
    }

    fn material(&mut self, m: Material) -> MaterialId {
        self.scene.materials.push(m);
        (self.scene.materials.len() - 1) as MaterialId
    }

    fn texture(&mut self, t: Texture) -> u32 {
        self.scene.textures.push(t);
        (self.scene.textures.len() - 1) as u32
    }

    fn group(&mut self, node: Option<NodeId>) -> &mut Group {
        if let Some(i) = self.scene.groups.iter().position(|g| g.node == node) {
            return &mut self.scene.groups[i];
        }
        self.scene.groups.push(Group {
            node,
            ..Default::default()
        });
        self.scene.groups.last_mut().expect("just pushed")
    }

    fn animated_node(&mut self, name: &str, track: KeyframeTrack) -> NodeId {
        self.scene.tracks.push(KeyframeTrack {
            name: name.to_string(),
            ..track
        });
        let tid = (self.scene.tracks.len() - 1) as u32;
        self.scene.nodes.push(Node {
            parent: None,
            kind: NodeKind::Animated {
                name: name.to_string(),
                track: Some(tid),
            },
        });
        (self.scene.nodes.len() - 1) as NodeId
    }

    fn tri(
        &mut self,
        node: Option<NodeId>,
        p: [Vec3; 3],
        uv: Option<[Vec2; 3]>,
        material: MaterialId,
    ) {
        self.group(node).triangles.push(Triangle {
            p,
            n: None,
            uv,
            material,
        });
    }

    /// A quad `a b c d` (counter-clockwise), with texture coordinates scaled by `uv_scale`.
    fn quad(&mut self, node: Option<NodeId>, q: [Vec3; 4], uv_scale: Vec2, material: MaterialId) {
        let uv = [
            Vec2::ZERO,
            Vec2::new(uv_scale.x, 0.0),
            uv_scale,
            Vec2::new(0.0, uv_scale.y),
        ];
        self.tri(
            node,
            [q[0], q[1], q[2]],
            Some([uv[0], uv[1], uv[2]]),
            material,
        );
        self.tri(
            node,
            [q[0], q[2], q[3]],
            Some([uv[0], uv[2], uv[3]]),
            material,
        );
    }

    /// An axis-aligned box transformed by `m`.
    fn cuboid(&mut self, node: Option<NodeId>, m: Mat4, material: MaterialId) {
        let c = |x: f32, y: f32, z: f32| m.transform_point3(Vec3::new(x, y, z));
        let (l, h) = (-0.5, 0.5);
        let faces = [
            [c(l, l, h), c(h, l, h), c(h, h, h), c(l, h, h)],
            [c(h, l, l), c(l, l, l), c(l, h, l), c(h, h, l)],
            [c(h, l, h), c(h, l, l), c(h, h, l), c(h, h, h)],
            [c(l, l, l), c(l, l, h), c(l, h, h), c(l, h, l)],
            [c(l, h, h), c(h, h, h), c(h, h, l), c(l, h, l)],
            [c(l, l, l), c(h, l, l), c(h, l, h), c(l, l, h)],
        ];
        for f in faces {
            self.quad(node, f, Vec2::ONE, material);
        }
    }

    /// A capped cylinder from `a` to `b`.
    fn cylinder(&mut self, node: Option<NodeId>, a: Vec3, b: Vec3, r: f32, material: MaterialId) {
        self.group(node).cones.push(Cone {
            base: a,
            base_radius: r,
            apex: b,
            apex_radius: r,
            material,
        });
        let w = (b - a).normalize();
        let u = w.any_orthonormal_vector();
        let v = w.cross(u);
        let segs = 24;
        for (center, sign) in [(a, -1.0f32), (b, 1.0)] {
            for i in 0..segs {
                let t0 = i as f32 / segs as f32 * std::f32::consts::TAU;
                let t1 = (i + 1) as f32 / segs as f32 * std::f32::consts::TAU;
                let p0 = center + r * (u * t0.cos() + v * t0.sin());
                let p1 = center + r * (u * t1.cos() + v * t1.sin());
                let p = if sign > 0.0 {
                    [center, p0, p1]
                } else {
                    [center, p1, p0]
                };
                self.tri(node, p, None, material);
            }
        }
    }

    fn sphere(&mut self, node: Option<NodeId>, center: Vec3, radius: f32, material: MaterialId) {
        self.group(node).spheres.push(Sphere {
            center,
            radius,
            material,
        });
    }

    fn light(&mut self, position: Vec3, color: Vec3) {
        self.scene.lights.push(Light {
            position,
            color,
            track: None,
            name: None,
        });
    }

    fn camera(&mut self, base: Camera, track: Option<KeyframeTrack>) {
        let track = track.map(|t| {
            self.scene.tracks.push(KeyframeTrack {
                name: "camera".into(),
                ..t
            });
            (self.scene.tracks.len() - 1) as u32
        });
        self.scene.camera = CameraTrack {
            base,
            track,
            resolution: None,
        };
    }
}

fn checker(name: &str, n: u32, a: Vec3, b: Vec3) -> Texture {
    Texture::from_fn(name, 64, 64, |x, y| {
        if ((x * n / 64) + (y * n / 64)) % 2 == 0 {
            a
        } else {
            b
        }
    })
}

fn smooth_noise(x: f32, y: f32, seed: u64) -> f32 {
    let (xi, yi) = (x.floor(), y.floor());
    let (fx, fy) = (x - xi, y - yi);
    let v = |dx: f32, dy: f32| {
        to_unit_f32(hash(&[
            seed,
            (xi + dx) as i64 as u64,
            (yi + dy) as i64 as u64,
        ]))
    };
    let s = |t: f32| t * t * (3.0 - 2.0 * t);
    let (sx, sy) = (s(fx), s(fy));
    let a = v(0.0, 0.0) + (v(1.0, 0.0) - v(0.0, 0.0)) * sx;
    let b = v(0.0, 1.0) + (v(1.0, 1.0) - v(0.0, 1.0)) * sx;
    a + (b - a) * sy
}

fn fbm(x: f32, y: f32, octaves: u32, seed: u64) -> f32 {
    let (mut sum, mut amp, mut freq) = (0.0, 0.5, 1.0);
    for o in 0..octaves {
        sum += amp * (smooth_noise(x * freq, y * freq, seed + o as u64) - 0.5);
        amp *= 0.5;
        freq *= 2.03;
    }
    sum
}

fn yaw_keys(times_yaws: &[(f32, f32)]) -> RotationSpline {
    RotationSpline::new(
        times_yaws
            .iter()
            .map(|&(t, yaw)| TcbKey::catmull_rom(t, (Vec3::Y, yaw)))
            .collect(),
    )
    .expect("built-in tracks have enough keys")
}

fn positions(keys: &[(f32, Vec3)]) -> VectorSpline {
    VectorSpline::new(
        keys.iter()
            .map(|&(t, p)| TcbKey::catmull_rom(t, p))
            .collect(),
    )
    .expect("enough keys")
}

/// Static camera, a toy car driving a loop over a reflective checkered floor.
pub fn toycar() -> Scene {
    let mut b = Builder::new("toycar");
    b.scene.background = Vec3::new(0.55, 0.65, 0.85);
    b.scene.ambient = Vec3::splat(1.0);
    let tex = b.texture(checker(
        "checker",
        8,
        Vec3::splat(0.9),
        Vec3::new(0.15, 0.2, 0.35),
    ));
    let floor = b.material(Material {
        ambient: Vec3::splat(0.08),
        diffuse: Vec3::splat(0.7),
        specular: Vec3::splat(0.25),
        shininess: 40.0,
        texture: Some(tex),
        ..Material::default()
    });
    let s = 6.0;
    b.quad(
        None,
        [
            Vec3::new(-s, 0.0, s),
            Vec3::new(s, 0.0, s),
            Vec3::new(s, 0.0, -s),
            Vec3::new(-s, 0.0, -s),
        ],
        Vec2::splat(6.0),
        floor,
    );
    let mirror = b.material(Material {
        ambient: Vec3::ZERO,
        diffuse: Vec3::splat(0.05),
        specular: Vec3::splat(0.85),
        shininess: 200.0,
        ..Material::default()
    });
    let glass = b.material(Material {
        ambient: Vec3::ZERO,
        diffuse: Vec3::splat(0.02),
        specular: Vec3::splat(0.1),
        shininess: 150.0,
        transmission: 0.85,
        ior: 1.5,
        texture: None,
    });
    b.sphere(None, Vec3::new(-1.6, 0.7, -1.8), 0.7, mirror);
    b.sphere(None, Vec3::new(1.7, 0.5, -1.2), 0.5, glass);
    let post = b.material(Material::matte(Vec3::new(0.8, 0.7, 0.3)));
    b.cylinder(
        None,
        Vec3::new(0.3, 0.0, -2.6),
        Vec3::new(0.3, 1.2, -2.6),
        0.15,
        post,
    );

    // The car drives a loop around the origin, facing its direction of travel.
    let n = 9;
    let radius = 1.2;
    let mut tkeys = Vec::new();
    let mut rkeys = Vec::new();
    for i in -1..=n {
        let t = i as f32 * 1.25;
        let a = t / 10.0 * std::f32::consts::TAU;
        tkeys.push((t, Vec3::new(radius * 1.3 * a.cos(), 0.0, radius * a.sin())));
        // Tangent direction of the ellipse, as a yaw of the car's +X axis.
        let tangent = Vec3::new(-1.3 * a.sin(), 0.0, a.cos());
        rkeys.push((t, (-tangent.z).atan2(tangent.x).to_degrees()));
    }
    // Unwrap yaws so consecutive keys differ by less than 180 degrees.
    for i in 1..rkeys.len() {
        while rkeys[i].1 - rkeys[i - 1].1 > 180.0 {
            rkeys[i].1 -= 360.0;
        }
        while rkeys[i].1 - rkeys[i - 1].1 < -180.0 {
            rkeys[i].1 += 360.0;
        }
    }
    let car = b.animated_node(
        "car",
        KeyframeTrack {
            translation: Some(positions(&tkeys)),
            rotation: Some(yaw_keys(&rkeys)),
            ..Default::default()
        },
    );
    let red = b.material(Material {
        ambient: Vec3::new(0.08, 0.01, 0.01),
        diffuse: Vec3::new(0.75, 0.08, 0.06),
        specular: Vec3::splat(0.3),
        shininess: 60.0,
        ..Material::default()
    });
    let dark = b.material(Material::matte(Vec3::splat(0.06)));
    let win = b.material(Material {
        ambient: Vec3::ZERO,
        diffuse: Vec3::new(0.05, 0.08, 0.1),
        specular: Vec3::splat(0.6),
        shininess: 120.0,
        ..Material::default()
    });
    b.cuboid(
        Some(car),
        Mat4::from_scale_rotation_translation(
            Vec3::new(0.9, 0.22, 0.45),
            Quat::IDENTITY,
            Vec3::new(0.0, 0.21, 0.0),
        ),
        red,
    );
    b.cuboid(
        Some(car),
        Mat4::from_scale_rotation_translation(
            Vec3::new(0.45, 0.18, 0.4),
            Quat::IDENTITY,
            Vec3::new(-0.05, 0.41, 0.0),
        ),
        win,
    );
    for (x, z) in [(0.3, 0.24), (-0.3, 0.24), (0.3, -0.24), (-0.3, -0.24)] {
        let zs = if z > 0.0 { 0.04 } else { -0.04 };
        b.cylinder(
            Some(car),
            Vec3::new(x, 0.1, z),
            Vec3::new(x, 0.1, z + zs),
            0.1,
            dark,
        );
    }
    b.light(Vec3::new(3.0, 5.0, 4.0), Vec3::splat(0.7));
    b.light(Vec3::new(-4.0, 4.0, -1.0), Vec3::splat(0.35));
    b.camera(
        Camera {
            eye: Vec3::new(0.0, 2.2, 4.6),
            at: Vec3::new(0.0, 0.3, -0.4),
            up: Vec3::Y,
            fov_y_deg: 45.0,
            hither: 1e-3,
        },
        None,
    );
    b.scene.animation = Some(AnimationRange {
        start: 0.0,
        end: 10.0,
        frames: 601,
    });
    b.scene
}

/// A cluttered room the camera circles through.
pub fn room() -> Scene {
    let mut b = Builder::new("room");
    b.scene.background = Vec3::ZERO;
    b.scene.ambient = Vec3::ONE;
    let tiles = b.texture(checker(
        "tiles",
        16,
        Vec3::new(0.8, 0.75, 0.65),
        Vec3::new(0.45, 0.35, 0.3),
    ));
    let floor = b.material(Material {
        ambient: Vec3::splat(0.1),
        diffuse: Vec3::splat(0.7),
        specular: Vec3::splat(0.15),
        shininess: 30.0,
        texture: Some(tiles),
        ..Material::default()
    });
    let wall = b.material(Material {
        ambient: Vec3::splat(0.12),
        ..Material::matte(Vec3::new(0.75, 0.78, 0.7))
    });
    let (w, h) = (5.0, 3.0);
    b.quad(
        None,
        [
            Vec3::new(-w, 0.0, w),
            Vec3::new(w, 0.0, w),
            Vec3::new(w, 0.0, -w),
            Vec3::new(-w, 0.0, -w),
        ],
        Vec2::splat(5.0),
        floor,
    );
    b.quad(
        None,
        [
            Vec3::new(-w, h, -w),
            Vec3::new(w, h, -w),
            Vec3::new(w, h, w),
            Vec3::new(-w, h, w),
        ],
        Vec2::ONE,
        wall,
    );
    for (a, c) in [
        (Vec3::new(-w, 0.0, -w), Vec3::new(w, 0.0, -w)),
        (Vec3::new(w, 0.0, -w), Vec3::new(w, 0.0, w)),
        (Vec3::new(w, 0.0, w), Vec3::new(-w, 0.0, w)),
        (Vec3::new(-w, 0.0, w), Vec3::new(-w, 0.0, -w)),
    ] {
        b.quad(
            None,
            [a, c, c + Vec3::Y * h, a + Vec3::Y * h],
            Vec2::ONE,
            wall,
        );
    }
    // Clutter: boxes, balls and posts at hashed positions, kept out of the camera's ring.
    let palette = [
        Vec3::new(0.8, 0.2, 0.15),
        Vec3::new(0.2, 0.6, 0.25),
        Vec3::new(0.2, 0.3, 0.8),
        Vec3::new(0.85, 0.7, 0.2),
        Vec3::new(0.6, 0.3, 0.7),
    ];
    let mats: Vec<MaterialId> = palette
        .iter()
        .map(|&c| {
            b.material(Material {
                specular: Vec3::splat(0.2),
                shininess: 50.0,
                ..Material::matte(c)
            })
        })
        .collect();
    let shiny = b.material(Material {
        diffuse: Vec3::splat(0.1),
        specular: Vec3::splat(0.8),
        shininess: 200.0,
        ..Material::default()
    });
    let mut placed = 0;
    let mut i = 0u64;
    while placed < 60 && i < 1000 {
        i += 1;
        let r = |k: u64| to_unit_f32(hash(&[77, i, k]));
        let p = Vec3::new(
            (r(0) - 0.5) * 2.0 * (w - 0.4),
            0.0,
            (r(1) - 0.5) * 2.0 * (w - 0.4),
        );
        let ring = Vec2::new(p.x, p.z).length();
        if (2.2..3.4).contains(&ring) {
            continue; // the camera's path
        }
        let m = mats[(r(2) * mats.len() as f32) as usize % mats.len()];
        let size = 0.2 + 0.5 * r(3);
        match (r(4) * 3.0) as u32 {
            0 => b.cuboid(
                None,
                Mat4::from_scale_rotation_translation(
                    Vec3::new(size, size * (0.5 + 2.0 * r(5)), size),
                    Quat::from_rotation_y(r(6) * 3.0),
                    p + Vec3::Y * (size * (0.5 + 2.0 * r(5)) * 0.5),
                ),
                m,
            ),
            1 => b.sphere(
                None,
                p + Vec3::Y * size * 0.5,
                size * 0.5,
                if r(7) < 0.3 { shiny } else { m },
            ),
            _ => b.cylinder(None, p, p + Vec3::Y * (0.5 + 2.0 * r(5)), size * 0.25, m),
        }
        placed += 1;
    }
    b.light(Vec3::new(0.0, 2.2, 0.0), Vec3::splat(0.6));
    b.light(Vec3::new(3.5, 2.5, 3.5), Vec3::splat(0.3));
    b.light(Vec3::new(-3.5, 2.5, -3.0), Vec3::splat(0.3));
    // Camera: circles the room at radius 2.8, looking roughly at the center with a sway.
    let mut tk = Vec::new();
    let mut rk = Vec::new();
    for i in -1..=21 {
        let t = i as f32 * 0.5;
        let a = t / 10.0 * std::f32::consts::TAU;
        tk.push((
            t,
            Vec3::new(2.8 * a.sin(), 1.4 + 0.3 * (3.0 * a).sin(), 2.8 * a.cos()),
        ));
        rk.push((t, a.to_degrees() + 25.0 * (2.0 * a).sin()));
    }
    let track = KeyframeTrack {
        translation: Some(positions(&tk)),
        rotation: Some(yaw_keys(&rk)),
        ..Default::default()
    };
    b.camera(
        Camera {
            eye: tk[1].1,
            at: Vec3::ZERO,
            up: Vec3::Y,
            fov_y_deg: 60.0,
            hither: 1e-3,
        },
        Some(track),
    );
    b.scene.animation = Some(AnimationRange {
        start: 0.0,
        end: 10.0,
        frames: 601,
    });
    b.scene
}

/// Height of the built-in terrain at `(x, z)`.
fn terrain_height(x: f32, z: f32) -> f32 {
    2.5 * fbm(x * 0.06, z * 0.06, 4, 5) + 0.25 * fbm(x * 1.7, z * 1.7, 3, 11)
}

/// A walk over a finely detailed height field.
pub fn terrain() -> Scene {
    let mut b = Builder::new("terrain");
    b.scene.background = Vec3::new(0.6, 0.75, 0.95);
    b.scene.ambient = Vec3::ONE;
    let grass = b.texture(Texture::from_fn("grass", 256, 256, |x, y| {
        let n = fbm(x as f32 * 0.35, y as f32 * 0.35, 3, 3) + 0.5;
        let speck = to_unit_f32(hash(&[9, x as u64, y as u64]));
        Vec3::new(0.25 + 0.3 * n, 0.45 + 0.3 * n, 0.15 + 0.1 * speck) * (0.6 + 0.5 * speck)
    }));
    let ground = b.material(Material {
        ambient: Vec3::splat(0.15),
        diffuse: Vec3::splat(0.85),
        specular: Vec3::ZERO,
        texture: Some(grass),
        ..Material::default()
    });
    let n = 320usize;
    let size = 48.0f32;
    let step = size / n as f32;
    let grid = |i: usize, j: usize| {
        let (x, z) = (-size / 2.0 + i as f32 * step, -size / 2.0 + j as f32 * step);
        Vec3::new(x, terrain_height(x, z), z)
    };
    // Smooth shading normals from central differences of the height function.
    let normal = |p: Vec3| {
        let e = step * 0.5;
        let dx = terrain_height(p.x + e, p.z) - terrain_height(p.x - e, p.z);
        let dz = terrain_height(p.x, p.z + e) - terrain_height(p.x, p.z - e);
        Vec3::new(-dx, 2.0 * e, -dz).normalize()
    };
    let uvs = |p: Vec3| Vec2::new(p.x * 0.25, p.z * 0.25);
    let g = b.group(None);
    for j in 0..n {
        for i in 0..n {
            let (a, c, d, e) = (
                grid(i, j),
                grid(i + 1, j),
                grid(i + 1, j + 1),
                grid(i, j + 1),
            );
            for p in [[a, e, d], [a, d, c]] {
                g.triangles.push(Triangle {
                    p,
                    n: Some(p.map(normal)),
                    uv: Some(p.map(uvs)),
                    material: ground,
                });
            }
        }
    }
    let rock = b.material(Material {
        specular: Vec3::splat(0.1),
        shininess: 20.0,
        ..Material::matte(Vec3::new(0.5, 0.48, 0.45))
    });
    for i in 0..40u64 {
        let r = |k: u64| to_unit_f32(hash(&[31, i, k]));
        let (x, z) = ((r(0) - 0.5) * size * 0.9, (r(1) - 0.5) * size * 0.9);
        let rad = 0.2 + 0.8 * r(2);
        b.sphere(
            None,
            Vec3::new(x, terrain_height(x, z) + rad * 0.4, z),
            rad,
            rock,
        );
    }
    b.light(Vec3::new(40.0, 60.0, 30.0), Vec3::splat(0.9));
    // The walk: a gentle curve at walking pace, eye 1.7 above the ground.
    let mut tk = Vec::new();
    let mut rk = Vec::new();
    for i in -1..=11 {
        let t = i as f32;
        let x = -4.0 + 1.4 * t;
        let z = 8.0 - 1.0 * t + 1.5 * (t * 0.4).sin();
        tk.push((t, Vec3::new(x, terrain_height(x, z) + 1.7, z)));
        rk.push((t, -55.0 + 8.0 * (t * 0.5).sin()));
    }
    let track = KeyframeTrack {
        translation: Some(positions(&tk)),
        rotation: Some(yaw_keys(&rk)),
        ..Default::default()
    };
    b.camera(
        Camera {
            eye: tk[1].1,
            at: tk[2].1,
            up: Vec3::Y,
            fov_y_deg: 55.0,
            hither: 1e-3,
        },
        Some(track),
    );
    b.scene.animation = Some(AnimationRange {
        start: 0.0,
        end: 10.0,
        frames: 601,
    });
    b.scene
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_builtin_builds_and_animates() {
        for name in NAMES {
            let s = load(name).unwrap();
            assert!(s.primitive_count() > 0, "{name}");
            assert!(!s.lights.is_empty(), "{name}");
            let (t0, t1) = s.time_range();
            assert!(t1 > t0);
        }
        // The toy car moves; the room camera moves.
        let car = toycar();
        assert_ne!(car.node_world(0, 1.0), car.node_world(0, 2.0));
        let room = room();
        assert_ne!(room.camera_at(1.0).eye, room.camera_at(2.0).eye);
        assert!(load("nope").is_none());
    }

    #[test]
    fn unknown_names_get_the_list_and_the_name_a_typo_meant() {
        for name in NAMES {
            assert_eq!(unknown_name(name), None);
        }
        // Files are the loaders' to judge.
        assert_eq!(unknown_name("scenes/kitchen.aff"), None);
        let why = unknown_name("toycat").expect("not a scene");
        assert!(why.contains("did you mean `toycar`?"), "{why}");
        let why = unknown_name("kitchen").expect("not a scene");
        assert!(!why.contains("did you mean"), "{why}");
        assert!(NAMES.iter().all(|n| why.contains(n)), "{why}");
    }
}
