//! `--trace cpu|gpu|auto`: where rays are traced. Only `bench` takes it so far; the
//! test that needs a GPU adapter (Mesa's lavapipe will do) is ignored by default and
//! named `gpu_`.

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
fn trace_is_taken_by_bench_only_and_lists_its_values() {
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
