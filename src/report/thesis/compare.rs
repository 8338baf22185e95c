//! `probecal compare`: several experiments side by side (e.g. checkerboard vs
//! ArUco on the same probe motion), with the rigs as columns, and where each rig's
//! error comes from, measured from the run.

use crate::report::error::OutputError;
use serde::Serialize;

use crate::core::geometry::pixel_to_image_mm;
use crate::core::stats::mean;
use crate::evaluate::cutoff_label;
use crate::pipeline::labels::RunLabels;
use crate::pipeline::record::{DatasetRun, Stage};

/// One column of the comparison.
#[derive(Debug, Clone, Serialize)]
pub struct CompareColumn {
    pub experiment: String,
    pub dataset: String,
    pub rig: String,
    /// Row label → formatted value.
    pub values: Vec<(String, String)>,
    /// Where the error comes from, in words, with the numbers of this run.
    pub explanation: String,
}

fn mm(v: Option<f64>) -> String {
    v.map(|v| format!("{v:.3}")).unwrap_or_else(|| "—".into())
}

/// The BRE per axis at the reported cut-off, and the mean per axis at every cut-off.
fn bre_rows(run: &DatasetRun) -> Vec<(String, String)> {
    let primary = &run.thresholds[run.primary];
    let mut values = Vec::new();
    for (axis, name) in ["x", "y", "z"].iter().enumerate() {
        for (stat, get) in crate::evaluate::STAT_ROWS {
            values.push((
                format!("BRE {name} {stat} (mm)"),
                mm(primary.stats.map(|s| get(&s.axes()[axis]))),
            ));
        }
    }
    for row in &run.thresholds {
        values.push((
            format!("BRE mean x/y/z, cut-off {} mm", cutoff_label(row.cutoff_mm)),
            match row.stats {
                Some(s) => format!(
                    "{:.3} / {:.3} / {:.3} ({})",
                    s.x.mean,
                    s.y.mean,
                    s.z.mean,
                    row.frames.len()
                ),
                None => format!("— ({})", row.frames.len()),
            },
        ));
    }
    values
}

/// The rows against the ground truth (the calibration, the gated estimator, the
/// boards' poses and their lever arm), added to `values`; the paragraph that
/// explains them.
fn truth_rows(
    labels: &RunLabels,
    run: &DatasetRun,
    used: &[&crate::pipeline::record::FrameRecord],
    t: &crate::pipeline::record::TruthSummary,
    values: &mut Vec<(String, String)>,
) -> String {
    let c = &t.calibration;
    values.push((
        "truth: image corners mean (mm)".into(),
        format!("{:.3}", c.corner_error_mean_mm),
    ));
    // The estimator the gates check (`thresholds.gates.method`): the one a
    // phantom is for, when it is not the reported calibration.
    let gated = labels.gated_method.as_deref().and_then(|name| {
        let m = run.methods.iter().find(|m| m.method.name() == name)?;
        Some((name, m.truth?.corner_error_mean_mm))
    });
    values.push((
        "truth: image corners mean, the estimator the gates check (mm)".into(),
        match gated {
            Some((name, e)) => format!("{e:.3} ({name})"),
            None => format!("{:.3}", c.corner_error_mean_mm),
        },
    ));
    values.push((
        "truth: image corners max (mm)".into(),
        format!("{:.3}", c.corner_error_max_mm),
    ));
    values.push(("truth: rotation (°)".into(), format!("{:.3}", c.rotation_error_deg)));
    values.push((
        "truth: translation (mm)".into(),
        format!("{:.3}", c.translation_error_mm),
    ));
    let used_truth: Vec<_> = used.iter().filter_map(|f| t.frames.get(&f.files.frame)).collect();
    let probe_t = mean(used_truth.iter().filter_map(|f| f.probe_pose_error.map(|e| e.0)));
    let probe_r = mean(used_truth.iter().filter_map(|f| f.probe_pose_error.map(|e| e.1)));
    let probe_depth = mean(used_truth.iter().filter_map(|f| f.probe_depth_error_mm));
    let phantom_t = mean(used_truth.iter().filter_map(|f| f.phantom_pose_error.map(|e| e.0)));
    let phantom_r = mean(used_truth.iter().filter_map(|f| f.phantom_pose_error.map(|e| e.1)));
    // Lever arm: from the probe board's origin to the image centre, through the estimate.
    let fit = run.primary_fit();
    let [w, h] = used.iter().find_map(|f| f.bscan_size_px).unwrap_or([0, 0]);
    let centre = pixel_to_image_mm([(w as f64 - 1.0) / 2.0, (h as f64 - 1.0) / 2.0], run.spacing_mm_per_px);
    let lever = fit.apply(&centre).coords.norm();
    let lever_effect = probe_r.map(|r| r.to_radians() * lever);
    values.push(("probe board position error (mm)".into(), mm(probe_t)));
    values.push(("… of it along the viewing axis (mm)".into(), mm(probe_depth)));
    values.push(("probe board rotation error (°)".into(), mm(probe_r)));
    values.push(("phantom board position error (mm)".into(), mm(phantom_t)));
    values.push(("phantom board rotation error (°)".into(), mm(phantom_r)));
    values.push(("lever arm board → image centre (mm)".into(), format!("{lever:.1}")));
    values.push(("probe rotation error × lever arm (mm)".into(), mm(lever_effect)));
    let depth = if run.camera.tracker.is_some() {
        String::new()
    } else {
        format!(
            ", {} mm of it along the camera's viewing axis (depth is what a monocular camera measures worst),",
            mm(probe_depth)
        )
    };
    let (who, marker) = if run.camera.tracker.is_some() {
        ("tracker's", "marker")
    } else {
        ("photo's", "board")
    };
    let mut explanation = format!(
        "The probe {marker}'s pose (the {who}) is off by {} mm on average{depth} and by {}°. Over the \
         {lever:.0} mm lever arm from the {marker} to the image centre that rotation alone moves B-scan \
         points by {} mm; the phantom {marker} adds {} mm and {}°. The calibration solved from these \
         frames places the image corners {:.3} mm from the truth.",
        mm(probe_t),
        mm(probe_r),
        mm(lever_effect),
        mm(phantom_t),
        mm(phantom_r),
        c.corner_error_mean_mm
    );
    if let Some((name, e)) = gated {
        explanation.push_str(&format!(
            " The estimator its gates check, {name}, places them {e:.3} mm from it."
        ));
    }
    explanation
}

