//! Paper Table 1 and Figure 8 on the BART kitchen: the three animations, the
//! paper's numbers for comparison, and the combined outputs (one `summary.json` with an
//! evaluation summary per animation, a Markdown table beside the paper's, an HTML index).
//!
//! The animations are data, not code paths: each is a time window of the kitchen with
//! either the scene's own camera or a committed camera-path file (compiled in, so the
//! command needs only the user's BART folder).

use std::{
    fmt::Write as _,
    path::{Path, PathBuf},
};

use serde::{Deserialize, Serialize};

use super::{report::rate_label, EvalError, EvalOutput, Summary};
use crate::{methods::MethodKind, output::OutputDir};

/// One of the paper's animations, as evaluated here.
#[derive(Clone, Copy, Debug)]
pub struct Animation {
    /// Name used in tables and output folders.
    pub name: &'static str,
    /// What it shows and why this window.
    pub description: &'static str,
    /// Start of the evaluated window (scene seconds; a warm-up precedes it).
    pub start: f64,
    /// Length of the window (seconds).
    pub duration: f64,
    /// Seconds every method runs before the window.
    pub warmup: f64,
    /// Camera-path CSV text overriding the scene camera (`None`: the kitchen's own).
    pub camera_path: Option<&'static str>,
    /// File name of that camera path under `assets/camera_paths/`.
    pub camera_path_file: Option<&'static str>,
}

/// The paper's three animations on the kitchen, in the paper's column order, and a
/// still view (not in the paper).
pub const ANIMATIONS: [Animation; 4] = [
    Animation {
        name: "interactive",
        description: "a person-like walk with three fast turns (85° in 0.25 s, 125° in 0.4 s, \
                      95° in 0.3 s) and hand jitter, written to mimic a viewer recording \
                      (assets/camera_paths/make_kitchen_interactive.py); t = 5–8 s while the toy car drives",
        start: 5.0,
        duration: 3.0,
        warmup: 1.0,
        camera_path: Some(include_str!("../../assets/camera_paths/kitchen_interactive.csv")),
        camera_path_file: Some("kitchen_interactive.csv"),
    },
    Animation {
        name: "bart",
        description: "the kitchen's own camera animation, t = 4.5–7.5 s: the end of the descent \
                      to floor level, a 75° turn in 0.5 s, and the toy car driving",
        start: 4.5,
        duration: 3.0,
        warmup: 1.0,
        camera_path: None,
        camera_path_file: None,
    },
    Animation {
        name: "toycar",
        description: "a fixed close-up at floor level (assets/camera_paths/kitchen_toycar.csv); \
                      the toy car enters from the left, turns and leaves on the right, t = 9.5–12.5 s",
        start: 9.5,
        duration: 3.0,
        warmup: 1.0,
        camera_path: Some(include_str!("../../assets/camera_paths/kitchen_toycar.csv")),
        camera_path_file: Some("kitchen_toycar.csv"),
    },
    Animation {
        name: "still",
        description: "a fixed view (assets/camera_paths/kitchen_still.csv) of a door, a \
                      cabinet, tiles and textured walls where nothing moves: renders of it \
                      at every 0.1 s of t = 0–9 s are identical; t = 5–8 s after a 4 s \
                      warm-up, what a viewer sees whenever the user stops moving",
        start: 5.0,
        duration: 3.0,
        warmup: 4.0,
        camera_path: Some(include_str!("../../assets/camera_paths/kitchen_still.csv")),
        camera_path_file: Some("kitchen_still.csv"),
    },
];

/// Look an animation up by name.
pub fn animation(name: &str) -> Result<&'static Animation, EvalError> {
    ANIMATIONS.iter().find(|a| a.name == name).ok_or_else(|| {
        let names: Vec<_> = ANIMATIONS.iter().map(|a| a.name).collect();
        EvalError::UnknownAnimation {
            name: name.into(),
            expected: names.join(", "),
        }
    })
}

/// The methods of the table, the Fig. 8 ablation and today's practice (TAA
/// and the late warps), in display order.
pub const METHODS: [MethodKind; 11] = [
    MethodKind::Framed60Hz,
    MethodKind::FramedFull,
    MethodKind::TraditionalFrameless,
    MethodKind::Adaptive,
    MethodKind::AdaptivePaper,
    MethodKind::AdaptiveNoReprojection,
    MethodKind::FullRes60Hz,
    MethodKind::PointTracking,
    MethodKind::Taa,
    MethodKind::LateWarp,
    MethodKind::TaaWarp,
];

