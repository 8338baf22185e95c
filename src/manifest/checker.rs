//! Collects a manifest's problems with their field paths and lines, and the
//! checks the sections share (finite, positive, ranges, files that exist).

use crate::spec::rig::Board;
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

use super::*;
use crate::core::limits::{MAX_BOARD_CORNERS, MAX_YAML_DEPTH};
use crate::io::yaml_limits::too_deep;

pub(crate) struct Checker<'a> {
    pub(crate) file: &'a Path,
    pub(crate) text: &'a str,
    pub(crate) errors: Vec<ManifestError>,
}

/// Folder names a run writes beside the experiments' folders in `--out`.
pub const RESERVED_NAMES: [&str; 4] = ["study", "runs", "ablation", "design"];

/// Longest experiment or dataset name.
pub const MAX_NAME_LEN: usize = 100;

/// Why a name cannot name a folder of the run's output, if it cannot: only
/// letters, digits, `_` and `-` (no path, no dots), not reserved, not too long.
pub fn name_fault(name: &str) -> Option<String> {
    if name.is_empty() || name.len() > MAX_NAME_LEN {
        return Some(format!("must be 1 to {MAX_NAME_LEN} characters long"));
    }
    if !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-') {
        return Some(format!(
            "`{name}` must use only letters, digits, `_` and `-` (it names a folder of the run's output)"
        ));
    }
    if RESERVED_NAMES.contains(&name) {
        return Some(format!(
            "`{name}` is reserved (the output folder's `{name}/` holds other results)"
        ));
    }
    None
}

impl Checker<'_> {
    /// A name of a folder of the run's output (see [`name_fault`]).
    pub(crate) fn name(&mut self, field: &str, name: &str) {
        if let Some(message) = name_fault(name) {
            self.fail(field, message);
        }
    }

    pub(crate) fn fail(&mut self, field: &str, message: impl Into<String>) {
        self.errors.push(ManifestError {
            file: self.file.to_path_buf(),
            field: field.to_string(),
            line: locate::line_of(self.text, field),
            message: message.into(),
        });
    }

    pub(crate) fn positive(&mut self, field: &str, value: f64) {
        if !(value.is_finite() && value > 0.0) {
            self.fail(
                field,
                format!("must be a positive number of millimetres/units, got {value}"),
            );
        }
    }

    pub(crate) fn at_least(&mut self, field: &str, value: f64, min: f64) {
        if !(value.is_finite() && value >= min) {
            self.fail(field, format!("must be at least {min}, got {value}"));
        }
    }

    pub(crate) fn finite(&mut self, field: &str, values: &[f64]) {
        if values.iter().any(|v| !v.is_finite()) {
            self.fail(field, "must hold finite numbers");
        }
    }

    pub(crate) fn range(&mut self, field: &str, range: [f64; 2]) {
        if !(range[0].is_finite() && range[1].is_finite() && range[0] > 0.0 && range[0] < range[1]) {
            self.fail(
                field,
                format!(
                    "must be [low, high] with 0 < low < high, got [{}, {}]",
                    range[0], range[1]
                ),
            );
        }
    }

    pub(crate) fn board(&mut self, field: &str, board: &Board) {
        if board.inner_corners[0] < 2 || board.inner_corners[1] < 2 {
            self.fail(&format!("{field}.inner_corners"), "needs at least 2x2 inner corners");
        }
        if board.inner_corners.iter().any(|&n| n > MAX_BOARD_CORNERS) {
            self.fail(
                &format!("{field}.inner_corners"),
                format!("at most {MAX_BOARD_CORNERS} inner corners per side"),
            );
        }
        self.positive(&format!("{field}.square_mm"), board.square_mm);
    }

    pub(crate) fn existing(&mut self, field: &str, base: &Path, value: &str, want_dir: bool) -> PathBuf {
        let path = base.join(value);
        let ok = if want_dir { path.is_dir() } else { path.is_file() };
        if !ok {
            let what = if want_dir { "folder" } else { "file" };
            self.fail(field, format!("{what} `{}` does not exist", path.display()));
        }
        path
    }
}

pub(crate) fn sha256_hex(bytes: &[u8]) -> String {
    let digest = Sha256::digest(bytes);
    digest.iter().map(|b| format!("{b:02x}")).collect()
}

/// serde_yaml's message without the position and path it repeats (they are shown apart).
fn strip_position<'a>(message: &'a str, field: &str) -> &'a str {
    let message = match message.find(" at line ") {
        Some(i) => &message[..i],
        None => message,
    };
    let parent = field.rsplit_once('.').map(|(p, _)| p).unwrap_or("");
    [field, parent]
        .iter()
        .filter(|p| !p.is_empty())
        .find_map(|p| message.strip_prefix(&format!("{p}: ")))
        .unwrap_or(message)
}

/// Deserialises YAML into `T`, locating an error by file, field path and line.
pub(crate) fn deserialize_located<T: serde::de::DeserializeOwned>(
    path: &Path,
    text: &str,
) -> Result<T, ManifestErrors> {
    if let Some((line, depth)) = too_deep(text) {
        return Err(ManifestErrors(vec![ManifestError {
            file: path.to_path_buf(),
            field: String::new(),
            line: Some(line),
            message: format!("nested {depth} levels deep; a manifest nests at most {MAX_YAML_DEPTH}"),
        }]));
    }
    let deserializer = serde_yaml::Deserializer::from_str(text);
    serde_path_to_error::deserialize(deserializer).map_err(|e| {
        let field = e.path().to_string();
        // serde_path_to_error writes `?` for a segment it could not name (syntax errors).
        let field = field
            .split('.')
            .take_while(|s| *s != "?" && !s.is_empty())
            .collect::<Vec<_>>()
            .join(".");
        let inner = e.inner();
        let line = inner
            .location()
            .map(|l| l.line())
            .or_else(|| locate::line_of(text, &field));
        ManifestErrors(vec![ManifestError {
            file: path.to_path_buf(),
            message: strip_position(&inner.to_string(), &field).to_string(),
            field,
            line,
        }])
    })
}
