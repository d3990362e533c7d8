//! `frameless table1` end to end on a tiny configuration (the real table takes tens of
//! minutes): the combined summary has one evaluation per animation, the paper's numbers
//! appear beside ours, and bad arguments fail before any work starts.

use std::path::PathBuf;
use std::process::Command;

/// The BART directory. The tests that need it are ignored by default; run without the
/// scenes they fail, never pass unchecked.
fn bart_dir() -> PathBuf {
    let dir = std::env::var_os("FRAMELESS_BART_DIR")
        .expect("FRAMELESS_BART_DIR must name the BART scene folder (e.g. ../shared/scenes/bart)");
    let dir = PathBuf::from(dir);
    assert!(
        dir.join("kitchen/kitchen.aff").is_file(),
        "FRAMELESS_BART_DIR={} has no kitchen/kitchen.aff",
        dir.display()
    );
    dir
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("frameless-table1-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

#[test]
#[ignore = "needs the BART scenes: set FRAMELESS_BART_DIR"]
fn bart_tiny_table_has_every_animation_and_the_paper_beside_it() {
    let bart = bart_dir();
    let out = tmp("out");
    let cache = tmp("cache");
    let st = Command::new(env!("CARGO_BIN_EXE_frameless"))
        .args(["table1", "--bart"])
        .arg(&bart)
        .args([
            "--size",
            "32x32",
            "--duration",
            "0.05",
            "--rates",
            "100k",
            "--ideal-spp",
            "1",
            "--methods",
            "traditional-frameless,adaptive-paper,full-res-60hz",
        ])
        .arg("--cache-dir")
        .arg(&cache)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let anims = v["animations"].as_array().unwrap();
    let names: Vec<_> = anims.iter().map(|a| a["name"].as_str().unwrap()).collect();
    assert_eq!(names, ["interactive", "bart", "toycar", "still"]);
    for a in anims {
        let results = a["summary"]["results"].as_array().unwrap();
        assert_eq!(results.len(), 3, "{}", a["name"]);
        for r in results {
            let rms = r["rms_mean"].as_f64().unwrap();
            assert!(rms.is_finite() && rms > 0.0);
        }
        // Each animation also has its own full eval output.
        let dir = out.join(a["name"].as_str().unwrap());
        assert!(dir.join("report.html").is_file() && dir.join("frames.csv").is_file());
    }
    let md = std::fs::read_to_string(out.join("table.md")).unwrap();
    // The paper's adaptive Interactive 100K figure sits beside ours.
    assert!(md.contains("(34.4)"), "{md}");
    assert!(out.join("report.html").is_file());
    let _ = std::fs::remove_dir_all(&out);
    let _ = std::fs::remove_dir_all(&cache);
}

/// The output folder holds one run: a second run with other animations replaces the
/// first run's folders instead of adding to them.
#[test]
#[ignore = "needs the BART scenes: set FRAMELESS_BART_DIR"]
fn bart_a_second_run_replaces_the_first_whole() {
    let bart = bart_dir();
    let out = tmp("replace");
    let cache = tmp("replace-cache");
    let run = |animations: &str| {
        let st = Command::new(env!("CARGO_BIN_EXE_frameless"))
            .args(["table1", "--bart"])
            .arg(&bart)
            .args(["--size", "16x16", "--duration", "0.05", "--rates", "100k"])
            .args(["--ideal-spp", "1", "--methods", "traditional-frameless"])
            .args(["--animations", animations])
            .arg("--cache-dir")
            .arg(&cache)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        assert!(
            st.status.success(),
            "{}",
            String::from_utf8_lossy(&st.stderr)
        );
        let mut names: Vec<String> = std::fs::read_dir(&out)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    };
    let files = [
        ".frameless-output",
        "report.html",
        "summary.json",
        "table.md",
    ];
    assert_eq!(
        run("interactive,bart"),
        [
            files[0],
            "bart",
            "interactive",
            files[1],
            files[2],
            files[3]
        ]
    );
    assert_eq!(
        run("still"),
        [files[0], files[1], "still", files[2], files[3]]
    );
    let _ = std::fs::remove_dir_all(&out);
    let _ = std::fs::remove_dir_all(&cache);
}

#[test]
fn bad_arguments_fail_before_work() {
    let out = tmp("bad");
    let run = |extra: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_frameless"))
            .arg("table1")
            .args(extra)
            .arg("--out")
            .arg(&out)
            .env_remove("FRAMELESS_BART_DIR")
            .output()
            .unwrap()
    };
    let st = run(&["--bart", "/nonexistent"]);
    assert!(!st.status.success());
    assert!(String::from_utf8_lossy(&st.stderr).contains("kitchen/kitchen.aff"));
    let st = run(&[]);
    assert!(!st.status.success());
    assert!(String::from_utf8_lossy(&st.stderr).contains("--bart"));
    assert!(!out.exists(), "no output may be written for bad arguments");
}

#[test]
#[ignore = "needs the BART scenes: set FRAMELESS_BART_DIR"]
fn bart_bad_animations_and_rates_fail_before_work() {
    let out = tmp("bad-bart");
    let b = bart_dir().to_string_lossy().to_string();
    let run = |extra: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_frameless"))
            .args(["table1", "--bart", &b])
            .args(extra)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap()
    };
    let st = run(&["--animations", "bart,dance"]);
    assert!(!st.status.success());
    assert!(String::from_utf8_lossy(&st.stderr).contains("unknown animation 'dance'"));
    let st = run(&["--rates", "fast"]);
    assert!(!st.status.success());
    assert!(!out.exists(), "no output may be written for bad arguments");
}

