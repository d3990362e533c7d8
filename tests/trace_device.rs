//! `--trace cpu|gpu|auto`: where rays are traced. Only `bench` and `still` take it so
//! far; the tests that need a GPU adapter (Mesa's lavapipe will do) are ignored by
//! default and named `gpu_`.

use std::process::{Command, Output};

fn frameless(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_frameless"))
        .args(args)
        .output()
        .expect("the binary runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn trace_is_taken_by_bench_and_still_only_and_lists_its_values() {
    let o = frameless(&["bench", "--trace", "bogus"]);
    let e = stderr(&o);
    assert!(!o.status.success());
    assert!(
        e.contains("'bogus'") && e.contains("--trace") && e.contains("cpu, gpu, auto"),
        "{e}"
    );
    // A command that cannot trace on the GPU refuses the option rather than ignore it.
    for cmd in ["eval", "render", "view", "live", "table1"] {
        let o = frameless(&[cmd, "--trace", "gpu"]);
        assert!(!o.status.success(), "{cmd} took --trace");
        assert!(stderr(&o).contains("'--trace'"), "{cmd}: {}", stderr(&o));
    }
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
