//! glTF and OBJ loading: animation sampling against hand-computed values, textures,
//! cameras, lights, OBJ/MTL materials, and malformed input (errors naming the file, never
//! a panic). Every file is generated here, in a fresh directory under the system's
//! temporary directory.

use std::f32::consts::FRAC_1_SQRT_2;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use frameless::scene::{
    self,
    gltf::{self as loader, NodeAnimation},
    NodeKind, Scene, SceneError,
};
use glam::{Quat, Vec2, Vec3};
use proptest::prelude::*;
use serde_json::{json, Value};

mod common;

fn tmpdir(tag: &str) -> PathBuf {
    static N: AtomicUsize = AtomicUsize::new(0);
    let d = std::env::temp_dir().join(format!(
        "frameless-gltf-obj-{}-{tag}-{}",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    ));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn base64(data: &[u8]) -> String {
    const A: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for c in data.chunks(3) {
        let n = (c[0] as u32) << 16
            | (*c.get(1).unwrap_or(&0) as u32) << 8
            | *c.get(2).unwrap_or(&0) as u32;
        for i in 0..4 {
            if i <= c.len() {
                s.push(A[(n >> (18 - 6 * i) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

fn png_rgb(w: u32, h: u32, rgb: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut e = png::Encoder::new(&mut out, w, h);
    e.set_color(png::ColorType::Rgb);
    e.set_depth(png::BitDepth::Eight);
    let mut wr = e.write_header().unwrap();
    wr.write_image_data(rgb).unwrap();
    wr.finish().unwrap();
    out
}

/// Binary buffer, buffer views and accessors of a glTF file under construction.
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
        if ty == "VEC3" {
            let mut lo = [f32::INFINITY; 3];
            let mut hi = [f32::NEG_INFINITY; 3];
            for c in vals.chunks(3) {
                for k in 0..3 {
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
        self.accessors
            .push(json!({ "bufferView": v, "componentType": 5123, "count": vals.len(), "type": "SCALAR" }));
        self.accessors.len() - 1
    }

    /// The document with buffer views and accessors filled in and buffer 0 at `uri`
    /// (`None`: the GLB binary chunk).
    fn attach(&mut self, mut doc: Value, uri: Option<String>) -> Value {
        while self.data.len() % 4 != 0 {
            self.data.push(0);
        }
        doc["asset"] = json!({ "version": "2.0" });
        doc["bufferViews"] = json!(self.views);
        doc["accessors"] = json!(self.accessors);
        let mut buf = json!({ "byteLength": self.data.len() });
        if let Some(u) = uri {
            buf["uri"] = json!(u);
        }
        doc["buffers"] = json!([buf]);
        doc
    }

    fn write_embedded(&mut self, path: &Path, doc: Value) {
        while self.data.len() % 4 != 0 {
            self.data.push(0);
        }
        let uri = format!(
            "data:application/octet-stream;base64,{}",
            base64(&self.data)
        );
        let doc = self.attach(doc, Some(uri));
        std::fs::write(path, serde_json::to_vec_pretty(&doc).unwrap()).unwrap();
    }

    fn write_external(&mut self, path: &Path, doc: Value, bin_name: &str) {
        let doc = self.attach(doc, Some(bin_name.to_string()));
        std::fs::write(path, serde_json::to_vec_pretty(&doc).unwrap()).unwrap();
        std::fs::write(path.parent().unwrap().join(bin_name), &self.data).unwrap();
    }

    fn glb(&mut self, doc: Value) -> Vec<u8> {
        let doc = self.attach(doc, None);
        common::glb(&serde_json::to_vec(&doc).unwrap(), &self.data)
    }
}

/// A unit quad in the XY plane with UVs, as a mesh primitive of material 0.
fn quad_primitive(bin: &mut Bin) -> Value {
    let pos = bin.floats(
        &[
            -1.0, -1.0, 0.0, 1.0, -1.0, 0.0, 1.0, 1.0, 0.0, -1.0, 1.0, 0.0,
        ],
        "VEC3",
    );
    let uv = bin.floats(&[0.0, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0], "VEC2");
    let idx = bin.indices(&[0, 1, 2, 0, 2, 3]);
    json!({ "attributes": { "POSITION": pos, "TEXCOORD_0": uv }, "indices": idx, "material": 0 })
}

fn sampled<'a>(s: &'a Scene, name: &str) -> &'a NodeAnimation {
    s.nodes
        .iter()
        .find_map(|n| match &n.kind {
            NodeKind::Sampled(a) if a.name == name => Some(&**a),
            _ => None,
        })
        .unwrap_or_else(|| panic!("no animated node {name}"))
}

fn close(a: Vec3, b: Vec3) -> bool {
    (a - b).length() < 1e-4
}

/// Nodes: `mover` (linear translation, step rotation), child `body` with the quad, and
/// `spline` (cubic-spline translation, linear rotation).
fn animated_scene(bin: &mut Bin) -> Value {
    let prim = quad_primitive(bin);
    let t01 = bin.floats(&[0.0, 2.0], "SCALAR");
    let tr = bin.floats(&[0.0, 0.0, 0.0, 4.0, 2.0, 0.0], "VEC3");
    let t_step = bin.floats(&[0.0, 1.0], "SCALAR");
    let q90 = Quat::from_rotation_y(std::f32::consts::FRAC_PI_2);
    let rot = bin.floats(&[0.0, 0.0, 0.0, 1.0, q90.x, q90.y, q90.z, q90.w], "VEC4");
    // Cubic spline keys at t = 0 and 2: (in, value, out) per key.
    let cubic = bin.floats(
        &[
            9.0, 9.0, 9.0, /* a0 (unused) */ 0.0, 0.0, 0.0, /* v0 */ 1.0, 0.0,
            0.0, /* b0 */
            3.0, 0.0, 0.0, /* a1 */ 2.0, 0.0, 0.0, /* v1 */ 9.0, 9.0,
            9.0, /* b1 (unused) */
        ],
        "VEC3",
    );
    json!({
        "scene": 0,
        "scenes": [{ "nodes": [0, 2] }],
        "nodes": [
            { "name": "mover", "children": [1], "scale": [1.0, 1.0, 1.0] },
            { "name": "body", "mesh": 0, "translation": [0.0, 0.5, 0.0] },
            { "name": "spline", "translation": [7.0, 7.0, 7.0] },
        ],
        "meshes": [{ "primitives": [prim] }],
        "materials": [{ "pbrMetallicRoughness": { "baseColorFactor": [0.5, 0.25, 1.0, 1.0], "metallicFactor": 0.0 } }],
        "animations": [{
            "channels": [
                { "sampler": 0, "target": { "node": 0, "path": "translation" } },
                { "sampler": 1, "target": { "node": 0, "path": "rotation" } },
                { "sampler": 2, "target": { "node": 2, "path": "translation" } },
                { "sampler": 3, "target": { "node": 2, "path": "rotation" } },
            ],
            "samplers": [
                { "input": t01, "output": tr, "interpolation": "LINEAR" },
                { "input": t_step, "output": rot, "interpolation": "STEP" },
                { "input": t01, "output": cubic, "interpolation": "CUBICSPLINE" },
                { "input": t_step, "output": rot },
            ],
        }],
    })
}

#[test]
fn animated_nodes_follow_gltf_sampling() {
    let dir = tmpdir("anim");
    let path = dir.join("anim.gltf");
    let mut bin = Bin::default();
    let doc = animated_scene(&mut bin);
    bin.write_embedded(&path, doc);
    let s = scene::load(path.to_str().unwrap()).unwrap();

    let mover = sampled(&s, "mover");
    // Linear translation (0,0,0) → (4,2,0) over [0, 2], clamped outside.
    assert!(close(mover.translation_at(0.5), Vec3::new(1.0, 0.5, 0.0)));
    assert!(close(mover.translation_at(1.5), Vec3::new(3.0, 1.5, 0.0)));
    assert!(close(mover.translation_at(-1.0), Vec3::ZERO));
    assert!(close(mover.translation_at(5.0), Vec3::new(4.0, 2.0, 0.0)));
    // Step rotation: identity until t = 1, then 90° about +Y.
    let q90 = Quat::from_rotation_y(std::f32::consts::FRAC_PI_2);
    assert!(mover.rotation_at(0.99).dot(Quat::IDENTITY).abs() > 1.0 - 1e-6);
    assert!(mover.rotation_at(1.0).dot(q90).abs() > 1.0 - 1e-6);
    assert!(mover.rotation_at(3.0).dot(q90).abs() > 1.0 - 1e-6);

    let spline = sampled(&s, "spline");
    // Hermite at u = ½, dt = 2: h00 = ½, h10 = ⅛, h01 = ½, h11 = −⅛:
    // 0·½ + 2·⅛·1 + 2·½ + 2·(−⅛)·3 = 0.25 + 1 − 0.75 = 0.5.
    assert!(
        close(spline.translation_at(1.0), Vec3::new(0.5, 0.0, 0.0)),
        "{}",
        spline.translation_at(1.0)
    );
    // At u = ¼: h00 = 27/32, h10 = 9/64, h01 = 5/32, h11 = −3/64:
    // 2·9/64·1 + 2·5/32 + 2·(−3/64)·3 = 18/64 + 20/64 − 18/64 = 20/64.
    assert!(close(
        spline.translation_at(0.5),
        Vec3::new(20.0 / 64.0, 0.0, 0.0)
    ));
    assert!(close(spline.translation_at(2.0), Vec3::new(2.0, 0.0, 0.0)));
    // Keys are hit exactly and the tangents of the ends do not leak outside.
    assert!(close(spline.translation_at(0.0), Vec3::ZERO));
    assert!(close(spline.translation_at(-3.0), Vec3::ZERO));
    // Linear rotation (slerp): half way is 45°.
    let q45 = Quat::from_rotation_y(std::f32::consts::FRAC_PI_4);
    assert!(spline.rotation_at(0.5).dot(q45).abs() > 1.0 - 1e-6);
    // The rest scale stays where no sampler overrides it.
    assert_eq!(spline.scale_at(1.0), Vec3::ONE);

    // The hierarchy: the quad hangs under `mover` and moves with it.
    let g = &s.groups[0];
    let node = g.node.unwrap();
    assert!(s.node_is_animated(node));
    let m = s.node_world(node, 2.0);
    // At t = 2: T(4,2,0)·R(90° Y) · T(0,0.5,0): the body's origin is at (4, 2.5, 0).
    assert!(close(
        m.transform_point3(Vec3::ZERO),
        Vec3::new(4.0, 2.5, 0.0)
    ));
    // Rotated 90° about Y, local +X points to world −Z.
    assert!(close(m.transform_vector3(Vec3::X), Vec3::NEG_Z));
    let range = s.animation.unwrap();
    assert_eq!((range.start, range.end), (0.0, 2.0));
    // Material mapping: dielectric, fully rough → diffuse = base color, no mirror.
    let mat = &s.materials[g.triangles[0].material as usize];
    assert!(close(mat.diffuse, Vec3::new(0.5, 0.25, 1.0)));
    assert_eq!(mat.specular, Vec3::ZERO);
    // No camera or light in the file: defaults are placed.
    assert_eq!(s.lights.len(), 1);
    assert!(s.camera.base.eye.z > s.camera.base.at.z);
}

#[test]
fn textured_quad_from_gltf_and_glb() {
    let dir = tmpdir("tex");
    // 2×2 image: red, green / blue, white.
    let png = png_rgb(2, 2, &[255, 0, 0, 0, 255, 0, 0, 0, 255, 255, 255, 255]);
    let check = |s: &Scene| {
        assert_eq!(s.textures.len(), 1);
        let t = &s.textures[0];
        assert_eq!((t.width, t.height), (2, 2));
        assert!(close(t.texels[0], Vec3::X));
        assert!(close(t.texels[1], Vec3::Y));
        assert!(close(t.texels[2], Vec3::Z));
        let tris = &s.groups[0].triangles;
        assert_eq!(tris.len(), 2);
        // glTF's v points down the image, this renderer's up: the file's (0,1), (1,1), (1,0)
        // come back flipped, so the quad's top-left corner (file uv (0,0)) shows the
        // image's first texel, red.
        assert_eq!(
            tris[0].uv,
            Some([
                Vec2::new(0.0, 0.0),
                Vec2::new(1.0, 0.0),
                Vec2::new(1.0, 1.0)
            ])
        );
        assert_eq!(tris[1].uv.unwrap()[2], Vec2::new(0.0, 1.0));
        assert!(close(t.sample(Vec2::new(0.25, 1.0 - 0.25)), Vec3::X));
        assert!(close(t.sample(Vec2::new(0.25, 0.25)), Vec3::Z));
        assert_eq!(tris[1].p[2], Vec3::new(-1.0, 1.0, 0.0));
        // No normals in the file: flat shading from the geometric normal.
        assert_eq!(tris[0].n, None);
        let m = &s.materials[tris[0].material as usize];
        assert_eq!(m.texture, Some(0));
    };
    let material = json!([{ "pbrMetallicRoughness": { "baseColorTexture": { "index": 0 }, "metallicFactor": 0.0 } }]);

    // .gltf with an embedded buffer and a data-URI PNG.
    let mut bin = Bin::default();
    let prim = quad_primitive(&mut bin);
    let doc = json!({
        "scenes": [{ "nodes": [0] }], "nodes": [{ "mesh": 0 }], "meshes": [{ "primitives": [prim] }],
        "materials": material, "textures": [{ "source": 0 }],
        "images": [{ "uri": format!("data:image/png;base64,{}", base64(&png)) }],
    });
    let path = dir.join("quad.gltf");
    bin.write_embedded(&path, doc);
    check(&scene::load(path.to_str().unwrap()).unwrap());

    // .glb with the PNG in a buffer view.
    let mut bin = Bin::default();
    let prim = quad_primitive(&mut bin);
    let view = bin.view(&png);
    let doc = json!({
        "scenes": [{ "nodes": [0] }], "nodes": [{ "mesh": 0 }], "meshes": [{ "primitives": [prim] }],
        "materials": material, "textures": [{ "source": 0 }],
        "images": [{ "bufferView": view, "mimeType": "image/png" }],
    });
    let path = dir.join("quad.glb");
    std::fs::write(&path, bin.glb(doc)).unwrap();
    check(&scene::load(path.to_str().unwrap()).unwrap());

    // .gltf with external buffer and image files (one with a space, percent-encoded).
    let mut bin = Bin::default();
    let prim = quad_primitive(&mut bin);
    std::fs::write(dir.join("my tex.png"), &png).unwrap();
    let doc = json!({
        "scenes": [{ "nodes": [0] }], "nodes": [{ "mesh": 0 }], "meshes": [{ "primitives": [prim] }],
        "materials": material, "textures": [{ "source": 0 }], "images": [{ "uri": "my%20tex.png" }],
    });
    let path = dir.join("external.gltf");
    bin.write_external(&path, doc, "external.bin");
    check(&scene::load(path.to_str().unwrap()).unwrap());

    // Missing image file: an error naming it.
    std::fs::remove_file(dir.join("my tex.png")).unwrap();
    let e = scene::load(path.to_str().unwrap()).unwrap_err();
    assert!(e.to_string().contains("my tex.png"), "{e}");
}

fn camera_doc(bin: &mut Bin) -> Value {
    let prim = quad_primitive(bin);
    let t = bin.floats(&[0.0, 2.0], "SCALAR");
    let tr = bin.floats(&[0.0, 0.0, 5.0, 2.0, 0.0, 5.0], "VEC3");
    let q = Quat::from_rotation_y(std::f32::consts::FRAC_PI_2);
    json!({
        "scenes": [{ "nodes": [0, 1, 2, 3, 4] }],
        "nodes": [
            { "mesh": 0 },
            { "name": "ortho", "camera": 2 },
            { "name": "main", "camera": 0, "translation": [0.0, 1.0, 5.0] },
            { "name": "side", "camera": 1, "translation": [3.0, 0.0, 0.0], "rotation": [q.x, q.y, q.z, q.w] },
            { "name": "dolly", "camera": 0, "translation": [0.0, 0.0, 5.0] },
        ],
        "cameras": [
            { "type": "perspective", "perspective": { "yfov": 0.6, "znear": 0.05 } },
            { "name": "sidecam", "type": "perspective", "perspective": { "yfov": 1.0, "znear": 0.1, "aspectRatio": 2.0 } },
            { "type": "orthographic", "orthographic": { "xmag": 1.0, "ymag": 1.0, "znear": 0.1, "zfar": 10.0 } },
        ],
        "meshes": [{ "primitives": [prim] }],
        "materials": [{}],
        "animations": [{
            "channels": [{ "sampler": 0, "target": { "node": 4, "path": "translation" } }],
            "samplers": [{ "input": t, "output": tr }],
        }],
    })
}

#[test]
fn cameras_by_order_and_name() {
    let dir = tmpdir("cam");
    let path = dir.join("cams.gltf");
    let mut bin = Bin::default();
    let doc = camera_doc(&mut bin);
    bin.write_embedded(&path, doc);

    // The first perspective camera (the orthographic one before it is skipped).
    let s = loader::load(&path).unwrap();
    let c = s.camera.base;
    assert!(close(c.eye, Vec3::new(0.0, 1.0, 5.0)));
    assert!(close(c.at - c.eye, Vec3::NEG_Z));
    assert!(close(c.up, Vec3::Y));
    assert!((c.fov_y_deg - 0.6f32.to_degrees()).abs() < 1e-4);
    assert!((c.hither - 0.05).abs() < 1e-7);
    assert!(s.camera.track.is_none());

    // By camera name; rotated 90° about +Y, it looks along −X.
    let s = loader::load_with_camera(&path, Some("sidecam")).unwrap();
    let c = s.camera.base;
    assert!(close(c.eye, Vec3::new(3.0, 0.0, 0.0)));
    assert!(close(c.at - c.eye, Vec3::NEG_X));
    assert!((c.fov_y_deg - 1.0f32.to_degrees()).abs() < 1e-4);
    // By node name, too.
    let s = loader::load_with_camera(&path, Some("side")).unwrap();
    assert!(close(s.camera.base.eye, Vec3::new(3.0, 0.0, 0.0)));

    // An animated camera node is followed.
    let s = loader::load_with_camera(&path, Some("dolly")).unwrap();
    assert!(s.camera.track.is_some());
    for (t, x) in [(0.0, 0.0), (0.5, 0.5), (1.0, 1.0), (2.0, 2.0), (3.0, 2.0)] {
        let c = s.camera_at(t);
        assert!(close(c.eye, Vec3::new(x, 0.0, 5.0)), "t = {t}: {}", c.eye);
        assert!(close(c.at - c.eye, Vec3::NEG_Z));
    }

    let e = loader::load_with_camera(&path, Some("nobody")).unwrap_err();
    assert!(
        e.to_string().contains("nobody") && e.to_string().contains("sidecam"),
        "{e}"
    );
    let e = loader::load_with_camera(&path, Some("ortho")).unwrap_err();
    assert!(e.to_string().contains("perspective"), "{e}");
}

/// The committed `docs/examples/fence.gltf` (written by `docs/examples/make_fence.py`)
/// loads with the camera its file animates: a strafe, a stop, then a pan.
#[test]
fn the_fence_example_follows_its_animated_camera() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/docs/examples/fence.gltf");
    let s = scene::load(path).unwrap();
    assert!(s.camera.track.is_some());
    // Eye x from the file's keys; the view straight ahead once the strafe has stopped.
    for (t, x) in [(0.0, -4.0), (1.0, -1.0), (2.5, 2.5), (3.5, 2.5), (5.0, 2.5)] {
        let c = s.camera_at(t);
        assert!(close(c.eye, Vec3::new(x, 1.2, 3.2)), "t = {t}: {}", c.eye);
    }
    let yaw = |t: f32| {
        let c = s.camera_at(t);
        let d = c.at - c.eye;
        (-d.x).atan2(-d.z)
    };
    assert!(yaw(3.0).abs() < 1e-4, "still ahead at 3 s: {}", yaw(3.0));
    // Held between equal keys (2.5-3.5 s): the same view at every moment, to the bit,
    // away from the ends, where the baked spline still eases in and out.
    assert_held_from(&s, 2.6);
    assert!((yaw(5.0) - 0.7).abs() < 1e-3, "panned at 5 s: {}", yaw(5.0));
}

/// The committed `docs/examples/arcade.gltf` (written by `docs/examples/make_arcade.py`)
/// loads with the camera its file animates: a dolly in, a hold, a fast turn, a rise.
#[test]
fn the_arcade_example_follows_its_animated_camera() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/docs/examples/arcade.gltf");
    let s = scene::load(path).unwrap();
    assert!(s.camera.track.is_some());
    let eyes = [
        (0.0, Vec3::new(0.0, 1.6, 6.0)),
        (1.5, Vec3::new(0.6, 1.6, 2.0)),
        (3.5, Vec3::new(0.6, 1.6, 2.0)),
        (5.5, Vec3::new(0.6, 2.6, 2.0)),
    ];
    for (t, eye) in eyes {
        let c = s.camera_at(t);
        assert!(close(c.eye, eye), "t = {t}: {}", c.eye);
    }
    let yaw = |t: f32| {
        let d = s.camera_at(t).at - s.camera_at(t).eye;
        (-d.x).atan2(-d.z)
    };
    assert!(
        (yaw(2.0) - 0.3).abs() < 1e-3,
        "turned left at 2 s: {}",
        yaw(2.0)
    );
    assert!(
        (yaw(3.5) + 0.5).abs() < 1e-3,
        "turned right at 3.5 s: {}",
        yaw(3.5)
    );
    // Held between equal keys (1.5-2.5 s): the same view at every moment, to the bit.
    assert_held_from(&s, 1.6);
}

/// `s`'s camera shows the same view, to the bit, at every refresh of 60 Hz for 0.8 s
/// from `t0`.
fn assert_held_from(s: &scene::Scene, t0: f32) {
    let held = s.camera_at(t0).frame(256, 256);
    for k in 0..=48 {
        let t = t0 + k as f32 / 60.0;
        assert!(
            s.camera_at(t).frame(256, 256).same_view(&held),
            "moved at {t}"
        );
    }
}

#[test]
fn punctual_lights() {
    let dir = tmpdir("lights");
    let path = dir.join("lights.gltf");
    let mut bin = Bin::default();
    let prim = quad_primitive(&mut bin);
    let doc = json!({
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": { "KHR_lights_punctual": { "lights": [
            { "type": "point", "color": [1.0, 0.5, 0.25], "intensity": 16.0 },
            { "type": "directional", "intensity": 2.0 },
        ] } },
        "scenes": [{ "nodes": [0, 1, 2] }],
        "nodes": [
            { "mesh": 0 },
            { "translation": [0.0, 0.0, 4.0], "extensions": { "KHR_lights_punctual": { "light": 0 } } },
            { "rotation": [-FRAC_1_SQRT_2, 0.0, 0.0, FRAC_1_SQRT_2], "extensions": { "KHR_lights_punctual": { "light": 1 } } },
        ],
        "meshes": [{ "primitives": [prim] }],
        "materials": [{}],
    });
    bin.write_embedded(&path, doc);
    let s = scene::load(path.to_str().unwrap()).unwrap();
    assert_eq!(s.lights.len(), 2);
    // Point light 4 units from the bounds' center: 16 cd / 4² = 1 per unit color.
    assert!(close(s.lights[0].position, Vec3::new(0.0, 0.0, 4.0)));
    assert!(close(s.lights[0].color, Vec3::new(1.0, 0.5, 0.25)));
    // Directional light pointing down (−Z rotated −90° about X is −Y): placed far above.
    assert!(close(s.lights[1].color, Vec3::splat(2.0)));
    let p = s.lights[1].position;
    assert!(p.y > 100.0 && p.x.abs() < 1e-2 && p.z.abs() < 1e-2, "{p}");
}

const OBJ: &str = "# a textured quad and a glass triangle
mtllib quad.mtl
o quad
v -1 -1 0
v 1 -1 0
v 1 1 0
v -1 1 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vn 0 0 1
usemtl wood
f 1/1/1 2/2/1 3/3/1 4/4/1
o glass
v 0 0 1
v 1 0 1
v 0 1 1
usemtl glass
f -3 -2 -1
";

const MTL: &str = "newmtl wood
Kd 0.8 0.6 0.4
Ks 0.1 0.1 0.1
Ns 50
map_Kd -s 1 1 1 tex.ppm

newmtl glass
Kd 1 1 1
Ks 0.2 0.2 0.2
Ns 200
d 0.25
Ni 1.5
illum 7
";

fn write_obj(dir: &Path, obj: &str, mtl: Option<&str>, texture: bool) -> PathBuf {
    let path = dir.join("quad.obj");
    std::fs::write(&path, obj).unwrap();
    if let Some(m) = mtl {
        std::fs::write(dir.join("quad.mtl"), m).unwrap();
    }
    if texture {
        // 1×2 PPM: top row red, bottom row blue.
        let mut ppm = b"P6\n1 2\n255\n".to_vec();
        ppm.extend_from_slice(&[255, 0, 0, 0, 0, 255]);
        std::fs::write(dir.join("tex.ppm"), ppm).unwrap();
    }
    path
}

#[test]
fn obj_with_mtl() {
    let dir = tmpdir("obj");
    let path = write_obj(&dir, OBJ, Some(MTL), true);
    let s = scene::load(path.to_str().unwrap()).unwrap();
    let tris = &s.groups[0].triangles;
    assert_eq!(tris.len(), 3);
    assert_eq!(
        tris[0].p,
        [
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0)
        ]
    );
    assert_eq!(tris[0].n, Some([Vec3::Z; 3]));
    // OBJ's v points up the image, as in this renderer: used as written.
    assert_eq!(
        tris[0].uv,
        Some([
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(1.0, 1.0)
        ])
    );
    assert_eq!(
        tris[2].p,
        [
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(0.0, 1.0, 1.0)
        ]
    );
    assert_eq!(tris[2].n, None);

    let wood = &s.materials[tris[0].material as usize];
    assert!(close(wood.diffuse, Vec3::new(0.8, 0.6, 0.4)));
    assert!(close(wood.specular, Vec3::splat(0.1)));
    assert_eq!(wood.shininess, 50.0);
    assert_eq!(wood.transmission, 0.0);
    let t = &s.textures[wood.texture.unwrap() as usize];
    assert_eq!((t.width, t.height, t.name.as_str()), (1, 2, "tex.ppm"));
    // The bottom of the quad (OBJ v near 0) shows the bottom row of the image (blue).
    assert!(close(t.sample(Vec2::new(0.5, 0.25)), Vec3::Z));

    let glass = &s.materials[tris[2].material as usize];
    assert!((glass.transmission - 0.75).abs() < 1e-6);
    assert!(close(glass.diffuse, Vec3::splat(0.25)));
    assert_eq!(glass.ior, 1.5);
    assert_eq!(glass.shininess, 200.0);
    assert!(close(glass.specular, Vec3::splat(0.2)));
    assert_eq!(s.lights.len(), 1);
}

#[test]
fn obj_missing_mtl_and_texture() {
    // A missing library is a warning: default materials.
    let dir = tmpdir("obj-nomtl");
    let path = write_obj(&dir, OBJ, None, false);
    let s = scene::load(path.to_str().unwrap()).unwrap();
    assert_eq!(s.groups[0].triangles.len(), 3);
    assert_eq!(s.materials, vec![frameless::scene::Material::default()]);

    // A missing texture is an error naming it.
    let dir = tmpdir("obj-notex");
    let path = write_obj(&dir, OBJ, Some(MTL), false);
    let e = scene::load(path.to_str().unwrap()).unwrap_err();
    assert!(e.to_string().contains("tex.ppm"), "{e}");
}

#[test]
fn obj_errors_have_lines() {
    let dir = tmpdir("obj-bad");
    let path = write_obj(&dir, "v 0 0 0\nv 1 0 0\n\nf 1 2 3\n", None, false);
    match scene::load(path.to_str().unwrap()).unwrap_err() {
        SceneError::Parse {
            file,
            line,
            column,
            message,
        } => {
            assert!(file.ends_with("quad.obj"));
            assert_eq!((line, column), (4, 7), "{message}");
        }
        e => panic!("{e}"),
    }
    let path = write_obj(&dir, "v 0 0 0\nv 1 0 zero\n", None, false);
    let e = scene::load(path.to_str().unwrap()).unwrap_err();
    assert!(
        matches!(
            e,
            SceneError::Parse {
                line: 2,
                column: 7,
                ..
            }
        ),
        "{e}"
    );
    // An error tobj finds itself still gets its line.
    let path = write_obj(&dir, "v 0 0 0\nv 0 0 0\nv 0 0 0 0\n", None, false);
    let e = scene::load(path.to_str().unwrap()).unwrap_err();
    assert!(matches!(e, SceneError::Parse { line: 3, .. }), "{e}");
    // A malformed library is an error in that file.
    let path = write_obj(&dir, OBJ, Some("newmtl a\nKd 1 x 1\n"), false);
    let e = scene::load(path.to_str().unwrap()).unwrap_err();
    assert!(
        matches!(&e, SceneError::Parse { file, line: 2, .. } if file.ends_with("quad.mtl")),
        "{e}"
    );
    // Two color components (tobj itself would panic on it) is an error too; one is grey.
    let path = write_obj(&dir, OBJ, Some("newmtl wood\nKd 1 1\n"), false);
    let e = scene::load(path.to_str().unwrap()).unwrap_err();
    assert!(
        matches!(&e, SceneError::Parse { file, line: 2, column: 6, .. } if file.ends_with("quad.mtl")),
        "{e}"
    );
    let path = write_obj(&dir, OBJ, Some("newmtl wood\nKd 0.5\n"), false);
    let s = scene::load(path.to_str().unwrap()).unwrap();
    assert_eq!(
        s.materials[s.groups[0].triangles[0].material as usize].diffuse,
        Vec3::splat(0.5)
    );
}

/// A small valid .glb exercising most of the loader: animation, texture, camera, light.
fn rich_glb() -> Vec<u8> {
    let (json, bin) = rich_glb_parts();
    common::glb(&json, &bin)
}

/// The JSON and BIN chunks of [`rich_glb`].
fn rich_glb_parts() -> (Vec<u8>, Vec<u8>) {
    let mut bin = Bin::default();
    let mut doc = animated_scene(&mut bin);
    let png = png_rgb(1, 1, &[10, 20, 30]);
    let view = bin.view(&png);
    doc["materials"] = json!([{ "pbrMetallicRoughness": { "baseColorTexture": { "index": 0 } } }]);
    doc["textures"] = json!([{ "source": 0 }]);
    doc["images"] = json!([{ "bufferView": view, "mimeType": "image/png" }]);
    doc["cameras"] =
        json!([{ "type": "perspective", "perspective": { "yfov": 0.7, "znear": 0.1 } }]);
    doc["nodes"][2]["camera"] = json!(0);
    doc["extensions"] =
        json!({ "KHR_lights_punctual": { "lights": [{ "type": "spot", "intensity": 3.0 }] } });
    doc["nodes"][1]["extensions"] = json!({ "KHR_lights_punctual": { "light": 0 } });
    let doc = bin.attach(doc, None);
    (serde_json::to_vec(&doc).unwrap(), bin.data.clone())
}

#[test]
fn rich_glb_loads() {
    let dir = tmpdir("rich");
    let path = dir.join("rich.glb");
    std::fs::write(&path, rich_glb()).unwrap();
    let s = scene::load(path.to_str().unwrap()).unwrap();
    assert_eq!(s.textures.len(), 1);
    assert_eq!(s.lights.len(), 1);
    assert!(
        s.lights[0].track.is_some(),
        "a light on an animated node follows it"
    );
    assert!(s.camera.track.is_some());
    assert!((s.camera.base.fov_y_deg - 0.7f32.to_degrees()).abs() < 1e-4);
}

fn load_err(path: &Path) -> String {
    let e = scene::load(path.to_str().unwrap()).unwrap_err();
    e.to_string()
}

#[test]
fn malformed_gltf_errors_name_the_file() {
    let dir = tmpdir("bad");
    // Truncated .glb at several lengths.
    let glb = rich_glb();
    for cut in [3, 11, 12, 19, 40, glb.len() / 2, glb.len() - 1] {
        let path = dir.join("cut.glb");
        std::fs::write(&path, &glb[..cut]).unwrap();
        let e = load_err(&path);
        assert!(e.contains("cut.glb"), "cut {cut}: {e}");
    }

    // Missing external buffer.
    let mut bin = Bin::default();
    let prim = quad_primitive(&mut bin);
    let doc = json!({ "scenes": [{ "nodes": [0] }], "nodes": [{ "mesh": 0 }], "meshes": [{ "primitives": [prim] }], "materials": [{}] });
    let path = dir.join("nobuf.gltf");
    bin.write_external(&path, doc.clone(), "nobuf.bin");
    std::fs::remove_file(dir.join("nobuf.bin")).unwrap();
    let e = load_err(&path);
    assert!(e.contains("nobuf.bin") && e.contains("nobuf.gltf"), "{e}");

    // Out-of-range vertex index.
    let mut bin = Bin::default();
    let pos = bin.floats(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0], "VEC3");
    let idx = bin.indices(&[0, 1, 3]);
    let bad = |prim: Value| json!({ "scenes": [{ "nodes": [0] }], "nodes": [{ "mesh": 0 }], "meshes": [{ "primitives": [prim] }] });
    let path = dir.join("badindex.gltf");
    bin.write_embedded(
        &path,
        bad(json!({ "attributes": { "POSITION": pos }, "indices": idx })),
    );
    let e = load_err(&path);
    assert!(
        e.contains("badindex.gltf") && e.contains("out of range"),
        "{e}"
    );

    // Accessor, material and node indices that do not exist.
    for (name, prim) in [
        ("noacc", json!({ "attributes": { "POSITION": 99 } })),
        (
            "nomat",
            json!({ "attributes": { "POSITION": pos }, "material": 5 }),
        ),
        (
            "noidx",
            json!({ "attributes": { "POSITION": pos }, "indices": 42 }),
        ),
    ] {
        let path = dir.join(format!("{name}.gltf"));
        bin.write_embedded(&path, bad(prim));
        let e = load_err(&path);
        assert!(
            e.contains(&format!("{name}.gltf")) && e.contains("does not exist"),
            "{e}"
        );
    }

    // An accessor reaching past its buffer view.
    let mut bin = Bin::default();
    let pos = bin.floats(&[0.0; 9], "VEC3");
    bin.accessors[pos]["count"] = json!(4);
    let path = dir.join("overrun.gltf");
    bin.write_embedded(&path, bad(json!({ "attributes": { "POSITION": pos } })));
    assert!(load_err(&path).contains("do not fit"));

    // A node cycle.
    let mut bin = Bin::default();
    let path = dir.join("cycle.gltf");
    bin.write_embedded(&path, json!({ "scenes": [{ "nodes": [0] }], "nodes": [{ "children": [1] }, { "children": [0] }] }));
    assert!(load_err(&path).contains("reached twice"));

    // JSON syntax errors have a line and column.
    let path = dir.join("syntax.gltf");
    std::fs::write(
        &path,
        "{\n  \"asset\": { \"version\": \"2.0\" },\n  \"nodes\": [ { \"mesh\": } ]\n}\n",
    )
    .unwrap();
    match scene::load(path.to_str().unwrap()).unwrap_err() {
        SceneError::Parse { file, line, .. } => assert!(file.ends_with("syntax.gltf") && line == 3),
        e => panic!("{e}"),
    }

    // Unsupported required extension.
    let path = dir.join("draco.gltf");
    std::fs::write(
        &path,
        r#"{"asset":{"version":"2.0"},"extensionsRequired":["KHR_draco_mesh_compression"]}"#,
    )
    .unwrap();
    assert!(load_err(&path).contains("KHR_draco_mesh_compression"));
}

