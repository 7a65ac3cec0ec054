//! The library's modules and files import each other without a circle, and its functions
//! are short. Every `crate::x` path in a top-level module's non-test code is an arrow from
//! that module to `x`, and the arrows must order the modules (leaves such as `types` and
//! `csc` at the bottom, the `solver` facade and `ffi` at the top); the same holds between
//! the files of `src/`, an arrow going to the file that defines what a path names. No
//! function outside the test modules is over [`MAX_FUNCTION_LINES`] lines. Read from the
//! source text, so no tool is needed.

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
        let next = next
            .trim_start_matches("pub(crate) ")
            .trim_start_matches("pub ");
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

// The files of `src/`.

/// Files whose import circle a restructuring in progress takes apart, each with why: the
/// circles through them are not reported. An entry that no longer applies fails the test,
/// so that the list only shrinks.
const CIRCLES_BEING_RESTRUCTURED: &[(&str, &str)] = &[];

/// Files with a function over [`MAX_FUNCTION_LINES`] lines that a restructuring in progress
/// splits or removes, each with why. An entry that no longer applies fails the test.
const LONG_FUNCTIONS_BEING_RESTRUCTURED: &[(&str, &str)] = &[];

/// The longest a function outside the test modules may be, from its `fn` line to its
/// closing brace.
const MAX_FUNCTION_LINES: usize = 80;

/// A file's module path: `src/admm/engine.rs` is `admm::engine`, `src/admm/mod.rs` is
/// `admm`, `src/lib.rs` the crate root.
fn module_path(src: &Path, file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(src).expect("under src/");
    let mut path: Vec<String> = rel
        .components()
        .map(|c| {
            c.as_os_str()
                .to_string_lossy()
                .trim_end_matches(".rs")
                .to_string()
        })
        .collect();
    if matches!(path.last().map(String::as_str), Some("mod" | "lib")) {
        path.pop();
    }
    path
}

/// A name a `use` brings in: the path as written and the name it is known by (`*` for a
/// glob); a public one may only pass the name on.
#[derive(Debug, PartialEq)]
struct Import {
    path: Vec<String>,
    name: String,
    public: bool,
}

fn segments(path: &str) -> Vec<String> {
    path.split("::")
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(String::from)
        .collect()
}

/// The imports of a use tree such as `crate::{a::b as c, d::{self, e}}`, under `prefix`.
fn use_tree(prefix: &[String], tree: &str, public: bool, out: &mut Vec<Import>) {
    let tree = tree.trim();
    if tree.is_empty() {
        return;
    }
    let Some(open) = tree.find('{') else {
        let (written, alias) = match tree.split_once(" as ") {
            Some((p, a)) => (p, Some(a.trim().to_string())),
            None => (tree, None),
        };
        let mut path = prefix.to_vec();
        path.extend(segments(written));
        if path.last().is_some_and(|s| s == "self") {
            path.pop();
        }
        if let Some(last) = path.last() {
            let name = alias.unwrap_or_else(|| last.clone());
            out.push(Import { path, name, public });
        }
        return;
    };
    let mut inner_prefix = prefix.to_vec();
    inner_prefix.extend(segments(&tree[..open]));
    let inner = &tree[open + 1..tree.rfind('}').expect("a closed use group")];
    let (mut depth, mut start) = (0, 0);
    for (k, c) in inner.char_indices() {
        match c {
            '{' => depth += 1,
            '}' => depth -= 1,
            ',' if depth == 0 => {
                use_tree(&inner_prefix, &inner[start..k], public, out);
                start = k + 1;
            }
            _ => {}
        }
    }
    use_tree(&inner_prefix, &inner[start..], public, out);
}

/// The `use` statements of a file's code, read, and the rest of the code.
fn split_uses(code: &str) -> (Vec<Import>, String) {
    let (mut imports, mut rest) = (Vec::new(), String::new());
    let mut statement: Option<(bool, String)> = None;
    for line in code.lines() {
        if statement.is_none() {
            let t = line.trim_start();
            let public = t.starts_with("pub");
            let after_pub = match t.strip_prefix("pub") {
                Some(p) if p.starts_with('(') => p.split_once(") ").map_or("", |(_, r)| r),
                Some(p) => p.trim_start(),
                None => t,
            };
            match after_pub.strip_prefix("use ") {
                Some(tree) => statement = Some((public, tree.to_string())),
                None => {
                    rest.push_str(line);
                    rest.push('\n');
                    continue;
                }
            }
        } else if let Some((_, text)) = &mut statement {
            text.push_str(line);
        }
        if let Some((public, text)) = statement.take_if(|(_, text)| text.contains(';')) {
            let tree = text.split(';').next().unwrap_or("");
            use_tree(&[], tree, public, &mut imports);
        }
    }
    (imports, rest)
}

