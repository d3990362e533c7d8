//! The adaptive space-time reconstructor: kernel normalisation and hole filling, the
//! filter's volume constraint, convergence on a static scene, response to a sudden
//! change, determinism across thread counts.

use std::sync::Arc;

use frameless::{
    clock::Clock,
    image::Image,
    methods::{
        adaptive::{tiling::Tiling, Adaptive, SamplerParams},
        Method, MethodContext, MethodKind,
    },
    reconstruction::{
        filter::{extents, local_rate, FilterBounds},
        ReconParams, Reconstructor, RingSample,
    },
    sampling::Rng,
    scene::{
        animation::{KeyframeTrack, TcbKey, VectorSpline},
        Camera, CameraTrack, Group, Material, Node, NodeKind, Scene, Triangle,
    },
    trace::{TraceOptions, Tracer},
};
use glam::Vec3;

mod common;
use common::{flat, quad};

fn camera() -> Camera {
    Camera {
        eye: Vec3::new(0.0, 0.0, 1.0),
        at: Vec3::ZERO,
        up: Vec3::Y,
        fov_y_deg: 90.0,
        hither: 1e-3,
    }
}

fn scene(groups: Vec<Group>, materials: Vec<Material>) -> Scene {
    Scene {
        name: "t".into(),
        materials,
        groups,
        camera: CameraTrack {
            base: camera(),
            track: None,
            resolution: None,
        },
        ambient: Vec3::ONE,
        ..Default::default()
    }
}

/// White disc-ish diamond on a grey background: edges in every direction.
fn static_scene() -> Scene {
    let mut tris = quad(-2.0, 2.0, -2.0, 2.0, 0.0, 0);
    tris.push(Triangle {
        p: [
            Vec3::new(-0.6, -0.5, 0.2),
            Vec3::new(0.7, -0.3, 0.2),
            Vec3::new(0.0, 0.6, 0.2),
        ],
        n: None,
        uv: None,
        material: 1,
    });
    scene(
        vec![Group {
            node: None,
            triangles: tris,
            ..Default::default()
        }],
        vec![flat(0.2), flat(0.9)],
    )
}

/// Black background; a white square in the middle appears at t = 1.
fn appearing_scene() -> Scene {
    let mut s = scene(
        vec![
            Group {
                node: None,
                triangles: quad(-2.0, 2.0, -2.0, 2.0, 0.0, 0),
                ..Default::default()
            },
            Group {
                node: Some(0),
                triangles: quad(-0.5, 0.5, -0.5, 0.5, 0.3, 1),
                ..Default::default()
            },
        ],
        vec![flat(0.0), flat(1.0)],
    );
    s.tracks.push(KeyframeTrack {
        name: "box".into(),
        visibility: vec![(-10.0, false), (1.0, true)],
        ..Default::default()
    });
    s.nodes.push(Node {
        parent: None,
        kind: NodeKind::Animated {
            name: "box".into(),
            track: Some(0),
        },
    });
    s
}

/// A quad moving right at `speed` world units per second.
fn motion_scene(speed: f32) -> Scene {
    let keys = (-1..=4)
        .map(|i| TcbKey {
            time: i as f32,
            value: Vec3::new(speed * i as f32, 0.0, 0.0),
            tension: 0.0,
            continuity: 0.0,
            bias: 0.0,
        })
        .collect();
    let mut s = scene(
        vec![
            Group {
                node: None,
                triangles: quad(-3.0, 3.0, -3.0, 3.0, 0.0, 0),
                ..Default::default()
            },
            Group {
                node: Some(0),
                triangles: quad(-1.3, -0.7, -0.3, 0.3, 0.2, 1),
                ..Default::default()
            },
        ],
        vec![flat(0.1), flat(0.8)],
    );
    s.tracks.push(KeyframeTrack {
        name: "mover".into(),
        translation: VectorSpline::new(keys),
        ..Default::default()
    });
    s.nodes.push(Node {
        parent: None,
        kind: NodeKind::Animated {
            name: "mover".into(),
            track: Some(0),
        },
    });
    s
}

