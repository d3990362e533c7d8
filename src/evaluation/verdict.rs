//! The report's first screen: who wins at each rate, in one sentence and one small bar
//! chart, above the tables. Ranked as the tables rank: by mean RMS error, among the
//! methods held to that rate's budget (one with a budget of its own, such as
//! `full-res-60hz`, is shown in the tables but not ranked).

use std::fmt::Write as _;

use super::{style, ResultRow, Summary};
use crate::clock::rate_label;

/// The rows ranked at `rate`, lowest mean RMS first.
fn ranked(s: &Summary, rate: f64) -> Vec<&ResultRow> {
    let mut rows: Vec<&ResultRow> = s
        .results
        .iter()
        .filter(|r| r.rate == rate && r.effective_rate == rate && r.rms_mean.is_finite())
        .collect();
    rows.sort_by(|a, b| a.rms_mean.total_cmp(&b.rms_mean));
    rows
}

/// One sentence: at each rate the method with the lowest mean RMS error, with its RMS
/// and the runner-up's, and FLIP's best where that is another method.
pub fn sentence(s: &Summary, rates: &[f64]) -> String {
    let clauses: Vec<String> = rates.iter().filter_map(|&rate| clause(s, rate)).collect();
    if clauses.is_empty() {
        return "No method here was held to a sample budget, so none is ranked.".into();
    }
    format!("Lowest mean RMS error: {}.", clauses.join("; "))
}

/// "at 400K <b>adaptive</b> (6.72; next taa-warp, 14.21)", or nothing for a rate no
/// ranked method ran at.
fn clause(s: &Summary, rate: f64) -> Option<String> {
    let rows = ranked(s, rate);
    let best = rows.first()?;
    let mut c = format!(
        "at {} <b>{}</b> ({:.2}",
        rate_label(rate),
        best.method,
        best.rms_mean
    );
    if let Some(next) = rows.get(1) {
        let _ = write!(c, "; next {}, {:.2}", next.method, next.rms_mean);
    }
    let flip_best = rows
        .iter()
        .filter(|r| r.flip_mean.is_finite())
        .min_by(|a, b| a.flip_mean.total_cmp(&b.flip_mean));
    if let Some(f) = flip_best.filter(|f| f.method != best.method) {
        let _ = write!(c, "; lowest FLIP: {}, {:.4}", f.method, f.flip_mean);
    }
    c.push(')');
    Some(c)
}

/// Pixels of the chart: bar width, gap between bars, gap between rates, plot height,
/// the room for the axis labels on the left and the rate labels below.
const BAR: u32 = 10;
const BAR_GAP: u32 = 2;
const GROUP_GAP: u32 = 22;
const PLOT_H: u32 = 120;
const LEFT: u32 = 36;
const BELOW: u32 = 20;

/// A small SVG bar chart of the ranked methods' mean RMS at each rate, one group of
/// bars a rate, each method in its colour of every plot, and the legend below it.
pub fn chart(s: &Summary, rates: &[f64]) -> String {
    let groups: Vec<(f64, Vec<&ResultRow>)> = rates
        .iter()
        .map(|&r| (r, ranked(s, r)))
        .filter(|(_, rows)| !rows.is_empty())
        .collect();
    if groups.is_empty() {
        return String::new();
    }
    let top = groups
        .iter()
        .flat_map(|(_, rows)| rows.iter().map(|r| r.rms_mean))
        .fold(0.0f64, f64::max)
        .max(f64::MIN_POSITIVE);
    let width = LEFT
        + groups
            .iter()
            .map(|(_, rows)| rows.len() as u32 * (BAR + BAR_GAP) + GROUP_GAP)
            .sum::<u32>();
    let mut svg = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{width}\" height=\"{}\" \
         font-family=\"sans-serif\" font-size=\"11\" role=\"img\" aria-label=\"mean RMS \
         error of each method at each rate\"><text x=\"{}\" y=\"10\" text-anchor=\"end\">\
         {top:.1}</text><text x=\"{}\" y=\"{PLOT_H}\" text-anchor=\"end\">0</text>\
         <line x1=\"{LEFT}\" y1=\"{PLOT_H}\" x2=\"{width}\" y2=\"{PLOT_H}\" stroke=\"#888\"/>",
        PLOT_H + BELOW,
        LEFT - 4,
        LEFT - 4
    );
    let mut x = LEFT;
    for (rate, rows) in &groups {
        let group_w = rows.len() as u32 * (BAR + BAR_GAP);
        for r in rows {
            let h = (r.rms_mean / top * (PLOT_H - 12) as f64).round() as u32;
            let colour = style::of_method(r.method.name()).map_or("#777".into(), |l| l.css());
            let _ = write!(
                svg,
                "<rect x=\"{x}\" y=\"{}\" width=\"{BAR}\" height=\"{h}\" fill=\"{colour}\">\
                 <title>{} at {}: RMS {:.2}</title></rect>",
                PLOT_H - h,
                r.method,
                rate_label(*rate),
                r.rms_mean
            );
            x += BAR + BAR_GAP;
        }
        let _ = write!(
            svg,
            "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">{}</text>",
            x - group_w / 2,
            PLOT_H + BELOW - 4,
            rate_label(*rate)
        );
        x += GROUP_GAP;
    }
    svg.push_str("</svg>");
    svg + &legend(&groups)
}

/// The chart's legend: each method once, a square of its colour and its name.
fn legend(groups: &[(f64, Vec<&ResultRow>)]) -> String {
    let mut seen = Vec::new();
    let mut html = String::from("<p class=\"note\">");
    for r in groups.iter().flat_map(|(_, rows)| rows.iter()) {
        if seen.contains(&r.method) {
            continue;
        }
        seen.push(r.method);
        let colour = style::of_method(r.method.name()).map_or("#777".into(), |l| l.css());
        let _ = write!(
            html,
            "<span style=\"white-space:nowrap;margin-right:.8em\"><span \
             style=\"display:inline-block;width:.8em;height:.8em;background:{colour}\"></span> \
             {}</span> ",
            r.method
        );
    }
    html.push_str("</p>");
    html
}
