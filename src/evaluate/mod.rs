//! Stage 5: how good a calibration is.
//!
//! - BRE (back-projection residual error): per frame and axis of the phantom frame,
//!   `|p - phantom_T_camera · camera_T_marker · marker_T_image · points_in_image|`, mm.
//! - The thesis's threshold table: frames above a BRE cut-off are removed (worst
//!   first, re-solving after each removal, see [`select_below`]); the calibration
//!   of the frames kept and their statistics are reported.
//! - Against ground truth (rendered data): the image's four corners and centre
//!   mapped by the estimated and the true `marker_T_image`; their distances.

pub mod arc_noise;
pub mod block_bootstrap;
pub mod pose_coverage;
pub mod pose_noise;
pub mod resampling;
pub mod sphere_bound;
pub mod wire_profile;

use polars::prelude::*;
use serde::{Deserialize, Serialize};

use crate::core::geometry::{image_probe_points, rotation_angle_between_deg, Rigid};
use crate::estimate::correspondence::{solve, Correspondence};
use crate::estimate::horn::{HornError, HornFit, Variant};

/// The largest per-axis BRE of any feature of a frame, and the largest 3D distance.
fn worst_feature(frame: &Correspondence, calibration: &HornFit, spacing: [f64; 2]) -> ([f64; 3], f64) {
    frame
        .residuals_in_phantom(calibration, spacing)
        .iter()
        .fold(([0.0; 3], 0.0), |(a, n), d| {
            (
                [a[0].max(d.x.abs()), a[1].max(d.y.abs()), a[2].max(d.z.abs())],
                f64::max(n, d.norm()),
            )
        })
}

/// How a frame's BRE is compared with a cut-off.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CutoffRule {
    /// The largest of |x|, |y|, |z| must be below the cut-off.
    MaxAxis,
    /// The 3D distance must be below the cut-off.
    Norm,
}

/// How a cut-off is written in tables: `<∞` or `<2`.
pub fn cutoff_label(cutoff: f64) -> String {
    if cutoff.is_infinite() {
        "<∞".to_string()
    } else {
        format!("<{}", trim_number(cutoff))
    }
}

pub fn trim_number(v: f64) -> String {
    let s = format!("{v}");
    s.trim_end_matches(".0").to_string()
}

/// Std (n − 1), mean, min, max of one axis, mm.
#[derive(Debug, Clone, Copy, Default, Serialize, Deserialize, PartialEq)]
pub struct AxisStats {
    pub std: f64,
    pub mean: f64,
    pub min: f64,
    pub max: f64,
}

/// Reads one statistic of an axis.
pub type StatGetter = fn(&AxisStats) -> f64;

/// The thesis's rows, in its order.
pub const STAT_ROWS: [(&str, StatGetter); 4] = [
    ("Std.", |a| a.std),
    ("Mean", |a| a.mean),
    ("Min", |a| a.min),
    ("Max", |a| a.max),
];

/// BRE statistics along x, y, z of the phantom frame.
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct BreStats {
    pub x: AxisStats,
    pub y: AxisStats,
    pub z: AxisStats,
}

impl BreStats {
    pub fn axes(&self) -> [AxisStats; 3] {
        [self.x, self.y, self.z]
    }
    /// The largest of the three axis means.
    pub fn max_mean(&self) -> f64 {
        self.x.mean.max(self.y.mean).max(self.z.mean)
    }
}

fn axis_stats(column: &Column) -> PolarsResult<AxisStats> {
    let s = column.as_materialized_series();
    Ok(AxisStats {
        std: s.std(1).unwrap_or(f64::NAN),
        mean: s.mean().unwrap_or(f64::NAN),
        min: s.min::<f64>()?.unwrap_or(f64::NAN),
        max: s.max::<f64>()?.unwrap_or(f64::NAN),
    })
}

/// Statistics of per-frame BRE values (columns `x`, `y`, `z`) with polars.
pub fn bre_stats(values: &[[f64; 3]]) -> PolarsResult<BreStats> {
    let column = |i: usize, name: &str| Column::new(name.into(), values.iter().map(|v| v[i]).collect::<Vec<f64>>());
    let df = DataFrame::new(values.len(), vec![column(0, "x"), column(1, "y"), column(2, "z")])?;
    Ok(BreStats {
        x: axis_stats(df.column("x")?)?,
        y: axis_stats(df.column("y")?)?,
        z: axis_stats(df.column("z")?)?,
    })
}

/// Error of an estimate against the truth.
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct TruthComparison {
    /// Over the image's four corners and its centre.
    pub corner_error_mean_mm: f64,
    pub corner_error_max_mm: f64,
    pub rotation_error_deg: f64,
    pub translation_error_mm: f64,
    /// The same error along the image's own axes.
    pub in_image: ImageFrameError,
}