/// The paper's Table 1 (RMS, 0–255): `(our method, animation, rate, value)`; the
/// paper's adaptive method is our `adaptive-paper`.
/// The paper's "400K 60 Hz" and "400K Full Res" rows are our `framed-60hz` and
/// `framed-full` at each rate; "Full Res 60 Hz" runs at its own 10× budget.
pub const PAPER: [(MethodKind, &str, f64, f64); 35] = {
    use MethodKind::*;
    const K: f64 = 1000.0;
    [
        (Framed60Hz, "interactive", 100.0 * K, 92.7),
        (Framed60Hz, "interactive", 400.0 * K, 71.8),
        (Framed60Hz, "interactive", 800.0 * K, 60.9),
        (Framed60Hz, "bart", 400.0 * K, 112.0),
        (Framed60Hz, "bart", 800.0 * K, 100.0),
        (Framed60Hz, "toycar", 400.0 * K, 47.0),
        (Framed60Hz, "toycar", 800.0 * K, 42.8),
        (FramedFull, "interactive", 100.0 * K, 110.0),
        (FramedFull, "interactive", 400.0 * K, 72.6),
        (FramedFull, "interactive", 800.0 * K, 60.4),
        (FramedFull, "bart", 400.0 * K, 127.0),
        (FramedFull, "bart", 800.0 * K, 112.0),
        (FramedFull, "toycar", 400.0 * K, 43.8),
        (FramedFull, "toycar", 800.0 * K, 38.9),
        (TraditionalFrameless, "interactive", 100.0 * K, 80.8),
        (TraditionalFrameless, "interactive", 400.0 * K, 48.8),
        (TraditionalFrameless, "interactive", 800.0 * K, 39.3),
        (TraditionalFrameless, "bart", 400.0 * K, 92.3),
        (TraditionalFrameless, "bart", 800.0 * K, 74.8),
        (TraditionalFrameless, "toycar", 400.0 * K, 35.3),
        (TraditionalFrameless, "toycar", 800.0 * K, 32.5),
        (AdaptivePaper, "interactive", 100.0 * K, 34.4),
        (AdaptivePaper, "interactive", 400.0 * K, 24.1),
        (AdaptivePaper, "interactive", 800.0 * K, 23.6),
        (AdaptivePaper, "bart", 400.0 * K, 50.1),
        (AdaptivePaper, "bart", 800.0 * K, 51.9),
        (AdaptivePaper, "toycar", 400.0 * K, 20.4),
        (AdaptivePaper, "toycar", 800.0 * K, 18.5),
        (FullRes60Hz, "interactive", 100.0 * K, 28.0),
        (FullRes60Hz, "interactive", 400.0 * K, 28.0),
        (FullRes60Hz, "interactive", 800.0 * K, 28.0),
        (FullRes60Hz, "bart", 400.0 * K, 30.7),
        (FullRes60Hz, "bart", 800.0 * K, 30.7),
        (FullRes60Hz, "toycar", 400.0 * K, 29.4),
        (FullRes60Hz, "toycar", 800.0 * K, 29.4),
    ]
};

/// The paper's value for a cell, if it reported one.
pub fn paper_value(method: MethodKind, animation: &str, rate: f64) -> Option<f64> {
    PAPER
        .iter()
        .find(|(m, a, r, _)| *m == method && *a == animation && *r == rate)
        .map(|x| x.3)
}

/// One animation's evaluation inside the combined summary.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct AnimationResult {
    /// Animation name.
    pub name: String,
    /// What it shows.
    pub description: String,
    /// Camera-path file under `assets/camera_paths/`, if any.
    pub camera_path: Option<String>,
    /// The evaluation summary, as `frameless eval` writes it.
    pub summary: Summary,
}

/// The combined `summary.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct TableSummary {
    /// One entry per animation, in the order run.
    pub animations: Vec<AnimationResult>,
}

fn cell(s: &Summary, method: MethodKind, rate: f64) -> Option<&super::ResultRow> {
    s.results
        .iter()
        .find(|r| r.method == method && (r.rate == rate || method.rate_independent()))
}

