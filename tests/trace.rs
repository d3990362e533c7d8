//! Tracer behaviour on tiny hand-built scenes: hits, texture orientation, shadows,
//! moving instances (hit point and velocity), visibility, camera paths, determinism.

use std::sync::Arc;

use frameless::{
    render::still,
    scene::{
        animation::{KeyframeTrack, TcbKey, VectorSpline},
        Camera, CameraPath, CameraTrack, Group, Light, Material, Node, NodeKind, Scene, Texture,
        Triangle,
    },
    trace::{TraceOptions, Tracer},
};
use glam::{Mat4, Vec2, Vec3};

mod common;
use common::animate;

fn base_scene() -> Scene {
    Scene {
        name: "t".into(),
        materials: vec![Material::matte(Vec3::ONE)],
        lights: vec![Light {
            position: Vec3::new(0.0, 0.0, 10.0),
            color: Vec3::ONE,
            track: None,
            name: None,
        }],
        camera: CameraTrack {
            base: Camera {
                eye: Vec3::new(0.0, 0.0, 5.0),
                at: Vec3::ZERO,
                up: Vec3::Y,
                fov_y_deg: 45.0,
                hither: 1e-3,
            },
            track: None,
            resolution: None,
        },
        background: Vec3::new(0.0, 0.0, 1.0),
        ambient: Vec3::ONE,
        ..Default::default()
    }
}

fn quad(z: f32, half: f32, material: u32) -> Vec<Triangle> {
    let p = [
        Vec3::new(-half, -half, z),
        Vec3::new(half, -half, z),
        Vec3::new(half, half, z),
        Vec3::new(-half, half, z),
    ];
    let uv = [
        Vec2::new(0.0, 0.0),
        Vec2::new(1.0, 0.0),
        Vec2::new(1.0, 1.0),
        Vec2::new(0.0, 1.0),
    ];
    vec![
        Triangle {
            p: [p[0], p[1], p[2]],
            n: None,
            uv: Some([uv[0], uv[1], uv[2]]),
            material,
        },
        Triangle {
            p: [p[0], p[2], p[3]],
            n: None,
            uv: Some([uv[0], uv[2], uv[3]]),
            material,
        },
    ]
}

#[test]
fn primary_hit_depth_and_miss() {
    let mut s = base_scene();
    s.groups.push(Group {
        node: None,
        triangles: quad(0.0, 1.0, 0),
        ..Default::default()
    });
    let tr = Tracer::new(Arc::new(s), 64, 64, TraceOptions::default());
    let c = tr.trace(32.0, 32.0, 0.0);
    assert!(c.hit);
    assert!((c.depth - 5.0).abs() < 1e-4, "{}", c.depth);
    assert!(c.hit_point.length() < 1e-3);
    assert_eq!(c.velocity, Vec3::ZERO);
    // Lit head-on by a white light: diffuse 1 · 1 + ambient 0.1.
    assert!((c.color.x - 1.1).abs() < 1e-3, "{:?}", c.color);
    let corner = tr.trace(0.5, 0.5, 0.0);
    assert!(!corner.hit);
    assert_eq!(corner.color, Vec3::new(0.0, 0.0, 1.0));
}

#[test]
fn texture_appears_upright_with_v_up() {
    // 2x2 texture: row 0 = red, green; row 1 = blue, white; texel centers at uv ¼ and ¾.
    // The quad's uv (0,0) is at its
    // bottom-left corner (−x, −y), so the BOTTOM-left of the image must be red.
    let tex = Texture::from_fn("t", 2, 2, |x, y| match (x, y) {
        (0, 0) => Vec3::X,
        (1, 0) => Vec3::Y,
        (0, 1) => Vec3::Z,
        _ => Vec3::ONE,
    });
    let mut s = base_scene();
    s.textures.push(tex);
    s.materials = vec![Material {
        ambient: Vec3::ZERO,
        diffuse: Vec3::ONE,
        texture: Some(0),
        ..Material::matte(Vec3::ONE)
    }];
    s.groups.push(Group {
        node: None,
        triangles: quad(0.0, 1.0, 0),
        ..Default::default()
    });
    let tr = Tracer::new(Arc::new(s), 100, 100, TraceOptions::default());
    let state = tr.state_at(0.0);
    let frame = state.camera;
    let at = |p: Vec3| {
        let (x, y, _) = frame.project(p).unwrap();
        tr.sample(&state, x, y).color
    };
    let near = |a: Vec3, b: Vec3| (a - b).length() < 0.05;
    assert!(
        near(at(Vec3::new(-0.5, 0.5, 0.0)), Vec3::X),
        "{:?}",
        at(Vec3::new(-0.5, 0.5, 0.0))
    );
    assert!(near(at(Vec3::new(0.5, 0.5, 0.0)), Vec3::Y));
    assert!(near(at(Vec3::new(-0.5, -0.5, 0.0)), Vec3::Z));
    assert!(near(at(Vec3::new(0.5, -0.5, 0.0)), Vec3::ONE));
}

