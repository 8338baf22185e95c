//! The run against the rendered truth (evaluation only, after every estimate is
//! made): each frame's feature pixels and board poses, and the camera.

use std::collections::BTreeMap;

use crate::core::geometry::{rigid_from_rows, rotation_angle_between_deg, Rigid};
use crate::core::stats::mean_max;
use crate::detect::camera_refinement::calibration_information;
use crate::detect::projection::{intrinsics_vector, IntrinsicsVector};
use crate::estimate::horn::HornFit;
use crate::evaluate::arc_noise::{self, ArcAgainstTruth, ArcNoiseCheck};
use crate::evaluate::sphere_bound::EdgeNoise;
use crate::evaluate::{TrueCalibration, TruthComparison};
use crate::io::truth::{GroundTruth, TruthCamera};
use crate::pipeline::record::{CameraStage, DatasetRun, FrameRecord, FrameTruth, MethodResult, TruthSummary};
use crate::pipeline::settings;

/// The evaluation's view of a rendered dataset's truth.
pub fn true_calibration(t: &GroundTruth) -> TrueCalibration {
    TrueCalibration {
        marker_T_image: t.marker_T_image,
        image_size_px: t.bscan_size_px,
        range_scale: t.range_scale,
        apex_mm: t.bscan_apex_mm,
    }
}

/// How a dome phantom's arcs are checked against the truth: the run's pixel
/// size and the noise model the bound assumes.
pub struct ArcCheck {
    pub spacing_mm_per_px: [f64; 2],
    pub noise: EdgeNoise,
}

/// Scores a finished run against its dataset's truth: each cut-off's
/// calibration, each estimator's, every frame's detections and the camera.
/// Called after every estimate is made, it writes only truth records (the
/// frames' records are read, never written), so no estimator can read the
/// truth: `tests/truth_blind.rs` runs each phantom with and without
/// `ground_truth.json` and requires the same estimates.
pub fn score_run(run: &mut DatasetRun, t: &GroundTruth, arcs_against: &ArcCheck) {
    let truth = true_calibration(t);
    let spacing = run.solve.spacing_mm_per_px;
    for row in &mut run.thresholds {
        row.truth = row
            .fit
            .as_ref()
            .ok()
            .map(|fit| crate::evaluate::compare_mapped(fit, spacing, &truth, spacing));
    }
    for m in &mut run.methods {
        m.truth = Some(method_against(m, spacing, &truth));
    }
    run.truth = run.thresholds[run.primary]
        .truth
        .map(|calibration| score(&run.frames, t, &run.camera, calibration, arcs_against));
}

/// An estimator's error against the truth: its calibration maps pixels with
/// its own pixel size, the truth with the run's (`truth_spacing`).
fn method_against(m: &MethodResult, truth_spacing: [f64; 2], truth: &TrueCalibration) -> TruthComparison {
    let estimate = HornFit {
        target_T_source: m.marker_T_image,
        scale: 1.0,
        rms_residual_mm: 0.0,
    };
    crate::evaluate::compare_mapped(&estimate, m.spacing_mm_per_px, truth, truth_spacing)
}

/// Scores every frame against the truth and sums up the dataset;
/// `calibration` is the reported calibration's comparison.
fn score(
    frames: &[FrameRecord],
    t: &GroundTruth,
    camera: &CameraStage,
    calibration: TruthComparison,
    arcs_against: &ArcCheck,
) -> TruthSummary {
    let mut arc_errors = Vec::new();
    let mut pose_t = Vec::new();
    let mut pose_r = Vec::new();
    let mut phantom_t = Vec::new();
    let mut frame_truths = BTreeMap::new();
    for f in frames {
        let Some(tf) = t.frame(f.files.frame) else { continue };
        let mut ft = FrameTruth {
            kind: tf.kind.clone(),
            elevation_offset_mm: tf.elevation_offset_mm,
            ..FrameTruth::default()
        };
        let distance = |a: [f64; 2], b: [f64; 2]| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt();
        // The feature pixels against the truth: the centre's projection, or each
        // paired wire dot against its wire's true dot.
        let error = if f.wire_labels.is_empty() {
            f.features_px.first().map(|p| distance(*p, tf.centre_projection_px))
        } else {
            let errors: Vec<f64> = f
                .features_px
                .iter()
                .zip(&f.wire_labels)
                .filter_map(|(p, label)| {
                    let dot = tf.wire_dots_px.iter().find(|d| &d.wire == label)?;
                    Some(distance(*p, dot.pixel))
                })
                .collect();
            (!errors.is_empty()).then(|| errors.iter().sum::<f64>() / errors.len() as f64)
        };
        if let Some(e) = error {
            ft.arc_centre_error_px = Some(e);
            if f.rejection.is_none() && tf.kind == "normal" {
                arc_errors.push(e);
            }
        }
        let pose_error = |est: &Rigid, truth: &Rigid| {
            (
                (est.translation.vector - truth.translation.vector).norm(),
                rotation_angle_between_deg(est, truth),
            )
        };
        // A photo's pose is compared with the marker when the photo was taken; a
        // tracker's with the marker at the B-scan (it is synchronised with it).
        let true_marker = if f.tracked.is_some() {
            &tf.camera_T_marker_bscan
        } else {
            &tf.camera_T_marker_photo
        };
        if let (Some((camera_T_marker, camera_T_phantom)), Ok(true_pose)) =
            (f.pose_pair(), rigid_from_rows(true_marker))
        {
            let (dt, dr) = pose_error(&camera_T_marker, &true_pose);
            ft.probe_pose_error = Some((dt, dr));
            ft.probe_depth_error_mm =
                Some((camera_T_marker.translation.vector.z - true_pose.translation.vector.z).abs());
            pose_t.push(dt);
            pose_r.push(dr);
            let (pt, pr) = pose_error(&camera_T_phantom, &t.camera_T_phantom);
            ft.phantom_pose_error = Some((pt, pr));
            phantom_t.push(pt);
        }
        frame_truths.insert(f.files.frame, ft);
    }
    let tk = &t.camera.camera_matrix;
    let arc_noise = arc_noise_check(frames, t, arcs_against);
    TruthSummary {
        calibration,
        frames: frame_truths,
        camera_focal_error_px: camera
            .intrinsics
            .as_ref()
            .map(|k| (k.fx() - tk[0][0]).abs().max((k.fy() - tk[1][1]).abs())),
        camera_principal_error_px: camera
            .intrinsics
            .as_ref()
            .map(|k| ((k.cx() - tk[0][2]).powi(2) + (k.cy() - tk[1][2]).powi(2)).sqrt()),
        camera_intrinsics_nees: camera_nees(camera, &t.camera),
        arc_centre_error_px: mean_max(&arc_errors),
        probe_pose_translation_error_mm: mean_max(&pose_t),
        probe_pose_rotation_error_deg: mean_max(&pose_r),
        phantom_pose_translation_error_mm: mean_max(&phantom_t),
        arc_noise,
    }
}

