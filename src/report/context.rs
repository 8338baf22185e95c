//! The run page's context: everything the HTML and LaTeX pages show, prepared
//! (numbers formatted, mm with 3 decimals as in the thesis). It is also written
//! as `report_context.json`, a stable target for tests.

use serde::Serialize;

use super::summary::describe;
use crate::core::geometry::{euler_zyx_deg, to_rows};
use crate::evaluate::cutoff_label;
use crate::evaluate::{BreStats, STAT_ROWS};
use crate::pipeline::record::DatasetRun;

fn mm(v: f64) -> String {
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
pub struct CutoffColumn {
    pub label: String,
    pub frames: usize,
}

#[derive(Debug, Serialize, PartialEq)]
pub struct Rejected {
    pub frame: usize,
    pub stage: String,
    pub reason: String,
}

#[derive(Debug, Serialize, PartialEq)]
pub struct KeyValue {
    pub key: String,
    pub value: String,
}

#[derive(Debug, Serialize, PartialEq)]
pub struct Gate {
    pub name: String,
    pub limit: String,
    pub value: String,
    pub passed: bool,
}

/// Everything the page shows, formatted.
#[derive(Debug, Serialize, PartialEq)]
pub struct RunContext {
    pub experiment: String,
    pub dataset: String,
    pub description: String,
    pub manifest: String,
    pub manifest_sha256: String,
    pub probecal_version: String,
    pub frames_total: usize,
    pub frames_used: usize,
    pub frames_rejected: usize,
    pub camera: Vec<KeyValue>,
    pub calibration_matrix: Vec<Vec<String>>,
    pub calibration: Vec<KeyValue>,
    /// The thesis's BRE table at the calibration cut-off: rows Std./Mean/Min/Max, columns x, y, z.
    pub bre_caption: String,
    pub bre_table: Vec<StatRow>,
    /// The thesis's threshold table: one column per cut-off.
    pub threshold_columns: Vec<CutoffColumn>,
    pub threshold_blocks: Vec<AxisBlock>,
    pub truth: Vec<KeyValue>,
    pub truth_by_cutoff: Vec<StatRow>,
    pub gates: Vec<Gate>,
    pub rejected: Vec<Rejected>,
    pub bre_figure_svg: String,
    /// Other estimators on the same frames: name, description, frames, truth errors.
    pub methods: Vec<StatRow>,
    /// Why two estimators give the same calibration, when they do.
    pub methods_agree: Vec<String>,
    /// Wire phantoms: the start guess's offset from where it converged.
    pub start_offset: String,
    /// Wire phantoms: per offset, the random starts that converged.
    pub start_basin: Vec<StatRow>,
    pub validation: Vec<KeyValue>,
    /// Manifest summary, software versions, inputs.
    pub setup: Vec<KeyValue>,
    /// B-scans with their detections: file beside the report (LaTeX), caption.
    pub gallery: Vec<GalleryEntry>,
    /// Further figures: PNG file beside the report (LaTeX), caption.
    pub figures: Vec<GalleryEntry>,
}

#[derive(Debug, Serialize, PartialEq)]
pub struct GalleryEntry {
    pub file: String,
    pub caption: String,
}

fn setup_rows(run: &DatasetRun, manifest: &crate::manifest::Manifest) -> Vec<KeyValue> {
    use crate::manifest::CameraSource;
    use crate::spec::phantom::Phantom;
    let phantom = match &manifest.phantom {
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
    let rig = match &manifest.camera {
        CameraSource::TrackerCsv(t) => format!(
            "tracker poses from {} ({}, {})",
            t.file, t.probe_transform, t.reference_transform
        ),
        _ => super::compare::rig_label(&manifest.rig),
    };
    vec![
        kv("phantom", phantom),
        kv("pose source", rig),
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
                super::provenance::opencv_version()
            ),
        ),
        kv(
            "inputs",
            format!("{} files; their SHA-256 in provenance.json", run.input_files.len()),
        ),
    ]
}

fn stat_rows(stats: &BreStats) -> Vec<StatRow> {
    let axes = stats.axes();
    STAT_ROWS
        .iter()
        .map(|(name, get)| StatRow {
            parameter: name.to_string(),
            values: axes.iter().map(|a| mm(get(a))).collect(),
        })
        .collect()
}

fn kv(key: &str, value: String) -> KeyValue {
    KeyValue {
        key: key.to_string(),
        value,
    }
}

