//! What both live pages print per frame: a number's column and the per-frame
//! times' summary.

use serde::Serialize;

use crate::core::stats::{mean_sd, percentile};

/// A number as the live tables write it (4 decimals; empty when absent).
pub(crate) fn number(v: Option<f64>) -> String {
    v.map(|v| format!("{v:.4}")).unwrap_or_default()
}

/// Mean, 95th percentile and largest of per-frame times, ms.
#[derive(Serialize)]
pub struct Timing {
    pub mean: f64,
    pub p95: f64,
    pub max: f64,
}

pub(crate) fn timing(values: &[f64]) -> Timing {
    Timing {
        mean: mean_sd(values).mean,
        p95: if values.is_empty() {
            0.0
        } else {
            percentile(values, 0.95)
        },
        max: values.iter().copied().fold(0.0, f64::max),
    }
}

/// Writes a live session's `summary.json` and `live.csv` into `out` (whole, or nothing).
pub(crate) fn write_session<S: Serialize>(
    out: &std::path::Path,
    summary: &S,
    frames_csv: String,
) -> Result<(), crate::report::error::OutputError> {
    let files = [
        (
            "summary.json".to_string(),
            crate::results::summary::to_text(summary)?.into_bytes(),
        ),
        ("live.csv".to_string(), frames_csv.into_bytes()),
    ];
    Ok(crate::io::fs::write_all_atomic(out, &files)?)
}
