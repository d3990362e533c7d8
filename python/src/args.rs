//! Arguments as the command line spells them (`"256x256"`, `"400k"`, method names),
//! parsed by the library's parsers so that a bad one gets the command line's reason.
//! The ranges clap checks on the command line (`--spp`, `--max-depth`, …) are checked
//! here with the same bounds, the message naming the Python keyword (`spp=0`), not
//! the option.

use frameless::{
    clock::parse_rate,
    evaluation::live::LiveConfig,
    evaluation::EvalConfig,
    methods::MethodKind,
    realtime::RtMethod,
    reconstruction::device::{self, GpuContext},
    settings::{self, ReconDevice},
    trace::TextureFilter,
};
use pyo3::{prelude::*, types::PyDict};

use crate::errors::{message, value};

/// `WxH`, as `--size` takes it.
pub fn size(s: &str) -> PyResult<(u32, u32)> {
    frameless::limits::parse_size(s).map_err(|e| value(e.to_string()))
}

/// Sample rates as `--rate` takes them (`100k`, `1.5M`, `400000`).
pub fn rates(list: &[String]) -> PyResult<Vec<f64>> {
    list.iter()
        .map(|r| parse_rate(r).map_err(|e| value(message(&e))))
        .collect()
}

/// Method names under the simulated clock, blanks around a name ignored.
pub fn methods(list: &[String]) -> PyResult<Vec<MethodKind>> {
    list.iter()
        .map(|m| MethodKind::parse(m.trim()).map_err(|e| value(message(&e))))
        .collect()
}

/// Method names of the real-time pipeline.
pub fn rt_methods(list: &[String]) -> PyResult<Vec<RtMethod>> {
    list.iter()
        .map(|m| RtMethod::parse(m.trim()).map_err(|e| value(message(&e))))
        .collect()
}

/// `texture_filter=`, as `--texture-filter` takes it.
pub fn texture_filter(name: &str) -> PyResult<TextureFilter> {
    match name {
        "ray-cones" => Ok(TextureFilter::RayCones),
        "none" => Ok(TextureFilter::None),
        _ => Err(value(format!(
            "texture_filter={name:?}: expected 'ray-cones' or 'none'{}",
            did_you_mean(name, &["ray-cones", "none"])
        ))),
    }
}

/// `recon=`, as `--recon` takes it: the GPU the reconstructor runs on (`None`: the
/// CPU). This module is built without the GPU reconstructor, so `gpu` is refused with
/// the library's reason and `auto` runs on the CPU, as the binary built so does.
pub fn recon(name: &str) -> PyResult<Option<std::sync::Arc<GpuContext>>> {
    let names = ReconDevice::ALL.map(|d| d.name());
    let choice: ReconDevice = name.parse().map_err(|_| {
        value(format!(
            "recon={name:?}: expected 'cpu', 'gpu' or 'auto'{}",
            did_you_mean(name, &names)
        ))
    })?;
    device::acquire(choice).map_err(|e| value(format!("recon={name:?}: {}", message(&e))))
}

/// `trace=`, as `--trace` takes it: the GPU the samples are traced on (`None`: the
/// CPU tracer). This module is built without GPU support, so `gpu` is refused with the
/// library's reason and `auto` traces on the CPU, as the binary built so does.
pub fn trace(name: &str) -> PyResult<Option<std::sync::Arc<GpuContext>>> {
    let names = settings::TraceDevice::ALL.map(|d| d.name());
    let choice: settings::TraceDevice = name.parse().map_err(|_| {
        value(format!(
            "trace={name:?}: expected 'cpu', 'gpu' or 'auto'{}",
            did_you_mean(name, &names)
        ))
    })?;
    frameless::gpu::acquire(choice).map_err(|e| value(format!("trace={name:?}: {}", message(&e))))
}

/// `recon=` and `trace=`: the run's devices, as `--recon` and `--trace` give them.
pub fn devices(recon_name: &str, trace_name: &str) -> PyResult<frameless::gpu::Devices> {
    Ok(frameless::gpu::Devices {
        recon: recon(recon_name)?,
        trace: trace(trace_name)?,
    })
}

/// "; did you mean 'x'?" for the known name closest to `name` (at most a third of its
/// letters changed), or nothing.
pub fn did_you_mean(name: &str, known: &[&str]) -> String {
    known
        .iter()
        .map(|k| (edit_distance(name, k), *k))
        .filter(|(d, _)| *d * 3 <= name.chars().count().max(3))
        .min()
        .map_or_else(String::new, |(_, k)| format!("; did you mean '{k}'?"))
}

/// Levenshtein distance, in characters.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diag = row[0];
        row[0] = i + 1;
        for (j, cb) in b.iter().enumerate() {
            let next = (diag + usize::from(ca != *cb))
                .min(row[j] + 1)
                .min(row[j + 1] + 1);
            diag = row[j + 1];
            row[j + 1] = next;
        }
    }
    row[b.len()]
}

/// A whole-number keyword clap bounds on the command line.
pub fn in_range(keyword: &str, v: u64, lo: u64, hi: u64) -> PyResult<()> {
    if (lo..=hi).contains(&v) {
        Ok(())
    } else {
        Err(value(format!("{keyword}={v} is not in {lo}..={hi}")))
    }
}

/// A keyword that must be a finite number, as every time and rate is.
pub fn finite(keyword: &str, v: f64) -> PyResult<f64> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(value(format!("{keyword}={v} is not finite")))
    }
}

