//! The evaluation report as a reader gets it: every file it names is there, each strip
//! panel says which method it shows, and, where Chromium is installed, a headless
//! browser opens the report and every image in it loads.

use std::{
    path::{Path, PathBuf},
    process::{Command, Stdio},
    sync::Arc,
    time::{Duration, Instant},
};

use frameless::{
    evaluation::{self, report, EvalConfig, Silent},
    methods::MethodKind,
    scene::builtin,
    trace::TextureFilter,
};

const METHODS: [MethodKind; 2] = [MethodKind::TraditionalFrameless, MethodKind::Adaptive];

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("frameless-report-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

/// A small evaluation written as a report folder at `dir`.
fn write_report(dir: &Path) {
    let cfg = {
        let mut c = EvalConfig::new("toycar <small>");
        c.start = 0.5;
        c.duration = 0.1;
        c.display.size = frameless::settings::Size(40, 30);
        c.rates = vec![100_000.0, 200_000.0];
        c.methods = METHODS.to_vec();
        c.quality.seed = 1;
        c.reference.ideal_spp = 2;
        c.warmup = 0.2;
        c.display.refresh_hz = 60.0;
        c.quality.max_depth = 3;
        c.quality.texture_filter = TextureFilter::None;
        c.strip_frames = vec![1, 4];
        c.flip_every = 1;
        c
    };
    let scene = Arc::new(builtin::load("toycar").expect("built-in scene"));
    let mut out = evaluation::run(scene, &cfg, &Silent).expect("evaluation runs");
    report::write_all(&mut out, dir).expect("outputs written");
}

/// Every `src="…"` and `href="…"` of an HTML text.
fn references(html: &str) -> Vec<String> {
    let mut refs = Vec::new();
    for attr in ["src=\"", "href=\""] {
        for (i, _) in html.match_indices(attr) {
            let rest = &html[i + attr.len()..];
            refs.push(rest[..rest.find('"').expect("closed attribute")].to_string());
        }
    }
    refs
}

#[test]
fn every_file_the_report_names_is_there_and_every_panel_is_labelled() {
    let dir = scratch("links");
    write_report(&dir);
    let html = std::fs::read_to_string(dir.join("report.html")).unwrap();
    let refs = references(&html);
    assert!(refs.len() > 10, "{refs:?}");
    for r in &refs {
        assert!(
            dir.join(r).is_file(),
            "report.html names {r}, which is not there"
        );
    }
    for table in [
        "Mean RMS error",
        "Mean PSNR",
        "Mean FLIP",
        "Sustained error",
        "Transient error",
        "Instability",
    ] {
        assert!(html.contains(&format!("<h2>{table}")), "no {table} table");
    }
    // Two rates × two strip frames, each with its FLIP maps beside the images.
    for rate in ["100K", "200K"] {
        for frame in ["0001", "0004"] {
            for kind in ["strip", "flip"] {
                let f = format!("{kind}_{rate}_{frame}.png");
                assert!(refs.contains(&f), "{f} not in the report");
            }
        }
    }
    // Each panel names its method: ideal and every method once per strip.
    for label in ["ideal", "traditional-frameless", "adaptive"] {
        let n = html.matches(&format!("<figcaption><b>{label}</b>")).count();
        assert_eq!(n, 4, "{label} labels {n} panels");
    }
    // The scene name is text, not markup.
    assert!(html.contains("toycar &lt;small&gt;") && !html.contains("<small>"));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_report_made_again_leaves_out_what_was_deleted() {
    let dir = scratch("rewrite");
    write_report(&dir);
    let gone = "strip_200K_0004.png";
    std::fs::remove_file(dir.join(gone)).unwrap();
    std::fs::remove_file(dir.join("summary.md")).unwrap();
    // Older outputs named the instability column `flicker`: they are still read.
    let csv = std::fs::read_to_string(dir.join("frames.csv")).unwrap();
    std::fs::write(
        dir.join("frames.csv"),
        csv.replacen("instability", "flicker", 1),
    )
    .unwrap();
    let p = report::rewrite(&dir).expect("report made again");
    let html = std::fs::read_to_string(p).unwrap();
    let refs = references(&html);
    for r in &refs {
        assert!(
            dir.join(r).is_file(),
            "report.html names {r}, which is not there"
        );
    }
    assert!(!refs.iter().any(|r| r == gone || r == "summary.md"));
    assert!(refs.iter().any(|r| r == "strip_200K_0001.png"));
    assert!(html.contains("RMS "), "per-panel values from frames.csv");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The report's HTML from the heading that starts with `heading` to the end of the
/// table under it.
fn table_after<'a>(html: &'a str, heading: &str) -> &'a str {
    let at = html.find(heading).unwrap_or_else(|| panic!("no {heading}"));
    &html[at..at + html[at..].find("</table>").unwrap()]
}

#[test]
fn a_folder_written_before_the_sustained_and_transient_errors_still_makes_a_report() {
    let dir = scratch("before-split");
    write_report(&dir);
    let fresh = std::fs::read_to_string(dir.join("report.html")).unwrap();
    let table = |html: &str| table_after(html, "<h2>Sustained error").to_string();
    assert!(!table(&fresh).contains("<td>–</td>"), "{}", table(&fresh));
    // Drop the two columns from frames.csv and the two means from summary.json, as an
    // earlier version wrote them.
    let csv = std::fs::read_to_string(dir.join("frames.csv")).unwrap();
    assert!(csv
        .lines()
        .next()
        .unwrap()
        .ends_with(",sustained,transient"));
    let old: String = csv
        .lines()
        .map(|l| {
            let fields: Vec<&str> = l.split(',').collect();
            fields[..fields.len() - 2].join(",") + "\n"
        })
        .collect();
    std::fs::write(dir.join("frames.csv"), old).unwrap();
    let mut summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    for r in summary["results"].as_array_mut().unwrap() {
        let r = r.as_object_mut().unwrap();
        assert!(r.remove("sustained_mean").is_some() && r.remove("transient_mean").is_some());
    }
    std::fs::write(dir.join("summary.json"), summary.to_string()).unwrap();
    let p = report::rewrite(&dir).expect("report made again from the older files");
    let html = std::fs::read_to_string(p).unwrap();
    // Not measured then: a dash, not a zero.
    assert!(table(&html).contains("<td>–</td>"), "{}", table(&html));
    assert!(!table(&html).contains("0.00"), "{}", table(&html));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_video_metric_written_beside_an_evaluation_shows_in_its_report() {
    let dir = scratch("vdp");
    write_report(&dir);
    let html = std::fs::read_to_string(dir.join("report.html")).unwrap();
    assert!(!html.contains("Video JOD"), "no table without vdp.json");
    // As `python -m frameless.vdp` writes it.
    std::fs::write(
        dir.join("vdp.json"),
        r#"{"metric": "ColorVideoVDP", "version": "0.5.7", "display": "standard_fhd",
            "frames_per_second": 60.0, "results": [
            {"method": "traditional-frameless", "rate": 100000.0, "jod": 8.02},
            {"method": "adaptive", "rate": 100000.0, "jod": 9.41},
            {"method": "traditional-frameless", "rate": 200000.0, "jod": 8.5},
            {"method": "adaptive", "rate": 200000.0, "jod": 8.25}]}"#,
    )
    .unwrap();
    let html = std::fs::read_to_string(report::rewrite(&dir).expect("report made again")).unwrap();
    let table = table_after(
        &html,
        "<h2>Video JOD (ColorVideoVDP 0.5.7, display standard_fhd",
    );
    assert!(
        table.contains("<td class=\"best\">9.41</td>") && table.contains("<td>8.02</td>"),
        "{table}"
    );
    assert!(
        table.contains("<td class=\"best\">8.50</td>") && table.contains("<td>8.25</td>"),
        "{table}"
    );
    assert!(
        !html.contains("JOD per visual channel"),
        "no channels in this file"
    );
    // With each channel's JOD alone, as `python -m frameless.vdp` now keeps them: a
    // table of them, each row's lowest in bold.
    std::fs::write(
        dir.join("vdp.json"),
        r#"{"metric": "ColorVideoVDP", "version": "0.5.7", "display": "standard_fhd",
            "results": [
            {"method": "adaptive", "rate": 100000.0, "jod": 9.41, "jod_parts":
              {"achromatic_sustained": 9.5, "red_green": 9.9, "yellow_violet": 9.95,
               "achromatic_transient": 9.62}},
            {"method": "traditional-frameless", "rate": 100000.0, "jod": 8.02, "jod_parts":
              {"achromatic_sustained": 8.2, "red_green": 9.8, "yellow_violet": 9.7,
               "achromatic_transient": 8.1}}]}"#,
    )
    .unwrap();
    let html = std::fs::read_to_string(report::rewrite(&dir).unwrap()).unwrap();
    let table = table_after(&html, "<h3>JOD per visual channel");
    assert!(table.contains("<th>achromatic sustained</th>"), "{table}");
    assert!(
        table.contains("<td class=\"best\">9.50</td>") && table.contains("<td>9.62</td>"),
        "{table}"
    );
    assert!(
        table.contains("<td class=\"best\">8.10</td>") && table.contains("<td>8.20</td>"),
        "{table}"
    );
    // A channel's JOD above 10 is refused like a method's.
    let bad = std::fs::read_to_string(dir.join("vdp.json"))
        .unwrap()
        .replace("9.95", "10.5");
    std::fs::write(dir.join("vdp.json"), bad).unwrap();
    let html = std::fs::read_to_string(report::rewrite(&dir).unwrap()).unwrap();
    assert!(
        html.contains("vdp.json is there but could not be read"),
        "a bad part taken"
    );
    // A file that cannot be read is named, not taken.
    std::fs::write(dir.join("vdp.json"), "{").unwrap();
    let html = std::fs::read_to_string(report::rewrite(&dir).unwrap()).unwrap();
    assert!(
        html.contains("vdp.json is there but could not be read") && !html.contains("Video JOD")
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Chromium, where installed: `$FRAMELESS_CHROMIUM`, else the usual names on the PATH.
fn chromium() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("FRAMELESS_CHROMIUM") {
        return Some(p.into());
    }
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path).find_map(|d| {
        [
            "chromium",
            "chromium-browser",
            "google-chrome",
            "google-chrome-stable",
        ]
        .iter()
        .map(|n| d.join(n))
        .find(|p| p.is_file())
    })
}

