//! What the live sessions write per frame: a number's column, and the files.

use serde::Serialize;

/// A number as the live tables write it (4 decimals; empty when absent).
pub(crate) fn number(v: Option<f64>) -> String {
    v.map(|v| format!("{v:.4}")).unwrap_or_default()
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
