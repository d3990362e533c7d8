//! What `frameless sampler` writes of a sampler after its run: the displayed image, the
//! visualisations of its state ([`super::vis`]) and `stats.json`, into one output
//! folder replaced whole.

use std::path::{Path, PathBuf};

use super::{vis, Sampler};
use crate::{image::Image, output::OutputDir};

/// An output of the sampler's run that could not be written.
#[derive(Debug, thiserror::Error)]
#[error("{what} {}: {source}", path.display())]
pub struct WriteError {
    /// What was being done: `creating`, `writing` or `replacing`.
    pub what: &'static str,
    /// The file or folder.
    pub path: PathBuf,
    /// Why.
    pub source: std::io::Error,
}

/// The run a sampler's outputs describe, for `stats.json`.
#[derive(Clone, Debug)]
pub struct SamplerRun<'a> {
    /// The scene as named on the command line.
    pub scene: &'a str,
    /// Samples per second.
    pub rate: f64,
    /// Scene time at the start of the run.
    pub start: f64,
    /// Scene time at its end.
    pub end: f64,
    /// Wall-clock seconds the run took.
    pub wall_s: f64,
}

/// Write what `s` saw after `run` into the folder `out` (replaced whole): the pictures
/// and `stats.json`, whose contents it returns.
pub fn write(
    out: &Path,
    s: &Sampler,
    display: &Image,
    run: &SamplerRun<'_>,
) -> Result<serde_json::Value, WriteError> {
    let err = |what, path: &Path| {
        let path = path.to_path_buf();
        move |source| WriteError { what, path, source }
    };
    let staging = OutputDir::begin(out).map_err(err("creating", out))?;
    let save = |name: &str, img: &Image| -> Result<(), WriteError> {
        let p = staging.path().join(name);
        img.save_png(&p).map_err(err("writing", &p))
    };
    save("display.png", display)?;
    save("tiling.png", &vis::tiling_overlay(s, display))?;
    save("gradients.png", &vis::gradient_map(s))?;
    save("density.png", &vis::density_map(s))?;
    save("occlusion.png", &vis::occlusion_map(s, run.end))?;
    let (trace_s, total_s) = s.timing();
    let gain_inputs = {
        let (gs, gt, age) = s.gain_inputs(run.end);
        serde_json::json!({"gs": gs, "gt": gt, "age_s": age})
    };
    let (w, h) = (display.width, display.height);
    let stats = serde_json::json!({
        "scene": run.scene, "width": w, "height": h, "rate": run.rate, "start": run.start,
        "end": run.end,
        "tiles": s.tiling().len(), "target_tiles": s.target_tiles(),
        "gain_inputs": gain_inputs,
        "counters": s.counters(),
        "sampler_s": total_s, "trace_s": trace_s,
        "control_overhead": if total_s > 0.0 { (total_s - trace_s) / total_s } else { 0.0 },
        "wall_s": run.wall_s,
    });
    let p = staging.path().join("stats.json");
    let text = serde_json::to_string_pretty(&stats).expect("a JSON value serializes");
    std::fs::write(&p, text).map_err(err("writing", &p))?;
    staging.commit().map_err(err("replacing", out))?;
    Ok(stats)
}
