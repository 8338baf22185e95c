//! A dataset run's files: the per-frame table (Parquet + CSV, through polars),
//! `summary.json` (the stable machine-readable interface), the manifest as run,
//! and the terminal tables. Files are written to a temporary name and renamed.

use std::path::Path;

use polars::prelude::*;

use crate::evaluate::trim_number;
use crate::pipeline::record::{DatasetRun, FrameTruth};
use crate::pipeline::run::resolve::{SolveInputs, SOLVE_INPUTS_FILE};
use crate::results::summary::{to_text, Summary};

use crate::io::fs::write_atomic;
use crate::io::fs::{display_path, WriteError};

pub use crate::report::error::OutputError;

/// The frames' truth columns (rendered datasets; empty otherwise).
fn truth_columns(run: &DatasetRun) -> Vec<Column> {
    let truths: Vec<Option<&FrameTruth>> = run
        .frames
        .iter()
        .map(|r| run.truth.as_ref().and_then(|t| t.frames.get(&r.files.frame)))
        .collect();
    let opt =
        |get: &dyn Fn(&FrameTruth) -> Option<f64>| truths.iter().map(|t| t.and_then(get)).collect::<Vec<Option<f64>>>();
    vec![
        Column::new(
            "truth_kind".into(),
            truths.iter().map(|t| t.map(|t| t.kind.clone())).collect::<Vec<_>>(),
        ),
        Column::new(
            "truth_elevation_offset_mm".into(),
            opt(&|t| Some(t.elevation_offset_mm)),
        ),
        Column::new("truth_arc_centre_error_px".into(), opt(&|t| t.arc_centre_error_px)),
        Column::new(
            "truth_probe_pose_error_mm".into(),
            opt(&|t| t.probe_pose_error.map(|e| e.0)),
        ),
        Column::new(
            "truth_probe_pose_error_deg".into(),
            opt(&|t| t.probe_pose_error.map(|e| e.1)),
        ),
        Column::new(
            "truth_phantom_pose_error_mm".into(),
            opt(&|t| t.phantom_pose_error.map(|e| e.0)),
        ),
        Column::new(
            "truth_phantom_pose_error_deg".into(),
            opt(&|t| t.phantom_pose_error.map(|e| e.1)),
        ),
    ]
}

/// One column per cut-off: whether each frame is kept below it.
fn kept_columns(run: &DatasetRun) -> Vec<Column> {
    let f = &run.frames;
    let mut columns = Vec::new();
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
    columns
}

