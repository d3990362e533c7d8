//! The report's first screen says who wins at each rate: the sentence above the tables
//! names, for every rate, the method with the lowest mean RMS error among those held to
//! that budget (as `summary.json` has them), and a chart in the methods' colours
//! follows it, all before the first table; further down, the image strips fold by rate.

use std::process::Command;

use frameless::clock::rate_label;

#[test]
fn the_first_screen_names_the_winner_at_each_rate() {
    let out = std::env::temp_dir().join(format!("frameless-verdict-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let run = Command::new(env!("CARGO_BIN_EXE_frameless"))
        .args([
            "eval",
            "--size",
            "24x16",
            "--duration",
            "0.1",
            "--warmup",
            "0.2",
            "--no-cache",
            "--rate",
            "100k,400k",
            "--method",
            "traditional-frameless,adaptive,taa,full-res-60hz",
            "-o",
        ])
        .arg(&out)
        .output()
        .expect("the binary runs");
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    let first_table = html.find("<table").expect("the tables");
    let verdict = html.find("class=\"verdict\"").expect("a verdict");
    let chart = html.find("<svg").expect("a chart");
    assert!(
        verdict < chart && chart < first_table,
        "the verdict and chart come first"
    );
    let rows = summary["results"].as_array().unwrap();
    for rate in [100_000.0, 400_000.0] {
        let winner = rows
            .iter()
            .filter(|r| r["rate"] == rate && r["effective_rate"] == rate)
            .min_by(|a, b| {
                a["rms_mean"]
                    .as_f64()
                    .unwrap()
                    .total_cmp(&b["rms_mean"].as_f64().unwrap())
            })
            .expect("a ranked method");
        let named = format!(
            "at {} <b>{}</b>",
            rate_label(rate),
            winner["method"].as_str().unwrap()
        );
        assert!(
            html[verdict..first_table].contains(&named),
            "{named} not in the verdict"
        );
    }
    // A method with a budget of its own is shown in the tables, not ranked, charted
    // or in the chart's legend (the paragraph after the chart).
    let legend_end = chart + html[chart..].find("</svg>").unwrap();
    let legend_end = legend_end + html[legend_end..].find("</p>").unwrap();
    assert!(!html[verdict..legend_end].contains("full-res-60hz"));
    assert!(html[verdict..legend_end].contains("traditional-frameless"));
    // The image strips fold by rate, so the page stays short: one section per rate,
    // only the first open.
    assert_eq!(html.matches("<details").count(), 2, "one section per rate");
    assert_eq!(html.matches("<details open>").count(), 1);
    std::fs::remove_dir_all(&out).unwrap();
}
