//! The adaptive method where the view is still: it keeps converging (the still-region
//! history of the reconstructor), it does not flicker, and an object that starts to
//! move after a long still period leaves no ghost of the converged image.

use std::sync::Arc;

use frameless::{
    clock::Clock,
    evaluation::{self, metrics, EvalConfig, Silent},
    image::Image,
    methods::{Method, MethodContext, MethodKind},
    render::still,
    scene::{
        animation::{KeyframeTrack, TcbKey, VectorSpline},
        Scene,
    },
    trace::{TextureFilter, TraceOptions, Tracer},
};
use glam::Vec3;

mod common;
use common::{animate, two_spheres};

const SIZE: u32 = 48;
/// About 43 samples per pixel per second at 48×48.
const RATE: f64 = 100_000.0;

fn cfg(methods: &[MethodKind], warmup: f64, duration: f64) -> EvalConfig {
    let mut c = EvalConfig::new("t");
    c.start = 0.0;
    c.duration = duration;
    c.display.size = frameless::settings::Size(SIZE, SIZE);
    c.rates = vec![RATE];
    c.methods = methods.to_vec();
    c.quality.seed = 2;
    c.reference.ideal_spp = 64;
    c.warmup = warmup;
    c.display.refresh_hz = 60.0;
    c.quality.max_depth = 2;
    c.strip_frames = vec![];
    c.flip_every = 1000;
    c.quality.texture_filter = TextureFilter::RayCones;
    c
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

#[test]
fn a_still_view_converges_below_a_four_spp_still_without_flicker() {
    let methods = [MethodKind::Adaptive, MethodKind::AdaptivePaper];
    let out = evaluation::run(Arc::new(two_spheres()), &cfg(&methods, 2.0, 0.5), &Silent).unwrap();
    let rms = |m: MethodKind| -> Vec<f64> {
        out.frames
            .iter()
            .filter(|f| f.method == m)
            .map(|f| f.rms)
            .collect()
    };
    let (ours, paper) = (rms(MethodKind::Adaptive), rms(MethodKind::AdaptivePaper));
    let q = ours.len() / 4;
    let late = mean(&ours[ours.len() - q..]);
    // A 4-spp stratified still of the same (static) view against the same kind of
    // ideal: 64 spp, another seed.
    let tracer = Tracer::new(
        Arc::new(two_spheres()),
        SIZE,
        SIZE,
        TraceOptions {
            max_depth: 2,
            ..Default::default()
        },
    );
    let ideal = still::render(&tracer, 0.0, 64, 5, &|_| {}).to_rgb8();
    let four = still::render(&tracer, 0.0, 4, 9, &|_| {}).to_rgb8();
    let four_spp = metrics::rms(&ideal, &four);
    eprintln!(
        "adaptive {late:.2} (first quarter {:.2}), paper {:.2}, 4 spp {four_spp:.2}",
        mean(&ours[..q]),
        mean(&paper[paper.len() - q..])
    );
    assert!(late < four_spp, "adaptive {late:.2} vs 4 spp {four_spp:.2}");
    // It is the history that does it: the paper's reconstructor stops improving.
    assert!(late < 0.75 * mean(&paper[paper.len() - q..]));
    // Still pixels do not flicker: the displayed change from refresh to refresh that
    // the ideal does not have (0–255) is small, and well below the paper's.
    let instability = |m: MethodKind| {
        out.summary
            .results
            .iter()
            .find(|r| r.method == m)
            .unwrap()
            .instability_mean
    };
    let (ours, paper) = (
        instability(MethodKind::Adaptive),
        instability(MethodKind::AdaptivePaper),
    );
    eprintln!("temporal instability: adaptive {ours:.3}, paper {paper:.3}");
    assert!(ours < 0.1, "adaptive flickers: {ours:.3}");
    assert!(ours < 0.5 * paper, "adaptive {ours:.3} vs paper {paper:.3}");
}

/// The two-sphere scene whose large sphere holds still until t = 1.9 s, then moves
/// left at about 3 units per second (some 40 pixels per second on screen at first).
fn starts_moving() -> Scene {
    let mut scene = two_spheres();
    let big = scene.groups[0].spheres.remove(0);
    let keys = [(0.0, 0.0), (1.8, 0.0), (1.9, 0.0), (2.2, -0.9), (2.5, -1.8)]
        .into_iter()
        .map(|(t, dx)| TcbKey::catmull_rom(t, Vec3::new(dx, 0.0, 0.0)))
        .collect();
    let node = animate(
        &mut scene,
        KeyframeTrack {
            name: "big".into(),
            translation: VectorSpline::new(keys),
            ..Default::default()
        },
    );
    scene.groups.push(frameless::scene::Group {
        node: Some(node),
        spheres: vec![big],
        ..Default::default()
    });
    scene
}

/// RMS (0–255) over the pixels of `mask` between two 8-bit RGB images.
fn masked_rms(a: &[u8], b: &[u8], mask: &[bool]) -> f64 {
    let (mut s, mut n) = (0.0, 0usize);
    for (k, &m) in mask.iter().enumerate() {
        if m {
            for c in 0..3 {
                let d = a[3 * k + c] as f64 - b[3 * k + c] as f64;
                s += d * d;
            }
            n += 3;
        }
    }
    (s / n.max(1) as f64).sqrt()
}

#[test]
fn an_object_that_starts_moving_after_a_long_still_leaves_no_ghost() {
    let scene = Arc::new(starts_moving());
    let tracer = Arc::new(Tracer::new(
        scene.clone(),
        SIZE,
        SIZE,
        TraceOptions {
            max_depth: 2,
            ..Default::default()
        },
    ));
    let ctx = MethodContext {
        tracer: tracer.clone(),
        clock: Clock {
            start: 0.0,
            rate: RATE,
            first_refresh: 0.0,
            refresh_hz: 60.0,
        },
        seed: 4,
        ideal_spp: 1,
        ideal_cache: None,
        gpu: None,
        rays: None,
    };
    let build = |m: MethodKind| (m.info().build)(&ctx).unwrap();
    let (mut ours, mut without) = (
        build(MethodKind::Adaptive),
        build(MethodKind::AdaptiveNoHistory),
    );
    let ideal = |t: f64| still::render(&tracer, t, 16, 1, &|_| {}).to_rgb8();
    let before = ideal(1.8);
    let shown = |m: &mut Box<dyn Method>, t: f64| -> Vec<u8> {
        let img: &Image = m.display(t).image;
        img.to_rgb8()
    };
    // Run both through the still period at every refresh, as a display would.
    let first_moving = 114; // refresh 114 is t = 1.9 s
    for k in 0..first_moving {
        let t = k as f64 / 60.0;
        shown(&mut ours, t);
        shown(&mut without, t);
    }
    let (mut err_ours, mut err_without, mut err_frozen) = (vec![], vec![], vec![]);
    for k in first_moving..first_moving + 24 {
        let t = k as f64 / 60.0;
        let truth = ideal(t);
        // Where the image changed since the still period: the sphere's new and
        // vacated places.
        let mask: Vec<bool> = (0..(SIZE * SIZE) as usize)
            .map(|p| (0..3).any(|c| before[3 * p + c].abs_diff(truth[3 * p + c]) > 12))
            .collect();
        let (a, b) = (shown(&mut ours, t), shown(&mut without, t));
        if k >= first_moving + 8 {
            err_ours.push(masked_rms(&a, &truth, &mask));
            err_without.push(masked_rms(&b, &truth, &mask));
            err_frozen.push(masked_rms(&before, &truth, &mask));
        }
    }
    let (ours, without, frozen) = (mean(&err_ours), mean(&err_without), mean(&err_frozen));
    eprintln!(
        "changed region RMS: adaptive {ours:.1}, without history {without:.1}, frozen {frozen:.1}"
    );
    // Updated within a few refreshes: from the 8th refresh after the motion starts the
    // changed region is far from a display frozen at the converged image, and no worse
    // than without the history.
    assert!(
        ours < 0.5 * frozen,
        "adaptive {ours:.1} vs frozen {frozen:.1}"
    );
    assert!(
        ours <= 1.1 * without + 1.0,
        "adaptive {ours:.1} vs without history {without:.1}"
    );
}
