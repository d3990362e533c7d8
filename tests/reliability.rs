//! The reliability issue's reproducers: no input lost through `--out`, reports and
//! merges held to what their files may say, and messages that name the right thing.
//! Each test failed before its fix.

use std::{
    path::{Path, PathBuf},
    process::{Command, Output},
};

use proptest::prelude::*;

/// A fresh, empty folder for one test (or one case of a property).
fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!(
        "frameless-reliability-{}-{name}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn frameless(cwd: &Path, args: &[&str], env: &[(&str, &str)]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_frameless"))
        .current_dir(cwd)
        .args(args)
        .env_remove("WGPU_BACKEND")
        .env_remove("WGPU_ADAPTER_NAME")
        .envs(env.iter().copied())
        .output()
        .unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

const CAMERA_PATH: &str = "t,eye_x,eye_y,eye_z,at_x,at_y,at_z,up_x,up_y,up_z,fov_y_deg\n\
                           0,0,0,5,0,0,0,0,1,0,40\n\
                           2,1,0,5,0,0,0,0,1,0,40\n";

const OBJ: &str = "v -1 -1 0\nv 1 -1 0\nv 0 1 0\nf 1 2 3\n";

/// The smallest run of each command that writes a folder: a few refreshes of 16×16.
const EVAL: &[&str] = &[
    "eval",
    "--size",
    "16x16",
    "--duration",
    "0.05",
    "--warmup",
    "0",
    "--rate",
    "10k",
    "--method",
    "framed-60hz",
    "--ideal-spp",
    "1",
];
const RENDER: &[&str] = &[
    "render",
    "--size",
    "16x16",
    "--duration",
    "0.05",
    "--warmup",
    "0",
    "--rate",
    "10k",
    "--method",
    "framed-60hz",
];
const LIVE: &[&str] = &[
    "live",
    "--size",
    "16x16",
    "--seconds",
    "0.05",
    "--warmup",
    "0",
    "--method",
    "framed-full",
    "--ideal-spp",
    "1",
];
const SAMPLER: &[&str] = &[
    "sampler",
    "--size",
    "16x16",
    "--duration",
    "0.05",
    "--rate",
    "10k",
];
const VIEW: &[&str] = &["view", "--headless", "--seconds", "0.05", "--size", "16x16"];

/// `out` made an earlier output folder, which every command may replace whole.
fn earlier_output(out: &Path) {
    std::fs::create_dir_all(out).unwrap();
    std::fs::write(out.join(frameless::output::MARKER), "").unwrap();
}

// --- 1. No input lost through --out ----------------------------------------------------

