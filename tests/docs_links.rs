//! The committed documents and reports name only files that are committed: every
//! relative link and image of the README and `docs/**/*.md`, and every `src` and `href`
//! of the committed `report.html` files.

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

/// The targets that name a file of the repository and are missing.
fn missing(doc: &Path, targets: Vec<String>) -> Vec<String> {
    let dir = doc.parent().unwrap();
    targets
        .into_iter()
        .filter(|t| !t.contains("://") && !t.starts_with('#') && !t.starts_with("mailto:"))
        .filter_map(|t| {
            let path = t.split('#').next().unwrap_or_default().to_string();
            (!path.is_empty() && !dir.join(&path).exists())
                .then(|| format!("{}: {t}", doc.display()))
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
    assert_eq!(
        missing(
            &doc,
            html_targets("<img src=\"nope.png\"><a href=\"https://x\">")
        )
        .len(),
        1
    );
}