/// The paths of more than one segment written in code (`crate::a::f`, `super::B`,
/// `engine::run`), as segments.
fn inline_paths(code: &str) -> Vec<Vec<String>> {
    let is_ident = |c: char| c.is_alphanumeric() || c == '_';
    let chars: Vec<char> = code.chars().collect();
    let mut paths = Vec::new();
    let mut k = 0;
    while k < chars.len() {
        let starts =
            is_ident(chars[k]) && (k == 0 || !(is_ident(chars[k - 1]) || chars[k - 1] == ':'));
        if !starts {
            k += 1;
            continue;
        }
        let mut path = Vec::new();
        loop {
            let start = k;
            while k < chars.len() && is_ident(chars[k]) {
                k += 1;
            }
            path.push(chars[start..k].iter().collect::<String>());
            let more = chars.get(k) == Some(&':')
                && chars.get(k + 1) == Some(&':')
                && chars.get(k + 2).is_some_and(|&c| is_ident(c));
            if !more {
                break;
            }
            k += 2;
        }
        if path.len() > 1 {
            paths.push(path);
        }
    }
    paths
}

/// Whether `word` appears in `code` as a whole word.
fn uses_word(code: &str, word: &str) -> bool {
    let is_ident = |c: char| c.is_alphanumeric() || c == '_';
    code.match_indices(word).any(|(k, _)| {
        let before = code[..k].chars().next_back();
        let after = code[k + word.len()..].chars().next();
        !before.is_some_and(is_ident) && !after.is_some_and(is_ident)
    })
}

/// A file of `src/` as the checks read it.
struct SourceFile {
    /// Relative to the crate: `src/admm/engine.rs`.
    name: String,
    module: Vec<String>,
    imports: Vec<Import>,
    /// The non-test code without comments and `use` statements.
    body: String,
    /// The non-test code without comments, line for line.
    code: String,
}

/// The files of `src/` but those only compiled for tests (`#[cfg(test)] mod x;`).
struct Crate {
    files: Vec<SourceFile>,
    by_module: BTreeMap<Vec<String>, usize>,
}

impl Crate {
    fn read() -> Self {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let src = root.join("src");
        let mut paths = Vec::new();
        sources(&src, &mut paths);
        paths.sort();
        let mut files: Vec<SourceFile> = paths
            .iter()
            .map(|p| {
                let code = code(&std::fs::read_to_string(p).expect("a readable source file"));
                let (imports, body) = split_uses(&code);
                let name = p.strip_prefix(root).expect("in the crate");
                SourceFile {
                    name: name.to_string_lossy().replace('\\', "/"),
                    module: module_path(&src, p),
                    imports,
                    body,
                    code,
                }
            })
            .collect();
        let test_only: BTreeSet<Vec<String>> = files
            .iter()
            .flat_map(|f| {
                let lines: Vec<&str> = f.code.lines().map(str::trim).collect();
                let children = lines.windows(2).filter_map(|w| {
                    let name = w[1].strip_prefix("mod ")?.strip_suffix(';')?;
                    (w[0] == "#[cfg(test)]").then(|| [f.module.clone(), vec![name.into()]].concat())
                });
                children.collect::<Vec<_>>()
            })
            .collect();
        files.retain(|f| !test_only.contains(&f.module));
        let by_module = files
            .iter()
            .enumerate()
            .map(|(k, f)| (f.module.clone(), k))
            .collect();
        Self { files, by_module }
    }

    /// The absolute module path of a path written in file `f`; `None` outside the crate.
    fn absolute(&self, f: usize, path: &[String], depth: usize) -> Option<Vec<String>> {
        let file = &self.files[f];
        let (first, mut rest) = path.split_first()?;
        let mut base = match first.as_str() {
            "crate" => Vec::new(),
            "self" => file.module.clone(),
            "super" => file.module[..file.module.len().saturating_sub(1)].to_vec(),
            _ => {
                let child = [file.module.clone(), vec![first.clone()]].concat();
                if self.by_module.contains_key(&child) {
                    child
                } else {
                    let import = file.imports.iter().find(|i| &i.name == first)?;
                    // A crate imported by its name alone (`use mpi;`) stands for itself.
                    if depth > 8 || import.path == [first.clone()] {
                        return None;
                    }
                    self.absolute(f, &import.path, depth + 1)?
                }
            }
        };
        while rest.first().is_some_and(|s| s == "super") {
            base.pop();
            rest = &rest[1..];
        }
        base.extend(rest.iter().cloned());
        Some(base)
    }

