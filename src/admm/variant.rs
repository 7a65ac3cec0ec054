//! The named ADMM variants (docs/algorithms.md §6.5): `cp|vp` x `N|R|RR` x `He|Wohlberg|Spectral`.

use super::RhoRule;
use crate::types::Error;

/// Over-relaxation of the iteration (docs/algorithms.md §6.4).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Relaxation {
    /// Plain ADMM (`N`).
    None,
    /// Nesterov relaxation, eqs. (50)-(52) (`R`).
    Nesterov,
    /// Nesterov relaxation with the restart rule, eqs. (53)-(57) (`RR`).
    NesterovRestart,
}

/// A penalty rule and a relaxation, with their name.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Variant {
    /// Penalty (rho) rule.
    pub rule: RhoRule,
    /// Relaxation.
    pub relaxation: Relaxation,
}

/// The twelve variant names (docs/algorithms.md §6.5).
pub const VARIANT_NAMES: [&str; 12] = [
    "cp-N",
    "cp-R",
    "cp-RR",
    "vp-N-He",
    "vp-R-He",
    "vp-RR-He",
    "vp-N-Wohlberg",
    "vp-R-Wohlberg",
    "vp-RR-Wohlberg",
    "vp-N-Spectral",
    "vp-R-Spectral",
    "vp-RR-Spectral",
];

impl Variant {
    /// Parses a variant name (docs/algorithms.md §6.5) (`cp-N` ... `vp-RR-Spectral`). `auto` is resolved by the solver
    /// settings, not here.
    pub fn from_name(name: &str) -> Result<Self, Error> {
        let bad = || Error::InvalidSetting {
            name: "variant",
            reason: format!(
                "unknown variant '{name}' (expected auto or one of {})",
                VARIANT_NAMES.join(", ")
            ),
        };
        let parts: Vec<&str> = name.split('-').collect();
        let relaxation = |s: &str| match s {
            "N" => Some(Relaxation::None),
            "R" => Some(Relaxation::Nesterov),
            "RR" => Some(Relaxation::NesterovRestart),
            _ => None,
        };
        match parts.as_slice() {
            ["cp", r] => Ok(Self {
                rule: RhoRule::Constant,
                relaxation: relaxation(r).ok_or_else(bad)?,
            }),
            ["vp", r, rule] => {
                let rule = match *rule {
                    "He" => RhoRule::he(),
                    "Wohlberg" => RhoRule::wohlberg(),
                    "Spectral" => RhoRule::spectral(),
                    _ => return Err(bad()),
                };
                Ok(Self {
                    rule,
                    relaxation: relaxation(r).ok_or_else(bad)?,
                })
            }
            _ => Err(bad()),
        }
    }

    /// The name of this variant.
    pub fn name(&self) -> &'static str {
        let r = match self.relaxation {
            Relaxation::None => 0,
            Relaxation::Nesterov => 1,
            Relaxation::NesterovRestart => 2,
        };
        let p = match self.rule {
            RhoRule::Constant => 0,
            RhoRule::He { .. } => 1,
            RhoRule::Wohlberg { .. } => 2,
            RhoRule::Spectral { .. } => 3,
        };
        VARIANT_NAMES[p * 3 + r]
    }
}
