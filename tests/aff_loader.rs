//! The BART AFF loader: every directive on small inline files, error reporting, and the
//! published BART scenes when `FRAMELESS_BART_DIR` points at them.

use std::fs;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use frameless::scene::aff::{load, parse_str};
use frameless::scene::{NodeKind, Scene, SceneError};
use glam::{Mat4, Quat, Vec2, Vec3};

/// A fresh, empty directory, removed again when dropped.
struct TempDir(PathBuf);

impl std::ops::Deref for TempDir {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = fs::remove_dir_all(&self.0);
    }
}

fn temp_dir(tag: &str) -> TempDir {
    static N: AtomicUsize = AtomicUsize::new(0);
    let n = N.fetch_add(1, Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("frameless-aff-{}-{tag}-{n}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).unwrap();
    TempDir(dir)
}

fn write(dir: &Path, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
    let path = dir.join(name);
    if let Some(parent) = path.parent() {
        fs::create_dir_all(parent).unwrap();
    }
    fs::write(&path, bytes).unwrap();
    path
}

/// A w×h P6 texture of one color.
fn ppm(w: u32, h: u32, rgb: [u8; 3]) -> Vec<u8> {
    let mut v = format!("P6\n{w} {h}\n255\n").into_bytes();
    for _ in 0..w * h {
        v.extend_from_slice(&rgb);
    }
    v
}

fn parse_in(dir: &Path, text: &str) -> Scene {
    match parse_str("main.aff", text.as_bytes(), dir) {
        Ok(s) => s,
        Err(e) => panic!("unexpected error: {e}"),
    }
}

fn parse(text: &str) -> Scene {
    parse_in(&temp_dir("ok"), text)
}

fn parse_err_in(dir: &Path, text: &[u8]) -> SceneError {
    match parse_str("main.aff", text, dir) {
        Ok(_) => panic!("expected an error"),
        Err(e) => e,
    }
}

fn parse_err(text: &str) -> SceneError {
    parse_err_in(&temp_dir("err"), text.as_bytes())
}

/// Asserts a parse error at `file:line:column` whose message contains `needle`.
fn assert_parse_error(e: &SceneError, file: &str, line: usize, column: usize, needle: &str) {
    match e {
        SceneError::Parse {
            file: f,
            line: l,
            column: c,
            message,
        } => {
            assert!(f.ends_with(file), "file {f}, expected {file} ({e})");
            assert_eq!((*l, *c), (line, column), "location of: {e}");
            assert!(
                message.contains(needle),
                "message '{message}' lacks '{needle}'"
            );
        }
        other => panic!("expected a parse error, got {other:?}"),
    }
}

fn close(a: Vec3, b: Vec3) -> bool {
    (a - b).length() < 1e-4
}

fn mat_close(a: Mat4, b: Mat4) -> bool {
    a.abs_diff_eq(b, 1e-4)
}

fn all_triangles(s: &Scene) -> usize {
    s.groups.iter().map(|g| g.triangles.len()).sum()
}

fn node_named(s: &Scene, name: &str) -> u32 {
    let i = s
        .nodes
        .iter()
        .position(|n| matches!(&n.kind, NodeKind::Animated { name: m, .. } if m == name))
        .unwrap_or_else(|| panic!("no node {name}"));
    i as u32
}

/// Four collinear keys: a linear Catmull–Rom segment, P(t) = t·step on t ∈ [1, 2].
fn linear_keys(step: [f32; 3]) -> String {
    (0..4)
        .map(|i| {
            let t = i as f32;
            format!(
                "{t} {} {} {} 0 0 0\n",
                t * step[0],
                t * step[1],
                t * step[2]
            )
        })
        .collect()
}

#[test]
fn defaults_without_directives() {
    let s = parse("# nothing but a comment\n");
    assert_eq!(s.name, "main");
    assert_eq!(s.ambient, Vec3::ONE);
    assert_eq!(s.background, Vec3::ZERO);
    assert!(s.animation.is_none());
    assert!(s.camera.track.is_none());
    assert!(s.camera.resolution.is_none());
    assert!(s.groups.is_empty() && s.lights.is_empty() && s.materials.is_empty());
}

#[test]
fn viewpoint_background_ambient() {
    let s = parse(
        "b 0.5 0.25 1.0\n\
         v\nfrom 1 2 3\nat 0 0 0\nup 0 1 0\nangle 40\nhither 0.01\nresolution 320 240\n\
         am 2.5 2.5 2.5\n",
    );
    assert_eq!(s.background, Vec3::new(0.5, 0.25, 1.0));
    assert_eq!(s.ambient, Vec3::splat(2.5));
    let c = s.camera.base;
    assert_eq!(
        (c.eye, c.at, c.up),
        (Vec3::new(1.0, 2.0, 3.0), Vec3::ZERO, Vec3::Y)
    );
    assert_eq!((c.fov_y_deg, c.hither), (40.0, 0.01));
    assert_eq!(s.camera.resolution, Some((320, 240)));
    assert_eq!(s.camera_at(3.0), c);

    // A tiny hither means 1.0 (reference behaviour); fields may come in any order.
    let s = parse("v resolution 8 6 hither 0.00001 angle 30 up 0 0 1 at 1 1 1 from 0 0 0");
    assert_eq!(s.camera.base.hither, 1.0);
    assert_eq!(s.camera.base.up, Vec3::Z);
    assert_eq!(s.camera.resolution, Some((8, 6)));

    let e = parse_err("v from 0 0 0 at 0 0 1 up 0 1 0 angle 40 hither 1\nb 0 0 0");
    assert_parse_error(&e, "main.aff", 2, 1, "viewpoint field");
    let e = parse_err("v from 0 0 0 from 0 0 1");
    assert_parse_error(&e, "main.aff", 1, 14, "twice");
    let e = parse_err("v from 0 0 0 at 0 0 1 up 0 1 0 angle 40 hither 1 resolution 0 10");
    assert_parse_error(&e, "main.aff", 1, 61, "width");
}

#[test]
fn lights_with_and_without_color() {
    let s = parse(
        "l 1 2 3\n\
         l 4 5 6 0.5 0.25 0.125\n\
         l 7 8 9\n\
         s 0 0 0 1\n\
         xs 1 1 1 0 1 0 0 10 0 0 { l 0 0 0 }\n\
         l -1 -2 -3",
    );
    let l: Vec<_> = s.lights.iter().map(|l| (l.position, l.color)).collect();
    assert_eq!(l[0], (Vec3::new(1.0, 2.0, 3.0), Vec3::ONE));
    assert_eq!(
        l[1],
        (Vec3::new(4.0, 5.0, 6.0), Vec3::new(0.5, 0.25, 0.125))
    );
    assert_eq!(l[2], (Vec3::new(7.0, 8.0, 9.0), Vec3::ONE));
    assert_eq!(l[3], (Vec3::new(10.0, 0.0, 0.0), Vec3::ONE));
    assert_eq!(l[4], (Vec3::new(-1.0, -2.0, -3.0), Vec3::ONE));
    assert_eq!(s.lights.len(), 5);
    assert!(s
        .lights
        .iter()
        .all(|l| l.track.is_none() && l.name.is_none()));
    assert_eq!(s.groups[0].spheres.len(), 1);
    // A partial color is an error, not a silently shifted stream.
    let e = parse_err("l 1 2 3 0.5 0.5\ns 0 0 0 1");
    assert_parse_error(&e, "main.aff", 2, 1, "light color");
}

#[test]
fn animated_light_follows_its_track() {
    let s = parse(&format!(
        "la lamp 9 9 9 0.5 0.5 0.5\nla other 1 1 1\nk lamp {{ transl 4\n{} }}",
        linear_keys([1.0, 0.0, 2.0])
    ));
    assert_eq!(s.lights.len(), 2);
    assert_eq!(s.lights[0].name.as_deref(), Some("lamp"));
    assert_eq!(s.lights[0].track, Some(0));
    assert_eq!(s.lights[1].track, None);
    assert_eq!(s.lights[1].color, Vec3::ONE);
    let at = s.lights_at(1.5);
    assert!(close(at[0].0, Vec3::new(1.5, 0.0, 3.0)), "{:?}", at[0]);
    assert_eq!(at[0].1, Vec3::splat(0.5));
    assert_eq!(at[1].0, Vec3::ONE);
}

#[test]
fn materials_nff_extended_default_and_persistence() {
    let dir = temp_dir("mat");
    write(
        &dir,
        "inc.aff",
        "fm 0.1 0.2 0.3  0.4 0.5 0.6  0.7 0.8 0.9  20 0.25 1.5\n",
    );
    let s = parse_in(
        &dir,
        "s 0 0 0 1\n\
         f 1 0.5 0.25  0.8 0.3 12 0.1 1.33\n\
         s 1 0 0 1\n\
         xs 1 1 1 0 1 0 0 0 0 0 { i 0 inc.aff }\n\
         s 2 0 0 1\n\
         s 3 0 0 1\n",
    );
    let m: Vec<_> = s.groups[0].spheres.iter().map(|sp| sp.material).collect();
    assert_eq!(
        s.materials[m[0] as usize],
        frameless::scene::Material::default()
    );
    let nff = &s.materials[m[1] as usize];
    let color = Vec3::new(1.0, 0.5, 0.25);
    assert!(close(nff.diffuse, color * 0.8));
    assert!(close(nff.ambient, color * 0.08));
    assert_eq!(nff.specular, Vec3::splat(0.3));
    assert_eq!(
        (nff.shininess, nff.transmission, nff.ior),
        (12.0, 0.1, 1.33)
    );
    // The material set inside the include (inside a block) stays current afterwards.
    let fm = &s.materials[m[2] as usize];
    assert_eq!(fm.ambient, Vec3::new(0.1, 0.2, 0.3));
    assert_eq!(fm.diffuse, Vec3::new(0.4, 0.5, 0.6));
    assert_eq!(fm.specular, Vec3::new(0.7, 0.8, 0.9));
    assert_eq!((fm.shininess, fm.transmission, fm.ior), (20.0, 0.25, 1.5));
    assert_eq!(fm.texture, None);
    // Identical materials are shared.
    assert_eq!(m[2], m[3]);
    assert_eq!(s.materials.len(), 3);
}

#[test]
fn spheres_and_cones_baked_through_static_transforms() {
    let s = parse(
        "s 1 2 3 0.5\n\
         c 0 0 0 1  0 2 0 -0.5\n\
         xs 2 3 1 0 0 1 90 10 0 0 {\n\
           s 1 0 0 1\n\
           c 0 0 0 1  0 1 0 0.5\n\
         }\n",
    );
    assert_eq!(s.groups.len(), 1);
    let g = &s.groups[0];
    assert_eq!(g.node, None);
    assert_eq!(
        (g.spheres[0].center, g.spheres[0].radius),
        (Vec3::new(1.0, 2.0, 3.0), 0.5)
    );
    assert_eq!(g.cones[0].base, Vec3::ZERO);
    assert_eq!(g.cones[0].apex, Vec3::new(0.0, 2.0, 0.0));
    assert_eq!(
        (g.cones[0].base_radius, g.cones[0].apex_radius),
        (1.0, -0.5)
    );
    // Scale (2,3,1), then 90° about Z ((x,y) → (−y,x)), then +10 x.
    assert!(close(g.spheres[1].center, Vec3::new(10.0, 2.0, 0.0)));
    assert!((g.spheres[1].radius - 3.0).abs() < 1e-5);
    assert!(close(g.cones[1].base, Vec3::new(10.0, 0.0, 0.0)));
    assert!(close(g.cones[1].apex, Vec3::new(7.0, 0.0, 0.0)));
    assert!((g.cones[1].base_radius - 3.0).abs() < 1e-5);
    assert!((g.cones[1].apex_radius - 1.5).abs() < 1e-5);
}

#[test]
fn polygons_become_fans() {
    let s = parse(
        "p 4\n0 0 0\n1 0 0\n1 1 0\n0 1 0\np 5 0 0 0 1 0 0 2 1 0 1 2 0 0 1 0\np 2 0 0 0 1 1 1",
    );
    let t = &s.groups[0].triangles;
    assert_eq!(t.len(), 2 + 3);
    assert_eq!(t[0].p, [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0)]);
    assert_eq!(t[1].p, [Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0), Vec3::Y]);
    assert!(t.iter().all(|t| t.n.is_none() && t.uv.is_none()));
    assert_eq!(t[4].p[2], Vec3::Y);
}

