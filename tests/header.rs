//! `include/cadmm.h` is generated from `src/ffi/` and committed; this test fails when it is
//! stale. `CADMM_BLESS=1 cargo test --test header` rewrites it instead.

use std::path::Path;

/// The header as cbindgen generates it now, with the version macros from Cargo.toml.
fn generate() -> String {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut config = cbindgen::Config::from_file(root.join("cbindgen.toml"))
        .expect("cbindgen.toml is readable and valid");
    config.after_includes = Some(format!(
        "#define CADMM_VERSION_MAJOR {}\n\
         #define CADMM_VERSION_MINOR {}\n\
         #define CADMM_VERSION_PATCH {}\n\
         #define CADMM_VERSION_STRING \"{}\"",
        env!("CARGO_PKG_VERSION_MAJOR"),
        env!("CARGO_PKG_VERSION_MINOR"),
        env!("CARGO_PKG_VERSION_PATCH"),
        env!("CARGO_PKG_VERSION"),
    ));
    let bindings = cbindgen::Builder::new()
        .with_config(config)
        .with_src(root.join("src/ffi/mod.rs"))
        .generate()
        .expect("cbindgen generates the header");
    let mut out = Vec::new();
    bindings.write(&mut out);
    String::from_utf8(out).expect("the header is UTF-8")
}

#[test]
fn header_is_up_to_date() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("include/cadmm.h");
    let generated = generate();
    if std::env::var("CADMM_BLESS").as_deref() == Ok("1") {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(&path, &generated).unwrap();
        return;
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        committed == generated,
        "include/cadmm.h is stale: regenerate it with `CADMM_BLESS=1 cargo test --test header`"
    );
}

/// The committed header's version macro (read from the file, not from what this test
/// generates) names the version of the library linked into this test.
#[test]
fn header_version_matches_the_library() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("include/cadmm.h");
    let committed = std::fs::read_to_string(&path).expect("include/cadmm.h is readable");
    let header_version = committed
        .lines()
        .find_map(|l| l.strip_prefix("#define CADMM_VERSION_STRING \""))
        .and_then(|rest| rest.strip_suffix('"'))
        .expect("include/cadmm.h defines CADMM_VERSION_STRING");
    let v = unsafe { std::ffi::CStr::from_ptr(cadmm::ffi::cadmm_version()) };
    assert_eq!(v.to_str().unwrap(), header_version);
}

/// `cadmm::ffi::*` holds the whole C API: `src/ffi/mod.rs` re-exports each module that
/// declares part of it (a function, a struct, a constant or a type) as a whole
/// (`pub use module::*;`), so that no list of names can fall behind.
#[test]
fn every_module_of_the_c_api_is_reexported_whole() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("src/ffi");
    let root = std::fs::read_to_string(dir.join("mod.rs")).expect("src/ffi/mod.rs is readable");
    let mut missing = Vec::new();
    for entry in std::fs::read_dir(&dir).expect("src/ffi/ is readable") {
        let path = entry.expect("a directory entry").path();
        let Some(module) = path.file_stem().and_then(|s| s.to_str()) else {
            continue;
        };
        if module == "mod" {
            continue;
        }
        let text = std::fs::read_to_string(&path).unwrap_or_default();
        let exports = ["#[no_mangle]", "pub struct ", "pub const ", "pub type "]
            .iter()
            .any(|item| text.contains(item));
        if exports && !root.contains(&format!("pub use {module}::*;")) {
            missing.push(module.to_owned());
        }
    }
    assert!(
        missing.is_empty(),
        "src/ffi/mod.rs does not re-export these modules of the C API whole: {missing:?}"
    );
}
