//! Helpers shared by the integration tests (each test file is its own crate, so not
//! every helper is used everywhere).
#![allow(dead_code)]

use frameless::scene::{
    animation::KeyframeTrack, Camera, CameraTrack, Group, Light, Material, Node, NodeKind, Scene,
    Sphere, Triangle,
};
use glam::Vec3;

/// A flat-shaded material: ambient only, so luminance is exactly its color.
pub fn flat(c: f32) -> Material {
    Material {
        ambient: Vec3::splat(c),
        diffuse: Vec3::ZERO,
        ..Material::default()
    }
}

/// An axis-aligned rectangle `[x0, x1] × [y0, y1]` at depth `z`, facing +z, as two
/// triangles.
pub fn quad(x0: f32, x1: f32, y0: f32, y1: f32, z: f32, material: u32) -> Vec<Triangle> {
    let p = [
        Vec3::new(x0, y0, z),
        Vec3::new(x1, y0, z),
        Vec3::new(x1, y1, z),
        Vec3::new(x0, y1, z),
    ];
    vec![
        Triangle {
            p: [p[0], p[1], p[2]],
            n: None,
            uv: None,
            material,
        },
        Triangle {
            p: [p[0], p[2], p[3]],
            n: None,
            uv: None,
            material,
        },
    ]
}

/// A checkerboard of `nx × ny` squares of side `cell` from `(x0, y0)` at depth `z`,
/// facing +z, in materials 0 and 1 alternately.
pub fn checkerboard(x0: f32, y0: f32, nx: u32, ny: u32, cell: f32, z: f32) -> Vec<Triangle> {
    let mut tris = Vec::new();
    for i in 0..nx {
        for j in 0..ny {
            let (x, y) = (x0 + cell * i as f32, y0 + cell * j as f32);
            tris.extend(quad(x, x + cell, y, y + cell, z, (i + j) % 2));
        }
    }
    tris
}

/// A wall with two spheres in front: silhouettes, so antialiasing matters.
pub fn two_spheres() -> Scene {
    Scene {
        name: "t".into(),
        materials: vec![
            Material::matte(Vec3::new(0.8, 0.7, 0.5)),
            Material::matte(Vec3::new(0.1, 0.3, 0.9)),
        ],
        groups: vec![Group {
            node: None,
            triangles: quad(-5.0, 5.0, -5.0, 5.0, -1.0, 0),
            spheres: vec![
                Sphere {
                    center: Vec3::new(-0.3, 0.1, -0.5),
                    radius: 0.35,
                    material: 1,
                },
                Sphere {
                    center: Vec3::new(0.45, -0.25, -0.3),
                    radius: 0.2,
                    material: 1,
                },
            ],
            ..Default::default()
        }],
        lights: vec![Light {
            position: Vec3::new(1.0, 2.0, 4.0),
            color: Vec3::ONE,
            track: None,
            name: None,
        }],
        camera: CameraTrack {
            base: Camera {
                eye: Vec3::new(0.0, 0.0, 1.5),
                at: Vec3::ZERO,
                up: Vec3::Y,
                fov_y_deg: 90.0,
                hither: 1e-3,
            },
            track: None,
            resolution: None,
        },
        ambient: Vec3::splat(0.3),
        ..Default::default()
    }
}

/// Add `track` to `scene` with a root node it animates; returns the node's index.
pub fn animate(scene: &mut Scene, track: KeyframeTrack) -> u32 {
    scene.nodes.push(Node {
        parent: None,
        kind: NodeKind::Animated {
            name: track.name.clone(),
            track: Some(scene.tracks.len() as u32),
        },
    });
    scene.tracks.push(track);
    (scene.nodes.len() - 1) as u32
}

/// A binary glTF container around a JSON and a BIN chunk (padded as required).
pub fn glb(json: &[u8], bin: &[u8]) -> Vec<u8> {
    let mut j = json.to_vec();
    while j.len() % 4 != 0 {
        j.push(b' ');
    }
    let mut b = bin.to_vec();
    while b.len() % 4 != 0 {
        b.push(0);
    }
    let total = 12 + 8 + j.len() + 8 + b.len();
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(j.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&j);
    out.extend_from_slice(&(b.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&b);
    out
}
