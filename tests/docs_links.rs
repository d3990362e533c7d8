//! The committed documents and reports name only files that are committed: every
//! relative link and image of the README and `docs/**/*.md` (`docs/usage.md`, the
//! command reference, included), and every `src` and `href` of the committed
//! `report.html` files. A link into a Markdown file's section (`file.md#anchor`, or
//! `#anchor` within the same file) must name a heading that file has, so that moving a
//! section between documents cannot leave links pointing at nothing.

use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Files under `dir` whose name ends in `suffix`.
fn files(dir: &Path, suffix: &str, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().path()) {
        if e.is_dir() {
            files(&e, suffix, out);
        } else if e.to_string_lossy().ends_with(suffix) {
            out.push(e);
        }
    }
}

/// The targets of `](target)` in Markdown text (links and images).
fn markdown_targets(text: &str) -> Vec<String> {
    text.match_indices("](")
        .filter_map(|(i, _)| {
            let rest = &text[i + 2..];
            rest.find(')').map(|end| rest[..end].to_string())
        })
        .collect()
}

/// The values of `src="…"` and `href="…"` in HTML text.
fn html_targets(text: &str) -> Vec<String> {
    ["src=\"", "href=\""]
        .iter()
        .flat_map(|attr| {
            text.match_indices(attr).filter_map(move |(i, _)| {
                let rest = &text[i + attr.len()..];
                rest.find('"').map(|end| rest[..end].to_string())
            })
        })
        .collect()
}

/// The anchors GitHub gives a Markdown text's headings: lower case, spaces as hyphens,
/// punctuation other than `-` and `_` dropped, `-1`, `-2`, … after repeats. Headings
/// inside fenced code are not headings.
fn anchors(text: &str) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    let mut fenced = false;
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        let Some(title) = line.strip_prefix('#') else {
            continue;
        };
        if fenced {
            continue;
        }
        let title = title.trim_start_matches('#');
        if !title.starts_with(' ') {
            continue;
        }
        let slug: String = title
            .trim()
            .to_lowercase()
            .chars()
            .filter_map(|c| match c {
                ' ' => Some('-'),
                c if c.is_alphanumeric() || c == '-' || c == '_' => Some(c),
                _ => None,
            })
            .collect();
        let repeats = out
            .iter()
            .filter(|a| {
                **a == slug
                    || a.strip_prefix(&format!("{slug}-"))
                        .is_some_and(|n| n.parse::<u32>().is_ok())
            })
            .count();
        out.push(if repeats == 0 {
            slug
        } else {
            format!("{slug}-{repeats}")
        });
    }
    out
}

/// The targets that name a file of the repository, or a section of a Markdown file,
/// that is not there.
fn missing(doc: &Path, targets: Vec<String>) -> Vec<String> {
    let dir = doc.parent().unwrap();
    targets
        .into_iter()
        .filter(|t| !t.contains("://") && !t.starts_with("mailto:"))
        .filter_map(|t| {
            let (path, anchor) = match t.split_once('#') {
                Some((p, a)) => (p, Some(a)),
                None => (t.as_str(), None),
            };
            let file = if path.is_empty() {
                doc.to_path_buf()
            } else {
                dir.join(path)
            };
            let ok = file.exists()
                && match anchor {
                    Some(a) if file.extension().is_some_and(|e| e == "md") => {
                        anchors(&std::fs::read_to_string(&file).unwrap())
                            .iter()
                            .any(|h| h == a)
                    }
                    _ => true,
                };
            (!ok).then(|| format!("{}: {t}", doc.display()))
        })
        .collect()
}

#[test]
fn documents_link_only_committed_files() {
    let mut docs = vec![root().join("README.md")];
    files(&root().join("docs"), ".md", &mut docs);
    assert!(docs.len() > 5, "{docs:?}");
    let mut bad = Vec::new();
    let mut checked = 0;
    for d in &docs {
        let targets = markdown_targets(&std::fs::read_to_string(d).unwrap());
        checked += targets.len();
        bad.extend(missing(d, targets));
    }
    assert!(
        checked > 50,
        "only {checked} links found: is the parser broken?"
    );
    assert!(
        bad.is_empty(),
        "links to files that are not there:\n{}",
        bad.join("\n")
    );
}

#[test]
fn committed_reports_load_only_committed_files() {
    let mut reports = Vec::new();
    files(&root().join("docs/results"), "report.html", &mut reports);
    assert!(!reports.is_empty());
    let mut bad = Vec::new();
    for r in &reports {
        let targets = html_targets(&std::fs::read_to_string(r).unwrap());
        assert!(!targets.is_empty(), "{} names no file", r.display());
        bad.extend(missing(r, targets));
    }
    assert!(
        bad.is_empty(),
        "reports name files that are not there:\n{}",
        bad.join("\n")
    );
}

#[test]
fn the_checks_see_a_missing_file() {
    let doc = root().join("README.md");
    assert_eq!(
        missing(
            &doc,
            markdown_targets("see [x](docs/nope.md) and [y](LICENSE-MIT)")
        )
        .len(),
        1
    );
    // A section the file has, one it lacks, and the same two within the README.
    assert_eq!(
        missing(
            &doc,
            markdown_targets(
                "[a](docs/usage.md#camera-paths) [b](docs/usage.md#no-such-section) \
                 [c](#license) [d](#no-such-section)"
            )
        ),
        vec![
            format!("{}: docs/usage.md#no-such-section", doc.display()),
            format!("{}: #no-such-section", doc.display()),
        ]
    );
    assert_eq!(
        anchors("# A `b`: c\n```\n# not a heading\n```\n## A b c\n### (x) y-z_w"),
        ["a-b-c", "a-b-c-1", "x-y-z_w"]
    );
    assert_eq!(
        missing(
            &doc,
            html_targets("<img src=\"nope.png\"><a href=\"https://x\">")
        )
        .len(),
        1
    );
}
