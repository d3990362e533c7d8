//! The outputs of a live evaluation: `frames.csv`, `summary.json`, `summary.md`, the
//! RMS-over-time plot of each method's median run, strips of what the methods showed
//! with FLIP error maps, and `report.html`, built from the same pieces as `eval`'s.

use std::{
    fmt::Write as _,
    path::{Path, PathBuf},
};

use super::{builds::Build, LiveFrameRow, LiveOutput, LiveRow, LiveSummary, Scores};
use crate::{
    evaluation::{
        report::{
            escape, panel_img, plot_lines, split_strip, tagged_strip_names, write_strip_files,
            STYLE,
        },
        EvalError,
    },
    image::read_png_rgb8,
    limits,
    methods::MethodKind,
    output::{self, OutputDir},
};

/// One column of the tables: title, the value of a run's scores, decimals, whether
/// higher is better (`None`: a property, not ranked).
type Column = (
    &'static str,
    fn(&Scores) -> Option<f64>,
    usize,
    Option<bool>,
);

/// Image quality against the ideal, at scan-out.
const QUALITY: [Column; 7] = [
    ("RMS (0–255)", |s| Some(s.rms), 2, Some(false)),
    ("PSNR (dB)", |s| Some(s.psnr), 2, Some(true)),
    ("FLIP", |s| Some(s.flip), 4, Some(false)),
    ("sustained (0–255)", |s| s.sustained, 2, Some(false)),
    ("transient (0–255)", |s| s.transient, 2, Some(false)),
    // Lag counts in it at the scene's speed, as flicker does: shown, not ranked.
    ("instability (0–255)", |s| Some(s.instability), 2, None),
    (
        "age at scan-out (ms)",
        |s| s.age_s.map(|a| a * 1e3),
        1,
        None,
    ),
];

/// What each method got of the machine.
const LIVE: [Column; 7] = [
    (
        "samples/s (M)",
        |s| Some(s.live.samples_per_s * 1e-6),
        2,
        None,
    ),
    ("new images/s", |s| Some(s.live.images_per_s), 1, None),
    (
        "late refreshes",
        |s| Some(s.live.late_refreshes as f64),
        0,
        None,
    ),
    ("machine share", |s| s.live.machine_share, 2, None),
    ("others' share", |s| s.live.others_share, 2, None),
    (
        "load average before",
        |s| s.live.load_average_before,
        2,
        None,
    ),
    (
        "others' load before",
        |s| s.live.others_load_before,
        2,
        None,
    ),
];

/// A cell: the median, and its range over the runs when there are several.
fn cell(row: &LiveRow, f: fn(&Scores) -> Option<f64>, prec: usize) -> String {
    let Some(m) = f(&row.median).filter(|v| v.is_finite()) else {
        return "–".into();
    };
    match (f(&row.min), f(&row.max)) {
        (Some(lo), Some(hi)) if row.runs > 1 => format!("{m:.prec$} ({lo:.prec$}–{hi:.prec$})"),
        _ => format!("{m:.prec$}"),
    }
}

/// The best median of a ranked column.
fn best(s: &LiveSummary, f: fn(&Scores) -> Option<f64>, higher: bool) -> Option<f64> {
    let vals = s
        .results
        .iter()
        .filter_map(|r| f(&r.median))
        .filter(|v| v.is_finite());
    if higher {
        vals.reduce(f64::max)
    } else {
        vals.reduce(f64::min)
    }
}

fn heading(s: &LiveSummary) -> String {
    format!(
        "{} at {}x{}, {} Hz, t = {} s + {} s live (warm-up {} s; {} run{} of each method, \
         alternated; threads for {} of the machine's {} cores; seed {}, ideal {} spp{}; \
         tracer: {}; reconstructor: {}; the view traced {}{})",
        s.scene,
        s.width,
        s.height,
        s.refresh_hz,
        s.start,
        s.seconds,
        s.warmup,
        s.repeat,
        if s.repeat == 1 { "" } else { "s" },
        s.cores,
        s.machine_cores,
        s.seed,
        s.ideal_spp,
        if s.camera_path { ", camera path" } else { "" },
        s.trace,
        s.recon,
        if s.view_ahead {
            "ahead, where the display will look"
        } else {
            "where it is"
        },
        adaptive_note(s),
    )
}