/// The points each board's pose was solved from, over a run's used frames.
pub(crate) struct BoardPoints {
    pub median: [f64; 2],
    pub fewest: [usize; 2],
}

/// Probe's and phantom's, or `None` when no used frame has board points (tracker poses).
pub(crate) fn board_points(run: &DatasetRun) -> Option<BoardPoints> {
    let counts: Vec<[usize; 2]> = run
        .frames
        .iter()
        .filter(|f| f.rejection.is_none())
        .filter_map(|f| f.poses.as_ref())
        .map(|p| [p.camera_T_marker.corners_px.len(), p.camera_T_phantom.corners_px.len()])
        .filter(|c| c[0] > 0 && c[1] > 0)
        .collect();
    if counts.is_empty() {
        return None;
    }
    let median = [0, 1].map(|k| {
        let mut v: Vec<f64> = counts.iter().map(|c| c[k] as f64).collect();
        crate::core::stats::median(&mut v)
    });
    let fewest = [0, 1].map(|k| counts.iter().map(|c| c[k]).min().unwrap_or_default());
    Some(BoardPoints { median, fewest })
}

/// Builds one column from a dataset run.
pub fn column(labels: &RunLabels, run: &DatasetRun) -> CompareColumn {
    let used: Vec<_> = run.frames.iter().filter(|f| f.rejection.is_none()).collect();
    let rejected_at = |stage: Stage| {
        run.frames
            .iter()
            .filter(|f| f.rejection.as_ref().is_some_and(|r| r.stage() == stage))
            .count()
    };
    let probe_rms = mean(
        used.iter()
            .filter_map(|f| f.poses.as_ref().map(|p| p.camera_T_marker.reprojection_rms_px)),
    );
    let phantom_rms = mean(
        used.iter()
            .filter_map(|f| f.poses.as_ref().map(|p| p.camera_T_phantom.reprojection_rms_px)),
    );
    let primary = &run.thresholds[run.primary];
    let mut values = vec![
        (
            "frames used / total".to_string(),
            format!("{} / {}", used.len(), run.frames.len()),
        ),
        (
            "rejected: board pose".to_string(),
            rejected_at(Stage::BoardPose).to_string(),
        ),
        ("rejected: arc".to_string(), rejected_at(Stage::Arc).to_string()),
        (
            "board points per frame, median: probe / phantom".to_string(),
            board_points(run).map_or("—".into(), |p| format!("{:.0} / {:.0}", p.median[0], p.median[1])),
        ),
        ("probe board reprojection RMS (px)".to_string(), mm(probe_rms)),
        ("phantom board reprojection RMS (px)".to_string(), mm(phantom_rms)),
        (
            "calibration cut-off (frames)".to_string(),
            format!("{} ({})", cutoff_label(primary.cutoff_mm), primary.frames.len()),
        ),
    ];
    values.extend(bre_rows(run));
    let explanation = match &run.truth {
        Some(t) => truth_rows(labels, run, &used, t, &mut values),
        None => String::new(),
    };
    CompareColumn {
        experiment: run.experiment.clone(),
        dataset: run.dataset.clone(),
        rig: labels.pose_source_short.clone(),
        values,
        explanation,
    }
}