#[test]
fn polygon_patches_keep_normals() {
    let s = parse("pp 3\n0 0 0 0 0 2\n1 0 0 0 0 1\n0 1 0 0 1 1\n");
    let t = &s.groups[0].triangles[0];
    assert_eq!(t.p, [Vec3::ZERO, Vec3::X, Vec3::Y]);
    let n = t.n.unwrap();
    assert!(close(n[0], Vec3::Z) && close(n[1], Vec3::Z));
    assert!(close(n[2], Vec3::new(0.0, 1.0, 1.0).normalize()));
}

#[test]
fn textured_triangles_share_textures_and_make_material_variants() {
    let dir = temp_dir("tex");
    write(&dir, "red.ppm", ppm(2, 2, [255, 0, 0]));
    write(&dir, "blue.ppm", ppm(1, 1, [0, 0, 255]));
    let s = parse_in(
        &dir,
        "fm 0.1 0.1 0.1 0.5 0.5 0.5 0 0 0 10 0 1\n\
         tt red.ppm\n0 0 0 0 0\n1 0 0 1 0\n0 1 0 0 1\n\
         ttp red.ppm\n0 0 1 0 0 1 0.5 0.5\n1 0 1 0 0 1 1.5 0.5\n0 1 1 0 0 1 0.5 2\n\
         tt blue.ppm 0 0 0 0 0 1 0 0 1 0 0 1 0 0 1\n\
         s 0 0 0 1\n",
    );
    assert_eq!(s.textures.len(), 2);
    assert_eq!(s.textures[0].name, "red.ppm");
    assert_eq!(s.textures[0].texels[0], Vec3::X);
    let t = &s.groups[0].triangles;
    assert_eq!(t[0].uv, Some([Vec2::ZERO, Vec2::X, Vec2::Y]));
    assert!(t[0].n.is_none());
    assert_eq!(t[1].p[0], Vec3::Z);
    assert_eq!(t[1].n, Some([Vec3::Z; 3]));
    assert_eq!(t[1].uv.unwrap()[2], Vec2::new(0.5, 2.0));
    assert_eq!(t[0].material, t[1].material);
    let red = &s.materials[t[0].material as usize];
    let blue = &s.materials[t[2].material as usize];
    let plain = &s.materials[s.groups[0].spheres[0].material as usize];
    assert_eq!(
        (red.texture, blue.texture, plain.texture),
        (Some(0), Some(1), None)
    );
    assert_eq!(red.diffuse, plain.diffuse);
    assert_eq!(s.materials.len(), 3);
}

