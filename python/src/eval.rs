//! `frameless eval` and `frameless live` without their output folders: the summary
//! and the per-refresh table come back as JSON text, which the Python side turns into
//! dicts and numpy columns.

use std::path::PathBuf;

use frameless::evaluation::{self, live as live_eval, EvalConfig};
use pyo3::prelude::*;

use crate::{args, errors, scene::NativeScene, work};

/// JSON text of something the library serialises (numbers and strings only).
fn json<T: serde::Serialize>(v: &T) -> String {
    serde_json::to_string(v).expect("summaries and rows serialise")
}

/// evaluate(scene, methods, rates, start, duration, size, refresh_hz, seed, ideal_spp,
///          warmup, max_depth, texture_filter, flip_every, cache_dir, recon="cpu",
///          progress=None, trace="cpu")
/// --
///
/// `frameless eval` with these settings: `(summary_json, frames_json)`; `cache_dir`
/// None reads and writes no ideal-image cache.
#[pyfunction]
#[pyo3(signature = (scene, methods, rates, start, duration, size, refresh_hz, seed, ideal_spp,
                    warmup, max_depth, texture_filter, flip_every, cache_dir, recon="cpu",
                    progress=None, trace="cpu"))]
#[allow(clippy::too_many_arguments)]
fn evaluate(
    py: Python<'_>,
    scene: &NativeScene,
    methods: Vec<String>,
    rates: Vec<String>,
    start: f64,
    duration: f64,
    size: &str,
    refresh_hz: f64,
    seed: u64,
    ideal_spp: u64,
    warmup: f64,
    max_depth: u64,
    texture_filter: &str,
    flip_every: u64,
    cache_dir: Option<PathBuf>,
    recon: &str,
    progress: Option<Bound<'_, PyAny>>,
    trace: &str,
) -> PyResult<(String, String)> {
    args::in_range("flip_every", flip_every, 1, u32::MAX as u64)?;
    let (display, quality, reference) = args::groups(
        size,
        refresh_hz,
        seed,
        ideal_spp,
        max_depth,
        texture_filter,
        cache_dir,
    )?;
    let mut cfg = EvalConfig::new(&scene.name);
    cfg.camera_path = scene.camera_path.clone();
    cfg.start = args::finite("start", start)?;
    cfg.duration = args::finite("duration", duration)?;
    cfg.rates = args::rates(&rates)?;
    cfg.methods = args::methods(&methods)?;
    cfg.warmup = args::finite("warmup", warmup)?;
    cfg.flip_every = flip_every as usize;
    // As the command line: the groups set last (image strips at the quartiles of the
    // window).
    cfg.set_groups(&display, &quality, &reference);
    cfg.validate().map_err(errors::eval)?;
    cfg.devices = args::devices(recon, trace)?;
    let scene = scene.scene.clone();
    work::run(py, progress.as_ref(), move |work| {
        let out = evaluation::run(scene, &cfg, work).map_err(errors::eval)?;
        Ok((json(&out.summary), json(&out.frames)))
    })
}

/// live(scene, methods, start, seconds, warmup, size, refresh_hz, repeat, threads, seed,
///      ideal_spp, max_depth, texture_filter, cache_dir, recon="cpu", progress=None,
///      trace="cpu", image_budget=None, ring_factor=None, max_radius=None, view_ahead=True,
///      late_samples=True)
/// --
///
/// `frameless live` with these settings: `(summary_json, frames_json)`.
#[pyfunction]
#[pyo3(signature = (scene, methods, start, seconds, warmup, size, refresh_hz, repeat, threads,
                    seed, ideal_spp, max_depth, texture_filter, cache_dir, recon="cpu",
                    progress=None, trace="cpu", image_budget=None, ring_factor=None,
                    max_radius=None, view_ahead=true, late_samples=true))]
#[allow(clippy::too_many_arguments)]
fn live(
    py: Python<'_>,
    scene: &NativeScene,
    methods: Option<Vec<String>>,
    start: f64,
    seconds: f64,
    warmup: f64,
    size: &str,
    refresh_hz: f64,
    repeat: u64,
    threads: Option<u64>,
    seed: u64,
    ideal_spp: u64,
    max_depth: u64,
    texture_filter: &str,
    cache_dir: Option<PathBuf>,
    recon: &str,
    progress: Option<Bound<'_, PyAny>>,
    trace: &str,
    image_budget: Option<f64>,
    ring_factor: Option<f64>,
    max_radius: Option<f64>,
    view_ahead: bool,
    late_samples: bool,
) -> PyResult<(String, String)> {
    args::in_range("repeat", repeat, 1, 100)?;
    let (display, quality, reference) = args::groups(
        size,
        refresh_hz,
        seed,
        ideal_spp,
        max_depth,
        texture_filter,
        cache_dir,
    )?;
    let mut cfg = live_eval::LiveConfig::new(&scene.name);
    cfg.camera_path = scene.camera_path.clone();
    cfg.start = args::finite("start", start)?;
    cfg.seconds = args::finite("duration", seconds)?;
    cfg.warmup = args::finite("warmup", warmup)?;
    cfg.set_groups(&display, &quality, &reference);
    if let Some(m) = methods {
        cfg.methods = args::rt_methods(&m)?;
    }
    cfg.repeat = repeat as usize;
    if let Some(n) = threads {
        args::in_range("threads", n, 1, 1024)?;
        cfg.cores = n as usize;
    }
    if let Some(b) = image_budget {
        cfg.adaptive.image_budget = args::finite("image_budget", b)?;
    }
    cfg.adaptive.ring_factor = ring_factor.map(|f| args::finite("ring_factor", f)).transpose()?;
    cfg.adaptive.max_radius = max_radius.map(|r| args::finite("max_radius", r)).transpose()?;
    cfg.view_ahead = view_ahead;
    cfg.adaptive.no_late_samples = !late_samples;
    cfg.validate().map_err(errors::eval)?;
    cfg.devices = args::devices(recon, trace)?;
    let scene = scene.scene.clone();
    work::run(py, progress.as_ref(), move |work| {
        let out = live_eval::run(scene, &cfg, work).map_err(errors::eval)?;
        Ok((json(&out.summary), json(&out.frames)))
    })
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(evaluate, m)?)?;
    m.add_function(wrap_pyfunction!(live, m)?)
}