/// defaults()
/// --
///
/// The library's defaults of `eval`, `live` and `still`, which the Python signatures
/// repeat (a test holds them equal).
#[pyfunction]
fn defaults(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    let d = PyDict::new(py);
    let e = EvalConfig::new("toycar");
    let eval = PyDict::new(py);
    let names = |ms: &[MethodKind]| ms.iter().map(|m| m.name()).collect::<Vec<_>>();
    eval.set_item("methods", names(&e.methods))?;
    eval.set_item("rates", e.rates.clone())?;
    eval.set_item("start", e.start)?;
    eval.set_item("duration", e.duration)?;
    eval.set_item("size", e.size())?;
    eval.set_item("refresh_hz", e.display.refresh_hz)?;
    eval.set_item("seed", e.quality.seed)?;
    eval.set_item("ideal_spp", e.reference.ideal_spp)?;
    eval.set_item("warmup", e.warmup)?;
    eval.set_item("max_depth", e.quality.max_depth)?;
    eval.set_item("flip_every", e.flip_every)?;
    d.set_item("evaluate", eval)?;
    let l = LiveConfig::new("toycar");
    let live = PyDict::new(py);
    let rt: Vec<&str> = l.methods.iter().map(|m| m.name()).collect();
    live.set_item("methods", rt)?;
    live.set_item("start", l.start)?;
    live.set_item("duration", l.seconds)?;
    live.set_item("warmup", l.warmup)?;
    live.set_item("size", l.size())?;
    live.set_item("refresh_hz", l.display.refresh_hz)?;
    live.set_item("repeat", l.repeat)?;
    live.set_item("seed", l.quality.seed)?;
    live.set_item("ideal_spp", l.reference.ideal_spp)?;
    live.set_item("max_depth", l.quality.max_depth)?;
    d.set_item("live", live)?;
    // `frameless still`'s own defaults; the rest are every command's.
    let still = PyDict::new(py);
    still.set_item("size", settings::SIZE)?;
    still.set_item("seed", settings::SEED)?;
    still.set_item("spp", settings::STILL_SPP)?;
    still.set_item("max_depth", settings::MAX_DEPTH)?;
    d.set_item("still", still)?;
    d.set_item("max_depth_limit", frameless::limits::MAX_DEPTH)?;
    d.set_item("max_ideal_spp", frameless::limits::MAX_IDEAL_SPP)?;
    d.set_item("scenes", frameless::scene::builtin::NAMES.to_vec())?;
    let all: Vec<&str> = MethodKind::ALL.iter().map(|m| m.name()).collect();
    d.set_item("all_methods", all)?;
    let all_rt: Vec<&str> = RtMethod::ALL.iter().map(|m| m.name()).collect();
    d.set_item("all_live_methods", all_rt)?;
    let renamed = PyDict::new(py);
    for (old, new) in frameless::methods::OLD_NAMES {
        renamed.set_item(old, new)?;
    }
    d.set_item("renamed_methods", renamed)?;
    Ok(d)
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(defaults, m)?)
}

/// `--ideal-spp` and `--max-depth` in the ranges the command line takes.
pub fn ideal_spp_and_depth(ideal_spp: u64, max_depth: u64) -> PyResult<()> {
    in_range(
        "ideal_spp",
        ideal_spp,
        1,
        frameless::limits::MAX_IDEAL_SPP as u64,
    )?;
    in_range(
        "max_depth",
        max_depth,
        0,
        frameless::limits::MAX_DEPTH as u64,
    )
}

/// How samples are traced, from the Python keywords, in the ranges the command line
/// takes; a field they do not set at the command line's default.
// The struct update is there for the fields these keywords do not set.
#[allow(clippy::needless_update)]
pub fn quality(seed: u64, max_depth: u64, filter: &str) -> PyResult<settings::QualityGroup> {
    in_range(
        "max_depth",
        max_depth,
        0,
        frameless::limits::MAX_DEPTH as u64,
    )?;
    Ok(settings::QualityGroup {
        seed,
        max_depth: max_depth as u32,
        texture_filter: texture_filter(filter)?,
        ..Default::default()
    })
}

/// The settings groups of a run from the Python keywords, in the ranges the command
/// line takes; each unset field at the command line's default. `cache_dir` is the
/// folder itself (`None`: no cache), as the Python side resolves `--cache-dir` and
/// `--no-cache`.
// The struct updates are there for the fields these keywords do not set: a field a
// group gains takes its default here without a change to this function.
#[allow(clippy::too_many_arguments, clippy::needless_update)]
pub fn groups(
    size: &str,
    refresh_hz: f64,
    seed: u64,
    ideal_spp: u64,
    max_depth: u64,
    filter: &str,
    cache_dir: Option<std::path::PathBuf>,
) -> PyResult<(
    settings::DisplayGroup,
    settings::QualityGroup,
    settings::ReferenceGroup,
)> {
    ideal_spp_and_depth(ideal_spp, max_depth)?;
    let display = settings::DisplayGroup {
        size: size
            .parse()
            .map_err(|e: frameless::limits::LimitError| value(e.to_string()))?,
        refresh_hz: finite("refresh_hz", refresh_hz)?,
        ..Default::default()
    };
    let quality = quality(seed, max_depth, filter)?;
    let mut reference = settings::ReferenceGroup {
        ideal_spp: ideal_spp as u32,
        ..Default::default()
    };
    reference.set_cache(cache_dir);
    Ok((display, quality, reference))
}
