//! `probecal check`: compares runs with committed baselines and fails on accuracy
//! regressions.
//!
//! A baseline is a small YAML file per experiment (`<experiment>.yaml` in the
//! baselines folder) holding, per dataset, the accuracy figures that matter, each
//! with its value and the tolerance a later run may differ by. Every metric is
//! "lower is better": a run is *regressed* on a metric above `value + tolerance`,
//! *improved* below `value − tolerance`, and *within noise* otherwise. The
//! tolerances come from the manifest (`thresholds.regression`) when the baseline
//! is written with `--update`. Absolute gates recorded in the run's summary
//! (`thresholds.gates`) are checked too.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use serde_json::Value;

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
    /// dataset → metric name → metric.
    pub datasets: BTreeMap<String, BTreeMap<String, Metric>>,
}

/// The outcome of one comparison.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    Improved,
    WithinNoise,
    Regressed,
    /// The baseline has the metric, the run does not.
    Missing,
}

impl Verdict {
    pub fn label(self) -> &'static str {
        match self {
            Verdict::Improved => "improved",
            Verdict::WithinNoise => "within noise",
            Verdict::Regressed => "REGRESSED",
            Verdict::Missing => "MISSING",
        }
    }
}

/// One line of the comparison table.
#[derive(Debug, Clone, PartialEq)]
pub struct Comparison {
    pub experiment: String,
    pub dataset: String,
    pub metric: String,
    pub baseline: Metric,
    pub current: Option<f64>,
    pub verdict: Verdict,
    /// Where to look (the run's page).
    pub report: PathBuf,
}

#[derive(Debug, thiserror::Error)]
pub enum CheckError {
    #[error("{path}: {message}")]
    Read { path: PathBuf, message: String },
    #[error("no run summaries (*/*/summary.json) found under {0}")]
    NoRuns(PathBuf),
    #[error(
        "no baseline for experiment `{experiment}`: {path} must exist before comparison; \
         write it from a run you trust with `probecal check --update {run}`"
    )]
    MissingBaseline {
        experiment: String,
        path: PathBuf,
        run: PathBuf,
    },
    #[error("{path}: cannot write: {message}")]
    Write { path: PathBuf, message: String },
}

/// A run summary found on disk.
#[derive(Debug, Clone)]
pub struct RunSummary {
    pub path: PathBuf,
    pub experiment: String,
    pub dataset: String,
    pub json: Value,
}

/// Finds `summary.json` files: the paths themselves, or `*/*/summary.json` under folders.
pub fn find_summaries(inputs: &[PathBuf]) -> Result<Vec<RunSummary>, CheckError> {
    let mut files = Vec::new();
    for input in inputs {
        if input.is_file() {
            files.push(input.clone());
            continue;
        }
        let read = |p: &Path| {
            std::fs::read_dir(p).map_err(|e| CheckError::Read {
                path: p.to_path_buf(),
                message: e.to_string(),
            })
        };
        let mut found = Vec::new();
        for experiment in read(input)? {
            let experiment = experiment
                .map_err(|e| CheckError::Read {
                    path: input.clone(),
                    message: e.to_string(),
                })?
                .path();
            if !experiment.is_dir() {
                continue;
            }
            for dataset in read(&experiment)? {
                let dataset = dataset
                    .map_err(|e| CheckError::Read {
                        path: experiment.clone(),
                        message: e.to_string(),
                    })?
                    .path();
                if dataset.join("summary.json").is_file() {
                    found.push(dataset.join("summary.json"));
                }
            }
        }
        if found.is_empty() {
            return Err(CheckError::NoRuns(input.clone()));
        }
        found.sort();
        files.extend(found);
    }
    files
        .into_iter()
        .map(|path| {
            let text = std::fs::read_to_string(&path).map_err(|e| CheckError::Read {
                path: path.clone(),
                message: e.to_string(),
            })?;
            let json: Value = serde_json::from_str(&text).map_err(|e| CheckError::Read {
                path: path.clone(),
                message: e.to_string(),
            })?;
            let field = |k: &str| {
                json[k].as_str().map(str::to_string).ok_or_else(|| CheckError::Read {
                    path: path.clone(),
                    message: format!("field `{k}` is missing: not a probecal summary"),
                })
            };
            Ok(RunSummary {
                experiment: field("experiment")?,
                dataset: field("dataset")?,
                path: path.clone(),
                json,
            })
        })
        .collect()
}