#[test]
fn hard_shadow_behind_blocker() {
    let mut s = base_scene();
    let mut tris = quad(0.0, 3.0, 0);
    tris.extend(quad(2.0, 0.3, 0)); // a small blocker between light and the quad's center
    s.groups.push(Group {
        node: None,
        triangles: tris,
        ..Default::default()
    });
    // Camera off to the side so it sees the shadowed center past the blocker.
    s.camera.base.eye = Vec3::new(3.0, 0.0, 5.0);
    let tr = Tracer::new(Arc::new(s), 64, 64, TraceOptions::default());
    let state = tr.state_at(0.0);
    let (x, y, _) = state.camera.project(Vec3::new(0.0, 0.0, 0.0)).unwrap();
    let shadowed = tr.sample(&state, x, y);
    let (x, y, _) = state.camera.project(Vec3::new(-2.0, 0.0, 0.0)).unwrap();
    let lit = tr.sample(&state, x, y);
    assert!(
        (shadowed.hit_point.z).abs() < 1e-3,
        "must see the back quad, got {:?}",
        shadowed.hit_point
    );
    assert!(
        (shadowed.color.x - 0.1).abs() < 1e-4,
        "only ambient in shadow: {:?}",
        shadowed.color
    );
    assert!(lit.color.x > 0.5);
}

fn linear_track(speed: Vec3) -> KeyframeTrack {
    // Collinear evenly spaced keys make the Kochanek–Bartels spline exactly linear.
    let keys = (-1..=4)
        .map(|i| TcbKey {
            time: i as f32,
            value: speed * i as f32,
            tension: 0.0,
            continuity: 0.0,
            bias: 0.0,
        })
        .collect();
    KeyframeTrack {
        name: "mover".into(),
        translation: VectorSpline::new(keys),
        ..Default::default()
    }
}

#[test]
fn moving_instance_has_velocity_and_moves() {
    let mut s = base_scene();
    s.tracks.push(linear_track(Vec3::new(0.5, 0.0, 0.0)));
    // The instance sits under a static parent that scales by 2: world speed doubles.
    s.nodes.push(Node {
        parent: None,
        kind: NodeKind::Static(Mat4::from_scale(Vec3::splat(2.0))),
    });
    s.nodes.push(Node {
        parent: Some(0),
        kind: NodeKind::Animated {
            name: "mover".into(),
            track: Some(0),
        },
    });
    s.groups.push(Group {
        node: Some(1),
        triangles: quad(0.0, 0.25, 0),
        ..Default::default()
    });
    let tr = Tracer::new(Arc::new(s), 64, 64, TraceOptions::default());
    // At t = 1 the quad is centered at x = 2·0.5 = 1.
    let st = tr.state_at(1.0);
    let (x, y, _) = st.camera.project(Vec3::new(1.0, 0.0, 0.0)).unwrap();
    let hit = tr.sample(&st, x, y);
    assert!(hit.hit);
    assert!(
        (hit.velocity - Vec3::new(1.0, 0.0, 0.0)).length() < 1e-3,
        "{:?}",
        hit.velocity
    );
    // At t = 2 it has moved to x = 2; the old place shows background.
    let st2 = tr.state_at(2.0);
    assert!(!tr.sample(&st2, x, y).hit);
    let (x2, y2, _) = st2.camera.project(Vec3::new(2.0, 0.0, 0.0)).unwrap();
    assert!(tr.sample(&st2, x2, y2).hit);
}

/// A static floor under a blocker that moves (`speed` ≠ 0) or stands still, seen from
/// the side: samples of the floor in its shadow are dynamic only when it moves.
#[test]
fn samples_shadowed_by_a_moving_blocker_are_dynamic() {
    for (speed, moving) in [(Vec3::new(0.1, 0.0, 0.0), true), (Vec3::ZERO, false)] {
        let mut s = base_scene();
        s.ambient = Vec3::splat(0.1);
        s.groups.push(Group {
            node: None,
            triangles: quad(0.0, 3.0, 0),
            ..Default::default()
        });
        let node = animate(&mut s, linear_track(speed));
        s.groups.push(Group {
            node: Some(node),
            triangles: quad(2.0, 0.3, 0),
            ..Default::default()
        });
        s.camera.base.eye = Vec3::new(3.0, 0.0, 5.0);
        let tr = Tracer::new(Arc::new(s), 64, 64, TraceOptions::default());
        let state = tr.state_at(0.0);
        let at = |p: Vec3| {
            let (x, y, _) = state.camera.project(p).unwrap();
            tr.sample(&state, x, y)
        };
        let (shadowed, lit) = (at(Vec3::ZERO), at(Vec3::new(-2.0, 1.5, 0.0)));
        assert!(shadowed.hit_point.z.abs() < 1e-3 && shadowed.color.x < 0.2);
        assert_eq!(shadowed.velocity, Vec3::ZERO);
        assert_eq!(shadowed.dynamic, moving, "speed {speed:?}");
        assert!(lit.hit_point.z.abs() < 1e-3 && lit.color.x > 0.5);
        assert!(!lit.dynamic);
        // The blocker itself is dynamic when it moves (its velocity says so too).
        let blocker = at(Vec3::new(0.0, 0.0, 2.0));
        assert!(blocker.hit_point.z > 1.9);
        assert_eq!(blocker.dynamic, moving);
    }
}