/// The Still animation's view of the kitchen does not change over its warm-up and
/// window: images at several instants are identical, pixel for pixel.
#[test]
#[ignore = "needs the BART scenes: set FRAMELESS_BART_DIR"]
fn bart_the_still_animation_is_still() {
    use frameless::{evaluation::table1, render::still, scene::CameraPath};
    let bart = bart_dir();
    let a = table1::animation("still").expect("a still animation");
    let path = CameraPath::parse("kitchen_still.csv", a.camera_path.expect("its camera"))
        .expect("camera path parses");
    let tracer = tracer_with(&bart, path);
    let at = |t: f64| still::render(&tracer, t, 1, 1, &|_| {}).pixels;
    let first = at(a.start - a.warmup);
    let steps = 8;
    for k in 1..=steps {
        let t = a.start - a.warmup + (a.warmup + a.duration) * k as f64 / steps as f64;
        assert!(at(t) == first, "the view changes at t = {t}");
    }
    // The same check sees the toy car in the Toycar close-up.
    let toycar = table1::animation("toycar").expect("toycar");
    let path = CameraPath::parse("kitchen_toycar.csv", toycar.camera_path.expect("camera"))
        .expect("camera path parses");
    let moving = tracer_with(&bart, path);
    let at = |t: f64| still::render(&moving, t, 1, 1, &|_| {}).pixels;
    assert!(
        at(toycar.start) != at(toycar.start + toycar.duration / 2.0),
        "the check can see motion"
    );
}

fn tracer_with(
    bart: &std::path::Path,
    path: frameless::scene::CameraPath,
) -> frameless::trace::Tracer {
    let scene = frameless::scene::load(&bart.join("kitchen/kitchen.aff").to_string_lossy())
        .expect("kitchen loads");
    frameless::trace::Tracer::new(std::sync::Arc::new(scene), 96, 96, Default::default())
        .with_camera_path(Some(path))
}

/// The options `table1` shares with `eval`: `--no-cache` reads and writes no ideal
/// image, and `--warmup` and `--camera-path` replace every animation's own.
#[test]
#[ignore = "needs the BART scenes: set FRAMELESS_BART_DIR"]
fn bart_no_cache_warmup_and_camera_path_apply_to_every_animation() {
    let bart = bart_dir();
    let out = tmp("shared-options");
    let cache = tmp("shared-options-cache");
    let path =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("assets/camera_paths/kitchen_toycar.csv");
    let st = Command::new(env!("CARGO_BIN_EXE_frameless"))
        .args(["table1", "--bart"])
        .arg(&bart)
        .args([
            "--animations",
            "interactive,bart",
            "--size",
            "16",
            "--duration",
            "0.05",
        ])
        .args([
            "--rate",
            "100k",
            "--ideal-spp",
            "1",
            "--method",
            "traditional-frameless",
        ])
        .args(["--no-cache", "--warmup", "0.1", "--camera-path"])
        .arg(&path)
        .arg("--cache-dir")
        .arg(&cache)
        .arg("-o")
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    assert!(!cache.exists(), "--no-cache wrote the cache");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    for a in v["animations"].as_array().unwrap() {
        let s = &a["summary"];
        assert_eq!(s["warmup"].as_f64(), Some(0.1), "{}", a["name"]);
        assert_eq!(s["camera_path"].as_bool(), Some(true), "{}", a["name"]);
    }
    let _ = std::fs::remove_dir_all(&out);
}
