//! The types a PLUS device set's readers share: the error that names the file
//! and line, and a `CoordinateDefinitions` transform (kept apart from
//! the reader, `config.rs`, so that the size and value limits of `xml_limits.rs`
//! can name them without importing the reader).

use std::path::PathBuf;

use nalgebra::Matrix4;

/// Why a configuration file could not be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{}{}: {message}", path.display(), line.map(|l| format!(":{l}")).unwrap_or_default())]
pub struct ConfigError {
    pub path: PathBuf,
    pub line: Option<usize>,
    pub message: String,
}

/// A `CoordinateDefinitions/Transform`: `to_T_from`, a general 4x4 matrix.
#[derive(Debug, Clone, PartialEq)]
pub struct FixedTransform {
    pub from: String,
    pub to: String,
    pub matrix: Matrix4<f64>,
    pub line: usize,
}
