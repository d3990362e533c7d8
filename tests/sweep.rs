//! Sharded sweeps end to end: `assets/sweeps/example.toml` run as three concurrent
//! shards sharing one cold ideal-image cache and merged gives the outputs of the same
//! sweep run as one shard and merged, and those of `evaluation::run` on the same
//! settings; a merge with a shard missing, a job twice, a result of another sweep or a
//! foreign file is an error naming them.
//!
//! Timings are not results: `summary.json` is compared byte for byte outside its
//! `timing` objects (wall-clock seconds and cache counts, summed over the jobs), and
//! `report.html`, which prints them, only for being there.

use std::{
    collections::BTreeMap,
    path::{Path, PathBuf},
    process::{Command, Output},
    sync::{Arc, OnceLock},
};

use frameless::{
    evaluation::{self, report, sweep::SweepFile, Silent},
    scene,
};

fn example() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/sweeps/example.toml")
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("frameless-sweep-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

fn frameless(args: &[&dyn AsRef<std::ffi::OsStr>]) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_frameless"));
    // Few threads: the shards run side by side on small machines.
    c.args(["--threads", "2"]);
    for a in args {
        c.arg(a);
    }
    c
}

fn ok(o: Output, what: &str) -> Output {
    assert!(
        o.status.success(),
        "{what} failed:\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    o
}

/// Every file under `dir` but output markers, by path relative to it.
fn tree(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    fn walk(root: &Path, dir: &Path, out: &mut BTreeMap<PathBuf, Vec<u8>>) {
        for e in std::fs::read_dir(dir).expect("readable folder") {
            let p = e.expect("entry").path();
            // The marker says a folder is an output; an evaluation's folder inside a
            // merged output is not one by itself, so only the top folders carry it.
            if p.is_dir() {
                walk(root, &p, out);
            } else if p.file_name() != Some(std::ffi::OsStr::new(frameless::output::MARKER)) {
                let rel = p.strip_prefix(root).expect("under root").to_path_buf();
                out.insert(rel, std::fs::read(&p).expect("readable file"));
            }
        }
    }
    let mut out = BTreeMap::new();
    walk(dir, dir, &mut out);
    out
}

/// `summary.json` with every `"timing": {...}` object's contents cut out (Timing has no
/// nested objects).
fn without_timing(json: &[u8]) -> String {
    let text = String::from_utf8(json.to_vec()).expect("UTF-8");
    let mut out = String::new();
    let mut rest = text.as_str();
    let mut cut = 0;
    while let Some(i) = rest.find("\"timing\": {") {
        let open = i + "\"timing\": {".len();
        let close = open + rest[open..].find('}').expect("timing closes");
        out.push_str(&rest[..open]);
        rest = &rest[close..];
        cut += 1;
    }
    out.push_str(rest);
    assert!(cut > 0, "a summary has timing sections");
    out
}

/// The two output trees hold the same files with the same results.
fn assert_same_outputs(a: &Path, b: &Path) {
    let (ta, tb) = (tree(a), tree(b));
    assert_eq!(
        ta.keys().collect::<Vec<_>>(),
        tb.keys().collect::<Vec<_>>(),
        "{} and {} hold different files",
        a.display(),
        b.display()
    );
    let mut compared = 0;
    for (rel, bytes) in &ta {
        let name = rel.file_name().expect("file name").to_string_lossy();
        if name == "report.html" {
            continue;
        }
        if name == "summary.json" {
            assert_eq!(
                without_timing(bytes),
                without_timing(&tb[rel]),
                "{}",
                rel.display()
            );
        } else {
            assert!(bytes == &tb[rel], "{} differs", rel.display());
        }
        compared += 1;
    }
    assert!(compared >= 5, "only {compared} files compared");
}

struct Fixture {
    /// The three shards' result folders.
    shards: Vec<PathBuf>,
    /// The whole sweep as one shard.
    single: PathBuf,
    /// The three shards merged.
    merged3: PathBuf,
    /// The single run merged.
    merged1: PathBuf,
}

/// Run the example sweep once as three concurrent shards and once as one, each merged.
fn fixture() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        let shared_cache = tmp("cache-shared");
        let shards: Vec<PathBuf> = (0..3).map(|i| tmp(&format!("shard{i}"))).collect();
        let children: Vec<_> = shards
            .iter()
            .enumerate()
            .map(|(i, out)| {
                frameless(&[
                    &"sweep",
                    &example(),
                    &"--shard",
                    &format!("{i}/3"),
                    &"--out",
                    out,
                    &"--cache-dir",
                    &shared_cache,
                ])
                .stdout(std::process::Stdio::piped())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .expect("frameless starts")
            })
            .collect();
        for (i, c) in children.into_iter().enumerate() {
            ok(
                c.wait_with_output().expect("shard runs"),
                &format!("shard {i}/3"),
            );
        }
        let single = tmp("single");
        ok(
            frameless(&[
                &"sweep",
                &example(),
                &"--out",
                &single,
                &"--cache-dir",
                &tmp("cache-single"),
            ])
            .output()
            .expect("runs"),
            "the single run",
        );
        let merged3 = tmp("merged3");
        let merged1 = tmp("merged1");
        ok(
            frameless(&[
                &"merge", &shards[0], &shards[1], &shards[2], &"--out", &merged3,
            ])
            .output()
            .expect("runs"),
            "merging three shards",
        );
        ok(
            frameless(&[&"merge", &single, &"--out", &merged1])
                .output()
                .expect("runs"),
            "merging one shard",
        );
        Fixture {
            shards,
            single,
            merged3,
            merged1,
        }
    })
}

