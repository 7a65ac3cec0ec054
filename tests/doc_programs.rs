//! Every complete program of the README and of the documentation book (`docs/`) is compiled
//! and run, and every relative link of those pages leads somewhere.
//!
//! The convention the pages follow:
//! - a ```` ```c ```` block containing `int main` is a complete C program: compiled with
//!   `-std=c11 -Wall -Wextra -Werror` against `include/` and linked with a private copy of
//!   the cadmm shared library this test run built (as `tests/c_programs.rs` does);
//! - a ```` ```rust ```` block containing `fn main` is a complete Rust program: compiled by
//!   rustc with `-D warnings` against the `cadmm` rlib this test run built;
//! - every other `c`, `cpp` or `rust` block is a fragment and says so on its first line
//!   (a comment starting with `fragment`);
//! - a program block followed by a paragraph that ends in `prints:` and a ```` ```text ````
//!   block states its output: every non-empty line of that block must appear in what the
//!   program prints.
//!
//! Programs run in the project root and must exit with 0; they find the FCLib problems at
//! `../shared/data/fclib`. A program that uses FCLib files is skipped, with a note, in a
//! test run without the `fclib` feature.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::Command;

fn manifest_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// `target/<profile>`: this test executable lives in `target/<profile>/deps/`.
fn profile_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("path of the test executable");
    let deps = exe.parent().expect("the test executable has a directory");
    if deps.file_name().is_some_and(|n| n == "deps") {
        deps.parent().expect("deps/ has a parent").to_path_buf()
    } else {
        deps.to_path_buf()
    }
}

/// The pages: the README and every Markdown file of the book's directory.
fn pages() -> Vec<PathBuf> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)
            .unwrap_or_else(|e| panic!("doc_programs: cannot read {}: {e}", dir.display()))
            .map(|e| e.expect("a directory entry").path())
            .collect();
        entries.sort();
        for path in entries {
            if path.is_dir() {
                walk(&path, out);
            } else if path.extension().is_some_and(|e| e == "md") {
                out.push(path);
            }
        }
    }
    let root = manifest_dir();
    let mut out = vec![root.join("README.md")];
    walk(&root.join("docs"), &mut out);
    out
}

/// A fenced code block of a page.
struct Block {
    page: PathBuf,
    /// 1-based line of the opening fence.
    line: usize,
    /// The first word of the info string (`c`, `rust`, `text`...).
    lang: String,
    code: String,
    /// The prose between the previous block's closing fence and this block's opening one.
    before: String,
}

impl Block {
    fn place(&self) -> String {
        let root = manifest_dir();
        let page = self.page.strip_prefix(&root).unwrap_or(&self.page);
        format!("{}:{}", page.display(), self.line)
    }

    fn is_program(&self) -> bool {
        match self.lang.as_str() {
            "c" | "cpp" => self.code.contains("int main"),
            "rust" => self.code.contains("fn main"),
            _ => false,
        }
    }

    fn is_marked_fragment(&self) -> bool {
        let first = self.code.lines().next().unwrap_or("").trim_start();
        let comment = first
            .strip_prefix("//")
            .or_else(|| first.strip_prefix("/*"))
            .or_else(|| first.strip_prefix('#'));
        comment.is_some_and(|c| c.trim_start().starts_with("fragment"))
    }
}