/// The per-frame table: one row per frame, used or rejected with the stage and reason.
pub fn frames_table(run: &DatasetRun) -> PolarsResult<DataFrame> {
    let f = &run.frames;
    let n = f.len();
    let opt = |get: &dyn Fn(&crate::pipeline::record::FrameRecord) -> Option<f64>| {
        f.iter().map(get).collect::<Vec<Option<f64>>>()
    };
    let rel = |p: &Path| display_path(p.strip_prefix(&run.dataset_folder).unwrap_or(p));
    let columns = vec![
        Column::new(
            "frame".into(),
            f.iter().map(|r| r.files.frame as u64).collect::<Vec<_>>(),
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
                .map(|r| r.rejection.as_ref().map(|j| j.stage().label()))
                .collect::<Vec<_>>(),
        ),
        Column::new(
            "reason".into(),
            f.iter()
                .map(|r| r.rejection.as_ref().map(|j| j.to_string()))
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
        // The points each board's pose is solved from: a checkerboard's inner
        // corners, four per ArUco marker, a ChArUco board's found corners.
        Column::new(
            "probe_board_points".into(),
            f.iter()
                .map(|r| r.poses.as_ref().map(|p| p.camera_T_marker.corners_px.len() as u32))
                .collect::<Vec<_>>(),
        ),
        Column::new(
            "phantom_board_points".into(),
            f.iter()
                .map(|r| r.poses.as_ref().map(|p| p.camera_T_phantom.corners_px.len() as u32))
                .collect::<Vec<_>>(),
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
    ];
    let mut columns = columns;
    columns.extend(truth_columns(run));
    columns.extend(kept_columns(run));
    DataFrame::new(n, columns)
}

/// Writes the per-frame table as `frames.csv` and `frames.parquet` in `folder`.
pub fn write_frames_table(folder: &Path, table: &mut DataFrame) -> Result<(), OutputError> {
    let mut csv = Vec::new();
    CsvWriter::new(&mut csv).finish(table)?;
    write_atomic(&folder.join("frames.csv"), &csv)?;
    let mut parquet = Vec::new();
    ParquetWriter::new(&mut parquet).finish(table)?;
    write_atomic(&folder.join("frames.parquet"), &parquet)?;
    Ok(())
}

/// Writes a dataset run into `folder`.
pub fn write_dataset_run(
    run: &DatasetRun,
    labels: &crate::pipeline::labels::RunLabels,
    folder: &Path,
) -> Result<Summary, OutputError> {
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |e: std::io::Error| OutputError::Io {
            path: path.clone(),
            message: e.to_string(),
        }
    };
    std::fs::create_dir_all(folder).map_err(io(folder))?;
    write_frames_table(folder, &mut frames_table(run)?)?;
    let inputs = SolveInputs::of(&run.experiment, &run.dataset, &run.pairs, &run.solve);
    let inputs = inputs.to_yaml().map_err(|e| OutputError::Report(e.to_string()))?;
    write_atomic(&folder.join(SOLVE_INPUTS_FILE), inputs.as_bytes())?;
    let summary = Summary::of(run, labels);
    let text = to_text(&summary)?;
    write_atomic(&folder.join("summary.json"), text.as_bytes())?;
    let mut context = crate::report::page::context::context(run, labels);
    let gallery = crate::report::page::gallery::gallery(run).map_err(|e| OutputError::Report(e.to_string()))?;
    if !gallery.is_empty() {
        let dir = folder.join("gallery");
        std::fs::create_dir_all(&dir).map_err(io(&dir))?;
        for g in &gallery {
            let file = format!("gallery/frame_{:03}.jpg", g.frame);
            write_atomic(&folder.join(&file), &g.jpeg)?;
            context.gallery.push(crate::report::page::context::GalleryEntry {
                file,
                caption: g.caption.clone(),
            });
        }
    }
    let uris: Vec<String> = gallery
        .iter()
        .map(|g| crate::report::page::gallery::data_uri(&g.jpeg))
        .collect();
    let mut svgs = Vec::new();
    let charts = crate::report::page::figures::charts(run);
    if !charts.is_empty() {
        let dir = folder.join("figures");
        std::fs::create_dir_all(&dir).map_err(io(&dir))?;
    }
    // Each chart is drawn (PNG and SVG) on a core of its own, in chart order.
    let drawn = crate::core::parallel::parallel_map(charts.len(), |i| {
        let chart = &charts[i];
        Ok::<_, OutputError>((
            crate::report::page::figures::png(chart)?,
            crate::report::page::figures::svg(chart)?,
        ))
    });
    for (chart, drawn) in charts.iter().zip(drawn) {
        let (png, svg) = drawn?;
        let file = format!("figures/{}.png", chart.id);
        write_atomic(&folder.join(&file), &png)?;
        svgs.push(svg);
        context.figures.push(crate::report::page::context::GalleryEntry {
            file,
            caption: chart.caption.clone(),
        });
    }
    let context_json = serde_json::to_string_pretty(&context)? + "\n";
    write_atomic(&folder.join("report_context.json"), context_json.as_bytes())?;
    let html = crate::report::page::render::render_html(&context, &uris, &svgs)?;
    write_atomic(&folder.join("report.html"), html.as_bytes())?;
    let tex = crate::report::page::render::render_tex(&context)?;
    write_atomic(&folder.join("report.tex"), tex.as_bytes())?;
    let png = crate::report::page::figures::bre_figure_png(run)?;
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
    Ok(summary)
}

impl From<WriteError> for OutputError {
    fn from(e: WriteError) -> OutputError {
        OutputError::Io {
            path: e.path,
            message: e.message,
        }
    }
}
