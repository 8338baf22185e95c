//! The run page's rows: each table of the page built from the run, numbers
//! formatted (mm with 3 decimals as in the thesis).

use serde::Serialize;

use crate::core::geometry::euler_zyx_deg;
use crate::evaluate::cutoff_label;
use crate::evaluate::{BreStats, STAT_ROWS};
use crate::pipeline::record::{DatasetRun, TruthSummary};
use crate::results::summary::describe;

pub(in crate::report) fn mm(v: f64) -> String {
    if v.is_finite() {
        format!("{v:.3}")
    } else {
        "—".into()
    }
}

#[derive(Debug, Serialize, PartialEq)]
pub struct StatRow {
    pub parameter: String,
    pub values: Vec<String>,
}

#[derive(Debug, Serialize, PartialEq)]
pub struct AxisBlock {
    pub axis: String,
    pub rows: Vec<StatRow>,
}

#[derive(Debug, Serialize, PartialEq)]
pub struct KeyValue {
    pub key: String,
    pub value: String,
}

pub(in crate::report) fn setup_rows(run: &DatasetRun, labels: &crate::pipeline::labels::RunLabels) -> Vec<KeyValue> {
    use crate::spec::phantom::Phantom;
    let phantom = match &labels.phantom {
        Phantom::Hemisphere {
            centre_in_phantom_mm: c,
            radius_mm,
        } => format!(
            "hemisphere, R = {radius_mm} mm, centre ({}, {}, {}) mm",
            c[0], c[1], c[2]
        ),
        Phantom::Point {
            position_in_phantom_mm: p,
            head_radius_mm,
        } => format!(
            "pin head, r = {head_radius_mm} mm, at ({}, {}, {}) mm",
            p[0], p[1], p[2]
        ),
        Phantom::FourWire {
            wires,
            wire_diameter_mm,
        } => {
            format!("{} wires of {wire_diameter_mm} mm", wires.len())
        }
        Phantom::Spheres { spheres } => format!(
            "{} spheres, R = {} mm",
            spheres.len(),
            spheres
                .iter()
                .map(|s| s.radius_mm.to_string())
                .collect::<Vec<_>>()
                .join(" / ")
        ),
    };
    let mut rows = vec![kv("phantom", phantom), kv("pose source", labels.pose_source.clone())];
    if let Some(p) = crate::report::thesis::compare::board_points(run) {
        rows.push(kv(
            "board points per used frame: probe / phantom",
            format!(
                "median {:.0} / {:.0}, fewest {} / {} (frames.csv: probe_board_points, phantom_board_points)",
                p.median[0], p.median[1], p.fewest[0], p.fewest[1]
            ),
        ));
    }
    rows.extend([
        kv("camera", run.camera.source.clone()),
        kv(
            "dataset",
            match run.seed {
                Some(seed) => format!("{} (rendered, seed {seed})", run.dataset),
                None => format!("{} (recorded)", run.dataset),
            },
        ),
        kv(
            "B-scan pixel size (mm)",
            format!("{} x {}", run.spacing_mm_per_px[0], run.spacing_mm_per_px[1]),
        ),
        kv(
            "software",
            format!(
                "probecal {}, OpenCV {}",
                env!("CARGO_PKG_VERSION"),
                crate::report::page::provenance::opencv_version()
            ),
        ),
        kv(
            "inputs",
            format!("{} files; their SHA-256 in provenance.json", run.input_files.len()),
        ),
    ]);
    rows
}

pub(in crate::report) fn stat_rows(stats: &BreStats) -> Vec<StatRow> {
    let axes = stats.axes();
    STAT_ROWS
        .iter()
        .map(|(name, get)| StatRow {
            parameter: name.to_string(),
            values: axes.iter().map(|a| mm(get(a))).collect(),
        })
        .collect()
}

pub(in crate::report) fn kv(key: &str, value: String) -> KeyValue {
    KeyValue {
        key: key.to_string(),
        value,
    }
}