/// A copy of the report beside it that, once loaded, appends a line saying how many
/// of its images there are and which did not load.
const CHECK: &str = "<script>window.addEventListener('load',()=>{const imgs=[...document.images];\
const bad=imgs.filter(i=>!(i.complete&&i.naturalWidth>0)).map(i=>i.getAttribute('src'));\
const p=document.createElement('pre');p.id='frameless-check';\
p.textContent='images '+imgs.length+' broken '+bad.length+': '+bad.join(' ');\
document.body.appendChild(p);});</script></body>";

/// Open `page` in headless Chromium and return the check line the page wrote.
fn images_loaded(browser: &Path, page: &Path) -> String {
    let profile = page.with_extension("profile");
    let mut child = Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--virtual-time-budget=10000",
            "--dump-dom",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg(format!("file://{}", page.display()))
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("chromium starts");
    let t0 = Instant::now();
    while child.try_wait().expect("waitable").is_none() {
        if t0.elapsed() > Duration::from_secs(120) {
            let _ = child.kill();
            panic!("chromium did not finish in 120 s");
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    let dom = child.wait_with_output().expect("output").stdout;
    let dom = String::from_utf8_lossy(&dom);
    let start = dom
        .find("<pre id=\"frameless-check\">")
        .unwrap_or_else(|| panic!("no check line in the page: {dom:.2000}"));
    let line = &dom[start + "<pre id=\"frameless-check\">".len()..];
    line[..line.find('<').unwrap_or(line.len())].to_string()
}

#[test]
#[ignore = "needs Chromium: chromium on PATH or FRAMELESS_CHROMIUM"]
fn browser_chromium_loads_every_image_of_the_report() {
    let browser = chromium()
        .expect("chromium not found: install it, or set FRAMELESS_CHROMIUM to a Chromium binary");
    let dir = scratch("chromium");
    write_report(&dir);
    let html = std::fs::read_to_string(dir.join("report.html")).unwrap();
    let images = html.matches("<img ").count();
    let check = dir.join("check.html");
    std::fs::write(&check, html.replace("</body>", CHECK)).unwrap();
    let line = images_loaded(&browser, &check);
    assert_eq!(line.trim(), format!("images {images} broken 0:"), "{line}");
    // The check sees a missing image: it can fail.
    let broken = dir.join("broken.html");
    std::fs::write(
        &broken,
        html.replacen("strip_100K_0001.png", "missing.png", 1)
            .replace("</body>", CHECK),
    )
    .unwrap();
    let line = images_loaded(&browser, &broken);
    assert!(line.contains("broken 1: missing.png"), "{line}");
    let _ = std::fs::remove_dir_all(&dir);
}
