//! Evaluation outputs: `frames.csv`, `summary.json`, `summary.md` (paper Table 1
//! shape), RMS-over-time plots (paper Fig. 8), image strips and `report.html`.

use std::{fmt::Write as _, path::Path};

use plotters::prelude::*;

use super::{EvalError, EvalOutput, Summary};
pub use crate::clock::{parse_rate, rate_label};
use crate::{image::write_png_rgb8, methods::MethodKind, output::OutputDir};

/// A table of one metric: title, the value of a row, decimals.
type Metric = (&'static str, fn(&super::ResultRow) -> f64, usize);

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
    let tables: [Metric; 5] = [
        ("Mean RMS error (0–255, lower is better)", |r| r.rms_mean, 1),
        ("Mean PSNR (dB, higher is better)", |r| r.psnr_mean, 2),
        ("Mean FLIP (lower is better)", |r| r.flip_mean, 4),
        (
            "Temporal instability (0–255, change not in the ideal; lower is better)",
            |r| r.flicker_mean,
            2,
        ),
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
                    Some(x) => {
                        let _ = write!(out, " {:.*} |", prec, f(x));
                    }
                    None => out.push_str(" – |"),
                }
            }
            out.push('\n');
        }
        out.push('\n');
    }
    out
}

fn csv(out: &EvalOutput) -> String {
    let mut s = String::from("method,rate,frame,time,rms,psnr,flip,flicker,age_s\n");
    for f in &out.frames {
        let flip = f.flip.map(|v| format!("{v:.6}")).unwrap_or_default();
        let flicker = f.flicker.map(|v| format!("{v:.4}")).unwrap_or_default();
        let _ = writeln!(
            s,
            "{},{},{},{:.6},{:.4},{:.4},{flip},{flicker},{:.6}",
            f.method, f.rate, f.frame, f.time, f.rms, f.psnr, f.age_s
        );
    }
    s
}

const PALETTE: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(23, 190, 207),
];

/// RMS over time at one rate, one line per method (paper Fig. 8), as SVG.
pub fn plot_rms(out: &EvalOutput, rate: f64, path: &Path) -> Result<(), EvalError> {
    let s = &out.summary;
    let methods = methods_in_order(s);
    let series: Vec<(String, Vec<(f64, f64)>)> = methods
        .iter()
        .map(|m| {
            let pts = out
                .frames
                .iter()
                .filter(|f| &f.method == m && f.rate == rate)
                .map(|f| (f.frame as f64, f.rms))
                .collect();
            (m.name().to_string(), pts)
        })
        .collect();
    let ymax = series
        .iter()
        .flat_map(|(_, p)| p.iter().map(|(_, y)| *y))
        .fold(1.0f64, f64::max)
        * 1.05;
    let xmax = (s.duration * s.refresh_hz).max(1.0);
    let root = SVGBackend::new(path, (800, 450)).into_drawing_area();
    let e = |e: Box<dyn std::error::Error>| EvalError::Plot {
        path: path.to_path_buf(),
        why: e.to_string(),
    };
    root.fill(&WHITE).map_err(|x| e(Box::new(x)))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!(
                "RMS error vs. ideal, {} at {} samples/s",
                s.scene,
                rate_label(rate)
            ),
            ("sans-serif", 20),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(0.0..xmax, 0.0..ymax)
        .map_err(|x| e(Box::new(x)))?;
    chart
        .configure_mesh()
        .x_desc(format!("frame ({} Hz)", s.refresh_hz))
        .y_desc("RMS (0-255)")
        .draw()
        .map_err(|x| e(Box::new(x)))?;
    for (i, (name, pts)) in series.iter().enumerate() {
        if pts.is_empty() {
            continue;
        }
        let color = PALETTE[i % PALETTE.len()];
        chart
            .draw_series(LineSeries::new(pts.iter().copied(), color.stroke_width(2)))
            .map_err(|x| e(Box::new(x)))?
            .label(name.as_str())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
            });
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(|x| e(Box::new(x)))?;
    root.present().map_err(|x| e(Box::new(x)))?;
    Ok(())
}

/// Side-by-side strip of images (8-bit RGB, all `w × h`) with 4-pixel white gaps.
pub fn strip(images: &[Vec<u8>], w: u32, h: u32) -> (u32, u32, Vec<u8>) {
    let gap = 4u32;
    let n = images.len() as u32;
    let sw = n * w + n.saturating_sub(1) * gap;
    let mut rgb = vec![255u8; (sw * h * 3) as usize];
    for (i, img) in images.iter().enumerate() {
        let x0 = i as u32 * (w + gap);
        for y in 0..h {
            let src = &img[(y * w * 3) as usize..((y + 1) * w * 3) as usize];
            let dst = ((y * sw + x0) * 3) as usize;
            rgb[dst..dst + src.len()].copy_from_slice(src);
        }
    }
    (sw, h, rgb)
}

