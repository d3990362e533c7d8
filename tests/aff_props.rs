//! Robustness of the AFF loader: a valid scene using most directives (with an include and a
//! texture) is mutated at random; the loader must never panic, every error must say where
//! it is, and every scene it accepts must be internally consistent.

use std::fs;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use frameless::scene::aff::parse_str;
use frameless::scene::{NodeKind, Scene, SceneError};
use proptest::prelude::*;
use proptest::sample::{select, Index};
use proptest::test_runner::TestCaseError;

const MAIN: &[u8] = b"\
% a small scene touching most directives \xe9
v
from 0 1 -6
at 0 1 0
up 0 1 0
angle 45
hither 0.1
resolution 64 48
b 0.5 0.5 1.0
am 0.5 0.5 0.5
l -4 4.5 0 0.5 0.5 0.5
l 4 4.5 0
la lamp 0 3 0 1 1 1
f 1 0.5 0.2 0.8 0.2 10 0 1
s 0 0 0 1
c 0 0 0 1 0 1 0 0.5
fm 0.2 0.2 0.2 0.6 0.6 0.6 0.3 0.3 0.3 20 0 1.5
p 4 0 0 0 1 0 0 1 1 0 0 1 0
pp 3 0 0 0 0 0 1 1 0 0 0 0 1 0 1 0 0 0 1
tt tex.ppm 0 0 0 0 0 1 0 0 1 0 0 1 0 0 1
ttp tex.ppm 0 0 0 0 0 1 0 0  1 0 0 0 0 1 1 0  0 1 0 0 0 1 0 1
tpa 2
 0 0 0 0 0 0 1 1 0 0 0 0 1 0 1 0 0 0 1
 1 0 0 1 0 0 1 1 0 1 0 0 1 0 1 1 0 0 1
d 0
xs 2 2 2 0 1 0 90 1 0 0 {
  m vertices 3 0 0 0 1 0 0 0 1 0
    normals 1 0 0 1
    texturecoords 3 tex.ppm 0 0 1 0 0 1
    triangles 1 0 1 2 0 0 0 0 1 2
  x spin {
    i 0 part.aff
    i 5 never.aff
  }
}
a 0 4 100
k spin {
  transl 4
  0 0 0 0 0 0 0
  1 1 0 0 0 0 0
  2 2 0 0 0 0 0
  3 3 0 0 0 0 0
  rot 4
  0 0 1 0 0 0 0 0
  1 0 1 0 90 0 0 0
  2 0 1 0 180 0 0 0
  3 0 1 0 270 0 0 0
  scale 4
  0 1 1 1 0 0 0
  1 1 1 1 0 0 0
  2 2 2 2 0 0 0
  3 2 2 2 0 0 0
  visibility 2
  0 1
  2.5 0
}
k camera {
  transl 4
  0 0 1 -6 0 0 0
  1 0 1 -6 0 0 0
  2 0 1 -5 0 0 0
  3 0 1 -4 0 0 0
}
k lamp { transl 4 0 0 3 0 0 0 0 1 0 3 0 0 0 0 2 1 3 0 0 0 0 3 1 3 0 0 0 0 }
";

const PART: &str = "\
# the included part
fm 0.1 0.1 0.1 0.9 0.1 0.1 0 0 0 5 0 1
m vertices 4 0 0 0 1 0 0 1 1 0 0 1 0
  triangles 2 0 1 2 0 2 3
xs 1 1 1 0 0 1 45 0 0 0 { s 0 2 0 0.5 }
tt tex.ppm 0 0 0 0 0 1 0 0 1 0 0 1 0 0 1
";

