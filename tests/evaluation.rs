//! The evaluation harness on small cases: double-buffer timing, convergence on a static
//! scene, determinism across thread counts, and argument errors.

use std::sync::Arc;

use frameless::{
    clock::Clock,
    evaluation::{self, EvalConfig, Silent},
    methods::{framed::Framed, Method, MethodContext, MethodKind},
    scene::{Camera, CameraTrack, Group, Light, Material, Scene, Sphere, Triangle},
    trace::{TraceOptions, Tracer},
};
use glam::Vec3;

/// A static scene with edges (sphere silhouettes over a floor) so antialiasing matters.
fn static_scene() -> Scene {
    let floor = [
        Vec3::new(-5.0, 0.0, 5.0),
        Vec3::new(5.0, 0.0, 5.0),
        Vec3::new(5.0, 0.0, -5.0),
        Vec3::new(-5.0, 0.0, -5.0),
    ];
    Scene {
        name: "static".into(),
        materials: vec![
            Material::matte(Vec3::new(0.8, 0.7, 0.5)),
            Material::matte(Vec3::new(0.2, 0.4, 0.9)),
        ],
        groups: vec![Group {
            node: None,
            triangles: vec![
                Triangle {
                    p: [floor[0], floor[1], floor[2]],
                    n: None,
                    uv: None,
                    material: 0,
                },
                Triangle {
                    p: [floor[0], floor[2], floor[3]],
                    n: None,
                    uv: None,
                    material: 0,
                },
            ],
            spheres: vec![
                Sphere {
                    center: Vec3::new(-0.6, 0.5, 0.0),
                    radius: 0.5,
                    material: 1,
                },
                Sphere {
                    center: Vec3::new(0.7, 0.3, 0.6),
                    radius: 0.3,
                    material: 1,
                },
            ],
            ..Default::default()
        }],
        lights: vec![Light {
            position: Vec3::new(2.0, 4.0, 3.0),
            color: Vec3::ONE,
            track: None,
            name: None,
        }],
        camera: CameraTrack {
            base: Camera {
                eye: Vec3::new(0.0, 1.5, 3.0),
                at: Vec3::new(0.0, 0.3, 0.0),
                up: Vec3::Y,
                fov_y_deg: 50.0,
                hither: 1e-3,
            },
            track: None,
            resolution: None,
        },
        background: Vec3::new(0.1, 0.1, 0.2),
        ambient: Vec3::splat(0.5),
        ..Default::default()
    }
}

fn config(methods: &[MethodKind], rates: &[f64], warmup: f64, duration: f64) -> EvalConfig {
    let mut c = EvalConfig::new("static");
    c.start = 0.0;
    c.duration = duration;
    c.display.size = frameless::settings::Size(32, 24);
    c.rates = rates.to_vec();
    c.methods = methods.to_vec();
    c.quality.seed = 3;
    c.reference.ideal_spp = 16;
    c.warmup = warmup;
    c.display.refresh_hz = 60.0;
    c.quality.max_depth = 3;
    c.quality.texture_filter = frameless::trace::TextureFilter::None;
    c.strip_frames = vec![0];
    c.flip_every = 1;
    c
}

fn rms_series(out: &evaluation::EvalOutput, method: MethodKind, rate: f64) -> Vec<f64> {
    out.frames
        .iter()
        .filter(|f| f.method == method && f.rate == rate)
        .map(|f| f.rms)
        .collect()
}

