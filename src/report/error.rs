//! Why a run's files could not be written: the one error of the writers and
//! renderers, a leaf every page and writer imports.

use std::path::PathBuf;

use polars::error::PolarsError;

#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("{}: {message}", path.display())]
    Io { path: PathBuf, message: String },
    #[error("{0}")]
    Read(#[from] ReadError),
    #[error("polars: {0}")]
    Polars(#[from] PolarsError),
    #[error("{0}")]
    Json(#[from] crate::io::json::JsonError),
    #[error("{0}")]
    Config(#[from] crate::io::plus::config::ConfigError),
    #[error("template: {0}")]
    Template(String),
    #[error("figure: {0}")]
    Figure(String),
    #[error("report: {0}")]
    Report(String),
    #[error("{}", .0.join("\n"))]
    Index(Vec<String>),
}

impl From<OutputError> for crate::pipeline::error::ReporterError {
    fn from(e: OutputError) -> Self {
        crate::pipeline::error::ReporterError(Box::new(e))
    }
}

pub use crate::results::ReadError;

impl OutputError {
    /// An I/O failure at `path`.
    pub fn io(path: impl Into<PathBuf>, e: impl std::fmt::Display) -> OutputError {
        OutputError::Io {
            path: path.into(),
            message: e.to_string(),
        }
    }

    /// A plotters failure while drawing a figure.
    pub fn figure(e: impl std::fmt::Display) -> OutputError {
        OutputError::Figure(e.to_string())
    }
}

impl From<tera::Error> for OutputError {
    fn from(e: tera::Error) -> OutputError {
        OutputError::Template(error_chain(&e))
    }
}

impl From<serde_json::Error> for OutputError {
    fn from(e: serde_json::Error) -> OutputError {
        OutputError::Report(format!("JSON: {e}"))
    }
}

/// A tera error with its causes, joined.
pub fn error_chain(e: &tera::Error) -> String {
    let mut text = e.to_string();
    let mut source = std::error::Error::source(e);
    while let Some(s) = source {
        text.push_str(&format!(": {s}"));
        source = s.source();
    }
    text
}
