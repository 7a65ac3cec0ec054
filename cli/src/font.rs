//! The TrueType font plotters draws text with (its pure-Rust `ab_glyph` renderer needs one
//! registered at run time): `$CADMM_FONT`, else the first of a few common system paths
//! (Debian/Ubuntu: package `fonts-dejavu-core`). Shared by `cadmm bench` and
//! `examples/aa_paper.rs`.

use plotters::style::{register_font, FontStyle};
use std::sync::OnceLock;

const FONT_PATHS: [&str; 8] = [
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu-sans-fonts/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
    "/usr/share/fonts/truetype/freefont/FreeSans.ttf",
    "/System/Library/Fonts/Supplemental/Arial.ttf",
    "C:\\Windows\\Fonts\\arial.ttf",
];

/// Finds and registers the font once; `Err` says why there is none (plots are then skipped).
pub fn font() -> Result<(), String> {
    static FONT: OnceLock<Result<(), String>> = OnceLock::new();
    FONT.get_or_init(|| {
        let candidates: Vec<String> = std::env::var("CADMM_FONT")
            .ok()
            .into_iter()
            .chain(FONT_PATHS.iter().map(|s| s.to_string()))
            .collect();
        for p in &candidates {
            if let Ok(bytes) = std::fs::read(p) {
                // The registry keeps a 'static reference; one font for the whole run.
                let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
                if register_font("sans-serif", FontStyle::Normal, bytes).is_ok() {
                    return Ok(());
                }
            }
        }
        Err(format!(
            "no TrueType font found (set CADMM_FONT, or install fonts-dejavu-core); tried {}",
            candidates.join(", ")
        ))
    })
    .clone()
}
