//! The constants of the bound and the camera's stated information, measured
//! again: each test runs the experiment its constant was measured on (its
//! default seed, rendered into `datasets/` if not cached there) and checks the
//! constant against what the run gives. They are reproductions, run by
//! `scripts/reproduce.sh` (listed in `scripts/long-tests`).

mod common;

use common::{probecal, root, scratch};
use probecal::pipeline::run::design;

/// Runs an experiment (its default seed, rendered into `datasets/` if not
/// cached there) into a scratch folder's `reports/`; returns the folder.
fn run_default_seed(manifest: &str, name: &str) -> std::path::PathBuf {
    let dir = scratch("measured_constants", name);
    let out = probecal()
        .args([
            "run",
            root().join(manifest).to_str().unwrap(),
            "--out",
            dir.join("reports").to_str().unwrap(),
            "--datasets",
            root().join("datasets").to_str().unwrap(),
            "--quiet",
        ])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    dir
}

/// The bound's edge noise for the normal-peak detector is what its measuring
/// run gives: the median arc-fit RMS of the default hemisphere run with that
/// detector (`experiments/measurements/hemisphere_normal_peak.yaml`).
#[test]
#[ignore = "renders a dataset and runs its experiment (a reproduction: scripts/reproduce.sh)"]
fn the_normal_peaks_edge_noise_is_its_hemisphere_runs_median_arc_rms() {
    let dir = run_default_seed("experiments/measurements/hemisphere_normal_peak.yaml", "normal_peak");
    let frames = std::fs::read_to_string(dir.join("reports/hemisphere_normal_peak/dataset3/frames.csv")).unwrap();
    let mut lines = frames.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let column = header.iter().position(|h| *h == "arc_rms_px").unwrap();
    let mut rms_px: Vec<f64> = lines
        .filter_map(|l| l.split(',').nth(column).and_then(|v| v.parse().ok()))
        .collect();
    assert!(rms_px.len() > 40, "{} arcs", rms_px.len());
    let median_px = probecal::core::stats::median(&mut rms_px);
    let stated = design::NOISE_NORMAL_PEAK.edge_sd_mm;
    assert!(
        (median_px * 0.2 - stated).abs() < 0.0001,
        "median arc RMS {median_px} px = {} mm, the bound assumes {stated} mm",
        median_px * 0.2
    );
    // docs/results/multi-sphere.md: the arcs' shared shape error falls to about 0.10 mm (0.178 mm with
    // the column's peak), and the arcs spread more than that noise and 20
    // points per arc predict (1.1-1.2 times).
    let summary: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.join("reports/hemisphere_normal_peak/dataset3/summary.json")).unwrap(),
    )
    .unwrap();
    let arcs = &summary["truth"]["arc_noise"]["all"];
    let bias_mm = arcs["bias_mm"][0].as_f64().unwrap();
    assert!((0.08..0.12).contains(&bias_mm), "{arcs}");
    let spread: Vec<f64> = arcs["sd_over_model"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert!(spread.iter().all(|s| (1.1..1.25).contains(s)), "{arcs}");
}

#[test]
#[ignore = "renders a dataset and runs its experiment (a reproduction: scripts/reproduce.sh)"]
fn the_refined_camera_is_as_far_from_the_truth_as_its_information_says() {
    // The multi-sphere experiment solves its camera again with the frames'
    // boards, and the bound and the fit take what that refinement states it
    // knows of the intrinsics. The phantom's board stays where it is in every
    // photo: counted as 48 views, the camera claimed to know its intrinsics
    // about eight times better (in variance) than it did. Counted once, the
    // error weighed by the stated information is a χ² draw with nine degrees
    // of freedom, below 21.67 ninety-nine times in a hundred.
    let dir = run_default_seed("experiments/spheres_checkerboard.yaml", "camera_nees");
    let summary: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.join("reports/spheres_checkerboard/dataset3/summary.json")).unwrap(),
    )
    .unwrap();
    let nees = summary["truth"]["camera_intrinsics_nees"].as_f64().unwrap();
    assert!(nees < 21.67, "NEES {nees}");
    let source = summary["camera"]["source"].as_str().unwrap();
    assert!(source.contains("counted once"), "{source}");
}
