use std::path::Path;

use super::*;
use crate::evaluation::table1;

const EXAMPLE: &str = include_str!("../../../assets/sweeps/example.toml");
const TABLE1: &str = include_str!("../../../assets/sweeps/table1.toml");

fn parse(text: &str) -> Result<Sweep, SweepError> {
    Sweep::parse(text, "test.toml")
}

/// The smallest valid sweep, with `extra` inserted before its evaluation.
fn minimal(extra: &str) -> String {
    format!(
        "name = \"t\"\nsizes = [\"16x12\"]\nseeds = [1]\nmethods = [\"adaptive\"]\n\
         rates = [\"100k\"]\n{extra}\n[[evaluation]]\nname = \"a\"\nscene = \"toycar\"\n\
         start = 0.2\nduration = 0.1\nwarmup = 0.1\n"
    )
}

#[test]
fn committed_sweeps_parse_into_their_jobs() {
    let ex = parse(EXAMPLE).expect("example.toml parses");
    // Three methods at two rates, and one that ignores the rate.
    assert_eq!(ex.jobs().len(), 3 * 2 + 1);
    let t = parse(TABLE1).expect("table1.toml parses");
    assert_eq!(t.report, SweepReport::Table1);
    // Four animations, ten methods at three rates and full-res-60hz once.
    assert_eq!(t.jobs().len(), 4 * (10 * 3 + 1));
    let ids: Vec<String> = t.jobs().iter().map(JobKey::id).collect();
    let unique: std::collections::HashSet<&String> = ids.iter().collect();
    assert_eq!(unique.len(), ids.len(), "job names are unique");
    assert!(ids.contains(&"interactive.256x256.seed1.adaptive.400K".to_string()));
    assert!(ids.contains(&"still.256x256.seed1.full-res-60hz.any-rate".to_string()));
}

/// `assets/sweeps/table1.toml` is the jobs of `frameless table1`: its animations, in
/// order, with their windows, descriptions and camera paths, and its methods.
#[test]
fn table1_sweep_reproduces_the_table1_animations() {
    let t = parse(TABLE1).expect("table1.toml parses");
    let names: Vec<&str> = t.evaluations.iter().map(|e| e.name.as_str()).collect();
    let expected: Vec<&str> = table1::ANIMATIONS.iter().map(|a| a.name).collect();
    assert_eq!(names, expected);
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/sweeps");
    for (e, a) in t.evaluations.iter().zip(table1::ANIMATIONS) {
        assert_eq!(
            (e.start, e.duration, e.warmup),
            (a.start, a.duration, a.warmup),
            "{}",
            a.name
        );
        assert_eq!(e.description, a.description, "{}", a.name);
        assert_eq!(e.scene, "bart:kitchen/kitchen.aff");
        assert_eq!(e.title, format!("kitchen ({})", a.name));
        match (&e.camera_path, a.camera_path, a.camera_path_file) {
            (None, None, None) => {}
            (Some(p), Some(text), Some(file)) => {
                assert!(p.ends_with(&format!("/{file}")), "{p}");
                let on_disk = std::fs::read_to_string(dir.join(p)).expect("camera path");
                assert_eq!(on_disk, text, "{}", a.name);
            }
            other => panic!("{}: camera paths differ: {other:?}", a.name),
        }
    }
    assert_eq!(t.methods, table1::METHODS.to_vec());
    // `frameless table1` traces at depth 5.
    assert_eq!(t.max_depth, 5);
}

#[test]
fn every_shard_count_splits_the_same_jobs_once() {
    let t = parse(TABLE1).expect("table1.toml parses");
    let jobs = t.jobs();
    for n in 1..=9 {
        let mut per_shard = vec![0usize; n as usize];
        for j in &jobs {
            let owners: Vec<u32> = (0..n)
                .filter(|&i| Shard { index: i, count: n }.owns(j))
                .collect();
            assert_eq!(owners.len(), 1, "{} at N = {n}", j.id());
            per_shard[owners[0] as usize] += 1;
        }
        // A hash, so not exactly even; but no shard may be left idle or take twice
        // its share of the 124 jobs.
        let fair = jobs.len() / n as usize;
        assert!(
            per_shard.iter().all(|&c| c > 0 && c <= 2 * fair),
            "N = {n}: {per_shard:?}"
        );
    }
    // The shards of the example sweep all have work, which the sharded-run test needs.
    let ex = parse(EXAMPLE).expect("example.toml parses");
    for i in 0..3 {
        let s = Shard { index: i, count: 3 };
        assert!(ex.jobs().iter().any(|j| s.owns(j)), "shard {s} is empty");
    }
}

/// The hash decides which shard runs what; shards built by different versions must
/// agree, so it is pinned.
#[test]
fn the_shard_hash_is_pinned() {
    assert_eq!(stable_hash(b""), mix64(0xcbf2_9ce4_8422_2325));
    // FNV-1a of "a" is 0xaf63dc4c8601ec8c.
    assert_eq!(stable_hash(b"a"), mix64(0xaf63_dc4c_8601_ec8c));
}

