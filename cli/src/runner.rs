//! Runs a child process with a wall-clock deadline, collecting its stdout and stderr.

use std::io::Read;
use std::process::{Command, Stdio};
use std::thread;
use std::time::{Duration, Instant};

/// How a child process ended.
pub enum ChildEnd {
    /// It exited by itself (`code` is `None` when a signal ended it).
    Exited {
        /// Exit code.
        code: Option<i32>,
        /// Everything it printed on stdout.
        stdout: String,
        /// Everything it printed on stderr.
        stderr: String,
    },
    /// It was still running at the deadline and was killed.
    Killed,
}

fn drain(mut r: impl Read + Send + 'static) -> thread::JoinHandle<String> {
    thread::spawn(move || {
        let mut buf = Vec::new();
        let _ = r.read_to_end(&mut buf);
        String::from_utf8_lossy(&buf).into_owned()
    })
}

/// Spawns `cmd` and waits at most `deadline`; `Err` only when it cannot be started.
pub fn run(mut cmd: Command, deadline: Duration) -> Result<ChildEnd, String> {
    cmd.stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    // A process group of its own, so that a kill also reaches the processes it forked (the
    // Siconos script solves in a forked child that would otherwise keep our pipes open).
    #[cfg(unix)]
    std::os::unix::process::CommandExt::process_group(&mut cmd, 0);
    let mut child = cmd
        .spawn()
        .map_err(|e| format!("cannot start {:?}: {e}", cmd.get_program()))?;
    let out = drain(child.stdout.take().expect("stdout is piped"));
    let err = drain(child.stderr.take().expect("stderr is piped"));
    let t0 = Instant::now();
    let status = loop {
        match child.try_wait() {
            Ok(Some(s)) => break Some(s),
            Ok(None) if t0.elapsed() < deadline => thread::sleep(Duration::from_millis(5)),
            _ => break None,
        }
    };
    match status {
        Some(s) => Ok(ChildEnd::Exited {
            code: s.code(),
            stdout: out.join().unwrap_or_default(),
            stderr: err.join().unwrap_or_default(),
        }),
        None => {
            kill_group(&mut child);
            let _ = child.wait();
            // The readers end once every process of the group is gone.
            let _ = out.join();
            let _ = err.join();
            Ok(ChildEnd::Killed)
        }
    }
}

#[cfg(unix)]
fn kill_group(child: &mut std::process::Child) {
    // The child leads its own group (process_group(0)): its pid is the group id.
    if let Ok(pid) = libc::pid_t::try_from(child.id()) {
        // SAFETY: kill(2) with a negative pid signals that process group only.
        unsafe {
            libc::kill(-pid, libc::SIGKILL);
        }
    }
    let _ = child.kill();
}

#[cfg(not(unix))]
fn kill_group(child: &mut std::process::Child) {
    let _ = child.kill();
}