/// The fenced blocks of a page (``` fences, possibly indented inside a list item).
fn blocks(page: &Path) -> Vec<Block> {
    let text = std::fs::read_to_string(page)
        .unwrap_or_else(|e| panic!("doc_programs: cannot read {}: {e}", page.display()));
    let mut out = Vec::new();
    let mut open: Option<(usize, usize, String, String)> = None; // line, indent, lang, prose
    let mut code = String::new();
    let mut prose = String::new();
    for (k, line) in text.lines().enumerate() {
        let trimmed = line.trim_start();
        let indent = line.len() - trimmed.len();
        match (&open, trimmed.strip_prefix("```")) {
            (None, Some(info)) => {
                let lang = info.split([',', ' ']).next().unwrap_or("").to_string();
                open = Some((k + 1, indent, lang, std::mem::take(&mut prose)));
                code.clear();
            }
            (Some(_), Some(rest)) if rest.trim().is_empty() => {
                let (line, _, lang, before) = open.take().expect("a block is open");
                out.push(Block {
                    page: page.to_path_buf(),
                    line,
                    lang,
                    code: std::mem::take(&mut code),
                    before,
                });
            }
            (Some((_, fence_indent, _, _)), _) => {
                code.push_str(line.get(*fence_indent.min(&indent)..).unwrap_or(""));
                code.push('\n');
            }
            (None, None) => {
                prose.push_str(line);
                prose.push('\n');
            }
        }
    }
    assert!(
        open.is_none(),
        "doc_programs: {}: an unclosed ``` block",
        page.display()
    );
    out
}

/// The output a page states for the program `blocks[k]`, if any.
fn stated_output(blocks: &[Block], k: usize) -> Option<Vec<String>> {
    let next = blocks.get(k + 1)?;
    let says_prints = next.before.trim_end().to_lowercase().ends_with("prints:");
    (next.lang == "text" && says_prints).then(|| {
        next.code
            .lines()
            .map(str::trim)
            .filter(|l| !l.is_empty())
            .map(String::from)
            .collect()
    })
}

/// A program found in the pages, with the output its page states.
struct Program {
    place: String,
    lang: String,
    code: String,
    expected: Vec<String>,
}

/// Every complete program of the pages; fails on a `c`/`cpp`/`rust` block that is neither a
/// program nor marked as a fragment, and on a C++ program (nothing compiles those).
fn programs() -> Vec<Program> {
    let mut out = Vec::new();
    let mut unmarked = Vec::new();
    for page in pages() {
        let blocks = blocks(&page);
        for (k, b) in blocks.iter().enumerate() {
            if !matches!(b.lang.as_str(), "c" | "cpp" | "rust") {
                continue;
            }
            if b.is_program() && b.lang != "cpp" {
                out.push(Program {
                    place: b.place(),
                    lang: b.lang.clone(),
                    code: b.code.clone(),
                    expected: stated_output(&blocks, k).unwrap_or_default(),
                });
            } else if !b.is_marked_fragment() {
                unmarked.push(b.place());
            }
        }
    }
    assert!(
        unmarked.is_empty(),
        "doc_programs: these c/cpp/rust blocks are neither complete programs (`int main`, \
         `fn main`; C++ is never compiled) nor marked as fragments (a first-line comment \
         starting with `fragment`): {unmarked:?}"
    );
    out
}

/// True when a program needs FCLib files, which only a build with `fclib` reads.
fn needs_fclib(code: &str) -> bool {
    code.contains("fclib::") || code.contains("_fclib(")
}

/// A name for a program's files: its page and line.
fn file_stem(place: &str) -> String {
    place
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect()
}

/// Runs a built program in the project root; returns an error message or its output.
fn run(place: &str, exe: &Path, expected: &[String]) -> Result<(), String> {
    // cargo's LD_LIBRARY_PATH can name a stale copy of the library and would override the
    // executable's runpath.
    let output = Command::new(exe)
        .env_remove("LD_LIBRARY_PATH")
        .current_dir(manifest_dir())
        .output()
        .map_err(|e| format!("{place}: cannot run {}: {e}", exe.display()))?;
    let stdout = String::from_utf8_lossy(&output.stdout);
    let stderr = String::from_utf8_lossy(&output.stderr);
    println!("{place}:\n{stdout}");
    if !output.status.success() {
        return Err(format!(
            "{place}: the program failed ({})\n--- stdout\n{stdout}\n--- stderr\n{stderr}",
            output.status
        ));
    }
    let missing: Vec<&String> = expected
        .iter()
        .filter(|l| !stdout.contains(l.as_str()))
        .collect();
    if !missing.is_empty() {
        return Err(format!(
            "{place}: the page says it prints {missing:?}, it printed:\n{stdout}"
        ));
    }
    Ok(())
}