#[test]
fn animated_triangles() {
    let text = "tpa 2\n\
         0  0 0 0  0 0 1   1 0 0  0 0 1   0 1 0  0 0 1\n\
         2  0 0 2  0 1 0   1 0 2  0 1 0   0 1 2  0 0 0\n";
    let s = parse(text);
    assert_eq!(s.animated_triangles.len(), 1);
    let a = &s.animated_triangles[0];
    assert_eq!(a.times, vec![0.0, 2.0]);
    assert_eq!(a.node, None);
    assert_eq!(
        s.materials[a.material as usize],
        frameless::scene::Material::default()
    );
    let (p, n, v) = a.eval(1.0);
    assert!(close(p[0], Vec3::new(0.0, 0.0, 1.0)));
    assert!(close(n[0], Vec3::new(0.0, 1.0, 1.0).normalize()));
    assert!(close(v[1], Vec3::new(0.0, 0.0, 1.0)));
    // A zero key normal is replaced by the key's face normal.
    assert_eq!(a.normals[1][2], Vec3::Z);
    // Under blocks, the node is the innermost one (static or animated).
    let s = parse(&format!("x spin {{ xs 1 1 1 0 1 0 0 0 0 0 {{ {text} }} }}"));
    assert_eq!(s.animated_triangles[0].node, Some(1));
    assert_eq!(s.nodes[1].parent, Some(0));
    let e = parse_err("tpa 0\n");
    assert_parse_error(&e, "main.aff", 1, 5, "at least one key");
}

