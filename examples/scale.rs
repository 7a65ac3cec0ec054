//! The piles of the scale benchmark (`cli/bench/scale.py`): the lattice pile of
//! `examples/extreme/scenes.rs` and the irregular pile (polydisperse spheres dropped on a
//! jittered lattice, contacts where gaps are small), at sizes given by a target contact
//! count or by lattice dimensions, written as FCLib global problems.
//!
//! ```sh
//! cargo run --release --features fclib --example scale -- --dump DIR \
//!     [--sizes 1000,2800,10000,25000,100000] [--kinds lattice,irregular] \
//!     [--radii 0.35:0.5] [--jitter 1] [--gap 0.1] [--mu 0.5] [--seed N]
//! ```
//!
//! The last five shape the irregular pile (`scenes::PileShape`; the defaults are
//! `scenes::PILE_SHAPE`): radii uniform in `--radii`, drop sites moved up to `--jitter`
//! times their free room from the lattice, contacts where gaps are below `--gap` times the
//! smaller radius, friction `--mu`, and the random stream's `--seed`. A pile of another
//! shape is written with the shape in its name.
//!
//! A size is a target contact count (`2800`: cubic-ish lattices, twice as tall as wide,
//! sized to come near it) or lattice dimensions (`20x20x87`). One line per pile: its
//! contacts, bodies, nnz(H), islands (groups of bodies joined by contacts) and file
//! (`DIR/lattice-pile-N.hdf5`, `DIR/irregular-pile-N.hdf5`, N its contact count). Without
//! `--dump`, only the sizes are printed.

#[path = "../tests/common/mod.rs"]
mod common;
#[path = "extreme/scenes.rs"]
mod scenes;

use cadmm::GlobalProblem;
use scenes::Scene;
use std::process::ExitCode;

#[derive(Clone, Copy)]
enum Size {
    Contacts(usize),
    Dims(usize, usize, usize),
}

struct Args {
    dump: Option<String>,
    sizes: Vec<Size>,
    kinds: Vec<String>,
    shape: scenes::PileShape,
}

fn number<T: std::str::FromStr>(flag: &str, v: &str) -> Result<T, String> {
    v.parse().map_err(|_| format!("{flag} {v}: not a number"))
}

/// The shape's flags, checked against each other.
fn check_shape(s: &scenes::PileShape) -> Result<(), String> {
    let fine = 0.0 < s.r_min
        && s.r_min <= s.r_max
        && s.r_max <= 0.5
        && (0.0..=1.0).contains(&s.jitter)
        && s.gap_fraction > 0.0
        && s.mu >= 0.0;
    match fine {
        true => Ok(()),
        false => Err(format!(
            "pile shape {s:?}: needs 0 < r_min <= r_max <= 0.5, jitter in [0, 1], gap > 0, mu >= 0"
        )),
    }
}

/// The shape in a file name, empty for the default one.
fn shape_label(s: &scenes::PileShape) -> String {
    match *s == scenes::PILE_SHAPE {
        true => String::new(),
        false => format!(
            "-r{}-{}-j{}-g{}-mu{}-s{}",
            s.r_min, s.r_max, s.jitter, s.gap_fraction, s.mu, s.seed
        ),
    }
}

fn parse_size(v: &str) -> Result<Size, String> {
    let d: Vec<usize> = v
        .split('x')
        .map(|x| x.parse().map_err(|e| format!("--sizes {v}: {e}")))
        .collect::<Result<_, _>>()?;
    match d[..] {
        [n] if n > 0 => Ok(Size::Contacts(n)),
        [x, y, z] if x > 0 && y > 0 && z > 0 => Ok(Size::Dims(x, y, z)),
        _ => Err(format!(
            "--sizes {v}: expected a contact count or NXxNYxNZ, all positive"
        )),
    }
}

