//! `probecal live` on PLUS's fCal 2.0 recording: each frame processed as it
//! arrives (its error predicted by the calibration of the frames before it),
//! and the final calibration the batch run's.

mod common;

use std::path::{Path, PathBuf};

use common::{probecal, root, scratch};

/// The shared fCal experiment with its paths made absolute and the lag fixed at
/// `lag_s` (a positive lag has each frame finished when the next one arrives).
fn manifest_with_lag(dir: &Path, lag_s: &str) -> PathBuf {
    let text = common::fcal_manifest_text();
    let shared = root().join("../shared").canonicalize().unwrap();
    let text = text
        .replace("../../shared", &shared.display().to_string())
        .replace("time_offset_s: estimate", &format!("time_offset_s: {lag_s}"));
    assert!(text.contains(&format!("time_offset_s: {lag_s}")));
    std::fs::create_dir_all(dir).unwrap();
    let path = dir.join("fcal_live.yaml");
    std::fs::write(&path, text).unwrap();
    path
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn live_predicts_each_frame_and_ends_on_the_batch_calibration() {
    let dir = scratch("plus_live", "lag");
    let manifest = manifest_with_lag(&dir, "0.05");
    let live = probecal()
        .arg("live")
        .arg(&manifest)
        .args(["--speed", "0", "--out"])
        .arg(dir.join("live"))
        .output()
        .unwrap();
    assert!(live.status.success(), "{}", String::from_utf8_lossy(&live.stderr));
    let batch = probecal()
        .arg("run")
        .arg(&manifest)
        .args(["--quiet", "--out"])
        .arg(dir.join("batch"))
        .output()
        .unwrap();
    assert!(batch.status.success(), "{}", String::from_utf8_lossy(&batch.stderr));
    let summary = json(&dir.join("live/summary.json"));
    // The typed results model holds every field written.
    let typed: probecal::results::live::LiveSummary = serde_json::from_value(summary.clone()).unwrap();
    assert_eq!(serde_json::to_value(&typed).unwrap(), summary);
    let run = json(&dir.join("batch/plus_fcal2_nwire/fcal2_3nwires/summary.json"));
    assert_eq!(summary["final_matrix"], run["image_to_probe"]["matrix"]);
    assert_eq!(summary["frames"], 190);
    // Each frame once, in order; after the first fit every used frame has its
    // error predicted by the calibration it did not enter, and the running
    // estimate is of the size the validation sequence shows.
    let csv = std::fs::read_to_string(dir.join("live/live.csv")).unwrap();
    let rows: Vec<Vec<&str>> = csv.lines().skip(1).map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 190);
    for (k, row) in rows.iter().enumerate() {
        assert_eq!(row[0], k.to_string());
        let used: usize = row[7].parse().unwrap();
        if used > 10 && row[4].is_empty() {
            assert!(!row[5].is_empty(), "frame {k}: no prediction");
        }
    }
    let running = summary["running_pre3d_mm"].as_f64().unwrap();
    let validation = run["validation"]["pre3d_mm"]["mean"].as_f64().unwrap();
    assert!(
        (running - validation).abs() < 0.25 * validation,
        "running {running} against validation {validation}"
    );
}

#[test]
fn a_camera_manifest_or_a_bad_speed_is_refused() {
    let camera = probecal()
        .arg("live")
        .arg(root().join("tests/fixtures/hemisphere_small.yaml"))
        .args(["--out", "unused"])
        .output()
        .unwrap();
    assert_eq!(camera.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&camera.stderr).contains("replays a tracked sequence"));
    let speed = probecal()
        .arg("live")
        .arg(root().join("experiments/plus_fcal2_nwire.yaml"))
        .args(["--out", "unused", "--speed=-1"])
        .output()
        .unwrap();
    assert_eq!(speed.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&speed.stderr).contains("--speed -1"));
    assert!(!Path::new("unused").exists());
}