/// The metrics a run is judged on, from its summary (lower is better for each).
pub fn metrics(summary: &Value) -> BTreeMap<String, (f64, f64)> {
    let tolerances = &summary["regression_tolerances"];
    let tol = |k: &str, default: f64| tolerances[k].as_f64().unwrap_or(default);
    let mut out = BTreeMap::new();
    for axis in ["x", "y", "z"] {
        if let Some(v) = summary["bre_mm"][axis]["mean"].as_f64() {
            out.insert(format!("bre_mean_{axis}_mm"), (v, tol("bre_mean_mm", 0.05)));
        }
    }
    if let Some(v) = summary["truth"]["corner_error_mm"]["mean"].as_f64() {
        out.insert("truth_corner_error_mm".into(), (v, tol("truth_corner_error_mm", 0.05)));
    }
    if let Some(v) = summary["truth"]["rotation_error_deg"].as_f64() {
        out.insert(
            "truth_rotation_error_deg".into(),
            (v, tol("truth_rotation_error_deg", 0.05)),
        );
    }
    if let Some(v) = summary["frames"]["rejected"].as_f64() {
        out.insert("frames_rejected".into(), (v, tol("frames_rejected", 2.0)));
    }
    if let Some(v) = summary["validation"]["pre3d_mm"]["mean"].as_f64() {
        out.insert("pre3d_mean_mm".into(), (v, tol("pre3d_mm", 0.02)));
    }
    out
}

pub fn baseline_path(baselines: &Path, experiment: &str) -> PathBuf {
    baselines.join(format!("{experiment}.yaml"))
}

