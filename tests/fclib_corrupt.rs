//! FCLib files whose headers lie about sizes: the reader must refuse them with an error
//! naming the dataset, before allocating what they claim (a mutated file found by the
//! `fclib_read` fuzz target declared 2^34 elements for a scalar and aborted the process).
#![cfg(feature = "fclib")]

use cadmm::{fclib, CscMatrix, Error, LocalProblem, Problem};

#[test]
fn a_dataset_declaring_more_than_the_file_holds_is_refused() {
    let dir = std::env::temp_dir().join(format!("cadmm-corrupt-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("huge.hdf5");
    let p = LocalProblem::new(CscMatrix::identity(3), vec![-1.0, 0.0, 0.0], vec![0.3]).unwrap();
    fclib::write_problem(&path, &Problem::Local(p)).unwrap();
    {
        // Replace W's row count by a chunked dataset of 2^40 elements with no data written:
        // a valid HDF5 file of a few kilobytes whose reading would allocate 8 TiB.
        let file = hdf5::File::open_rw(&path).unwrap();
        let w = file.group("fclib_local/W").unwrap();
        w.unlink("m").unwrap();
        w.new_dataset::<i64>()
            .chunk(1024)
            .shape(1usize << 40)
            .create("m")
            .unwrap();
    }
    match fclib::read(&path) {
        Err(Error::Io(msg)) => assert!(msg.contains("/m declares"), "{msg}"),
        other => panic!("expected an i/o error, got {other:?}"),
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A scratch directory of this test process, removed by the caller.
fn scratch(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("cadmm-corrupt-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Replaces (or adds) integer datasets of `group` in the file at `path`.
fn set_ints(path: &std::path::Path, group: &str, fields: &[(&str, &[i64])]) {
    let file = hdf5::File::open_rw(path).unwrap();
    let g = file.group(group).unwrap();
    for (name, data) in fields {
        if g.link_exists(name) {
            g.unlink(name).unwrap();
        }
        g.new_dataset_builder()
            .with_data(*data)
            .create(*name)
            .unwrap();
    }
}

/// Replaces a float dataset of `group`.
fn set_floats(path: &std::path::Path, group: &str, name: &str, data: &[f64]) {
    let file = hdf5::File::open_rw(path).unwrap();
    let g = file.group(group).unwrap();
    g.unlink(name).unwrap();
    g.new_dataset_builder()
        .with_data(data)
        .create(name)
        .unwrap();
}

/// The one-contact global problem, as a file.
fn global_file(path: &std::path::Path) {
    let p = cadmm::GlobalProblem::new(
        CscMatrix::identity(3),
        CscMatrix::identity(3),
        vec![-1.0, 0.0, 0.0],
        vec![0.0; 3],
        vec![0.3],
    )
    .unwrap();
    fclib::write_problem(path, &Problem::Global(p)).unwrap();
}

/// The one-contact local problem, as a file.
fn local_file(path: &std::path::Path) {
    let p = LocalProblem::new(CscMatrix::identity(3), vec![-1.0, 0.0, 0.0], vec![0.3]).unwrap();
    fclib::write_problem(path, &Problem::Local(p)).unwrap();
}

/// The read must fail with an i/o error whose message holds every one of `words`.
fn expect_io(path: &std::path::Path, words: &[&str]) {
    match fclib::read(path) {
        Err(Error::Io(msg)) => {
            for w in words {
                assert!(msg.contains(w), "{msg:?} does not say {w:?}");
            }
        }
        other => panic!("expected an i/o error saying {words:?}, got {other:?}"),
    }
}

const HUGE: i64 = 10_000_000_000_000; // 1e13

/// Issue 41: size fields of 1e13 over a 3 x 3 matrix, in each encoding. The triplet and
/// row-compressed readers built column pointers of `n + 1` entries from them (an abort on
/// the allocation); they are checked against the datasets and the problem's vectors first.
#[test]
fn huge_size_fields_are_refused_before_use() {
    let dir = scratch("sizes");
    let path = dir.join("global.hdf5");
    // Triplets (Siconos' encoding): rows in i, columns in p.
    let triplets: [(&str, &[i64]); 4] = [
        ("nz", &[3]),
        ("nzmax", &[3]),
        ("p", &[0, 1, 2]),
        ("i", &[0, 1, 2]),
    ];
    global_file(&path);
    set_ints(&path, "fclib_global/M", &triplets);
    set_ints(&path, "fclib_global/M", &[("m", &[HUGE]), ("n", &[HUGE])]);
    expect_io(&path, &["M", "m = 10000000000000"]);
    global_file(&path);
    set_ints(&path, "fclib_global/H", &triplets);
    set_ints(&path, "fclib_global/H", &[("n", &[HUGE])]);
    expect_io(&path, &["H", "n = 10000000000000"]);
    // Compressed column: n + 1 column pointers are announced, 4 stored.
    global_file(&path);
    set_ints(&path, "fclib_global/M", &[("n", &[HUGE])]);
    expect_io(&path, &["M", "n = 10000000000000"]);
    // Compressed row, local: the column count was used unchecked.
    let path = dir.join("local.hdf5");
    local_file(&path);
    set_ints(&path, "fclib_local/W", &[("nz", &[-2]), ("n", &[HUGE])]);
    expect_io(&path, &["W", "n = 10000000000000"]);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Issue 41: a row-compressed W whose values `x` are fewer than its column indices `i` was
/// read past the end of `x` (a panic, CADMM_ERR_PANIC through C).
#[test]
fn a_short_value_dataset_is_an_io_error() {
    let dir = scratch("short");
    let path = dir.join("local.hdf5");
    local_file(&path);
    set_ints(&path, "fclib_local/W", &[("nz", &[-2])]);
    set_floats(&path, "fclib_local/W", "x", &[1.0, 1.0]);
    expect_io(&path, &["W", "x", "i"]);
    let cpath = std::ffi::CString::new(path.to_str().unwrap()).unwrap();
    let mut out = std::ptr::null_mut();
    let rc = unsafe { cadmm::ffi::cadmm_problem_read_fclib(cpath.as_ptr(), &mut out) };
    assert_eq!(rc, cadmm::ffi::CADMM_ERR_IO);
    assert!(out.is_null());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Issue 41: reading a FIFO nobody writes to blocked forever. Only regular files are
/// opened. The read runs on a thread so that a regression fails here instead of hanging.
#[test]
fn a_fifo_is_refused_without_blocking() {
    let dir = scratch("fifo");
    let fifo = dir.join("pipe.hdf5");
    // libc's mkfifo, not the command: a child process forked while another test holds an
    // HDF5 file open inherits the descriptor and its lock, and that test's next open of
    // the file fails ("unable to lock file").
    let cpath = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
    // SAFETY: a NUL-terminated path.
    assert_eq!(unsafe { libc::mkfifo(cpath.as_ptr(), 0o600) }, 0);
    for path in [fifo.clone(), dir.clone()] {
        let (tx, rx) = std::sync::mpsc::channel();
        let p = path.clone();
        std::thread::spawn(move || {
            let _ = tx.send((fclib::read(&p), fclib::read_solution(&p).err()));
        });
        let (read, solution) = rx
            .recv_timeout(std::time::Duration::from_secs(10))
            .unwrap_or_else(|_| panic!("reading {} blocked", path.display()));
        match read {
            Err(Error::Io(msg)) => assert!(msg.contains("not a regular file"), "{msg}"),
            other => panic!("expected an i/o error, got {other:?}"),
        }
        match solution {
            Some(Error::Io(msg)) => assert!(msg.contains("not a regular file"), "{msg}"),
            other => panic!("expected an i/o error, got {other:?}"),
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
