//! Writes the glTF demo scene `docs/examples/demo.gltf` (+ `demo.bin`), used for the
//! render `docs/images/gltf.png`:
//!
//! ```text
//! cargo run --example make_gltf [-- OUTPUT_DIR]
//! cargo run --release -- still --scene docs/examples/demo.gltf --time 1 --size 400x300 --spp 16 --out docs/images/gltf.png
//! ```
//!
//! A checkered floor (PNG texture in the buffer), a turntable carrying two boxes (linear
//! rotation), a red cube hopping along a cubic-spline path with a stepped spin, a glass
//! sphere (`KHR_materials_transmission`, `KHR_materials_ior`), a brushed-metal pillar, a
//! perspective camera, a point and a directional light (`KHR_lights_punctual`).

use std::f32::consts::{PI, TAU};
use std::path::PathBuf;

use glam::{Mat3, Quat, Vec3};
use serde_json::{json, Value};

#[derive(Default)]
struct Bin {
    data: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Bin {
    fn view(&mut self, bytes: &[u8]) -> usize {
        while self.data.len() % 4 != 0 {
            self.data.push(0);
        }
        self.views
            .push(json!({ "buffer": 0, "byteOffset": self.data.len(), "byteLength": bytes.len() }));
        self.data.extend_from_slice(bytes);
        self.views.len() - 1
    }

    fn floats(&mut self, vals: &[f32], ty: &str) -> usize {
        let comps = match ty {
            "SCALAR" => 1,
            "VEC2" => 2,
            "VEC3" => 3,
            _ => 4,
        };
        let bytes: Vec<u8> = vals.iter().flat_map(|v| v.to_le_bytes()).collect();
        let v = self.view(&bytes);
        let mut acc = json!({ "bufferView": v, "componentType": 5126, "count": vals.len() / comps, "type": ty });
        if ty == "VEC3" || ty == "SCALAR" {
            let mut lo = vec![f32::INFINITY; comps];
            let mut hi = vec![f32::NEG_INFINITY; comps];
            for c in vals.chunks(comps) {
                for k in 0..comps {
                    lo[k] = lo[k].min(c[k]);
                    hi[k] = hi[k].max(c[k]);
                }
            }
            acc["min"] = json!(lo);
            acc["max"] = json!(hi);
        }
        self.accessors.push(acc);
        self.accessors.len() - 1
    }

    fn indices(&mut self, vals: &[u16]) -> usize {
        let bytes: Vec<u8> = vals.iter().flat_map(|v| v.to_le_bytes()).collect();
        let v = self.view(&bytes);
        self.accessors.push(json!({ "bufferView": v, "componentType": 5123, "count": vals.len(), "type": "SCALAR" }));
        self.accessors.len() - 1
    }

    /// A mesh primitive from positions, normals, optional UVs and indices.
    fn primitive(
        &mut self,
        p: &[Vec3],
        n: &[Vec3],
        uv: Option<&[[f32; 2]]>,
        idx: &[u16],
        material: usize,
    ) -> Value {
        let flat = |v: &[Vec3]| v.iter().flat_map(|x| x.to_array()).collect::<Vec<f32>>();
        let pos = self.floats(&flat(p), "VEC3");
        let nor = self.floats(&flat(n), "VEC3");
        let mut attrs = json!({ "POSITION": pos, "NORMAL": nor });
        if let Some(uv) = uv {
            let t: Vec<f32> = uv.iter().flatten().copied().collect();
            attrs["TEXCOORD_0"] = json!(self.floats(&t, "VEC2"));
        }
        let i = self.indices(idx);
        json!({ "attributes": attrs, "indices": i, "material": material })
    }
}

/// A unit cube centred on the origin, flat-shaded (24 vertices).
fn cube(bin: &mut Bin, material: usize) -> Value {
    let (mut p, mut n, mut uv, mut idx) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let mut normal = Vec3::ZERO;
            normal[axis] = sign;
            let u = Vec3::from_array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]][axis]);
            let v = normal.cross(u);
            let base = p.len() as u16;
            for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                p.push(normal * 0.5 + u * (0.5 * a) + v * (0.5 * b));
                n.push(normal);
                uv.push([(a + 1.0) * 0.5, (1.0 - b) * 0.5]);
            }
            idx.extend_from_slice(&[base, base + 1, base + 2, base, base + 2, base + 3]);
        }
    }
    bin.primitive(&p, &n, Some(&uv), &idx, material)
}

/// A UV sphere of radius 1 with smooth normals.
fn sphere(bin: &mut Bin, material: usize) -> Value {
    let (rings, segs) = (16u16, 32u16);
    let (mut p, mut idx) = (Vec::new(), Vec::new());
    for r in 0..=rings {
        let th = PI * r as f32 / rings as f32;
        for s in 0..=segs {
            let ph = TAU * s as f32 / segs as f32;
            p.push(Vec3::new(
                th.sin() * ph.cos(),
                th.cos(),
                -th.sin() * ph.sin(),
            ));
        }
    }
    let w = segs + 1;
    for r in 0..rings {
        for s in 0..segs {
            let (a, b) = (r * w + s, (r + 1) * w + s);
            idx.extend_from_slice(&[a, b, b + 1, a, b + 1, a + 1]);
        }
    }
    bin.primitive(&p, &p.clone(), None, &idx, material)
}