/// Reads a baseline file.
pub fn load_baseline(path: &Path) -> Result<Baseline, CheckError> {
    let text = std::fs::read_to_string(path).map_err(|e| CheckError::Read {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    serde_yaml::from_str(&text).map_err(|e| CheckError::Read {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}

/// Writes the baselines of the given runs (one file per experiment), replacing the
/// datasets they contain and keeping the others.
pub fn update(runs: &[RunSummary], baselines: &Path) -> Result<Vec<PathBuf>, CheckError> {
    let mut by_experiment: BTreeMap<&str, Vec<&RunSummary>> = BTreeMap::new();
    for r in runs {
        by_experiment.entry(&r.experiment).or_default().push(r);
    }
    let mut written = Vec::new();
    for (experiment, runs) in by_experiment {
        let path = baseline_path(baselines, experiment);
        let mut baseline = if path.is_file() {
            load_baseline(&path)?
        } else {
            Baseline {
                experiment: experiment.to_string(),
                datasets: BTreeMap::new(),
            }
        };
        for r in runs {
            // Four decimals keep the file readable; the tolerances are far coarser.
            let round = |v: f64| (v * 1e4).round() / 1e4;
            let m = metrics(&r.json)
                .into_iter()
                .map(|(k, (value, tolerance))| {
                    (
                        k,
                        Metric {
                            value: round(value),
                            tolerance,
                        },
                    )
                })
                .collect();
            baseline.datasets.insert(r.dataset.clone(), m);
        }
        let body = serde_yaml::to_string(&baseline).map_err(|e| CheckError::Write {
            path: path.clone(),
            message: e.to_string(),
        })?;
        let text = format!(
            "# Accuracy baseline of experiment `{experiment}`, written by `probecal check --update`.\n\
             # Lower is better for every metric; a run regresses above value + tolerance.\n{body}"
        );
        crate::io::fs::write_atomic(&path, text.as_bytes()).map_err(|e| CheckError::Write {
            path: path.clone(),
            message: e.to_string(),
        })?;
        written.push(path);
    }
    Ok(written)
}

/// Compares runs with their baselines.
pub fn compare(runs: &[RunSummary], baselines: &Path) -> Result<Vec<Comparison>, CheckError> {
    let mut out = Vec::new();
    for r in runs {
        let path = baseline_path(baselines, &r.experiment);
        if !path.is_file() {
            let run = r
                .path
                .parent()
                .and_then(Path::parent)
                .and_then(Path::parent)
                .unwrap_or(Path::new("."))
                .to_path_buf();
            return Err(CheckError::MissingBaseline {
                experiment: r.experiment.clone(),
                path,
                run,
            });
        }
        let baseline = load_baseline(&path)?;
        let Some(expected) = baseline.datasets.get(&r.dataset) else {
            return Err(CheckError::Read {
                path,
                message: format!("has no dataset `{}`; add it with `probecal check --update`", r.dataset),
            });
        };
        let current = metrics(&r.json);
        for (name, metric) in expected {
            let value = current.get(name).map(|c| c.0);
            let verdict = match value {
                None => Verdict::Missing,
                Some(v) if v > metric.value + metric.tolerance => Verdict::Regressed,
                Some(v) if v < metric.value - metric.tolerance => Verdict::Improved,
                Some(_) => Verdict::WithinNoise,
            };
            out.push(Comparison {
                experiment: r.experiment.clone(),
                dataset: r.dataset.clone(),
                metric: name.clone(),
                baseline: *metric,
                current: value,
                verdict,
                report: r.path.with_file_name("report.html"),
            });
        }
    }
    Ok(out)
}

/// Failed absolute gates recorded in the summaries: (run, gate name, value, limit).
pub fn failed_gates(runs: &[RunSummary]) -> Vec<String> {
    let mut out = Vec::new();
    for r in runs {
        for g in r.json["gates"].as_array().into_iter().flatten() {
            if g["passed"] != Value::Bool(true) {
                out.push(format!(
                    "{} / {}: gate {} = {} exceeds {}",
                    r.experiment,
                    r.dataset,
                    g["name"].as_str().unwrap_or("?"),
                    g["value"]
                        .as_f64()
                        .map(|v| format!("{v:.3}"))
                        .unwrap_or_else(|| "missing".into()),
                    g["limit"]
                ));
            }
        }
    }
    out
}

/// The comparison as a table.
pub fn table(comparisons: &[Comparison]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{:<44} {:<26} {:>9} {:>9} {:>9} {:>9}  verdict",
        "experiment / dataset", "metric", "baseline", "current", "delta", "tolerance"
    );
    for c in comparisons {
        let (current, delta) = match c.current {
            Some(v) => (format!("{v:.3}"), format!("{:+.3}", v - c.baseline.value)),
            None => ("—".into(), "—".into()),
        };
        let _ = writeln!(
            s,
            "{:<44} {:<26} {:>9.3} {:>9} {:>9} {:>9.3}  {}",
            format!("{} / {}", c.experiment, c.dataset),
            c.metric,
            c.baseline.value,
            current,
            delta,
            c.baseline.tolerance,
            c.verdict.label()
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn summary(corner: f64, rejected: u64) -> Value {
        json!({
            "experiment": "e", "dataset": "d",
            "frames": {"rejected": rejected},
            "bre_mm": {"x": {"mean": 0.2}, "y": {"mean": 0.3}, "z": {"mean": 0.4}},
            "truth": {"corner_error_mm": {"mean": corner}, "rotation_error_deg": 0.1},
            "regression_tolerances": {"truth_corner_error_mm": 0.05},
            "gates": [{"name": "truth_corner_error_mm", "limit": 1.0, "value": corner, "passed": corner <= 1.0}]
        })
    }

    #[test]
    fn verdicts_follow_the_tolerance() {
        let dir = std::env::temp_dir().join(format!("probecal-check-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let run = |corner, rejected| RunSummary {
            path: dir.join("run/e/d/summary.json"),
            experiment: "e".into(),
            dataset: "d".into(),
            json: summary(corner, rejected),
        };
        update(&[run(0.30, 1)], &dir).unwrap();
        let verdict = |corner, rejected| {
            let c = compare(&[run(corner, rejected)], &dir).unwrap();
            let m = c.iter().find(|c| c.metric == "truth_corner_error_mm").unwrap();
            let f = c.iter().find(|c| c.metric == "frames_rejected").unwrap();
            (m.verdict, f.verdict)
        };
        assert_eq!(verdict(0.30, 1), (Verdict::WithinNoise, Verdict::WithinNoise));
        assert_eq!(verdict(0.34, 3), (Verdict::WithinNoise, Verdict::WithinNoise));
        assert_eq!(verdict(0.36, 4), (Verdict::Regressed, Verdict::Regressed));
        assert_eq!(verdict(0.20, 1), (Verdict::Improved, Verdict::WithinNoise));
        let missing = compare(
            &[RunSummary {
                experiment: "other".into(),
                ..run(0.3, 1)
            }],
            &dir,
        )
        .unwrap_err();
        assert!(
            missing.to_string().contains("must exist before comparison"),
            "{missing}"
        );
        assert_eq!(failed_gates(&[run(1.2, 0)]).len(), 1);
        assert!(failed_gates(&[run(0.3, 0)]).is_empty());
        std::fs::remove_dir_all(&dir).ok();
    }
}
