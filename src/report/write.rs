//! A dataset run's files: the per-frame table (Parquet + CSV, through polars),
//! `summary.json` (the stable machine-readable interface), the manifest as run,
//! and the terminal tables. Files are written to a temporary name and renamed.

use std::path::{Path, PathBuf};

use polars::prelude::*;
use serde_json::{json, Value};

use crate::core::geometry::{euler_zyx_deg, to_rows};
use crate::evaluate::{cutoff_label, trim_number, AxisStats, BreStats, STAT_ROWS};
use crate::pipeline::run::DatasetRun;

use crate::io::fs::write_atomic;
use crate::io::fs::{display_path, WriteError};

#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("{path}: {message}")]
    Io { path: PathBuf, message: String },
    #[error("polars: {0}")]
    Polars(#[from] PolarsError),
    #[error("report: {0}")]
    Report(String),
}

fn cutoff_json(cutoff: f64) -> Value {
    if cutoff.is_infinite() {
        json!("inf")
    } else {
        json!(cutoff)
    }
}

/// The per-frame table: one row per frame, used or rejected with the stage and reason.
pub fn frames_table(run: &DatasetRun) -> PolarsResult<DataFrame> {
    let f = &run.frames;
    let n = f.len();
    let opt = |get: &dyn Fn(&crate::pipeline::run::FrameRecord) -> Option<f64>| {
        f.iter().map(get).collect::<Vec<Option<f64>>>()
    };
    let rel = |p: &Path| display_path(p.strip_prefix(&run.dataset_folder).unwrap_or(p));
    let columns = vec![
        Column::new(
            "frame".into(),
            f.iter().map(|r| r.files.frame as u32).collect::<Vec<_>>(),
        ),
        Column::new(
            "camera_image".into(),
            f.iter()
                .map(|r| r.files.camera_image.as_deref().map(rel))
                .collect::<Vec<Option<String>>>(),
        ),
        Column::new(
            "bscan_image".into(),
            f.iter().map(|r| rel(&r.files.bscan_image)).collect::<Vec<_>>(),
        ),
        Column::new(
            "status".into(),
            f.iter()
                .map(|r| if r.rejection.is_none() { "used" } else { "rejected" })
                .collect::<Vec<_>>(),
        ),
        Column::new(
            "rejected_at".into(),
            f.iter()
                .map(|r| r.rejection.as_ref().map(|(s, _)| s.label()))
                .collect::<Vec<_>>(),
        ),
        Column::new(
            "reason".into(),
            f.iter()
                .map(|r| r.rejection.as_ref().map(|(_, m)| m.clone()))
                .collect::<Vec<_>>(),
        ),
        Column::new(
            "probe_board_rms_px".into(),
            opt(&|r| r.poses.as_ref().map(|p| p.camera_T_marker.reprojection_rms_px)),
        ),
        Column::new(
            "phantom_board_rms_px".into(),
            opt(&|r| r.poses.as_ref().map(|p| p.camera_T_phantom.reprojection_rms_px)),
        ),
        Column::new(
            "arc_centre_u_px".into(),
            opt(&|r| r.arc.as_ref().map(|a| a.centre_px[0])),
        ),
        Column::new(
            "arc_centre_v_px".into(),
            opt(&|r| r.arc.as_ref().map(|a| a.centre_px[1])),
        ),
        Column::new("arc_radius_mm".into(), opt(&|r| r.arc.as_ref().map(|a| a.radius_mm))),
        Column::new("arc_span_deg".into(), opt(&|r| r.arc.as_ref().map(|a| a.span_deg))),
        Column::new("arc_rms_px".into(), opt(&|r| r.arc.as_ref().map(|a| a.rms_px))),
        Column::new("arc_confidence".into(), opt(&|r| r.arc.as_ref().map(|a| a.confidence))),
        Column::new(
            "arc_points".into(),
            f.iter()
                .map(|r| r.arc.as_ref().map(|a| a.points as u32))
                .collect::<Vec<_>>(),
        ),
        Column::new("bre_x_mm".into(), opt(&|r| r.bre_mm.map(|b| b.0[0]))),
        Column::new("bre_y_mm".into(), opt(&|r| r.bre_mm.map(|b| b.0[1]))),
        Column::new("bre_z_mm".into(), opt(&|r| r.bre_mm.map(|b| b.0[2]))),
        Column::new("bre_norm_mm".into(), opt(&|r| r.bre_mm.map(|b| b.1))),
        Column::new(
            "truth_kind".into(),
            f.iter().map(|r| r.truth_kind.clone()).collect::<Vec<_>>(),
        ),
        Column::new(
            "truth_elevation_offset_mm".into(),
            opt(&|r| r.truth_elevation_offset_mm),
        ),
        Column::new(
            "truth_arc_centre_error_px".into(),
            opt(&|r| r.truth_arc_centre_error_px),
        ),
        Column::new(
            "truth_probe_pose_error_mm".into(),
            opt(&|r| r.truth_probe_pose_error.map(|e| e.0)),
        ),
        Column::new(
            "truth_probe_pose_error_deg".into(),
            opt(&|r| r.truth_probe_pose_error.map(|e| e.1)),
        ),
        Column::new(
            "truth_phantom_pose_error_mm".into(),
            opt(&|r| r.truth_phantom_pose_error.map(|e| e.0)),
        ),
        Column::new(
            "truth_phantom_pose_error_deg".into(),
            opt(&|r| r.truth_phantom_pose_error.map(|e| e.1)),
        ),
    ];
    let mut columns = columns;
    for row in &run.thresholds {
        let name = if row.cutoff_mm.is_infinite() {
            "kept_below_inf".to_string()
        } else {
            format!("kept_below_{}mm", trim_number(row.cutoff_mm))
        };
        columns.push(Column::new(
            name.into(),
            f.iter()
                .map(|r| row.frames.contains(&r.files.frame))
                .collect::<Vec<_>>(),
        ));
    }
    DataFrame::new(n, columns)
}

