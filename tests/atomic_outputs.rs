//! Outputs are written atomically: an evaluation killed while it writes leaves `--out`
//! holding the previous run or the new one, whole, never a mixture; the next run cleans
//! what the killed one left; an output that cannot be written fails before any work.

use std::{
    collections::BTreeMap,
    path::{Path, PathBuf},
    process::{Command, Stdio},
    time::{Duration, Instant},
};

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("frameless-atomic-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("scratch folder");
    d
}

fn frameless() -> Command {
    Command::new(env!("CARGO_BIN_EXE_frameless"))
}

/// A small evaluation whose output step writes a dozen files (three plots, nine strips).
fn eval(seed: u64, cache: &Path, out: &Path) -> Command {
    let mut c = frameless();
    c.args([
        "eval",
        "--scene",
        "toycar",
        "--size",
        "96x64",
        "--duration",
        "0.25",
        "--rates",
        "100k,200k,400k",
        "--methods",
        "traditional-frameless,framed-60hz,framed-full",
        "--warmup",
        "0.1",
        "--ideal-spp",
        "1",
    ])
    .args(["--seed", &seed.to_string()])
    .arg("--cache-dir")
    .arg(cache)
    .arg("--out")
    .arg(out)
    .stdout(Stdio::null())
    .stderr(Stdio::piped());
    c
}

