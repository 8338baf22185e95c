//! `probecal resolve`: solves a run again from its own folder and prints the
//! matrix and its largest difference from the reported one; 0 when it is the
//! same calibration, 1 when not or when the folder cannot be solved again.

use std::path::Path;

use super::failure::Failure;
use crate::report::runs::resolve::{resolve, SAME_CALIBRATION};

pub fn command(run_folder: &Path) -> Result<(), Failure> {
    let (difference, again) = resolve(run_folder).map_err(Failure::failed)?;
    println!("marker_T_image solved again from {}:", run_folder.display());
    for row in again {
        println!("  {:>14.9} {:>14.9} {:>14.9} {:>14.9}", row[0], row[1], row[2], row[3]);
    }
    let same = difference <= SAME_CALIBRATION;
    println!(
        "largest difference from summary.json: {difference:.3e} ({})",
        if same {
            "the same calibration"
        } else {
            "NOT the calibration the run reports"
        }
    );
    if same {
        Ok(())
    } else {
        Err(Failure::failed(format!(
            "{}: the calibration solved again differs from the reported one by {difference:.3e}",
            run_folder.display()
        )))
    }
}