/// The adaptive settings of the runs where they are not the defaults.
fn adaptive_note(s: &LiveSummary) -> String {
    let defaults = crate::realtime::AdaptiveSettings::default().tuning();
    match s.adaptive {
        Some(t) if t != defaults => format!(
            "; adaptive: image budget {}, ring {}× the pixels, splat radius at most {} px{}{}",
            t.image_budget,
            t.ring_factor,
            t.max_radius,
            if t.sampler_reprojection {
                ", the sampler reprojecting"
            } else {
                ""
            },
            if t.late_samples {
                ""
            } else {
                ", a moving view built from the samples in hand when its build began"
            }
        ),
        _ => String::new(),
    }
}

/// Every run's warnings: (method, run, warning).
fn warnings(s: &LiveSummary) -> impl Iterator<Item = (&'static str, usize, &str)> {
    s.runs.iter().flat_map(|r| {
        r.warnings
            .iter()
            .map(move |w| (r.method.name(), r.repeat, w.as_str()))
    })
}

/// The summary as Markdown: image quality and live figures, methods as rows, each cell
/// the median over the runs with its range.
pub fn markdown(s: &LiveSummary) -> String {
    let mut out = format!("# Live evaluation: {}\n\n", heading(s));
    for (title, columns) in [
        (
            "Image quality at scan-out (median over runs, range in brackets)",
            &QUALITY[..],
        ),
        ("What each method got of the machine", &LIVE[..]),
    ] {
        let _ = write!(out, "## {title}\n\n| method |");
        for (name, ..) in columns {
            let _ = write!(out, " {name} |");
        }
        out.push_str("\n|---|");
        out.push_str(&"---:|".repeat(columns.len()));
        out.push('\n');
        for r in &s.results {
            let _ = write!(out, "| {} |", r.method.name());
            for (_, f, prec, _) in columns {
                let _ = write!(out, " {} |", cell(r, *f, *prec));
            }
            out.push('\n');
        }
        out.push('\n');
    }
    let held: Vec<String> = held_back(s)
        .map(|(m, why)| format!("- {m}: {why}."))
        .collect();
    if !held.is_empty() {
        let _ = writeln!(out, "## {HELD_BACK}\n\n{}\n", held.join("\n"));
    }
    let warned: Vec<String> = warnings(s)
        .map(|(m, k, w)| format!("- {m} run {k}: {w}"))
        .collect();
    if !warned.is_empty() {
        let _ = writeln!(out, "## Warnings\n\n{}\n", warned.join("\n"));
    }
    out
}

/// The title of what held each method's new images back.
const HELD_BACK: &str =
    "What held the new images back (each method's median run, its warm-up included)";