/// Runs every program of one language with `build`, collecting all failures.
fn check_all(lang: &str, build: impl Fn(&Program, &Path) -> Result<PathBuf, String>) {
    let out_dir = profile_dir().join("doc_programs");
    std::fs::create_dir_all(&out_dir).expect("create the output directory");
    let mut failures = Vec::new();
    let mut ran = 0;
    for p in programs().iter().filter(|p| p.lang == lang) {
        if needs_fclib(&p.code) && !cfg!(feature = "fclib") {
            println!(
                "{}: skipped, it reads FCLib files (feature fclib is off)",
                p.place
            );
            continue;
        }
        match build(p, &out_dir).and_then(|exe| run(&p.place, &exe, &p.expected)) {
            Ok(()) => ran += 1,
            Err(e) => failures.push(e),
        }
    }
    assert!(
        failures.is_empty(),
        "doc_programs:\n{}",
        failures.join("\n\n")
    );
    println!("{ran} {lang} programs compiled and ran");
}

/// The cadmm shared library built for this run, copied into `out_dir` (another cargo
/// command could replace the shared one meanwhile). Returns the directory of the copy.
fn library_copy(out_dir: &Path) -> PathBuf {
    let name = format!(
        "{}cadmm{}",
        std::env::consts::DLL_PREFIX,
        std::env::consts::DLL_SUFFIX
    );
    let profile = profile_dir();
    let lib = [profile.join("deps").join(&name), profile.join(&name)]
        .into_iter()
        .find(|p| p.is_file())
        .unwrap_or_else(|| panic!("doc_programs: {name} not found in {}", profile.display()));
    let bytes = std::fs::read(&lib).expect("read the shared library");
    let has_fclib = bytes.windows(8).any(|w| w == b"H5Fopen\0");
    assert_eq!(
        has_fclib,
        cfg!(feature = "fclib"),
        "doc_programs: {} was built with other features than this test run (another cargo \
         build replaced it); rerun the tests",
        lib.display()
    );
    let dir = out_dir.join("lib");
    std::fs::create_dir_all(&dir).expect("create the library copy directory");
    std::fs::copy(&lib, dir.join(&name)).expect("copy the shared library");
    dir
}

/// Compiles a C program against `include/` and the library copy in `lib_dir`.
fn build_c(p: &Program, out_dir: &Path, lib_dir: &Path) -> Result<PathBuf, String> {
    let stem = file_stem(&p.place);
    let src = out_dir.join(format!("{stem}.c"));
    let exe = out_dir.join(&stem);
    std::fs::write(&src, &p.code).map_err(|e| format!("{}: {e}", p.place))?;
    let compiler = cc::Build::new()
        .cargo_metadata(false)
        .cargo_warnings(false)
        .opt_level(1)
        .target(&host_triple())
        .host(&host_triple())
        .try_get_compiler()
        .map_err(|e| format!("no C compiler: {e}"))?;
    let mut cmd = compiler.to_command();
    cmd.args(["-std=c11", "-Wall", "-Wextra", "-Werror"])
        .arg(format!("-I{}", manifest_dir().join("include").display()))
        .arg(&src)
        .arg("-o")
        .arg(&exe)
        .arg(format!("-L{}", lib_dir.display()))
        .arg("-lcadmm")
        .arg(format!("-Wl,-rpath,{}", lib_dir.display()))
        .arg("-lm");
    compile(&p.place, cmd).map(|()| exe)
}

