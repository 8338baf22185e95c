//! The run against the rendered truth (evaluation only, after every estimate is
//! made): each frame's feature pixels and board poses, and the camera.

use super::record::{CameraStage, FrameRecord, TruthSummary};
use crate::core::geometry::{rigid_from_rows, rotation_angle_between_deg, Rigid};
use crate::core::stats::mean_max;
use crate::evaluate::TruthComparison;
use crate::io::truth::GroundTruth;

/// Scores every frame against the truth (kept on its record) and sums up the
/// dataset; `calibration` is the reported calibration's comparison.
pub fn score(
    frames: &mut [FrameRecord],
    t: &GroundTruth,
    camera: &CameraStage,
    calibration: TruthComparison,
) -> TruthSummary {
    let mut arc_errors = Vec::new();
    let mut pose_t = Vec::new();
    let mut pose_r = Vec::new();
    let mut phantom_t = Vec::new();
    for f in frames.iter_mut() {
        let Some(tf) = t.frame(f.files.frame) else { continue };
        f.truth_kind = Some(tf.kind.clone());
        f.truth_elevation_offset_mm = Some(tf.elevation_offset_mm);
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
            f.truth_arc_centre_error_px = Some(e);
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
            f.truth_probe_pose_error = Some((dt, dr));
            f.truth_probe_depth_error_mm =
                Some((camera_T_marker.translation.vector.z - true_pose.translation.vector.z).abs());
            pose_t.push(dt);
            pose_r.push(dr);
            let (pt, pr) = pose_error(&camera_T_phantom, &t.camera_T_phantom);
            f.truth_phantom_pose_error = Some((pt, pr));
            phantom_t.push(pt);
        }
    }
    let tk = &t.camera.camera_matrix;
    TruthSummary {
        calibration,
        camera_focal_error_px: camera
            .intrinsics
            .as_ref()
            .map(|k| (k.fx() - tk[0][0]).abs().max((k.fy() - tk[1][1]).abs())),
        camera_principal_error_px: camera
            .intrinsics
            .as_ref()
            .map(|k| ((k.cx() - tk[0][2]).powi(2) + (k.cy() - tk[1][2]).powi(2)).sqrt()),
        arc_centre_error_px: mean_max(&arc_errors),
        probe_pose_translation_error_mm: mean_max(&pose_t),
        probe_pose_rotation_error_deg: mean_max(&pose_r),
        phantom_pose_translation_error_mm: mean_max(&phantom_t),
    }
}
