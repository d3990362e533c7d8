//! `frameless table1` end to end on a tiny configuration (the real table takes tens of
//! minutes): the combined summary has one evaluation per animation, the paper's numbers
//! appear beside ours, and bad arguments fail before any work starts.

use std::path::PathBuf;
use std::process::Command;

fn bart_dir() -> Option<PathBuf> {
    let Some(dir) = std::env::var_os("FRAMELESS_BART_DIR") else {
        eprintln!("note: FRAMELESS_BART_DIR is unset; skipping the table1 test");
        return None;
    };
    let dir = PathBuf::from(dir);
    assert!(
        dir.join("kitchen/kitchen.aff").is_file(),
        "FRAMELESS_BART_DIR={} has no kitchen/kitchen.aff",
        dir.display()
    );
    Some(dir)
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("frameless-table1-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

#[test]
fn tiny_table_has_every_animation_and_the_paper_beside_it() {
    let Some(bart) = bart_dir() else { return };
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
            "traditional-frameless,adaptive,full-res-60hz",
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
    assert_eq!(names, ["interactive", "bart", "toycar"]);
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
    if let Some(bart) = bart_dir() {
        let b = bart.to_string_lossy().to_string();
        let st = run(&["--bart", &b, "--animations", "bart,dance"]);
        assert!(!st.status.success());
        assert!(String::from_utf8_lossy(&st.stderr).contains("unknown animation 'dance'"));
        let st = run(&["--bart", &b, "--rates", "fast"]);
        assert!(!st.status.success());
    }
    assert!(!out.exists(), "no output may be written for bad arguments");
}
