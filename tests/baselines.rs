//! Point tracking, TAA and late warp on small hand-built cases.

use std::sync::Arc;

use frameless::{
    clock::Clock,
    evaluation::{self, EvalConfig, Silent},
    methods::{
        late_warp::LateWarp,
        point_tracking::PointTracking,
        taa::{Taa, TaaParams},
        Method, MethodContext, MethodKind,
    },
    scene::{
        animation::KeyframeTrack, Camera, CameraPath, CameraTrack, Group, Light, Material, Node,
        NodeKind, Scene,
    },
    trace::{TraceOptions, Tracer},
};
use glam::Vec3;

mod common;
use common::{flat, quad, two_spheres};

fn base(groups: Vec<Group>) -> Scene {
    Scene {
        name: "t".into(),
        materials: vec![
            Material::matte(Vec3::new(0.8, 0.7, 0.5)),
            Material::matte(Vec3::new(0.1, 0.3, 0.9)),
        ],
        groups,
        lights: vec![Light {
            position: Vec3::new(1.0, 2.0, 4.0),
            color: Vec3::ONE,
            track: None,
            name: None,
        }],
        camera: CameraTrack {
            base: Camera {
                eye: Vec3::new(0.0, 0.0, 1.0),
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

#[test]
fn point_tracking_histogram_on_a_one_pixel_pan() {
    // A wall at distance 1 with a 90° view: 32 pixels span 2 units, one pixel 1/16 unit.
    // The camera slides one pixel to the right per frame, so every cached point lands on
    // the pixel to the left of where it was: the right column receives none, every other
    // pixel exactly one.
    let (w, rate) = (32u32, 32.0 * 32.0 * 10.0); // 10 frames per second
    let step = 2.0 / w as f32;
    let text = format!(
        "t,eye_x,eye_y,eye_z,at_x,at_y,at_z,up_x,up_y,up_z,fov_y_deg\n0,0,0,1,0,0,0,0,1,0,90\n1,{s},0,1,{s},0,0,0,1,0,90\n",
        s = step * 10.0
    );
    let scene = base(vec![Group {
        node: None,
        triangles: quad(-5.0, 5.0, -5.0, 5.0, 0.0, 0),
        ..Default::default()
    }]);
    let tracer = Tracer::new(Arc::new(scene), w, w, TraceOptions::default())
        .with_camera_path(Some(CameraPath::parse("p.csv", &text).unwrap()));
    let ctx = MethodContext {
        tracer: Arc::new(tracer),
        clock: Clock {
            start: 0.0,
            rate,
            first_refresh: 0.0,
            refresh_hz: 60.0,
        },
        seed: 1,
        ideal_spp: 1,
        ideal_cache: None,
        gpu: None,
        rays: None,
    };
    let mut m = PointTracking::new(&ctx, true);
    m.display(0.25); // frames 0 and 1 complete (0.1 s each) and are tracked once
    let s = m.stats();
    assert_eq!(s.tracked_frames, 1);
    assert_eq!(s.histogram, [w as u64, (w * w - w) as u64, 0, 0, 0]);
    assert!(s.plain_trace_s > 0.0 && s.tracked_trace_s > 0.0);
}

/// Static scene with edges (sphere silhouettes) so antialiasing matters.
fn static_scene() -> Scene {
    two_spheres()
}

fn cfg(methods: &[MethodKind], rate: f64, duration: f64) -> EvalConfig {
    let mut c = EvalConfig::new("t");
    c.start = 0.0;
    c.duration = duration;
    c.display.size = frameless::settings::Size(48, 48);
    c.rates = vec![rate];
    c.methods = methods.to_vec();
    c.quality.seed = 2;
    c.reference.ideal_spp = 16;
    c.warmup = 0.0;
    c.display.refresh_hz = 60.0;
    c.quality.max_depth = 2;
    c.quality.texture_filter = frameless::trace::TextureFilter::None;
    c.strip_frames = vec![];
    c.flip_every = 1000;
    c
}

#[test]
fn taa_converges_toward_the_antialiased_ideal_on_a_static_scene() {
    // 48x48 display, 1,152 samples per frame at 69,120 samples/s: a 33x34 grid, upsampled.
    let out = evaluation::run(
        Arc::new(static_scene()),
        &cfg(&[MethodKind::Taa, MethodKind::Framed60Hz], 69_120.0, 1.0),
        &Silent,
    )
    .unwrap();
    let series = |m: MethodKind| -> Vec<f64> {
        out.frames
            .iter()
            .filter(|f| f.method == m)
            .map(|f| f.rms)
            .collect()
    };
    let (taa, framed) = (series(MethodKind::Taa), series(MethodKind::Framed60Hz));
    let tail = |v: &[f64]| v[v.len() - 10..].iter().sum::<f64>() / 10.0;
    // First shown frame (refresh 1) is one jittered frame; later ones accumulate.
    assert!(
        tail(&taa) < 0.85 * taa[1],
        "taa first {} vs end {}",
        taa[1],
        tail(&taa)
    );
    assert!(
        tail(&taa) < 0.8 * tail(&framed),
        "taa {} vs framed {}",
        tail(&taa),
        tail(&framed)
    );
}

#[test]
fn taa_rejects_history_at_a_disocclusion() {
    // A near blocker disappears at t = 0.5 (visibility track): the wall behind it is
    // disoccluded and history there must be rejected, not blended in as a ghost.
    let mut scene = static_scene();
    scene.tracks.push(KeyframeTrack {
        name: "b".into(),
        visibility: vec![(0.5, false)],
        ..Default::default()
    });
    scene.nodes.push(Node {
        parent: None,
        kind: NodeKind::Animated {
            name: "b".into(),
            track: Some(0),
        },
    });
    scene.groups.push(Group {
        node: Some(0),
        triangles: quad(-0.4, 0.4, -0.4, 0.4, 0.5, 1),
        ..Default::default()
    });
    let tracer = Arc::new(Tracer::new(
        Arc::new(scene),
        48,
        48,
        TraceOptions::default(),
    ));
    let ctx = MethodContext {
        tracer: tracer.clone(),
        clock: Clock {
            start: 0.0,
            rate: 69_120.0,
            first_refresh: 0.0,
            refresh_hz: 60.0,
        },
        seed: 1,
        ideal_spp: 1,
        ideal_cache: None,
        gpu: None,
        rays: None,
    };
    let mut m = Taa::new(&ctx, TaaParams::default()).unwrap();
    // Frame j starts at refresh j and is shown at refresh j + 1: frame 30, the first
    // without the blocker, is traced by the display call for refresh 31.
    let mut before = 0;
    for k in 0..=31 {
        m.display(k as f64 / 60.0);
        if k == 30 {
            before = m.rejections();
        }
    }
    let rejected = m.rejections() - before;
    // Every pixel deep inside the blocker's old footprint must reject: there no previous
    // sample nearby saw the wall. (Within a low-resolution cell or two of its edge,
    // previous samples of the wall legitimately vouch for the history.)
    let near = |x: i32, y: i32| {
        let (x, y) = (x.clamp(0, 47) as f32 + 0.5, y.clamp(0, 47) as f32 + 0.5);
        tracer.trace(x, y, 0.4).depth < tracer.trace(x, y, 0.6).depth - 0.1
    };
    let interior = (0..48)
        .flat_map(|y| (0..48).map(move |x| (x, y)))
        .filter(|&(x, y)| (-3..=3).all(|dy| (-3..=3).all(|dx| near(x + dx, y + dy))))
        .count() as u64;
    eprintln!("{rejected} rejected, {interior} px deep inside");
    assert!(
        interior > 48 * 48 / 20,
        "blocker interior only {interior} px"
    );
    assert!(
        rejected >= interior,
        "only {rejected} pixels rejected history, {interior} deep inside the disocclusion"
    );
    // Right away the center shows the wall, not a blend with the blocker.
    let shown = m.display(31.0 / 60.0).image.get(24, 24);
    let truth = tracer.trace(24.5, 24.5, 0.5).color;
    assert!(
        (shown - truth).length() < 0.1,
        "shown {shown:?} vs wall {truth:?}"
    );
}

/// `static_scene` with a flat white square on the wall (a feature to find) and a 40°
/// view, seen from a camera that yaws at 180°/s about its fixed eye between t = 0 and
/// 1/3 s (a pure rotation: about 4.6 pixels per refresh at 64 pixels across).
fn panned_scene() -> (Scene, CameraPath) {
    let mut scene = static_scene();
    // Ambient only: 0.3 · (1 / 0.3) = 1 whatever the lights.
    scene.materials.push(flat(1.0 / 0.3));
    scene.groups.push(Group {
        node: None,
        triangles: quad(0.3, 0.5, 0.1, 0.3, -0.99, 2),
        ..Default::default()
    });
    let mut text = String::from(frameless::scene::camera_path::HEADER);
    text.push('\n');
    for k in 0..=20 {
        let t = k as f32 / 60.0;
        let yaw = (-30.0 + 180.0 * t).to_radians();
        text.push_str(&format!(
            "{t},0,0,1.5,{},0,{},0,1,0,40\n",
            yaw.sin(),
            1.5 - yaw.cos()
        ));
    }
    (scene, CameraPath::parse("yaw.csv", &text).unwrap())
}

fn panned_cfg(methods: &[MethodKind], path: Option<CameraPath>) -> EvalConfig {
    // 1,024 samples per frame: a 32x32 grid, upscaled 2x.
    let mut c = cfg(methods, 61_440.0, 0.3);
    c.display.size = frameless::settings::Size(64, 64);
    c.camera_path = path;
    c
}

fn rms_series(out: &evaluation::EvalOutput, m: MethodKind) -> Vec<f64> {
    out.frames
        .iter()
        .filter(|f| f.method == m)
        .map(|f| f.rms)
        .collect()
}

#[test]
fn late_warp_shows_a_panned_scene_in_the_right_place_at_no_ray_cost() {
    let (scene, path) = panned_scene();
    let methods = [MethodKind::LateWarp, MethodKind::Framed60Hz];
    let out = evaluation::run(
        Arc::new(scene.clone()),
        &panned_cfg(&methods, Some(path.clone())),
        &Silent,
    )
    .unwrap();
    // Refresh 0 shows nothing yet; every later refresh shows a frame 1/60 s old.
    let mean = |v: Vec<f64>| v[1..].iter().sum::<f64>() / (v.len() - 1) as f64;
    let (warped, stale) = (
        mean(rms_series(&out, MethodKind::LateWarp)),
        mean(rms_series(&out, MethodKind::Framed60Hz)),
    );
    assert!(
        warped < 0.6 * stale,
        "late-warp RMS {warped} vs framed-60hz {stale}"
    );
    // The warp traces no rays.
    let samples = |m: MethodKind| {
        out.summary
            .results
            .iter()
            .find(|r| r.method == m)
            .unwrap()
            .samples
    };
    assert_eq!(
        samples(MethodKind::LateWarp),
        samples(MethodKind::Framed60Hz)
    );
    assert!(samples(MethodKind::LateWarp) > 0);

    // The white square's centroid lands where the camera at display time sees it.
    let tracer = Arc::new(
        Tracer::new(Arc::new(scene), 64, 64, TraceOptions::default()).with_camera_path(Some(path)),
    );
    let ctx = MethodContext {
        tracer: tracer.clone(),
        clock: Clock {
            start: 0.0,
            rate: 61_440.0,
            first_refresh: 0.0,
            refresh_hz: 60.0,
        },
        seed: 1,
        ideal_spp: 1,
        ideal_cache: None,
        gpu: None,
        rays: None,
    };
    let (mut warp, mut framed) = (
        LateWarp::new(&ctx).unwrap(),
        MethodKind::Framed60Hz.build(&ctx).unwrap(),
    );
    let centroid = |img: &frameless::image::Image| {
        let (mut sum, mut n) = ((0.0, 0.0), 0.0);
        for y in 0..img.height {
            for x in 0..img.width {
                // White against a tan wall (blue at most 0.65) and blue spheres.
                if img.get(x, y).min_element() > 0.9 {
                    sum = (sum.0 + x as f32 + 0.5, sum.1 + y as f32 + 0.5);
                    n += 1.0;
                }
            }
        }
        assert!(n > 4.0, "the square is not on screen");
        (sum.0 / n, sum.1 / n)
    };
    // The square (9° right of the start view's axis) is wholly in the shown frame (the
    // one started a refresh earlier) from refresh 9.
    for k in 1..=17 {
        let t = k as f64 / 60.0;
        if k < 9 {
            warp.display(t);
            framed.display(t);
            continue;
        }
        let (wx, wy) = centroid(warp.display(t).image);
        let (fx, _) = centroid(framed.display(t).image);
        let (px, py, _) = tracer
            .state_at(t)
            .camera
            .project(Vec3::new(0.4, 0.2, -0.99))
            .unwrap();
        assert!(
            (wx - px).abs() < 1.0 && (wy - py).abs() < 1.0,
            "refresh {k}: warped square at ({wx}, {wy}), truly at ({px}, {py})"
        );
        assert!(
            (fx - px).abs() > 3.0,
            "refresh {k}: the stale frame is not stale"
        );
    }
}

#[test]
fn late_warp_is_framed_60hz_under_a_still_camera() {
    let methods = [MethodKind::LateWarp, MethodKind::Framed60Hz];
    let out = evaluation::run(
        Arc::new(static_scene()),
        &panned_cfg(&methods, None),
        &Silent,
    )
    .unwrap();
    let (warped, framed) = (
        rms_series(&out, MethodKind::LateWarp),
        rms_series(&out, MethodKind::Framed60Hz),
    );
    assert_eq!(warped.len(), framed.len());
    for (k, (a, b)) in warped.iter().zip(&framed).enumerate() {
        assert!((a - b).abs() < 1e-3, "refresh {k}: {a} vs {b}");
    }
}

#[test]
fn taa_warp_follows_a_pan_that_taa_lags_at_no_ray_cost() {
    let (scene, path) = panned_scene();
    let methods = [MethodKind::TaaWarp, MethodKind::Taa];
    let out = evaluation::run(Arc::new(scene), &panned_cfg(&methods, Some(path)), &Silent).unwrap();
    // Refresh 0 shows nothing yet; every later refresh shows a frame 1/60 s old.
    let mean = |v: Vec<f64>| v[1..].iter().sum::<f64>() / (v.len() - 1) as f64;
    let (warped, plain) = (
        mean(rms_series(&out, MethodKind::TaaWarp)),
        mean(rms_series(&out, MethodKind::Taa)),
    );
    eprintln!("taa-warp RMS {warped}, taa {plain}");
    assert!(warped < 0.8 * plain, "taa-warp RMS {warped} vs taa {plain}");
    let samples = |m: MethodKind| {
        out.summary
            .results
            .iter()
            .find(|r| r.method == m)
            .map(|r| r.samples)
            .unwrap()
    };
    assert_eq!(samples(MethodKind::TaaWarp), samples(MethodKind::Taa));
}
