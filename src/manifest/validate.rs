//! `Manifest::load`'s checks, section by section: what serde cannot check
//! (units, positivity, ordering, files that must exist), every problem located.

use crate::spec::phantom::Phantom;
use crate::spec::render::{RenderSpec, RENDERED_TRACKER_POSES};
use crate::spec::rig::{Board, Rig};
use raw::SolveVariant;
use std::path::{Path, PathBuf};

use super::*;
use crate::core::limits::{MAX_CALIBRATION_VIEWS, MAX_FRAMES, MAX_IMAGE_PIXELS};

pub(super) fn validate(c: &mut Checker<'_>, base: &Path, raw: raw::RawManifest, path: &Path, text: &str) -> Manifest {
    c.name("experiment", &raw.experiment);
    phantom_section(c, &raw);
    solve_section(c, &raw);
    let rig = super::rig_check::rig_section(c, base, &raw);
    let camera = poses_section(c, base, &raw);
    let spacing = raw.bscan.spacing_mm_per_px;
    c.positive("bscan.spacing_mm_per_px[0]", spacing[0]);
    c.positive("bscan.spacing_mm_per_px[1]", spacing[1]);
    let arc = raw.bscan.arc_detection.clone();
    c.range("bscan.arc_detection.radius_fraction", arc.radius_fraction);
    c.at_least("bscan.arc_detection.min_span_deg", arc.min_span_deg, 1.0);
    c.positive("bscan.arc_detection.max_rms_px", arc.max_rms_px);
    c.at_least("bscan.arc_detection.min_points", arc.min_points as f64, 5.0);

    let calibration_cutoff_mm = thresholds_section(c, &raw.thresholds);
    let t = &raw.thresholds;
    let datasets = datasets_section(c, base, &raw, &camera);
    Manifest {
        path: path.to_path_buf(),
        sha256: sha256_hex(text.as_bytes()),
        text: text.to_string(),
        experiment: raw.experiment,
        description: raw.description,
        phantom: raw.phantom,
        rig,
        camera,
        bscan_spacing_mm_per_px: spacing,
        arc_detection: arc,
        thresholds: Thresholds {
            bre_cutoffs_mm: t.bre_cutoffs_mm.clone(),
            cutoff_rule: t.cutoff_rule,
            calibration_cutoff_mm,
            min_frames: t.min_frames,
            gates: t.gates.clone(),
            regression: t.regression.clone(),
        },
        solve_variant: raw.solve.variant,
        initial_marker_T_image: raw
            .solve
            .initial_marker_T_image
            .as_ref()
            .map(crate::synth::scene::true_transform),
        robust: raw.solve.robust,
        sphere_fit: raw.solve.sphere_fit.clone(),
        validation: raw.solve.validation.clone(),
        datasets,
    }
}

/// The camera section: an intrinsics file, or a calibration from board views.
fn camera_source(c: &mut Checker<'_>, base: &Path, camera: &raw::RawCamera, raw_rig: &Rig) -> CameraSource {
    match (&camera.intrinsics_file, &camera.calibrate) {
        (Some(file), None) => CameraSource::IntrinsicsFile(c.existing("camera.intrinsics_file", base, file, false)),
        (None, Some(cal)) => {
            c.board(
                "camera.calibrate",
                &Board {
                    inner_corners: cal.inner_corners,
                    square_mm: cal.square_mm,
                    id_dots: 0,
                },
            );
            if cal.refine_with_frames && !matches!(raw_rig, Rig::Checkerboard { .. }) {
                c.fail(
                    "camera.calibrate.refine_with_frames",
                    "the frames' boards refine the intrinsics on a checkerboard rig only",
                );
            }
            let images = cal
                .images
                .as_ref()
                .map(|f| c.existing("camera.calibrate.images", base, f, true));
            CameraSource::Calibrate {
                images,
                board: cal.clone(),
            }
        }
        _ => {
            c.fail("camera", "give exactly one of `intrinsics_file` or `calibrate`");
            CameraSource::IntrinsicsFile(PathBuf::new())
        }
    }
}

