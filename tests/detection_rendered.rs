#![allow(non_snake_case)]
//! The detection stages on rendered images, measured against the ground truth:
//! board corners (px) and identification, arc centres (px), camera intrinsics.

use std::path::{Path, PathBuf};

use nalgebra::Point3;
use probecal::core::geometry::rigid_from_rows;
use probecal::detect::arc::{self, ArcSettings};
use probecal::detect::board::BoardLayout;
use probecal::detect::board_pose::{self, RigLayout};
use probecal::io::camera_model::CameraIntrinsics;
use probecal::manifest::{DatasetSource, Manifest};
use serde_json::Value;

/// The fixture rendered once for all tests of this file (they run in parallel).
fn rendered() -> (Manifest, PathBuf, Value) {
    static RENDERED: std::sync::OnceLock<(Manifest, PathBuf, Value)> = std::sync::OnceLock::new();
    RENDERED.get_or_init(render).clone()
}

fn render() -> (Manifest, PathBuf, Value) {
    let manifest = Manifest::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/hemisphere_small.yaml"))
        .expect("fixture");
    let DatasetSource::Render(spec) = &manifest.datasets[0].source else {
        panic!("fixture renders")
    };
    let folder = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("detection_rendered/small");
    probecal::synth::ensure_rendered(&probecal::pipeline::settings::lab(&manifest), spec, &folder).expect("render");
    let truth: Value =
        serde_json::from_str(&std::fs::read_to_string(folder.join("ground_truth.json")).unwrap()).unwrap();
    (manifest, folder, truth)
}

fn true_camera(truth: &Value) -> CameraIntrinsics {
    serde_json::from_value::<TrueCamera>(truth["camera"].clone())
        .expect("camera")
        .into()
}

#[derive(serde::Deserialize)]
struct TrueCamera {
    image_size_px: [u32; 2],
    camera_matrix: [[f64; 3]; 3],
    distortion: [f64; 5],
}

impl From<TrueCamera> for CameraIntrinsics {
    fn from(t: TrueCamera) -> Self {
        CameraIntrinsics {
            image_size_px: t.image_size_px,
            camera_matrix: t.camera_matrix,
            distortion: t.distortion,
            rms_px: None,
            per_view_rms_px: vec![],
        }
    }
}

fn rows(v: &Value) -> [[f64; 4]; 4] {
    serde_json::from_value(v.clone()).expect("4x4")
}

#[test]
#[ignore = "renders datasets (full tier: scripts/test.sh)"]
fn board_corners_and_identity_match_the_truth() {
    let (_, folder, truth) = rendered();
    let camera = true_camera(&truth);
    let probe = BoardLayout {
        inner_corners: [10, 10],
        square_mm: 13.0,
        id_dots: 1,
    };
    let phantom = BoardLayout {
        inner_corners: [10, 10],
        square_mm: 13.0,
        id_dots: 2,
    };
    let rig = RigLayout { probe, phantom };
    let camera_T_phantom = rigid_from_rows(&rows(&truth["camera_T_phantom"])).unwrap();
    let mut errors = Vec::new();
    let mut occluded_rejected = 0;
    for frame in truth["frames"].as_array().unwrap() {
        let k = frame["frame"].as_u64().unwrap();
        let image = probecal::io::image::read_gray(&folder.join(format!("frames/camera_{k:03}.png"))).unwrap();
        let poses = match board_pose::estimate_checkerboards(&image, &camera, &rig).unwrap() {
            Ok(p) => p,
            // Something lies across the probe board in this photo: it may be lost.
            Err(reason) if !frame["occluder"].is_null() => {
                assert!(reason.to_string().contains("probe board"), "frame {k}: {reason}");
                occluded_rejected += 1;
                continue;
            }
            Err(reason) => panic!("frame {k}: {reason}"),
        };
        let camera_T_marker = rigid_from_rows(&rows(&frame["camera_T_marker_photo"])).unwrap();
        for (pose, layout, observed) in [
            (camera_T_marker, probe, &poses.camera_T_marker),
            (camera_T_phantom, phantom, &poses.camera_T_phantom),
        ] {
            for (corner, detected) in layout.corners_in_board_mm().iter().zip(&observed.corners_px) {
                let p = camera.project(&(pose * Point3::new(corner.x, corner.y, 0.0))).unwrap();
                errors.push(((p[0] - detected[0]).powi(2) + (p[1] - detected[1]).powi(2)).sqrt());
            }
        }
    }
    let mean = errors.iter().sum::<f64>() / errors.len() as f64;
    let max = errors.iter().cloned().fold(0.0, f64::max);
    println!(
        "board corners: {} corners, error mean {mean:.4} px, max {max:.4} px; {occluded_rejected} occluded photos lost the probe board",
        errors.len()
    );
    // A wrong origin corner or a swapped board would give errors of tens of pixels.
    assert!(mean < 0.1, "mean corner error {mean} px");
    assert!(max < 0.5, "max corner error {max} px");
}