/// `eval`, `live` and `render` with their camera path, scene or cache inside the
/// earlier output folder they would replace: refused, naming both, the input kept.
#[test]
fn an_input_inside_the_output_folder_is_refused_and_kept() {
    let root = dir("inside-out");
    let cases: [(&[&str], &str, &str); 7] = [
        (EVAL, "--camera-path", "cam.csv"),
        (EVAL, "--scene", "tri.obj"),
        (EVAL, "--cache-dir", "cache"),
        (LIVE, "--camera-path", "cam.csv"),
        (LIVE, "--cache-dir", "cache"),
        (RENDER, "--camera-path", "cam.csv"),
        (RENDER, "--scene", "tri.obj"),
    ];
    for (i, (command, option, name)) in cases.into_iter().enumerate() {
        let out = root.join(format!("out{i}"));
        earlier_output(&out);
        let input = out.join(name);
        match name {
            "cam.csv" => std::fs::write(&input, CAMERA_PATH).unwrap(),
            "tri.obj" => std::fs::write(&input, OBJ).unwrap(),
            _ => std::fs::create_dir_all(input.join("kept")).unwrap(),
        }
        let mut args = command.to_vec();
        let (input_arg, out_arg) = (input.to_str().unwrap(), out.to_str().unwrap());
        args.extend([option, input_arg, "--out", out_arg]);
        let o = frameless(&root, &args, &[]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{args:?} was not refused: {err}");
        assert!(
            err.contains("holds the input") && err.contains(name),
            "{args:?}: {err}"
        );
        assert!(input.exists(), "{args:?} lost its input");
    }
}

/// How a test names a path inside the output folder: as is, through `.` or a `..`,
/// relative to the working folder, or through a link to the folder.
#[derive(Clone, Copy, Debug)]
enum Spelling {
    Plain,
    Dot,
    Up,
    Relative,
    Link,
}

/// The inputs a command reads that a property case may put inside `--out`.
#[derive(Clone, Copy, Debug)]
enum Input {
    CameraPath,
    Scene,
    Cache,
    Bart,
    Results,
    SweepFile,
}

/// A command that writes a folder, with the inputs it takes.
fn commands() -> Vec<(&'static str, Vec<Input>)> {
    use Input::*;
    vec![
        ("eval", vec![CameraPath, Scene, Cache]),
        ("live", vec![CameraPath, Scene, Cache]),
        ("render", vec![CameraPath, Scene]),
        ("sampler", vec![CameraPath, Scene]),
        ("view", vec![CameraPath, Scene]),
        ("table1", vec![Bart, Cache]),
        ("merge", vec![Results]),
        ("sweep", vec![SweepFile, Cache]),
    ]
}

/// A sweep of one tiny job, its scene a file beside it.
const SWEEP: &str = "name = \"s\"\nsizes = [\"16x16\"]\nseeds = [1]\nmethods = [\"framed-60hz\"]\n\
                     rates = [\"10k\"]\n[[evaluation]]\nname = \"e\"\nscene = \"toycar\"\n\
                     start = 0\nduration = 0.05\nwarmup = 0\n";

/// Write the input `kind` at `at`; what must still be there afterwards.
fn make_input(kind: Input, at: &Path) -> PathBuf {
    std::fs::create_dir_all(at.parent().unwrap()).unwrap();
    match kind {
        Input::CameraPath => std::fs::write(at, CAMERA_PATH).unwrap(),
        Input::Scene => std::fs::write(at, OBJ).unwrap(),
        Input::SweepFile => std::fs::write(at, SWEEP).unwrap(),
        Input::Cache | Input::Results => {
            std::fs::create_dir_all(at).unwrap();
            std::fs::write(at.join("kept.txt"), "kept").unwrap();
            return at.join("kept.txt");
        }
        Input::Bart => {
            std::fs::create_dir_all(at.join("kitchen")).unwrap();
            std::fs::write(at.join("kitchen/kitchen.aff"), "not a scene").unwrap();
            return at.join("kitchen/kitchen.aff");
        }
    }
    at.to_path_buf()
}

/// The arguments that run `command` reading `input` (spelled as given) into `out`.
fn arguments(command: &str, kind: Input, input: &str, out: &str) -> Vec<String> {
    let base: &[&str] = match command {
        "eval" => EVAL,
        "live" => LIVE,
        "render" => RENDER,
        "sampler" => SAMPLER,
        "view" => VIEW,
        other => &[other][..],
    };
    let mut args: Vec<String> = base.iter().map(|s| s.to_string()).collect();
    let option = match kind {
        Input::CameraPath => Some("--camera-path"),
        Input::Scene => Some("--scene"),
        Input::Cache => Some("--cache-dir"),
        Input::Bart => Some("--bart"),
        Input::Results | Input::SweepFile => None,
    };
    args.extend(option.map(String::from));
    args.push(input.into());
    args.extend(["--out".into(), out.into()]);
    if command == "sweep" && !matches!(kind, Input::SweepFile) {
        args.insert(1, "s.toml".into());
    }
    if command == "merge" && !matches!(kind, Input::Results) {
        args.insert(1, "results".into());
    }
    args
}

/// The input's path as the case spells it, with `link` a link to `out`.
fn spell(s: Spelling, root: &Path, out_name: &str, rel: &str) -> String {
    match s {
        Spelling::Plain => root.join(out_name).join(rel).display().to_string(),
        Spelling::Dot => format!("{}/./{rel}", root.join(out_name).display()),
        Spelling::Up => format!("{}/sub/../{rel}", root.join(out_name).display()),
        Spelling::Relative => format!("{out_name}/{rel}"),
        Spelling::Link => root.join("link").join(rel).display().to_string(),
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, failure_persistence: None, ..ProptestConfig::default() })]

    /// For any command that writes a folder and any input it reads, put inside an
    /// earlier output folder given as `--out` and spelled any way: afterwards the input
    /// is still there, unchanged, whether the command refused (exit 1) or kept it.
    #[test]
    fn an_input_inside_out_is_never_lost(
        command in 0..8usize,
        which in 0..3usize,
        spelling in prop_oneof![
            Just(Spelling::Plain), Just(Spelling::Dot), Just(Spelling::Up),
            Just(Spelling::Relative), Just(Spelling::Link)
        ],
        nested in any::<bool>(),
    ) {
        let (name, inputs) = commands().swap_remove(command);
        let kind = inputs[which % inputs.len()];
        let root = dir(&format!("prop-{name}-{kind:?}-{spelling:?}-{nested}"));
        earlier_output(&root.join("out"));
        std::fs::create_dir_all(root.join("out/sub")).unwrap();
        #[cfg(unix)]
        std::os::unix::fs::symlink(root.join("out"), root.join("link")).unwrap();
        std::fs::write(root.join("s.toml"), SWEEP).unwrap();
        std::fs::create_dir_all(root.join("results")).unwrap();
        let file = match kind {
            Input::CameraPath => "cam.csv",
            Input::Scene => "tri.obj",
            Input::SweepFile => "sweep.toml",
            Input::Cache => "cache",
            Input::Bart => "bart",
            Input::Results => "results",
        };
        let rel = if nested { format!("deeper/{file}") } else { file.to_string() };
        let kept = make_input(kind, &root.join("out").join(&rel));
        let before = std::fs::read(&kept).unwrap();
        let input = spell(spelling, &root, "out", &rel);
        let args = arguments(name, kind, &input, "out");
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = frameless(&root, &args, &[("FRAMELESS_CACHE", root.join("c").to_str().unwrap())]);
        prop_assert!(
            matches!(o.status.code(), Some(0 | 1)),
            "{args:?} crashed: {}", stderr(&o)
        );
        prop_assert_eq!(std::fs::read(&kept).ok(), Some(before), "{:?} lost {}: {}", args, kept.display(), stderr(&o));
        let _ = std::fs::remove_dir_all(&root);
    }
}