fn html(
    out: &EvalOutput,
    plots: &[(f64, String)],
    strips: &[(f64, usize, String, Vec<String>)],
) -> String {
    let s = &out.summary;
    let mut h = String::new();
    let _ = write!(
        h,
        "<!doctype html><html><head><meta charset=\"utf-8\"><title>frameless evaluation: {}</title>\
         <style>body{{font-family:sans-serif;max-width:1100px;margin:2em auto;color:#222}}\
         table{{border-collapse:collapse;margin:1em 0}}td,th{{border:1px solid #ccc;padding:4px 8px;text-align:right}}\
         th:first-child,td:first-child{{text-align:left}}img{{max-width:100%}}figcaption{{color:#555}}</style></head><body>",
        s.scene
    );
    let _ = write!(
        h,
        "<h1>Evaluation: {}</h1><p>{}×{} at {} Hz, window {} s from t = {} s, warm-up {} s, seed {}, ideal {} spp{}.</p>",
        s.scene,
        s.width,
        s.height,
        s.refresh_hz,
        s.duration,
        s.start,
        s.warmup,
        s.seed,
        s.ideal_spp,
        if s.camera_path { ", camera path" } else { "" }
    );
    let methods = methods_in_order(s);
    let rates = rates_in_order(s);
    let tables: [Metric; 4] = [
        ("Mean RMS error (0–255)", |r| r.rms_mean, 1),
        ("Mean FLIP", |r| r.flip_mean, 4),
        ("Temporal instability (0–255)", |r| r.flicker_mean, 2),
        ("Mean information age (ms)", |r| r.age_mean_s * 1e3, 1),
    ];
    for (title, f, prec) in tables {
        let _ = write!(h, "<h2>{title}</h2><table><tr><th>method</th>");
        for r in &rates {
            let _ = write!(h, "<th>{}</th>", rate_label(*r));
        }
        h.push_str("</tr>");
        for m in &methods {
            let _ = write!(h, "<tr><td>{m}</td>");
            for r in &rates {
                match s.results.iter().find(|x| &x.method == m && x.rate == *r) {
                    Some(x) => {
                        let _ = write!(h, "<td>{:.*}</td>", prec, f(x));
                    }
                    None => h.push_str("<td>–</td>"),
                }
            }
            h.push_str("</tr>");
        }
        h.push_str("</table>");
    }
    h.push_str("<h2>RMS error over time</h2>");
    for (r, file) in plots {
        let _ = write!(
            h,
            "<figure><img src=\"{file}\" alt=\"RMS plot at {}\"></figure>",
            rate_label(*r)
        );
    }
    h.push_str("<h2>Image strips</h2>");
    for (r, k, file, names) in strips {
        let _ = write!(
            h,
            "<figure><img src=\"{file}\"><figcaption>{} samples/s, frame {k} (t = {:.3} s), left to right: {}</figcaption></figure>",
            rate_label(*r),
            s.start + *k as f64 / s.refresh_hz,
            names.join(", ")
        );
    }
    let t = &s.timing;
    let _ = write!(
        h,
        "<h2>Cost</h2><p>ideal images {:.1} s ({} of {} from cache, {} cache entries rejected and re-rendered), methods {:.1} s (tracing {:.1} s), metrics {:.1} s, output {:.1} s.</p>\
         <p>Per-frame data: <a href=\"frames.csv\">frames.csv</a>; summary: <a href=\"summary.json\">summary.json</a>.</p></body></html>",
        t.ideal_s,
        t.ideal_cache_hits,
        (s.duration * s.refresh_hz).floor(),
        t.ideal_cache_rejected,
        t.methods_s,
        t.trace_s,
        t.metrics_s,
        t.output_s
    );
    h
}

/// Write every output as the folder `dir`, replacing what was there only once all are
/// written (see [`OutputDir`]): `dir` holds this run or the previous one, never a mix.
/// Returns the report's path.
pub fn write_all(out: &mut EvalOutput, dir: &Path) -> Result<std::path::PathBuf, EvalError> {
    let staging = OutputDir::begin(dir).map_err(|e| EvalError::io(dir, e))?;
    write_into(out, staging.path())?;
    staging.commit().map_err(|e| EvalError::io(dir, e))?;
    Ok(dir.join("report.html"))
}

/// Write every output into the existing, private folder `dir`.
pub(crate) fn write_into(out: &mut EvalOutput, dir: &Path) -> Result<(), EvalError> {
    let t0 = std::time::Instant::now();
    let io = EvalError::io;
    let write = |name: &str, text: &str| -> Result<(), EvalError> {
        let p = dir.join(name);
        std::fs::write(&p, text).map_err(|e| io(&p, e))
    };
    write("frames.csv", &csv(out))?;
    write("summary.md", &markdown(&out.summary))?;
    let mut plots = Vec::new();
    for r in rates_in_order(&out.summary) {
        let name = format!("rms_{}.svg", rate_label(r));
        plot_rms(out, r, &dir.join(&name))?;
        plots.push((r, name));
    }
    let (w, h) = (out.summary.width, out.summary.height);
    let mut strip_files = Vec::new();
    for (r, k, list) in &out.strips {
        let name = format!("strip_{}_{:04}.png", rate_label(*r), k);
        let images: Vec<Vec<u8>> = list.iter().map(|(_, rgb)| rgb.clone()).collect();
        let (sw, sh, rgb) = strip(&images, w, h);
        let p = dir.join(&name);
        write_png_rgb8(&p, sw, sh, &rgb).map_err(|e| io(&p, e))?;
        strip_files.push((*r, *k, name, list.iter().map(|(m, _)| m.clone()).collect()));
    }
    out.summary.timing.output_s = t0.elapsed().as_secs_f64();
    write("report.html", &html(out, &plots, &strip_files))?;
    write(
        "summary.json",
        // A summary of numbers and strings always serialises.
        &serde_json::to_string_pretty(&out.summary).expect("summary serialises"),
    )?;
    Ok(())
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
