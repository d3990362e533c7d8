//! `--recon cpu|gpu|auto`: where the adaptive reconstructor runs, and what the results
//! record of it. The tests that need a GPU adapter (Mesa's lavapipe will do) are
//! ignored by default and named `gpu_`; `cargo test -- --ignored gpu_` runs them.

use std::{
    path::{Path, PathBuf},
    process::{Command, Output},
};

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("frameless-recon-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("scratch folder");
    d
}

/// `frameless eval` of one method on the built-in `toycar` at 64x48 for six refreshes,
/// with `extra` arguments, into `out`.
fn eval(method: &str, extra: &[&str], out: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_frameless"))
        .args([
            "eval", "--scene", "toycar", "--size", "64x48", "--start", "0.5",
        ])
        .args(["--duration", "0.1", "--warmup", "0.1", "--rate", "100k"])
        .args(["--method", method, "--ideal-spp", "1", "--no-cache"])
        .args(extra)
        .arg("--out")
        .arg(out)
        .output()
        .expect("the binary runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn succeeded(o: &Output) {
    assert!(o.status.success(), "{}", stderr(o));
}

/// The `recon` object of the `summary.json` in `dir`.
fn recon_of(dir: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(dir.join("summary.json")).expect("summary.json");
    let v: serde_json::Value = serde_json::from_str(&text).expect("JSON");
    v["recon"].clone()
}

#[test]
fn eval_records_the_cpu_reconstructor_by_default() {
    let d = scratch("cpu");
    for (name, extra) in [("default", &[][..]), ("asked", &["--recon", "cpu"][..])] {
        let out = d.join(name);
        let o = eval("adaptive-paper", extra, &out);
        succeeded(&o);
        assert_eq!(
            recon_of(&out),
            serde_json::json!({ "device": "cpu", "adapter": null }),
            "{name}"
        );
        let md = std::fs::read_to_string(out.join("summary.md")).expect("summary.md");
        assert!(md.contains("Reconstructor: cpu\n"), "{md}");
        // The CPU asked for is the CPU had: nothing to say.
        assert!(!stderr(&o).contains("reconstructing on"), "{}", stderr(&o));
    }
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn recon_is_checked_before_any_work() {
    let d = scratch("bogus");
    let out = d.join("out");
    let o = eval("adaptive-paper", &["--recon", "bogus"], &out);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(e.contains("--recon"), "{e}");
    for choice in ["cpu", "gpu", "auto"] {
        assert!(e.contains(choice), "{e} does not list {choice}");
    }
    assert!(!out.exists(), "no output for a refused option");
    let _ = std::fs::remove_dir_all(&d);
}

/// `auto` takes a hardware GPU where there is one and says so, and says it falls back
/// to the CPU where there is none; the summary records what it got.
#[test]
fn recon_auto_reconstructs_where_it_says() {
    let d = scratch("auto");
    let out = d.join("out");
    let o = eval("adaptive-paper", &["--recon", "auto"], &out);
    succeeded(&o);
    let e = stderr(&o);
    let note = "note: no hardware GPU adapter; reconstructing on the CPU";
    let recon = recon_of(&out);
    if e.contains(note) {
        assert_eq!(recon["device"], "cpu", "{e}");
        assert_eq!(e.matches(note).count(), 1, "said once: {e}");
    } else {
        assert_eq!(recon["device"], "gpu", "{e}");
        let adapter = recon["adapter"].as_str().expect("the adapter is recorded");
        assert!(e.contains(&format!("reconstructing on {adapter}")), "{e}");
        assert!(
            !adapter.contains("software"),
            "auto took a software adapter: {e}"
        );
    }
    let _ = std::fs::remove_dir_all(&d);
}

/// Without the `gpu` feature, `--recon gpu` is an error that says why and what to use.
#[cfg(not(feature = "gpu"))]
#[test]
fn recon_gpu_without_the_feature_is_a_clear_error() {
    let d = scratch("nofeature");
    let out = d.join("out");
    let o = eval("adaptive-paper", &["--recon", "gpu"], &out);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(
        e.contains("built without the 'gpu' feature") && e.contains("--recon cpu"),
        "{e}"
    );
    assert!(!out.exists(), "the error comes before any work");
    // `auto` runs on the CPU, and says so.
    succeeded(&eval("adaptive-paper", &["--recon", "auto"], &out));
    assert_eq!(recon_of(&out)["device"], "cpu");
    let _ = std::fs::remove_dir_all(&d);
}

/// With the feature, `--recon gpu` where no adapter matches is an error that says what
/// to install or use instead.
#[cfg(feature = "gpu")]
#[test]
fn recon_gpu_without_an_adapter_is_a_clear_error() {
    let d = scratch("noadapter");
    let out = d.join("out");
    let o = Command::new(env!("CARGO_BIN_EXE_frameless"))
        .env("WGPU_ADAPTER_NAME", "no adapter is called this")
        .args(["eval", "--size", "64x48", "--recon", "gpu", "--out"])
        .arg(&out)
        .output()
        .expect("the binary runs");
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(
        e.contains("--recon gpu") && e.contains("no GPU adapter") && e.contains("--recon cpu"),
        "{e}"
    );
    assert!(!out.exists(), "the error comes before any work");
    let _ = std::fs::remove_dir_all(&d);
}

/// The GPU context these tests ask for, as `--recon gpu` acquires it.
#[cfg(feature = "gpu")]
fn gpu_context() -> std::sync::Arc<frameless::reconstruction::device::GpuContext> {
    use frameless::reconstruction::device::{acquire, ReconDevice};
    acquire(ReconDevice::Gpu)
        .expect("a GPU adapter (install Mesa's lavapipe: mesa-vulkan-drivers)")
        .expect("`gpu` gives a context or an error")
}

#[cfg(feature = "gpu")]
#[test]
#[ignore = "needs a GPU adapter (Mesa's lavapipe will do)"]
fn gpu_eval_of_the_papers_method_records_the_gpu() {
    let d = scratch("gpu-paper");
    let out = d.join("out");
    let o = eval("adaptive-paper", &["--recon", "gpu"], &out);
    succeeded(&o);
    let recon = recon_of(&out);
    assert_eq!(recon["device"], "gpu", "{recon}");
    let adapter = recon["adapter"].as_str().expect("the adapter is recorded");
    assert_eq!(adapter, gpu_context().describe());
    let e = stderr(&o);
    assert_eq!(
        e.matches(&format!("reconstructing on {adapter}")).count(),
        1,
        "{e}"
    );
    let md = std::fs::read_to_string(out.join("summary.md")).expect("summary.md");
    assert!(
        md.contains(&format!("Reconstructor: gpu ({adapter})")),
        "{md}"
    );
    let _ = std::fs::remove_dir_all(&d);
}

/// `adaptive` (ours) on the GPU does what `Reconstructor::use_gpu` says of its
/// parameters: it runs, or fails before any work saying what the GPU lacks.
#[cfg(feature = "gpu")]
#[test]
#[ignore = "needs a GPU adapter (Mesa's lavapipe will do)"]
fn gpu_eval_of_ours_runs_on_the_gpu() {
    let d = scratch("gpu-ours");
    let out = d.join("out");
    let o = eval("adaptive", &["--recon", "gpu"], &out);
    succeeded(&o);
    assert_eq!(recon_of(&out)["device"], "gpu");
    let _ = std::fs::remove_dir_all(&d);
}

/// `frameless view --headless --recon gpu`: the adaptive image builder reconstructs on
/// the GPU and `stats.json` says so; another method's images are the CPU's.
#[cfg(feature = "gpu")]
#[test]
#[ignore = "needs a GPU adapter (Mesa's lavapipe will do)"]
fn gpu_view_headless_records_the_gpu() {
    let d = scratch("gpu-view");
    let adapter = gpu_context().describe();
    for (method, device) in [("adaptive", "gpu"), ("framed-full", "cpu")] {
        let out = d.join(method);
        let o = Command::new(env!("CARGO_BIN_EXE_frameless"))
            .args(["view", "--headless", "--seconds", "0.5", "--size", "48x32"])
            .args([
                "--method", method, "--recon", "gpu", "--images", "0", "--out",
            ])
            .arg(&out)
            .output()
            .expect("the binary runs");
        succeeded(&o);
        let text = std::fs::read_to_string(out.join("stats.json")).expect("stats.json");
        let stats: serde_json::Value = serde_json::from_str(&text).expect("JSON");
        let recon = &stats["pipeline"]["recon"];
        assert_eq!(recon["device"], device, "{method}: {recon}");
        if device == "gpu" {
            assert_eq!(recon["adapter"], adapter.as_str(), "{method}");
            assert!(stats["pipeline"]["gpu_failure"].is_null(), "{text}");
        }
    }
    let _ = std::fs::remove_dir_all(&d);
}

/// The reconstruction benchmarks on the GPU: the paper's parameters measure, and the
/// real-time ones measure or say why not, as `bench --recon gpu` reports them.
#[cfg(feature = "gpu")]
#[test]
#[ignore = "needs a GPU adapter (Mesa's lavapipe will do)"]
fn gpu_bench_figures_run_on_the_gpu_or_say_why_not() {
    use frameless::{
        bench,
        reconstruction::{ReconParams, Reconstructor},
    };
    let ctx = gpu_context();
    let ms = bench::reconstruct_ms_on(Some(&ctx), 64, 64, 20_000, 1, 1).expect("paper's steps");
    assert!(ms.is_finite() && ms > 0.0, "{ms}");
    let expected = Reconstructor::new(16, 16, 1e4, ReconParams::realtime()).use_gpu(ctx.clone());
    match (
        bench::reconstruct_realtime_ms_on(Some(&ctx), 64, 48, 1, 1),
        expected,
    ) {
        (Ok(ms), Ok(())) => assert!(ms.is_finite() && ms > 0.0, "{ms}"),
        (Err(why), Err(e)) => assert_eq!(why.to_string(), e.to_string()),
        (got, want) => panic!("benchmark {got:?}, use_gpu {want:?}"),
    }
}

/// `bench --live-recon` times the reconstructor alone: a GPU tracer asked of it is an
/// error before any work, not an option silently left unused.
#[test]
fn live_recon_bench_refuses_a_gpu_tracer() {
    let o = Command::new(env!("CARGO_BIN_EXE_frameless"))
        .args(["bench", "--live-recon", "--trace", "gpu"])
        .output()
        .expect("the binary runs");
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(
        e.contains("--trace gpu") && e.contains("--live-recon"),
        "{e}"
    );
    assert!(!e.contains("measuring"), "it measured before refusing: {e}");
}

/// `bench --live-recon --recon gpu`'s figures are the GPU's: every timed refresh ran
/// there (a fallback to the CPU is an error), and the pass times say what the GPU
/// waited on apart from the CPU's parts.
#[cfg(feature = "gpu")]
#[test]
#[ignore = "needs a GPU adapter (Mesa's lavapipe will do)"]
fn gpu_live_recon_figures_are_the_gpus() {
    use frameless::{bench, reconstruction::ReconParams};
    let case = bench::LiveCase {
        width: 96,
        height: 64,
        rate: 2.0e5,
        refresh_hz: 30.0,
    };
    let ctx = gpu_context();
    for turning in [false, true] {
        let gpu = bench::live_image_ms(
            case,
            2.0,
            ReconParams::realtime(),
            4,
            turning,
            Some(ctx.clone()),
        )
        .expect("the GPU measures the figure");
        assert_eq!(gpu.recon, ctx.used(), "turning {turning}");
        let ms = |name: &str| gpu.pass_ms.iter().find(|(n, _)| *n == name).unwrap().1;
        assert!(ms("gpu_wait") > 0.0, "{:?}", gpu.pass_ms);
        assert_eq!(ms("splat"), 0.0, "the CPU splatted: {:?}", gpu.pass_ms);
        let cpu = bench::live_image_ms(case, 2.0, ReconParams::realtime(), 4, turning, None)
            .expect("the CPU measures the figure");
        assert_eq!(cpu.recon.device, "cpu");
        let on_gpu = |(n, v): &(&str, f64)| n.starts_with("gpu_") && *v > 0.0;
        assert!(!cpu.pass_ms.iter().any(on_gpu), "{:?}", cpu.pass_ms);
        assert_eq!(
            gpu.placed_per_image, cpu.placed_per_image,
            "turning {turning}"
        );
    }
}