/// `frameless merge` of shards 0 and 1 with `third` into `out`.
fn merge_with(third: &Path, out: &Path) -> Output {
    let f = fixture();
    frameless(&[&"merge", &f.shards[0], &f.shards[1], &third, &"--out", &out])
        .output()
        .expect("runs")
}

fn file_names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .expect("readable")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn three_shards_merge_to_what_one_run_writes() {
    let f = fixture();
    // Each shard ran some jobs, and together exactly the single run's.
    let mut all: Vec<String> = Vec::new();
    for s in &f.shards {
        let names = file_names(s);
        assert!(!names.is_empty(), "{} ran no job", s.display());
        all.extend(names);
    }
    all.sort();
    assert_eq!(all, file_names(&f.single));
    assert_eq!(all.len(), 7);
    assert_same_outputs(&f.merged3, &f.merged1);
    let summary = std::fs::read_to_string(f.merged3.join("summary.json")).expect("summary");
    assert!(summary.contains("\"jobs\": 7"), "{summary}");
}

/// The merged evaluation folder is what `frameless eval` writes for the same settings:
/// the library's run and report writer, on the instance's whole configuration, without
/// a cache.
#[test]
fn merged_outputs_are_those_of_a_single_evaluation() {
    let f = fixture();
    let file = SweepFile::load(&example()).expect("example loads");
    let inst = file.sweep.instances()[0];
    let cfg = file.sweep.config(&inst, None, None);
    let scene = Arc::new(scene::load("toycar").expect("built-in scene"));
    let mut out = evaluation::run(scene, &cfg, &Silent).expect("evaluation runs");
    let dir = tmp("eval");
    report::write_all(&mut out, &dir).expect("outputs written");
    let merged = f.merged1.join(file.sweep.folder(&inst));
    assert_same_outputs(&merged, &dir);
    // The rate-independent method fills both rate columns, and strips hold every
    // method.
    let csv = std::fs::read_to_string(merged.join("frames.csv")).expect("frames.csv");
    assert_eq!(
        csv.lines()
            .filter(|l| l.starts_with("full-res-60hz,"))
            .count(),
        2 * 15
    );
    assert_eq!(out.strips.len(), 2 * 3);
    assert!(out.strips.iter().all(|s| s.shown.len() == 4));
}

#[test]
fn a_missing_shard_is_an_error_naming_its_jobs() {
    let f = fixture();
    let out = tmp("missing");
    let o = frameless(&[&"merge", &f.shards[0], &f.shards[1], &"--out", &out])
        .output()
        .expect("runs");
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    let missing = file_names(&f.shards[2]);
    assert!(
        err.contains(&format!("missing {} of 7 jobs", missing.len())),
        "{err}"
    );
    for name in missing {
        let job = name.trim_end_matches(".json");
        assert!(err.contains(&format!("{job} (shard 2/3)")), "{job}: {err}");
    }
    assert!(!out.exists(), "a failed merge writes nothing");
}

#[test]
fn a_job_twice_is_an_error_naming_it() {
    let f = fixture();
    let dup = tmp("dup");
    std::fs::create_dir_all(&dup).expect("folder");
    let name = &file_names(&f.shards[1])[0];
    std::fs::copy(f.shards[1].join(name), dup.join(name)).expect("copy");
    let o = frameless(&[
        &"merge",
        &f.shards[0],
        &f.shards[1],
        &f.shards[2],
        &dup,
        &"--out",
        &tmp("dup-out"),
    ])
    .output()
    .expect("runs");
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("1 jobs found more than once"), "{err}");
    assert!(err.contains(name.trim_end_matches(".json")), "{err}");
}

