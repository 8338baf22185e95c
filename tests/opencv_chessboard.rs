//! Camera calibration of OpenCV's own sample photos (`left*.jpg`, 9x6 inner
//! corners) through the pipeline's calibration stage, checked against the result
//! OpenCV publishes and the tolerances its own regression test uses.

mod common;

use std::path::PathBuf;

use probecal::detect::camera_calibration::calibrate_folder;

fn data() -> PathBuf {
    common::shared_data("opencv-chessboard", "")
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn reproduces_opencvs_published_calibration() {
    let folder = data();
    assert!(
        folder.is_dir(),
        "{} is missing: the shared data must sit beside the checkout",
        folder.display()
    );
    // The folder also holds left_intrinsics.yml and text files: only images are read.
    let cal = calibrate_folder(&folder, [9, 6], 1.0).expect("calibration");
    let used = cal.views.iter().filter(|v| v.used).count();
    assert_eq!(used, 13, "views used: {:?}", cal.views);

    let k = &cal.intrinsics;
    let rms = k.rms_px.expect("rms");
    let published_k = [532.80992, 532.93346, 342.49522, 233.88793];
    let published_d = [-0.2813256, 0.0291130, 0.0012123, -0.0001408, 0.1548658];
    let l1_k = (k.fx() - published_k[0]).abs()
        + (k.fy() - published_k[1]).abs()
        + (k.cx() - published_k[2]).abs()
        + (k.cy() - published_k[3]).abs();
    let l1_d: f64 = k.distortion.iter().zip(published_d).map(|(a, b)| (a - b).abs()).sum();
    println!(
        "fx {:.4} fy {:.4} cx {:.4} cy {:.4} dist {:?} rms {rms:.6}; L1(K) {l1_k:.4}, L1(dist) {l1_d:.5}",
        k.fx(),
        k.fy(),
        k.cx(),
        k.cy(),
        k.distortion
    );
    assert!((rms - 0.196335).abs() <= 0.01, "RMS {rms} vs published 0.196335");
    assert!(l1_k < 10.0, "camera matrix L1 distance {l1_k}");
    assert!(l1_d < 0.05, "distortion L1 distance {l1_d}");
    assert_eq!(k.image_size_px, [640, 480]);
    assert_eq!(k.per_view_rms_px.len(), 13);
    assert!(
        k.per_view_rms_px.iter().all(|e| *e > 0.0 && *e < 1.0),
        "{:?}",
        k.per_view_rms_px
    );
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn calibrate_camera_command_writes_opencv_filestorage() {
    let out = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("left_calibrated.yml");
    let _ = std::fs::remove_file(&out);
    let status = std::process::Command::new(env!("CARGO_BIN_EXE_probecal"))
        .args(["calibrate-camera", "--board", "9x6", "--square-mm", "25", "--out"])
        .arg(&out)
        .arg(data())
        .output()
        .expect("run probecal");
    assert!(status.status.success(), "{}", String::from_utf8_lossy(&status.stderr));
    let text = std::fs::read_to_string(&out).expect("output file");
    for key in [
        "%YAML:1.0",
        "camera_matrix: !!opencv-matrix",
        "distortion_coefficients: !!opencv-matrix",
        "avg_reprojection_error",
        "image_width: 640",
        "board_width: 9",
    ] {
        assert!(text.contains(key), "`{key}` missing from\n{text}");
    }
    let back = probecal::io::camera_model::CameraIntrinsics::load(&out).expect("reads back");
    assert!((back.fx() - 532.8).abs() < 2.0, "fx {}", back.fx());
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn too_few_views_is_a_clear_error() {
    let one = data().join("left01.jpg");
    let err = probecal::detect::camera_calibration::calibrate_from(&[one], [9, 6], 1.0)
        .unwrap_err()
        .to_string();
    assert!(err.contains("found in 1 of 1 views; at least 4 are needed"), "{err}");
    let wrong_board = probecal::detect::camera_calibration::calibrate_folder(&data(), [7, 7], 1.0)
        .unwrap_err()
        .to_string();
    assert!(
        wrong_board.contains("left01.jpg: no 7x7 chessboard found"),
        "{wrong_board}"
    );
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn one_photo_repeated_as_every_view_is_refused() {
    let dir = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("repeated_views");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    for i in 0..6 {
        std::fs::copy(data().join("left01.jpg"), dir.join(format!("view{i}.jpg"))).unwrap();
    }
    let out = common::probecal()
        .arg("calibrate-camera")
        .arg(&dir)
        .args(["--board", "9x6", "--square-mm", "25", "--out"])
        .arg(dir.join("camera.yml"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("was found in 1 of 6 views"), "{stderr}");
    assert!(stderr.contains("the same view as"), "{stderr}");
    assert!(!dir.join("camera.yml").exists());
}
