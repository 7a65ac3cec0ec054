//! What the CLI's integration tests share: where the shared data and tools are, and which
//! Python can run Siconos.

use std::path::{Path, PathBuf};
use std::process::Command;

/// `$CADMM_SHARED`, else `../shared` next to the workspace.
pub fn shared() -> PathBuf {
    std::env::var_os("CADMM_SHARED")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared"))
}

/// `$CADMM_PYTHON` (else `/usr/bin/python3`, the interpreter python3-siconos is built for)
/// when it imports Siconos and what fc_error.py needs.
pub fn siconos_python() -> Option<String> {
    let py = std::env::var("CADMM_PYTHON").unwrap_or_else(|_| "/usr/bin/python3".into());
    Command::new(&py)
        .args(["-c", "import siconos.numerics, h5py, scipy"])
        .output()
        .is_ok_and(|o| o.status.success())
        .then_some(py)
}