/// Per-frame BRE along x, y, z (all-frames calibration) as an inline SVG.
/// The per-frame BRE along each axis (all-frames calibration).
pub(in crate::report) fn validation_rows(run: &DatasetRun) -> Vec<KeyValue> {
    let Some(v) = &run.validation else { return Vec::new() };
    let b = &v.bootstrap;
    let iv = |i: crate::evaluate::resampling::Interval| format!("[{}, {}]", mm(i.low), mm(i.high));
    let mut rows = vec![
        kv(
            "PRE, leave-one-out: mean (PRA) ± SD (mm)",
            format!(
                "{} ± {} (n = {})",
                mm(v.leave_one_out.summary.mean),
                mm(v.leave_one_out.summary.std),
                v.leave_one_out.summary.n
            ),
        ),
        kv(
            "CR: corners and centre over half-split calibrations (mm)",
            format!(
                "{} ({} calibrations)",
                mm(v.reproducibility.cr_mm),
                v.reproducibility.calibrations
            ),
        ),
    ];
    for (k, axis) in ["x", "y", "z"].iter().enumerate() {
        rows.push(kv(
            &format!("bootstrap 95 % interval: translation {axis} (mm)"),
            iv(b.translation_mm[k]),
        ));
    }
    for (k, name) in ["roll x", "pitch y", "yaw z"].iter().enumerate() {
        rows.push(kv(
            &format!("bootstrap 95 % interval: {name} (°)"),
            iv(b.euler_zyx_deg[k]),
        ));
    }
    for (k, axis) in ["x", "y", "z"].iter().enumerate() {
        rows.push(kv(
            &format!("bootstrap 95 % interval: BRE mean {axis} (mm)"),
            iv(b.bre_mean_mm[k]),
        ));
    }
    rows.push(kv(
        "bootstrap: image corners moved, 95th percentile (mm)",
        format!("{} ({} resamples)", mm(b.corner_shift_p95_mm), b.resamples),
    ));
    rows
}

/// The camera's intrinsics and, when calibrated here, its views.
pub(in crate::report) fn camera_rows(run: &DatasetRun) -> Vec<KeyValue> {
    let mut camera = vec![kv("source", run.camera.source.clone())];
    if let Some(k) = &run.camera.intrinsics {
        camera.push(kv("fx, fy (px)", format!("{:.2}, {:.2}", k.fx(), k.fy())));
        camera.push(kv("cx, cy (px)", format!("{:.2}, {:.2}", k.cx(), k.cy())));
        camera.push(kv(
            "k1, k2, p1, p2, k3",
            k.distortion
                .iter()
                .map(|v| format!("{v:.5}"))
                .collect::<Vec<_>>()
                .join(", "),
        ));
        if let Some(rms) = k.rms_px {
            camera.push(kv("RMS reprojection error (px)", format!("{rms:.3}")));
        }
    }
    if let Some(cal) = &run.camera.calibration {
        camera.push(kv(
            "views used",
            format!("{} of {}", cal.views.iter().filter(|v| v.used).count(), cal.views.len()),
        ));
    }
    camera
}

/// The calibration: frames used, its rotation and translation, the pixel size
/// and the closed form's residual.
pub(in crate::report) fn calibration_rows(
    run: &DatasetRun,
    labels: &crate::pipeline::labels::RunLabels,
) -> Vec<KeyValue> {
    let fit = run.primary_fit();
    let primary = &run.thresholds[run.primary];
    let euler = euler_zyx_deg(&fit.target_T_source);
    let t = fit.target_T_source.translation.vector;
    let calibration = vec![
        kv(
            "frames used",
            format!(
                "{} (cut-off {} mm)",
                primary.frames.len(),
                cutoff_label(primary.cutoff_mm)
            ),
        ),
        kv(
            "Euler ZYX: roll x, pitch y, yaw z (°)",
            format!("{:.3}, {:.3}, {:.3}", euler[0], euler[1], euler[2]),
        ),
        kv("translation (mm)", format!("{:.3}, {:.3}, {:.3}", t.x, t.y, t.z)),
        kv(
            "pixel spacing sx, sy (mm/px)",
            format!("{}, {}", run.spacing_mm_per_px[0], run.spacing_mm_per_px[1]),
        ),
        kv(
            "solved as",
            format!("{:?}, scale {:.5}", labels.solve_variant, fit.scale).to_lowercase(),
        ),
        kv("Horn RMS residual (mm)", mm(fit.rms_residual_mm)),
    ];
    calibration
}

/// The BRE statistics per axis, one column per cut-off.
pub(in crate::report) fn threshold_blocks(run: &DatasetRun) -> Vec<AxisBlock> {
    let threshold_blocks = ["X", "Y", "Z"]
        .iter()
        .enumerate()
        .map(|(axis, name)| AxisBlock {
            axis: name.to_string(),
            rows: STAT_ROWS
                .iter()
                .map(|(pname, get)| StatRow {
                    parameter: pname.to_string(),
                    values: run
                        .thresholds
                        .iter()
                        .map(|r| {
                            r.stats
                                .map(|s| mm(get(&[s.x, s.y, s.z][axis])))
                                .unwrap_or_else(|| "—".into())
                        })
                        .collect(),
                })
                .collect(),
        })
        .collect();
    threshold_blocks
}