/// A calibration's error as a motion of the image plane: `true_image_T_image`,
/// `marker_T_image_true⁻¹ · marker_T_image` (rigid parts), which carries a
/// point of the estimated image to where the truth puts it. Its rotation
/// vector is about the image's axes (x lateral, y along the beam, z the plane's
/// normal: a rotation about x tilts the plane up or down the depth), its
/// translation along them; a point `p` of the image moves by `ω × p + t`.
#[derive(Debug, Clone, Copy, Default, Serialize, Deserialize, PartialEq)]
pub struct ImageFrameError {
    pub rotation_about_image_axes_deg: [f64; 3],
    pub translation_in_image_mm: [f64; 3],
}

impl ImageFrameError {
    pub fn between(marker_T_image: &Rigid, true_marker_T_image: &Rigid) -> ImageFrameError {
        let true_image_T_image = true_marker_T_image.inverse() * marker_T_image;
        let rotation = true_image_T_image.rotation.scaled_axis();
        let t = true_image_T_image.translation.vector;
        ImageFrameError {
            rotation_about_image_axes_deg: [rotation.x, rotation.y, rotation.z].map(f64::to_degrees),
            translation_in_image_mm: [t.x, t.y, t.z],
        }
    }
}

pub fn compare_with_truth(
    estimate: &HornFit,
    truth: &Rigid,
    image_size_px: [usize; 2],
    spacing: [f64; 2],
) -> TruthComparison {
    compare_mapped(
        estimate,
        spacing,
        &TrueCalibration::rigid(*truth, image_size_px),
        spacing,
    )
}

/// The true calibration of a rendered dataset (evaluation only): the marker's
/// pose of the image plane, the B-scan's size, and where the scanner displays
/// echoes when its speed of sound is not the medium's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrueCalibration {
    pub marker_T_image: Rigid,
    pub image_size_px: [usize; 2],
    /// True range per displayed range from the transducer face (1: exact).
    pub range_scale: f64,
    /// The fan's virtual apex in the image frame (mm); its distance to the
    /// transducer face is the convex radius.
    pub apex_mm: [f64; 2],
}

impl TrueCalibration {
    /// A truth where every pixel is where the pixel size puts it.
    pub fn rigid(marker_T_image: Rigid, image_size_px: [usize; 2]) -> TrueCalibration {
        TrueCalibration {
            marker_T_image,
            image_size_px,
            range_scale: 1.0,
            apex_mm: [0.0, 0.0],
        }
    }

    /// Where the echoes displayed at the image's corners and centre truly come
    /// from, in the image frame (mm), for a raster of pixel size `spacing`.
    pub fn points_in_image_mm(&self, spacing: [f64; 2]) -> [nalgebra::Point3<f64>; 5] {
        let shown = image_probe_points(self.image_size_px, spacing);
        if self.range_scale == 1.0 {
            return shown;
        }
        shown.map(|p| {
            let [u, v] = self.true_point_of_displayed([p.x, p.y]);
            nalgebra::Point3::new(u, v, 0.0)
        })
    }

    /// Where an echo displayed at `shown_mm` (image frame) truly is: its range
    /// from the transducer face scaled by `range_scale` along its beam (where
    /// it is shown, exactly, at a scale of 1).
    pub fn true_point_of_displayed(&self, shown_mm: [f64; 2]) -> [f64; 2] {
        if self.range_scale == 1.0 {
            return shown_mm;
        }
        let [ax, ay] = self.apex_mm;
        let face = -ay;
        let (dx, dy) = (shown_mm[0] - ax, shown_mm[1] - ay);
        let r = (dx * dx + dy * dy).sqrt();
        let true_r = face + (r - face) * self.range_scale;
        let k = if r > 0.0 { true_r / r } else { 1.0 };
        [ax + dx * k, ay + dy * k]
    }
}

/// The same, for an estimate that maps pixels with its own pixel size
/// (`spacing`, e.g. estimated) while the truth's raster has `truth_spacing`.
pub fn compare_mapped(
    estimate: &HornFit,
    spacing: [f64; 2],
    truth: &TrueCalibration,
    truth_spacing: [f64; 2],
) -> TruthComparison {
    let estimated = image_probe_points(truth.image_size_px, spacing);
    let true_points = truth.points_in_image_mm(truth_spacing);
    let marker_T_image = &truth.marker_T_image;
    let distances: Vec<f64> = estimated
        .iter()
        .zip(&true_points)
        .map(|(e, t)| (estimate.apply(e) - marker_T_image * t).norm())
        .collect();
    TruthComparison {
        corner_error_mean_mm: distances.iter().sum::<f64>() / distances.len() as f64,
        corner_error_max_mm: distances.iter().cloned().fold(0.0, f64::max),
        rotation_error_deg: rotation_angle_between_deg(&estimate.target_T_source, marker_T_image),
        translation_error_mm: (estimate.target_T_source.translation.vector - marker_T_image.translation.vector).norm(),
        in_image: ImageFrameError::between(&estimate.target_T_source, marker_T_image),
    }
}