#[test]
fn double_buffering_timing_hand_worked() {
    // 32x24 = 768 samples per frame at 768·20 samples/s: a frame takes 1/20 s = 3
    // refreshes. With no warm-up, frame 0 (started t=0) completes at 0.05 = refresh 3 and
    // is shown from refresh 3; frame 1 (started 0.05) completes at 0.1 = refresh 6.
    let scene = Arc::new(static_scene());
    let tracer = Arc::new(Tracer::new(scene, 32, 24, TraceOptions::default()));
    let rate = 768.0 * 20.0;
    let ctx = MethodContext {
        tracer,
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
    let mut m = Framed::full_res(&ctx).unwrap();
    assert_eq!(m.samples_per_frame(), 768);
    assert!((m.frame_duration() - 0.05).abs() < 1e-12);
    let mut ages = Vec::new();
    let mut used = Vec::new();
    for k in 0..8 {
        let t = k as f64 / 60.0;
        ages.push(m.display(t).mean_age);
        used.push(m.samples_used());
    }
    // Nothing shown before refresh 3: age counts from the clock start.
    for (k, age) in ages.iter().enumerate().take(3) {
        assert!((age - k as f64 / 60.0).abs() < 1e-9, "refresh {k}: {age}");
    }
    // Refreshes 3..5 show frame 0 (sampled at t = 0); 6..7 show frame 1 (t = 0.05).
    for (k, age) in ages.iter().enumerate().take(6).skip(3) {
        assert!((age - k as f64 / 60.0).abs() < 1e-9, "refresh {k}: {age}");
    }
    for (k, age) in ages.iter().enumerate().take(8).skip(6) {
        assert!(
            (age - (k as f64 / 60.0 - 0.05)).abs() < 1e-9,
            "refresh {k}: {age}"
        );
    }
    assert_eq!(used, vec![0, 0, 0, 768, 768, 768, 1536, 1536]);
}

#[test]
fn framed_full_reaches_its_floor_once_a_frame_completes_and_frameless_converges() {
    // Static scene, no warm-up: both start from a black screen. framed-full completes
    // its first frame after 768/rate s; traditional frameless fills pixels one by one.
    let rate = 768.0 * 12.0; // a frame every 5 refreshes
    let cfg = config(
        &[MethodKind::FramedFull, MethodKind::TraditionalFrameless],
        &[rate],
        0.0,
        0.5,
    );
    let out = evaluation::run(Arc::new(static_scene()), &cfg, &Silent).unwrap();
    let framed = rms_series(&out, MethodKind::FramedFull, rate);
    let frameless = rms_series(&out, MethodKind::TraditionalFrameless, rate);
    // Before completion the screen is black: large error. From refresh 5 on: the floor.
    let floor = framed[5];
    assert!(framed[..5].iter().all(|e| *e > 3.0 * floor), "{framed:?}");
    assert!(
        framed[5..].iter().all(|e| (e - floor).abs() < 1e-9),
        "{framed:?}"
    );
    // Frameless error falls as the screen fills and ends where the framed image is: both
    // show one pixel-center sample per pixel of the same static scene.
    assert!(
        frameless[1] > frameless[4] && frameless[4] >= frameless[6],
        "{frameless:?}"
    );
    let last = *frameless.last().unwrap();
    assert!(
        (last - floor).abs() < 1e-9,
        "frameless {last} vs framed {floor}"
    );
    // Temporal instability: a static scene shown steadily does not flicker at all; the
    // frameless display changes as it fills while the ideal does not.
    let instability: Vec<f64> = out
        .frames
        .iter()
        .filter(|f| f.method == MethodKind::FramedFull)
        .filter_map(|f| f.instability)
        .collect();
    assert!(
        instability[5..].iter().all(|f| *f == 0.0),
        "{instability:?}"
    );
    assert!(out.frames.iter().any(
        |f| f.method == MethodKind::TraditionalFrameless && f.instability.unwrap_or(0.0) > 0.0
    ));
    // The floor is the aliasing of 1 sample per pixel: small but not zero.
    assert!(floor > 0.0 && floor < 20.0, "{floor}");
}

#[test]
fn deterministic_across_thread_counts() {
    let cfg = config(
        &[MethodKind::Framed60Hz, MethodKind::TraditionalFrameless],
        &[20_000.0],
        0.1,
        0.2,
    );
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| evaluation::run(Arc::new(static_scene()), &cfg, &Silent).unwrap())
    };
    let (a, b) = (run(1), run(3));
    assert_eq!(a.frames, b.frames);
    assert_eq!(a.strips, b.strips);
}

#[test]
fn bad_settings_are_clear_errors() {
    let scene = || Arc::new(static_scene());
    let err = |cfg: &EvalConfig| {
        evaluation::run(scene(), cfg, &Silent)
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default()
    };
    let e = err(&config(&[MethodKind::FramedFull], &[0.0], 1.0, 1.0));
    assert!(e.contains("rate"), "{e}");
    let e = err(&config(&[MethodKind::FramedFull], &[100.0], 1.0, 1.0));
    assert!(e.contains("too low for framed-full"), "{e}");
    let e = err(&config(&[MethodKind::Framed60Hz], &[30.0], 1.0, 1.0));
    assert!(e.contains("too low for framed-60hz"), "{e}");
    let e = err(&config(&[MethodKind::FramedFull], &[1e5], 1.0, -1.0));
    assert!(e.contains("duration"), "{e}");
    assert!(MethodKind::parse("adaptive-magic")
        .unwrap_err()
        .to_string()
        .contains("framed-60hz"));
}

#[test]
fn ideal_cache_round_trips_and_recovers_from_corruption() {
    let dir = std::env::temp_dir().join(format!("frameless-cache-test-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let mut cfg = config(&[MethodKind::FramedFull], &[768.0 * 60.0], 0.0, 0.05);
    cfg.reference.set_cache(Some(dir.clone()));
    let first = evaluation::run(Arc::new(static_scene()), &cfg, &Silent).unwrap();
    assert_eq!(first.summary.timing.ideal_cache_hits, 0);
    let second = evaluation::run(Arc::new(static_scene()), &cfg, &Silent).unwrap();
    assert_eq!(second.summary.timing.ideal_cache_hits, 3);
    assert_eq!(first.frames, second.frames);
    // Truncate every entry, as an interrupted write without the rename would: the run
    // re-renders instead of reading garbage, and the numbers do not change.
    for e in std::fs::read_dir(&dir).unwrap() {
        let p = e.unwrap().path();
        let bytes = std::fs::read(&p).unwrap();
        std::fs::write(&p, &bytes[..bytes.len() / 2]).unwrap();
    }
    let third = evaluation::run(Arc::new(static_scene()), &cfg, &Silent).unwrap();
    assert_eq!(first.frames, third.frames);
    assert_eq!(third.summary.timing.ideal_cache_hits, 0);
    assert_eq!(third.summary.timing.ideal_cache_rejected, 3);
    // A different scene gets different entries.
    let mut other = static_scene();
    other.ambient = Vec3::splat(0.6);
    let fourth = evaluation::run(Arc::new(other), &cfg, &Silent).unwrap();
    assert_eq!(fourth.summary.timing.ideal_cache_hits, 0);
    std::fs::remove_dir_all(&dir).ok();
}