fn validate_render(c: &mut Checker<'_>, field: &str, spec: &RenderSpec) {
    if spec.frames < 3 {
        c.fail(
            &format!("{field}.frames"),
            format!("at least 3 frames are needed, got {}", spec.frames),
        );
    }
    if spec.frames > MAX_FRAMES {
        c.fail(
            &format!("{field}.frames"),
            format!("at most {MAX_FRAMES} frames, got {}", spec.frames),
        );
    }
    if spec.calibration_views > MAX_CALIBRATION_VIEWS {
        c.fail(
            &format!("{field}.calibration_views"),
            format!("at most {MAX_CALIBRATION_VIEWS} views, got {}", spec.calibration_views),
        );
    }
    let pixels = spec.camera.image_size_px[0] as u64 * spec.camera.image_size_px[1] as u64;
    if pixels > MAX_IMAGE_PIXELS {
        c.fail(
            &format!("{field}.camera.image_size_px"),
            format!("at most {MAX_IMAGE_PIXELS} pixels, got {pixels}"),
        );
    }
    if spec.calibration_views < 4 {
        c.fail(
            &format!("{field}.calibration_views"),
            format!(
                "camera calibration needs at least 4 views, got {}",
                spec.calibration_views
            ),
        );
    }
    let cam = &spec.camera;
    if cam.image_size_px[0] < 64 || cam.image_size_px[1] < 64 {
        c.fail(
            &format!("{field}.camera.image_size_px"),
            "must be at least 64x64 pixels",
        );
    }
    c.positive(&format!("{field}.camera.focal_px"), cam.focal_px);
    c.finite(&format!("{field}.camera.distortion"), &cam.distortion);
    c.at_least(&format!("{field}.camera.noise_grey_levels"), cam.noise_grey_levels, 0.0);
    c.at_least(&format!("{field}.camera.blur_sigma_px"), cam.blur_sigma_px, 0.0);
    c.range(&format!("{field}.board_distance_mm"), spec.board_distance_mm);
    c.at_least(
        &format!("{field}.tracker.position_sd_mm"),
        spec.tracker.position_sd_mm,
        0.0,
    );
    c.at_least(
        &format!("{field}.tracker.rotation_sd_deg"),
        spec.tracker.rotation_sd_deg,
        0.0,
    );
    let s = &spec.sweep;
    for (name, v) in [
        ("tilt_x_deg", s.tilt_x_deg),
        ("tilt_y_deg", s.tilt_y_deg),
        ("rotation_z_deg", s.rotation_z_deg),
        ("elevation_offset_sd_mm", s.elevation_offset_sd_mm),
        ("tremor_mm", s.tremor_mm),
        ("tremor_deg", s.tremor_deg),
    ] {
        c.at_least(&format!("{field}.sweep.{name}"), v, 0.0);
    }
    validate_bscan(c, field, spec);
    if let Some(t) = &spec.marker_T_image {
        c.finite(&format!("{field}.marker_T_image.rotation_deg"), &t.rotation_deg);
        c.finite(&format!("{field}.marker_T_image.translation_mm"), &t.translation_mm);
    }
    if let Some(r) = &spec.realism {
        super::realism::check(c, &format!("{field}.realism"), r);
    }
}

/// The rendered B-scans' geometry and the rates of their faults.
fn validate_bscan(c: &mut Checker<'_>, field: &str, spec: &RenderSpec) {
    let b = &spec.bscan;
    c.positive(&format!("{field}.bscan.depth_mm"), b.depth_mm);
    if !(b.fan_deg > 0.0 && b.fan_deg < 170.0) {
        c.fail(
            &format!("{field}.bscan.fan_deg"),
            format!("must be between 0 and 170 degrees, got {}", b.fan_deg),
        );
    }
    c.positive(&format!("{field}.bscan.convex_radius_mm"), b.convex_radius_mm);
    c.at_least(&format!("{field}.bscan.slice_thickness_mm"), b.slice_thickness_mm, 0.0);
    if !(0.0..=1.0).contains(&spec.occlusion_rate) {
        c.fail(
            &format!("{field}.occlusion_rate"),
            format!("must be a fraction between 0 and 1, got {}", spec.occlusion_rate),
        );
    }
    if let Some(o) = &spec.occluders {
        for (name, rate) in [
            ("hand_rate", o.hand_rate),
            ("cable_rate", o.cable_rate),
            ("rim_rate", o.rim_rate),
        ] {
            if !(0.0..=1.0).contains(&rate) {
                c.fail(
                    &format!("{field}.occluders.{name}"),
                    format!("must be a fraction between 0 and 1, got {rate}"),
                );
            }
        }
    }
    for (name, v) in [
        ("outlier_rate", b.outlier_rate),
        ("missing_rate", b.missing_rate),
        ("bubble_rate", b.bubble_rate),
    ] {
        if !(0.0..=1.0).contains(&v) {
            c.fail(
                &format!("{field}.bscan.{name}"),
                format!("must be a fraction between 0 and 1, got {v}"),
            );
        }
    }
}