fn stats_json(s: &AxisStats) -> Value {
    json!({"mean": s.mean, "std": s.std, "min": s.min, "max": s.max})
}

fn bre_json(s: &BreStats) -> Value {
    json!({"x": stats_json(&s.x), "y": stats_json(&s.y), "z": stats_json(&s.z)})
}

/// `summary.json`: the stable interface (mm and degrees).
pub fn summary(run: &DatasetRun, manifest: &crate::manifest::Manifest) -> Value {
    let primary = &run.thresholds[run.primary];
    let fit = run.primary_fit();
    let used = run.used_frames();
    let mut rejections = serde_json::Map::new();
    for f in &run.frames {
        if let Some((stage, _)) = &f.rejection {
            let entry = rejections.entry(stage.label().to_string()).or_insert(json!(0));
            *entry = json!(entry.as_u64().unwrap_or(0) + 1);
        }
    }
    let k = run.camera.intrinsics.as_ref();
    let mut out = json!({
        "experiment": run.experiment,
        "dataset": run.dataset,
        "rendered": run.rendered,
        "probecal_version": env!("CARGO_PKG_VERSION"),
        "manifest_sha256": manifest.sha256,
        "frames": {"total": run.frames.len(), "used": used, "rejected": run.frames.len() - used, "rejected_by_stage": rejections},
        "camera": {
            "source": run.camera.source,
            "fx_px": k.map(|k| k.fx()), "fy_px": k.map(|k| k.fy()),
            "cx_px": k.map(|k| k.cx()), "cy_px": k.map(|k| k.cy()),
            "distortion": k.map(|k| k.distortion),
            "rms_px": k.and_then(|k| k.rms_px),
            "views_used": run.camera.calibration.as_ref().map(|c| c.views.iter().filter(|v| v.used).count()),
            "views_total": run.camera.calibration.as_ref().map(|c| c.views.len()),
        },
        "calibration": {
            "marker_T_image": to_rows(&fit.target_T_source),
            "scale_mm_per_px": [run.spacing_mm_per_px[0] * fit.scale, run.spacing_mm_per_px[1] * fit.scale],
            "solve_variant": manifest.solve_variant,
            "euler_zyx_deg": euler_zyx_deg(&fit.target_T_source),
            "translation_mm": fit.target_T_source.translation.vector.as_slice(),
            "cutoff_mm": cutoff_json(primary.cutoff_mm),
            "frames_used": primary.frames.len(),
            "horn_rms_residual_mm": fit.rms_residual_mm,
        },
        "bre_mm": primary.stats.as_ref().map(bre_json),
        "thresholds": run.thresholds.iter().map(|r| json!({
            "cutoff_mm": cutoff_json(r.cutoff_mm),
            "frames": r.frames.len(),
            "bre_mm": r.stats.as_ref().map(bre_json),
            "error": r.fit.as_ref().err().map(|e| e.to_string()),
            "truth": r.truth.map(|t| json!({"corner_error_mm": {"mean": t.corner_error_mean_mm, "max": t.corner_error_max_mm}, "rotation_error_deg": t.rotation_error_deg})),
        })).collect::<Vec<_>>(),
        "gates": run.gates,
        "regression_tolerances": manifest.thresholds.regression,
    });
    if !run.methods.is_empty() {
        out["methods"] = run
            .methods
            .iter()
            .map(|m| {
                json!({
                    "name": m.name,
                    "description": m.description,
                    "frames_used": m.frames_used,
                    "frames_left_out": m.frames_left_out,
                    "marker_T_image": to_rows(&m.marker_T_image),
                    "spacing_mm_per_px": m.spacing_mm_per_px,
                    "truth": m.truth.map(|t| json!({
                        "corner_error_mm": {"mean": t.corner_error_mean_mm, "max": t.corner_error_max_mm},
                        "rotation_error_deg": t.rotation_error_deg,
                    })),
                })
            })
            .collect();
    }
    if let Some(v) = &run.validation {
        out["validation"] = json!({
            "protocol": "frames of the calibration cut-off; PRE by leave-one-out; CR over random half-splits; bootstrap percentile intervals (2.5 %, 97.5 %)",
            "pre_loo_mm": v.leave_one_out.summary,
            "cr_mm": v.reproducibility.cr_mm,
            "cr_calibrations": v.reproducibility.calibrations,
            "bootstrap": v.bootstrap,
        });
    }
    if let Some(t) = &run.truth {
        let pair = |v: Option<(f64, f64)>| v.map(|(mean, max)| json!({"mean": mean, "max": max}));
        out["truth"] = json!({
            "corner_error_mm": {"mean": t.calibration.corner_error_mean_mm, "max": t.calibration.corner_error_max_mm},
            "rotation_error_deg": t.calibration.rotation_error_deg,
            "translation_error_mm": t.calibration.translation_error_mm,
            "camera_focal_error_px": t.camera_focal_error_px,
            "camera_principal_point_error_px": t.camera_principal_error_px,
            "arc_centre_error_px": pair(t.arc_centre_error_px),
            "probe_pose_error_mm": pair(t.probe_pose_translation_error_mm),
            "probe_pose_error_deg": pair(t.probe_pose_rotation_error_deg),
            "phantom_pose_error_mm": pair(t.phantom_pose_translation_error_mm),
        });
    }
    out
}

