//! `probecal check`: compares runs with their accuracy baselines (or, with
//! `--update`, writes the baselines), prints the table and every failure; 0 no
//! regression, 1 a regression, a failed gate or a baseline not written, 2 no
//! runs or no baseline to compare with.

use std::path::{Path, PathBuf};

use super::failure::Failure;
use crate::report::runs::check::{compare, failed_gates, find_summaries, table, update, Verdict};

pub fn command(runs: &[PathBuf], baselines: &Path, write_baselines: bool, allow_drop: bool) -> Result<(), Failure> {
    let summaries = find_summaries(runs).map_err(Failure::bad_input)?;
    if write_baselines {
        for path in update(&summaries, baselines, allow_drop).map_err(Failure::failed)? {
            println!("baseline written: {}", path.display());
        }
        return Ok(());
    }
    let comparisons = compare(&summaries, baselines).map_err(Failure::bad_input)?;
    print!("{}", table(&comparisons));
    let mut regressed = 0;
    for c in &comparisons {
        if matches!(c.verdict, Verdict::Regressed | Verdict::Missing) {
            regressed += 1;
            eprintln!(
                "{}: {} / {}: {} is {} (baseline {:.3} + tolerance {:.3}); look at {}",
                c.verdict.label(),
                c.experiment,
                c.dataset,
                c.metric,
                c.current.map(|v| format!("{v:.3}")).unwrap_or_else(|| "missing".into()),
                c.baseline.value,
                c.baseline.tolerance,
                c.report.display()
            );
        }
    }
    let gates = failed_gates(&summaries);
    for gate in &gates {
        eprintln!("GATE FAILED: {gate}");
    }
    if regressed > 0 || !gates.is_empty() {
        return Err(Failure::failed(format!(
            "{regressed} of {} metrics regressed or missing, {} gates failed",
            comparisons.len(),
            gates.len()
        )));
    }
    println!(
        "{} metrics of {} runs: no regression",
        comparisons.len(),
        summaries.len()
    );
    Ok(())
}