#[test]
fn meshes_with_all_attribute_combinations() {
    let dir = temp_dir("mesh");
    write(&dir, "t.ppm", ppm(1, 1, [9, 9, 9]));
    let verts = "vertices 4  0 0 0  1 0 0  1 1 0  0 1 0\n";
    let s = parse_in(
        &dir,
        &format!(
            "m {verts} triangles 2  0 1 2  0 2 3\n\
             m {verts} normals 2 0 0 1 0 0 3 triangles 1  0 1 2  0 1 0\n\
             m {verts} texturecoords 3 t.ppm 0 0 1 0 1 1 triangles 1  2 3 0  2 1 0\n\
             m {verts} normals 1 0 0 1 texturecoords 2 t.ppm 0 0 1 1\n\
               triangles 2  0 1 2  0 0 0  0 1 1   0 2 3  0 0 0  1 0 1\n"
        ),
    );
    let t = &s.groups[0].triangles;
    assert_eq!(t.len(), 6);
    assert_eq!(t[1].p, [Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0), Vec3::Y]);
    assert!(t[0].n.is_none() && t[0].uv.is_none());
    assert_eq!(t[2].n, Some([Vec3::Z, Vec3::Z, Vec3::Z]));
    assert!(t[2].uv.is_none());
    assert_eq!(t[3].p[0], Vec3::new(1.0, 1.0, 0.0));
    assert_eq!(t[3].uv, Some([Vec2::new(1.0, 1.0), Vec2::X, Vec2::ZERO]));
    assert!(t[3].n.is_none());
    assert_eq!(t[5].uv, Some([Vec2::ONE, Vec2::ZERO, Vec2::ONE]));
    assert_eq!(t[5].n, Some([Vec3::Z; 3]));
    assert_eq!(s.textures.len(), 1);
    assert_eq!(s.materials[t[3].material as usize].texture, Some(0));
    assert_eq!(s.materials[t[0].material as usize].texture, None);

    let e = parse_err("m vertices 3 0 0 0 1 0 0 0 1 0\ntriangles 1\n0 1 3\n");
    assert_parse_error(&e, "main.aff", 3, 5, "vertex index 3 out of range");
    let e = parse_err("m vertices 3 0 0 0 1 0 0 0 1 0 normals 1 0 0 1 triangles 1 0 1 2 0 -1 0");
    assert_parse_error(&e, "main.aff", 1, 68, "normal index -1");
    let e = parse_err("m vertices 1 0 0 0 triangles 1 0 0\ns 0 0 0 1");
    assert_parse_error(&e, "main.aff", 2, 1, "expected vertex index");
    let e = parse_err("m triangles 0");
    assert_parse_error(&e, "main.aff", 1, 3, "'vertices'");
    // Sections come in a fixed order.
    let e = parse_err_in(
        &dir,
        b"m vertices 0 texturecoords 0 t.ppm normals 0 triangles 0",
    );
    assert_parse_error(&e, "main.aff", 1, 36, "expected 'triangles'");
}

#[test]
fn includes_resolve_relative_to_the_including_file() {
    let dir = temp_dir("inc");
    write(&dir, "sub/a.aff", "i 0 b.aff\ns 1 0 0 1\n");
    write(&dir, "sub/b.aff", "s 2 0 0 1\n");
    write(
        &dir,
        "sub/tex.aff",
        "tt t.ppm 0 0 0 0 0 1 0 0 1 0 0 1 0 0 1\n",
    );
    write(&dir, "sub/t.ppm", ppm(1, 1, [1, 2, 3]));
    // The same file included several times is not a cycle.
    let s = parse_in(
        &dir,
        "i 0 sub/a.aff\ni 0 sub/a.aff\ni 0 sub/tex.aff\ns 3 0 0 1",
    );
    let xs: Vec<f32> = s.groups[0].spheres.iter().map(|s| s.center.x).collect();
    assert_eq!(xs, vec![2.0, 1.0, 2.0, 1.0, 3.0]);
    assert_eq!(s.textures.len(), 1);
}

#[test]
fn detail_levels_skip_includes() {
    let dir = temp_dir("detail");
    write(&dir, "fine.aff", "s 5 0 0 1\n");
    // Skipped includes are not even opened.
    let s = parse_in(&dir, "i 1 fine.aff\ni 3 does_not_exist.aff\ns 0 0 0 1");
    assert_eq!(s.groups[0].spheres.len(), 1);
    let s = parse_in(
        &dir,
        "d 2\ni 1 fine.aff\ni 2 fine.aff\ni 3 missing.aff\ni -1 fine.aff",
    );
    assert_eq!(s.groups[0].spheres.len(), 3);
}