/// Runs a compiler; its output is the error when it fails.
fn compile(place: &str, mut cmd: Command) -> Result<(), String> {
    let output = cmd
        .output()
        .map_err(|e| format!("{place}: cannot run {cmd:?}: {e}"))?;
    if output.status.success() {
        return Ok(());
    }
    Err(format!(
        "{place}: does not compile\ncommand: {cmd:?}\n{}{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    ))
}

/// The target triple of this (host) build, which `cc` needs outside a build script.
fn host_triple() -> String {
    let arch = std::env::consts::ARCH;
    if cfg!(all(target_os = "linux", target_env = "gnu")) {
        format!("{arch}-unknown-linux-gnu")
    } else if cfg!(target_os = "macos") {
        format!("{arch}-apple-darwin")
    } else {
        format!("{arch}-unknown-{}", std::env::consts::OS)
    }
}

/// The rustc of the toolchain that runs this test: the one beside `$CARGO`, so that it
/// reads the rlibs cargo built.
fn rustc() -> PathBuf {
    std::env::var_os("CARGO")
        .map(PathBuf::from)
        .and_then(|cargo| Some(cargo.parent()?.join("rustc")))
        .filter(|p| p.is_file())
        .unwrap_or_else(|| PathBuf::from("rustc"))
}

/// The native library directories the build scripts of this profile named (HDF5, MPI):
/// the rlibs name their libraries, the final link needs to find them.
fn native_dirs() -> BTreeSet<PathBuf> {
    let mut dirs = BTreeSet::new();
    let Ok(builds) = std::fs::read_dir(profile_dir().join("build")) else {
        return dirs;
    };
    for build in builds.flatten() {
        let Ok(text) = std::fs::read_to_string(build.path().join("output")) else {
            continue;
        };
        for line in text.lines() {
            let Some(value) = line.split_once("rustc-link-search=").map(|(_, v)| v) else {
                continue;
            };
            let path = PathBuf::from(value.split_once('=').map_or(value, |(_, p)| p));
            if path.is_dir() {
                dirs.insert(path);
            }
        }
    }
    dirs
}

/// Compiles a Rust program against the cadmm rlib of this profile and its dependencies.
fn build_rust(p: &Program, out_dir: &Path) -> Result<PathBuf, String> {
    let deps = profile_dir().join("deps");
    let rlib = deps.join("libcadmm.rlib");
    if !rlib.is_file() {
        return Err(format!("the cadmm rlib is missing: {}", rlib.display()));
    }
    let stem = file_stem(&p.place);
    let src = out_dir.join(format!("{stem}.rs"));
    let exe = out_dir.join(&stem);
    std::fs::write(&src, &p.code).map_err(|e| format!("{}: {e}", p.place))?;
    let mut cmd = Command::new(rustc());
    cmd.args(["--edition", "2021", "--crate-type", "bin", "-D", "warnings"])
        .args(["-C", "opt-level=1", "--crate-name", "doc_program"])
        .arg("--extern")
        .arg(format!("cadmm={}", rlib.display()))
        .arg(format!("-Ldependency={}", deps.display()));
    for dir in native_dirs() {
        cmd.arg(format!("-Lnative={}", dir.display()))
            .arg(format!("-Clink-arg=-Wl,-rpath,{}", dir.display()));
    }
    cmd.arg(&src).arg("-o").arg(&exe);
    compile(&p.place, cmd).map(|()| exe)
}

#[test]
fn c_programs_compile_and_run() {
    let out_dir = profile_dir().join("doc_programs");
    std::fs::create_dir_all(&out_dir).expect("create the output directory");
    let lib_dir = library_copy(&out_dir);
    check_all("c", |p, out| build_c(p, out, &lib_dir));
}

#[test]
fn rust_programs_compile_and_run() {
    check_all("rust", build_rust);
}

/// The README shows one complete program in each language, and says what it prints.
#[test]
fn the_readme_has_a_program_in_each_language() {
    let readme = manifest_dir().join("README.md");
    let blocks = blocks(&readme);
    for lang in ["c", "rust"] {
        let k = blocks
            .iter()
            .position(|b| b.lang == lang && b.is_program())
            .unwrap_or_else(|| panic!("README.md has no complete {lang} program"));
        assert!(
            stated_output(&blocks, k).is_some_and(|o| !o.is_empty()),
            "README.md: the {lang} program's output is not stated (`prints:` and a text block)"
        );
    }
}

/// The book's chapters, as `docs/SUMMARY.md` lists them (paths relative to `docs/`).
fn chapters() -> BTreeSet<PathBuf> {
    let summary = std::fs::read_to_string(manifest_dir().join("docs/SUMMARY.md"))
        .expect("docs/SUMMARY.md is readable");
    markdown_links(&summary)
        .into_iter()
        .map(|(target, _)| PathBuf::from(target))
        .collect()
}

/// The relative link targets of a page outside code: `[text](target)` and
/// `![alt](target)`, as (path, anchor).
fn markdown_links(text: &str) -> Vec<(String, Option<String>)> {
    let mut out = Vec::new();
    let mut in_code = false;
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            in_code = !in_code;
            continue;
        }
        if in_code {
            continue;
        }
        // Inline code spans hold no links.
        let prose: String = line.split('`').step_by(2).collect::<Vec<_>>().join(" ");
        for (k, _) in prose.match_indices("](") {
            let rest = &prose[k + 2..];
            let Some(end) = rest.find(')') else { continue };
            let target = rest[..end].split_whitespace().next().unwrap_or("");
            if target.contains("://") || target.starts_with("mailto:") {
                continue;
            }
            let (path, anchor) = match target.split_once('#') {
                Some((p, a)) => (p.to_string(), Some(a.to_string())),
                None => (target.to_string(), None),
            };
            out.push((path, anchor));
        }
    }
    out
}

