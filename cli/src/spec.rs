//! Solver names of `cadmm bench --solvers`: `cadmm:<auto|variant>[+aa<M>]` and
//! `siconos:<NAME>`.

use cadmm::VariantChoice;

/// Siconos solvers the peer script knows, with the problem forms each one exists for. Mirrors
/// `SOLVERS` in `bench/siconos_solve.py`: asking it for a missing pair is an input error there,
/// here it is a failed run ("unsupported"), so profiles still have an entry for every pair.
const SICONOS: [(&str, bool, bool); 6] = [
    // (name, global, local)
    ("ADMM", true, true),
    ("NSGS", true, true),
    ("NSGS_WR", true, false),
    ("IPM", true, false),
    ("NSN_AC", true, true),
    ("PROX", true, true),
];

/// One solver configuration of a benchmark.
#[derive(Debug, Clone, PartialEq)]
pub enum SolverSpec {
    /// cadmm with a variant, an optional Anderson memory and an optional Newton polish
    /// switch (`None`: the variant's default).
    Cadmm {
        /// `auto`, `newton` or an ADMM variant name, as the `solve` command takes it.
        variant: String,
        /// Anderson memory from the `+aaM` suffix.
        anderson: Option<usize>,
        /// Newton polish from the `+newton` / `+nonewton` suffix.
        newton: Option<bool>,
    },
    /// A Siconos numerics solver run by the peer script.
    Siconos {
        /// Upper-case name (`ADMM`, `NSGS_WR`, ...).
        name: &'static str,
    },
}

impl SolverSpec {
    /// Parses one entry of `--solvers`.
    pub fn parse(s: &str) -> Result<Self, String> {
        let s = s.trim();
        if let Some(rest) = s.strip_prefix("cadmm:") {
            let mut parts = rest.split('+');
            let variant = parts.next().unwrap_or_default();
            let (mut anderson, mut newton) = (None, None);
            for suffix in parts {
                match suffix {
                    "newton" => newton = Some(true),
                    "nonewton" => newton = Some(false),
                    _ => {
                        let m = suffix
                            .strip_prefix("aa")
                            .and_then(|m| m.parse::<usize>().ok())
                            .ok_or_else(|| {
                                format!(
                                    "'{s}': a suffix is +aaM (Anderson memory M), +newton or \
                                     +nonewton"
                                )
                            })?;
                        anderson = Some(m);
                    }
                }
            }
            VariantChoice::from_name(variant).map_err(|e| format!("'{s}': {e}"))?;
            if anderson.is_some_and(|m| m > 64) {
                return Err(format!("'{s}': Anderson memory must be at most 64"));
            }
            return Ok(SolverSpec::Cadmm {
                variant: variant.to_string(),
                anderson,
                newton,
            });
        }
        if let Some(rest) = s.strip_prefix("siconos:") {
            let up = rest.to_ascii_uppercase();
            return SICONOS
                .iter()
                .find(|(n, _, _)| *n == up)
                .map(|(n, _, _)| SolverSpec::Siconos { name: n })
                .ok_or_else(|| {
                    let names: Vec<&str> = SICONOS.iter().map(|(n, _, _)| *n).collect();
                    format!(
                        "'{s}': unknown Siconos solver (one of {})",
                        names.join(", ")
                    )
                });
        }
        Err(format!(
            "'{s}': expected cadmm:<auto|newton|variant>[+aaM][+newton|+nonewton] or siconos:<NAME>"
        ))
    }

    /// The name in results and legends (canonical spelling of what was asked).
    pub fn label(&self) -> String {
        match self {
            SolverSpec::Cadmm {
                variant,
                anderson,
                newton,
            } => {
                let mut label = format!("cadmm:{variant}");
                if let Some(m) = anderson {
                    label += &format!("+aa{m}");
                }
                match newton {
                    Some(true) => label += "+newton",
                    Some(false) => label += "+nonewton",
                    None => {}
                }
                label
            }
            SolverSpec::Siconos { name } => format!("siconos:{name}"),
        }
    }

    /// The label made safe for file names: `cadmm:cp-N+aa5` -> `cadmm_cp-N_aa5`.
    pub fn file_tag(&self) -> String {
        sanitize(&self.label())
    }

    /// Whether this is one of ours (the reference of the summary's time ratios).
    pub fn is_cadmm(&self) -> bool {
        matches!(self, SolverSpec::Cadmm { .. })
    }

    /// Whether the solver exists for this form (`true`: global).
    pub fn supports(&self, global: bool) -> bool {
        match self {
            SolverSpec::Cadmm { .. } => true,
            SolverSpec::Siconos { name } => SICONOS
                .iter()
                .any(|(n, g, l)| n == name && if global { *g } else { *l }),
        }
    }
}

/// Keeps ASCII letters, digits, `-` and `.`; everything else becomes `_`.
pub fn sanitize(s: &str) -> String {
    s.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '.' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_names() {
        let a = SolverSpec::parse("cadmm:cp-N+aa5").unwrap();
        assert_eq!(
            a,
            SolverSpec::Cadmm {
                variant: "cp-N".into(),
                anderson: Some(5),
                newton: None,
            }
        );
        assert_eq!(a.file_tag(), "cadmm_cp-N_aa5");
        let b = SolverSpec::parse("cadmm:auto+nonewton").unwrap();
        assert_eq!(b.label(), "cadmm:auto+nonewton");
        assert_eq!(
            SolverSpec::parse("cadmm:auto").unwrap().file_tag(),
            "cadmm_auto"
        );
        let s = SolverSpec::parse("siconos:nsgs_wr").unwrap();
        assert_eq!(s.label(), "siconos:NSGS_WR");
        assert!(s.supports(true) && !s.supports(false));
        assert_eq!(
            SolverSpec::parse("siconos:ADMM").unwrap().file_tag(),
            "siconos_ADMM"
        );
        for bad in [
            "cadmm:vp-X",
            "cadmm:auto+5",
            "cadmm:auto+aa65",
            "cadmm:auto+newtonn",
            "siconos:FOO",
            "pin:ADMM",
        ] {
            assert!(SolverSpec::parse(bad).is_err(), "{bad}");
        }
    }
}
