//! ChArUco detection and camera calibration against OpenCV-Python
//! (python3-opencv 4.6, `tests/charuco/opencv_reference.py`): on OpenCV's own
//! ArUco photos the markers, corner ids and corners equal `detectMarkers` +
//! `interpolateCornersCharuco` to 0.01 px; on ChArUco photos made by OpenCV
//! (its board drawing, photographed through a distorting camera, blurred and
//! noisy), `calibrate-camera --charuco` agrees with `calibrateCameraCharuco`.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::{probecal, root, scratch, shared_data};
use probecal::detect::charuco_calibration::{detect_view, CharucoSpec};
use probecal::io::camera_model::CameraIntrinsics;
use probecal::io::image::read_gray;

const BOARD: &str = "5x7:40:20:DICT_6X6_250";

fn reference(args: &[&str]) -> serde_json::Value {
    let out = Command::new("/usr/bin/python3")
        .arg(root().join("tests/charuco/opencv_reference.py"))
        .args(args)
        .output()
        .expect("/usr/bin/python3 with python3-opencv (scripts/setup.sh)");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap_or(serde_json::Value::Null)
}

fn spec(dictionary: &str) -> CharucoSpec {
    CharucoSpec {
        squares: [5, 7],
        square_mm: 40.0,
        marker_mm: 20.0,
        dictionary: dictionary.to_string(),
    }
}

#[test]
#[ignore = "needs ../shared/data and python3-opencv (full tier: scripts/test.sh)"]
fn markers_and_corners_equal_opencv_python_on_its_own_photos() {
    let custom = shared_data("opencv-aruco", "tutorial_dict.yml");
    let cases = [
        ("choriginal.jpg", "DICT_6X6_250".to_string()),
        ("singlemarkersoriginal.jpg", "DICT_6X6_250".to_string()),
        ("gboriginal.png", custom.display().to_string()),
    ];
    let mut charuco_corners = 0;
    for (file, dictionary) in cases {
        let image = shared_data("opencv-aruco", file);
        let want = reference(&[
            "detect",
            &image.display().to_string(),
            &format!("5x7:40:20:{dictionary}"),
        ]);
        let (d, board) = spec(&dictionary).board().unwrap();
        let got = detect_view(&read_gray(&image).unwrap(), &d, &board).unwrap();
        let ids = |v: &serde_json::Value| -> Vec<i32> {
            v.as_array()
                .unwrap()
                .iter()
                .map(|i| i.as_i64().unwrap() as i32)
                .collect()
        };
        assert_eq!(got.marker_ids, ids(&want["marker_ids"]), "{file}");
        assert_eq!(got.corner_ids, ids(&want["corner_ids"]), "{file}");
        for (p, q) in got.corners_px.iter().zip(want["corners"].as_array().unwrap()) {
            let (x, y) = (q[0].as_f64().unwrap(), q[1].as_f64().unwrap());
            assert!(
                (p[0] - x).abs() <= 0.01 && (p[1] - y).abs() <= 0.01,
                "{file}: {p:?} vs {x} {y}"
            );
        }
        charuco_corners += got.corner_ids.len();
        if file == "choriginal.jpg" {
            // OpenCV's tutorial: 17 markers, 24 ChArUco corners.
            assert_eq!((got.marker_ids.len(), got.corner_ids.len()), (17, 24));
        }
    }
    assert!(charuco_corners >= 24);
}