/// The phantom section: finite positions, positive sizes, wires that are lines.
fn phantom_section(c: &mut Checker<'_>, raw: &raw::RawManifest) {
    match &raw.phantom {
        Phantom::Hemisphere {
            centre_in_phantom_mm,
            radius_mm,
        } => {
            c.finite("phantom.hemisphere.centre_in_phantom_mm", centre_in_phantom_mm);
            c.positive("phantom.hemisphere.radius_mm", *radius_mm);
        }
        Phantom::Point {
            position_in_phantom_mm,
            head_radius_mm,
        } => {
            c.finite("phantom.point.position_in_phantom_mm", position_in_phantom_mm);
            c.positive("phantom.point.head_radius_mm", *head_radius_mm);
        }
        Phantom::Spheres { spheres } => super::spheres::check(c, raw, spheres),
        Phantom::FourWire {
            wires,
            wire_diameter_mm,
        } => {
            c.positive("phantom.four_wire.wire_diameter_mm", *wire_diameter_mm);
            if wires.len() < 3 {
                c.fail(
                    "phantom.four_wire.wires",
                    format!(
                        "needs at least 3 wires, not all parallel (got {}): dots on parallel wires leave the position along them unknown",
                        wires.len()
                    ),
                );
            }
            let mut directions = Vec::new();
            for (i, w) in wires.iter().enumerate() {
                let field = format!("phantom.four_wire.wires[{i}]");
                c.finite(&format!("{field}.start_in_phantom_mm"), &w.start_in_phantom_mm);
                c.finite(&format!("{field}.end_in_phantom_mm"), &w.end_in_phantom_mm);
                let d = nalgebra::Vector3::from(w.end_in_phantom_mm) - nalgebra::Vector3::from(w.start_in_phantom_mm);
                if d.norm().is_nan() || d.norm() <= 1.0 {
                    c.fail(
                        &format!("{field}.end_in_phantom_mm"),
                        "must be at least 1 mm from the start",
                    );
                } else {
                    directions.push(d.normalize());
                }
                if wires[..i].iter().any(|o| o.name == w.name) {
                    c.fail(&format!("{field}.name"), format!("`{}` names two wires", w.name));
                }
            }
            if wires.len() >= 3
                && directions.len() == wires.len()
                && directions.iter().all(|d| d.cross(&directions[0]).norm() < 1e-3)
            {
                c.fail(
                    "phantom.four_wire.wires",
                    "all wires are parallel: the position along them cannot be found",
                );
            }
            if raw.solve.initial_marker_T_image.is_none() {
                c.fail(
                    "solve.initial_marker_T_image",
                    "the four_wire phantom needs a rough marker_T_image to match dots to wires (rotation_deg, translation_mm)",
                );
            }
            if raw.solve.variant != SolveVariant::Rigid {
                c.fail(
                    "solve.variant",
                    "the four_wire phantom is solved rigid (the pixel spacing is trusted)",
                );
            }
        }
    }
}

