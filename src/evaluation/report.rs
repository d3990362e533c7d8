//! Evaluation outputs: `frames.csv`, `summary.json`, `summary.md` (paper Table 1
//! shape), RMS-over-time plots (paper Fig. 8), image strips with FLIP error maps,
//! optional linear OpenEXR images of the strip frames, and `report.html`, which opens
//! from disk and links only files that are there. [`rewrite`] makes the plots, maps
//! and report again from an output folder's `summary.json`, `frames.csv` and strips.

use std::{
    fmt::Write as _,
    path::{Path, PathBuf},
};

use plotters::prelude::*;

use super::{metrics, style, verdict, video_metric, EvalError, EvalOutput, FrameRow, Summary};
pub use crate::clock::{parse_rate, rate_label};
use crate::{
    image::{read_png_rgb8, write_png_indexed, write_png_rgb8},
    limits,
    methods::MethodKind,
    output::{self, OutputDir},
};

/// A table of one metric: title, the value of a row, decimals.
type Metric = (&'static str, fn(&super::ResultRow) -> f64, usize);

/// The tables of the errors that [`super::temporal`] tells apart, and of instability.
pub const SUSTAINED_TITLE: &str =
    "Sustained error (0–255: display and ideal each averaged over 100 ms, then compared; lag and smear; lower is better)";
/// See [`SUSTAINED_TITLE`].
pub const TRANSIENT_TITLE: &str =
    "Transient error (0–255: the error's fluctuation within those 100 ms; flicker and dust; lower is better)";
/// See [`SUSTAINED_TITLE`].
pub const INSTABILITY_TITLE: &str =
    "Instability (0–255: change of the error from one refresh to the next; lag counts in it at the rate the scene moves, as flicker does)";

/// The report's definitions of the temporal columns, above its tables.
const TEMPORAL_NOTE: &str = "<p class=\"note\">Sustained and transient errors judge the \
    error over the 100 ms ending at each refresh (6 refreshes at 60 Hz), about how long the \
    eye integrates light. <b>Sustained</b>: the displayed images averaged over those \
    refreshes against the ideal images averaged over the same, as RMS on 0–255; a display \
    that shows the scene late or smeared keeps its error from refresh to refresh, so it \
    stays here. <b>Transient</b>: what the averaging removed, the RMS of each refresh's \
    error about that average; flicker and pixel dust that change every refresh are here. \
    The squares of the two add up to the mean squared RMS error of the 100 ms. A run's first \
    refreshes, before a full 100 ms, have neither. <b>Instability</b> is the mean absolute \
    change of the error between consecutive refreshes: a display that freezes while the \
    scene moves scores the scene's own change per refresh, however far behind it falls, \
    so a low value does not mean a stable picture; it is shown, not ranked.</p>";

/// A row's mean sustained error (NaN: not measured, shown as a dash).
fn sustained(r: &super::ResultRow) -> f64 {
    r.sustained_mean.unwrap_or(f64::NAN)
}

/// A row's mean transient error (NaN: not measured, shown as a dash).
fn transient(r: &super::ResultRow) -> f64 {
    r.transient_mean.unwrap_or(f64::NAN)
}

fn methods_in_order(s: &Summary) -> Vec<MethodKind> {
    let mut m: Vec<MethodKind> = Vec::new();
    for r in &s.results {
        if !m.contains(&r.method) {
            m.push(r.method);
        }
    }
    m
}

fn rates_in_order(s: &Summary) -> Vec<f64> {
    let mut v: Vec<f64> = Vec::new();
    for r in &s.results {
        if !v.contains(&r.rate) {
            v.push(r.rate);
        }
    }
    v
}

/// The summary as Markdown tables (RMS, FLIP, age), methods × rates.
pub fn markdown(s: &Summary) -> String {
    let methods = methods_in_order(s);
    let rates = rates_in_order(s);
    let mut out = String::new();
    let _ =
        writeln!(
        out,
        "# Evaluation: {} at {}x{}, {} Hz, t = {} s + {} s (warm-up {} s, seed {}, ideal {} spp)\n",
        s.scene, s.width, s.height, s.refresh_hz, s.start, s.duration, s.warmup, s.seed, s.ideal_spp
    );
    let _ = writeln!(out, "Reconstructor: {}\n", s.recon);
    let _ = writeln!(out, "Tracer: {}\n", tracer_words(s));
    let tables: [Metric; 7] = [
        ("Mean RMS error (0–255, lower is better)", |r| r.rms_mean, 1),
        ("Mean PSNR (dB, higher is better)", |r| r.psnr_mean, 2),
        ("Mean FLIP (lower is better)", |r| r.flip_mean, 4),
        (SUSTAINED_TITLE, sustained, 2),
        (TRANSIENT_TITLE, transient, 2),
        (INSTABILITY_TITLE, |r| r.instability_mean, 2),
        ("Mean information age (ms)", |r| r.age_mean_s * 1e3, 1),
    ];
    for (title, f, prec) in tables {
        let _ = writeln!(out, "## {title}\n");
        let _ = write!(out, "| method |");
        for r in &rates {
            let _ = write!(out, " {} |", rate_label(*r));
        }
        let _ = write!(out, "\n|---|");
        for _ in &rates {
            let _ = write!(out, "---:|");
        }
        out.push('\n');
        for m in &methods {
            let _ = write!(out, "| {m} |");
            for r in &rates {
                match s.results.iter().find(|x| &x.method == m && x.rate == *r) {
                    Some(x) if f(x).is_finite() => {
                        let _ = write!(out, " {:.*} |", prec, f(x));
                    }
                    _ => out.push_str(" – |"),
                }
            }
            out.push('\n');
        }
        out.push('\n');
    }
    out
}

/// `frames.csv`: one row per method, rate column and frame, the columns named as
/// [`FrameRow`]'s fields; values are rounded to what the measurements resolve, and a
/// metric not computed on a frame is an empty field.
pub fn frames_csv(frames: &[FrameRow]) -> Result<Vec<u8>, csv::Error> {
    let round = |v: f64, decimals: i32| {
        let scale = 10f64.powi(decimals);
        (v * scale).round() / scale
    };
    let mut w = csv::Writer::from_writer(Vec::new());
    for f in frames {
        w.serialize(FrameRow {
            time: round(f.time, 6),
            rms: round(f.rms, 4),
            psnr: round(f.psnr, 4),
            flip: f.flip.map(|v| round(v, 6)),
            instability: f.instability.map(|v| round(v, 4)),
            age_s: round(f.age_s, 6),
            sustained: f.sustained.map(|v| round(v, 4)),
            transient: f.transient.map(|v| round(v, 4)),
            ..f.clone()
        })?;
    }
    w.into_inner().map_err(|e| csv::Error::from(e.into_error()))
}

/// Read a `frames.csv` (also one written before `flicker` was renamed `instability`).
pub fn read_frames_csv(path: &Path) -> Result<Vec<FrameRow>, EvalError> {
    let bad = |why: String| EvalError::Data {
        path: path.to_path_buf(),
        why,
    };
    let bytes =
        limits::read_file(path, limits::MAX_DATA_FILE_BYTES).map_err(|e| EvalError::io(path, e))?;
    let mut reader = csv::Reader::from_reader(&bytes[..]);
    reader
        .deserialize()
        .map(|row| row.map_err(|e| bad(e.to_string())))
        .collect()
}

/// Read an evaluation's `summary.json` (also one written by earlier versions).
pub fn read_summary(path: &Path) -> Result<Summary, EvalError> {
    let bad = |why: String| EvalError::Data {
        path: path.to_path_buf(),
        why,
    };
    let text =
        limits::read_text(path, limits::MAX_DATA_FILE_BYTES).map_err(|e| EvalError::io(path, e))?;
    serde_json::from_str(&text).map_err(|e| bad(e.to_string()))
}

/// `$draw` with `$mark` bound to a function making `$look`'s mark at a point (each kind
/// of mark is a type of its own, so the choice is made around the drawing, not inside
/// it).
macro_rules! with_mark {
    ($look:expr, |$mark:ident| $draw:expr) => {{
        let (fill, line) = ($look.colour.filled(), $look.colour.stroke_width(2));
        match $look.marker {
            style::Marker::Circle => {
                let $mark = |at| Circle::new(at, 4, fill);
                $draw
            }
            style::Marker::Triangle => {
                let $mark = |at| TriangleMarker::new(at, 5, fill);
                $draw
            }
            style::Marker::Square => {
                let $mark = |at| EmptyElement::at(at) + Rectangle::new([(-3, -3), (3, 3)], fill);
                $draw
            }
            style::Marker::Cross => {
                let $mark = |at| Cross::new(at, 4, line);
                $draw
            }
        }
    }};
}

/// RMS over time at one rate, one line per method (paper Fig. 8), as SVG: frames on
/// the x axis (whole numbers), the legend beside the plot, never over the curves.
pub fn plot_rms(
    summary: &Summary,
    frames: &[FrameRow],
    rate: f64,
    path: &Path,
) -> Result<(), EvalError> {
    let s = summary;
    let methods = methods_in_order(s);
    let series: Vec<(String, Vec<(i32, f64)>)> = methods
        .iter()
        .map(|m| {
            let pts = frames
                .iter()
                .filter(|f| &f.method == m && f.rate == rate)
                .map(|f| (f.frame as i32, f.rms))
                .collect();
            (m.name().to_string(), pts)
        })
        .collect();
    let xmax = ((s.duration * s.refresh_hz).round() as i32 - 1).max(1);
    let caption = format!(
        "RMS error vs. ideal, {} at {} samples/s",
        s.scene,
        rate_label(rate)
    );
    plot_lines(
        path,
        &caption,
        &format!("refresh ({} Hz)", s.refresh_hz),
        xmax,
        &series,
    )
}

/// Lines of RMS error over refreshes `0..=xmax`, one per series, as SVG, the legend
/// beside the plot.
pub(crate) fn plot_lines(
    path: &Path,
    caption: &str,
    x_desc: &str,
    xmax: i32,
    series: &[(String, Vec<(i32, f64)>)],
) -> Result<(), EvalError> {
    let ymax = series
        .iter()
        .flat_map(|(_, p)| p.iter().map(|(_, y)| *y))
        .filter(|y| y.is_finite())
        .fold(1.0f64, f64::max)
        * 1.05;
    let e = |e: Box<dyn std::error::Error>| EvalError::Plot {
        path: path.to_path_buf(),
        why: e.to_string(),
    };
    let legend_width = 230;
    let root = SVGBackend::new(path, (720 + legend_width, 450)).into_drawing_area();
    root.fill(&WHITE).map_err(|x| e(Box::new(x)))?;
    let (plot_area, legend_area) = root.split_horizontally(720);
    let mut chart = ChartBuilder::on(&plot_area)
        .caption(caption, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(46)
        .y_label_area_size(56)
        .build_cartesian_2d(0..xmax, 0.0..ymax)
        .map_err(|x| e(Box::new(x)))?;
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc("RMS (0-255)")
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .x_label_formatter(&|x| format!("{x}"))
        .draw()
        .map_err(|x| e(Box::new(x)))?;
    // About a dozen marks a line, each method's at its own phase of the cycle.
    let every = (xmax as usize / MARKS_PER_LINE).max(1);
    for (i, (name, pts)) in series.iter().enumerate() {
        if pts.is_empty() {
            continue;
        }
        let look = style::of_series(name, i);
        let line = look.colour.stroke_width(2);
        let (dash, gap) = look.dash;
        if dash == 0 {
            chart.draw_series(LineSeries::new(pts.iter().copied(), line))
        } else {
            chart.draw_series(DashedLineSeries::new(pts.iter().copied(), dash, gap, line))
        }
        .map_err(|x| e(Box::new(x)))?;
        let marks = pts.iter().skip(look.phase % every).step_by(every);
        with_mark!(look, |mark| chart.draw_series(marks.map(|&p| mark(p))))
            .map_err(|x| e(Box::new(x)))?;
    }
    draw_legend(&legend_area, series, &e)?;
    root.present().map_err(|x| e(Box::new(x)))?;
    Ok(())
}

/// The legend of [`plot_lines`]: a sample of each line with its mark and its method,
/// top to bottom in series order.
fn draw_legend(
    area: &DrawingArea<SVGBackend<'_>, plotters::coord::Shift>,
    series: &[(String, Vec<(i32, f64)>)],
    e: &dyn Fn(Box<dyn std::error::Error>) -> EvalError,
) -> Result<(), EvalError> {
    for (i, (name, _)) in series.iter().enumerate() {
        let y = 40 + 22 * i as i32;
        let look = style::of_series(name, i);
        let style = look.colour.stroke_width(2);
        let (dash, gap) = look.dash;
        let line = vec![(8, y), (48, y)];
        if dash == 0 {
            area.draw(&PathElement::new(line, style))
        } else {
            area.draw(&plotters::element::DashedPathElement::new(
                line, dash, gap, style,
            ))
        }
        .map_err(|x| e(Box::new(x)))?;
        with_mark!(look, |mark| area.draw(&mark((28, y)))).map_err(|x| e(Box::new(x)))?;
        area.draw(&Text::new(
            name.clone(),
            (56, y - 8),
            ("sans-serif", 14).into_font(),
        ))
        .map_err(|x| e(Box::new(x)))?;
    }
    Ok(())
}

/// Marks a line carries over its length ([`plot_lines`]).
const MARKS_PER_LINE: usize = 12;

/// Side-by-side strip of images (8-bit RGB, all `w × h`) with [`STRIP_GAP`]-pixel
/// white gaps.
pub fn strip(images: &[Vec<u8>], w: u32, h: u32) -> (u32, u32, Vec<u8>) {
    strip_of(images, w, h, 3, 255)
}

/// [`strip`] of images of `channels` bytes a pixel, gaps filled with `fill`.
fn strip_of(images: &[Vec<u8>], w: u32, h: u32, channels: u32, fill: u8) -> (u32, u32, Vec<u8>) {
    let gap = STRIP_GAP;
    let n = images.len() as u32;
    let sw = n * w + n.saturating_sub(1) * gap;
    let mut out = vec![fill; (sw * h * channels) as usize];
    for (i, img) in images.iter().enumerate() {
        let x0 = i as u32 * (w + gap);
        for y in 0..h {
            let src = &img[(y * w * channels) as usize..((y + 1) * w * channels) as usize];
            let dst = ((y * sw + x0) * channels) as usize;
            out[dst..dst + src.len()].copy_from_slice(src);
        }
    }
    (sw, h, out)
}

/// White pixels between the panels of a strip.
pub const STRIP_GAP: u32 = 4;

/// The panels of a strip made by [`strip`], if it holds exactly `n` of `w × h`.
pub(crate) fn split_strip(sw: u32, sh: u32, rgb: &[u8], w: u32, n: usize) -> Option<Vec<Vec<u8>>> {
    // In u64: a strip's sizes come from files anyone can edit.
    let (n64, w64) = (n as u64, w as u64);
    let width = n64 * w64 + n64.saturating_sub(1) * STRIP_GAP as u64;
    if n == 0 || sw as u64 != width || rgb.len() as u64 != sw as u64 * sh as u64 * 3 {
        return None;
    }
    let n32 = n as u32;
    Some(
        (0..n32)
            .map(|i| {
                let x0 = (i * (w + STRIP_GAP)) as usize;
                (0..sh as usize)
                    .flat_map(|y| {
                        let row = y * sw as usize;
                        rgb[(row + x0) * 3..(row + x0 + w as usize) * 3]
                            .iter()
                            .copied()
                    })
                    .collect()
            })
            .collect(),
    )
}

/// One strip as written: its images and what they show.
#[derive(Clone, Debug)]
pub struct StripFiles {
    /// The rate column.
    pub rate: f64,
    /// Frame index in the window.
    pub frame: usize,
    /// The strip of displayed images.
    pub image: String,
    /// The strip of FLIP error maps against the first panel, the ideal image.
    pub flip: String,
    /// What the panels show, left to right: [`MethodKind::Ideal`], then the methods.
    pub labels: Vec<MethodKind>,
}

/// File names of the strip at `rate` and `frame`: images and FLIP maps.
fn strip_names(rate: f64, frame: usize) -> (String, String) {
    tagged_strip_names(&rate_label(rate), frame)
}

/// File names of the strip `tag` at `frame`: images and FLIP maps.
pub(crate) fn tagged_strip_names(tag: &str, frame: usize) -> (String, String) {
    let tag = format!("{tag}_{frame:04}");
    (format!("strip_{tag}.png"), format!("flip_{tag}.png"))
}

/// Write a strip's images and the FLIP map of each panel against the first (the
/// ideal image) into `dir`.
fn write_strip(
    dir: &Path,
    (rate, frame): (f64, usize),
    panels: &[(MethodKind, &[u8])],
    (w, h): (u32, u32),
    write_images: bool,
) -> Result<StripFiles, EvalError> {
    let names = strip_names(rate, frame);
    let images: Vec<&[u8]> = panels.iter().map(|(_, rgb)| *rgb).collect();
    write_strip_files(dir, &names, &images, (w, h), write_images)?;
    let (image, flip) = names;
    Ok(StripFiles {
        rate,
        frame,
        image,
        flip,
        labels: panels.iter().map(|(m, _)| *m).collect(),
    })
}

/// Write a strip's images (when asked) as `names.0` and the FLIP map of each panel
/// against the first (the ideal image) as `names.1`, in `dir`.
pub(crate) fn write_strip_files(
    dir: &Path,
    (image, flip): &(String, String),
    panels: &[&[u8]],
    (w, h): (u32, u32),
    write_images: bool,
) -> Result<(), EvalError> {
    let p = dir.join(image);
    if write_images {
        let images: Vec<Vec<u8>> = panels.iter().map(|rgb| rgb.to_vec()).collect();
        let (sw, sh, rgb) = strip(&images, w, h);
        write_png_rgb8(&p, sw, sh, &rgb).map_err(|e| EvalError::io(&p, e))?;
    }
    let ideal = panels[0];
    let maps: Vec<Vec<u8>> = panels
        .iter()
        .map(|rgb| {
            // Images of the strip's own size always compare.
            metrics::flip_map(ideal, rgb, w, h).unwrap_or_else(|| vec![0; rgb.len() / 3])
        })
        .collect();
    let (sw, sh, indices) = strip_of(&maps, w, h, 1, metrics::FLIP_STEPS + 1);
    let p = dir.join(flip);
    write_png_indexed(&p, sw, sh, &indices, &metrics::flip_palette())
        .map_err(|e| EvalError::io(&p, e))
}

/// The `<img>` of panel `i` of a strip file whose panels are `w × h`: the strip
/// shifted so that only that panel shows.
pub(crate) fn panel_img(file: &str, i: usize, (w, h): (u32, u32), alt: &str) -> String {
    let x0 = i as u32 * (w + STRIP_GAP);
    format!(
        "<img src=\"{}\" width=\"{w}\" height=\"{h}\" style=\"object-fit:none;\
         object-position:-{x0}px 0\" alt=\"{}\">",
        escape(file),
        escape(alt)
    )
}

/// `&`, `<`, `>` and `"` as HTML entities.
pub(crate) fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

pub(crate) const STYLE: &str =
    "body{font-family:system-ui,sans-serif;max-width:1200px;margin:2em auto;\
padding:0 1.5em;color:#222;line-height:1.45}\
h2{margin-top:1.6em;border-bottom:1px solid #ddd}\
table{border-collapse:collapse;margin:.4em 0 1.2em}\
td,th{border:1px solid #ccc;padding:3px 9px;text-align:right}\
th:first-child,td:first-child{text-align:left}td.best{font-weight:bold;background:#e8f4e8}\
img.plot{max-width:100%;height:auto}\
.panels{display:flex;flex-wrap:wrap;gap:12px 10px;margin:.5em 0 1.5em}\
.panel{margin:0}.panel img{display:block;max-width:none;margin-bottom:3px}\
.panel figcaption{font-size:.85em;color:#444;margin-bottom:3px}.panel figcaption b{color:#111}\
p.note{color:#555;font-size:.9em}";

/// The report: tables, plots, strips with their labels and FLIP maps, and links to
/// the data, each only if its file is in `dir`.
fn html(
    s: &Summary,
    frames: &[FrameRow],
    plots: &[(f64, String)],
    strips: &[StripFiles],
    dir: &Path,
) -> String {
    let present = |file: &str| dir.join(file).is_file();
    let mut h = String::new();
    html_heading(&mut h, s);
    html_verdict(&mut h, s);
    html_tables(&mut h, s);
    html_video_table(&mut h, s, dir);
    html_plots(&mut h, plots, &present);
    html_strips(&mut h, s, frames, strips, &present);
    html_cost_and_data(&mut h, s, &present);
    h.push_str("</body></html>\n");
    h
}

/// The page's head, title and the run's settings.
fn html_heading(h: &mut String, s: &Summary) {
    let _ = write!(
        h,
        "<!doctype html><html lang=\"en\"><head><meta charset=\"utf-8\">\
         <meta name=\"viewport\" content=\"width=device-width,initial-scale=1\">\
         <title>frameless evaluation: {}</title><style>{STYLE}</style></head><body>",
        escape(&s.scene)
    );
    let _ = write!(
        h,
        "<h1>Evaluation: {}</h1><p>{}×{} pixels, display refreshed at {} Hz; {} s window \
         from t = {} s after {} s of warm-up; seed {}; ideal images with {} samples per \
         pixel{}.</p><p>Reconstructor: {}.</p><p>Tracer: {}.</p>",
        escape(&s.scene),
        s.width,
        s.height,
        s.refresh_hz,
        s.duration,
        s.start,
        s.warmup,
        s.seed,
        s.ideal_spp,
        if s.camera_path { "; camera path" } else { "" },
        escape(&s.recon.to_string()),
        escape(&tracer_words(s))
    );
}

/// The tracer a run's samples and ideal images came from, and why it stopped part way
/// if it did.
fn tracer_words(s: &Summary) -> String {
    match &s.trace_failure {
        Some(why) => format!(
            "{} (failed part way, the rest traced on the CPU: {why})",
            s.trace
        ),
        None => s.trace.to_string(),
    }
}

/// The first screen: who wins at each rate, in one sentence and a small chart.
fn html_verdict(h: &mut String, s: &Summary) {
    let rates = rates_in_order(s);
    let _ = write!(
        h,
        "<p class=\"verdict\" style=\"font-size:1.1em\">{}</p>{}",
        verdict::sentence(s, &rates),
        verdict::chart(s, &rates)
    );
}

/// One table per score: methods by rate, the best of each rate in bold.
fn html_tables(h: &mut String, s: &Summary) {
    let methods = methods_in_order(s);
    let rates = rates_in_order(s);
    // Title, value, decimals, whether higher is better.
    type Column = (&'static str, fn(&super::ResultRow) -> f64, usize, bool);
    let tables: [Column; 7] = [
        (
            "Mean RMS error (0–255, lower is better)",
            |r| r.rms_mean,
            2,
            false,
        ),
        ("Mean PSNR (dB, higher is better)", |r| r.psnr_mean, 2, true),
        (
            "Mean FLIP (0–1, lower is better)",
            |r| r.flip_mean,
            4,
            false,
        ),
        (SUSTAINED_TITLE, sustained, 2, false),
        (TRANSIENT_TITLE, transient, 2, false),
        (INSTABILITY_TITLE, |r| r.instability_mean, 2, false),
        (
            "Mean information age (ms)",
            |r| r.age_mean_s * 1e3,
            1,
            false,
        ),
    ];
    h.push_str(
        "<p class=\"note\">Columns are sample budgets (samples/s). Bold: the best of the \
         methods that ran at that budget (methods with a budget of their own, such as \
         <code>full-res-60hz</code>, are not ranked).</p>",
    );
    h.push_str(TEMPORAL_NOTE);
    let cell = |m: &MethodKind, r: f64| s.results.iter().find(|x| &x.method == m && x.rate == r);
    for (i, (title, f, prec, higher)) in tables.into_iter().enumerate() {
        // Information age is a property, not a score, and instability mixes lag with
        // flicker (see `TEMPORAL_NOTE`): neither is ranked.
        let ranked = i < 5;
        let _ = write!(h, "<h2>{title}</h2><table><tr><th>method</th>");
        for r in &rates {
            let _ = write!(h, "<th>{}</th>", rate_label(*r));
        }
        h.push_str("</tr>");
        let best: Vec<Option<f64>> = rates
            .iter()
            .map(|&r| {
                let vals = s
                    .results
                    .iter()
                    .filter(|x| x.rate == r && x.effective_rate == r)
                    .map(f)
                    .filter(|v| v.is_finite());
                if higher {
                    vals.reduce(f64::max)
                } else {
                    vals.reduce(f64::min)
                }
            })
            .collect();
        for m in &methods {
            let _ = write!(h, "<tr><td>{m}</td>");
            for (r, b) in rates.iter().zip(&best) {
                match cell(m, *r) {
                    Some(x) if f(x).is_finite() => {
                        let v = f(x);
                        let is_best = ranked && x.effective_rate == *r && Some(v) == *b;
                        let class = if is_best { " class=\"best\"" } else { "" };
                        let _ = write!(h, "<td{class}>{v:.prec$}</td>");
                    }
                    _ => h.push_str("<td>–</td>"),
                }
            }
            h.push_str("</tr>");
        }
        h.push_str("</table>");
    }
}

/// The report's JOD table (methods of `s` by its rates, the best of each rate at equal
/// budget in bold), or a note saying why `vdp.json` could not be read; nothing when
/// the folder has none.
fn html_video_table(h: &mut String, s: &Summary, dir: &Path) {
    let v = match video_metric::read(dir) {
        None => return,
        Some(Err(why)) => {
            let _ = write!(
                h,
                "<p class=\"note\">{} is there but could not be read: {}</p>",
                video_metric::FILE,
                escape(&why.to_string())
            );
            return;
        }
        Some(Ok(v)) => v,
    };
    let _ = write!(
        h,
        "<h2>Video JOD ({} {}, display {}; 10 is no visible difference, higher is better)</h2>\
         <p class=\"note\">The metric's prediction of how visibly each method's displayed \
         video, every refresh of the window, differs from the ideal video, from {}.</p>\
         <table><tr><th>method</th>",
        escape(&v.metric),
        escape(&v.version),
        escape(&v.display),
        video_metric::FILE
    );
    let rates = rates_in_order(s);
    for r in &rates {
        let _ = write!(h, "<th>{}</th>", rate_label(*r));
    }
    h.push_str("</tr>");
    let jod = |m: &str, rate: f64| {
        v.results
            .iter()
            .find(|x| x.method == m && x.rate == rate)
            .map(|x| x.jod)
    };
    let equal_budget = |m: &str, rate: f64| {
        s.results
            .iter()
            .any(|x| x.method.name() == m && x.rate == rate && x.effective_rate == rate)
    };
    let best: Vec<Option<f64>> = rates
        .iter()
        .map(|&r| {
            s.results
                .iter()
                .filter(|x| x.rate == r && x.effective_rate == r)
                .filter_map(|x| jod(x.method.name(), r))
                .reduce(f64::max)
        })
        .collect();
    for m in methods_in_order(s).iter().map(|m| m.name()) {
        let _ = write!(h, "<tr><td>{}</td>", escape(m));
        for (r, b) in rates.iter().zip(&best) {
            match jod(m, *r) {
                Some(j) => {
                    let bold = equal_budget(m, *r) && Some(j) == *b;
                    let class = if bold { " class=\"best\"" } else { "" };
                    let _ = write!(h, "<td{class}>{j:.2}</td>");
                }
                None => h.push_str("<td>–</td>"),
            }
        }
        h.push_str("</tr>");
    }
    h.push_str("</table>");
    html_video_parts(h, s, &v);
}

/// The JOD of each visual channel alone, per method and rate (the lowest of each row
/// in bold: where most of the visible difference is), when `vdp.json` keeps them.
fn html_video_parts(h: &mut String, s: &Summary, v: &video_metric::VideoScores) {
    let Some(names) = v.results.iter().find_map(|r| {
        let p = r.part_values()?;
        (!p.is_empty()).then(|| p.iter().map(|(k, _)| k.to_string()).collect::<Vec<_>>())
    }) else {
        return;
    };
    h.push_str(
        "<h3>JOD per visual channel</h3><p class=\"note\">The JOD each channel of the \
         metric would give alone, the others set to no difference; the lowest of a row \
         (bold) is where most of the visible difference is: the sustained response for \
         what stays wrong, the transient one for flicker.</p><table><tr><th>method</th>\
         <th>samples/s</th>",
    );
    for n in &names {
        let label = n
            .replace("red_green", "red–green")
            .replace("yellow_violet", "yellow–violet")
            .replace('_', " ");
        let _ = write!(h, "<th>{}</th>", escape(&label));
    }
    h.push_str("</tr>");
    for m in methods_in_order(s).iter().map(|m| m.name()) {
        for r in rates_in_order(s) {
            let Some(row) = v.results.iter().find(|x| x.method == m && x.rate == r) else {
                continue;
            };
            let parts = row.part_values().unwrap_or_default();
            let low = parts.iter().map(|(_, j)| *j).reduce(f64::min);
            let _ = write!(h, "<tr><td>{}</td><td>{}</td>", escape(m), rate_label(r));
            for n in &names {
                match parts.iter().find(|(k, _)| k == n) {
                    Some((_, j)) => {
                        let class = if Some(*j) == low {
                            " class=\"best\""
                        } else {
                            ""
                        };
                        let _ = write!(h, "<td{class}>{j:.2}</td>");
                    }
                    None => h.push_str("<td>–</td>"),
                }
            }
            h.push_str("</tr>");
        }
    }
    h.push_str("</table>");
}

/// The RMS-over-time plots that are in the folder.
fn html_plots(h: &mut String, plots: &[(f64, String)], present: &dyn Fn(&str) -> bool) {
    let plots: Vec<&(f64, String)> = plots.iter().filter(|(_, f)| present(f)).collect();
    if !plots.is_empty() {
        h.push_str("<h2>RMS error over time</h2>");
        for (r, file) in plots {
            let _ = write!(
                h,
                "<figure><img class=\"plot\" src=\"{}\" alt=\"RMS error of every method over the window at {} samples/s\"></figure>",
                escape(file),
                rate_label(*r)
            );
        }
    }
}

/// The image strips that are in the folder, a panel per method with its frame's
/// scores, and the FLIP maps below them.
fn html_strips(
    h: &mut String,
    s: &Summary,
    frames: &[FrameRow],
    strips: &[StripFiles],
    present: &dyn Fn(&str) -> bool,
) {
    let strips: Vec<&StripFiles> = strips.iter().filter(|st| present(&st.image)).collect();
    if !strips.is_empty() {
        h.push_str(
            "<h2>Images</h2><p class=\"note\">What each method displays at a few refreshes, \
             beside the ideal image, and below each its FLIP error map against the ideal \
             (black: no visible difference, through red, to yellow: the largest). Per \
             panel: that frame's RMS error and FLIP. One section per rate, the first \
             open; click a rate to open or fold its images.</p>",
        );
    }
    // One foldable section per rate, so that the page stays short: the first open.
    let mut rates: Vec<f64> = Vec::new();
    for st in &strips {
        if !rates.contains(&st.rate) {
            rates.push(st.rate);
        }
    }
    for (k, &rate) in rates.iter().enumerate() {
        let of_rate: Vec<&StripFiles> = strips.iter().copied().filter(|x| x.rate == rate).collect();
        let _ = write!(
            h,
            "<details{}><summary><b>{} samples/s</b>: {} refreshes</summary>",
            if k == 0 { " open" } else { "" },
            rate_label(rate),
            of_rate.len()
        );
        html_strips_of_rate(h, s, frames, &of_rate, present);
        h.push_str("</details>");
    }
}

/// The strips of one rate, each a row of labelled panels.
fn html_strips_of_rate(
    h: &mut String,
    s: &Summary,
    frames: &[FrameRow],
    strips: &[&StripFiles],
    present: &dyn Fn(&str) -> bool,
) {
    for st in strips {
        let flip = present(&st.flip);
        let _ = write!(
            h,
            "<h3>{} samples/s, refresh {} (t = {:.3} s)</h3><div class=\"panels\">",
            rate_label(st.rate),
            st.frame,
            s.start + st.frame as f64 / s.refresh_hz
        );
        for (i, &label) in st.labels.iter().enumerate() {
            let crop = |file: &str, what: &str| {
                panel_img(file, i, (s.width, s.height), &format!("{what}, {label}"))
            };
            let _ = write!(
                h,
                "<figure class=\"panel\"><figcaption><b>{}</b>",
                escape(label.name())
            );
            let row = frames
                .iter()
                .find(|f| f.method == label && f.rate == st.rate && f.frame == st.frame);
            if let Some(f) = row {
                let _ = write!(h, "<br>RMS {:.2}", f.rms);
                if let Some(v) = f.flip {
                    let _ = write!(h, " · FLIP {v:.3}");
                }
            } else if i == 0 {
                h.push_str("<br>reference");
            }
            h.push_str("</figcaption>");
            h.push_str(&crop(&st.image, "image"));
            if flip && i > 0 {
                h.push_str(&crop(&st.flip, "FLIP error map"));
            }
            h.push_str("</figure>");
        }
        h.push_str("</div>");
    }
}

/// Where the run's time went, and links to the data files that are in the folder.
fn html_cost_and_data(h: &mut String, s: &Summary, present: &dyn Fn(&str) -> bool) {
    let t = &s.timing;
    let _ = write!(
        h,
        "<h2>Cost</h2><p>Ideal images {:.1} s ({} of {} from the cache, {} cache entries \
         rejected and rendered again); methods {:.1} s, of which tracing rays {:.1} s; \
         metrics {:.1} s; output {:.1} s.</p>",
        t.ideal_s,
        t.ideal_cache_hits,
        (s.duration * s.refresh_hz).floor(),
        t.ideal_cache_rejected,
        t.methods_s,
        t.trace_s,
        t.metrics_s,
        t.output_s
    );
    let data: Vec<String> = [
        ("frames.csv", "every frame's measurements"),
        ("summary.json", "the means above"),
        ("summary.md", "the tables as Markdown"),
    ]
    .iter()
    .filter(|(f, _)| present(f))
    .map(|(f, what)| format!("<a href=\"{f}\">{f}</a> ({what})"))
    .collect();
    if !data.is_empty() {
        let _ = write!(h, "<h2>Data</h2><p>{}.</p>", data.join("; "));
    }
}

/// Write every output as the folder `dir`, replacing what was there only once all are
/// written (see [`OutputDir`]): `dir` holds this run or the previous one, never a mix.
/// Returns the report's path.
pub fn write_all(out: &mut EvalOutput, dir: &Path) -> Result<PathBuf, EvalError> {
    let staging = OutputDir::begin(dir).map_err(|e| EvalError::io(dir, e))?;
    write_into(out, staging.path())?;
    staging.commit().map_err(|e| EvalError::io(dir, e))?;
    Ok(dir.join("report.html"))
}

/// Write every output into the existing, private folder `dir`.
pub(crate) fn write_into(out: &mut EvalOutput, dir: &Path) -> Result<(), EvalError> {
    let t0 = std::time::Instant::now();
    let io = EvalError::io;
    let write = |name: &str, bytes: &[u8]| -> Result<(), EvalError> {
        let p = dir.join(name);
        output::write_atomic(&p, bytes).map_err(|e| io(&p, e))
    };
    let csv = frames_csv(&out.frames).map_err(|e| EvalError::Data {
        path: dir.join("frames.csv"),
        why: e.to_string(),
    })?;
    write("frames.csv", &csv)?;
    write("summary.md", markdown(&out.summary).as_bytes())?;
    let plots = write_plots(&out.summary, &out.frames, dir)?;
    let (w, h) = (out.summary.width, out.summary.height);
    let mut strips = Vec::new();
    for s in &out.strips {
        let panels: Vec<(MethodKind, &[u8])> = s.panels().collect();
        strips.push(write_strip(dir, (s.rate, s.frame), &panels, (w, h), true)?);
    }
    if !out.linear.is_empty() {
        let exr = dir.join("exr");
        std::fs::create_dir_all(&exr).map_err(|e| io(&exr, e))?;
        for l in &out.linear {
            let name = match l.rate {
                Some(r) => format!("{}_{}_{:04}.exr", l.method, rate_label(r), l.frame),
                None => format!("{}_{:04}.exr", l.method, l.frame),
            };
            let p = exr.join(name);
            l.image.save_exr(&p).map_err(|e| io(&p, e))?;
        }
    }
    out.summary.timing.output_s = t0.elapsed().as_secs_f64();
    write(
        "summary.json",
        // A summary of numbers and strings always serialises.
        serde_json::to_string_pretty(&out.summary)
            .expect("summary serialises")
            .as_bytes(),
    )?;
    write(
        "report.html",
        html(&out.summary, &out.frames, &plots, &strips, dir).as_bytes(),
    )?;
    Ok(())
}

fn write_plots(
    s: &Summary,
    frames: &[FrameRow],
    dir: &Path,
) -> Result<Vec<(f64, String)>, EvalError> {
    let mut plots = Vec::new();
    for r in rates_in_order(s) {
        let name = format!("rms_{}.svg", rate_label(r));
        plot_rms(s, frames, r, &dir.join(&name))?;
        plots.push((r, name));
    }
    Ok(plots)
}

/// Make the plots, FLIP maps and `report.html` of the evaluation output folder `dir`
/// again, with this version's report, from its `summary.json`, `frames.csv` and the
/// image strips it holds (strips deleted since are left out; the data files are not
/// changed). Each file is replaced atomically. Returns the report's path.
pub fn rewrite(dir: &Path) -> Result<PathBuf, EvalError> {
    let summary_path = dir.join("summary.json");
    let summary = read_summary(&summary_path)?;
    let bad = |path: PathBuf| move |source| EvalError::Invalid { path, source };
    summary.check().map_err(bad(summary_path))?;
    let frames_path = dir.join("frames.csv");
    let frames = read_frames_csv(&frames_path)?;
    summary.check_frames(&frames).map_err(bad(frames_path))?;
    let plots = write_plots(&summary, &frames, dir)?;
    let mut labels = vec![MethodKind::Ideal];
    labels.extend(methods_in_order(&summary));
    let (w, h) = (summary.width, summary.height);
    let mut strips = Vec::new();
    for r in rates_in_order(&summary) {
        let prefix = format!("strip_{}_", rate_label(r));
        let mut found: Vec<usize> = std::fs::read_dir(dir)
            .map_err(|e| EvalError::io(dir, e))?
            .filter_map(|e| e.ok()?.file_name().into_string().ok())
            .filter_map(|n| n.strip_prefix(&prefix)?.strip_suffix(".png")?.parse().ok())
            .collect();
        found.sort_unstable();
        for k in found {
            let p = dir.join(strip_names(r, k).0);
            let (sw, sh, rgb) = read_png_rgb8(&p).map_err(|e| EvalError::io(&p, e))?;
            // A strip whose panels are not this summary's methods is not labelled wrongly:
            // it is left out of the report.
            let Some(panels) = split_strip(sw, sh, &rgb, w, labels.len()).filter(|_| sh == h)
            else {
                continue;
            };
            let panels: Vec<(MethodKind, &[u8])> = labels
                .iter()
                .copied()
                .zip(panels.iter().map(Vec::as_slice))
                .collect();
            strips.push(write_strip(dir, (r, k), &panels, (w, h), false)?);
        }
    }
    let p = dir.join("report.html");
    output::write_atomic(&p, html(&summary, &frames, &plots, &strips, dir).as_bytes())
        .map_err(|e| EvalError::io(&p, e))?;
    Ok(p)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rates_parse_and_label() {
        assert_eq!(parse_rate("400k").unwrap(), 400_000.0);
        assert_eq!(parse_rate("1.5M").unwrap(), 1_500_000.0);
        assert_eq!(parse_rate("100000").unwrap(), 100_000.0);
        assert!(parse_rate("0").is_err());
        assert!(parse_rate("-5k").is_err());
        assert!(parse_rate("fast").is_err());
        assert!(parse_rate("nan").is_err());
        assert_eq!(rate_label(400_000.0), "400K");
        assert_eq!(rate_label(1_500_000.0), "1.5M");
        assert_eq!(rate_label(3_932_160.0), "3.93M");
    }
}
