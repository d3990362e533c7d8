//! Property tests over the files `sweep` and `report` read: sweep files with random
//! keys and values at, inside and past every range, and evaluation folders whose
//! `summary.json` and `frames.csv` were mutated. Each gives a clean error or a result,
//! never a panic, and a value past its range is always an error.

use std::path::{Path, PathBuf};

use frameless::{
    evaluation::{report, sweep::Sweep},
    limits,
};
use proptest::prelude::*;

/// A numeric sweep setting: its key, and values inside its range and past it.
struct Setting {
    key: &'static str,
    inside: Vec<String>,
    past: Vec<String>,
}

fn settings() -> Vec<Setting> {
    let s = |key, inside: &[&str], past: &[&str]| Setting {
        key,
        inside: inside.iter().map(|v| v.to_string()).collect(),
        past: past.iter().map(|v| v.to_string()).collect(),
    };
    let spp = limits::MAX_IDEAL_SPP;
    let depth = limits::MAX_DEPTH;
    vec![
        s(
            "ideal_spp",
            &["1", "16", &spp.to_string()],
            &["0", &(spp + 1).to_string(), "4294967295", "-1"],
        ),
        s(
            "max_depth",
            &["0", "5", &depth.to_string()],
            &[&(depth + 1).to_string(), "4294967295", "-1"],
        ),
        s("flip_every", &["1", "7"], &["0", "-3"]),
        s(
            "refresh_hz",
            &["1.0", "60.0", "1000.0"],
            &["0.5", "1000.5", "nan", "inf", "-60.0"],
        ),
        s(
            "sizes",
            &["[\"16x16\"]", "[\"4096x1\"]", "[\"1x4096\"]"],
            &[
                "[\"4097x4096\"]",
                "[\"0x16\"]",
                "[]",
                "[\"16x16\", \"16x16\"]",
            ],
        ),
        s(
            "rates",
            &["[\"100k\"]", "[\"60\", \"1M\"]"],
            &[
                "[\"1e9\"]",
                "[\"0\"]",
                "[]",
                "[\"100k\", \"100k\"]",
                "[\"-5\"]",
            ],
        ),
        s(
            "seeds",
            &["[1]", "[0, 9223372036854775807]"],
            &["[]", "[1, 1]", "[-1]"],
        ),
    ]
}

/// The evaluation's settings: key, inside, past.
fn evaluation_settings() -> Vec<Setting> {
    let s = |key, inside: &[&str], past: &[&str]| Setting {
        key,
        inside: inside.iter().map(|v| v.to_string()).collect(),
        past: past.iter().map(|v| v.to_string()).collect(),
    };
    vec![
        s("start", &["1", "0", "-2"], &["1e300", "nan", "20000"]),
        s("duration", &["0.1", "1"], &["0", "-1", "3601", "inf"]),
        s("warmup", &["0", "0.5", "600"], &["-0.1", "601", "nan"]),
    ]
}

/// One sweep file: per setting, `None` (left out), `Some((false, i))` (inside value i)
/// or `Some((true, i))` (past value i); and perhaps an unknown key.
fn sweep_file(
    top: &[Option<(bool, usize)>],
    eval: &[Option<(bool, usize)>],
    unknown: Option<&str>,
) -> (String, bool) {
    let mut past_any = false;
    let mut pick = |s: &Setting, c: Option<(bool, usize)>| {
        c.map(|(past, i)| {
            past_any |= past;
            let list = if past { &s.past } else { &s.inside };
            (s.key, list[i % list.len()].clone())
        })
    };
    let mut text = String::from("name = \"p\"\nmethods = [\"traditional-frameless\"]\n");
    let defaults = [
        ("sizes", "[\"16x16\"]"),
        ("rates", "[\"100k\"]"),
        ("seeds", "[1]"),
    ];
    let chosen: Vec<(&str, String)> = settings()
        .iter()
        .zip(top)
        .filter_map(|(s, &c)| pick(s, c))
        .collect();
    for (k, v) in defaults {
        if !chosen.iter().any(|(c, _)| *c == k) {
            text += &format!("{k} = {v}\n");
        }
    }
    for (k, v) in &chosen {
        text += &format!("{k} = {v}\n");
    }
    if let Some(k) = unknown {
        text += &format!("{k} = 1\n");
    }
    text += "[[evaluation]]\nname = \"e\"\nscene = \"toycar\"\n";
    let chosen: Vec<(&str, String)> = evaluation_settings()
        .iter()
        .zip(eval)
        .filter_map(|(s, &c)| pick(s, c))
        .collect();
    for (k, default) in [("start", "1"), ("duration", "0.1"), ("warmup", "0.1")] {
        let v = chosen
            .iter()
            .find(|(c, _)| *c == k)
            .map_or(default.to_string(), |(_, v)| v.clone());
        text += &format!("{k} = {v}\n");
    }
    (text, past_any || unknown.is_some())
}