/// The camera's error against the truth in the uncertainty its calibration
/// states: `(k - k_true)ᵀ I (k - k_true)` over the nine intrinsics, `I` what the
/// calibration's views (and the frames' boards it was refined with) know of
/// them (`camera_refinement::calibration_information`). Where that information
/// is honest this is χ² with nine degrees of freedom: 9 on average, above 21.7
/// one time in a hundred. `None` without a calibration's corners at hand.
fn camera_nees(camera: &CameraStage, truth: &TruthCamera) -> Option<f64> {
    let estimate = intrinsics_vector(camera.intrinsics.as_ref()?);
    let information = calibration_information(camera.calibration.as_ref()?)?;
    let [k1, k2, p1, p2, k3] = truth.distortion;
    let m = truth.camera_matrix;
    let true_k = IntrinsicsVector::from_column_slice(&[m[0][0], m[1][1], m[0][2], m[1][2], k1, k2, p1, p2, k3]);
    let error = estimate - true_k;
    let nees = (error.transpose() * information * error)[(0, 0)];
    nees.is_finite().then_some(nees)
}

/// Every arc of the kept ordinary frames against its sphere's true cut
/// (`evaluate::arc_noise`), the spheres as the truth states them built (a
/// manifest may state them as measured). An arc is its sphere's when the true
/// plane cuts that sphere and its circle's centre lies within half a radius of
/// the centre's true projection; a frame is kept when no stage rejected it. At
/// another speed of sound than the medium's, each displayed point is taken
/// where its echo truly is. `None` for a truth without a dome phantom.
fn arc_noise_check(frames: &[FrameRecord], t: &GroundTruth, check: &ArcCheck) -> Option<ArcNoiseCheck> {
    let spheres = settings::known_spheres(t.phantom.as_ref()?)?;
    let true_calibration = true_calibration(t);
    let [sx, sy] = check.spacing_mm_per_px;
    let in_image_mm = |p: &[f64; 2]| true_calibration.true_point_of_displayed([p[0] * sx, p[1] * sy]);
    let phantom_T_camera = t.camera_T_phantom.inverse();
    let mut arcs = Vec::new();
    for f in frames.iter().filter(|f| f.rejection.is_none()) {
        let Some(tf) = t.frame(f.files.frame).filter(|tf| tf.kind == "normal") else {
            continue;
        };
        let Ok(camera_T_marker) = rigid_from_rows(&tf.camera_T_marker_bscan) else {
            continue;
        };
        let image_T_phantom = (phantom_T_camera * camera_T_marker * t.marker_T_image).inverse();
        let centres: Vec<_> = spheres
            .iter()
            .map(|s| (image_T_phantom * s.centre_in_phantom_mm, s.radius_mm))
            .collect();
        // One arc per B-scan (a hemisphere) is kept as the frame's arc alone.
        let found = if f.arcs.is_empty() { f.arc.as_slice() } else { &f.arcs };
        for arc in found {
            let at = in_image_mm(&arc.centre_px);
            let nearest = centres
                .iter()
                .filter(|(c, radius)| c.z.abs() < *radius)
                .map(|(c, radius)| ((c.x - at[0]).hypot(c.y - at[1]), c, radius))
                .filter(|(distance, _, radius)| *distance < 0.5 * **radius)
                .min_by(|a, b| a.0.total_cmp(&b.0));
            if let Some((_, c, radius)) = nearest {
                arcs.push(ArcAgainstTruth {
                    edge_points_in_image_mm: arc.arc_points_px.iter().map(in_image_mm).collect(),
                    centre_in_image_mm: [c.x, c.y, c.z],
                    radius_mm: *radius,
                });
            }
        }
    }
    arc_noise::check(&arcs, &check.noise)
}
