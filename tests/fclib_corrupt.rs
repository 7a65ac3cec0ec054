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