/// The measured table beside the paper's: one Markdown table per metric, rows are
/// methods, columns animation × rate; RMS cells read `ours (paper)`.
pub fn markdown(t: &TableSummary) -> String {
    let cols = columns(t);
    let mut methods: Vec<MethodKind> = Vec::new();
    for a in &t.animations {
        for r in &a.summary.results {
            if !methods.contains(&r.method) {
                methods.push(r.method);
            }
        }
    }
    let mut out = String::new();
    for metric in METRICS {
        metric_table(&mut out, &metric, &cols, &methods);
    }
    out
}

/// A column of the table: an animation at one rate, with the animation's summary.
struct Column<'a> {
    animation: &'a str,
    rate: f64,
    summary: &'a Summary,
}

/// The columns, animation × rate, in the table's order.
fn columns(t: &TableSummary) -> Vec<Column<'_>> {
    let mut cols = Vec::new();
    for a in &t.animations {
        let mut rates: Vec<f64> = a.summary.results.iter().map(|r| r.rate).collect();
        rates.sort_by(f64::total_cmp);
        rates.dedup();
        // The rate-independent method's own budget is not a column.
        rates.retain(|&r| {
            a.summary
                .results
                .iter()
                .any(|x| x.rate == r && !x.method.rate_independent())
        });
        for rate in rates {
            cols.push(Column {
                animation: &a.name,
                rate,
                summary: &a.summary,
            });
        }
    }
    cols
}

/// One metric of the Markdown table.
struct Metric {
    title: &'static str,
    /// The row's value.
    value: fn(&super::ResultRow) -> f64,
    decimals: usize,
    /// Whether the paper's value is shown beside ours.
    with_paper: bool,
}

const METRICS: [Metric; 5] = [
    Metric {
        title: "Mean RMS error, 0–255 (paper's in parentheses)",
        value: |r| r.rms_mean,
        decimals: 1,
        with_paper: true,
    },
    Metric {
        title: "Mean FLIP (the paper reports none)",
        value: |r| r.flip_mean,
        decimals: 3,
        with_paper: false,
    },
    Metric {
        title: "Sustained error, 0–255 (display and ideal averaged over 100 ms, then compared: lag, smear)",
        value: |r| r.sustained_mean.unwrap_or(f64::NAN),
        decimals: 2,
        with_paper: false,
    },
    Metric {
        title: "Transient error, 0–255 (the error's fluctuation within 100 ms: flicker, dust)",
        value: |r| r.transient_mean.unwrap_or(f64::NAN),
        decimals: 2,
        with_paper: false,
    },
    Metric {
        title: "Instability, 0–255 (change of the error per refresh: lag at the scene's speed, and flicker)",
        value: |r| r.instability_mean,
        decimals: 2,
        with_paper: false,
    },
];

