//! Reads `/solution/{r, u, v, l}` (FCLib layout) written by cadmm or by the Siconos script.

use cadmm::Solution;
use std::path::Path;

/// Reads a solution file; `u`, `v` and `l` are empty when absent.
pub fn read(path: &Path) -> Result<Solution, String> {
    let err = |e: hdf5::Error| format!("{}: {e}", path.display());
    let file = hdf5::File::open(path).map_err(err)?;
    let g = file.group("solution").map_err(err)?;
    let vector = |name: &str| -> Result<Vec<f64>, String> {
        if !g.link_exists(name) {
            return Ok(Vec::new());
        }
        g.dataset(name)
            .and_then(|d| d.read_raw::<f64>())
            .map_err(|e| format!("{}: /solution/{name}: {e}", path.display()))
    };
    let r = vector("r")?;
    if r.is_empty() && !g.link_exists("r") {
        return Err(format!("{}: no /solution/r", path.display()));
    }
    Ok(Solution {
        r,
        u: vector("u")?,
        v: vector("v")?,
        lambda: vector("l")?,
    })
}