#[derive(Clone, Debug)]
enum Mutation {
    Truncate(usize),
    Flip(usize, u8),
    Insert(usize, Vec<u8>),
    Overwrite(usize, u32),
}

fn mutate(bytes: &mut Vec<u8>, muts: Vec<Mutation>) {
    for m in muts {
        let n = bytes.len().max(1);
        match m {
            Mutation::Truncate(i) => bytes.truncate(i % n),
            Mutation::Flip(i, x) => {
                if !bytes.is_empty() {
                    let i = i % bytes.len();
                    bytes[i] ^= x;
                }
            }
            Mutation::Insert(i, b) => {
                let i = i % (bytes.len() + 1);
                bytes.splice(i..i, b);
            }
            Mutation::Overwrite(i, v) => {
                if bytes.len() >= 4 {
                    let i = i % (bytes.len() - 3);
                    bytes[i..i + 4].copy_from_slice(&v.to_le_bytes());
                }
            }
        }
    }
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        any::<usize>().prop_map(Mutation::Truncate),
        (any::<usize>(), 1u8..=255).prop_map(|(i, m)| Mutation::Flip(i, m)),
        (any::<usize>(), proptest::collection::vec(any::<u8>(), 1..8))
            .prop_map(|(i, b)| Mutation::Insert(i, b)),
        (any::<usize>(), any::<u32>()).prop_map(|(i, v)| Mutation::Overwrite(i, v)),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 128, failure_persistence: None, ..ProptestConfig::default() })]

    /// Mutated binary glTF never panics the loader (it may load or fail). Mutations hit
    /// the whole file, or only its JSON or BIN chunk with the container rebuilt around
    /// them, so that they also reach the document and the accessors behind a valid
    /// container.
    #[test]
    fn mutated_glb_never_panics(target in 0..3u8, muts in proptest::collection::vec(mutation(), 1..4)) {
        static BASE: std::sync::OnceLock<(Vec<u8>, Vec<u8>)> = std::sync::OnceLock::new();
        let (json, bin) = BASE.get_or_init(rich_glb_parts).clone();
        let bytes = match target {
            0 => {
                let mut b = common::glb(&json, &bin);
                mutate(&mut b, muts);
                b
            }
            1 => {
                let mut j = json;
                mutate(&mut j, muts);
                common::glb(&j, &bin)
            }
            _ => {
                let mut b = bin;
                mutate(&mut b, muts);
                common::glb(&json, &b)
            }
        };
        let dir = tmpdir("fuzz");
        let path = dir.join("m.glb");
        std::fs::write(&path, &bytes).unwrap();
        let _ = loader::load(&path);
        let _ = std::fs::remove_dir_all(&dir);
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, failure_persistence: None, ..ProptestConfig::default() })]

    /// Mutated OBJ and MTL text never panics the loader either.
    #[test]
    fn mutated_obj_never_panics(
        in_mtl in any::<bool>(),
        muts in proptest::collection::vec(mutation(), 1..4),
    ) {
        let (mut obj, mut mtl) = (OBJ.as_bytes().to_vec(), MTL.as_bytes().to_vec());
        mutate(if in_mtl { &mut mtl } else { &mut obj }, muts);
        let dir = tmpdir("fuzz-obj");
        std::fs::write(dir.join("quad.obj"), &obj).unwrap();
        std::fs::write(dir.join("quad.mtl"), &mtl).unwrap();
        let mut ppm = b"P6\n1 2\n255\n".to_vec();
        ppm.extend_from_slice(&[255, 0, 0, 0, 0, 255]);
        std::fs::write(dir.join("tex.ppm"), ppm).unwrap();
        let _ = scene::obj::load(&dir.join("quad.obj"));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