fn parse() -> Result<Args, String> {
    let mut a = Args {
        dump: None,
        sizes: [1000, 2800, 10_000, 25_000, 100_000]
            .map(Size::Contacts)
            .to_vec(),
        kinds: vec!["lattice".into(), "irregular".into()],
        shape: scenes::PILE_SHAPE,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let mut value = || it.next().ok_or(format!("{flag} needs a value"));
        match flag.as_str() {
            "--dump" => a.dump = Some(value()?),
            "--sizes" => {
                a.sizes = value()?
                    .split(',')
                    .map(parse_size)
                    .collect::<Result<_, _>>()?
            }
            "--kinds" => {
                a.kinds = value()?.split(',').map(String::from).collect();
                if let Some(k) = a
                    .kinds
                    .iter()
                    .find(|k| !matches!(k.as_str(), "lattice" | "irregular"))
                {
                    return Err(format!("--kinds: expected lattice or irregular, got {k}"));
                }
            }
            "--radii" => {
                let v = value()?;
                let (lo, hi) = v
                    .split_once(':')
                    .ok_or(format!("--radii {v}: expected MIN:MAX"))?;
                a.shape.r_min = number("--radii", lo)?;
                a.shape.r_max = number("--radii", hi)?;
            }
            "--jitter" => a.shape.jitter = number(&flag, &value()?)?,
            "--gap" => a.shape.gap_fraction = number(&flag, &value()?)?,
            "--mu" => a.shape.mu = number(&flag, &value()?)?,
            "--seed" => a.shape.seed = number(&flag, &value()?)?,
            _ => return Err(format!("unknown argument {flag}")),
        }
    }
    check_shape(&a.shape)?;
    Ok(a)
}

/// Side of the square base for about `target` contacts at 3 per sphere, twice as tall as
/// wide (`3 * side^2 * 2 side`).
fn side(target: usize) -> usize {
    ((target as f64 / 6.0).cbrt().round() as usize).max(1)
}

fn build(kind: &str, size: Size, shape: &scenes::PileShape) -> (Scene, (usize, usize, usize)) {
    let make = |(x, y, z)| match kind {
        "lattice" => scenes::pile(x, y, z),
        _ => scenes::irregular_pile_shaped(x, y, z, shape),
    };
    let dims = match size {
        Size::Dims(x, y, z) => (x, y, z),
        Size::Contacts(target) => {
            let s = side(target);
            let per_layer = match kind {
                // Below or on the ground, and one neighbour along x and along y.
                "lattice" => (3 * s * s - 2 * s) as f64,
                // Measured on a probe pile of the same base.
                _ => make((s, s, 2 * s)).contacts.len() as f64 / (2 * s) as f64,
            };
            (s, s, ((target as f64 / per_layer).round() as usize).max(1))
        }
    };
    (make(dims), dims)
}

#[cfg(feature = "fclib")]
fn dump(path: &str, global: GlobalProblem) -> Result<(), String> {
    cadmm::fclib::write_problem(path, &cadmm::Problem::Global(global))
        .map_err(|e| format!("{path}: {e}"))
}

#[cfg(not(feature = "fclib"))]
fn dump(_: &str, _: GlobalProblem) -> Result<(), String> {
    Err(
        "--dump needs the fclib feature: cargo run --release --features fclib --example scale"
            .into(),
    )
}

fn main() -> ExitCode {
    let args = match parse() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("scale: {e}");
            return ExitCode::from(2);
        }
    };
    if let Some(dir) = &args.dump {
        if let Err(e) = std::fs::create_dir_all(dir) {
            eprintln!("scale: {dir}: {e}");
            return ExitCode::FAILURE;
        }
    }
    println!(
        "{:10} {:>12} {:>9} {:>8} {:>9} {:>8}  file",
        "pile", "dims", "contacts", "bodies", "nnz(H)", "islands"
    );
    for &size in &args.sizes {
        for kind in &args.kinds {
            let (scene, (x, y, z)) = build(kind, size, &args.shape);
            let nc = scene.contacts.len();
            let global = scene.global();
            let nnz = global.h.nnz();
            let file = args.dump.as_ref().map(|d| match kind.as_str() {
                "lattice" => format!("{d}/{kind}-pile-{nc}.hdf5"),
                _ => format!("{d}/{kind}-pile-{nc}{}.hdf5", shape_label(&args.shape)),
            });
            if let Some(path) = &file {
                if let Err(e) = dump(path, global) {
                    eprintln!("scale: {e}");
                    return ExitCode::FAILURE;
                }
            }
            println!(
                "{:10} {:>12} {:>9} {:>8} {:>9} {:>8}  {}",
                kind,
                format!("{x}x{y}x{z}"),
                nc,
                scene.bodies.len(),
                nnz,
                scenes::islands(&scene).1,
                file.as_deref().unwrap_or("-")
            );
        }
    }
    ExitCode::SUCCESS
}