    /// The file that defines what an absolute path names, following the imports of the
    /// module the path ends in (a `pub use` passes a name on without an arrow of its own).
    fn defining_file(&self, path: &[String], depth: usize) -> Option<usize> {
        let k = (0..=path.len())
            .rev()
            .find(|&k| self.by_module.contains_key(&path[..k]))?;
        let module = self.by_module[&path[..k]];
        let Some(item) = path.get(k) else {
            return Some(module);
        };
        match self.files[module].imports.iter().find(|i| &i.name == item) {
            Some(import) if depth < 8 => {
                let mut next = self.absolute(module, &import.path, depth + 1)?;
                next.extend(path[k + 1..].iter().cloned());
                self.defining_file(&next, depth + 1)
            }
            _ => Some(module),
        }
    }

    /// Each file's arrows to the files whose code it uses.
    fn graph(&self) -> BTreeMap<String, BTreeSet<String>> {
        let mut graph = BTreeMap::new();
        for (f, file) in self.files.iter().enumerate() {
            // A private import is used (unused ones do not compile); a public one only
            // passes a name on unless the file's own code uses it.
            let imported = file
                .imports
                .iter()
                .filter(|i| !i.public || (i.name != "*" && uses_word(&file.body, &i.name)))
                .map(|i| i.path.clone());
            let targets: BTreeSet<String> = imported
                .chain(inline_paths(&file.body))
                .filter_map(|p| self.defining_file(&self.absolute(f, &p, 0)?, 0))
                .filter(|&t| t != f)
                .map(|t| self.files[t].name.clone())
                .collect();
            graph.insert(file.name.clone(), targets);
        }
        graph
    }
}

/// The groups of nodes that reach each other: each holds one circle or more.
fn circles(graph: &BTreeMap<String, BTreeSet<String>>) -> Vec<BTreeSet<String>> {
    let reach = |from: &String| {
        let (mut seen, mut todo) = (BTreeSet::new(), vec![from.clone()]);
        while let Some(node) = todo.pop() {
            for next in graph.get(&node).into_iter().flatten() {
                if seen.insert(next.clone()) {
                    todo.push(next.clone());
                }
            }
        }
        seen
    };
    let reaches: BTreeMap<&String, BTreeSet<String>> =
        graph.keys().map(|n| (n, reach(n))).collect();
    let mut groups: Vec<BTreeSet<String>> = Vec::new();
    for (node, reached) in &reaches {
        if !reached.contains(*node) || groups.iter().any(|g| g.contains(*node)) {
            continue;
        }
        let group = reached
            .iter()
            .filter(|other| reaches.get(other).is_some_and(|r| r.contains(*node)))
            .cloned()
            .collect();
        groups.push(group);
    }
    groups
}

/// The functions of a file's non-test code (`code`, line for line) over
/// [`MAX_FUNCTION_LINES`] lines: name, first line (1-based) and length.
fn long_functions(code: &str) -> Vec<(String, usize, usize)> {
    let lines: Vec<&str> = code.lines().collect();
    let indent = |l: &str| l.len() - l.trim_start().len();
    let mut long = Vec::new();
    for (k, line) in lines.iter().enumerate() {
        let Some(name) = fn_name(line) else { continue };
        // The signature ends on the first line that ends in `{` (a body follows), `;` (a
        // declaration) or `}` (a body on one line).
        let end = (k..lines.len()).find(|&j| lines[j].trim_end().ends_with(['{', ';', '}']));
        let Some(open) = end.filter(|&j| lines[j].trim_end().ends_with('{')) else {
            continue;
        };
        let close = (open + 1..lines.len())
            .find(|&j| indent(lines[j]) == indent(line) && lines[j].trim_start().starts_with('}'));
        let length = close.map_or(lines.len(), |c| c + 1) - k;
        if length > MAX_FUNCTION_LINES {
            long.push((name, k + 1, length));
        }
    }
    long
}

/// The name of the function a line opens (`pub(crate) unsafe extern "C" fn name(`).
fn fn_name(line: &str) -> Option<String> {
    let mut rest = line.trim_start();
    loop {
        let qualified = [
            "pub ",
            "const ",
            "async ",
            "unsafe ",
            "extern \"C\" ",
            "default ",
        ]
        .iter()
        .find_map(|q| rest.strip_prefix(q));
        let restricted = rest
            .strip_prefix("pub(")
            .and_then(|r| r.split_once(") "))
            .map(|(_, r)| r);
        match qualified.or(restricted) {
            Some(r) => rest = r,
            None => break,
        }
    }
    let name: String = rest
        .strip_prefix("fn ")?
        .chars()
        .take_while(|c| c.is_alphanumeric() || *c == '_')
        .collect();
    (!name.is_empty()).then_some(name)
}

/// Fails on the exceptions of `list` that `applies` no longer finds.
fn assert_still_needed(list: &[(&str, &str)], what: &str, applies: impl Fn(&str) -> bool) {
    let stale: Vec<&str> = list
        .iter()
        .map(|(file, _)| *file)
        .filter(|file| !applies(file))
        .collect();
    assert!(
        stale.is_empty(),
        "no {what} left in {stale:?}: remove them from the list"
    );
}

