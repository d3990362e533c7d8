//! One vocabulary across commands: `-o` for `--out`, a square `--size N`, and one time
//! flag, `--duration`, with `--seconds` (live's and view's old name) accepted by every
//! command that takes a length of time.

use std::process::{Command, Output};

fn tmp(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("frameless-names-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

fn frameless(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_frameless"))
        .args(args)
        .output()
        .expect("the binary runs")
}

fn ok(args: &[&str]) {
    let out = frameless(args);
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn summary(dir: &std::path::Path) -> serde_json::Value {
    let text = std::fs::read_to_string(dir.join("summary.json")).expect("summary.json");
    serde_json::from_str(&text).expect("JSON")
}

#[test]
fn eval_takes_a_square_size_the_old_time_flag_and_short_out() {
    let out = tmp("eval");
    let o = out.to_str().unwrap();
    let common = [
        "--scene",
        "toycar",
        "--rate",
        "100k",
        "--method",
        "traditional-frameless",
    ];
    ok(&[
        &["eval", "--size", "16", "--seconds", "0.05", "-o", o][..],
        &common[..],
    ]
    .concat());
    let s = summary(&out);
    assert_eq!(
        (s["width"].as_u64(), s["height"].as_u64()),
        (Some(16), Some(16))
    );
    assert_eq!(s["duration"].as_f64(), Some(0.05));
    std::fs::remove_dir_all(&out).unwrap();
}

#[test]
fn view_and_live_take_duration_and_their_old_name() {
    for (flag, name) in [("--duration", "new"), ("--seconds", "old")] {
        let out = tmp(&format!("view-{name}"));
        let o = out.to_str().unwrap();
        ok(&["view", "--headless", flag, "0.05", "--size", "16", "-o", o]);
        assert!(out.join("stats.json").is_file(), "{flag}");
        std::fs::remove_dir_all(&out).unwrap();
    }
    // The limit check names the flag by the name the library knows it by.
    let out = frameless(&["live", "--duration", "0"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("must be in (0,"), "{err}");
}

#[test]
fn sizes_that_are_not_sizes_are_refused_with_both_forms_named() {
    let out = frameless(&["eval", "--size", "big"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("WxH") && err.contains("NxN"), "{err}");
}