#[test]
fn results_of_another_sweep_or_renderer_or_foreign_files_are_refused() {
    let f = fixture();
    let edit = |name: &str, from: &str, to: &str| -> PathBuf {
        let d = tmp(name);
        std::fs::create_dir_all(&d).expect("folder");
        for n in file_names(&f.shards[2]) {
            let text = std::fs::read_to_string(f.shards[2].join(&n)).expect("result");
            assert!(text.contains(from), "{from} in {n}");
            std::fs::write(d.join(&n), text.replacen(from, to, 1)).expect("written");
        }
        d
    };
    let hash = {
        let any = &file_names(&f.shards[0])[0];
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(f.shards[0].join(any)).expect("result"))
                .expect("JSON");
        v["sweep_hash"].as_str().expect("hash").to_string()
    };
    let cases = [
        (
            edit(
                "other-sweep",
                &format!("\"sweep_hash\":\"{hash}\""),
                "\"sweep_hash\":\"0000000000000000\"",
            ),
            "sweep file hash",
        ),
        (
            edit(
                "other-renderer",
                "\"renderer_version\":",
                "\"renderer_version\":9",
            ),
            "renderer version",
        ),
        (
            edit(
                "other-format",
                "\"format_version\":2",
                "\"format_version\":7",
            ),
            "format version 7",
        ),
    ];
    for (dir, what) in cases {
        let o = merge_with(&dir, &tmp("refused"));
        assert!(!o.status.success(), "{what}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(what), "{what}: {err}");
    }
    let foreign = tmp("foreign");
    std::fs::create_dir_all(&foreign).expect("folder");
    std::fs::write(foreign.join("notes.json"), "{\"hello\": 1}").expect("written");
    let o = frameless(&[&"merge", &f.single, &foreign, &"--out", &tmp("foreign-out")])
        .output()
        .expect("runs");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("notes.json: not a job result"),
        "{err}"
    );
}

/// A result file that contradicts its own key, or whose sweep text was edited, is
/// refused with a message naming it; so is a merge into one of its own input folders.
#[test]
fn results_that_contradict_their_key_or_hash_are_refused() {
    use serde_json::Value;
    let f = fixture();
    // Shard 2's results, with `edit` applied to the one file `pick` chooses.
    let tamper = |name: &str, pick: &dyn Fn(&Value) -> bool, edit: &dyn Fn(&mut Value)| {
        let d = tmp(name);
        std::fs::create_dir_all(&d).expect("folder");
        let mut edited = None;
        for n in file_names(&f.shards[2]) {
            let text = std::fs::read_to_string(f.shards[2].join(&n)).expect("result");
            let mut v: Value = serde_json::from_str(&text).expect("JSON");
            if edited.is_none() && pick(&v) {
                edit(&mut v);
                edited = Some(n.clone());
            }
            std::fs::write(d.join(&n), serde_json::to_string(&v).expect("JSON")).expect("written");
        }
        (d, edited.expect("a result to edit"))
    };
    let rated = |v: &Value| v["key"]["rate"].is_number();
    let with_strips = |v: &Value| v["strips"].as_array().is_some_and(|s| !s.is_empty());
    let cases: Vec<(PathBuf, String, &str)> = vec![
        {
            let (d, n) = tamper("row-rate", &rated, &|v| {
                v["results"][0]["rate"] = 123456.0.into()
            });
            (d, n, "not this job's")
        },
        {
            let (d, n) = tamper("frame-method", &rated, &|v| {
                let other = if v["key"]["method"] == "adaptive" {
                    "framed-60hz"
                } else {
                    "adaptive"
                };
                v["frames"][3]["method"] = other.into();
            });
            (d, n, "not this job's")
        },
        {
            let (d, n) = tamper("strip-twice", &with_strips, &|v| {
                let first = v["strips"][0].clone();
                v["strips"].as_array_mut().unwrap().push(first);
            });
            (d, n, "there twice")
        },
        {
            let (d, n) = tamper("sweep-text", &rated, &|v| {
                let t = v["sweep_text"]
                    .as_str()
                    .unwrap()
                    .replace("ideal_spp = 4", "ideal_spp = 5");
                v["sweep_text"] = t.into();
            });
            (d, n, "edited")
        },
    ];
    for (dir, name, what) in cases {
        let o = merge_with(&dir, &tmp("contradiction"));
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{name}: {err}");
        assert!(
            err.contains(&name) && err.contains(what),
            "{name}, {what}: {err}"
        );
    }
    // One job's strip removed while another's is duplicated: the duplicate is refused
    // rather than shown under the wrong label.
    let (d, _) = tamper("strip-moved", &with_strips, &|v| {
        v["strips"].as_array_mut().unwrap().clear();
    });
    let o = merge_with(&d, &tmp("moved"));
    assert_eq!(
        o.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    // A merge's output folder may not be, hold or lie inside an input folder, and the
    // inputs are untouched.
    let before = tree(&f.shards[0]);
    let inside = f.shards[0].join("merged");
    let parent = f.shards[0].parent().unwrap().to_path_buf();
    for out in [&f.shards[0], &inside, &parent] {
        let o = merge_with(&f.shards[2], out);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            o.status.code() == Some(1) && err.contains("the input"),
            "{}: {err}",
            out.display()
        );
    }
    assert!(!inside.exists());
    assert_eq!(tree(&f.shards[0]), before);
}

