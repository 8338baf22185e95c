//! Why a run's files could not be written: the one error of the writers, a leaf
//! every writer imports.

use std::path::PathBuf;

use polars::error::PolarsError;

#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("{path}: {message}")]
    Io { path: PathBuf, message: String },
    #[error("polars: {0}")]
    Polars(#[from] PolarsError),
    #[error("report: {0}")]
    Report(String),
}
