//! The results model: each run's outcome as typed values (Serialize and
//! Deserialize), from which its `summary.json` is written and every page,
//! gate and reader works. `summary.json` is its serialisation, with a
//! `schema_version` ([`SCHEMA_VERSION`]); `docs/summary-json.md` documents it.
//!
//! - [`summary`]: a camera (or tracker-CSV) run, and [`summary::RunSummary`],
//!   either kind as read back from disk;
//! - [`tracked`]: a tracked-sequence (PLUS recording) run;
//! - [`volume`]: what a tracked run says of its reconstruction;
//! - [`live`]: a live session (replay, watched folder, OpenIGTLink);
//! - [`reconstruction`]: `probecal reconstruct` (and its agreement with a reference);
//! - [`segmentation`]: `probecal segment` (and its score against PLUS's);
//! - [`study`]: `probecal study` (`study.json`);
//! - [`temporal`]: `probecal temporal`;
//! - [`selfcal`]: `probecal selfcal`.

pub mod ablation;
pub mod calibration;
pub mod comparison;
pub mod live;
pub mod reconstruction;
pub mod segmentation;
pub mod selfcal;
pub mod study;
pub mod summary;
pub mod temporal;
pub mod tracked;
pub mod volume;

use std::path::PathBuf;

/// The layout of `summary.json` this probecal writes and reads. A summary
/// without the field has version 1's layout (the field came with version 1).
pub const SCHEMA_VERSION: u32 = 1;

/// The schema version of a summary written before the field existed.
pub fn first_schema_version() -> u32 {
    1
}

/// Why a results file's `schema_version` cannot be read by this probecal: a
/// newer layout, or not a whole number from 1 (none: absent or readable).
pub fn schema_version_fault(value: &serde_json::Value) -> Option<String> {
    let version = value.get("schema_version")?;
    match version.as_u64() {
        Some(v) if v >= 1 && v <= u64::from(SCHEMA_VERSION) => None,
        Some(v) if v > u64::from(SCHEMA_VERSION) => Some(format!(
            "field `schema_version`: {v}: written by a newer probecal (this one reads summaries of schema version 1 to {SCHEMA_VERSION})"
        )),
        _ => Some(format!(
            "field `schema_version`: {version}: not a schema version (a whole number from 1)"
        )),
    }
}

/// A file that could not be read or is not what it should be: the path and
/// what is wrong (with the field and line where the format has them).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{}: {message}", path.display())]
pub struct ReadError {
    pub path: PathBuf,
    pub message: String,
}

impl ReadError {
    pub fn new(path: &std::path::Path, message: impl std::fmt::Display) -> ReadError {
        ReadError {
            path: path.to_path_buf(),
            message: message.to_string(),
        }
    }
}

/// A `summary.json`'s `kind` (none where it has none or cannot be read).
pub fn kind_of(summary: &std::path::Path) -> Option<String> {
    #[derive(serde::Deserialize)]
    struct Kind {
        kind: Option<String>,
    }
    crate::io::fs::read_text_capped(summary, crate::core::limits::MAX_TEXT_FILE_BYTES)
        .ok()
        .and_then(|t| serde_json::from_str::<Kind>(&t).ok())
        .and_then(|k| k.kind)
}

/// Whether a `summary.json` is another command's (`reconstruct`, `selfcal`)
/// beside the runs, not a calibration run's.
pub fn is_not_a_run(summary: &std::path::Path) -> bool {
    matches!(
        kind_of(summary).as_deref(),
        Some(reconstruction::KIND) | Some(selfcal::KIND)
    )
}

#[cfg(test)]
mod tests {
    use super::summary::RunSummary;
    use std::path::Path;

    fn read(text: &str) -> Result<RunSummary, super::ReadError> {
        RunSummary::parse(text, Path::new("summary.json"))
    }

    #[test]
    fn a_summary_says_its_schema_version_and_a_newer_one_is_refused() {
        let summary = super::tracked::TrackedSummary {
            schema_version: super::SCHEMA_VERSION,
            experiment: "fcal".into(),
            dataset: "sweep".into(),
            kind: super::tracked::TRACKED_KIND.into(),
            ..Default::default()
        };
        let text = crate::io::json::to_text(&summary).unwrap();
        assert!(text.contains("\n  \"schema_version\": 1,\n"), "{text}");
        assert!(matches!(read(&text), Ok(RunSummary::Tracked(s)) if s.schema_version == super::SCHEMA_VERSION));
        // Written before the field existed: version 1's layout.
        let without = text.replacen("\n  \"schema_version\": 1,", "", 1);
        assert!(matches!(read(&without), Ok(RunSummary::Tracked(s)) if s.schema_version == 1));
        let newer = text.replacen("\"schema_version\": 1,", "\"schema_version\": 2,", 1);
        let e = read(&newer).unwrap_err().to_string();
        assert!(e.contains("schema_version") && e.contains("newer probecal"), "{e}");
        for bad in ["0", "1.5", "\"1\"", "-1"] {
            let text = text.replacen("\"schema_version\": 1,", &format!("\"schema_version\": {bad},"), 1);
            let e = read(&text).unwrap_err().to_string();
            assert!(e.contains("not a schema version"), "{bad}: {e}");
        }
        // The experiment's name names folders: a path is not one.
        let escaping = text.replacen("\"experiment\": \"fcal\"", "\"experiment\": \"../x\"", 1);
        let e = read(&escaping).unwrap_err().to_string();
        assert!(e.contains("field `experiment`"), "{e}");
    }
}
