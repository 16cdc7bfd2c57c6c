//! The subcommands of `material-nn`, one module each (its arguments and what it runs), and what
//! they share: argument parsers, the progress bar and the stop flag Ctrl-C sets.

use indicatif::{ProgressBar, ProgressStyle};
use renderer::Rgb;
use std::sync::atomic::AtomicBool;

pub mod encode;
pub mod eval;
pub mod export;
pub mod nbrdf_fit;
pub mod search;
pub mod tabulate;
pub mod train;

/// `R,G,B` (or one grey value), each in [0, 1].
pub fn parse_rgb(s: &str) -> Result<Rgb, String> {
    let values: Vec<f32> = s
        .split(',')
        .map(|v| v.trim().parse::<f32>().map_err(|e| format!("'{v}': {e}")))
        .collect::<Result<_, _>>()?;
    let rgb = match values[..] {
        [g] => Rgb::splat(g),
        [r, g, b] => Rgb::new(r, g, b),
        _ => return Err(format!("'{s}': expected R,G,B or one value")),
    };
    if !(rgb.is_finite() && rgb.min_element() >= 0.0 && rgb.max_element() <= 1.0) {
        return Err(format!("'{s}': values must lie in [0, 1]"));
    }
    Ok(rgb)
}

/// A finite number > 0.
pub fn parse_positive(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("'{s}': expected a positive number")),
    }
}

/// A finite number ≥ 0.
pub fn parse_non_negative(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v.is_finite() && v >= 0.0 => Ok(v),
        _ => Err(format!("'{s}': expected a non-negative number")),
    }
}

/// A progress bar of `len` steps labelled `what`.
pub fn progress_bar(len: usize, what: &str) -> ProgressBar {
    let bar = ProgressBar::new(len as u64);
    if let Ok(style) = ProgressStyle::with_template(
        "{prefix} [{bar:40}] {pos}/{len} {elapsed_precise} eta {eta} {msg}",
    ) {
        bar.set_style(style.progress_chars("=> "));
    }
    bar.set_prefix(what.to_string());
    bar
}

/// Set by Ctrl-C; the training loop stops after the current step.
pub static STOP: AtomicBool = AtomicBool::new(false);
