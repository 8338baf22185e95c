//! `probecal reconstruct --wires`: the fCal 2.0 phantom's N-wires measured in a
//! reconstruction of PLUS's validation sweep (`../shared/data/plus-fcal2.0-3nwires`).
//! The figures respond to the calibration: an `ImageToProbe` moved by 3 mm
//! moves the wires off their lines by about as much.

mod common;

use std::path::{Path, PathBuf};

use common::{probecal, root, scratch, shared_data};
use serde_json::Value;

const FCAL: &str = "plus-fcal2.0-3nwires";
const SWEEP: &str = "fCal_Test_Validation_3NWires_fCal2.0.igs.mha";
const DEVICE_SET: &str = "PlusDeviceSet_fCal_Sim_SpatialCalibration_2.0.xml";
const RESULT: &str = "FreehandCalibration3NWires_fCal2.0.results.xml";

/// `probecal reconstruct` of the validation sweep with `calibration` and the
/// device set's wires: (exit code, stderr, summary.json when written).
fn reconstruct(out: &Path, calibration: &Path, wires: &Path) -> (Option<i32>, String, Option<Value>) {
    let r = probecal()
        .arg("reconstruct")
        .arg(shared_data(FCAL, SWEEP))
        .arg("--config")
        .arg(root().join("experiments/plus/fcal2_volume.xml"))
        .arg("--calibration")
        .arg(calibration)
        .arg("--wires")
        .arg(wires)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap();
    let summary = std::fs::read_to_string(out.join("summary.json"))
        .ok()
        .map(|t| serde_json::from_str(&t).unwrap());
    (r.status.code(), String::from_utf8_lossy(&r.stderr).to_string(), summary)
}

fn figure(summary: &Value, key: &str) -> f64 {
    summary["wires"]["figures"][key].as_f64().unwrap()
}

/// A run folder whose `summary.json` holds PLUS's ImageToProbe moved by `shift_mm` along x.
fn run_folder(dir: &Path, shift_mm: f64) -> PathBuf {
    let plus = probecal::io::plus::result::PlusResult::read(&shared_data(FCAL, RESULT)).unwrap();
    let mut m = plus.image_to_probe;
    m[(0, 3)] += shift_mm;
    let rows: Vec<Vec<f64>> = (0..4).map(|i| (0..4).map(|j| m[(i, j)]).collect()).collect();
    let folder = dir.join(format!("run_{shift_mm}"));
    std::fs::create_dir_all(&folder).unwrap();
    let summary = common::tracked_summary_with_matrix(serde_json::json!(rows));
    std::fs::write(folder.join("summary.json"), summary).unwrap();
    folder
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn the_wires_are_measured_and_follow_the_calibration() {
    let dir = scratch("reconstruct_wires", "follow");
    std::fs::create_dir_all(&dir).unwrap();
    let wires = shared_data(FCAL, DEVICE_SET);
    // PLUS's own result file as the calibration.
    let (code, stderr, summary) = reconstruct(&dir.join("plus"), &shared_data(FCAL, RESULT), &wires);
    assert_eq!(code, Some(0), "{stderr}");
    let plus = summary.unwrap();
    assert_eq!(plus["wires"]["figures"]["wires_measured"], 9, "{}", plus["wires"]);
    for wire in plus["wires"]["figures"]["wires"].as_array().unwrap() {
        let counted = wire["sections_counted"].as_u64().unwrap();
        assert!(counted * 2 >= wire["sections"].as_u64().unwrap(), "{wire}");
        let (position, straight, thick) = (
            wire["position_error_mm"].as_f64().unwrap(),
            wire["straightness_rms_mm"].as_f64().unwrap(),
            wire["thickness_fwhm_mm"].as_f64().unwrap(),
        );
        assert!(
            position < 1.5 && straight < 0.5 && (0.3..2.0).contains(&thick),
            "{wire}"
        );
    }
    let page = std::fs::read_to_string(dir.join("plus/report.html")).unwrap();
    assert!(
        page.contains("The phantom's wires in the volume"),
        "no wires section on the page"
    );

    // The same matrix from a run folder gives the same figures; moved 3 mm, the
    // wires move off their lines.
    let (code, stderr, same) = reconstruct(&dir.join("same"), &run_folder(&dir, 0.0), &wires);
    assert_eq!(code, Some(0), "{stderr}");
    assert_eq!(same.unwrap()["wires"]["figures"], plus["wires"]["figures"]);
    let (code, stderr, moved) = reconstruct(&dir.join("moved"), &run_folder(&dir, 3.0), &wires);
    assert_eq!(code, Some(0), "{stderr}");
    let moved = moved.unwrap();
    let gained = figure(&moved, "position_error_mm") - figure(&plus, "position_error_mm");
    assert!(
        gained > 1.0,
        "position error grew by only {gained:.3} mm for a 3 mm shift"
    );
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn a_device_set_without_wires_is_refused_and_nothing_is_written() {
    let dir = scratch("reconstruct_wires", "none");
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("out");
    let no_wires = root().join("experiments/plus/fcal2_volume.xml");
    let (code, stderr, _) = reconstruct(&out, &shared_data(FCAL, RESULT), &no_wires);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(
        stderr.contains("fcal2_volume.xml") && stderr.contains("no N-wire"),
        "{stderr}"
    );
    assert!(!out.exists());
}