/// The thesis's BRE table (rows Std./Mean/Min/Max, columns x, y, z) as text.
pub fn bre_table_text(stats: &BreStats) -> String {
    let mut s = format!("{:<6} {:>9} {:>9} {:>9}\n", "", "x", "y", "z");
    for (name, get) in STAT_ROWS {
        let [x, y, z] = stats.axes().map(|a| get(&a));
        s.push_str(&format!("{name:<6} {x:>9.3} {y:>9.3} {z:>9.3}\n"));
    }
    s
}

/// The thesis's threshold table (axis x parameter rows, one column per cut-off) as text.
pub fn threshold_table_text(run: &DatasetRun) -> String {
    let mut s = format!("{:<5} {:<6}", "Axis", "");
    for r in &run.thresholds {
        s.push_str(&format!(
            " {:>11}",
            format!("{} ({})", cutoff_label(r.cutoff_mm), r.frames.len())
        ));
    }
    s.push('\n');
    for (axis, axis_name) in ["X", "Y", "Z"].iter().enumerate() {
        for (i, (name, get)) in STAT_ROWS.iter().enumerate() {
            s.push_str(&format!("{:<5} {:<6}", if i == 0 { *axis_name } else { "" }, name));
            for r in &run.thresholds {
                match &r.stats {
                    Some(st) => s.push_str(&format!(" {:>11.3}", get(&st.axes()[axis]))),
                    None => s.push_str(&format!(" {:>11}", "—")),
                }
            }
            s.push('\n');
        }
    }
    s
}