/// Tokens spliced into the text: directives, braces, odd numbers, file names and junk.
const TOKENS: &[&str] = &[
    "{",
    "}",
    "x",
    "xs",
    "k",
    "m",
    "p",
    "pp",
    "tt",
    "ttp",
    "tpa",
    "i",
    "d",
    "a",
    "v",
    "l",
    "la",
    "f",
    "fm",
    "c",
    "s",
    "b",
    "am",
    "0",
    "1",
    "-1",
    "3",
    "4",
    "2.5",
    ".5",
    "1e39",
    "-1e-40",
    "nan",
    "inf",
    "49999999",
    "50000001",
    "99999999999999999999",
    "vertices",
    "normals",
    "texturecoords",
    "triangles",
    "transl",
    "rot",
    "scale",
    "visibility",
    "from",
    "resolution",
    "main.aff",
    "part.aff",
    "tex.ppm",
    "missing.ppm",
    "i 0 main.aff",
    "i 0 part.aff",
    "#",
    "%",
    "\n",
    "\u{e9}",
    "\u{0}",
];

#[derive(Clone, Debug)]
enum Mutation {
    Truncate(Index),
    DeleteBytes(Index, usize),
    InsertBytes(Index, Vec<u8>),
    ReplaceByte(Index, u8),
    DeleteToken(Index),
    ReplaceToken(Index, &'static str),
    InsertToken(Index, &'static str),
    DuplicateLine(Index),
    DeleteLine(Index),
    SwapLines(Index, Index),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        1 => any::<Index>().prop_map(Mutation::Truncate),
        2 => (any::<Index>(), 1usize..12).prop_map(|(i, n)| Mutation::DeleteBytes(i, n)),
        2 => (any::<Index>(), prop::collection::vec(any::<u8>(), 1..4))
            .prop_map(|(i, b)| Mutation::InsertBytes(i, b)),
        2 => (any::<Index>(), any::<u8>()).prop_map(|(i, b)| Mutation::ReplaceByte(i, b)),
        3 => any::<Index>().prop_map(Mutation::DeleteToken),
        4 => (any::<Index>(), select(TOKENS)).prop_map(|(i, t)| Mutation::ReplaceToken(i, t)),
        3 => (any::<Index>(), select(TOKENS)).prop_map(|(i, t)| Mutation::InsertToken(i, t)),
        2 => any::<Index>().prop_map(Mutation::DuplicateLine),
    ]
}

/// Whole-line edits, which keep most one-line directives intact and so reach deeper into
/// scenes that still load.
fn line_edit() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        any::<Index>().prop_map(Mutation::DuplicateLine),
        any::<Index>().prop_map(Mutation::DeleteLine),
        (any::<Index>(), any::<Index>()).prop_map(|(a, b)| Mutation::SwapLines(a, b)),
    ]
}

/// Byte ranges of whitespace-separated tokens.
fn token_spans(text: &[u8]) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    let mut start = None;
    for (i, b) in text.iter().enumerate() {
        match (b.is_ascii_whitespace(), start) {
            (false, None) => start = Some(i),
            (true, Some(s)) => {
                spans.push((s, i));
                start = None;
            }
            _ => {}
        }
    }
    if let Some(s) = start {
        spans.push((s, text.len()));
    }
    spans
}