fn views(dir: &Path) -> PathBuf {
    let folder = dir.join("views");
    let _ = std::fs::remove_dir_all(&folder);
    let out = Command::new("/usr/bin/python3")
        .arg(root().join("tests/charuco/opencv_reference.py"))
        .args(["render", &folder.display().to_string(), BOARD, "14", "7"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    folder
}

#[test]
#[ignore = "needs python3-opencv (full tier: scripts/test.sh)"]
fn charuco_camera_calibration_agrees_with_opencv_python() {
    let dir = scratch("charuco_calibration", "agree");
    let folder = views(&dir);
    // A photo with no board: listed with its reason, not used.
    let blank = opencv::core::Mat::new_rows_cols_with_default(
        480,
        640,
        opencv::core::CV_8UC1,
        opencv::core::Scalar::all(128.0),
    )
    .unwrap();
    probecal::io::image::mat_to_gray8(&blank)
        .unwrap()
        .write_png(&folder.join("zz_blank.png"))
        .unwrap();
    let want = reference(&["calibrate", &folder.display().to_string(), BOARD]);
    let yml = dir.join("out/camera.yml");
    let out = probecal()
        .arg("calibrate-camera")
        .arg(&folder)
        .args([
            "--charuco",
            "5x7",
            "--square-mm",
            "40",
            "--marker-mm",
            "20",
            "--dictionary",
            "DICT_6X6_250",
            "--out",
        ])
        .arg(&yml)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let got = CameraIntrinsics::load(&yml).unwrap();
    let k = &want["camera_matrix"];
    let rms = want["rms"].as_f64().unwrap();
    assert!(
        (got.rms_px.unwrap() - rms).abs() < 0.01,
        "RMS {:?} vs {rms}",
        got.rms_px
    );
    for (r, c) in [(0, 0), (1, 1), (0, 2), (1, 2)] {
        let w = k[r][c].as_f64().unwrap();
        assert!(
            (got.camera_matrix[r][c] - w).abs() < 5.0,
            "K[{r}][{c}] {} vs {w}",
            got.camera_matrix[r][c]
        );
    }
    assert_eq!(want["used"].as_array().unwrap().len(), 14);
    let text = std::fs::read_to_string(&yml).unwrap();
    assert_eq!(text.matches("used: 1").count(), 14);
    assert!(
        text.contains("zz_blank.png") && text.contains("0 ChArUco corners from 0 markers"),
        "{text}"
    );
}

#[test]
fn charuco_options_that_cannot_be_a_board_are_refused() {
    let dir = scratch("charuco_calibration", "options");
    let run = |extra: &[&str]| {
        probecal()
            .arg("calibrate-camera")
            .arg(&dir)
            .args(["--square-mm", "40", "--out"])
            .arg(dir.join("camera.yml"))
            .args(extra)
            .output()
            .unwrap()
    };
    let cases: [(&[&str], &str); 4] = [
        (
            &["--charuco", "5x7", "--marker-mm", "40", "--dictionary", "DICT_6X6_250"],
            "smaller than the square",
        ),
        (
            &["--charuco", "5x7", "--marker-mm", "20", "--dictionary", "DICT_6X6_9"],
            "unknown ArUco dictionary",
        ),
        (
            &["--charuco", "30x30", "--marker-mm", "20", "--dictionary", "DICT_4X4_50"],
            "holds 450 markers, the dictionary `DICT_4X4_50` has 50",
        ),
        (&["--charuco", "5x7", "--marker-mm", "20"], "--dictionary"),
    ];
    for (extra, message) in cases {
        let out = run(extra);
        assert_eq!(out.status.code(), Some(2), "{extra:?}");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(stderr.contains(message), "{extra:?}: {stderr}");
    }
    assert!(!dir.join("camera.yml").exists());
}

/// Six copies of one photo are one view, as for a chessboard: the copies are
/// listed as the same view as the first, and one view is too few.
#[test]
#[ignore = "needs python3-opencv (full tier: scripts/test.sh)"]
fn copies_of_one_photo_are_one_view() {
    let dir = scratch("charuco_calibration", "copies");
    let rendered = views(&dir);
    let mut first: Vec<PathBuf> = std::fs::read_dir(&rendered)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    first.sort();
    let folder = dir.join("copies");
    let _ = std::fs::remove_dir_all(&folder);
    std::fs::create_dir_all(&folder).unwrap();
    let extension = first[0].extension().unwrap().to_string_lossy().to_string();
    for k in 0..6 {
        std::fs::copy(&first[0], folder.join(format!("copy_{k}.{extension}"))).unwrap();
    }
    let yml = dir.join("camera.yml");
    let out = probecal()
        .arg("calibrate-camera")
        .arg(&folder)
        .args(["--charuco", "5x7", "--square-mm", "40", "--marker-mm", "20"])
        .args(["--dictionary", "DICT_6X6_250", "--out"])
        .arg(&yml)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    // As the chessboard path: the calibration failed (exit 1), every copy named.
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("was found in 1 of 6 views"), "{stderr}");
    assert_eq!(stderr.matches("the same view as").count(), 5, "{stderr}");
    assert!(!yml.exists());
}
