//! A baseline file and what a run is judged on: the accuracy figures of each
//! dataset of an experiment (`<experiment>.yaml` in the baselines folder), each
//! with its value and the tolerance a later run may differ by, lower is better
//! for all of them. `probecal check` compares runs
//! with them and writes them.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::results::summary::RunSummary;

/// One metric of a baseline.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Metric {
    pub value: f64,
    pub tolerance: f64,
}

/// A baseline file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Baseline {
    pub experiment: String,
    /// dataset → metric name → metric (each given once).
    #[serde(deserialize_with = "crate::io::unique_keys::map_of_maps")]
    pub datasets: BTreeMap<String, BTreeMap<String, Metric>>,
}

/// The metrics a run is judged on, from its summary (lower is better for each):
/// name → (value, tolerance).
pub fn metrics(summary: &RunSummary) -> BTreeMap<String, (f64, f64)> {
    let mut out = BTreeMap::new();
    match summary {
        RunSummary::Camera(s) => {
            let tol = &s.regression_tolerances;
            if let Some(bre) = &s.bre_mm {
                for (axis, stats) in ["x", "y", "z"].iter().zip(bre.axes()) {
                    out.insert(format!("bre_mean_{axis}_mm"), (stats.mean, tol.bre_mean_mm));
                }
            }
            if let Some(t) = &s.truth {
                out.insert(
                    "truth_corner_error_mm".into(),
                    (t.corner_error_mm.mean, tol.truth_corner_error_mm),
                );
                out.insert(
                    "truth_rotation_error_deg".into(),
                    (t.rotation_error_deg, tol.truth_rotation_error_deg),
                );
            }
            // Every estimator the run compares, not only the reported one: a
            // phantom's own method (a gate's `method`) regresses like the rest.
            for m in &s.methods {
                if let Some(t) = &m.truth {
                    out.insert(
                        format!("truth_corner_error_mm ({})", m.name),
                        (t.corner_error_mm.mean, tol.truth_corner_error_mm),
                    );
                    out.insert(
                        format!("truth_rotation_error_deg ({})", m.name),
                        (t.rotation_error_deg, tol.truth_rotation_error_deg),
                    );
                }
            }
            out.insert(
                "frames_rejected".into(),
                (s.frames.rejected as f64, tol.frames_rejected),
            );
        }
        RunSummary::Tracked(s) => {
            let tol = &s.regression_tolerances;
            out.insert(
                "frames_rejected".into(),
                (s.frames.rejected as f64, tol.frames_rejected),
            );
            if let Some(pre3d) = &s.validation.pre3d_mm {
                out.insert("pre3d_mean_mm".into(), (pre3d.mean, tol.pre3d_mm));
            }
        }
    }
    out
}

pub fn baseline_path(baselines: &Path, experiment: &str) -> PathBuf {
    baselines.join(format!("{experiment}.yaml"))
}