/// Each method's image build in its median run, in a sentence: (method, sentence), for
/// the methods whose runs report their builds.
fn held_back(s: &LiveSummary) -> impl Iterator<Item = (&'static str, String)> + '_ {
    s.results.iter().filter_map(|r| {
        let repeat = median_run(s, r);
        let run = s
            .runs
            .iter()
            .find(|run| run.method == r.method && run.repeat == repeat)?;
        Some((r.method.name(), Build::of(run)?.sentence(s.refresh_hz)))
    })
}

/// Write every output as the folder `dir`, replacing what was there only once all are
/// written. Returns the report's path.
pub fn write_all(out: &mut LiveOutput, dir: &Path) -> Result<PathBuf, EvalError> {
    let staging = OutputDir::begin(dir).map_err(|e| EvalError::io(dir, e))?;
    write_into(out, staging.path())?;
    staging.commit().map_err(|e| EvalError::io(dir, e))?;
    Ok(dir.join("report.html"))
}

fn write_into(out: &mut LiveOutput, dir: &Path) -> Result<(), EvalError> {
    let t0 = std::time::Instant::now();
    let write = |name: &str, bytes: &[u8]| -> Result<(), EvalError> {
        let p = dir.join(name);
        output::write_atomic(&p, bytes).map_err(|e| EvalError::io(&p, e))
    };
    write("frames.csv", &frames_csv(&out.frames, dir)?)?;
    write("summary.md", markdown(&out.summary).as_bytes())?;
    let s = &out.summary;
    plot(s, &out.frames, &dir.join("rms.svg"))?;
    let mut strips = Vec::new();
    for st in &out.strips {
        let names = tagged_strip_names("live", st.frame);
        let mut images = vec![st.ideal.as_slice()];
        images.extend(st.shown.iter().map(|(_, rgb)| rgb.as_slice()));
        write_strip_files(dir, &names, &images, (s.width, s.height), true)?;
        let mut labels = vec![MethodKind::Ideal.name()];
        labels.extend(st.shown.iter().map(|(m, _)| m.name()));
        strips.push((st.frame, names, labels));
    }
    out.summary.timing.output_s = t0.elapsed().as_secs_f64();
    let json = serde_json::to_string_pretty(&out.summary).expect("summary serialises");
    write("summary.json", json.as_bytes())?;
    write("report.html", html(&out.summary, &strips).as_bytes())
}

/// The bytes of a data file of `dir`, refused past the data-file limit or when not a
/// regular file.
fn read_data(path: &Path) -> Result<Vec<u8>, EvalError> {
    limits::read_file(path, limits::MAX_DATA_FILE_BYTES).map_err(|e| EvalError::io(path, e))
}

/// Read a live evaluation's `summary.json`.
pub fn read_summary(path: &Path) -> Result<LiveSummary, EvalError> {
    let bad = |why: String| EvalError::Data {
        path: path.to_path_buf(),
        why,
    };
    let s: LiveSummary =
        serde_json::from_slice(&read_data(path)?).map_err(|e| bad(e.to_string()))?;
    limits::check_display(s.width, s.height).map_err(|e| bad(format!("size: {e}")))?;
    Ok(s)
}

/// Read a live evaluation's `frames.csv`.
fn read_frames_csv(path: &Path) -> Result<Vec<LiveFrameRow>, EvalError> {
    let bad = |why: String| EvalError::Data {
        path: path.to_path_buf(),
        why,
    };
    let bytes = read_data(path)?;
    csv::Reader::from_reader(&bytes[..])
        .deserialize()
        .map(|row| row.map_err(|e| bad(e.to_string())))
        .collect()
}

/// Make the plot, the FLIP maps, `summary.md` and `report.html` of the live output
/// folder `dir` again with this version, from its `summary.json`, `frames.csv` and the
/// strips it holds (a strip whose panels are not the summary's methods is left out).
/// Returns the report's path.
pub fn rewrite(dir: &Path) -> Result<PathBuf, EvalError> {
    let s = read_summary(&dir.join("summary.json"))?;
    let frames = read_frames_csv(&dir.join("frames.csv"))?;
    plot(&s, &frames, &dir.join("rms.svg"))?;
    let mut labels = vec![MethodKind::Ideal.name()];
    labels.extend(s.results.iter().map(|r| r.method.name()));
    let mut found: Vec<usize> = std::fs::read_dir(dir)
        .map_err(|e| EvalError::io(dir, e))?
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .filter_map(|n| {
            n.strip_prefix("strip_live_")?
                .strip_suffix(".png")?
                .parse()
                .ok()
        })
        .collect();
    found.sort_unstable();
    let mut strips = Vec::new();
    for frame in found {
        let names = tagged_strip_names("live", frame);
        let p = dir.join(&names.0);
        let (sw, sh, rgb) = read_png_rgb8(&p).map_err(|e| EvalError::io(&p, e))?;
        let Some(panels) =
            split_strip(sw, sh, &rgb, s.width, labels.len()).filter(|_| sh == s.height)
        else {
            continue;
        };
        let images: Vec<&[u8]> = panels.iter().map(Vec::as_slice).collect();
        write_strip_files(dir, &names, &images, (s.width, s.height), false)?;
        strips.push((frame, names, labels.clone()));
    }
    let p = dir.join("summary.md");
    output::write_atomic(&p, markdown(&s).as_bytes()).map_err(|e| EvalError::io(&p, e))?;
    let p = dir.join("report.html");
    output::write_atomic(&p, html(&s, &strips).as_bytes()).map_err(|e| EvalError::io(&p, e))?;
    Ok(p)
}

/// `frames.csv`: one row per method, run and refresh, rounded to what the
/// measurements resolve.
fn frames_csv(frames: &[LiveFrameRow], dir: &Path) -> Result<Vec<u8>, EvalError> {
    let round = |v: f64, d: i32| (v * 10f64.powi(d)).round() / 10f64.powi(d);
    let mut w = csv::Writer::from_writer(Vec::new());
    let bad = |why: String| EvalError::Data {
        path: dir.join("frames.csv"),
        why,
    };
    for f in frames {
        w.serialize(LiveFrameRow {
            time: round(f.time, 6),
            shown_time: f.shown_time.map(|v| round(v, 6)),
            rms: round(f.rms, 4),
            psnr: round(f.psnr, 4),
            flip: round(f.flip, 6),
            instability: f.instability.map(|v| round(v, 4)),
            age_s: f.age_s.map(|v| round(v, 6)),
            sustained: f.sustained.map(|v| round(v, 4)),
            transient: f.transient.map(|v| round(v, 4)),
            ..f.clone()
        })
        .map_err(|e| bad(e.to_string()))?;
    }
    w.into_inner().map_err(|e| bad(e.to_string()))
}

/// RMS over the window, one line per method: its median run by mean RMS.
fn plot(s: &LiveSummary, frames: &[LiveFrameRow], path: &Path) -> Result<(), EvalError> {
    let series: Vec<(String, Vec<(i32, f64)>)> = s
        .results
        .iter()
        .map(|r| {
            let repeat = median_run(s, r);
            let pts = frames
                .iter()
                .filter(|f| f.method == r.method && f.repeat == repeat)
                .map(|f| (f.frame as i32, f.rms))
                .collect();
            (r.method.name().to_string(), pts)
        })
        .collect();
    let n = (s.seconds * s.refresh_hz + 1e-9).floor() as i32;
    let caption = format!("RMS error vs. ideal at scan-out, {} live", s.scene);
    let x_desc = format!("refresh ({} Hz), median run of each method", s.refresh_hz);
    plot_lines(path, &caption, &x_desc, (n - 1).max(1), &series)
}

/// The run of `row`'s method whose mean RMS is the median (the lower middle one).
fn median_run(s: &LiveSummary, row: &LiveRow) -> usize {
    let mut runs: Vec<_> = s.runs.iter().filter(|r| r.method == row.method).collect();
    runs.sort_by(|a, b| a.scores.rms.total_cmp(&b.scores.rms));
    runs.get(runs.len().saturating_sub(1) / 2)
        .map_or(1, |r| r.repeat)
}

type StripEntry = (usize, (String, String), Vec<&'static str>);

fn html(s: &LiveSummary, strips: &[StripEntry]) -> String {
    let mut h = format!(
        "<!doctype html><html lang=\"en\"><head><meta charset=\"utf-8\">\
         <meta name=\"viewport\" content=\"width=device-width,initial-scale=1\">\
         <title>frameless live evaluation: {}</title><style>{STYLE}</style></head><body>\
         <h1>Live evaluation: {}</h1><p>{}.</p><p class=\"note\">Every method ran in real \
         time on this machine, through the same pipeline as <code>frameless view</code>; \
         each refresh is scored against the ideal image at the scene time it was scanned \
         out. Cells: the median over the runs, with the least and the largest in \
         brackets. Bold: the best median.</p>",
        escape(&s.scene),
        escape(&s.scene),
        escape(&heading(s))
    );
    for (title, columns) in [
        ("Image quality at scan-out", &QUALITY[..]),
        ("What each method got of the machine", &LIVE[..]),
    ] {
        table(&mut h, s, title, columns);
    }
    let held: Vec<String> = held_back(s)
        .map(|(m, why)| format!("<li>{m}: {}.</li>", escape(&why)))
        .collect();
    if !held.is_empty() {
        let _ = write!(
            h,
            "<h2>{}</h2><ul>{}</ul>",
            escape(HELD_BACK),
            held.concat()
        );
    }
    let warned: Vec<String> = warnings(s)
        .map(|(m, k, w)| format!("<li>{m} run {k}: {}</li>", escape(w)))
        .collect();
    if !warned.is_empty() {
        let _ = write!(h, "<h2>Warnings</h2><ul>{}</ul>", warned.concat());
    }
    h.push_str(
        "<h2>RMS error over time</h2><figure><img class=\"plot\" src=\"rms.svg\" \
         alt=\"RMS error of each method's median run over the window\"></figure>",
    );
    strips_html(&mut h, s, strips);
    let t = &s.timing;
    let _ = writeln!(
        h,
        "<h2>Cost</h2><p>Ideal images {:.1} s ({} from the cache); live runs {:.1} s; \
         scoring {:.1} s; output {:.1} s.</p><h2>Data</h2><p><a href=\"frames.csv\">\
         frames.csv</a> (every refresh of every run); <a href=\"summary.json\">summary.json\
         </a> (every run, the medians and ranges); <a href=\"summary.md\">summary.md</a> \
         (the tables as Markdown).</p></body></html>",
        t.ideal_s, t.ideal_cache_hits, t.live_s, t.metrics_s, t.output_s
    );
    h
}

fn table(h: &mut String, s: &LiveSummary, title: &str, columns: &[Column]) {
    let _ = write!(h, "<h2>{title}</h2><table><tr><th>method</th>");
    for (name, ..) in columns {
        let _ = write!(h, "<th>{}</th>", escape(name));
    }
    h.push_str("</tr>");
    let bests: Vec<Option<f64>> = columns
        .iter()
        .map(|(_, f, _, higher)| higher.and_then(|hi| best(s, *f, hi)))
        .collect();
    for r in &s.results {
        let _ = write!(h, "<tr><td>{}</td>", r.method.name());
        for ((_, f, prec, _), b) in columns.iter().zip(&bests) {
            let is_best = b.is_some() && f(&r.median) == *b;
            let class = if is_best { " class=\"best\"" } else { "" };
            let _ = write!(h, "<td{class}>{}</td>", cell(r, *f, *prec));
        }
        h.push_str("</tr>");
    }
    h.push_str("</table>");
}

fn strips_html(h: &mut String, s: &LiveSummary, strips: &[StripEntry]) {
    h.push_str(
        "<h2>Images</h2><p class=\"note\">What each method's median run displayed at a few \
         refreshes, beside the ideal image of the scan-out time, and below each its FLIP \
         error map against the ideal (black: no visible difference, through red, to \
         yellow: the largest).</p>",
    );
    for (frame, (image, flip), labels) in strips {
        let _ = write!(
            h,
            "<h3>Refresh {frame} (scanned out at t = {:.3} s)</h3><div class=\"panels\">",
            s.start + *frame as f64 / s.refresh_hz
        );
        for (i, label) in labels.iter().enumerate() {
            let crop = |file: &str, what: &str| {
                panel_img(file, i, (s.width, s.height), &format!("{what}, {label}"))
            };
            let _ = write!(
                h,
                "<figure class=\"panel\"><figcaption><b>{}</b></figcaption>{}",
                escape(label),
                crop(image, "image")
            );
            if i > 0 {
                h.push_str(&crop(flip, "FLIP error map"));
            }
            h.push_str("</figure>");
        }
        h.push_str("</div>");
    }
}
