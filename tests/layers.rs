//! The library's modules import only modules on their own layer or below, as
//! `docs/ARCHITECTURE.md` lays them out, and the modules of one layer do not import each
//! other in a circle. Read from the source text: every `crate::` path, including those
//! inside `use crate::{...}` trees, names the top-level module it reaches into.

use std::{
    collections::{BTreeMap, BTreeSet},
    path::{Path, PathBuf},
};

/// Layers from the bottom up; must match `docs/ARCHITECTURE.md`.
const LAYERS: &[&[&str]] = &[
    &[
        "image", "output", "limits", "settings", "sampling", "clock", "tiles", "gpu",
    ],
    &["scene"],
    &["trace"],
    &["render"],
    &["reconstruction"],
    &["methods"],
    &["evaluation", "bench", "realtime"],
];

fn layer_of(module: &str) -> Option<usize> {
    LAYERS.iter().position(|l| l.contains(&module))
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).expect("readable source folder") {
        let p = e.expect("directory entry").path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// Code without comments (line comments and doc comments), so that prose naming a
/// module is not read as an import.
fn strip_comments(text: &str) -> String {
    text.lines()
        .map(|l| match l.find("//") {
            Some(i) if !l[..i].contains('"') => &l[..i],
            _ => l,
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// The top-level modules a source text reaches through `crate::`.
fn imported_modules(text: &str) -> BTreeSet<String> {
    let code = strip_comments(text);
    let mut out = BTreeSet::new();
    let bytes = code.as_bytes();
    let ident = |i: usize| -> String {
        code[i..]
            .chars()
            .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
            .collect()
    };
    let mut from = 0;
    while let Some(k) = code[from..].find("crate::") {
        let at = from + k + "crate::".len();
        from = at;
        if bytes.get(at) == Some(&b'{') {
            // A use tree: the first segment of every item at brace depth 1.
            let mut depth = 0;
            let mut start_of_item = true;
            for (j, c) in code[at..].char_indices() {
                match c {
                    '{' => {
                        depth += 1;
                        start_of_item = depth == 1;
                    }
                    '}' => {
                        depth -= 1;
                        if depth == 0 {
                            break;
                        }
                    }
                    ',' if depth == 1 => start_of_item = true,
                    c if c.is_whitespace() => {}
                    _ if start_of_item && depth == 1 => {
                        let name = ident(at + j);
                        if !name.is_empty() {
                            out.insert(name);
                        }
                        start_of_item = false;
                    }
                    _ => {}
                }
            }
        } else {
            let name = ident(at);
            if !name.is_empty() {
                out.insert(name);
            }
        }
    }
    out
}

/// Each top-level library module and the top-level modules it imports.
fn module_graph() -> BTreeMap<String, BTreeSet<String>> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for f in files {
        let rel = f.strip_prefix(&src).expect("under src");
        let first = rel.components().next().expect("a path").as_os_str();
        let module = first.to_string_lossy().trim_end_matches(".rs").to_string();
        if matches!(module.as_str(), "lib" | "main" | "cli") {
            continue; // the crate root and the binary sit above every layer
        }
        let text = std::fs::read_to_string(&f).expect("readable source");
        let deps = imported_modules(&text);
        let entry = graph.entry(module.clone()).or_default();
        entry.extend(deps.into_iter().filter(|d| *d != module));
    }
    graph
}

#[test]
fn every_module_is_on_a_layer() {
    for m in module_graph().keys() {
        assert!(
            layer_of(m).is_some(),
            "module `{m}` is on no layer: add it to docs/ARCHITECTURE.md and LAYERS"
        );
    }
}

#[test]
fn imports_point_down() {
    let mut upward = Vec::new();
    for (m, deps) in module_graph() {
        let Some(lm) = layer_of(&m) else { continue };
        for d in deps {
            match layer_of(&d) {
                Some(ld) if ld > lm => upward.push(format!("{m} imports {d}")),
                _ => {}
            }
        }
    }
    assert!(upward.is_empty(), "imports that point up: {upward:?}");
}

#[test]
fn no_circles_between_modules() {
    let graph = module_graph();
    // Depth-first search for a back edge.
    fn visit(
        m: &str,
        graph: &BTreeMap<String, BTreeSet<String>>,
        state: &mut BTreeMap<String, u8>,
        path: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        match state.get(m) {
            Some(1) => {
                let i = path.iter().position(|p| p == m).unwrap_or(0);
                let mut cycle = path[i..].to_vec();
                cycle.push(m.to_string());
                return Some(cycle);
            }
            Some(2) => return None,
            _ => {}
        }
        state.insert(m.to_string(), 1);
        path.push(m.to_string());
        for d in graph.get(m).into_iter().flatten() {
            if let Some(c) = visit(d, graph, state, path) {
                return Some(c);
            }
        }
        path.pop();
        state.insert(m.to_string(), 2);
        None
    }
    let mut state = BTreeMap::new();
    for m in graph.keys() {
        if let Some(cycle) = visit(m, &graph, &mut state, &mut Vec::new()) {
            panic!("import circle: {}", cycle.join(" -> "));
        }
    }
}

#[test]
fn the_reader_sees_use_trees_and_ignores_comments() {
    let text = "use crate::{\n    image::Image,\n    scene::{self, Scene},\n};\n// crate::evaluation in a comment\nfn f() { crate::trace::x(); }";
    let got: Vec<String> = imported_modules(text).into_iter().collect();
    assert_eq!(got, ["image", "scene", "trace"]);
}