/// The comparison as a Markdown table (rows: quantities; columns: experiments).
pub fn markdown(columns: &[CompareColumn]) -> String {
    let mut s = String::from("| |");
    for c in columns {
        s.push_str(&format!(" {} / {} ({}) |", c.experiment, c.dataset, c.rig));
    }
    s.push_str("\n|---|");
    s.push_str(&"---|".repeat(columns.len()));
    s.push('\n');
    let rows: Vec<String> = columns
        .first()
        .map(|c| c.values.iter().map(|v| v.0.clone()).collect())
        .unwrap_or_default();
    for row in rows {
        s.push_str(&format!("| {row} |"));
        for c in columns {
            let v = c
                .values
                .iter()
                .find(|v| v.0 == row)
                .map(|v| v.1.as_str())
                .unwrap_or("—");
            s.push_str(&format!(" {v} |"));
        }
        s.push('\n');
    }
    for c in columns {
        if !c.explanation.is_empty() {
            s.push_str(&format!("\n**{} / {}**: {}\n", c.experiment, c.dataset, c.explanation));
        }
    }
    s
}

const COMPARE_TEMPLATE: &str = include_str!("../../../templates/compare.html.tera");

/// The comparison page.
pub fn render_html(columns: &[CompareColumn]) -> Result<String, OutputError> {
    render(columns, "compare.html")
}

/// The comparison as LaTeX (landscape, one column per experiment).
pub fn render_tex(columns: &[CompareColumn]) -> Result<String, OutputError> {
    render(columns, "compare.tex")
}

fn render(columns: &[CompareColumn], template: &str) -> Result<String, OutputError> {
    let rows: Vec<String> = columns
        .first()
        .map(|c| c.values.iter().map(|v| v.0.clone()).collect())
        .unwrap_or_default();
    let table: Vec<(String, Vec<String>)> = rows
        .iter()
        .map(|row| {
            (
                row.clone(),
                columns
                    .iter()
                    .map(|c| {
                        c.values
                            .iter()
                            .find(|v| &v.0 == row)
                            .map(|v| v.1.clone())
                            .unwrap_or_else(|| "—".into())
                    })
                    .collect(),
            )
        })
        .collect();
    let mut ctx = tera::Context::new();
    ctx.insert("columns", columns);
    ctx.insert("table", &table);
    let mut t = tera::Tera::default();
    t.add_raw_templates(vec![
        ("compare.html", COMPARE_TEMPLATE),
        ("compare.tex", COMPARE_TEX_TEMPLATE),
    ])?;
    crate::report::templating::register_tex_filter(&mut t);
    Ok(t.render(template, &ctx)?)
}

const COMPARE_TEX_TEMPLATE: &str = include_str!("../../../templates/compare.tex.tera");

/// Writes `compare.md`, `compare.html` and `compare.tex` into `out` for the runs
/// (each with its manifest's index); the markdown is printed unless quiet.
pub fn write(
    out: &std::path::Path,
    labels: &[RunLabels],
    runs: &[(usize, DatasetRun)],
    quiet: bool,
) -> Result<(), OutputError> {
    use crate::io::fs::write_atomic;
    let columns: Vec<CompareColumn> = runs.iter().map(|(i, r)| column(&labels[*i], r)).collect();
    let markdown = markdown(&columns);
    if !quiet {
        println!("{markdown}");
    }
    write_atomic(&out.join("compare.md"), markdown.as_bytes())?;
    let html = render_html(&columns)?;
    write_atomic(&out.join("compare.html"), html.as_bytes())?;
    let tex = render_tex(&columns)?;
    Ok(write_atomic(&out.join("compare.tex"), tex.as_bytes())?)
}