/// The solve section: robust estimation, the sphere fit, resampling, the start guess.
fn solve_section(c: &mut Checker<'_>, raw: &raw::RawManifest) {
    let r = &raw.solve.robust;
    if let Some(t) = r.threshold_mm {
        c.positive("solve.robust.threshold_mm", t);
    }
    c.positive("solve.robust.noise_sd_mm", r.noise_sd_mm);
    c.at_least("solve.robust.samples", r.samples as f64, 1.0);
    if let Some(name) = &raw.thresholds.gates.method {
        if !raw::ESTIMATOR_NAMES.contains(&name.as_str()) {
            c.fail(
                "thresholds.gates.method",
                format!(
                    "`{name}` is not an estimator; one of: {}",
                    raw::ESTIMATOR_NAMES.join(", ")
                ),
            );
        }
    }
    super::spheres::fit_options(c, raw);
    if let Some(sd) = raw.solve.sphere_fit.elevation_prior_sd_mm {
        c.positive("solve.sphere_fit.elevation_prior_sd_mm", sd);
    }
    c.at_least(
        "solve.validation.bootstrap_resamples",
        raw.solve.validation.bootstrap_resamples as f64,
        20.0,
    );
    c.at_least(
        "solve.validation.cr_half_splits",
        raw.solve.validation.cr_half_splits as f64,
        1.0,
    );
    if let Some(t) = &raw.solve.initial_marker_T_image {
        c.finite("solve.initial_marker_T_image.rotation_deg", &t.rotation_deg);
        c.finite("solve.initial_marker_T_image.translation_mm", &t.translation_mm);
    }
}

/// Where the poses come from: the camera (an intrinsics file or a calibration),
/// or a tracker's CSV.
fn poses_section(c: &mut Checker<'_>, base: &Path, raw: &raw::RawManifest) -> CameraSource {
    match (&raw.camera, &raw.poses) {
        (Some(camera), None) => camera_source(c, base, camera, &raw.rig),
        (None, Some(poses)) => {
            let t = &poses.tracker_csv;
            let f = "poses.tracker_csv";
            if t.file.trim().is_empty() {
                c.fail(&format!("{f}.file"), "must name a file inside each dataset folder");
            }
            for (field, name) in [
                ("probe_transform", &t.probe_transform),
                ("reference_transform", &t.reference_transform),
            ] {
                if name.trim().is_empty() || name.contains(',') {
                    c.fail(&format!("{f}.{field}"), "must be a transform name without commas");
                }
            }
            if t.probe_transform == t.reference_transform {
                c.fail(
                    &format!("{f}.reference_transform"),
                    "must differ from probe_transform: the probe and the phantom carry different markers",
                );
            }
            CameraSource::TrackerCsv(t.clone())
        }
        (Some(_), Some(_)) => {
            c.fail(
                "poses",
                "give `camera` (poses from photos) or `poses` (from a tracker), not both",
            );
            CameraSource::IntrinsicsFile(PathBuf::new())
        }
        (None, None) => {
            c.fail("camera", "is needed (or `poses.tracker_csv` for poses from a tracker)");
            CameraSource::IntrinsicsFile(PathBuf::new())
        }
    }
}