/// The calibration's and the stages' errors against the ground truth.
pub(in crate::report) fn truth_rows(tr: &TruthSummary) -> Vec<KeyValue> {
    let mut truth = Vec::new();
    let c = &tr.calibration;
    truth.push(kv(
        "image corners and centre: mean error (mm)",
        mm(c.corner_error_mean_mm),
    ));
    truth.push(kv(
        "image corners and centre: max error (mm)",
        mm(c.corner_error_max_mm),
    ));
    truth.push(kv("rotation error (°)", mm(c.rotation_error_deg)));
    truth.push(kv("translation error (mm)", mm(c.translation_error_mm)));
    if let (Some(focal), Some(principal)) = (tr.camera_focal_error_px, tr.camera_principal_error_px) {
        truth.push(kv("camera focal length error (px)", mm(focal)));
        truth.push(kv("camera principal point error (px)", mm(principal)));
    }
    if let Some((mean, max)) = tr.arc_centre_error_px {
        truth.push(kv(
            "arc centre vs sphere-centre projection, normal frames: mean / max (px)",
            format!("{} / {}", mm(mean), mm(max)),
        ));
    }
    if let Some((mean, max)) = tr.probe_pose_translation_error_mm {
        truth.push(kv(
            "probe board position error: mean / max (mm)",
            format!("{} / {}", mm(mean), mm(max)),
        ));
    }
    if let Some((mean, max)) = tr.phantom_pose_translation_error_mm {
        truth.push(kv(
            "phantom board position error: mean / max (mm)",
            format!("{} / {}", mm(mean), mm(max)),
        ));
    }
    if let Some((mean, max)) = tr.probe_pose_rotation_error_deg {
        truth.push(kv(
            "probe board rotation error: mean / max (°)",
            format!("{} / {}", mm(mean), mm(max)),
        ));
    }
    if let Some(check) = &tr.arc_noise {
        truth.push(kv(
            "arcs against their true cuts: the bound's noise model (edge SD, points an arc is worth)",
            format!("{} mm, {}", mm(check.model_edge_sd_mm), check.model_points_per_arc),
        ));
        if let Some(blur) = check.model_slice_blur {
            truth.push(kv(
                "the model's growth with the cut: the scanner's pulse and slice SD (mm)",
                format!("{}, {}", mm(blur.axial_sd_mm), mm(blur.elevation_sd_mm)),
            ));
        }
        for b in std::iter::once(&check.all).chain(&check.by_cut) {
            let [radius, along_u, along_v] = b.sd_over_model;
            truth.push(kv(
            &format!(
                "arcs cut {:.1}–{:.1} R from the centre ({}): edge RMS (mm); spread of radius, centre u, centre v over the model's",
                b.cut[0], b.cut[1], b.arcs
            ),
            format!("{}; {:.2}, {:.2}, {:.2}", mm(b.point_rms_mm), radius, along_u, along_v),
        ));
        }
    }
    truth
}

/// The truth errors of each cut-off's calibration.
pub(in crate::report) fn truth_by_cutoff(run: &DatasetRun) -> Vec<StatRow> {
    vec![
        StatRow {
            parameter: "corner error mean (mm)".into(),
            values: run
                .thresholds
                .iter()
                .map(|r| {
                    r.truth
                        .map(|t| mm(t.corner_error_mean_mm))
                        .unwrap_or_else(|| "—".into())
                })
                .collect(),
        },
        StatRow {
            parameter: "rotation error (°)".into(),
            values: run
                .thresholds
                .iter()
                .map(|r| r.truth.map(|t| mm(t.rotation_error_deg)).unwrap_or_else(|| "—".into()))
                .collect(),
        },
    ]
}

/// One row per estimator: its description, frames, and truth errors.
pub(in crate::report) fn method_rows(run: &DatasetRun) -> Vec<StatRow> {
    run.methods
        .iter()
        .map(|m| StatRow {
            parameter: m.method.name().to_string(),
            values: vec![
                describe(m),
                m.frames_used.to_string(),
                if m.frames_left_out.is_empty() {
                    "—".into()
                } else {
                    m.frames_left_out
                        .iter()
                        .map(|f| f.to_string())
                        .collect::<Vec<_>>()
                        .join(" ")
                },
                m.truth
                    .map(|t| mm(t.corner_error_mean_mm))
                    .unwrap_or_else(|| "—".into()),
                m.truth.map(|t| mm(t.corner_error_max_mm)).unwrap_or_else(|| "—".into()),
                m.truth.map(|t| mm(t.rotation_error_deg)).unwrap_or_else(|| "—".into()),
            ],
        })
        .collect()
}

/// How often the solve converged from starts around the manifest's guess.
pub(in crate::report) fn start_basin_rows(run: &DatasetRun) -> Vec<StatRow> {
    run.start_guess
        .iter()
        .flat_map(|g| &g.basin)
        .map(|b| StatRow {
            parameter: format!("{} mm, {}°", b.translation_mm, b.rotation_deg),
            values: vec![
                format!("{} of {}", b.converged, b.trials),
                format!("{:.0} %", 100.0 * b.converged as f64 / b.trials.max(1) as f64),
            ],
        })
        .collect()
}
