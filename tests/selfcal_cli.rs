//! `probecal selfcal` as a command: its refusals, and on PLUS's fCal 2.0
//! recording its outputs (a summary the results model reads whole, an
//! `ImageToProbe.xml` that `--calibration` takes back).

mod common;

use common::{probecal, scratch, shared_data};
use probecal::results::selfcal::SelfcalSummary;

const SET: &str = "plus-fcal2.0-3nwires";

#[test]
fn one_sweep_is_a_usage_error() {
    let out = scratch("selfcal_cli", "one_sweep");
    let r = probecal()
        .args([
            "selfcal",
            "a.mha",
            "--config",
            "c.xml",
            "--calibration",
            "r.xml",
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(r.status.code(), Some(2));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(err.contains("SEQUENCES"), "{err}");
    assert!(!out.exists());
}

#[test]
fn a_missing_start_is_named_and_nothing_is_written() {
    let dir = scratch("selfcal_cli", "missing_start");
    std::fs::create_dir_all(&dir).unwrap();
    let missing = dir.join("no-such-result.xml");
    let out = dir.join("out");
    let r = probecal()
        .args(["selfcal", "a.mha", "b.mha", "--config", "c.xml", "--calibration"])
        .arg(&missing)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(r.status.code(), Some(2));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(err.contains("no-such-result.xml"), "{err}");
    assert!(!out.join("summary.json").exists());
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn fcal_sweeps_refine_plus_matrix_and_say_what_they_hold() {
    let out = scratch("selfcal_cli", "fcal");
    let plus = shared_data(SET, "FreehandCalibration3NWires_fCal2.0.results.xml");
    let r = probecal()
        .arg("selfcal")
        .arg(shared_data(SET, "fCal_Test_Calibration_3NWires_fCal2.0.igs.mha"))
        .arg(shared_data(SET, "fCal_Test_Validation_3NWires_fCal2.0.igs.mha"))
        .arg("--config")
        .arg(shared_data(SET, "PlusDeviceSet_fCal_Sim_SpatialCalibration_2.0.xml"))
        .arg("--calibration")
        .arg(&plus)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&r.stdout);
    assert!(r.status.success(), "{}{stdout}", String::from_utf8_lossy(&r.stderr));
    println!("{stdout}");
    let text = std::fs::read_to_string(out.join("summary.json")).unwrap();
    let summary: SelfcalSummary = serde_json::from_str(&text).unwrap();
    assert_eq!(summary.directions.len(), 6);
    assert_eq!(summary.sweeps.len(), 2);
    assert!(summary.correlation_end >= summary.correlation_start - 1e-9);
    // Every direction not held is left where the start had it: the correction
    // has no part along it.
    let q = [
        summary.move_mm[0],
        summary.move_mm[1],
        summary.move_mm[2],
        summary.turn_deg[0].to_radians() * summary.radius_mm,
        summary.turn_deg[1].to_radians() * summary.radius_mm,
        summary.turn_deg[2].to_radians() * summary.radius_mm,
    ];
    for d in summary.directions.iter().filter(|d| !d.held) {
        let along: f64 = d.vector.iter().zip(&q).map(|(a, b)| a * b).sum();
        assert!(along.abs() < 1e-6, "{} moved {along} mm", d.mostly);
    }
    // The refined matrix is a calibration `--calibration` reads.
    let back = probecal::results::calibration::read(&out.join("ImageToProbe.xml")).unwrap();
    for (r, row) in summary.image_to_probe.iter().enumerate() {
        for (c, v) in row.iter().enumerate() {
            assert!((back.image_to_probe[(r, c)] - v).abs() < 1e-6);
        }
    }
    let page = std::fs::read_to_string(out.join("report.html")).unwrap();
    for d in &summary.directions {
        assert!(page.contains(&d.mostly), "the page names {}", d.mostly);
    }
}