/// The thresholds section; the calibration cut-off (infinity when not given).
fn thresholds_section(c: &mut Checker<'_>, t: &raw::RawThresholds) -> f64 {
    if t.bre_cutoffs_mm.is_empty() {
        c.fail(
            "thresholds.bre_cutoffs_mm",
            "needs at least one cut-off (use .inf for all frames)",
        );
    }
    for (i, w) in t.bre_cutoffs_mm.windows(2).enumerate() {
        if w[1] >= w[0] {
            c.fail(
                &format!("thresholds.bre_cutoffs_mm[{}]", i + 1),
                format!("cut-offs must be strictly descending, but {} follows {}", w[1], w[0]),
            );
        }
    }
    for (i, v) in t.bre_cutoffs_mm.iter().enumerate() {
        if v.is_nan() || *v <= 0.0 {
            c.fail(
                &format!("thresholds.bre_cutoffs_mm[{i}]"),
                format!("must be positive (or .inf), got {v}"),
            );
        }
    }
    let calibration_cutoff_mm = t.calibration_cutoff_mm.unwrap_or(f64::INFINITY);
    if !t.bre_cutoffs_mm.contains(&calibration_cutoff_mm) {
        c.fail(
            "thresholds.calibration_cutoff_mm",
            format!("must be one of bre_cutoffs_mm, got {calibration_cutoff_mm}"),
        );
    }
    if t.min_frames < 3 {
        c.fail(
            "thresholds.min_frames",
            format!("Horn's solution needs at least 3 frames, got {}", t.min_frames),
        );
    }
    let r = &t.regression;
    for (field, value) in [
        ("thresholds.regression.bre_mean_mm", r.bre_mean_mm),
        ("thresholds.regression.truth_corner_error_mm", r.truth_corner_error_mm),
        (
            "thresholds.regression.truth_rotation_error_deg",
            r.truth_rotation_error_deg,
        ),
        ("thresholds.regression.frames_rejected", r.frames_rejected),
        ("thresholds.regression.pre3d_mm", r.pre3d_mm),
    ] {
        c.at_least(field, value, 0.0);
    }
    for (field, value) in [
        ("thresholds.gates.truth_corner_error_mm", t.gates.truth_corner_error_mm),
        (
            "thresholds.gates.truth_rotation_error_deg",
            t.gates.truth_rotation_error_deg,
        ),
        ("thresholds.gates.bre_mean_mm", t.gates.bre_mean_mm),
    ] {
        if let Some(v) = value {
            c.positive(field, v);
        }
    }
    calibration_cutoff_mm
}

/// The datasets: unique safe names, one source each, and what the camera or the
/// tracker needs of them.
fn datasets_section(c: &mut Checker<'_>, base: &Path, raw: &raw::RawManifest, camera: &CameraSource) -> Vec<Dataset> {
    if raw.datasets.is_empty() {
        c.fail("datasets", "lists no dataset");
    }
    let mut datasets = Vec::new();
    for (i, d) in raw.datasets.iter().enumerate() {
        let field = format!("datasets[{i}]");
        c.name(&format!("{field}.name"), &d.name);
        if raw.datasets[..i].iter().any(|o| o.name == d.name) {
            c.fail(
                &format!("{field}.name"),
                format!("dataset name `{}` is used twice", d.name),
            );
        }
        let source = match (&d.render, &d.folder) {
            (Some(spec), None) => {
                validate_render(c, &format!("{field}.render"), spec);
                DatasetSource::Render(Box::new(spec.clone()))
            }
            (None, Some(folder)) => DatasetSource::Folder(c.existing(&format!("{field}.folder"), base, folder, true)),
            _ => {
                c.fail(
                    &field,
                    "give exactly one of `render` (a generator spec) or `folder` (recorded files)",
                );
                continue;
            }
        };
        datasets.push(Dataset {
            name: d.name.clone(),
            source,
        });
    }
    if matches!(*camera, CameraSource::Calibrate { images: None, .. })
        && datasets.iter().any(|d| matches!(d.source, DatasetSource::Folder(_)))
    {
        // A recorded folder must bring its calibration views or the manifest must name them.
        for (i, d) in datasets.iter().enumerate() {
            if let DatasetSource::Folder(folder) = &d.source {
                if !folder.join("camera_calibration").is_dir() {
                    c.fail(
                        &format!("datasets[{i}].folder"),
                        "has no camera_calibration/ folder; set camera.calibrate.images or camera.intrinsics_file",
                    );
                }
            }
        }
    }

    if let CameraSource::TrackerCsv(t) = camera {
        for (i, d) in datasets.iter().enumerate() {
            match &d.source {
                DatasetSource::Folder(folder) if !folder.join(&t.file).is_file() => c.fail(
                    "poses.tracker_csv.file",
                    format!("dataset `{}` ({}) has no {}", d.name, folder.display(), t.file),
                ),
                DatasetSource::Render(_) if t.file != RENDERED_TRACKER_POSES => c.fail(
                    "poses.tracker_csv.file",
                    format!(
                        "datasets[{i}] is rendered, and rendered datasets write their tracker's poses to `{RENDERED_TRACKER_POSES}`, not `{}`",
                        t.file
                    ),
                ),
                _ => {}
            }
        }
    }
    datasets
}
