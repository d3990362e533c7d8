//! Helpers shared by the integration tests (each test file is its own crate, so not
//! every helper is used everywhere).
#![allow(dead_code)]

use frameless::scene::{Material, Triangle};
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