#[test]
fn include_errors() {
    let dir = temp_dir("cycle");
    write(&dir, "a.aff", "s 0 0 0 1\ni 0 b.aff\n");
    write(&dir, "b.aff", "\n  i 0 a.aff\n");
    let e = parse_err_in(&dir, b"i 0 a.aff");
    assert_parse_error(&e, "b.aff", 2, 7, "include cycle");
    let msg = e.to_string();
    assert!(
        msg.contains("a.aff -> ") && msg.contains("b.aff -> "),
        "{msg}"
    );
    // Directly including itself.
    let e = parse_err_in(&dir, b"s 0 0 0 1\ni 0 main.aff");
    assert_parse_error(&e, "main.aff", 2, 5, "include cycle: main.aff");

    let e = parse_err("\ni 0 nowhere.aff\n");
    assert_parse_error(&e, "main.aff", 2, 1, "nowhere.aff");
    // Errors inside an included file name that file.
    write(&dir, "bad.aff", "s 0 0 0 1\n s 0 0 zero 1\n");
    let e = parse_err_in(&dir, b"i 0 bad.aff");
    assert_parse_error(&e, "bad.aff", 2, 8, "sphere center");
}

#[test]
fn static_transform_is_baked_by_hand_computation() {
    // Scale 2, rotate 90° about +Y ((x,y,z) → (z,y,−x)), translate +1 x.
    let s = parse(
        "xs 2 2 2  0 1 0 90  1 0 0 {\n\
           pp 3  1 0 0 1 0 0  0 1 0 0 1 0  0 0 1 0 0 1\n\
         }\n",
    );
    assert_eq!(s.groups.len(), 1);
    assert_eq!(s.groups[0].node, None);
    let t = &s.groups[0].triangles[0];
    assert!(close(t.p[0], Vec3::new(1.0, 0.0, -2.0)), "{:?}", t.p);
    assert!(close(t.p[1], Vec3::new(1.0, 2.0, 0.0)));
    assert!(close(t.p[2], Vec3::new(3.0, 0.0, 0.0)));
    let n = t.n.unwrap();
    assert!(close(n[0], Vec3::new(0.0, 0.0, -1.0)));
    assert!(close(n[1], Vec3::Y));
    assert!(close(n[2], Vec3::X));
    // Static nodes are recorded anyway.
    assert!(matches!(s.nodes[0].kind, NodeKind::Static(_)));

    // Non-uniform scale: normals use the inverse transpose.
    let s = parse("xs 1 2 1 0 0 1 0 0 0 0 { pp 3 0 0 0 1 1 0  1 0 0 1 1 0  0 0 1 1 1 0 }");
    let n = s.groups[0].triangles[0].n.unwrap()[0];
    assert!(close(n, Vec3::new(1.0, 0.5, 0.0).normalize()), "{n:?}");
    // Nested static blocks compose parent × child.
    let s = parse("xs 1 1 1 0 0 1 90 5 0 0 { xs 2 2 2 0 1 0 0 1 0 0 { s 1 0 0 1 } }");
    let sp = s.groups[0].spheres[0];
    assert!(close(sp.center, Vec3::new(5.0, 3.0, 0.0)), "{sp:?}");
    assert!((sp.radius - 2.0).abs() < 1e-5);
}

#[test]
fn hierarchy_composes_animated_and_static_nodes() {
    let text = format!(
        "xs 1 1 1 0 1 0 0 0 0 -3 {{\n\
           x outer {{\n\
             xs 2 2 2 0 0 1 90 5 0 0 {{\n\
               x inner {{\n\
                 xs 3 3 3 0 1 0 0 0 1 0 {{ s 1 0 0 1 }}\n\
                 s 0 0 0 1\n\
               }}\n\
               s 0 0 0 2\n\
             }}\n\
           }}\n\
           s 0 0 0 3\n\
         }}\n\
         k outer {{ transl 4\n{} }}\n\
         k inner {{ rot 4\n0 0 1 0 30 0 0 0\n1 0 1 0 30 0 0 0\n2 0 1 0 30 0 0 0\n3 0 1 0 30 0 0 0 }}\n",
        linear_keys([1.0, 0.0, 0.0])
    );
    let s = parse(&text);
    let outer = node_named(&s, "outer");
    let inner = node_named(&s, "inner");
    let t = 1.5;
    let hand = Mat4::from_translation(Vec3::new(0.0, 0.0, -3.0))
        * Mat4::from_translation(Vec3::new(t, 0.0, 0.0))
        * Mat4::from_translation(Vec3::new(5.0, 0.0, 0.0))
        * Mat4::from_rotation_z(90f32.to_radians())
        * Mat4::from_scale(Vec3::splat(2.0))
        * Mat4::from_quat(Quat::from_axis_angle(Vec3::Y, 30f32.to_radians()));
    assert!(
        mat_close(s.node_world(inner, t), hand),
        "{:?}\n{hand:?}",
        s.node_world(inner, t)
    );
    assert!(s.node_is_animated(inner));

    // One group per innermost animated node; static matrices below it are baked.
    assert_eq!(s.groups.len(), 3);
    let group = |node: Option<u32>| s.groups.iter().find(|g| g.node == node).unwrap();
    let gi = group(Some(inner));
    assert_eq!(gi.spheres.len(), 2);
    assert!(close(gi.spheres[0].center, Vec3::new(3.0, 1.0, 0.0)));
    assert!((gi.spheres[0].radius - 3.0).abs() < 1e-5);
    assert_eq!(gi.spheres[1].center, Vec3::ZERO);
    let go = group(Some(outer));
    assert!(close(go.spheres[0].center, Vec3::new(5.0, 0.0, 0.0)));
    assert!((go.spheres[0].radius - 4.0).abs() < 1e-5);
    let gw = group(None);
    assert!(close(gw.spheres[0].center, Vec3::new(0.0, 0.0, -3.0)));
    // The world position of inner's local origin moves with outer's track.
    let p = |t: f32| s.node_world(inner, t).transform_point3(Vec3::ZERO);
    assert!(close(p(1.0) + Vec3::X * 0.5, p(1.5)));
}