#[test]
#[ignore = "renders datasets (full tier: scripts/test.sh)"]
fn arc_centres_match_the_truth_and_missing_arcs_are_rejected() {
    let (_, folder, truth) = rendered();
    let settings = ArcSettings {
        spacing_mm_per_px: [0.2, 0.2],
        radius_mm: [0.55 * 15.0, 1.15 * 15.0],
        min_span_deg: 40.0,
        max_rms_px: 2.5,
        min_points: 25,
        fixed_radius_mm: Some(15.0),
        peak: probecal::detect::ridge::RidgePeak::Column,
    };
    let mut normal_errors = Vec::new();
    let mut missing = 0;
    for frame in truth["frames"].as_array().unwrap() {
        let k = frame["frame"].as_u64().unwrap();
        let kind = frame["kind"].as_str().unwrap();
        let image = probecal::io::image::read_gray(&folder.join(format!("frames/bscan_{k:03}.png"))).unwrap();
        let result = arc::detect(&image, &settings).unwrap();
        let centre: [f64; 2] = serde_json::from_value(frame["centre_projection_px"].clone()).unwrap();
        match (kind, result) {
            ("missing", Ok(f)) => panic!(
                "frame {k}: the plane misses the sphere but an arc was found at {:?}",
                f.centre_px
            ),
            ("missing", Err(_)) => missing += 1,
            ("normal", Ok(f)) => {
                normal_errors.push(((f.centre_px[0] - centre[0]).powi(2) + (f.centre_px[1] - centre[1]).powi(2)).sqrt())
            }
            ("normal", Err(reason)) => panic!("frame {k}: a clear arc was rejected: {reason}"),
            _ => {}
        }
    }
    let mean = normal_errors.iter().sum::<f64>() / normal_errors.len() as f64;
    let max = normal_errors.iter().cloned().fold(0.0, f64::max);
    println!(
        "arc centres: {} normal frames, error mean {mean:.3} px, max {max:.3} px; {missing} missing arcs rejected",
        normal_errors.len()
    );
    assert!(normal_errors.len() >= 8);
    assert!(mean < 1.0, "mean arc centre error {mean} px");
    assert!(max < 2.5, "max arc centre error {max} px");
}

#[test]
#[ignore = "renders datasets (full tier: scripts/test.sh)"]
fn camera_calibration_of_rendered_views_recovers_the_true_camera() {
    let (_, folder, truth) = rendered();
    let camera = true_camera(&truth);
    let cal = probecal::detect::camera_calibration::calibrate_folder(&folder.join("camera_calibration"), [9, 6], 30.0)
        .unwrap();
    let k = &cal.intrinsics;
    let focal = (k.fx() - camera.fx()).abs().max((k.fy() - camera.fy()).abs());
    let principal = ((k.cx() - camera.cx()).powi(2) + (k.cy() - camera.cy()).powi(2)).sqrt();
    println!(
        "camera: focal error {focal:.3} px, principal point error {principal:.3} px, RMS {:.3} px",
        k.rms_px.unwrap()
    );
    assert!(
        focal < 3.0 && principal < 3.0,
        "focal {focal} px, principal point {principal} px"
    );
    assert!(
        (k.distortion[0] - camera.distortion[0]).abs() < 0.01,
        "k1 {} vs {}",
        k.distortion[0],
        camera.distortion[0]
    );
    assert!(k.rms_px.unwrap() < 0.3);
}

#[test]
#[ignore = "renders datasets (full tier: scripts/test.sh)"]
fn rendering_is_deterministic() {
    let (manifest, folder, _) = rendered();
    let DatasetSource::Render(spec) = &manifest.datasets[0].source else {
        unreachable!()
    };
    let mut one = (**spec).clone();
    one.frames = 2;
    one.calibration_views = 4;
    let a = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("determinism/a");
    let b = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("determinism/b");
    for dir in [&a, &b] {
        let _ = std::fs::remove_dir_all(dir);
        probecal::synth::ensure_rendered(&probecal::pipeline::settings::lab(&manifest), &one, dir).unwrap();
    }
    for file in [
        "frames/camera_001.png",
        "frames/bscan_001.png",
        "camera_calibration/view_003.png",
        "ground_truth.json",
        "frames.csv",
    ] {
        assert_eq!(
            std::fs::read(a.join(file)).unwrap(),
            std::fs::read(b.join(file)).unwrap(),
            "{file} differs between two renders"
        );
    }
    // The first two frames of the 14-frame render are the same scene and pixels
    // (pixels: that render may be a cached folder an earlier build encoded).
    let pixels =
        |path: PathBuf| probecal::io::image::mat_to_gray8(&probecal::io::image::read_gray(&path).unwrap()).unwrap();
    assert_eq!(
        pixels(a.join("frames/bscan_001.png")),
        pixels(folder.join("frames/bscan_001.png"))
    );
}