fn apply(text: &mut Vec<u8>, m: &Mutation) {
    let spans = token_spans(text);
    let at = |i: &Index| i.index(text.len() + 1);
    match m {
        Mutation::Truncate(i) => {
            let n = at(i);
            text.truncate(n);
        }
        Mutation::DeleteBytes(i, n) => {
            let s = at(i).min(text.len());
            let e = (s + n).min(text.len());
            text.drain(s..e);
        }
        Mutation::InsertBytes(i, b) => {
            let s = at(i);
            text.splice(s..s, b.iter().copied());
        }
        Mutation::ReplaceByte(i, b) => {
            if !text.is_empty() {
                let s = i.index(text.len());
                text[s] = *b;
            }
        }
        Mutation::DeleteToken(i) | Mutation::ReplaceToken(i, _) | Mutation::InsertToken(i, _) => {
            if spans.is_empty() {
                return;
            }
            let (s, e) = spans[i.index(spans.len())];
            match m {
                Mutation::DeleteToken(_) => {
                    text.drain(s..e);
                }
                Mutation::ReplaceToken(_, t) => {
                    text.splice(s..e, t.bytes());
                }
                Mutation::InsertToken(_, t) => {
                    let mut b = t.as_bytes().to_vec();
                    b.push(b' ');
                    text.splice(s..s, b);
                }
                _ => unreachable!(),
            }
        }
        Mutation::DuplicateLine(i) | Mutation::DeleteLine(i) | Mutation::SwapLines(i, _) => {
            let mut lines: Vec<Vec<u8>> = text.split(|&b| b == b'\n').map(<[u8]>::to_vec).collect();
            let k = i.index(lines.len());
            match m {
                Mutation::DuplicateLine(_) => {
                    let l = lines[k].clone();
                    lines.insert(k, l);
                }
                Mutation::DeleteLine(_) => {
                    lines.remove(k);
                }
                Mutation::SwapLines(_, j) => {
                    let j = j.index(lines.len());
                    lines.swap(k, j);
                }
                _ => unreachable!(),
            }
            *text = lines.join(&b'\n');
        }
    }
}