/// One row of the threshold table.
#[derive(Debug, Clone, Serialize)]
pub struct ThresholdRow {
    /// `inf` for all frames.
    pub cutoff_mm: f64,
    /// Frames whose all-frames BRE is below the cut-off.
    pub frames: Vec<usize>,
    /// The calibration solved again on those frames, or why it could not be.
    #[serde(skip)]
    pub fit: Result<HornFit, HornError>,
    pub stats: Option<BreStats>,
    pub truth: Option<TruthComparison>,
}

/// What the evaluation needs besides the frames.
pub struct EvaluationInputs<'a> {
    /// Where the line fit starts (wire phantoms).
    pub start: Option<Rigid>,
    pub spacing: [f64; 2],
    pub cutoffs_mm: &'a [f64],
    pub rule: CutoffRule,
    pub min_frames: usize,
    pub variant: Variant,
}

impl CutoffRule {
    /// A frame's BRE as the rule measures it; not a number when any of its
    /// components is not (`f64::max` alone would drop a NaN axis).
    pub fn measure(self, bre_axes: &[f64; 3], norm: f64) -> f64 {
        match self {
            CutoffRule::MaxAxis if bre_axes.iter().any(|v| v.is_nan()) => f64::NAN,
            CutoffRule::MaxAxis => bre_axes.iter().cloned().fold(0.0, f64::max),
            CutoffRule::Norm => norm,
        }
    }

    /// Whether a measured BRE is below a cut-off: a value that is not a number
    /// never is.
    pub fn below(value: f64, cutoff_mm: f64) -> bool {
        value < cutoff_mm
    }
}

/// The frames kept below a cut-off and their calibration. Starting from all frames,
/// the frame with the largest BRE under the calibration of the frames still kept
/// is dropped, one at a time, re-solving after each drop, until every kept frame
/// is below the cut-off. (One gross outlier inflates every frame's BRE under the
/// all-frames calibration; dropping worst-first removes it before judging the rest.)
pub fn select_below(
    frames: &[Correspondence],
    cutoff: f64,
    inputs: &EvaluationInputs<'_>,
) -> (Vec<Correspondence>, Result<HornFit, HornError>) {
    let mut kept = frames.to_vec();
    loop {
        if kept.len() < inputs.min_frames {
            return (kept.clone(), Err(HornError::TooFewPairs(kept.len())));
        }
        let fit = match solve(&kept, inputs.spacing, inputs.variant, inputs.start.as_ref()) {
            Ok(fit) => fit,
            Err(e) => return (kept, Err(e)),
        };
        let worst = kept
            .iter()
            .enumerate()
            .map(|(i, f)| {
                let (axes, norm) = worst_feature(f, &fit, inputs.spacing);
                (i, inputs.rule.measure(&axes, norm))
            })
            .max_by(|a, b| a.1.total_cmp(&b.1));
        match worst {
            // NaN sorts above every number, so a frame whose BRE is not a number
            // goes first.
            Some((i, value)) if !CutoffRule::below(value, cutoff) => {
                kept.remove(i);
            }
            _ => return (kept, Ok(fit)),
        }
    }
}

