//! Runs a test of the calling test binary again on several MPI processes: the one harness
//! of the distributed tests, the library's own and those beside it. Not part of the API.
//!
//! The test runs under Open MPI's `mpirun --oversubscribe` (the machine may have fewer
//! cores than processes) inside a `timeout` (a hang fails the test), where [`is_child`]
//! tells it to do the work of one process; the parent checks the exit codes and what the
//! processes printed.

use std::ffi::OsStr;
use std::process::Command;

/// Set in the environment of the processes [`run`] starts.
const CHILD: &str = "CADMM_MPI_CHILD";

/// Whether this test runs as one of the processes [`run`] started.
pub fn is_child() -> bool {
    std::env::var_os(CHILD).is_some()
}

/// Runs this binary's test `name` on `np` processes, with the environment variables `env`
/// set; their standard output. Panics, with their output, when a process fails.
pub fn run(name: &str, np: usize, env: &[(&str, &OsStr)]) -> String {
    let out = Command::new("timeout")
        .args(["300", "mpirun", "--oversubscribe", "-np", &np.to_string()])
        .arg(std::env::current_exe().expect("the test binary"))
        .args([name, "--exact", "--nocapture", "--test-threads", "1"])
        .env(CHILD, "1")
        .envs(env.iter().copied())
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .output()
        .expect("mpirun runs (Debian: openmpi-bin)");
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "mpirun -np {np} {name}: {:?}\n{stdout}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}
