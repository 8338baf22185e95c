//! The tables of the regenerated results chapter: rows of formatted cells
//! under column groups, and the runs they are read from.

use std::path::Path;

use serde::Serialize;

use crate::results::summary::{RunSummary, Summary};

/// A table row: a label and its cells (already formatted).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Row {
    pub label: String,
    pub cells: Vec<String>,
}

#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Table {
    pub id: String,
    pub title: String,
    pub note: String,
    /// Column groups (e.g. x, y, z or the cut-offs), each with the sub-columns `sub`.
    pub groups: Vec<String>,
    pub sub: Vec<String>,
    /// Row blocks (e.g. one per axis); a block's label spans its rows.
    pub blocks: Vec<(String, Vec<Row>)>,
    /// LaTeX column spans of the groups (`3-4`), after the label columns.
    pub spans: Vec<String>,
    /// Each group's second sub-column is the thesis's value (shown grey).
    pub thesis_columns: bool,
}

impl Table {
    pub fn with_spans(mut self) -> Table {
        let lead = if self.blocks.len() > 1 { 2 } else { 1 };
        let n = self.sub.len();
        self.spans = (0..self.groups.len())
            .map(|g| format!("{}-{}", lead + g * n + 1, lead + (g + 1) * n))
            .collect();
        self
    }
}

pub fn fmt(v: Option<f64>) -> String {
    match v {
        Some(v) if v.is_finite() => format!("{v:.3}"),
        _ => "—".into(),
    }
}

/// A camera run's summary under `root`, if it is there and reads.
pub fn summary(root: &Path, experiment: &str, dataset: &str) -> Option<Summary> {
    match RunSummary::read(&root.join(experiment).join(dataset).join("summary.json")).ok()? {
        RunSummary::Camera(s) => Some(*s),
        RunSummary::Tracked(_) => None,
    }
}