/// The threshold table: for each cut-off, the frames kept, their calibration,
/// and its BRE statistics. The error against the truth (rendered data) is
/// scored after every estimate is made (`pipeline::truth::score_run`).
pub fn threshold_table(frames: &[Correspondence], inputs: &EvaluationInputs<'_>) -> PolarsResult<Vec<ThresholdRow>> {
    let mut rows = Vec::new();
    for &cutoff in inputs.cutoffs_mm {
        let (kept, fit) = select_below(frames, cutoff, inputs);
        let stats = match &fit {
            Ok(fit) => {
                // One sample per feature (the thesis's one per frame, for one feature a frame).
                let values: Vec<[f64; 3]> = kept
                    .iter()
                    .flat_map(|f| f.residuals_in_phantom(fit, inputs.spacing))
                    .map(|d| [d.x.abs(), d.y.abs(), d.z.abs()])
                    .collect();
                Some(bre_stats(&values)?)
            }
            Err(_) => None,
        };
        rows.push(ThresholdRow {
            cutoff_mm: cutoff,
            frames: kept.iter().map(|f| f.frame).collect(),
            fit,
            stats,
            truth: None,
        });
    }
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::geometry::pixel_to_image_mm;
    use crate::core::geometry::rigid_from_axis_angle;
    use crate::estimate::correspondence::bre;
    use nalgebra::{Point3, Vector3};

    #[test]
    fn the_error_in_the_image_frame_is_the_planted_tilt_and_shift() {
        let truth = rigid_from_axis_angle(Vector3::new(0.02, -0.03, 1.5), Vector3::new(-20.0, 160.0, 25.0));
        // The estimate's image is the true one tilted 0.2° about its lateral
        // axis and 0.3 mm off along its normal.
        let moved = rigid_from_axis_angle(
            Vector3::new(0.2f64.to_radians(), 0.0, 0.0),
            Vector3::new(0.0, 0.0, -0.3),
        );
        let estimate = truth * moved;
        let e = ImageFrameError::between(&estimate, &truth);
        let [rx, ry, rz] = e.rotation_about_image_axes_deg;
        assert!((rx - 0.2).abs() < 1e-9 && ry.abs() < 1e-9 && rz.abs() < 1e-9, "{e:?}");
        let [tx, ty, tz] = e.translation_in_image_mm;
        assert!(tx.abs() < 1e-9 && ty.abs() < 1e-9 && (tz + 0.3).abs() < 1e-9, "{e:?}");
        // A point of the estimated image lands where ω × p + t says, to first order.
        let p = Point3::new(40.0, 100.0, 0.0);
        let shift = truth.inverse() * (estimate * p) - p;
        let predicted = Vector3::new(rx, ry, rz).map(f64::to_radians).cross(&p.coords) + Vector3::new(tx, ty, tz);
        // (The second-order term here is θ² · 100 mm / 2 = 0.0006 mm.)
        assert!((shift - predicted).norm() < 1e-3, "{shift} vs {predicted}");
        let none = ImageFrameError::between(&truth, &truth);
        let size = |v: [f64; 3]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
        assert!(size(none.rotation_about_image_axes_deg) < 1e-9 && size(none.translation_in_image_mm) < 1e-9);
    }

    #[test]
    fn a_bre_that_is_not_a_number_passes_no_cut_off() {
        for rule in [CutoffRule::MaxAxis, CutoffRule::Norm] {
            let nan = rule.measure(&[0.1, f64::NAN, 0.2], f64::NAN);
            assert!(nan.is_nan(), "{rule:?}");
            assert!(!CutoffRule::below(nan, 1.0) && !CutoffRule::below(nan, f64::INFINITY));
            assert!(CutoffRule::below(rule.measure(&[0.1, 0.3, 0.2], 0.4), 1.0));
        }
        assert_eq!(CutoffRule::MaxAxis.measure(&[0.1, 0.3, 0.2], 9.0), 0.3);
    }

    #[test]
    fn stats_match_hand_computation() {
        let s = bre_stats(&[[1.0, 0.0, 2.0], [3.0, 0.0, 2.0], [5.0, 3.0, 2.0]]).unwrap();
        assert_eq!(s.x.mean, 3.0);
        assert_eq!(s.x.std, 2.0); // sample std (n - 1)
        assert_eq!((s.y.min, s.y.max), (0.0, 3.0));
        assert_eq!(s.z.std, 0.0);
    }

    #[test]
    fn exact_frames_give_zero_bre_and_exact_calibration() {
        let marker_T_image = rigid_from_axis_angle(Vector3::new(0.02, -0.03, 0.01), Vector3::new(-20.0, 160.0, 25.0));
        let camera_T_phantom = rigid_from_axis_angle(Vector3::new(2.0, 0.1, 0.2), Vector3::new(-100.0, 80.0, 500.0));
        let feature = Point3::new(60.0, 45.0, -40.0);
        let spacing = [0.2, 0.2];
        let frames: Vec<Correspondence> = (0..8)
            .map(|k| {
                let px = [300.0 + 40.0 * (k % 3) as f64, 250.0 + 30.0 * (k / 3) as f64];
                // Build a marker pose that puts this pixel exactly on the feature.
                let rot = rigid_from_axis_angle(Vector3::new(0.1 * k as f64, -0.05 * k as f64, 0.02), Vector3::zeros());
                let in_image = pixel_to_image_mm(px, spacing);
                let phantom_T_image_rot = rot.rotation;
                let t = feature.coords - phantom_T_image_rot * in_image.coords;
                let phantom_T_image = Rigid::from_parts(t.into(), phantom_T_image_rot);
                let camera_T_marker = camera_T_phantom * phantom_T_image * marker_T_image.inverse();
                Correspondence::point(k, px, feature, camera_T_marker, camera_T_phantom)
            })
            .collect();
        let fit = solve(&frames, spacing, Variant::Rigid, None).unwrap();
        let cmp = compare_with_truth(&fit, &marker_T_image, [800, 600], spacing);
        assert!(cmp.corner_error_max_mm < 1e-8, "{cmp:?}");
        for f in &frames {
            assert!(bre(f, &fit, spacing).1 < 1e-8);
        }
    }
}
