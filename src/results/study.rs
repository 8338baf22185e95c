//! `probecal study`'s outcome (`study.json`): the thesis's σ-table and, when
//! seeds were run, the Monte Carlo study of every estimator.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::pipeline::study::{MonteCarlo, SigmaRow};

/// `study.json`: the σ-table and, when seeds were run, the Monte Carlo study.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StudyFile {
    /// The layout's version ([`crate::results::SCHEMA_VERSION`]).
    #[serde(default = "crate::results::first_schema_version")]
    pub schema_version: u32,
    pub sigma_table: Vec<SigmaRow>,
    pub monte_carlo: Option<MonteCarlo>,
}

impl StudyFile {
    /// Reads a `study.json`.
    pub fn read(path: &Path) -> Result<StudyFile, crate::results::ReadError> {
        let fail = |e: &dyn std::fmt::Display| crate::results::ReadError::new(path, e);
        let text =
            crate::io::fs::read_text_capped(path, crate::core::limits::MAX_TEXT_FILE_BYTES).map_err(|e| fail(&e))?;
        let value = crate::io::unique_keys::json_value(&text).map_err(|e| fail(&e))?;
        if let Some(fault) = crate::results::schema_version_fault(&value) {
            return Err(fail(&fault));
        }
        let file: StudyFile = crate::io::unique_keys::json(&text).map_err(|e| fail(&e))?;
        if let Some(why) = file.monte_carlo.as_ref().and_then(seeds_refusal) {
            return Err(fail(&why));
        }
        Ok(file)
    }
}

/// Why a study's seeds cannot be read as a sample: a seed listed twice (it
/// would count twice in every mean and pairing), or an error that is not a
/// finite distance (negative, infinite or not a number).
fn seeds_refusal(mc: &MonteCarlo) -> Option<String> {
    let mut seen = std::collections::BTreeSet::new();
    for s in &mc.seeds {
        if !seen.insert(s.seed) {
            return Some(format!("monte_carlo.seeds: seed {} is listed twice", s.seed));
        }
        if let Some((method, e)) = s.rms_error_mm.iter().find(|(_, e)| !(e.is_finite() && *e >= 0.0)) {
            return Some(format!(
                "monte_carlo.seeds: seed {}, method `{method}`: rms error {e} mm is not a finite distance (≥ 0)",
                s.seed
            ));
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::StudyFile;

    fn read(text: &str) -> Result<StudyFile, String> {
        let dir = std::env::temp_dir().join(format!("probecal-study-file-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("study.json");
        std::fs::write(&path, text).unwrap();
        StudyFile::read(&path).map_err(|e| e.to_string())
    }

    #[test]
    fn a_study_says_its_schema_version_and_a_newer_one_is_refused() {
        let file = StudyFile {
            schema_version: crate::results::SCHEMA_VERSION,
            sigma_table: Vec::new(),
            monte_carlo: None,
        };
        let text = crate::io::json::to_text(&file).unwrap();
        assert!(text.contains("\"schema_version\": 1"), "{text}");
        assert_eq!(read(&text), Ok(file.clone()));
        let without = text.replacen("\n  \"schema_version\": 1,", "", 1);
        assert_eq!(read(&without).map(|f| f.schema_version), Ok(1));
        let newer = text.replacen("\"schema_version\": 1", "\"schema_version\": 2", 1);
        let e = read(&newer).unwrap_err();
        assert!(e.contains("study.json") && e.contains("newer probecal"), "{e}");
    }
}