fn run_ok(mut c: Command) {
    let out = c.output().expect("runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    snapshot(dir).unwrap_or_else(|| panic!("{} is not a folder of files", dir.display()))
}

/// The files of `dir` by name, or `None` when it cannot be read whole.
fn snapshot(dir: &Path) -> Option<BTreeMap<String, Vec<u8>>> {
    let mut m = BTreeMap::new();
    for e in std::fs::read_dir(dir).ok()? {
        let e = e.ok()?;
        if !e.path().is_file() {
            return None;
        }
        let name = e.file_name().to_string_lossy().into_owned();
        m.insert(name, std::fs::read(e.path()).ok()?);
    }
    Some(m)
}

/// Files that carry the run's timing and so differ between runs of the same settings.
const TIMED: [&str; 2] = ["summary.json", "report.html"];

/// Whether `dir` holds exactly the run of `reference` (seed `seed`): the same file
/// names, the same bytes where a run is deterministic, the same seed where it is not.
fn is_run(dir: &Path, reference: &BTreeMap<String, Vec<u8>>, seed: u64) -> bool {
    let got = files(dir);
    if got.keys().ne(reference.keys()) {
        return false;
    }
    let deterministic = got
        .iter()
        .filter(|(name, _)| !TIMED.contains(&name.as_str()))
        .all(|(name, bytes)| reference[name] == *bytes);
    let summary: serde_json::Value =
        serde_json::from_slice(&got["summary.json"]).unwrap_or_default();
    let html = String::from_utf8_lossy(&got["report.html"]);
    deterministic && summary["seed"] == seed && html.contains(&format!("seed {seed};"))
}

/// Everything beside `out` in its folder.
fn siblings(parent: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(parent)
        .expect("readable")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .filter(|n| n != "out")
        .collect();
    v.sort();
    v
}

fn copy_dir(from: &Path, to: &Path) {
    let _ = std::fs::remove_dir_all(to);
    std::fs::create_dir_all(to).unwrap();
    for (name, bytes) in files(from) {
        std::fs::write(to.join(name), bytes).unwrap();
    }
}

#[test]
fn kills_an_eval_mid_write_and_shows_no_mixed_outputs() {
    let d = scratch("kill");
    let cache = d.join("cache");
    // The two complete runs every killed run must match one of.
    let (ref_old, ref_new) = (d.join("ref_old"), d.join("ref_new"));
    run_ok(eval(1, &cache, &ref_old));
    run_ok(eval(2, &cache, &ref_new));
    let (old, new) = (files(&ref_old), files(&ref_new));
    assert!(old.len() >= 10, "{:?}", old.keys());
    assert_eq!(
        old.keys().collect::<Vec<_>>(),
        new.keys().collect::<Vec<_>>()
    );
    assert_ne!(
        old["frames.csv"], new["frames.csv"],
        "the seeds must differ visibly"
    );

    let parent = d.join("runs");
    std::fs::create_dir_all(&parent).unwrap();
    let out = parent.join("out");
    let (mut kept_old, mut became_new, mut killed_while_writing) = (0, 0, 0);
    // Trial 0 is killed during the evaluation; the others once the temporary output
    // folder appears (the output step has begun), after 0, 1, 3, 7, ..., 255 ms: the
    // early ones land while files are written, the late ones after the run finished.
    for trial in 0..10u64 {
        copy_dir(&ref_old, &out);
        let mut child = eval(2, &cache, &parent.join("out"))
            .spawn()
            .expect("spawns");
        let start = Instant::now();
        let mut writing_began = false;
        let own_partial = format!("out.partial-{}-", child.id());
        loop {
            if child.try_wait().expect("waits").is_some() {
                break;
            }
            if trial == 0 {
                if start.elapsed() > Duration::from_millis(150) {
                    break;
                }
            } else if siblings(&parent).iter().any(|n| n.starts_with(&own_partial))
                // Whatever the way of writing, the output step has begun once `out`
                // changes.
                || snapshot(&out).as_ref() != Some(&old)
            {
                writing_began = true;
                std::thread::sleep(Duration::from_millis((1 << (trial - 1)) - 1));
                break;
            }
            assert!(start.elapsed() < Duration::from_secs(60), "the run hangs");
            std::thread::sleep(Duration::from_micros(200));
        }
        let _ = child.kill();
        child.wait().expect("reaped");
        let (is_old, is_new) = if out.exists() {
            (is_run(&out, &old, 1), is_run(&out, &new, 2))
        } else {
            // Killed between the two renames of the commit: the previous run is whole
            // under its moved-aside name, and the next run puts it back.
            let aside = siblings(&parent)
                .into_iter()
                .find(|s| s.starts_with("out.old-"));
            let aside = aside.expect("out is missing and no previous run is kept aside");
            (is_run(&parent.join(aside), &old, 1), false)
        };
        assert!(
            is_old || is_new,
            "trial {trial}: out holds neither run whole: {:?}",
            snapshot(&out).map(|m| m.into_keys().collect::<Vec<_>>())
        );
        // Leftovers are only ever named for what they are.
        for s in siblings(&parent) {
            assert!(
                s.starts_with("out.partial-") || s.starts_with("out.old-"),
                "{s}"
            );
        }
        kept_old += is_old as u32;
        became_new += is_new as u32;
        killed_while_writing += (writing_began && is_old) as u32;
    }
    eprintln!(
        "10 kills: {kept_old} kept the previous run ({killed_while_writing} of them during the \
         output step), {became_new} left the new run"
    );
    // Otherwise the test never struck the window it is about.
    assert!(
        killed_while_writing > 0,
        "no kill landed during the output step"
    );
    // A complete run replaces the old outputs and removes what the killed runs left.
    run_ok(eval(2, &cache, &out));
    assert!(is_run(&out, &new, 2));
    assert_eq!(siblings(&parent), Vec::<String>::new());
    let _ = std::fs::remove_dir_all(&d);
}

/// A command must fail within this long when its output cannot be written, while the
/// work it was given takes minutes: the check comes before the work.
const FAST: Duration = Duration::from_secs(20);

fn fails_fast(mut c: Command) -> String {
    let mut child = c
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawns");
    let start = Instant::now();
    while child.try_wait().expect("waits").is_none() {
        if start.elapsed() > FAST {
            let _ = child.kill();
            panic!("{c:?} still running after {FAST:?}: the output was not checked first");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let out = child.wait_with_output().expect("output");
    assert!(!out.status.success(), "{c:?} succeeded");
    String::from_utf8_lossy(&out.stderr).into_owned()
}

#[test]
fn an_unwritable_out_fails_before_any_work() {
    let d = scratch("unwritable");
    let file = d.join("plain-file");
    std::fs::write(&file, "not a folder").unwrap();
    let bad = file.join("out");
    let cache = d.join("cache");
    let slow: [&[&str]; 4] = [
        &[
            "eval",
            "--size",
            "512x512",
            "--duration",
            "60",
            "--rates",
            "1M",
            "--methods",
            "traditional-frameless",
        ],
        &[
            "render",
            "--size",
            "512x512",
            "--duration",
            "60",
            "--rate",
            "1M",
        ],
        &[
            "sampler",
            "--size",
            "512x512",
            "--duration",
            "60",
            "--rate",
            "1M",
        ],
        &["view", "--headless", "--seconds", "60"],
    ];
    for args in slow {
        let mut c = frameless();
        c.args(args)
            .arg("--cache-dir")
            .arg(&cache)
            .arg("--out")
            .arg(&bad);
        if args[0] != "eval" {
            // Only eval has a cache; give the others their arguments alone.
            c = frameless();
            c.args(args).arg("--out").arg(&bad);
        }
        let err = fails_fast(c);
        assert!(
            err.contains(&bad.display().to_string()) && err.contains("is a file, not a folder"),
            "{args:?}: {err}"
        );
    }
    // The evaluation never started: it would have created its cache first.
    assert!(!cache.exists());
    // A folder that is not an earlier output is never replaced (that would delete it).
    let precious = d.join("precious");
    std::fs::create_dir(&precious).unwrap();
    std::fs::write(precious.join("notes.txt"), "mine").unwrap();
    for command in ["eval", "render", "sampler"] {
        let mut c = frameless();
        c.args([command, "--size", "512x512", "--duration", "60", "--out"])
            .arg(&precious);
        let err = fails_fast(c);
        assert!(err.contains("not an output folder"), "{command}: {err}");
    }
    assert_eq!(
        std::fs::read_to_string(precious.join("notes.txt")).unwrap(),
        "mine"
    );
    // A file where the output folder goes.
    let mut c = frameless();
    c.args(["render", "--duration", "60", "--size", "512x512", "--out"])
        .arg(&file);
    let err = fails_fast(c);
    assert!(err.contains("not a folder"), "{err}");
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "not a folder");
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn still_refuses_other_extensions_and_folders_and_leaves_nothing() {
    let d = scratch("still");
    let slow = ["still", "--size", "2048x2048", "--spp", "256", "--out"];
    for name in ["x.jpg", "x.PNG.jpeg", "x"] {
        let p = d.join(name);
        let mut c = frameless();
        c.args(slow).arg(&p);
        let err = fails_fast(c);
        let ext = Path::new(name)
            .extension()
            .map(|e| format!(".{}", e.to_string_lossy()))
            .unwrap_or_else(|| "no extension".into());
        assert!(err.contains(&ext) && err.contains(".png"), "{name}: {err}");
    }
    let folder = d.join("shots.png");
    std::fs::create_dir(&folder).unwrap();
    let mut c = frameless();
    c.args(slow).arg(&folder);
    let err = fails_fast(c);
    assert!(err.contains("is a folder"), "{err}");
    let mut left: Vec<_> = std::fs::read_dir(&d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    left.sort();
    assert_eq!(left, ["shots.png"], "nothing written, no temporary left");
    assert_eq!(std::fs::read_dir(&folder).unwrap().count(), 0);
    // An accepted name (any case) writes exactly that file.
    let ok = d.join("ok.PNG");
    run_ok({
        let mut c = frameless();
        c.args(["still", "--size", "8x6", "--spp", "1", "--out"])
            .arg(&ok);
        c
    });
    assert!(ok.is_file());
    let _ = std::fs::remove_dir_all(&d);
}