fn choice() -> impl Strategy<Value = Option<(bool, usize)>> {
    prop::option::weighted(0.6, (prop::bool::weighted(0.3), 0usize..8))
}

/// A fresh copy of the committed `toycar` evaluation folder.
fn eval_copy(case: u64) -> PathBuf {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/results/toycar");
    let d = std::env::temp_dir().join(format!(
        "frameless-report-props-{}-{case}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    for e in std::fs::read_dir(src).unwrap() {
        let e = e.unwrap();
        std::fs::copy(e.path(), d.join(e.file_name())).unwrap();
    }
    d
}

/// Values a field of `summary.json` or a cell of `frames.csv` is set to.
const ODD: &[&str] = &[
    "0",
    "-1",
    "1e300",
    "-1e300",
    "2147483664",
    "4294967296",
    "18446744073709551616",
    "NaN",
    "\"x\"",
    "null",
    "[]",
    "{}",
    "0.5",
    "true",
    "\"adaptive\"",
    "\"ideal\"",
];

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 256,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn sweep_files_parse_or_fail_cleanly_and_past_a_range_always_fails(
        top in prop::collection::vec(choice(), 7),
        eval in prop::collection::vec(choice(), 3),
        unknown in prop::option::weighted(0.1, prop::sample::select(vec!["ideal_sp", "depth", "x"])),
    ) {
        let (text, past) = sweep_file(&top, &eval, unknown);
        let parsed = Sweep::parse(&text, "p.toml");
        if past {
            prop_assert!(parsed.is_err(), "accepted:\n{}", text);
        }
        if let Err(e) = parsed {
            // Errors name the file.
            prop_assert!(e.to_string().contains("p.toml"), "{}", e);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 48,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn mutated_evaluation_folders_are_reported_or_refused_cleanly(
        case in any::<u64>(),
        summary_edits in prop::collection::vec((any::<prop::sample::Index>(), 0..ODD.len()), 0..3),
        row_edits in prop::collection::vec(
            (any::<prop::sample::Index>(), any::<prop::sample::Index>(), 0..ODD.len()), 0..4),
    ) {
        let d = eval_copy(case);
        let p = d.join("summary.json");
        let mut v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
        let keys: Vec<String> = v.as_object().unwrap().keys().cloned().collect();
        for (k, odd) in &summary_edits {
            let key = k.get(&keys).clone();
            v[&key] = serde_json::from_str(ODD[*odd]).unwrap_or(serde_json::Value::Null);
        }
        std::fs::write(&p, serde_json::to_string(&v).unwrap()).unwrap();
        let f = d.join("frames.csv");
        let text = std::fs::read_to_string(&f).unwrap();
        let mut lines: Vec<Vec<String>> =
            text.lines().map(|l| l.split(',').map(String::from).collect()).collect();
        for (row, col, odd) in &row_edits {
            let r = 1 + row.index(lines.len() - 1);
            let c = col.index(lines[r].len());
            lines[r][c] = ODD[*odd].trim_matches('"').to_string();
        }
        let text: Vec<String> = lines.iter().map(|l| l.join(",")).collect();
        std::fs::write(&f, text.join("\n") + "\n").unwrap();
        // Either outcome is fine; a panic fails the test.
        let _ = report::rewrite(&d);
        let _ = std::fs::remove_dir_all(&d);
    }
}