/// A shard run again keeps the results it finds, so a stopped shard resumes.
#[test]
fn a_shard_run_again_keeps_its_finished_jobs() {
    let f = fixture();
    let before = tree(&f.shards[0]);
    let o = ok(
        frameless(&[
            &"sweep",
            &example(),
            &"--shard",
            &"0/3",
            &"--out",
            &f.shards[0],
            &"--no-cache",
        ])
        .output()
        .expect("runs"),
        "shard 0/3 again",
    );
    let stdout = String::from_utf8_lossy(&o.stdout);
    let n = before.len();
    assert!(
        stdout.contains(&format!("{n} jobs, 0 run, {n} kept")),
        "{stdout}"
    );
    assert!(tree(&f.shards[0]) == before, "kept results are untouched");
    // --list names the shard's jobs without running them.
    let o = ok(
        frameless(&[&"sweep", &example(), &"--shard", &"0/3", &"--list"])
            .output()
            .expect("runs"),
        "--list",
    );
    let mut listed: Vec<String> = String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(|l| format!("{l}.json"))
        .collect();
    listed.sort();
    assert_eq!(
        listed,
        before
            .keys()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
    );
}

/// `assets/sweeps/table1.toml`, made tiny (32x32, 0.05 s windows, one rate, three
/// methods, 1 spp ideals) and run as two shards, merges to what `frameless table1`
/// writes with the same settings: Table 1 runs through a sweep.
#[test]
#[ignore = "needs the BART scenes: set FRAMELESS_BART_DIR"]
fn bart_the_table1_sweep_merges_to_what_table1_writes() {
    let bart = std::env::var_os("FRAMELESS_BART_DIR")
        .map(PathBuf::from)
        .expect("FRAMELESS_BART_DIR must name the BART scene folder (e.g. ../shared/scenes/bart)");
    let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets");
    let text = std::fs::read_to_string(assets.join("sweeps/table1.toml")).expect("table1.toml");
    let methods = "traditional-frameless,adaptive-paper,full-res-60hz";
    let quoted: Vec<String> = methods.split(',').map(|m| format!("\"{m}\"")).collect();
    let start = text.find("methods = [").expect("methods");
    let end = start + text[start..].find(']').expect("list ends") + 1;
    let tiny = format!(
        "{}methods = [{}]{}",
        &text[..start],
        quoted.join(", "),
        &text[end..]
    );
    let replacements = [
        ("sizes = [\"256x256\"]", "sizes = [\"32x32\"]".to_string()),
        (
            "rates = [\"100k\", \"400k\", \"800k\"]",
            "rates = [\"100k\"]".into(),
        ),
        ("ideal_spp = 16", "ideal_spp = 1".into()),
        ("duration = 3.0", "duration = 0.05".into()),
        (
            "\"../camera_paths/",
            format!("\"{}/camera_paths/", assets.display()),
        ),
    ];
    let mut tiny = tiny;
    for (from, to) in replacements {
        assert!(tiny.contains(from), "{from}");
        tiny = tiny.replace(from, &to);
    }
    let dir = tmp("table1-sweep");
    std::fs::create_dir_all(&dir).expect("folder");
    let sweep = dir.join("table1-tiny.toml");
    std::fs::write(&sweep, tiny).expect("written");
    let cache = tmp("table1-cache");
    let results = dir.join("results");
    let children: Vec<_> = ["0/2", "1/2"]
        .iter()
        .map(|shard| {
            frameless(&[
                &"sweep",
                &sweep,
                &"--shard",
                shard,
                &"--out",
                &results,
                &"--bart",
                &bart,
                &"--cache-dir",
                &cache,
            ])
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .expect("frameless starts")
        })
        .collect();
    for c in children {
        ok(c.wait_with_output().expect("shard runs"), "a Table 1 shard");
    }
    let merged = tmp("table1-merged");
    ok(
        frameless(&[&"merge", &results, &"--out", &merged])
            .output()
            .expect("runs"),
        "the Table 1 merge",
    );
    let direct = tmp("table1-direct");
    ok(
        frameless(&[
            &"table1",
            &"--bart",
            &bart,
            &"--size",
            &"32x32",
            &"--duration",
            &"0.05",
            &"--rates",
            &"100k",
            &"--ideal-spp",
            &"1",
            &"--methods",
            &methods,
            &"--cache-dir",
            &cache,
            &"--out",
            &direct,
        ])
        .output()
        .expect("runs"),
        "frameless table1",
    );
    assert_same_outputs(&merged, &direct);
    assert!(std::fs::read_to_string(merged.join("table.md"))
        .expect("table.md")
        .contains("(34.4)"));
}