/// The anchors a page defines: `id="..."` attributes and its headings' ids as mdBook
/// makes them (lower case, spaces to `-`, other punctuation dropped).
fn anchors(text: &str) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    for (k, _) in text.match_indices("id=\"") {
        let rest = &text[k + 4..];
        if let Some(end) = rest.find('"') {
            out.insert(rest[..end].to_string());
        }
    }
    for line in text.lines() {
        let Some(title) = line.strip_prefix('#').map(|t| t.trim_start_matches('#')) else {
            continue;
        };
        let id: String = title
            .trim()
            .chars()
            .filter_map(|c| match c {
                c if c.is_alphanumeric() || c == '_' || c == '-' => Some(c.to_ascii_lowercase()),
                c if c.is_whitespace() => Some('-'),
                _ => None,
            })
            .collect();
        out.insert(id);
    }
    out
}

/// Every relative link of the README and the book leads to an existing file, a link from
/// a book page to another page leads to a chapter of the book (mdBook renders nothing
/// else), and an anchor names a heading or an `id` of its page. mdBook 0.4 does not check
/// links itself.
#[test]
fn links_resolve() {
    let root = manifest_dir();
    let docs = root.join("docs");
    let chapters = chapters();
    let mut broken = Vec::new();
    // The changelog is included into the book (docs/changelog.md): its links are read
    // from docs/.
    let changelog = (root.join("CHANGELOG.md"), docs.clone());
    let others = pages().into_iter().map(|p| {
        let dir = p.parent().expect("a page has a directory").to_path_buf();
        (p, dir)
    });
    for (page, dir) in others.chain([changelog]) {
        let text = std::fs::read_to_string(&page).expect("a page is readable");
        let in_book = dir.starts_with(&docs);
        for (path, anchor) in markdown_links(&text) {
            let target = if path.is_empty() {
                page.clone()
            } else {
                dir.join(&path)
            };
            let shown = format!(
                "{}: ({path}#{})",
                page.display(),
                anchor.as_deref().unwrap_or("")
            );
            let Ok(target) = target.canonicalize() else {
                broken.push(format!("{shown}: no such file"));
                continue;
            };
            let is_page = target.extension().is_some_and(|e| e == "md");
            if in_book && is_page && page.file_name() != Some("SUMMARY.md".as_ref()) {
                let relative = target.strip_prefix(docs.canonicalize().expect("docs/"));
                if !relative.is_ok_and(|r| chapters.contains(r)) {
                    broken.push(format!("{shown}: not a chapter of docs/SUMMARY.md"));
                    continue;
                }
            }
            if let (Some(anchor), true) = (anchor, is_page) {
                let target_text = std::fs::read_to_string(&target).expect("a page is readable");
                if !anchors(&target_text).contains(&anchor) {
                    broken.push(format!("{shown}: no such anchor"));
                }
            }
        }
    }
    assert!(broken.is_empty(), "broken links:\n{}", broken.join("\n"));
}