/// Append the table of `metric`: a row per method, a cell per column.
fn metric_table(out: &mut String, metric: &Metric, cols: &[Column<'_>], methods: &[MethodKind]) {
    let _ = writeln!(out, "### {}\n", metric.title);
    out.push_str("| method |");
    for c in cols {
        let _ = write!(out, " {} {} |", c.animation, rate_label(c.rate));
    }
    out.push_str("\n|---|");
    for _ in cols {
        out.push_str("---:|");
    }
    out.push('\n');
    for m in methods {
        let _ = write!(out, "| {m} |");
        for c in cols {
            match cell(c.summary, *m, c.rate) {
                // Not measured by the version that wrote the summary.
                Some(x) if (metric.value)(x).is_nan() => out.push_str(" – |"),
                Some(x) => {
                    let _ = write!(out, " {:.*}", metric.decimals, (metric.value)(x));
                    if metric.with_paper {
                        if let Some(p) = paper_value(*m, c.animation, c.rate) {
                            let _ = write!(out, " ({p})");
                        }
                    }
                    out.push_str(" |");
                }
                None => out.push_str(" – |"),
            }
        }
        out.push('\n');
    }
    out.push('\n');
}

/// How adaptive stands in the table, one line per animation and rate: its RMS against
/// traditional frameless's (the ratio it aims to keep at or below 0.5), TAA's and
/// full-resolution 60 Hz's.
pub fn targets(t: &TableSummary) -> String {
    let mut out = String::new();
    for a in &t.animations {
        let s = &a.summary;
        let mut rates: Vec<f64> = s
            .results
            .iter()
            .filter(|r| r.method == MethodKind::Adaptive)
            .map(|r| r.rate)
            .collect();
        rates.sort_by(f64::total_cmp);
        for r in rates {
            let get = |m: MethodKind| cell(s, m, r).map(|x| x.rms_mean);
            let Some(ad) = get(MethodKind::Adaptive) else {
                continue;
            };
            let mut line = format!("- {} {}: adaptive RMS {ad:.1}", a.name, rate_label(r));
            if let Some(tf) = get(MethodKind::TraditionalFrameless) {
                let _ = write!(
                    line,
                    "; ÷ traditional frameless {tf:.1} = {:.2} (target ≤ 0.5)",
                    ad / tf
                );
            }
            if let Some(taa) = get(MethodKind::Taa) {
                let _ = write!(
                    line,
                    "; TAA {taa:.1} ({})",
                    if ad < taa {
                        "adaptive ahead"
                    } else {
                        "TAA ahead"
                    }
                );
            }
            if let Some(fr) = get(MethodKind::FullRes60Hz) {
                let _ = write!(
                    line,
                    "; full-res-60hz {fr:.1} ({})",
                    if ad <= fr {
                        "adaptive no worse"
                    } else {
                        "full-res better"
                    }
                );
            }
            out.push_str(&line);
            out.push('\n');
        }
    }
    out
}

/// Where the table's samples were traced and adaptive's images reconstructed, from
/// its animations' summaries: one line, each animation named where they differ.
fn devices(t: &TableSummary) -> String {
    let words = |s: &Summary| format!("Tracer: {}; reconstructor: {}", s.trace, s.recon);
    let all: Vec<String> = t.animations.iter().map(|a| words(&a.summary)).collect();
    match all.first() {
        Some(first) if all.iter().all(|w| w == first) => first.clone(),
        _ => t
            .animations
            .iter()
            .zip(&all)
            .map(|(a, w)| format!("{}: {w}", a.name))
            .collect::<Vec<_>>()
            .join(". "),
    }
}

/// The HTML index: the table and each animation's report, plots and strips.
pub fn html(t: &TableSummary, cost: &str) -> String {
    let mut h = String::from(
        "<!doctype html><html><head><meta charset=\"utf-8\"><title>frameless: Table 1 on the BART kitchen</title>\
         <style>body{font-family:system-ui,sans-serif;max-width:1400px;margin:2em auto;padding:0 1.5em}table{border-collapse:collapse}\
         td,th{border:1px solid #ccc;padding:2px 6px;text-align:right}img{max-width:100%}</style></head><body>\
         <h1>Paper Table 1 and Fig. 8 on the BART kitchen</h1>",
    );
    let _ = write!(h, "<p>{}</p>", escape(&devices(t)));
    let md = markdown(t);
    let mut in_table = false;
    for line in md.lines() {
        if let Some(title) = line.strip_prefix("### ") {
            let _ = write!(h, "<h2>{}</h2>", escape(title));
        } else if line.starts_with("|---") {
        } else if line.starts_with('|') {
            if !in_table {
                h.push_str("<table>");
                in_table = true;
            }
            h.push_str("<tr>");
            for c in line.trim_matches('|').split('|') {
                let _ = write!(h, "<td>{}</td>", escape(c.trim()));
            }
            h.push_str("</tr>");
        } else if in_table {
            h.push_str("</table>");
            in_table = false;
        }
    }
    if in_table {
        h.push_str("</table>");
    }
    let _ = write!(h, "<h2>Targets</h2><pre>{}</pre>", escape(&targets(t)));
    for a in &t.animations {
        let _ = write!(
            h,
            "<h2>{0}</h2><p>{1}. Full report: <a href=\"{0}/report.html\">{0}/report.html</a>.</p>",
            escape(&a.name),
            escape(&a.description)
        );
        let mut rates: Vec<f64> = a.summary.results.iter().map(|r| r.rate).collect();
        rates.sort_by(f64::total_cmp);
        rates.dedup();
        for r in rates {
            let p = format!("{}/rms_{}.svg", a.name, rate_label(r));
            let _ = write!(
                h,
                "<img src=\"{p}\" alt=\"RMS over time, {}\">",
                rate_label(r)
            );
        }
    }
    let _ = write!(h, "<h2>Cost</h2><p>{}</p></body></html>", escape(cost));
    h
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// Table 1's output folder under construction: each animation's evaluation outputs
/// in a sub-folder as it finishes, then the combined files. Everything is written into a
/// temporary sibling of the target, which replaces the target only in
/// [`Table1Output::finish`], so the target holds one whole run (this one or the
/// previous) and never a mix of animations from two runs.
pub struct Table1Output {
    staging: OutputDir,
}

impl Table1Output {
    /// Start the outputs that will replace the folder `dir`.
    pub fn begin(dir: &Path) -> Result<Self, EvalError> {
        Ok(Self {
            staging: OutputDir::begin(dir).map_err(|e| EvalError::io(dir, e))?,
        })
    }

    /// Write one animation's evaluation outputs (see [`super::report::write_all`]) into
    /// the sub-folder `name`.
    pub fn write_animation(&self, name: &str, out: &mut EvalOutput) -> Result<(), EvalError> {
        let dir = self.staging.path().join(name);
        // An animation named twice overwrites its first folder, as it always has.
        std::fs::create_dir_all(&dir).map_err(|e| EvalError::io(&dir, e))?;
        super::report::write_into(out, &dir)
    }

    /// Write the combined outputs and put the whole folder in place; returns the
    /// combined report's path.
    pub fn finish(self, t: &TableSummary, cost: &str) -> Result<PathBuf, EvalError> {
        write_combined(t, self.staging.path(), cost)?;
        let dir = self.staging.target().to_path_buf();
        self.staging.commit().map_err(|e| EvalError::io(&dir, e))?;
        Ok(dir.join("report.html"))
    }
}

/// Write the combined outputs into the existing folder `dir` (beside the
/// per-animation folders).
fn write_combined(t: &TableSummary, dir: &Path, cost: &str) -> Result<(), EvalError> {
    let io = EvalError::io;
    let write = |name: &str, text: &str| -> Result<(), EvalError> {
        let p = dir.join(name);
        std::fs::write(&p, text).map_err(|e| io(&p, e))
    };
    let mut md = format!("{}\n\n", devices(t));
    md.push_str(&markdown(t));
    md.push_str("### Targets\n\n");
    md.push_str(&targets(t));
    write("table.md", &md)?;
    write("report.html", &html(t, cost))?;
    write(
        "summary.json",
        // Numbers and strings always serialise.
        &serde_json::to_string_pretty(t).expect("table summary serialises"),
    )?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::CameraPath;

    /// The committed Table 1 (written before the devices were recorded: the CPU's).
    fn committed() -> TableSummary {
        let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("docs/results/table1/summary.json");
        serde_json::from_str(&std::fs::read_to_string(p).expect("committed table"))
            .expect("reads as a table summary")
    }

    /// The combined table names its tracer and reconstructor once where every
    /// animation ran on the same, and each animation's where they differ.
    #[test]
    fn the_table_names_its_devices() {
        let mut t = committed();
        assert_eq!(devices(&t), "Tracer: cpu; reconstructor: cpu");
        assert!(html(&t, "").contains("<p>Tracer: cpu; reconstructor: cpu</p>"));
        t.animations[1].summary.trace = crate::gpu::DeviceUsed {
            device: "gpu".into(),
            adapter: Some("an adapter".into()),
        };
        let d = devices(&t);
        let second = format!(
            "{}: Tracer: gpu (an adapter); reconstructor: cpu",
            t.animations[1].name
        );
        assert!(d.contains(&second), "{d}");
        let first = format!("{}: Tracer: cpu; reconstructor: cpu", t.animations[0].name);
        assert!(d.starts_with(&first), "{d}");
    }

    #[test]
    fn committed_camera_paths_parse() {
        for a in ANIMATIONS {
            if let Some(text) = a.camera_path {
                let p = CameraPath::parse(a.camera_path_file.unwrap(), text).unwrap();
                // The path must cover the window and its warm-up.
                let c0 = p.at((a.start - 1.0) as f32);
                let c1 = p.at((a.start + a.duration) as f32);
                assert!(c0.eye.is_finite() && c1.eye.is_finite());
            }
        }
    }

    #[test]
    fn animations_are_known_and_unique() {
        assert!(animation("bart").is_ok());
        assert!(animation("nope")
            .unwrap_err()
            .to_string()
            .contains("interactive, bart, toycar"));
        for m in METHODS {
            assert_eq!(MethodKind::parse(m.name()), Ok(m));
        }
        // Every paper row names one of our animations.
        for (_, a, _, _) in PAPER {
            assert!(animation(a).is_ok(), "{a}");
        }
    }
}