// --- 4, 5. Report reads only bounded regular files and writes only inside DIR ----------

/// A copy of a committed evaluation folder, without its report.
fn eval_folder(at: &Path) {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/results/toycar");
    std::fs::create_dir_all(at).unwrap();
    for e in std::fs::read_dir(&src).unwrap() {
        let e = e.unwrap();
        if e.file_type().unwrap().is_file() && e.file_name() != "report.html" {
            std::fs::copy(e.path(), at.join(e.file_name())).unwrap();
        }
    }
}

/// `report` under an address-space limit, so that a read without bounds fails at once
/// instead of taking the machine's memory (4 GiB: far more than the command maps to
/// start, threads and GPU libraries included). A report still running after a minute
/// is killed: it is waiting on something it should not have opened.
#[cfg(target_os = "linux")]
fn report_bounded(d: &Path) -> Output {
    use std::os::unix::process::CommandExt;
    let mut c = Command::new(env!("CARGO_BIN_EXE_frameless"));
    c.arg("report").arg(d);
    // SAFETY: setrlimit is async-signal-safe; nothing else runs in the child before exec.
    unsafe {
        c.pre_exec(|| {
            let most = 4u64 << 30;
            let lim = libc::rlimit {
                rlim_cur: most,
                rlim_max: most,
            };
            if libc::setrlimit(libc::RLIMIT_AS, &lim) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    let mut child = c
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let t0 = std::time::Instant::now();
    while child.try_wait().unwrap().is_none() && t0.elapsed().as_secs() < 60 {
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    let _ = child.kill();
    child.wait_with_output().unwrap()
}

/// A strip image that is a FIFO: refused as not a regular file, without opening it
/// (an open would wait for a writer that never comes).
#[cfg(target_os = "linux")]
#[test]
fn report_refuses_a_strip_that_is_a_fifo() {
    let d = dir("report-fifo");
    eval_folder(&d);
    let strip = d.join("strip_400K_0060.png");
    std::fs::remove_file(&strip).unwrap();
    let name = std::ffi::CString::new(strip.to_str().unwrap()).unwrap();
    // SAFETY: a valid C string; mkfifo only creates the file.
    assert_eq!(unsafe { libc::mkfifo(name.as_ptr(), 0o644) }, 0);
    let o = report_bounded(&d);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("strip_400K_0060.png") && err.contains("not a regular file"),
        "{err}"
    );
}

#[cfg(target_os = "linux")]
#[test]
fn report_refuses_a_summary_that_is_a_device() {
    let d = dir("report-device");
    eval_folder(&d);
    std::fs::remove_file(d.join("summary.json")).unwrap();
    std::os::unix::fs::symlink("/dev/zero", d.join("summary.json")).unwrap();
    let o = report_bounded(&d);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("summary.json") && err.contains("not a regular file"),
        "{err}"
    );
}

/// A Table 1 `summary.json` naming its animation `../victim` or an absolute path:
/// refused before any report is written, and nothing outside the folder is touched.
#[test]
fn report_never_writes_outside_its_folder() {
    let root = dir("report-outside");
    let victim = root.join("victim");
    eval_folder(&victim);
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(victim.join("summary.json")).unwrap())
            .unwrap();
    for (i, name) in ["../victim".to_string(), victim.display().to_string()]
        .into_iter()
        .enumerate()
    {
        let d = root.join(format!("table{i}"));
        std::fs::create_dir_all(&d).unwrap();
        let table = serde_json::json!({"animations": [{
            "name": name, "description": "", "camera_path": null, "summary": summary,
        }]});
        std::fs::write(d.join("summary.json"), table.to_string()).unwrap();
        let o = frameless(&root, &["report", d.to_str().unwrap()], &[]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{name}: {err}");
        assert!(
            err.contains("is not a folder name") && err.contains(&name),
            "{err}"
        );
        assert!(
            !victim.join("report.html").exists(),
            "{name}: wrote outside"
        );
    }
    // The same folder under a plain name is reported.
    let d = root.join("table-ok");
    std::fs::create_dir_all(&d).unwrap();
    eval_folder(&d.join("toycar"));
    let table = serde_json::json!({"animations": [{
        "name": "toycar", "description": "", "camera_path": null, "summary": summary,
    }]});
    std::fs::write(d.join("summary.json"), table.to_string()).unwrap();
    let o = frameless(&root, &["report", d.to_str().unwrap()], &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(d.join("toycar/report.html").is_file());
}

// --- 6. Merge checks values against the job's key ---------------------------------------

#[test]
fn merge_refuses_values_no_run_of_the_job_gives() {
    let root = dir("merge-values");
    std::fs::write(root.join("s.toml"), SWEEP).unwrap();
    let o = frameless(
        &root,
        &["sweep", "s.toml", "--out", "results", "--no-cache"],
        &[],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let file = std::fs::read_dir(root.join("results"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.extension().is_some_and(|x| x == "json"))
        .unwrap();
    let original: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&file).unwrap()).unwrap();
    let o = frameless(&root, &["merge", "results", "--out", "merged"], &[]);
    assert!(
        o.status.success(),
        "the unedited result merges: {}",
        stderr(&o)
    );
    type Edit = fn(&mut serde_json::Value);
    let edits: [(&str, Edit, &str); 7] = [
        (
            "rms_mean 1e308",
            |v| v["results"][0]["rms_mean"] = 1e308.into(),
            "rms_mean",
        ),
        (
            "frames 1e9",
            |v| v["results"][0]["frames"] = 1_000_000_000u64.into(),
            "frames 1000000000",
        ),
        (
            "a negative RMS",
            |v| v["frames"][0]["rms"] = (-1.0).into(),
            "RMS",
        ),
        (
            "a frame 100 s past the window",
            |v| {
                let t = v["frames"][0]["time"].as_f64().unwrap();
                v["frames"][0]["time"] = (t + 100.0).into();
            },
            "is not that frame's refresh",
        ),
        (
            "a PSNR of 1e308",
            |v| v["frames"][0]["psnr"] = 1e308.into(),
            "PSNR",
        ),
        (
            "another effective rate",
            |v| v["results"][0]["effective_rate"] = 1e308.into(),
            "effective_rate",
        ),
        (
            "samples past the budget",
            |v| v["results"][0]["samples"] = 1_000_000_000u64.into(),
            "over the",
        ),
    ];
    for (what, edit, needle) in edits {
        let mut v = original.clone();
        edit(&mut v);
        std::fs::write(&file, v.to_string()).unwrap();
        let o = frameless(&root, &["merge", "results", "--out", "merged"], &[]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{what} was merged: {err}");
        assert!(
            err.contains(file.file_name().unwrap().to_str().unwrap()),
            "{what}: {err}"
        );
        assert!(err.contains(needle), "{what}: `{needle}` not in {err}");
    }
}

// --- 7, 8. GPU environment -------------------------------------------------------------

/// A `WGPU_BACKEND` that names no backend: `--recon gpu` names the variable and the
/// valid values (not a missing driver); `--recon auto` says so and runs on the CPU.
#[cfg(feature = "gpu")]
#[test]
fn a_bad_wgpu_backend_is_named_with_its_valid_values() {
    let root = dir("wgpu-backend");
    let run = |recon: &str| {
        let mut args = EVAL.to_vec();
        args.extend(["--no-cache", "--recon", recon, "--out", "out"]);
        frameless(&root, &args, &[("WGPU_BACKEND", "nonsense")])
    };
    let o = run("gpu");
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("WGPU_BACKEND=nonsense") && err.contains("vulkan"),
        "{err}"
    );
    assert!(!err.contains("install a Vulkan driver"), "{err}");
    let o = run("auto");
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("WGPU_BACKEND") && err.contains("on the CPU"),
        "{err}"
    );
}

/// `--recon auto` stays on the CPU whatever keeps it from a GPU, a
/// `WGPU_ADAPTER_NAME` that matches no adapter included.
#[test]
fn recon_auto_falls_back_to_the_cpu_for_an_adapter_name_that_matches_nothing() {
    let root = dir("wgpu-adapter");
    let mut args = EVAL.to_vec();
    args.extend(["--no-cache", "--recon", "auto", "--out", "out"]);
    let o = frameless(&root, &args, &[("WGPU_ADAPTER_NAME", "no-such-adapter-46")]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("on the CPU"), "{err}");
    let summary = std::fs::read_to_string(root.join("out/summary.json")).unwrap();
    assert!(summary.contains("\"device\": \"cpu\""), "{summary}");
}

// --- 9. The option at fault --------------------------------------------------------------

#[test]
fn too_many_threads_for_live_blame_threads() {
    let root = dir("threads");
    let o = frameless(
        &root,
        &[
            "--threads",
            "1024",
            "live",
            "--method",
            "adaptive",
            "--no-cache",
            "--out",
            "out",
        ],
        &[],
    );
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("--threads 1024"), "{err}");
    assert!(!err.contains("--methods"), "{err}");
    assert!(!root.join("out").exists());
}