#[test]
fn keyframes_all_channels_animation_and_camera() {
    let text = format!(
        "a -1 5 300 % frames\n\
         x thing {{ s 0 0 0 1 }}\n\
         k thing {{\n\
           visibility 2\n 1 0\n 2 1\n\
           scale 4\n{}\
           rot 4\n 0 0 0 1 0 0 0 0\n 1 0 0 1 0 0 0 0\n 2 0 0 1 90 0 0 0\n 3 0 0 1 180 0 0 0\n\
           transl 4\n{}\
         }}\n\
         v from 0 0 0 at 0 0 -1 up 0 1 0 angle 45 hither 0.1 resolution 4 4\n\
         k camera {{ transl 4\n{} rot 4\n0 0 1 0 90 0 0 0\n1 0 1 0 90 0 0 0\n2 0 1 0 90 0 0 0\n3 0 1 0 90 0 0 0\n}}\n",
        "0 1 1 1 0 0 0\n1 1 1 1 0 0 0\n2 2 2 2 0 0 0\n3 2 2 2 0 0 0\n",
        linear_keys([0.0, 2.0, 0.0]),
        linear_keys([1.0, 1.0, 1.0]),
    );
    let s = parse(&text);
    let a = s.animation.unwrap();
    assert_eq!((a.start, a.end, a.frames), (-1.0, 5.0, 300));
    assert_eq!(s.tracks.len(), 2);
    let thing = node_named(&s, "thing");
    let NodeKind::Animated {
        track: Some(tr), ..
    } = s.nodes[thing as usize].kind
    else {
        panic!("thing has no track");
    };
    let track = &s.tracks[tr as usize];
    assert!(track.translation.is_some() && track.rotation.is_some() && track.scale.is_some());
    assert_eq!(track.visibility, vec![(1.0, false), (2.0, true)]);
    assert!(
        s.node_visible(thing, 0.5) && !s.node_visible(thing, 1.5) && s.node_visible(thing, 2.5)
    );
    let want = Mat4::from_scale_rotation_translation(
        Vec3::splat(2.0),
        Quat::from_rotation_z(90f32.to_radians()),
        Vec3::new(0.0, 4.0, 0.0),
    );
    assert!(mat_close(s.node_world(thing, 2.0), want));
    assert_eq!(s.camera.track, Some(1));
    let cam = s.camera_at(1.5);
    assert!(close(cam.eye, Vec3::splat(1.5)));
    // Rotated 90° about +Y, the camera looks down −X.
    assert!(close(cam.at - cam.eye, Vec3::NEG_X), "{cam:?}");
    assert_eq!(cam.fov_y_deg, 45.0);
}

#[test]
fn last_keyframe_block_of_a_name_wins() {
    let text = format!(
        "x w {{ s 0 0 0 1 }}\nk w {{ transl 4\n{} }}\nx w {{ s 0 0 0 1 }}\nk w {{ transl 4\n{} }}\nk nobody {{ visibility 1 0 0 }}\nx untracked {{ }}",
        linear_keys([1.0, 0.0, 0.0]),
        linear_keys([0.0, 1.0, 0.0])
    );
    let s = parse(&text);
    let tracks: Vec<_> = s
        .nodes
        .iter()
        .map(|n| match &n.kind {
            NodeKind::Animated { track, .. } => *track,
            _ => panic!("no static node here"),
        })
        .collect();
    assert_eq!(tracks, vec![Some(1), Some(1), None]);
    assert_eq!(s.tracks.len(), 3);
    assert_eq!(s.tracks[2].name, "nobody");
    assert!(s.camera.track.is_none());
    // Two nodes, two groups, even with the same name.
    assert_eq!(s.groups.len(), 2);
}

