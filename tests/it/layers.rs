//! The library's layering, read from its own source: which top-level module of `src/` names
//! which (`crate::x` in code, not in comments or tests). The modules must form no cycle, and
//! the ground floor (the shared maths and vocabulary: `geometry`, `sampling`, `color`,
//! `error`, `choice`, `progress`, `distributed`) names no stage. ARCHITECTURE.md draws the
//! same floors.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// The ground floor, and what each of its modules may name (nothing above it).
const GROUND: &[(&str, &[&str])] = &[
    ("error", &[]),
    ("progress", &[]),
    ("distributed", &[]),
    ("geometry", &[]),
    ("sampling", &["geometry"]),
    ("color", &["error"]),
    ("choice", &["error"]),
];

/// The top-level module a file of `src/` belongs to (`gather` for `src/gather/direct.rs`,
/// `bake` for `src/bake.rs`), or `None` for the crate root and test-only files.
fn module_of(relative: &Path) -> Option<String> {
    let first = relative.components().next()?.as_os_str().to_str()?;
    let name = first.strip_suffix(".rs").unwrap_or(first);
    (name != "lib" && name != "test_support").then(|| name.to_string())
}

/// The code of a file as the library builds it: without its `#[cfg(test)] mod tests` (by
/// convention the last item of a file), without comment lines, and nothing for a file of
/// tests (`tests.rs`).
fn library_code(path: &Path) -> String {
    if path.file_name().is_some_and(|n| n == "tests.rs") {
        return String::new();
    }
    let text = std::fs::read_to_string(path).unwrap();
    let code = text.split("#[cfg(test)]\nmod tests").next().unwrap_or("");
    code.lines()
        .filter(|l| !l.trim_start().starts_with("//"))
        .collect::<Vec<_>>()
        .join("\n")
}

/// Every top-level module named after `crate::` in `code`, also in a group
/// (`crate::{io, scene::Scene}`).
fn named(code: &str) -> BTreeSet<String> {
    /// The module name a path starts with (lower case: `Error` is the root's re-export).
    fn first_segment(path: &str) -> Option<String> {
        let name: String = path
            .trim_start()
            .chars()
            .take_while(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || *c == '_')
            .collect();
        (!name.is_empty()).then_some(name)
    }
    let mut out = BTreeSet::new();
    for (i, _) in code.match_indices("crate::") {
        let before = code[..i].chars().next_back();
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_') {
            continue; // `radiosity_crate::`, not ours
        }
        let rest = &code[i + "crate::".len()..];
        let Some(group) = rest.strip_prefix('{') else {
            out.extend(first_segment(rest));
            continue;
        };
        // The group's top-level items, up to its closing brace.
        let (mut depth, mut start) = (0usize, 0usize);
        for (k, c) in group.char_indices() {
            match c {
                '{' => depth += 1,
                '}' if depth == 0 => {
                    out.extend(first_segment(&group[start..k]));
                    break;
                }
                '}' => depth -= 1,
                ',' if depth == 0 => {
                    out.extend(first_segment(&group[start..k]));
                    start = k + 1;
                }
                _ => {}
            }
        }
    }
    out
}

fn rust_files(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// Module → the other top-level modules its library code names.
fn imports() -> BTreeMap<String, BTreeSet<String>> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for path in files {
        let Some(module) = module_of(path.strip_prefix(&src).unwrap()) else {
            continue;
        };
        let names = named(&library_code(&path));
        let entry = graph.entry(module.clone()).or_default();
        entry.extend(names.into_iter().filter(|n| *n != module));
    }
    // Names that are not modules (`crate::Error`, re-exported at the root, is upper case and
    // never matched; anything else unknown is dropped here).
    let modules: BTreeSet<String> = graph.keys().cloned().collect();
    for targets in graph.values_mut() {
        targets.retain(|t| modules.contains(t));
    }
    graph
}

/// A cycle of the graph, if it has one (depth-first search).
fn cycle(graph: &BTreeMap<String, BTreeSet<String>>) -> Option<Vec<String>> {
    fn visit(
        node: &str,
        graph: &BTreeMap<String, BTreeSet<String>>,
        state: &mut BTreeMap<String, u8>,
        path: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        state.insert(node.to_string(), 1);
        path.push(node.to_string());
        for next in graph.get(node).into_iter().flatten() {
            match state.get(next.as_str()).copied().unwrap_or(0) {
                1 => {
                    let start = path.iter().position(|p| p == next).unwrap();
                    let mut c = path[start..].to_vec();
                    c.push(next.clone());
                    return Some(c);
                }
                0 => {
                    if let Some(c) = visit(next, graph, state, path) {
                        return Some(c);
                    }
                }
                _ => {}
            }
        }
        path.pop();
        state.insert(node.to_string(), 2);
        None
    }
    let mut state = BTreeMap::new();
    for node in graph.keys() {
        if state.get(node.as_str()).copied().unwrap_or(0) == 0 {
            if let Some(c) = visit(node, graph, &mut state, &mut Vec::new()) {
                return Some(c);
            }
        }
    }
    None
}

#[test]
fn the_reader_sees_the_imports_it_should() {
    // The checks below are only as good as this reader: it must find a real import and
    // leave out comments and the test module.
    let code = "use crate::scene::Scene;\nuse crate::{bake::{self, Site}, Error, mesh};\n\
                // crate::gather in a comment\nfn f() { crate::light::x(); }\n\
                #[cfg(test)]\nfn g() { crate::io::y(); }\n#[cfg(test)]\nmod tests { use crate::pipeline; }";
    let dir = std::env::temp_dir().join(format!("radiosity-layers-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("probe.rs");
    std::fs::write(&file, code).unwrap();
    let found = named(&library_code(&file));
    std::fs::remove_dir_all(&dir).ok();
    let expected = ["bake", "io", "light", "mesh", "scene"].map(String::from);
    assert_eq!(found, BTreeSet::from(expected));
    // And on the library itself: the pipeline names every stage it sequences.
    let graph = imports();
    for stage in [
        "scene",
        "mesh",
        "visibility",
        "form_factor",
        "solve",
        "bake",
        "io",
    ] {
        assert!(
            graph["pipeline"].contains(stage),
            "pipeline → {stage} not seen"
        );
    }
}

#[test]
fn modules_form_no_cycle() {
    let graph = imports();
    if let Some(c) = cycle(&graph) {
        panic!(
            "the modules import each other in a circle: {} (ARCHITECTURE.md: modules import \
             downwards only)",
            c.join(" → ")
        );
    }
}

#[test]
fn the_ground_floor_imports_no_stage() {
    let graph = imports();
    for &(module, allowed) in GROUND {
        let names = graph
            .get(module)
            .unwrap_or_else(|| panic!("no module {module}"));
        let above: Vec<&String> = names
            .iter()
            .filter(|n| !allowed.contains(&n.as_str()))
            .collect();
        assert!(
            above.is_empty(),
            "the ground floor's {module} names {above:?}: shared maths and vocabulary must not \
             depend on a stage"
        );
    }
}
