//! One vocabulary across commands: one name per method, `-o` for `--out`, a square
//! `--size N`, and one time flag, `--duration`, with `--seconds` (live's and view's old
//! name) accepted by every command that takes a length of time.

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

/// The same method name in every command: `framed-full` runs under the simulated clock
/// (`eval`) and in the real-time pipeline (`view`), and `framed`, the pipeline's old
/// name for it, still runs in both with a note naming the new one.
#[test]
fn one_name_per_method_and_the_old_name_noted() {
    for (method, noted) in [("framed-full", false), ("framed", true)] {
        let out = tmp(&format!("eval-{method}"));
        let o = out.to_str().unwrap();
        let eval = [
            "eval",
            "--size",
            "16",
            "--duration",
            "0.05",
            "--rate",
            "100k",
            "--no-cache",
            "--method",
            method,
            "-o",
            o,
        ];
        let view = [
            "view",
            "--headless",
            "--duration",
            "0.05",
            "--size",
            "16",
            "--method",
            method,
            "-o",
            o,
        ];
        for args in [&eval[..], &view[..]] {
            let run = frameless(args);
            let err = String::from_utf8_lossy(&run.stderr);
            assert!(run.status.success(), "{args:?}: {err}");
            let note = "note: method `framed` is called `framed-full` now";
            assert_eq!(err.contains(note), noted, "{args:?}: {err}");
            std::fs::remove_dir_all(&out).unwrap();
        }
    }
}

/// One way to ask for OpenEXR: `--format exr` in `still`, `render` and `eval`; the old
/// ways (`still --out x.exr`, `eval --exr`) still work, `eval --exr` with a note.
#[test]
fn format_exr_is_one_option_and_the_old_ways_still_work() {
    let out = tmp("format");
    std::fs::create_dir_all(&out).unwrap();
    let file = |name: &str| out.join(name).to_str().unwrap().to_string();
    let still = ["still", "--size", "8", "--spp", "1"];
    ok(&[&still[..], &["--format", "exr", "-o", &file("a.exr")]].concat());
    ok(&[&still[..], &["-o", &file("b.exr")]].concat());
    for f in ["a.exr", "b.exr"] {
        frameless::image::read_exr(&out.join(f)).expect("an OpenEXR file");
    }
    let clash = frameless(&[&still[..], &["--format", "png", "-o", &file("c.exr")]].concat());
    let err = String::from_utf8_lossy(&clash.stderr);
    assert!(
        !clash.status.success() && err.contains("--format png"),
        "{err}"
    );
    assert!(!out.join("c.exr").exists());
    let eval = [
        "eval",
        "--size",
        "8",
        "--duration",
        "0.05",
        "--rate",
        "100k",
        "--no-cache",
        "--method",
        "traditional-frameless",
    ];
    for (flag, noted) in [(&["--format", "exr"][..], false), (&["--exr"][..], true)] {
        let dir = file("eval");
        let run = frameless(&[&eval[..], flag, &["-o", &dir]].concat());
        let err = String::from_utf8_lossy(&run.stderr);
        assert!(run.status.success(), "{flag:?}: {err}");
        assert_eq!(
            err.contains("note: --exr is `--format exr` now"),
            noted,
            "{err}"
        );
        let exr = std::fs::read_dir(out.join("eval/exr"))
            .expect("exr/ written")
            .count();
        assert!(exr > 0, "{flag:?}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
    std::fs::remove_dir_all(&out).unwrap();
}

/// `still` has every other command's defaults: the same size and seed as `eval`, so
/// its image is the ideal image `eval` scores against at that time.
#[test]
fn still_has_the_defaults_of_every_other_command() {
    let out = tmp("still-defaults");
    std::fs::create_dir_all(&out).unwrap();
    let explicit = out.join("explicit.png");
    let default = out.join("default.png");
    let size = format!(
        "{}x{}",
        frameless::settings::SIZE.0,
        frameless::settings::SIZE.1
    );
    let seed = frameless::settings::SEED.to_string();
    ok(&[
        "still",
        "--spp",
        "1",
        "--size",
        &size,
        "--seed",
        &seed,
        "-o",
        explicit.to_str().unwrap(),
    ]);
    ok(&["still", "--spp", "1", "-o", default.to_str().unwrap()]);
    let read = |p: &std::path::Path| frameless::image::read_png_rgb8(p).expect("a PNG");
    assert_eq!(read(&default), read(&explicit));
    std::fs::remove_dir_all(&out).unwrap();
}
