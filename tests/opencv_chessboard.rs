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
    let err = probecal::detect::camera_calibration::calibrate_from(
        &[one],
        [9, 6],
        1.0,
        probecal::detect::corners::Search::OpenCvSample,
    )
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

/// OpenCV's calibration sample run by Debian's python3-opencv, an independent
/// peer: the views it used and its RMS, px; `None` (with the reason printed)
/// where the peer is not installed.
fn opencv_sample(folder: &std::path::Path) -> Option<(usize, f64)> {
    let script = r#"
import glob, sys, cv2 as cv, numpy as np
pattern = (9, 6)
obj = np.zeros((54, 3), np.float32); obj[:, :2] = np.indices(pattern).T.reshape(-1, 2)
objp, imgp = [], []
term = (cv.TERM_CRITERIA_EPS + cv.TERM_CRITERIA_COUNT, 30, 0.1)
for f in sorted(glob.glob(sys.argv[1] + '/*.jpg')):
    img = cv.imread(f, cv.IMREAD_GRAYSCALE)
    found, corners = cv.findChessboardCorners(img, pattern)
    if found:
        cv.cornerSubPix(img, corners, (5, 5), (-1, -1), term)
        objp.append(obj); imgp.append(corners.reshape(-1, 2))
rms = cv.calibrateCamera(objp, imgp, img.shape[::-1], None, None)[0]
print(len(objp), repr(rms))
"#;
    let out = std::process::Command::new("/usr/bin/python3")
        .args(["-c", script])
        .arg(folder)
        .output();
    match out {
        Ok(o) if o.status.success() => {
            let text = String::from_utf8_lossy(&o.stdout).to_string();
            let mut words = text.split_whitespace();
            Some((words.next()?.parse().ok()?, words.next()?.parse().ok()?))
        }
        Ok(o) => {
            println!(
                "skipped: python3-opencv is not usable ({})",
                String::from_utf8_lossy(&o.stderr).lines().last().unwrap_or("")
            );
            None
        }
        Err(e) => {
            println!("skipped: /usr/bin/python3 cannot run ({e})");
            None
        }
    }
}

/// `calibrate-camera` into a folder that does not exist yet: the intrinsics
/// and, per view, its fate.
fn calibrate_camera(images: &std::path::Path, name: &str) -> (String, String) {
    let out = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("{name}-{}", std::process::id()))
        .join("new folder")
        .join("camera.yml");
    let r = std::process::Command::new(env!("CARGO_BIN_EXE_probecal"))
        .args(["calibrate-camera", "--board", "9x6", "--square-mm", "1", "--out"])
        .arg(&out)
        .arg(images)
        .output()
        .expect("run probecal");
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    (
        std::fs::read_to_string(&out).expect("the output, its folder made"),
        String::from_utf8_lossy(&r.stderr).to_string(),
    )
}

/// The command's views and RMS are those of OpenCV's own calibration sample
/// (same flags, same sub-pixel refinement) to 1e-4 px.
#[test]
#[ignore = "needs ../shared/data and python3-opencv (full tier: scripts/test.sh)"]
fn the_command_reproduces_opencvs_sample_to_a_ten_thousandth_of_a_pixel() {
    let Some((views, rms)) = opencv_sample(&data()) else {
        return;
    };
    let (text, _) = calibrate_camera(&data(), "sample");
    let ours: f64 = text
        .lines()
        .find_map(|l| l.strip_prefix("avg_reprojection_error: "))
        .and_then(|v| v.trim().parse().ok())
        .expect("the RMS in the file");
    println!(
        "OpenCV's sample: {views} views, RMS {rms}; ours {} views, RMS {ours}",
        text.matches("used: 1").count()
    );
    assert_eq!(text.matches("used: 1").count(), views);
    assert!((ours - rms).abs() <= 1e-4, "RMS {ours} against OpenCV's {rms}");
}

/// Blurred copies of the photos (Gaussian, sigma 2.5 px): OpenCV's default
/// search finds boards the adaptive threshold alone misses, and
/// findChessboardCornersSB finds more; every view OpenCV's default flags find
/// is used, and each view's fate is in the output file.
#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn every_board_opencv_finds_is_used_and_every_view_says_how() {
    use opencv::core::{Point2f, Size, Vector};
    use opencv::prelude::*;
    let folder = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("blurred-{}", std::process::id()));
    std::fs::create_dir_all(&folder).unwrap();
    let (mut adaptive_only, mut default_flags) = (0, 0);
    for entry in std::fs::read_dir(data()).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().and_then(|e| e.to_str()) != Some("jpg") {
            continue;
        }
        let image = probecal::io::image::read_gray(&path).unwrap();
        let mut blurred = opencv::core::Mat::default();
        opencv::imgproc::gaussian_blur_def(&image, &mut blurred, Size::new(0, 0), 2.5).unwrap();
        let name = folder.join(path.file_name().unwrap()).with_extension("png");
        probecal::io::image::mat_to_gray8(&blurred)
            .unwrap()
            .write_png(&name)
            .unwrap();
        let mut corners = Vector::<Point2f>::new();
        let pattern = Size::new(9, 6);
        let flags = opencv::calib3d::CALIB_CB_ADAPTIVE_THRESH;
        adaptive_only +=
            usize::from(opencv::calib3d::find_chessboard_corners(&blurred, pattern, &mut corners, flags).unwrap());
        default_flags +=
            usize::from(opencv::calib3d::find_chessboard_corners_def(&blurred, pattern, &mut corners).unwrap());
        assert!(blurred.rows() == 480);
    }
    let (text, stderr) = calibrate_camera(&folder, "blurred-calibration");
    let used = text.matches("used: 1").count();
    println!("blurred: adaptive threshold alone {adaptive_only}, OpenCV's default flags {default_flags}, used {used}\n{stderr}");
    assert!(
        default_flags > adaptive_only,
        "the blur no longer tells the searches apart"
    );
    assert!(
        used >= default_flags,
        "{used} views used, OpenCV's default flags find {default_flags}"
    );
    assert_eq!(text.matches("image: ").count(), 13, "every view's fate:\n{text}");
    assert!(text.contains("how: board found by findChessboardCornersSB"), "{text}");
}