fn ctx(scene: Scene, size: u32, rate: f64) -> MethodContext {
    MethodContext {
        tracer: Arc::new(Tracer::new(
            Arc::new(scene),
            size,
            size,
            TraceOptions::default(),
        )),
        clock: Clock {
            start: 0.0,
            rate,
            first_refresh: 0.0,
            refresh_hz: 60.0,
        },
        seed: 3,
        ideal_spp: 16,
        ideal_cache: None,
        gpu: None,
        rays: None,
    }
}

fn rms(a: &Image, b: &Image) -> f64 {
    let s: f64 = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .map(|(p, q)| {
            let d = (p.min(Vec3::ONE) - q.min(Vec3::ONE)) * 255.0;
            d.length_squared() as f64 / 3.0
        })
        .sum();
    (s / a.pixels.len() as f64).sqrt()
}

#[test]
fn constant_field_reconstructs_exactly_including_holes() {
    let (w, h) = (40u32, 30u32);
    let cam = camera().frame(w, h);
    let c = Vec3::new(0.3, 0.55, 0.8);
    let mut rng = Rng::new(&[7]);
    for (n, expect_holes) in [(15usize, true), (20_000, false)] {
        for params in [
            ReconParams::paper(),
            ReconParams::no_reprojection(),
            ReconParams::fixed_filter(),
        ] {
            let mut r = Reconstructor::new(w, h, 10_000.0, params);
            for i in 0..n {
                let (x, y) = (rng.uniform() * w as f32, rng.uniform() * h as f32);
                r.push(RingSample {
                    x,
                    y,
                    t: i as f64 / n as f64 * 0.05,
                    color: c,
                    hit_point: cam.eye + cam.direction(x, y) * (1.0 + rng.uniform()),
                    velocity: Vec3::new(rng.uniform(), 0.0, 0.0) * 0.1,
                    anchor: Default::default(),
                });
            }
            let mut tiling = Tiling::new(w, h);
            tiling.split(0, |_| Default::default());
            let img = r.reconstruct(0.06, &cam, &tiling.snapshot()).clone();
            if expect_holes && params.fixed_filter.is_none() {
                assert!(r.holes() > 0, "holes expected with {n} samples");
            }
            for p in &img.pixels {
                assert!((*p - c).abs().max_element() < 1e-5, "{p} vs {c}");
            }
        }
    }
}

#[test]
fn extents_satisfy_the_volume_constraint() {
    let b = FilterBounds::default();
    let rl = local_rate(400_000.0, 64, 1024);
    let v = 1.0 / rl;
    for (gx, gy, gt) in [(0.01, 0.02, 0.05), (0.1, 0.1, 0.5), (0.02, 0.01, 0.03)] {
        let e = extents(v, gx, gy, gt, &b);
        assert!((e.ex * e.ey * e.et / v - 1.0).abs() < 1e-9, "{e:?}");
        assert!((e.ex * gx / (e.ey * gy) - 1.0).abs() < 1e-9, "{e:?}");
        assert!((e.ey * gy / (e.et * gt) - 1.0).abs() < 1e-9, "{e:?}");
        assert!(e.ex > b.extent_xy.0 && e.ex < b.extent_xy.1);
        assert!(e.et > b.extent_t.0 && e.et < b.extent_t.1);
    }
}