/// A fresh directory holding the included file and the texture.
fn case_dir(part: &[u8]) -> PathBuf {
    static N: AtomicUsize = AtomicUsize::new(0);
    let n = N.fetch_add(1, Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("frameless-aff-props-{}-{n}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).unwrap();
    fs::write(dir.join("part.aff"), part).unwrap();
    let mut ppm = b"P6\n# texture\n2 2\n255\n".to_vec();
    ppm.extend_from_slice(&[255, 0, 0, 0, 255, 0, 0, 0, 255, 255, 255, 255]);
    fs::write(dir.join("tex.ppm"), ppm).unwrap();
    dir
}

/// Everything a renderer indexes must be in range, and evaluating must not panic.
fn check_scene(s: &Scene) -> Result<(), TestCaseError> {
    let (nm, nt, nn, ntr) = (
        s.materials.len(),
        s.textures.len(),
        s.nodes.len(),
        s.tracks.len(),
    );
    for (i, n) in s.nodes.iter().enumerate() {
        prop_assert!(
            n.parent.is_none_or(|p| (p as usize) < i),
            "parent after child"
        );
        if let NodeKind::Animated { track: Some(t), .. } = n.kind {
            prop_assert!((t as usize) < ntr);
        }
    }
    for m in &s.materials {
        prop_assert!(m.texture.is_none_or(|t| (t as usize) < nt));
    }
    for g in &s.groups {
        prop_assert!(g.node.is_none_or(|n| (n as usize) < nn));
        for t in &g.triangles {
            prop_assert!((t.material as usize) < nm);
            prop_assert!(t.p.iter().all(|p| p.is_finite()));
        }
        for sp in &g.spheres {
            prop_assert!((sp.material as usize) < nm && sp.center.is_finite());
        }
        for c in &g.cones {
            prop_assert!((c.material as usize) < nm && c.base.is_finite() && c.apex.is_finite());
        }
        if let Some(n) = g.node {
            let _ = s.node_state(n, 1.5);
        }
    }
    for a in &s.animated_triangles {
        prop_assert!(!a.times.is_empty());
        prop_assert!(a.positions.len() == a.times.len() && a.normals.len() == a.times.len());
        prop_assert!((a.material as usize) < nm && a.node.is_none_or(|n| (n as usize) < nn));
        let _ = a.eval(0.5);
    }
    prop_assert!(s.camera.track.is_none_or(|t| (t as usize) < ntr));
    prop_assert!(s
        .lights
        .iter()
        .all(|l| l.track.is_none_or(|t| (t as usize) < ntr)));
    let _ = s.camera_at(1.0);
    let _ = s.lights_at(1.0);
    Ok(())
}

/// Every error must point at a file, and parse errors at a place in it.
fn check_error(e: &SceneError, dir: &Path) -> Result<(), TestCaseError> {
    let msg = e.to_string();
    match e {
        SceneError::Parse {
            file, line, column, ..
        } => {
            // The scene, or a file of its folder that a (mutated) include names: the
            // part, or even the texture, which then fails to parse as a scene.
            prop_assert!(
                file == "main.aff" || Path::new(file.as_str()).starts_with(dir),
                "unexpected file in {msg}"
            );
            prop_assert!(*line >= 1 && *column >= 1, "{msg}");
            let location = format!("{file}:{line}:{column}");
            prop_assert!(msg.contains(&location), "{msg} lacks {location}");
        }
        SceneError::Io { path, .. } | SceneError::Texture { path, .. } => {
            prop_assert!(msg.contains(&path.display().to_string()), "{msg}");
        }
        other => prop_assert!(false, "unexpected error kind: {other:?}"),
    }
    Ok(())
}

#[test]
fn unmutated_scene_is_valid() {
    let dir = case_dir(PART.as_bytes());
    let s = parse_str("main.aff", MAIN, &dir).unwrap_or_else(|e| panic!("{e}"));
    check_scene(&s).unwrap();
    assert_eq!(s.textures.len(), 1);
    assert_eq!(s.animated_triangles.len(), 1);
    assert!(s.camera.track.is_some() && s.lights[2].track.is_some());
    // Main: p 4 (2) + pp + tt + ttp + m (1); part: m (2) + tt.
    let tris: usize = s.groups.iter().map(|g| g.triangles.len()).sum();
    assert_eq!(tris, 2 + 1 + 1 + 1 + 1 + 2 + 1);
    let _ = fs::remove_dir_all(dir);
}

#[test]
fn an_include_naming_the_texture_fails_in_the_texture() {
    // Found by the mutation test below in a CI run: `i 0 tex.ppm` parses
    // the image as a scene, and the error names the image, line 1.
    let dir = case_dir(PART.as_bytes());
    // MAIN holds a byte that is not UTF-8 (a test of its own): splice bytes.
    let (from, to) = (b"i 0 part.aff", b"i 0 tex.ppm");
    let at = MAIN
        .windows(from.len())
        .position(|w| w == from)
        .expect("MAIN includes part.aff");
    let main = [&MAIN[..at], &to[..], &MAIN[at + from.len()..]].concat();
    let e = parse_str("main.aff", &main, &dir).expect_err("an image is no scene");
    match &e {
        SceneError::Parse { file, line, .. } => {
            assert_eq!(*file, dir.join("tex.ppm").display().to_string(), "{e}");
            assert_eq!(*line, 1, "{e}");
        }
        other => panic!("unexpected error: {other:?}"),
    }
    check_error(&e, &dir).unwrap();
    let _ = fs::remove_dir_all(dir);
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 256,
        // Keep regressions out of the source tree; a failure prints its minimal input.
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn mutated_scenes_never_panic_and_errors_have_locations(
        mutate_part in prop::bool::weighted(0.25),
        mutations in prop::collection::vec(mutation(), 1..6),
    ) {
        run_case(mutate_part, &mutations)?;
    }

    #[test]
    fn line_edited_scenes_never_panic_and_errors_have_locations(
        mutate_part in prop::bool::weighted(0.25),
        mutations in prop::collection::vec(line_edit(), 1..4),
    ) {
        run_case(mutate_part, &mutations)?;
    }
}

fn run_case(mutate_part: bool, mutations: &[Mutation]) -> Result<(), TestCaseError> {
    let mut main = MAIN.to_vec();
    let mut part = PART.as_bytes().to_vec();
    for m in mutations {
        apply(if mutate_part { &mut part } else { &mut main }, m);
    }
    let dir = case_dir(&part);
    let result = parse_str("main.aff", &main, &dir);
    let checked = match &result {
        Ok(s) => check_scene(s),
        Err(e) => check_error(e, &dir),
    };
    let _ = fs::remove_dir_all(&dir);
    checked
}