#[test]
fn shards_parse() {
    assert_eq!(
        "2/3".parse::<Shard>().ok(),
        Some(Shard { index: 2, count: 3 })
    );
    assert_eq!(
        " 0 / 1 ".parse::<Shard>().ok(),
        Some(Shard { index: 0, count: 1 })
    );
    for bad in ["3/3", "1/0", "a/b", "1", "-1/3", "0/100001", ""] {
        let e = bad.parse::<Shard>().expect_err(bad).to_string();
        assert!(e.contains("i/N"), "{bad}: {e}");
    }
}

#[test]
fn an_unknown_key_is_an_error_naming_its_line_and_key() {
    let e = parse(&minimal("colour = \"red\""))
        .expect_err("unknown key")
        .to_string();
    assert!(e.contains("test.toml"), "{e}");
    assert!(e.contains("line 6"), "{e}");
    assert!(e.contains("colour"), "{e}");
    let text = minimal("").replace("warmup = 0.1", "warmup = 0.1\nwarm_up = 1");
    let e = parse(&text)
        .expect_err("unknown key in an evaluation")
        .to_string();
    assert!(e.contains("line 13") && e.contains("warm_up"), "{e}");
}

#[test]
fn bad_values_name_their_line() {
    let cases = [
        (minimal("").replace("\"adaptive\"", "\"adaptive-magic\""), "line 4", "adaptive-magic"),
        (minimal("").replace("\"100k\"", "\"fast\""), "line 5", "fast"),
        (minimal("").replace("\"16x12\"", "\"16by12\""), "line 2", "16by12"),
        (minimal("").replace("seeds = [1]", "seeds = []"), ":3:", "lists nothing"),
        (minimal("").replace("seeds = [1]", "seeds = [1, 1]"), ":3:", "twice"),
        (minimal("").replace("name = \"a\"", "name = \"a b\""), ":8:", "a b"),
        (minimal("strips = \"some\""), "line 6", "some"),
        (
            minimal("").replace("duration = 0.1", "duration = 0"),
            ":8:",
            "evaluation 'a' at 16x12: duration",
        ),
        (
            format!(
                "{}[[evaluation]]\nname = \"a\"\nscene = \"toycar\"\nstart = 0\nduration = 0.1\nwarmup = 0\n",
                minimal("")
            ),
            ":14:",
            "names two evaluations",
        ),
    ];
    for (text, place, what) in cases {
        let e = parse(&text).expect_err(what).to_string();
        assert!(e.contains(place) && e.contains(what), "{what}: {e}");
    }
    let e =
        parse(&minimal("").replace("[[evaluation]]", "[[nothing]]")).expect_err("no evaluation");
    assert!(e.to_string().contains("nothing"), "{e}");
}

#[test]
fn a_method_that_ignores_the_rate_is_one_job_filling_every_column() {
    let t = parse(EXAMPLE).expect("example.toml parses");
    let inst = t.instances()[0];
    let full_res = t
        .instance_jobs(&inst)
        .into_iter()
        .find(|j| j.method == MethodKind::FullRes60Hz)
        .expect("full-res-60hz job");
    assert_eq!(full_res.rate, None);
    let cfg = t.job_config(&inst, &full_res, None, None);
    assert_eq!(cfg.rates, t.rates);
    let adaptive = JobKey {
        method: MethodKind::Adaptive,
        rate: Some(t.rates[1]),
        ..full_res
    };
    let cfg = t.job_config(&inst, &adaptive, None, None);
    assert_eq!(
        (cfg.methods, cfg.rates),
        (vec![MethodKind::Adaptive], vec![t.rates[1]])
    );
}

/// A sweep of `n` evaluation tables.
fn evaluations_text(n: usize) -> String {
    use std::fmt::Write;
    let mut text = minimal("");
    for i in 0..n {
        let _ = write!(
            text,
            "[[evaluation]]\nname = \"e{i}\"\nscene = \"toycar\"\nstart = 0.2\n\
             duration = 0.1\nwarmup = 0.1\n"
        );
    }
    text
}

/// Every evaluation's line is named from an index of the line starts built once; a scan
/// from the top for each table made a file of 40,000 tables take minutes to check.
#[test]
fn checking_a_sweep_takes_time_about_linear_in_its_tables() {
    let text = evaluations_text(50);
    let s = parse(&text).unwrap();
    for e in &s.evaluations {
        let key = format!("name = \"{}\"", e.name);
        let line = text.lines().position(|l| l == key).unwrap() + 1;
        assert_eq!(e.line, line, "{}", e.name);
    }
    // The best of three runs, so that another process's burst does not decide. Four
    // times the tables take about four times as long when the check is linear and
    // sixteen times when it is quadratic; the bound lies between them.
    let best = |n: usize| {
        let text = evaluations_text(n);
        (0..3)
            .map(|_| {
                let t0 = std::time::Instant::now();
                parse(&text).unwrap();
                t0.elapsed().as_secs_f64()
            })
            .fold(f64::INFINITY, f64::min)
    };
    let (small, large) = (best(4_000), best(16_000));
    assert!(
        large / small < 8.0,
        "4,000 tables {small:.3} s, 16,000 tables {large:.3} s: {:.1} times",
        large / small
    );
}
