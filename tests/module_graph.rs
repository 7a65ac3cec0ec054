//! The library's top-level modules import each other without a circle: every `crate::x`
//! path in a module's non-test code is an arrow from that module to `x`, and the arrows
//! must order the modules (leaves such as `types` and `csc` at the bottom, the `solver`
//! facade and `ffi` at the top). Read from the source text, so no tool is needed.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Every `.rs` file under `dir`.
fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("src/ is readable") {
        let path = entry.expect("a directory entry").path();
        if path.is_dir() {
            sources(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The code of a file without its comments and without its test module (tests may reach
/// anywhere).
fn code(text: &str) -> String {
    let lines: Vec<&str> = text.lines().collect();
    let test_module = (1..lines.len()).find(|&k| {
        let next = lines[k].trim();
        lines[k - 1].trim() == "#[cfg(test)]" && next.starts_with("mod ") && next.ends_with('{')
    });
    lines[..test_module.map_or(lines.len(), |k| k - 1)]
        .iter()
        .map(|l| l.split("//").next().unwrap_or(""))
        .collect::<Vec<_>>()
        .join("\n")
}

/// The names that follow `crate::`, alone (`crate::csc::norm2`) or grouped
/// (`crate::{csc::norm2, types::Error}`).
fn crate_paths(code: &str) -> Vec<String> {
    let mut names = Vec::new();
    for (k, _) in code.match_indices("crate::") {
        let rest = &code[k + "crate::".len()..];
        let heads: Vec<&str> = match rest.strip_prefix('{') {
            Some(group) => group
                .split('}')
                .next()
                .unwrap_or("")
                .split(',')
                .map(str::trim)
                .collect(),
            None => vec![rest],
        };
        for head in heads {
            let name: String = head
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            if !name.is_empty() {
                names.push(name);
            }
        }
    }
    names
}

fn module_graph() -> BTreeMap<String, BTreeSet<String>> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    sources(&src, &mut files);
    let module_of = |p: &Path| {
        let rel = p.strip_prefix(&src).expect("under src/");
        let first = rel.components().next().expect("a path").as_os_str();
        first.to_string_lossy().trim_end_matches(".rs").to_string()
    };
    let modules: BTreeSet<String> = files.iter().map(|p| module_of(p)).collect();
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for file in &files {
        let from = module_of(file);
        if from == "lib" {
            continue;
        }
        let text = std::fs::read_to_string(file).expect("a readable source file");
        let arrows = graph.entry(from.clone()).or_default();
        // Names that are not modules (`crate::Error`, re-exported by the root) are skipped.
        for to in crate_paths(&code(&text)) {
            if to != from && modules.contains(&to) {
                arrows.insert(to);
            }
        }
    }
    graph
}

/// One circle of the graph, if there is any, as the modules along it.
fn find_circle(graph: &BTreeMap<String, BTreeSet<String>>) -> Option<Vec<String>> {
    fn visit(
        m: &str,
        graph: &BTreeMap<String, BTreeSet<String>>,
        path: &mut Vec<String>,
        done: &mut BTreeSet<String>,
    ) -> Option<Vec<String>> {
        if let Some(k) = path.iter().position(|p| p == m) {
            let mut circle = path[k..].to_vec();
            circle.push(m.to_string());
            return Some(circle);
        }
        if done.contains(m) {
            return None;
        }
        path.push(m.to_string());
        for next in graph.get(m).into_iter().flatten() {
            if let Some(c) = visit(next, graph, path, done) {
                return Some(c);
            }
        }
        path.pop();
        done.insert(m.to_string());
        None
    }
    let mut done = BTreeSet::new();
    graph
        .keys()
        .find_map(|m| visit(m, graph, &mut Vec::new(), &mut done))
}

#[test]
fn the_modules_import_each_other_without_a_circle() {
    let graph = module_graph();
    // The reader must see the arrows it is meant to see, or the check below is empty.
    assert!(graph["solver"].contains("types"), "{graph:?}");
    assert!(graph["ffi"].contains("solver"), "{graph:?}");
    if let Some(circle) = find_circle(&graph) {
        panic!("import circle: {}", circle.join(" -> "));
    }
}

#[test]
fn the_circle_finder_finds_a_circle() {
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    let arrow = |g: &mut BTreeMap<String, BTreeSet<String>>, a: &str, b: &str| {
        g.entry(a.into()).or_default().insert(b.into());
    };
    arrow(&mut graph, "solver", "types");
    arrow(&mut graph, "types", "csc");
    assert_eq!(find_circle(&graph), None);
    arrow(&mut graph, "csc", "solver");
    let circle = find_circle(&graph).expect("solver -> types -> csc -> solver");
    assert_eq!(circle.first(), circle.last());
    assert_eq!(circle.len(), 4);
}

#[test]
fn grouped_and_inline_paths_are_read() {
    let names = crate_paths("use crate::{csc::norm2, types::Error};\nlet x = crate::cone::f();");
    assert_eq!(names, ["csc", "types", "cone"]);
    let text =
        "use a; // crate::y\n#[cfg(test)]\nmod testing;\n#[cfg(test)]\nmod tests {\ncrate::x\n}";
    assert_eq!(code(text), "use a; \n#[cfg(test)]\nmod testing;");
}
