//! `--trace cpu|gpu|auto`: where rays are traced, and what the results record of it.
//! The tests that need a GPU adapter (Mesa's lavapipe will do) are ignored by default
//! and named `gpu_`; they fail, not skip, without one.

use std::{
    path::{Path, PathBuf},
    process::{Command, Output},
};

fn frameless(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_frameless"))
        .args(args)
        .output()
        .expect("the binary runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("frameless-trace-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("scratch folder");
    d
}

/// `frameless eval` of `methods` on toycar at 64x48 (0.25 s after a 0.5 s warm-up,
/// 16-spp ideals) with `extra` arguments (the rate among them), into `out`.
fn eval(methods: &str, extra: &[&str], out: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_frameless"))
        .args([
            "eval", "--scene", "toycar", "--size", "64x48", "--start", "1",
        ])
        .args(["--duration", "0.25", "--warmup", "0.5"])
        .args(["--method", methods, "--no-cache"])
        .args(extra)
        .arg("--out")
        .arg(out)
        .output()
        .expect("the binary runs")
}

/// The `summary.json` in `dir`.
fn summary(dir: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(dir.join("summary.json")).expect("summary.json");
    serde_json::from_str(&text).expect("JSON")
}

#[test]
fn every_command_that_traces_takes_trace_and_lists_its_values() {
    for cmd in ["bench", "still", "eval", "render", "view", "live", "table1"] {
        let o = frameless(&[cmd, "--trace", "bogus"]);
        let e = stderr(&o);
        assert!(!o.status.success(), "{cmd} took --trace bogus");
        assert!(
            e.contains("'bogus'") && e.contains("--trace") && e.contains("cpu, gpu, auto"),
            "{cmd}: {e}"
        );
    }
}

/// `view --headless` of `method` for one second on toycar at 64x48 with `extra`.
#[cfg(feature = "gpu")]
fn view(method: &str, extra: &[&str], out: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_frameless"))
        .args(["view", "--headless", "--method", method, "--size", "64x48"])
        .args(["--duration", "1", "--images", "1"])
        .args(extra)
        .arg("--out")
        .arg(out)
        .output()
        .expect("the binary runs")
}

/// Every real-time method traces on the GPU in the real-time pipeline and records it
/// (a method that could not would be refused before any work: the registry's tests
/// check that with the tests' own probe method, which traces nothing).
#[cfg(feature = "gpu")]
#[test]
#[ignore = "needs a GPU adapter (Mesa's lavapipe will do)"]
fn gpu_view_and_live_trace_on_the_gpu() {
    let d = scratch("realtime");
    let methods = [
        "traditional-frameless",
        "adaptive",
        "framed",
        "late-warp",
        "taa",
        "taa-warp",
    ];
    for method in methods {
        let out = d.join(method);
        let o = view(method, &["--trace", "gpu"], &out);
        assert!(o.status.success(), "{method}: {}", stderr(&o));
        let text = std::fs::read_to_string(out.join("stats.json")).expect("stats.json");
        let v: serde_json::Value = serde_json::from_str(&text).expect("JSON");
        let p = &v["pipeline"];
        assert_eq!(p["trace"]["device"], "gpu", "{method}: {v}");
        assert!(p.get("trace_failure").is_none(), "{method}: {v}");
        assert!(
            p["samples_per_s"].as_f64().unwrap_or(0.0) > 0.0,
            "{method}: {v}"
        );
    }
    let out = d.join("live");
    let o = Command::new(env!("CARGO_BIN_EXE_frameless"))
        .args([
            "live",
            "--method",
            "traditional-frameless,adaptive,late-warp,taa",
            "--trace",
            "gpu",
        ])
        .args(["--size", "64x48", "--duration", "0.5", "--warmup", "0.25"])
        .args(["--ideal-spp", "1", "--no-cache", "--out"])
        .arg(&out)
        .output()
        .expect("the binary runs");
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(summary(&out)["trace"]["device"], "gpu");
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn eval_records_the_cpu_tracer_by_default() {
    let d = scratch("cpu");
    let out = d.join("out");
    let o = eval(
        "traditional-frameless",
        &["--ideal-spp", "1", "--rate", "100k"],
        &out,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        summary(&out)["trace"],
        serde_json::json!({ "device": "cpu", "adapter": null })
    );
    let md = std::fs::read_to_string(out.join("summary.md")).expect("summary.md");
    assert!(md.contains("Tracer: cpu\n"), "{md}");
    let _ = std::fs::remove_dir_all(&d);
}

/// `--trace gpu` where no adapter matches is an error naming the option and what to
/// use instead, before any work; `auto` falls back to the CPU and says so once.
#[cfg(feature = "gpu")]
#[test]
fn trace_gpu_without_an_adapter_is_a_clear_error_and_auto_falls_back() {
    let d = scratch("noadapter");
    let out = d.join("out");
    let run = |choice: &str| {
        Command::new(env!("CARGO_BIN_EXE_frameless"))
            .env("WGPU_ADAPTER_NAME", "no adapter is called this")
            .args([
                "eval",
                "--size",
                "32x24",
                "--duration",
                "0.05",
                "--warmup",
                "0.05",
            ])
            .args(["--method", "traditional-frameless", "--rate", "100k"])
            .args(["--ideal-spp", "1", "--no-cache", "--trace", choice, "--out"])
            .arg(&out)
            .output()
            .expect("the binary runs")
    };
    let o = run("gpu");
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(
        e.contains("--trace gpu") && e.contains("no GPU adapter") && e.contains("--trace cpu"),
        "{e}"
    );
    assert!(!out.exists(), "the error comes before any work");
    let o = run("auto");
    assert!(o.status.success(), "{}", stderr(&o));
    let e = stderr(&o);
    assert_eq!(e.matches("tracing on the CPU").count(), 1, "said once: {e}");
    assert_eq!(summary(&out)["trace"]["device"], "cpu");
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn trace_help_says_what_each_choice_does() {
    let o = frameless(&["bench", "--help"]);
    let help = String::from_utf8_lossy(&o.stdout);
    for words in [
        "the CPU tracer, the reference",
        "a software one included",
        "a hardware GPU where there is one, else the CPU",
    ] {
        assert!(help.contains(words), "--trace help lacks {words}: {help}");
    }
}

#[cfg(feature = "gpu")]
#[test]
#[ignore = "needs a GPU adapter (Mesa's lavapipe will do)"]
fn gpu_bench_trace_gpu_records_the_adapter_and_its_figures() {
    let o = frameless(&[
        "bench", "--trace", "gpu", "--size", "64x48", "--rays", "4096", "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let r: serde_json::Value = serde_json::from_slice(&o.stdout).expect("bench JSON");
    assert_eq!(r["trace"]["device"], "gpu", "{r}");
    let adapter = r["trace"]["adapter"].as_str().expect("the adapter named");
    let g = &r["gpu_trace"];
    // The software label follows the adapter's kind as `describe` words it.
    assert_eq!(
        g["software"].as_bool(),
        Some(adapter.contains("software")),
        "{r}"
    );
    for figure in [
        "primary_mrays_per_s",
        "shaded_msamples_per_s",
        "secondary_mrays_per_s",
        "secondary_per_sample",
    ] {
        let v = g[figure].as_f64().unwrap_or(f64::NAN);
        // toycar's floor reflects and every hit casts a shadow ray: all positive.
        assert!(v.is_finite() && v > 0.0, "{figure} = {v}: {r}");
    }
}

#[cfg(feature = "gpu")]
#[test]
#[ignore = "needs a GPU adapter (Mesa's lavapipe will do)"]
fn gpu_still_traced_on_the_gpu_matches_the_cpu() {
    let dir = std::env::temp_dir().join(format!("frameless-still-trace-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let run = |trace: &str| {
        let out = dir.join(format!("{trace}.png"));
        let o = frameless(&[
            "still",
            "--size",
            "64x48",
            "--spp",
            "4",
            "--time",
            "1",
            "--trace",
            trace,
            "-o",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        (
            frameless::image::read_png_rgb8(&out).expect("a PNG"),
            stderr(&o),
        )
    };
    let (cpu, _) = run("cpu");
    let (gpu, said) = run("gpu");
    assert!(said.contains("tracing on "), "{said}");
    assert_eq!((cpu.0, cpu.1), (gpu.0, gpu.1));
    // The same samples traced alike: every 8-bit value within one level (a quarter
    // level apart before rounding can round apart).
    let worst = cpu
        .2
        .iter()
        .zip(&gpu.2)
        .map(|(a, b)| a.abs_diff(*b))
        .max()
        .unwrap();
    assert!(worst <= 1, "largest difference {worst} levels");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Per-frame RMS and FLIP of `dir`'s `frames.csv`, by method.
#[cfg(feature = "gpu")]
fn frame_metrics(dir: &Path) -> Vec<(String, f64, f64)> {
    let text = std::fs::read_to_string(dir.join("frames.csv")).expect("frames.csv");
    text.lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let num = |i: usize| f[i].parse::<f64>().unwrap_or(f64::NAN);
            (f[0].to_string(), num(4), num(6))
        })
        .collect()
}

/// `eval` of `methods` at `rate` with `--trace cpu` and `--trace gpu`: every frame's RMS
/// within 0.5 and FLIP within 0.01 (1%) of each other, and the strips' displayed
/// images within RMS 0.5 of each other; the GPU run records the GPU.
#[cfg(feature = "gpu")]
fn assert_eval_alike(name: &str, methods: &str, rate: &str) {
    let d = scratch(name);
    let (cpu, gpu) = (d.join("cpu"), d.join("gpu"));
    for (out, trace) in [(&cpu, "cpu"), (&gpu, "gpu")] {
        let o = eval(methods, &["--trace", trace, "--rate", rate], out);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let s = summary(&gpu);
    assert_eq!(s["trace"]["device"], "gpu", "{s}");
    assert!(s.get("trace_failure").is_none(), "{s}");
    let (a, b) = (frame_metrics(&cpu), frame_metrics(&gpu));
    assert_eq!(a.len(), b.len());
    for m in methods.split(',') {
        assert!(a.iter().any(|r| r.0 == m), "no frames of {m}");
    }
    for ((m, rms_a, flip_a), (_, rms_b, flip_b)) in a.iter().zip(&b) {
        assert!(
            (rms_a - rms_b).abs() <= 0.5,
            "{m}: RMS {rms_a} on the CPU, {rms_b} on the GPU"
        );
        assert!(
            (flip_a - flip_b).abs() <= 0.01,
            "{m}: FLIP {flip_a} on the CPU, {flip_b} on the GPU"
        );
    }
    let strips: Vec<_> = std::fs::read_dir(&cpu)
        .expect("the CPU run's folder")
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .filter(|n| n.starts_with("strip_"))
        .collect();
    assert!(!strips.is_empty());
    for name in strips {
        let x = frameless::image::read_png_rgb8(&cpu.join(&name)).expect("a PNG");
        let y = frameless::image::read_png_rgb8(&gpu.join(&name)).expect("a PNG");
        assert_eq!((x.0, x.1), (y.0, y.1));
        let sq: f64 =
            x.2.iter()
                .zip(&y.2)
                .map(|(p, q)| (*p as f64 - *q as f64).powi(2))
                .sum();
        let rms = (sq / x.2.len() as f64).sqrt();
        assert!(rms <= 0.5, "{name}: the strips differ by RMS {rms}");
    }
    let _ = std::fs::remove_dir_all(&d);
}

/// Issue 48's criterion: `eval --trace gpu` of traditional frameless and adaptive
/// within RMS 0.5 and 1% FLIP of `--trace cpu`.
#[cfg(feature = "gpu")]
#[test]
#[ignore = "needs a GPU adapter (Mesa's lavapipe will do)"]
fn gpu_eval_traced_on_the_gpu_matches_the_cpu() {
    assert_eval_alike("eval", "traditional-frameless,adaptive", "100k");
}

/// The same of every other simulated method (the late warps trace through the framed
/// methods, TAA's warp through TAA).
#[cfg(feature = "gpu")]
#[test]
#[ignore = "needs a GPU adapter (Mesa's lavapipe will do)"]
fn gpu_eval_of_the_other_methods_matches_the_cpu() {
    let methods = "framed-60hz,framed-full,full-res-60hz,point-tracking,taa,late-warp,taa-warp";
    assert_eval_alike("others", methods, "400k");
}

/// The ideal-cache hits of `frameless ARGS --cache-dir CACHE --out OUT`.
#[cfg(feature = "gpu")]
fn ideal_cache_hits(args: &[&str], cache: &Path, out: &Path) -> u64 {
    let o = Command::new(env!("CARGO_BIN_EXE_frameless"))
        .args(args)
        .arg("--cache-dir")
        .arg(cache)
        .arg("--out")
        .arg(out)
        .output()
        .expect("the binary runs");
    assert!(o.status.success(), "{}", stderr(&o));
    summary(out)["timing"]["ideal_cache_hits"]
        .as_u64()
        .expect("a count")
}

/// GPU ideals are cached and served again, and never served to a CPU run (nor the
/// CPU's to a GPU run).
#[cfg(feature = "gpu")]
#[test]
#[ignore = "needs a GPU adapter (Mesa's lavapipe will do)"]
fn gpu_ideals_are_cached_apart_from_the_cpus() {
    let d = scratch("cache");
    let cache = d.join("cache");
    let run = |trace: &str, k: u32| {
        let args = [
            "eval",
            "--size",
            "32x24",
            "--duration",
            "0.1",
            "--warmup",
            "0.1",
        ];
        let method = ["--method", "traditional-frameless", "--rate", "100k"];
        let args: Vec<&str> = [&args[..], &method, &["--trace", trace]].concat();
        ideal_cache_hits(&args, &cache, &d.join(format!("{trace}{k}")))
    };
    assert_eq!(run("gpu", 1), 0);
    assert_eq!(run("gpu", 2), 6, "the GPU's ideals were not served again");
    assert_eq!(run("cpu", 1), 0, "a CPU run was served the GPU's ideals");
    assert_eq!(run("cpu", 2), 6);
    assert_eq!(run("gpu", 3), 6);
    let _ = std::fs::remove_dir_all(&d);
}

#[cfg(feature = "gpu")]
#[test]
#[ignore = "needs a GPU adapter (lavapipe in CI)"]
fn gpu_live_ideals_are_traced_on_the_gpu_and_cached_apart() {
    let d = scratch("live-cache");
    let cache = d.join("cache");
    let run = |trace: &str, k: u32| {
        let args = [
            "live",
            "--method",
            "traditional-frameless",
            "--trace",
            trace,
        ];
        let size = ["--size", "32x24", "--duration", "0.25", "--warmup", "0.1"];
        let args: Vec<&str> = [&args[..], &size, &["--ideal-spp", "1"]].concat();
        ideal_cache_hits(&args, &cache, &d.join(format!("{trace}{k}")))
    };
    assert_eq!(run("gpu", 1), 0);
    let refreshes = run("gpu", 2);
    assert!(refreshes > 0, "the GPU's ideals were not served again");
    assert_eq!(run("cpu", 1), 0, "a CPU run was served the GPU's ideals");
    assert_eq!(run("cpu", 2), refreshes);
    let _ = std::fs::remove_dir_all(&d);
}