#[test]
fn keyframe_errors() {
    let e = parse_err("k a {\n transl 3\n 0 0 0 0 0 0 0\n 1 0 0 0 0 0 0\n 2 0 0 0 0 0 0\n}");
    assert_parse_error(&e, "main.aff", 2, 9, "at least 4 keys");
    let e = parse_err("k a { visibility 0 }");
    assert_parse_error(&e, "main.aff", 1, 18, "at least 1 keys");
    let e = parse_err("k a { visibility 1 0 1 visibility 1 0 1 }");
    assert_parse_error(&e, "main.aff", 1, 24, "twice");
    let e = parse_err("k a { spin 4 }");
    assert_parse_error(&e, "main.aff", 1, 7, "'transl'");
    let e = parse_err("k a visibility 1 0 1 }");
    assert_parse_error(&e, "main.aff", 1, 5, "'{'");
    let e = parse_err("k a { rot 4\n0 0 1 0 0 0 0 0\n");
    assert_parse_error(&e, "main.aff", 3, 1, "end of file");
}

#[test]
fn syntax_errors_have_locations() {
    let e = parse_err("s 0 0 0 1\n  q 1 2 3\n");
    assert_parse_error(&e, "main.aff", 2, 3, "unknown directive 'q'");
    assert!(e.to_string().starts_with("main.aff:2:3: "), "{e}");
    let e = parse_err("s 0 0 0 1\n}\n");
    assert_parse_error(&e, "main.aff", 2, 1, "unbalanced");
    let e = parse_err("s 0 0 0 1\nxs 1 1 1 0 1 0 0 0 0 0 {\n  x a {\n }\n");
    assert_parse_error(&e, "main.aff", 2, 1, "never closed");
    let e = parse_err("xs 1 1 1 0 1 0 0 0 0 0\ns 0 0 0 1");
    assert_parse_error(&e, "main.aff", 2, 1, "'{'");
    let e = parse_err("{ }");
    assert_parse_error(&e, "main.aff", 1, 1, "unexpected '{'");
    let e = parse_err("s 0 0 nan 1");
    assert_parse_error(&e, "main.aff", 1, 7, "sphere center");
    let e = parse_err("s 0 0 1e39 1");
    assert_parse_error(&e, "main.aff", 1, 7, "not a finite");
    let e = parse_err("s 0 0 0");
    assert_parse_error(&e, "main.aff", 1, 8, "end of file");
    let e = parse_err("p 99999999999\n0 0 0");
    assert_parse_error(&e, "main.aff", 1, 3, "exceeds the limit");
    // A count larger than the data: fails at the end of the file, without a huge allocation.
    let e = parse_err("m vertices 40000000 0 0 0");
    assert_parse_error(&e, "main.aff", 1, 26, "end of file");
    let e = parse_err("tpa 50000000 0");
    assert!(e.to_string().contains("end of file"), "{e}");
    let e = parse_err("a 0 1 2.5");
    assert_parse_error(&e, "main.aff", 1, 7, "integer");
}

#[test]
fn colours_past_the_limit_have_locations() {
    // Finite f32 numbers past the colour limit (found by `aff_props`): the error names
    // the place, not only the scene.
    let e = parse_err(
        "s 0 0 0 1
b 49999999 0.5 1
",
    );
    assert_parse_error(&e, "main.aff", 2, 3, "background");
    let e = parse_err(
        "am 1 1e7 1
",
    );
    assert_parse_error(&e, "main.aff", 1, 4, "ambient light");
    let e = parse_err(
        "l 0 0 0 1 1 -2e6
",
    );
    assert_parse_error(&e, "main.aff", 1, 9, "light colour");
    let e = parse_err(
        "f 1 1 1 2e6 0 1 0 1
",
    );
    assert_parse_error(&e, "main.aff", 1, 1, "diffuse");
    let e = parse_err(
        "fm 0 0 0 1 1 1 0 0 0 1 5e6 1
",
    );
    assert_parse_error(&e, "main.aff", 1, 1, "transmission");
    let e = parse_err("v\nfrom 0 0 1e30\nat 0 0 0\nup 0 1 0\nangle 45\nhither 1\nresolution 8 8\n");
    assert_parse_error(&e, "main.aff", 1, 1, "camera eye");
}

#[test]
fn blocks_may_span_include_boundaries() {
    let dir = temp_dir("span");
    write(&dir, "open.aff", "x a {\n");
    write(&dir, "close.aff", "s 0 0 0 1 }\n");
    let s = parse_in(&dir, "i 0 open.aff\ns 1 0 0 1\ni 0 close.aff\ns 2 0 0 1");
    assert_eq!(s.groups.len(), 2);
    assert_eq!(s.groups[0].node, Some(0));
    assert_eq!(s.groups[0].spheres.len(), 2);
    let e = parse_err_in(&dir, b"i 0 open.aff\n");
    assert_parse_error(&e, "open.aff", 1, 1, "never closed");
}

#[test]
fn texture_errors_name_the_referencing_file_and_line() {
    let dir = temp_dir("badtex");
    write(&dir, "broken.ppm", b"P6\n4 4\n255\nshort");
    write(
        &dir,
        "inner.aff",
        "\n\ntt gone.ppm 0 0 0 0 0 1 0 0 1 0 0 1 0 0 1\n",
    );
    let e = parse_err_in(&dir, b"i 0 inner.aff");
    assert_parse_error(&e, "inner.aff", 3, 4, "gone.ppm");
    let msg = e.to_string();
    assert!(msg.contains("inner.aff:3:4"), "{msg}");
    let e = parse_err_in(
        &dir,
        b"s 0 0 0 1\nm vertices 0 texturecoords 0 broken.ppm triangles 0",
    );
    assert_parse_error(&e, "main.aff", 2, 30, "truncated");
}