#[test]
fn static_scene_converges_toward_the_ideal() {
    // Before the ring is full the display rests on few samples; once the sampler and
    // reconstructor settle the error is lower (averaged over refreshes, since the
    // sampler keeps moving samples around).
    let c = ctx(static_scene(), 48, 60_000.0);
    let mut ideal = MethodKind::Ideal.build(&c).unwrap();
    let reference = ideal.display(0.0).image.clone();
    let mut m = Adaptive::new(&c, SamplerParams::paper()).unwrap();
    let mut errs = Vec::new();
    for k in 1..=90u32 {
        let img = m.display(k as f64 / 60.0).image.clone();
        errs.push(rms(&img, &reference));
    }
    let mean = |r: std::ops::Range<usize>| errs[r.clone()].iter().sum::<f64>() / r.len() as f64;
    let (early, mid, late) = (mean(0..2), mean(20..40), mean(60..90));
    assert!(
        late < 0.7 * early && mid < early && late <= mid * 1.1,
        "RMS should fall: early {early:.2}, mid {mid:.2}, late {late:.2}"
    );
}

#[test]
fn sudden_change_shows_within_a_few_refreshes() {
    let size = 32;
    let c = ctx(appearing_scene(), size, 100_000.0);
    let mut m = Adaptive::new(&c, SamplerParams::paper()).unwrap();
    let center = |img: &Image| {
        let mut s = 0.0;
        for y in 12..20 {
            for x in 12..20 {
                s += img.get(x, y).x;
            }
        }
        s / 64.0
    };
    let mut t = 0.0;
    for k in 1..=59 {
        t = k as f64 / 60.0;
        m.display(t);
    }
    let before = center(m.display(t).image);
    assert!(before < 0.05, "box hidden before t = 1: {before}");
    let mut shown_at = None;
    for k in 60..=70 {
        let t = k as f64 / 60.0;
        let v = center(m.display(t).image);
        if v > 0.8 {
            shown_at = Some(k - 60);
            break;
        }
    }
    let k = shown_at.expect("the box never showed within 10 refreshes");
    assert!(k <= 4, "box shown only after {k} refreshes");
}

#[test]
fn images_are_identical_for_any_thread_count() {
    let run = |threads: usize, kind: MethodKind| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                let c = ctx(motion_scene(1.0), 40, 50_000.0);
                let mut m = kind.build(&c).unwrap();
                let mut out = Vec::new();
                for k in 1..=30 {
                    let img = m.display(k as f64 / 60.0).image.clone();
                    assert!(img.pixels.iter().all(|p| p.is_finite()), "non-finite pixel");
                    out.push(img.pixels.iter().map(|p| p.to_array()).collect::<Vec<_>>());
                }
                out
            })
    };
    for kind in [
        MethodKind::Adaptive,
        MethodKind::AdaptiveNoReprojRecon,
        MethodKind::AdaptiveFixedFilter,
        MethodKind::AdaptiveNoReprojection,
    ] {
        assert_eq!(run(1, kind), run(3, kind), "{}", kind.name());
    }
}

#[test]
fn synthetic_ring_determinism_across_threads() {
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                let (mut r, cam, tiling) = frameless::bench::reconstruct_fixture(96, 64, 40_000, 2);
                r.reconstruct(1.0, &cam, &tiling);
                r.reconstruct(1.0, &cam, &tiling).pixels.clone()
            })
    };
    assert_eq!(run(1), run(3));
}

#[test]
fn carried_moved_and_resplatted_images_are_identical_for_any_thread_count() {
    use frameless::{bench, reconstruction::ReconParams};
    // The bench's live fixture, with the camera turning (sums carried with the view,
    // or the ring re-splatted) and still: the carry and history passes run in parallel
    // and must land everything in the same order on any number of threads.
    let case = bench::LiveCase {
        width: 120,
        height: 80,
        rate: 60_000.0,
        refresh_hz: 30.0,
    };
    let run = |threads: usize, resplat_moving_view: bool, turning: bool| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                let params = ReconParams {
                    resplat_moving_view,
                    ..ReconParams::realtime()
                };
                bench::live_image_ms(case, 2.0, params, 6, turning, None)
                    .unwrap()
                    .image_hash
            })
    };
    for (resplat, turning) in [(false, true), (true, true), (false, false)] {
        assert_eq!(
            run(1, resplat, turning),
            run(3, resplat, turning),
            "resplat_moving_view {resplat}, turning {turning}"
        );
    }
}