/// Writes a dataset run into `folder`.
pub fn write_dataset_run(
    run: &DatasetRun,
    manifest: &crate::manifest::Manifest,
    folder: &Path,
) -> Result<(), OutputError> {
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |e: std::io::Error| OutputError::Io {
            path: path.clone(),
            message: e.to_string(),
        }
    };
    std::fs::create_dir_all(folder).map_err(io(folder))?;
    let mut table = frames_table(run)?;
    let mut csv = Vec::new();
    CsvWriter::new(&mut csv).finish(&mut table)?;
    write_atomic(&folder.join("frames.csv"), &csv)?;
    let mut parquet = Vec::new();
    ParquetWriter::new(&mut parquet).finish(&mut table)?;
    write_atomic(&folder.join("frames.parquet"), &parquet)?;
    let summary = summary(run, manifest);
    let text = serde_json::to_string_pretty(&summary).map_err(|e| OutputError::Report(e.to_string()))? + "\n";
    write_atomic(&folder.join("summary.json"), text.as_bytes())?;
    let mut context = crate::report::context(run, manifest);
    let gallery = crate::report::gallery::gallery(run).map_err(|e| OutputError::Report(e.to_string()))?;
    if !gallery.is_empty() {
        let dir = folder.join("gallery");
        std::fs::create_dir_all(&dir).map_err(io(&dir))?;
        for g in &gallery {
            let file = format!("gallery/frame_{:03}.jpg", g.frame);
            write_atomic(&folder.join(&file), &g.jpeg)?;
            context.gallery.push(crate::report::GalleryEntry {
                file,
                caption: g.caption.clone(),
            });
        }
    }
    let uris: Vec<String> = gallery
        .iter()
        .map(|g| crate::report::gallery::data_uri(&g.jpeg))
        .collect();
    let mut svgs = Vec::new();
    let charts = crate::report::figures::charts(run);
    if !charts.is_empty() {
        let dir = folder.join("figures");
        std::fs::create_dir_all(&dir).map_err(io(&dir))?;
    }
    for chart in &charts {
        let file = format!("figures/{}.png", chart.id);
        write_atomic(
            &folder.join(&file),
            &crate::report::figures::png(chart).map_err(OutputError::Report)?,
        )?;
        svgs.push(crate::report::figures::svg(chart).map_err(OutputError::Report)?);
        context.figures.push(crate::report::GalleryEntry {
            file,
            caption: chart.caption.clone(),
        });
    }
    let context_json = serde_json::to_string_pretty(&context).map_err(|e| OutputError::Report(e.to_string()))? + "\n";
    write_atomic(&folder.join("report_context.json"), context_json.as_bytes())?;
    let html = crate::report::render_html(&context, &uris, &svgs).map_err(|e| OutputError::Report(e.to_string()))?;
    write_atomic(&folder.join("report.html"), html.as_bytes())?;
    let tex = crate::report::render_tex(&context).map_err(OutputError::Report)?;
    write_atomic(&folder.join("report.tex"), tex.as_bytes())?;
    let png = crate::report::bre_figure_png(run).map_err(OutputError::Report)?;
    write_atomic(&folder.join("bre_per_frame.png"), &png)?;
    if let Some(cal) = &run.camera.calibration {
        let path = folder.join("camera_intrinsics.yml");
        cal.intrinsics
            .save(&path, Some((cal.inner_corners, cal.square_mm)))
            .map_err(|e| OutputError::Io {
                path,
                message: e.to_string(),
            })?;
    }
    Ok(())
}

impl From<WriteError> for OutputError {
    fn from(e: WriteError) -> OutputError {
        OutputError::Io {
            path: e.path,
            message: e.message,
        }
    }
}
