//! The ChArUco rig on rendered photos, from their pixels: a partly hidden board
//! still gives its visible corners and a pose, where a hidden checkerboard
//! corner costs the frame.

mod common;

use common::{probecal, root, scratch};
use serde_json::Value;

/// A shipped experiment with fewer frames (and so fewer needed, and its truth
/// gates off: this test is about which frames a rig keeps), written beside its run.
fn shortened(name: &str, frames: usize, dir: &std::path::Path) -> std::path::PathBuf {
    let text = std::fs::read_to_string(root().join("experiments").join(format!("{name}.yaml"))).unwrap();
    let short = text
        .replace("      frames: 50", &format!("      frames: {frames}"))
        .replace("  min_frames: 10", "  min_frames: 4")
        .replace("    truth_corner_error_mm: ", "    truth_corner_error_mm: 100 #")
        .replace("    truth_rotation_error_deg: ", "    truth_rotation_error_deg: 100 #");
    assert_ne!(short, text, "{name}: frames not found");
    std::fs::create_dir_all(dir).unwrap();
    let path = dir.join(format!("{name}.yaml"));
    std::fs::write(&path, short).unwrap();
    path
}

fn frames_csv(path: &std::path::Path) -> Vec<std::collections::HashMap<String, String>> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    lines
        .map(|l| {
            // The reason column may hold commas in quotes; the columns read here come before it or are numeric.
            let mut cells = Vec::new();
            let mut quoted = false;
            let mut cell = String::new();
            for ch in l.chars() {
                match ch {
                    '"' => quoted = !quoted,
                    ',' if !quoted => cells.push(std::mem::take(&mut cell)),
                    c => cell.push(c),
                }
            }
            cells.push(cell);
            header.iter().map(|h| h.to_string()).zip(cells).collect()
        })
        .collect()
}

#[test]
#[ignore = "runs two rendered experiments (full tier: scripts/test.sh)"]
fn charuco_keeps_partly_hidden_frames_the_checkerboard_loses() {
    let dir = scratch("charuco_rig", "occluded");
    let frames = 16;
    let charuco = shortened("hemisphere_charuco_occluded", frames, &dir.join("manifests"));
    let checkerboard = shortened("hemisphere_checkerboard_occluded", frames, &dir.join("manifests"));
    let out = dir.join("out");
    let r = probecal()
        .arg("compare")
        .args([&charuco, &checkerboard])
        .arg("--out")
        .arg(&out)
        .arg("--datasets")
        .arg(dir.join("datasets"))
        .arg("--quiet")
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let summary = |name: &str| -> Value {
        serde_json::from_str(&std::fs::read_to_string(out.join(name).join("dataset3/summary.json")).unwrap()).unwrap()
    };
    let (a, b) = (
        summary("hemisphere_charuco_occluded"),
        summary("hemisphere_checkerboard_occluded"),
    );
    let used = |s: &Value| s["frames"]["used"].as_u64().unwrap() as usize;
    println!(
        "occluded, {frames} frames: ChArUco keeps {}, checkerboard {}; ChArUco corners {:.3} mm from the truth",
        used(&a),
        used(&b),
        a["truth"]["corner_error_mm"]["mean"]
    );
    assert!(used(&a) * 10 >= frames * 9, "ChArUco keeps {} of {frames}", used(&a));
    assert!(used(&b) < used(&a), "the checkerboard rig loses hidden frames");
    assert!(a["truth"]["corner_error_mm"]["mean"].as_f64().unwrap() < 1.0);

    // The frames whose boards were partly hidden were posed from fewer corners,
    // and those corners still place the board where it is.
    let truth: Value = serde_json::from_str(
        &std::fs::read_to_string(dir.join("datasets/hemisphere_charuco_occluded__dataset3/ground_truth.json")).unwrap(),
    )
    .unwrap();
    let rows = frames_csv(&out.join("hemisphere_charuco_occluded/dataset3/frames.csv"));
    let mut partial = 0;
    for (k, row) in rows.iter().enumerate() {
        let hidden: Vec<&str> = truth["frames"][k]["stated_occluders"]
            .as_array()
            .map(|o| o.iter().filter_map(|o| o["board"].as_str()).collect())
            .unwrap_or_default();
        let points = |c: &str| row[c].parse::<usize>().ok();
        if row["status"] != "used" {
            continue;
        }
        for (board, column, error) in [
            ("probe", "probe_board_points", "truth_probe_pose_error_mm"),
            ("phantom", "phantom_board_points", "truth_phantom_pose_error_mm"),
        ] {
            let n = points(column).expect("points of a used frame");
            assert!((6..=100).contains(&n), "frame {k}: {n} {board} corners");
            if hidden.contains(&board) && n < 100 {
                partial += 1;
                let e: f64 = row[error].parse().unwrap();
                assert!(
                    e < 2.0,
                    "frame {k}: {board} board {e} mm from the truth from {n} corners"
                );
            }
        }
    }
    assert!(partial >= 3, "only {partial} partly hidden boards were posed");
    let table = std::fs::read_to_string(out.join("compare.md")).unwrap();
    assert!(table.contains("ChArUco DICT_4X4_250 11x11 squares of 13 mm"), "{table}");
    assert!(
        table.contains("| board points per frame, median: probe / phantom |"),
        "{table}"
    );
}
