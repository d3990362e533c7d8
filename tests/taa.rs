//! The temporal upsampler (`taa`) on small hand-built cases: it converges on a still
//! view and drops its history after a camera cut.

use std::sync::Arc;

use frameless::{
    evaluation::{self, metrics, EvalConfig, Silent},
    methods::MethodKind,
    render::still,
    scene::{CameraPath, Scene},
    trace::{TraceOptions, Tracer},
};
use glam::Vec3;

mod common;
use common::two_spheres;

const SIZE: u32 = 48;
/// 1,152 samples per frame: a 33×34 grid under a 48×48 display, ~2× upsampling.
const RATE: f64 = 69_120.0;

fn scene() -> Scene {
    two_spheres()
}

fn cfg(camera_path: Option<CameraPath>, duration: f64) -> EvalConfig {
    let mut c = EvalConfig::new("t");
    c.camera_path = camera_path;
    c.start = 0.0;
    c.duration = duration;
    c.display.size = frameless::settings::Size(SIZE, SIZE);
    c.rates = vec![RATE];
    c.methods = vec![MethodKind::Taa];
    c.quality.seed = 2;
    c.reference.ideal_spp = 16;
    c.warmup = 0.0;
    c.display.refresh_hz = 60.0;
    c.quality.max_depth = 2;
    c.strip_frames = vec![];
    c.flip_every = 1000;
    c.quality.texture_filter = frameless::trace::TextureFilter::None;
    c
}

/// RMS (0–255) of TAA's displayed image against the ideal at every refresh.
fn taa_rms(camera_path: Option<CameraPath>, duration: f64) -> Vec<f64> {
    let out = evaluation::run(Arc::new(scene()), &cfg(camera_path, duration), &Silent).unwrap();
    out.frames.iter().map(|f| f.rms).collect()
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

#[test]
fn taa_converges_on_a_still_scene_below_one_sample_per_pixel() {
    let rms = taa_rms(None, 1.0);
    let q = rms.len() / 4;
    // Refresh 0 shows nothing yet (the first frame completes at refresh 1).
    let (first, last) = (mean(&rms[1..=q]), mean(&rms[rms.len() - q..]));
    assert!(
        last < 0.75 * first,
        "no convergence: first quarter {first:.2}, last quarter {last:.2}"
    );
    // A 1-spp image of the same view (one random position per pixel) against the same
    // ideal: a converged upsampler beats it although it traces ~0.5 samples per pixel
    // per frame.
    let tracer = Tracer::new(
        Arc::new(scene()),
        SIZE,
        SIZE,
        TraceOptions {
            max_depth: 2,
            ..Default::default()
        },
    );
    let ideal = still::render(&tracer, 0.5, 16, 2, &|_| {}).to_rgb8();
    let one = still::render(&tracer, 0.5, 1, 7, &|_| {}).to_rgb8();
    let one_spp = metrics::rms(&ideal, &one);
    assert!(last < 0.7 * one_spp, "taa {last:.2} vs 1 spp {one_spp:.2}");
}

fn view(eye: Vec3, at: Vec3) -> String {
    format!(
        "{},{},{},{},{},{},0,1,0,90",
        eye.x, eye.y, eye.z, at.x, at.y, at.z
    )
}

#[test]
fn taa_drops_its_history_after_a_camera_cut() {
    let header = frameless::scene::camera_path::HEADER;
    let a = view(Vec3::new(0.0, 0.0, 1.5), Vec3::ZERO);
    let b = view(Vec3::new(0.5, 0.3, 1.2), Vec3::new(1.0, -0.2, -1.0));
    // View A until frame 30 (t = 0.5), view B from 1 ms later: frame 31 is the first of B
    // and is shown at refresh 32.
    let cut = format!("{header}\n0,{a}\n0.5,{a}\n0.501,{b}\n2,{b}\n");
    let fresh = format!("{header}\n0,{b}\n");
    let path = |text: &str| Some(CameraPath::parse("p.csv", text).unwrap());
    let after_cut = taa_rms(path(&cut), 0.75);
    let from_start = taa_rms(path(&fresh), 0.25);
    // k = 2..=8 frames of view B accumulated in both runs; single frames are noisy (the
    // jitter phases differ), so compare means. Ghosts of view A made this 1.7×.
    let cut = mean(&after_cut[33..=39]);
    let fresh = mean(&from_start[2..=8]);
    assert!(
        cut <= 1.25 * fresh,
        "after the cut {cut:.2}, a fresh start {fresh:.2} ({:.2?} vs {:.2?})",
        &after_cut[32..40],
        &from_start[1..9]
    );
}
