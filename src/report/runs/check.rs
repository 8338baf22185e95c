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

use serde::Serialize;

pub use crate::report::runs::baseline::{baseline_path, metrics, Baseline, Metric};
use crate::results::summary::RunSummary;

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
pub struct FoundSummary {
    pub path: PathBuf,
    pub experiment: String,
    pub dataset: String,
    pub summary: RunSummary,
}

/// Finds `summary.json` files: the paths themselves, or `*/*/summary.json` under folders.
pub fn find_summaries(inputs: &[PathBuf]) -> Result<Vec<FoundSummary>, CheckError> {
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
            // Dot folders are a run's unfinished or failed writes, never results.
            let hidden = experiment
                .file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with('.'));
            if !experiment.is_dir() || hidden {
                continue;
            }
            for dataset in read(&experiment)? {
                let dataset = dataset
                    .map_err(|e| CheckError::Read {
                        path: experiment.clone(),
                        message: e.to_string(),
                    })?
                    .path();
                if crate::results::is_not_a_run(&dataset.join("summary.json")) {
                    // A volume reconstruction or a refinement from the images, not a calibration run.
                    continue;
                }
                if dataset.join("summary.json").is_file() {
                    // A run writes these with its summary; without them the folder is not a
                    // complete run, whatever its summary says.
                    if let Some(missing) = ["frames.csv", "report.html"]
                        .iter()
                        .find(|f| !dataset.join(f).is_file())
                    {
                        return Err(CheckError::Read {
                            path: dataset.clone(),
                            message: format!("an incomplete run folder: it has summary.json but no {missing}"),
                        });
                    }
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
            let summary = RunSummary::read(&path).map_err(|e| CheckError::Read {
                path: path.clone(),
                message: e.message,
            })?;
            // The experiment's name picks its baseline file: the reader has
            // refused any but a plain name.
            Ok(FoundSummary {
                experiment: summary.experiment().to_string(),
                dataset: summary.dataset().to_string(),
                path: path.clone(),
                summary,
            })
        })
        .collect()
}

