//! The FCLib reader on mutated files: every file must be read into a valid problem or
//! refused with an error (never a panic), and what is read must solve or end with a status.
#![no_main]

use cadmm::{Settings, Solver};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let path = std::env::temp_dir().join(format!("cadmm-fuzz-{}.hdf5", std::process::id()));
    if std::fs::write(&path, data).is_err() {
        return;
    }
    if let Ok(p) = cadmm::fclib::read(&path) {
        // Small problems only: a mutated size must not turn one input into a long solve.
        if p.n_contacts() <= 200 && p.n_velocities() <= 2000 {
            let settings = Settings {
                max_iterations: 200,
                time_limit: 0.2,
                ..Settings::default()
            };
            if let Ok(mut s) = Solver::new(p, settings) {
                let _ = s.solve();
            }
        }
    }
    let _ = std::fs::remove_file(&path);
});