fn floor(bin: &mut Bin, material: usize) -> Value {
    let s = 6.0;
    let p = [
        Vec3::new(-s, 0.0, s),
        Vec3::new(s, 0.0, s),
        Vec3::new(s, 0.0, -s),
        Vec3::new(-s, 0.0, -s),
    ];
    let uv = [[0.0, 6.0], [6.0, 6.0], [6.0, 0.0], [0.0, 0.0]];
    bin.primitive(&p, &[Vec3::Y; 4], Some(&uv), &[0, 1, 2, 0, 2, 3], material)
}

fn checker_png() -> Vec<u8> {
    let n = 32u32;
    let mut rgb = Vec::new();
    for y in 0..n {
        for x in 0..n {
            let c: [u8; 3] = if (x / 16 + y / 16) % 2 == 0 {
                [225, 222, 210]
            } else {
                [60, 80, 120]
            };
            // A thin grout line, so the texture's orientation and filtering show.
            let c = if x % 16 == 0 || y % 16 == 0 {
                [150, 150, 150]
            } else {
                c
            };
            rgb.extend_from_slice(&c);
        }
    }
    let mut out = Vec::new();
    let mut e = png::Encoder::new(&mut out, n, n);
    e.set_color(png::ColorType::Rgb);
    e.set_depth(png::BitDepth::Eight);
    let mut w = e.write_header().expect("png header");
    w.write_image_data(&rgb).expect("png data");
    w.finish().expect("png end");
    out
}

fn quat(q: Quat) -> [f32; 4] {
    [q.x, q.y, q.z, q.w]
}