/// Reads the baseline file of `experiment`.
pub fn load_baseline(path: &Path, experiment: &str) -> Result<Baseline, CheckError> {
    let text = crate::io::yaml_limits::read(path, "a baseline").map_err(|e| CheckError::Read {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    let baseline: Baseline = serde_yaml::from_str(&text).map_err(|e| CheckError::Read {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    let bad = |message: String| CheckError::Read {
        path: path.to_path_buf(),
        message,
    };
    if baseline.experiment != experiment {
        return Err(bad(format!(
            "field `experiment` names `{}`, but this is the baseline of `{experiment}`; a baseline judges only its own experiment",
            baseline.experiment
        )));
    }
    if baseline.datasets.is_empty() {
        return Err(bad(
            "holds no dataset: a baseline that judges nothing passes everything".into(),
        ));
    }
    for (dataset, metrics) in &baseline.datasets {
        if metrics.is_empty() {
            return Err(bad(format!("dataset `{dataset}` has no metric")));
        }
        for (name, m) in metrics {
            if !m.value.is_finite() {
                return Err(bad(format!(
                    "{dataset}.{name}.value is {}, not a finite number",
                    m.value
                )));
            }
            if !(m.tolerance.is_finite() && m.tolerance >= 0.0) {
                return Err(bad(format!(
                    "{dataset}.{name}.tolerance is {}, not a finite number of at least 0",
                    m.tolerance
                )));
            }
        }
    }
    Ok(baseline)
}

/// Writes the baselines of the given runs (one file per experiment), replacing the
/// datasets they contain and keeping the others.
pub fn update(runs: &[FoundSummary], baselines: &Path, allow_drop: bool) -> Result<Vec<PathBuf>, CheckError> {
    let mut by_experiment: BTreeMap<&str, Vec<&FoundSummary>> = BTreeMap::new();
    for r in runs {
        by_experiment.entry(&r.experiment).or_default().push(r);
    }
    let mut written = Vec::new();
    for (experiment, runs) in by_experiment {
        let path = baseline_path(baselines, experiment);
        let mut baseline = if path.is_file() {
            load_baseline(&path, experiment)?
        } else {
            Baseline {
                experiment: experiment.to_string(),
                datasets: BTreeMap::new(),
            }
        };
        for r in runs {
            // Four decimals keep the file readable; the tolerances are far coarser.
            let round = |v: f64| (v * 1e4).round() / 1e4;
            let m = metrics(&r.summary)
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
            let m: BTreeMap<String, Metric> = m;
            if let Some(previous) = baseline.datasets.get(&r.dataset) {
                let dropped: Vec<&String> = previous.keys().filter(|k| !m.contains_key(*k)).collect();
                if !dropped.is_empty() && !allow_drop {
                    return Err(CheckError::Write {
                        path: path.clone(),
                        message: format!(
                            "the run {} has no {}, which the baseline of `{}` judges; pass --allow-drop to drop {}",
                            r.path.display(),
                            dropped.iter().map(|k| format!("`{k}`")).collect::<Vec<_>>().join(", "),
                            r.dataset,
                            if dropped.len() == 1 { "it" } else { "them" }
                        ),
                    });
                }
            }
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
pub fn compare(runs: &[FoundSummary], baselines: &Path) -> Result<Vec<Comparison>, CheckError> {
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
        let baseline = load_baseline(&path, &r.experiment)?;
        let Some(expected) = baseline.datasets.get(&r.dataset) else {
            return Err(CheckError::Read {
                path,
                message: format!("has no dataset `{}`; add it with `probecal check --update`", r.dataset),
            });
        };
        let current = metrics(&r.summary);
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
pub fn failed_gates(runs: &[FoundSummary]) -> Vec<String> {
    let mut out = Vec::new();
    for r in runs {
        for g in r.summary.gates().iter().filter(|g| !g.passed) {
            out.push(format!(
                "{} / {}: gate {} = {} exceeds {}",
                r.experiment,
                r.dataset,
                g.name,
                g.value.map(|v| format!("{v:.3}")).unwrap_or_else(|| "missing".into()),
                serde_json::json!(g.limit)
            ));
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
    use crate::evaluate::AxisStats;
    use crate::pipeline::record::GateResult;
    use crate::results::summary::{
        BreSummary, FrameCounts, MeanMax, MethodSummary, Summary, TruthError, TruthSummaryJson,
    };

    fn summary(corner: f64, rejected: usize) -> RunSummary {
        let axis = |mean| AxisStats {
            mean,
            ..AxisStats::default()
        };
        RunSummary::Camera(Box::new(Summary {
            experiment: "e".into(),
            dataset: "d".into(),
            frames: FrameCounts {
                rejected,
                ..FrameCounts::default()
            },
            bre_mm: Some(BreSummary {
                x: axis(0.2),
                y: axis(0.3),
                z: axis(0.4),
            }),
            truth: Some(TruthSummaryJson {
                corner_error_mm: MeanMax { mean: corner, max: 0.0 },
                rotation_error_deg: 0.1,
                ..TruthSummaryJson::default()
            }),
            gates: vec![GateResult {
                name: "truth_corner_error_mm".into(),
                limit: 1.0,
                value: Some(corner),
                passed: corner <= 1.0,
            }],
            ..Summary::default()
        }))
    }

    #[test]
    fn every_estimator_of_a_run_is_judged_not_only_the_reported_one() {
        let dir = std::env::temp_dir().join(format!("probecal-check-methods-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let run = |fit_mm: f64| {
            let mut summary = summary(0.3, 0);
            if let RunSummary::Camera(s) = &mut summary {
                s.methods = vec![MethodSummary {
                    name: "sphere_fit".into(),
                    truth: Some(TruthError {
                        corner_error_mm: MeanMax { mean: fit_mm, max: 0.0 },
                        rotation_error_deg: 0.05,
                        ..TruthError::default()
                    }),
                    ..MethodSummary::default()
                }];
            }
            FoundSummary {
                path: dir.join("run/e/d/summary.json"),
                experiment: "e".into(),
                dataset: "d".into(),
                summary,
            }
        };
        update(&[run(0.15)], &dir, false).unwrap();
        let verdict = |fit_mm| {
            compare(&[run(fit_mm)], &dir)
                .unwrap()
                .into_iter()
                .find(|c| c.metric == "truth_corner_error_mm (sphere_fit)")
                .map(|c| c.verdict)
        };
        assert_eq!(verdict(0.16), Some(Verdict::WithinNoise));
        // The reported row is unchanged; only the other estimator got worse.
        assert_eq!(verdict(0.25), Some(Verdict::Regressed));
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn verdicts_follow_the_tolerance() {
        let dir = std::env::temp_dir().join(format!("probecal-check-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let run = |corner, rejected| FoundSummary {
            path: dir.join("run/e/d/summary.json"),
            experiment: "e".into(),
            dataset: "d".into(),
            summary: summary(corner, rejected),
        };
        update(&[run(0.30, 1)], &dir, false).unwrap();
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
            &[FoundSummary {
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
        // A run without a metric the baseline judges does not silently drop it.
        let mut fewer = run(0.3, 1);
        if let RunSummary::Camera(s) = &mut fewer.summary {
            s.truth = None;
        }
        let refused = update(std::slice::from_ref(&fewer), &dir, false).unwrap_err();
        assert!(refused.to_string().contains("pass --allow-drop"), "{refused}");
        update(&[fewer], &dir, true).unwrap();
        // Baselines that judge nothing, or with numbers that are not numbers, are refused.
        for (text, expect) in [
            ("experiment: e\ndatasets: {}\n", "holds no dataset"),
            ("experiment: e\ndatasets: {d: {}}\n", "dataset `d` has no metric"),
            (
                "experiment: e\ndatasets: {d: {m: {value: .nan, tolerance: 0.1}}}\n",
                "d.m.value is NaN",
            ),
            (
                "experiment: e\ndatasets: {d: {m: {value: 1.0, tolerance: -0.1}}}\n",
                "d.m.tolerance is -0.1",
            ),
            // A key given twice, at either level, and another experiment's file.
            (
                "experiment: e\ndatasets:\n  d:\n    m: {value: 1.0, tolerance: 0.1}\n  d:\n    m: {value: 9.0, tolerance: 0.1}\n",
                "`d` is given twice",
            ),
            (
                "experiment: e\ndatasets: {d: {m: {value: 1.0, tolerance: 0.1}, m: {value: 9.0, tolerance: 0.1}}}\n",
                "`m` is given twice",
            ),
            (
                "experiment: other\ndatasets: {d: {m: {value: 1.0, tolerance: 0.1}}}\n",
                "field `experiment` names `other`, but this is the baseline of `e`",
            ),
        ] {
            let path = dir.join("bad.yaml");
            std::fs::write(&path, text).unwrap();
            let e = load_baseline(&path, "e").unwrap_err().to_string();
            assert!(e.contains(expect), "{e}");
        }
        std::fs::remove_dir_all(&dir).ok();
    }
}
