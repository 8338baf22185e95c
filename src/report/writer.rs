//! The reporter the command line runs experiments with: every dataset's files
//! and provenance, the terminal's lines, and the index with the pages beside it.

use std::path::Path;
use std::time::SystemTime;

use crate::io::plus::result::PlusResult;
use crate::pipeline::error::ReporterError;
use crate::pipeline::experiment::{Reporter, RunFolder};
use crate::pipeline::labels::RunLabels;
use crate::pipeline::labels::TrackedLabels;
use crate::pipeline::record::DatasetRun;
use crate::pipeline::tracked::resolution::TrackedAfter;
use crate::pipeline::tracked::TrackedRun;
use crate::report::error::OutputError;
use crate::report::page::provenance::Provenance;
use crate::report::runs::index::{index_entry, IndexEntry};
use crate::results::summary::RunSummary;

/// Writes each run's folder and the index; prints unless quiet.
pub struct ReportWriter {
    pub quiet: bool,
    pub entries: Vec<IndexEntry>,
    /// The index is left to the caller (`compare` writes it after the
    /// comparison, which it links).
    pub index_later: bool,
}

impl ReportWriter {
    pub fn new(quiet: bool) -> ReportWriter {
        ReportWriter {
            quiet,
            entries: Vec::new(),
            index_later: false,
        }
    }

    /// `compare`'s pages for `runs` (none for no runs, and said where they are
    /// otherwise), then the index, which links them; the index is written even
    /// when the comparison fails.
    pub fn write_comparison(
        &self,
        out: &Path,
        labels: &[RunLabels],
        runs: &[(usize, crate::pipeline::record::DatasetRun)],
        quiet: bool,
    ) -> Result<(), OutputError> {
        let compared = match runs {
            [] => Ok(()),
            _ => crate::report::thesis::compare::write(out, labels, runs, quiet).map(|()| {
                println!("written to {} (compare.md, compare.html, compare.tex)", out.display());
            }),
        };
        let indexed = self.write_index(out);
        compared.and(indexed)
    }

    /// Writes `out/index.html` for the runs reported so far and the pages beside them.
    pub fn write_index(&self, out: &Path) -> Result<(), OutputError> {
        let errors = crate::report::runs::index::write(out, &self.entries);
        if errors.is_empty() {
            Ok(())
        } else {
            Err(OutputError::Index(errors))
        }
    }
}

impl Reporter for ReportWriter {
    fn dataset_started(&mut self, experiment: &str, dataset: &str) {
        if !self.quiet {
            eprintln!("== {experiment} / {dataset}");
        }
    }

    fn dataset_done(
        &mut self,
        labels: &RunLabels,
        run: &DatasetRun,
        folder: &RunFolder<'_>,
        started: SystemTime,
    ) -> Result<(), ReporterError> {
        let (shown, folder) = (folder.final_path, folder.write_to);
        let summary = crate::report::page::write::write_dataset_run(run, labels, folder)?;
        let mut provenance = Provenance::new(
            &labels.manifest_path,
            &labels.manifest_sha256,
            &run.dataset,
            &run.dataset_folder,
            &run.input_files,
            started,
        );
        provenance.seed = run.seed;
        provenance.timings_s = run.timings_s.iter().map(|(k, v)| (k.to_string(), *v)).collect();
        let written = provenance.write(folder).map_err(ReporterError::from);
        if !self.quiet {
            crate::report::console::dataset_run(run, &summary, shown);
        }
        self.entries.push(index_entry(&RunSummary::Camera(Box::new(summary))));
        written
    }

    fn tracked_done(
        &mut self,
        labels: &TrackedLabels,
        run: &TrackedRun,
        after: &TrackedAfter,
        plus: Option<&PlusResult>,
        folder: &RunFolder<'_>,
        started: SystemTime,
    ) -> Result<(), ReporterError> {
        let (shown, folder) = (folder.final_path, folder.write_to);
        let summary = crate::report::tracked::write(run, after, labels, plus, folder)?;
        Provenance::new(
            &labels.manifest_path,
            &labels.manifest_sha256,
            &labels.dataset,
            &labels.calibration_sequence,
            &labels.input_files,
            started,
        )
        .write(folder)?;
        if !self.quiet {
            crate::report::console::tracked_run(run, &summary, shown);
        }
        self.entries.push(index_entry(&RunSummary::Tracked(Box::new(summary))));
        Ok(())
    }

    fn gate_failed(&mut self, line: &str) {
        eprintln!("GATE FAILED: {line}");
    }

    fn finished(&mut self, out: &Path) -> Result<(), ReporterError> {
        if self.index_later {
            return Ok(());
        }
        Ok(self.write_index(out)?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::results::summary::{MeanMax, MethodSummary, Summary, TruthError, TruthSummaryJson};

    fn camera(gated_method: Option<&str>) -> RunSummary {
        RunSummary::Camera(Box::new(Summary {
            experiment: "e".into(),
            dataset: "d".into(),
            truth: Some(TruthSummaryJson {
                corner_error_mm: MeanMax { mean: 0.742, max: 1.0 },
                ..TruthSummaryJson::default()
            }),
            gated_method: gated_method.map(String::from),
            methods: vec![MethodSummary {
                name: "sphere_fit_pose_prior".into(),
                truth: Some(TruthError {
                    corner_error_mm: MeanMax { mean: 0.172, max: 0.3 },
                    rotation_error_deg: 0.16,
                    ..TruthError::default()
                }),
                ..MethodSummary::default()
            }],
            ..Summary::default()
        }))
    }

    #[test]
    fn the_index_shows_the_estimator_the_gates_check_beside_the_reported_one() {
        assert_eq!(
            index_entry(&camera(Some("sphere_fit_pose_prior"))).truth_corner,
            "0.742; sphere_fit_pose_prior 0.172"
        );
        assert_eq!(index_entry(&camera(None)).truth_corner, "0.742");
        // A gate naming an estimator the run does not have shows the reported one alone.
        assert_eq!(index_entry(&camera(Some("lmeds"))).truth_corner, "0.742");
    }
}