fn main() {
    let out = std::env::args().nth(1).map_or_else(
        || PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("docs/examples"),
        PathBuf::from,
    );
    std::fs::create_dir_all(&out).expect("creating the output directory");
    let mut bin = Bin::default();

    let materials = json!([
        { "name": "floor", "pbrMetallicRoughness": { "baseColorTexture": { "index": 0 }, "metallicFactor": 0.0, "roughnessFactor": 0.45 } },
        { "name": "red", "pbrMetallicRoughness": { "baseColorFactor": [0.85, 0.15, 0.1, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.35 } },
        { "name": "gold", "pbrMetallicRoughness": { "baseColorFactor": [0.95, 0.75, 0.3, 1.0], "metallicFactor": 1.0, "roughnessFactor": 0.15 } },
        { "name": "teal", "pbrMetallicRoughness": { "baseColorFactor": [0.1, 0.6, 0.55, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.8 } },
        { "name": "glass", "pbrMetallicRoughness": { "baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.0 },
          "extensions": { "KHR_materials_transmission": { "transmissionFactor": 0.9 }, "KHR_materials_ior": { "ior": 1.5 } } },
        { "name": "steel", "pbrMetallicRoughness": { "baseColorFactor": [0.8, 0.8, 0.82, 1.0], "metallicFactor": 1.0, "roughnessFactor": 0.6 } },
    ]);
    let meshes = json!([
        { "name": "floor", "primitives": [floor(&mut bin, 0)] },
        { "name": "red cube", "primitives": [cube(&mut bin, 1)] },
        { "name": "gold cube", "primitives": [cube(&mut bin, 2)] },
        { "name": "teal cube", "primitives": [cube(&mut bin, 3)] },
        { "name": "glass ball", "primitives": [sphere(&mut bin, 4)] },
        { "name": "pillar", "primitives": [cube(&mut bin, 5)] },
    ]);
    let png = checker_png();
    let image_view = bin.view(&png);

    // Animation: the turntable turns a quarter per second (linear, keys every 90°, since
    // slerp takes the short way); the red cube hops along a cubic spline and turns in
    // steps.
    let turn_t: Vec<f32> = (0..=4).map(|i| i as f32).collect();
    let turn_q: Vec<f32> = (0..=4)
        .flat_map(|i| quat(Quat::from_rotation_y(i as f32 * PI / 2.0)))
        .collect();
    let hop_t = [0.0f32, 1.0, 2.0, 3.0, 4.0];
    let mut hop = Vec::new();
    for x in [-2.6f32, -1.3, 0.0, 1.3, 2.6] {
        // Keys on the ground; vertical tangents make a hop between keys (peak 0.75 up).
        let up = 3.0;
        let pos = [x, 0.4, 2.2];
        hop.extend_from_slice(&[1.3, -up, 0.0]); // in-tangent: arriving downwards
        hop.extend_from_slice(&pos);
        hop.extend_from_slice(&[1.3, up, 0.0]); // out-tangent: leaving upwards
    }
    let spin_q: Vec<f32> = (0..5)
        .flat_map(|i| quat(Quat::from_rotation_y(i as f32 * 0.4)))
        .collect();
    let acc_turn_t = bin.floats(&turn_t, "SCALAR");
    let acc_turn_q = bin.floats(&turn_q, "VEC4");
    let acc_hop_t = bin.floats(&hop_t, "SCALAR");
    let acc_hop = bin.floats(&hop, "VEC3");
    let acc_spin = bin.floats(&spin_q, "VEC4");

    // Camera in front and above, looking at the middle of the scene.
    let eye = Vec3::new(0.0, 3.4, 8.0);
    let f = (Vec3::new(0.0, 0.7, 0.0) - eye).normalize();
    let right = f.cross(Vec3::Y).normalize();
    // glTF cameras look down their local −Z with +Y up.
    let cam_rot = Quat::from_mat3(&Mat3::from_cols(right, right.cross(f), -f));
    // Directional light shining down and away from the camera.
    let sun = Quat::from_rotation_y(0.6) * Quat::from_rotation_x(-1.0);

    let doc = json!({
        "asset": { "version": "2.0", "generator": "frameless examples/make_gltf.rs" },
        "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_transmission", "KHR_materials_ior"],
        "extensions": { "KHR_lights_punctual": { "lights": [
            { "name": "key", "type": "point", "color": [1.0, 0.95, 0.85], "intensity": 38.0 },
            { "name": "sun", "type": "directional", "color": [0.7, 0.8, 1.0], "intensity": 0.35 },
        ] } },
        "scene": 0,
        "scenes": [{ "name": "demo", "nodes": [0, 1, 2, 3, 4, 5, 6, 9] }],
        "nodes": [
            { "name": "floor", "mesh": 0 },
            { "name": "camera", "camera": 0, "translation": eye.to_array(), "rotation": quat(cam_rot) },
            { "name": "key light", "translation": [3.0, 5.0, 4.0], "extensions": { "KHR_lights_punctual": { "light": 0 } } },
            { "name": "sun", "rotation": quat(sun), "extensions": { "KHR_lights_punctual": { "light": 1 } } },
            { "name": "hopper", "mesh": 1, "scale": [0.8, 0.8, 0.8] },
            { "name": "glass ball", "mesh": 4, "translation": [1.6, 0.75, -0.6], "scale": [0.75, 0.75, 0.75] },
            { "name": "turntable", "translation": [-1.2, 0.0, -1.4], "children": [7, 8] },
            { "name": "gold cube", "mesh": 2, "translation": [0.9, 0.45, 0.0], "scale": [0.9, 0.9, 0.9] },
            { "name": "teal cube", "mesh": 3, "translation": [-0.9, 0.35, 0.0], "scale": [0.7, 0.7, 0.7], "rotation": quat(Quat::from_rotation_y(0.5)) },
            { "name": "pillar", "mesh": 5, "translation": [3.4, 1.0, -2.6], "scale": [0.5, 2.0, 0.5] },
        ],
        "cameras": [{ "type": "perspective", "perspective": { "yfov": 0.75, "znear": 0.05, "aspectRatio": 1.3333 } }],
        "meshes": meshes,
        "materials": materials,
        "textures": [{ "source": 0, "sampler": 0 }],
        "samplers": [{ "magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497 }],
        "images": [{ "bufferView": image_view, "mimeType": "image/png" }],
        "animations": [{
            "name": "demo",
            "channels": [
                { "sampler": 0, "target": { "node": 6, "path": "rotation" } },
                { "sampler": 1, "target": { "node": 4, "path": "translation" } },
                { "sampler": 2, "target": { "node": 4, "path": "rotation" } },
            ],
            "samplers": [
                { "input": acc_turn_t, "output": acc_turn_q, "interpolation": "LINEAR" },
                { "input": acc_hop_t, "output": acc_hop, "interpolation": "CUBICSPLINE" },
                { "input": acc_hop_t, "output": acc_spin, "interpolation": "STEP" },
            ],
        }],
    });
    let mut doc = doc;
    while bin.data.len() % 4 != 0 {
        bin.data.push(0);
    }
    doc["bufferViews"] = json!(bin.views);
    doc["accessors"] = json!(bin.accessors);
    doc["buffers"] = json!([{ "byteLength": bin.data.len(), "uri": "demo.bin" }]);
    let gltf = out.join("demo.gltf");
    std::fs::write(&gltf, serde_json::to_vec_pretty(&doc).expect("json"))
        .expect("writing demo.gltf");
    std::fs::write(out.join("demo.bin"), &bin.data).expect("writing demo.bin");
    eprintln!(
        "wrote {} and demo.bin ({} bytes)",
        gltf.display(),
        bin.data.len()
    );
}