/// Searching a reduced photo and refining at full size finds the same corners as
/// OpenCV's full-size search (on the single-board calibration views).
#[test]
#[ignore = "renders datasets (full tier: scripts/test.sh)"]
fn reduced_search_finds_the_same_corners() {
    let (_, folder, _) = rendered();
    let subpix = probecal::detect::corners::SubPix::default();
    let mut worst: f64 = 0.0;
    for view in 0..4 {
        let image =
            probecal::io::image::read_gray(&folder.join(format!("camera_calibration/view_{view:03}.png"))).unwrap();
        let full = probecal::detect::corners::detect_chessboard(&image, [9, 6], subpix)
            .unwrap()
            .expect("full size");
        let reduced = probecal::detect::corners::detect_chessboard_reduced(&image, [9, 6], subpix, 1000)
            .unwrap()
            .expect("reduced");
        for (a, b) in full.iter().zip(&reduced) {
            worst = worst.max(((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt());
        }
    }
    println!("reduced vs full-size search: largest corner difference {worst:.4} px");
    assert!(worst < 0.05, "corners differ by up to {worst} px");
}

/// A calibration view whose corners disagree with the others is dropped with its
/// reason and the camera solved again (seed 2's view 5 has a board at the image's
/// edge whose corners fit at 0.95 px while the others fit at 0.1 px).
#[test]
#[ignore = "renders datasets (full tier: scripts/test.sh)"]
fn outlier_calibration_view_is_dropped_with_its_reason() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/hemisphere_checkerboard_dataset2.yaml");
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replace("frames: 20", "frames: 3");
    let manifest = Manifest::from_text(&path, &text).expect("manifest");
    let DatasetSource::Render(spec) = &manifest.datasets[0].source else {
        unreachable!()
    };
    let folder = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("outlier_view/dataset2");
    probecal::synth::ensure_rendered(&probecal::pipeline::settings::lab(&manifest), spec, &folder).expect("render");
    let cal = probecal::detect::camera_calibration::calibrate_folder(&folder.join("camera_calibration"), [9, 6], 30.0)
        .unwrap();
    let dropped: Vec<_> = cal.views.iter().filter(|v| !v.used).collect();
    assert_eq!(dropped.len(), 1, "{:?}", cal.views);
    assert!(dropped[0].image.ends_with("view_005.png"));
    assert!(
        dropped[0].reason.as_deref().unwrap_or("").contains("times the median"),
        "{:?}",
        dropped[0].reason
    );
    let rms = cal.intrinsics.rms_px.unwrap();
    println!("outlier view dropped; RMS after {rms:.3} px");
    assert!(rms < 0.12, "RMS {rms}");
}

#[test]
#[ignore = "renders datasets (full tier: scripts/test.sh)"]
fn a_damaged_rendered_cache_is_rendered_again() {
    use probecal::synth::{ensure_rendered, RenderOutcome};
    let (manifest, _, _) = rendered();
    let DatasetSource::Render(spec) = &manifest.datasets[0].source else {
        unreachable!()
    };
    let mut one = (**spec).clone();
    one.frames = 3;
    one.calibration_views = 4;
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("damaged_cache");
    let _ = std::fs::remove_dir_all(&dir);
    let lab = probecal::pipeline::settings::lab(&manifest);
    assert_eq!(ensure_rendered(&lab, &one, &dir).unwrap(), RenderOutcome::Rendered);
    assert_eq!(ensure_rendered(&lab, &one, &dir).unwrap(), RenderOutcome::UpToDate);
    let photo = dir.join("frames/camera_001.png");
    let good = std::fs::read(&photo).unwrap();
    for (damage, expect) in [
        (Some(good[..good.len() / 2].to_vec()), "frames/camera_001.png has"),
        (None, "frames/camera_001.png is missing"),
        (
            Some([&good[..100], &[0u8; 1][..], &good[101..]].concat()),
            "differs from what was rendered",
        ),
    ] {
        match &damage {
            Some(bytes) => std::fs::write(&photo, bytes).unwrap(),
            None => std::fs::remove_file(&photo).unwrap(),
        }
        match ensure_rendered(&lab, &one, &dir).unwrap() {
            RenderOutcome::Repaired(reason) => assert!(reason.contains(expect), "{reason}"),
            other => panic!("{expect}: {other:?}"),
        }
        assert_eq!(std::fs::read(&photo).unwrap(), good, "rendered again, byte for byte");
    }
}