#[test]
fn the_files_import_each_other_without_a_circle() {
    let graph = Crate::read().graph();
    // The reader must see the arrows it is meant to see, or the check below is empty:
    // through a group import, a re-export of a directory module, and `super`.
    assert!(
        graph["src/solver.rs"].contains("src/types/error.rs"),
        "{graph:?}"
    );
    assert!(
        graph["src/coupled.rs"].contains("src/admm/engine.rs"),
        "{graph:?}"
    );
    assert!(
        graph["src/admm/engine.rs"].contains("src/admm/mod.rs"),
        "{graph:?}"
    );
    let excepted = |file: &str| CIRCLES_BEING_RESTRUCTURED.iter().any(|(f, _)| *f == file);
    let checked: BTreeMap<String, BTreeSet<String>> = graph
        .iter()
        .filter(|(file, _)| !excepted(file))
        .map(|(file, to)| {
            (
                file.clone(),
                to.iter().filter(|t| !excepted(t)).cloned().collect(),
            )
        })
        .collect();
    let reported: Vec<String> = circles(&checked)
        .iter()
        .map(|group| {
            let arrows = group.iter().flat_map(|a| {
                let inside = checked[a].iter().filter(|b| group.contains(*b));
                inside.map(move |b| format!("  {a} -> {b}"))
            });
            arrows.collect::<Vec<_>>().join("\n")
        })
        .collect();
    assert!(
        reported.is_empty(),
        "import circles:\n{}",
        reported.join("\n\n")
    );
    let groups = circles(&graph);
    let in_a_circle = |file: &str| groups.iter().any(|g| g.contains(file));
    assert_still_needed(CIRCLES_BEING_RESTRUCTURED, "circle", in_a_circle);
}

#[test]
fn no_function_is_over_80_lines() {
    let krate = Crate::read();
    let long_in = |file: &SourceFile| long_functions(&file.code);
    let excepted = |file: &str| {
        LONG_FUNCTIONS_BEING_RESTRUCTURED
            .iter()
            .any(|(f, _)| *f == file)
    };
    let reported: Vec<String> = krate
        .files
        .iter()
        .filter(|f| !excepted(&f.name))
        .flat_map(|f| {
            let long = long_in(f).into_iter();
            long.map(|(name, line, n)| format!("  {}:{line} fn {name}: {n} lines", f.name))
        })
        .collect();
    assert!(
        reported.is_empty(),
        "functions over {MAX_FUNCTION_LINES} lines:\n{}",
        reported.join("\n")
    );
    let has_long = |name: &str| {
        krate
            .files
            .iter()
            .any(|f| f.name == name && !long_in(f).is_empty())
    };
    assert_still_needed(LONG_FUNCTIONS_BEING_RESTRUCTURED, "long function", has_long);
}

#[test]
fn group_imports_and_re_exports_are_followed() {
    let mut imports = Vec::new();
    use_tree(&[], "crate::{a::b as c, d::{self, e}}", false, &mut imports);
    let read: Vec<(String, &str)> = imports
        .iter()
        .map(|i| (i.path.join("::"), i.name.as_str()))
        .collect();
    assert_eq!(
        read,
        [
            ("crate::a::b".to_string(), "c"),
            ("crate::d".to_string(), "d"),
            ("crate::d::e".to_string(), "e"),
        ]
    );
    let code = "pub use engine::{\n    run, State,\n};\nfn f() { super::g(crate::x::Y::new()) }\n";
    let (imports, body) = split_uses(code);
    assert_eq!(imports.len(), 2);
    assert!(imports[0].public);
    assert_eq!(body, "fn f() { super::g(crate::x::Y::new()) }\n");
    let paths: Vec<String> = inline_paths(&body).iter().map(|p| p.join("::")).collect();
    assert_eq!(paths, ["super::g", "crate::x::Y::new"]);
}

#[test]
fn long_functions_are_counted_to_their_closing_brace() {
    let body = |n: usize| "    let x = 1;\n".repeat(n);
    let code = format!(
        "pub(crate) fn short() {{\n{}}}\nfn declared();\nfn one() {{ 1 }}\nimpl A {{\n    pub fn long(\n        a: u8,\n    ) {{\n{}    }}\n}}\n",
        body(78),
        "    ".to_string() + &body(80)
    );
    assert_eq!(long_functions(&code), [("long".to_string(), 84, 84)]);
    let groups = circles(&BTreeMap::from([
        ("a".to_string(), BTreeSet::from(["b".to_string()])),
        (
            "b".to_string(),
            BTreeSet::from(["a".to_string(), "c".to_string()]),
        ),
        ("c".to_string(), BTreeSet::new()),
    ]));
    assert_eq!(groups, [BTreeSet::from(["a".to_string(), "b".to_string()])]);
}