/// Per-frame BRE along x, y, z (all-frames calibration) as an inline SVG.
/// The per-frame BRE along each axis (all-frames calibration).
fn validation_rows(run: &DatasetRun) -> Vec<KeyValue> {
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

/// Prepares the page's context.
pub fn context(run: &DatasetRun, manifest: &crate::manifest::Manifest) -> RunContext {
    let fit = run.primary_fit();
    let primary = &run.thresholds[run.primary];
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
            format!("{:?}, scale {:.5}", manifest.solve_variant, fit.scale).to_lowercase(),
        ),
        kv("Horn RMS residual (mm)", mm(fit.rms_residual_mm)),
    ];
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
    let mut truth = Vec::new();
    let mut truth_by_cutoff = Vec::new();
    if let Some(tr) = &run.truth {
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
        truth_by_cutoff = vec![
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
        ];
    }
    let used = run.used_frames();
    RunContext {
        experiment: run.experiment.clone(),
        dataset: run.dataset.clone(),
        description: manifest.description.clone(),
        manifest: manifest
            .path
            .file_name()
            .map(|n| n.to_string_lossy().to_string())
            .unwrap_or_default(),
        manifest_sha256: manifest.sha256.clone(),
        probecal_version: env!("CARGO_PKG_VERSION").into(),
        frames_total: run.frames.len(),
        frames_used: used,
        frames_rejected: run.frames.len() - used,
        camera,
        calibration_matrix: to_rows(&fit.target_T_source)
            .iter()
            .map(|r| r.iter().map(|v| format!("{v:.4}")).collect())
            .collect(),
        calibration,
        bre_caption: format!(
            "BRE along axes for dataset {} ({} frames, cut-off {} mm)",
            run.dataset,
            primary.frames.len(),
            cutoff_label(primary.cutoff_mm)
        ),
        bre_table: primary.stats.as_ref().map(stat_rows).unwrap_or_default(),
        threshold_columns: run
            .thresholds
            .iter()
            .map(|r| CutoffColumn {
                label: cutoff_label(r.cutoff_mm),
                frames: r.frames.len(),
            })
            .collect(),
        threshold_blocks,
        truth,
        truth_by_cutoff,
        gates: run
            .gates
            .iter()
            .map(|g| Gate {
                name: g.name.clone(),
                limit: mm(g.limit),
                value: g.value.map(mm).unwrap_or_else(|| "—".into()),
                passed: g.passed,
            })
            .collect(),
        rejected: run
            .frames
            .iter()
            .filter_map(|f| {
                f.rejection.as_ref().map(|r| Rejected {
                    frame: f.files.frame,
                    stage: r.stage().label().into(),
                    reason: r.to_string(),
                })
            })
            .collect(),
        bre_figure_svg: super::figures::bre_figure(run).unwrap_or_else(|e| format!("<p>figure not drawn: {e}</p>")),
        methods: run
            .methods
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
            .collect(),
        methods_agree: agreements(&run.methods),
        start_offset: run
            .start_guess
            .as_ref()
            .map(|g| {
                format!(
                    "The manifest's start guess (solve.initial_marker_T_image) is {:.1} mm and {:.1}° from the calibration it converged to.",
                    g.offset_translation_mm, g.offset_rotation_deg
                )
            })
            .unwrap_or_default(),
        start_basin: run
            .start_guess
            .iter()
            .flat_map(|g| &g.basin)
            .map(|b| StatRow {
                parameter: format!("{} mm, {}°", b.translation_mm, b.rotation_deg),
                values: vec![
                    format!("{} of {}", b.converged, b.trials),
                    format!("{:.0} %", 100.0 * b.converged as f64 / b.trials.max(1) as f64),
                ],
            })
            .collect(),
        validation: validation_rows(run),
        setup: setup_rows(run, manifest),
        gallery: Vec::new(),
        figures: Vec::new(),
    }
}

/// One sentence per pair of estimators that ended on the same calibration: the
/// same frames were left out, so the same final fit was solved.
fn agreements(methods: &[crate::pipeline::record::MethodResult]) -> Vec<String> {
    let mut out = Vec::new();
    for (i, a) in methods.iter().enumerate() {
        for b in &methods[i + 1..] {
            let same_fit = a.marker_T_image.to_homogeneous() == b.marker_T_image.to_homogeneous()
                && a.spacing_mm_per_px == b.spacing_mm_per_px;
            if same_fit && a.frames_left_out == b.frames_left_out {
                let left_out = if a.frames_left_out.is_empty() {
                    "no frame".to_string()
                } else {
                    format!(
                        "the same frames ({})",
                        a.frames_left_out
                            .iter()
                            .map(|f| f.to_string())
                            .collect::<Vec<_>>()
                            .join(", ")
                    )
                };
                out.push(format!(
                    "{} and {} agree: each left out {left_out} and solved the rest with the same fit, so their calibrations are identical.",
                    a.method.name(),
                    b.method.name()
                ));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::geometry::Rigid;
    use crate::pipeline::record::{Method, MethodResult};

    fn result(method: Method, left_out: Vec<usize>, shift_mm: f64) -> MethodResult {
        MethodResult {
            method,
            frames_used: 10 - left_out.len(),
            frames_left_out: left_out,
            marker_T_image: Rigid::translation(shift_mm, 0.0, 0.0),
            spacing_mm_per_px: [0.2, 0.2],
            truth: None,
        }
    }

    #[test]
    fn estimators_that_end_on_one_fit_are_explained_and_others_are_not() {
        let methods = [
            result(
                Method::Ransac {
                    threshold_mm: 1.3,
                    noise_sd_mm: Some(0.4),
                },
                vec![3, 7],
                0.0,
            ),
            result(Method::Lmeds { threshold_mm: 1.9 }, vec![3, 7], 0.0),
            result(Method::CutoffWorstFirst { cutoff_mm: 2.0 }, vec![3], 0.1),
        ];
        let said = agreements(&methods);
        assert_eq!(said.len(), 1, "{said:?}");
        assert!(
            said[0].starts_with("ransac and lmeds agree: each left out the same frames (3, 7)"),
            "{said:?}"
        );
    }
}