#[test]
fn visibility_track_hides_subtree() {
    let mut s = base_scene();
    let mut track = linear_track(Vec3::ZERO);
    track.visibility = vec![(1.0, false), (2.0, true)];
    s.tracks.push(track);
    s.nodes.push(Node {
        parent: None,
        kind: NodeKind::Animated {
            name: "mover".into(),
            track: Some(0),
        },
    });
    s.groups.push(Group {
        node: Some(0),
        triangles: quad(0.0, 1.0, 0),
        ..Default::default()
    });
    let tr = Tracer::new(Arc::new(s), 32, 32, TraceOptions::default());
    assert!(tr.trace(16.0, 16.0, 0.5).hit);
    assert!(!tr.trace(16.0, 16.0, 1.5).hit);
    assert!(tr.trace(16.0, 16.0, 2.5).hit);
}

#[test]
fn camera_path_overrides_scene_camera() {
    let mut s = base_scene();
    s.groups.push(Group {
        node: None,
        triangles: quad(0.0, 1.0, 0),
        ..Default::default()
    });
    let text = "t,eye_x,eye_y,eye_z,at_x,at_y,at_z,up_x,up_y,up_z,fov_y_deg\n\
                0,0,0,5,0,0,0,0,1,0,45\n\
                1,10,0,5,10,0,0,0,1,0,45\n";
    let path = CameraPath::parse("p.csv", text).unwrap();
    let tr = Tracer::new(Arc::new(s), 32, 32, TraceOptions::default()).with_camera_path(Some(path));
    assert!(tr.trace(16.0, 16.0, 0.0).hit);
    assert!(
        !tr.trace(16.0, 16.0, 1.0).hit,
        "camera moved away along the path"
    );
    assert!((tr.state_at(0.5).camera.eye.x - 5.0).abs() < 1e-5);
}

#[test]
fn a_camera_extrapolated_ahead_continues_its_past_motion_only() {
    // Moving along x at 10 units a second until t = 1, then held: ahead of a time on
    // the line, the extrapolated camera is where the path goes; ahead of the stop it
    // overshoots (it knows only the past), and a held camera stays held.
    let text = "t,eye_x,eye_y,eye_z,at_x,at_y,at_z,up_x,up_y,up_z,fov_y_deg\n\
                0,0,0,5,0,0,0,0,1,0,45\n\
                1,10,0,5,10,0,0,0,1,0,45\n\
                3,10,0,5,10,0,0,0,1,0,45\n";
    let path = CameraPath::parse("p.csv", text).unwrap();
    let tr = Tracer::new(Arc::new(base_scene()), 32, 32, TraceOptions::default())
        .with_camera_path(Some(path));
    let eye = |t: f64, ahead: f64| tr.state_at_ahead(t, ahead).camera.eye;
    assert_eq!(eye(0.5, 0.0), tr.state_at(0.5).camera.eye);
    assert!((eye(0.5, 0.02).x - 5.2).abs() < 1e-4, "{}", eye(0.5, 0.02));
    assert!((eye(1.0, 0.02).x - 10.2).abs() < 1e-4, "{}", eye(1.0, 0.02));
    assert!((eye(2.0, 0.02).x - 10.0).abs() < 1e-5, "{}", eye(2.0, 0.02));
    // The point looked at moves with the eye: the view still faces -z.
    let forward = tr.state_at_ahead(0.5, 0.02).camera.forward;
    assert!((forward - Vec3::NEG_Z).length() < 1e-5, "{forward}");
    // A live camera (the viewer's) has no past poses here: never extrapolated.
    let held = Camera {
        eye: Vec3::new(1.0, 2.0, 5.0),
        ..base_scene().camera.base
    };
    tr.set_live_camera(Some(held));
    assert_eq!(eye(0.5, 0.02), held.eye);
}

#[test]
fn still_is_independent_of_thread_count() {
    let scene = Arc::new(frameless::scene::builtin::load("toycar").unwrap());
    let tr = Tracer::new(scene, 48, 32, TraceOptions::default());
    let render = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| still::render(&tr, 3.0, 4, 7, &|_| {}))
    };
    assert_eq!(render(1), render(3));
}