#[test]
fn comments_and_latin1_bytes() {
    let text =
        b"# caf\xe9 cr\xe8me \xff\xfe\n% \xb0 degrees\nb 1 1 1 # trailing \xe9\ns 0 0 0 1% glued\n";
    let s = parse_str("latin.aff", text, &temp_dir("latin")).unwrap();
    assert_eq!(s.background, Vec3::ONE);
    assert_eq!(s.groups[0].spheres.len(), 1);
    // Outside a comment such bytes are an unknown directive, reported lossily.
    let e = parse_err_in(&temp_dir("latin"), b"\n\n \xe9t\xe9 1");
    assert_parse_error(&e, "main.aff", 3, 2, "unknown directive");
}

#[test]
fn load_reads_files_and_reports_missing_ones() {
    let dir = temp_dir("load");
    let path = write(&dir, "scene.aff", "i 0 part.aff\n");
    write(&dir, "part.aff", "s 0 0 0 1\n");
    let s = load(&path).unwrap();
    assert_eq!(s.name, "scene");
    assert_eq!(s.source.as_deref(), Some(path.as_path()));
    assert_eq!(s.groups[0].spheres.len(), 1);
    let e = load(&dir.join("nope.aff")).unwrap_err();
    assert!(matches!(e, SceneError::Io { .. }), "{e}");
    assert!(e.to_string().contains("nope.aff"));
}

// ---------------------------------------------------------------------------------------
// The published BART scenes.

/// The BART directory. These tests are ignored by default; run without the scenes they
/// fail, never pass unchecked.
fn bart_dir() -> PathBuf {
    let dir = std::env::var_os("FRAMELESS_BART_DIR")
        .expect("FRAMELESS_BART_DIR must name the BART scene folder (e.g. ../shared/scenes/bart)");
    let dir = PathBuf::from(dir);
    assert!(
        dir.join("kitchen/kitchen.aff").is_file() && dir.join("museum/museum3.aff").is_file(),
        "FRAMELESS_BART_DIR={} does not contain kitchen/kitchen.aff and museum/museum3.aff",
        dir.display()
    );
    dir
}

fn timed_load(path: &Path) -> Scene {
    let t0 = Instant::now();
    let s = load(path).unwrap_or_else(|e| panic!("{e}"));
    eprintln!(
        "loaded {} in {:.3} s",
        path.display(),
        t0.elapsed().as_secs_f64()
    );
    s
}

#[test]
#[ignore = "needs the BART scenes: set FRAMELESS_BART_DIR"]
fn bart_kitchen() {
    let dir = bart_dir();
    let s = timed_load(&dir.join("kitchen/kitchen.aff"));
    assert_eq!(all_triangles(&s), 110_561);
    assert_eq!(s.lights.len(), 6);
    assert_eq!(s.textures.len(), 8);
    assert_eq!(s.ambient, Vec3::splat(2.5));
    let a = s.animation.unwrap();
    assert_eq!((a.start, a.end, a.frames), (0.0, 20.0, 800));
    assert!(s.camera.track.is_some());
    assert_eq!(s.camera.resolution, Some((800, 600)));
    assert!(s.groups.iter().all(|g| g
        .triangles
        .iter()
        .all(|t| t.p.iter().all(|p| p.is_finite()))));

    let toycar = node_named(&s, "toycar");
    assert!(s
        .groups
        .iter()
        .any(|g| g.node == Some(toycar) && !g.is_empty()));
    let at = |t: f32| s.node_world(toycar, t).transform_point3(Vec3::ZERO);
    assert!(close(at(3.0), Vec3::new(4.45, 0.0, 2.75)), "{:?}", at(3.0));
    assert!((at(5.0) - at(10.0)).length() > 0.1);
    // Wheels sit under their own animated nodes, below toycar.
    let wheel = node_named(&s, "rotating_wheel_left");
    assert!(s
        .groups
        .iter()
        .any(|g| g.node == Some(wheel) && !g.triangles.is_empty()));
    let mut cur = s.nodes[wheel as usize].parent;
    let mut found = false;
    while let Some(p) = cur {
        found |= p == toycar;
        cur = s.nodes[p as usize].parent;
    }
    assert!(found, "rotating_wheel_left is not below toycar");
}

#[test]
#[ignore = "needs the BART scenes: set FRAMELESS_BART_DIR"]
fn bart_museums() {
    let dir = bart_dir();
    for (level, animated) in [(3, 64), (4, 256), (5, 1024)] {
        let s = timed_load(&dir.join(format!("museum/museum{level}.aff")));
        assert_eq!(s.animated_triangles.len(), animated, "museum{level}");
        let cones: usize = s.groups.iter().map(|g| g.cones.len()).sum();
        assert_eq!(cones, 8, "museum{level}");
        assert_eq!(all_triangles(&s), 10_000 + 274 + 10, "museum{level}");
        assert!(s.camera.track.is_some(), "museum{level}");
        assert_eq!(s.lights.len(), 2);
        assert_eq!(s.textures.len(), 5);
        let moved = s
            .animated_triangles
            .iter()
            .filter(|a| a.eval(0.0).0 != a.eval(2.0).0)
            .count();
        assert_eq!(moved, animated, "museum{level}");
    }
}
