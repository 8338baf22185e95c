//! Outputs of a tracked (sequence-file) run: frames.csv/.parquet, summary.json,
//! `Calibration.xml` (PLUS), `Calibration.tfm` (ITK/Slicer) and report.html.

pub mod figures;
pub mod gallery;
pub mod lag;
mod selection;
pub mod transform_files;
pub mod volume;
use std::path::Path;

use nalgebra::Matrix4;
use polars::prelude::*;

use crate::core::geometry::{euler_zyx_deg, Rigid};
use crate::core::stats::{best_95, block_mean_interval, mean, mean_sd_of, MeanSd};
use crate::evaluate::pose_coverage::AngleRange;
use crate::io::fs::write_atomic;
use crate::io::plus::result::PlusResult;
use crate::pipeline::labels::TrackedLabels;
use crate::pipeline::tracked::resolution::{TrackedAfter, ValidationResolution};
use crate::pipeline::tracked::{Role, TrackedRun};
use crate::report::error::OutputError;
use crate::results::summary::{
    to_text, CandidateScore, ConstraintCounts, FramesCompared, ImageToProbeSummary, ModelSelectionSummary,
    PairedDifference, ParameterSd, PlusResultSummary, Pre3d, PublishedPre3d, Segmented, TrackedFrameCounts,
    TrackedSummary, TrackedTolerances, TRACKED_KIND,
};

/// Consecutive frames per block of the paired comparison's bootstrap, as the
/// validation resolution's.
const PAIRED_BLOCK_FRAMES: usize = 10;

/// PRE3D of `image_to_probe` (PLUS's `Calibration` matrix) on `role`'s used
/// dots and poses in the frames `keep` admits, with the phantom's registration
/// as configured (a correction this run may have fitted is its own, not the
/// matrix's).
pub fn pre3d_of_matrix(
    run: &TrackedRun,
    labels: &TrackedLabels,
    image_to_probe: &Matrix4<f64>,
    role: Role,
    keep: impl Fn(usize) -> bool,
) -> Vec<f64> {
    let map = |pixel: [f64; 2]| image_to_probe.transform_point(&nalgebra::Point3::new(pixel[0], pixel[1], 0.0));
    run.frames
        .iter()
        .filter(|f| f.role == role && f.rejected.is_none() && keep(f.index))
        .flat_map(|f| crate::pipeline::tracked::pre3d(f, &labels.nwires, map, &Rigid::identity()))
        .collect()
}

/// How the tracker's lag was had, in words.
pub fn time_offset_note(run: &TrackedRun) -> String {
    match &run.lag_estimate {
        None => "as the manifest gives it".into(),
        Some(e) => e.decision.clone(),
    }
}

pub fn rows(m: &Matrix4<f64>) -> Vec<Vec<f64>> {
    (0..4).map(|r| (0..4).map(|c| m[(r, c)]).collect()).collect()
}

/// PRE3D of our calibration on `role`'s frames; with PLUS's result, its matrix
/// and ours side by side on the frames both segmented (all ours where the file
/// does not list PLUS's).
fn pre3d(run: &TrackedRun, labels: &TrackedLabels, plus: Option<&PlusResult>, role: Role) -> Pre3d {
    let ours = run.pre3d(role);
    let mut out = Pre3d {
        pre3d_mm: best_95(&ours),
        pre3d_all_mm: mean_sd_of(&ours),
        ..Pre3d::default()
    };
    (out.no_lag, out.across_lag_interval) = lag::other_lags_pre3d(run, labels, plus, role, |index| {
        let listed = plus.and_then(|p| match role {
            Role::Calibration => p.calibration_frames_segmented.as_ref(),
            Role::Validation => p.validation_frames_segmented.as_ref(),
        });
        listed.is_none_or(|t| t.contains(&index))
    });
    let Some(plus) = plus else { return out };
    let theirs = match role {
        Role::Calibration => plus.calibration_frames_segmented.as_ref(),
        Role::Validation => plus.validation_frames_segmented.as_ref(),
    };
    let keep = |index: usize| theirs.is_none_or(|t| t.contains(&index));
    let used: Vec<usize> = run
        .frames
        .iter()
        .filter(|f| f.role == role && f.rejected.is_none())
        .map(|f| f.index)
        .collect();
    let matrix = pre3d_of_matrix(run, labels, &plus.image_to_probe, role, keep);
    let fit = &run.fit;
    let plus_map = |pixel: [f64; 2]| {
        plus.image_to_probe
            .transform_point(&nalgebra::Point3::new(pixel[0], pixel[1], 0.0))
    };
    let mut same = Vec::new();
    let mut differences = Vec::new();
    for f in run
        .frames
        .iter()
        .filter(|f| f.role == role && f.rejected.is_none() && keep(f.index))
    {
        let ours = crate::pipeline::tracked::pre3d(
            f,
            &labels.nwires,
            |pixel| fit.image_to_probe.apply(pixel),
            &fit.phantom_correction,
        );
        let theirs = crate::pipeline::tracked::pre3d(f, &labels.nwires, plus_map, &Rigid::identity());
        if let (Some(a), Some(b)) = (mean(ours.iter().copied()), mean(theirs.iter().copied())) {
            differences.push(a - b);
        }
        same.extend(ours);
    }
    out.plus_matrix_pre3d_mm = best_95(&matrix);
    out.plus_matrix_pre3d_all_mm = mean_sd_of(&matrix);
    out.same_frames_pre3d_mm = best_95(&same);
    out.ours_minus_plus_matrix_mm = mean(differences.iter().copied()).map(|m| PairedDifference {
        mean: m,
        interval_90: block_mean_interval(&differences, PAIRED_BLOCK_FRAMES, 0.9),
        frames: differences.len(),
        block_frames: PAIRED_BLOCK_FRAMES,
        frames_won: differences.iter().filter(|d| **d < 0.0).count(),
    });
    out.frames_compared = Some(FramesCompared {
        ours: used.len(),
        plus: theirs.map(|t| t.len()),
        both: used.iter().filter(|i| keep(**i)).count(),
    });
    out
}

fn model_selection(run: &TrackedRun) -> ModelSelectionSummary {
    let s = &run.selection;
    let chosen = s.chosen();
    ModelSelectionSummary {
        folds: s.folds,
        frames: s.frames,
        candidates: s
            .scored
            .iter()
            .map(|c| CandidateScore {
                constraints: c.candidate.constraints,
                pixel_model: c.candidate.pixel_model,
                cv_pre3d_mm: c.cv_pre3d_mm,
                failure: c.failure.clone(),
            })
            .collect(),
        chosen_constraints: chosen.constraints,
        chosen_pixel_model: chosen.pixel_model,
    }
}

/// `summary.json`.
pub fn summary(
    run: &TrackedRun,
    after: &TrackedAfter,
    labels: &TrackedLabels,
    plus: Option<&PlusResult>,
) -> TrackedSummary {
    let fit = &run.fit.image_to_probe;
    let matrix = fit.matrix();
    let (cal_used, cal_total) = run.segmented(Role::Calibration);
    let (val_used, val_total) = run.segmented(Role::Validation);
    let t = fit.marker_T_image.translation.vector;
    TrackedSummary {
        schema_version: crate::results::SCHEMA_VERSION,
        experiment: labels.experiment.clone(),
        dataset: labels.dataset.clone(),
        kind: TRACKED_KIND.into(),
        frames: TrackedFrameCounts {
            calibration: Segmented {
                segmented: cal_used,
                total: cal_total,
            },
            validation: Segmented {
                segmented: val_used,
                total: val_total,
            },
            rejected: (cal_total - cal_used) + (val_total - val_used),
            rejected_by_check: crate::pipeline::sequence_frames::rejections_by_check(&run.frames),
            overlay_px: run.overlay_px,
        },
        constraints: ConstraintCounts {
            model: run.selection.chosen().constraints,
            count: run.constraints,
            kept: run.fit.inlier.iter().filter(|k| **k).count(),
        },
        time_offset_s: run.time_offset_s,
        time_offset_estimate: run.lag_estimate.clone(),
        image_to_probe: ImageToProbeSummary {
            matrix: rows(&matrix),
            pixel_model: run.fit.pixel_model,
            spacing_mm_per_px: fit.spacing_mm_per_px,
            shear_mm_per_px: fit.shear_mm_per_px,
            rotation_zyx_deg: euler_zyx_deg(&fit.marker_T_image),
            translation_mm: [t.x, t.y, t.z],
            sd: ParameterSd {
                rotation_mrad: run.fit.sd.iter().take(3).map(|v| v * 1000.0).collect(),
                translation_mm: run.fit.sd.iter().skip(3).take(3).copied().collect(),
                spacing_mm_per_px: run.fit.sd.iter().skip(6).take(2).copied().collect(),
                shear_mm_per_px: run.fit.sd.get(8).copied().unwrap_or(0.0),
            },
        },
        model_selection: model_selection(run),
        validation: pre3d(run, labels, plus, Role::Validation),
        resolution: after.resolution,
        calibration: pre3d(run, labels, plus, Role::Calibration),
        gates: after.gates.clone(),
        regression_tolerances: TrackedTolerances {
            pre3d_mm: labels.regression_pre3d_mm,
            frames_rejected: labels.regression_frames_rejected,
        },
        plus_result: plus.map(|p| PlusResultSummary {
            matrix: rows(&p.image_to_probe),
            published_validation_pre3d_mm: PublishedPre3d {
                mean: p.validation_mean_mm,
                std: p.validation_std_mm,
            },
            published_calibration_pre3d_mm: PublishedPre3d {
                mean: p.calibration_mean_mm,
                std: p.calibration_std_mm,
            },
        }),
        reconstruction: None,
    }
}

/// The per-frame table.
pub fn frames_table(run: &TrackedRun, patterns: usize) -> PolarsResult<DataFrame> {
    let f = &run.frames;
    let mut columns = vec![
        Column::new(
            "sequence".into(),
            f.iter()
                .map(|r| match r.role {
                    Role::Calibration => "calibration",
                    Role::Validation => "validation",
                })
                .collect::<Vec<_>>(),
        ),
        Column::new("frame".into(), f.iter().map(|r| r.index as u64).collect::<Vec<_>>()),
        Column::new(
            "timestamp_s".into(),
            f.iter().map(|r| r.timestamp_s).collect::<Vec<_>>(),
        ),
        Column::new(
            "status".into(),
            f.iter()
                .map(|r| if r.rejected.is_none() { "used" } else { "rejected" })
                .collect::<Vec<_>>(),
        ),
        Column::new(
            "check".into(),
            f.iter()
                .map(|r| r.rejected.as_ref().map(|j| j.check()))
                .collect::<Vec<_>>(),
        ),
        Column::new(
            "reason".into(),
            f.iter()
                .map(|r| r.rejected.as_ref().map(|j| j.to_string()))
                .collect::<Vec<_>>(),
        ),
    ];
    for p in 0..patterns {
        for w in 0..3 {
            for (axis, name) in ["u", "v"].iter().enumerate() {
                columns.push(Column::new(
                    format!("n{}_wire{}_{name}_px", p + 1, w + 1).into(),
                    f.iter()
                        .map(|r| r.dots_px.get(p).map(|d| d[w][axis]))
                        .collect::<Vec<_>>(),
                ));
            }
        }
        columns.push(Column::new(
            format!("n{}_pre3d_mm", p + 1).into(),
            f.iter().map(|r| r.pre3d_mm.get(p).copied()).collect::<Vec<_>>(),
        ));
    }
    DataFrame::new(f.len(), columns)
}

pub use crate::report::tracked::transform_files::{itk_tfm, plus_xml};

/// Writes the run's files into `folder`.
pub fn write(
    run: &TrackedRun,
    after: &TrackedAfter,
    labels: &TrackedLabels,
    plus: Option<&PlusResult>,
    folder: &Path,
) -> Result<TrackedSummary, OutputError> {
    std::fs::create_dir_all(folder).map_err(|e| OutputError::Io {
        path: folder.to_path_buf(),
        message: e.to_string(),
    })?;
    crate::report::page::write::write_frames_table(folder, &mut frames_table(run, labels.nwires.len())?)?;
    let mut summary = summary(run, after, labels, plus);
    if let Some(volume) = &after.volume {
        summary.reconstruction = Some(crate::report::tracked::volume::write(volume, folder)?);
    }
    let text = to_text(&summary)?;
    write_atomic(&folder.join("summary.json"), text.as_bytes())?;
    let matrix = run.fit.image_to_probe.matrix();
    write_atomic(&folder.join("ImageToProbe.xml"), plus_xml(&matrix).as_bytes())?;
    let tfm = itk_tfm(&matrix).ok_or_else(|| OutputError::Report("ImageToProbe is singular".into()))?;
    write_atomic(&folder.join("ImageToProbe.tfm"), tfm.as_bytes())?;
    let lag = crate::report::tracked::transform_files::tracker_lag_xml(run.time_offset_s, &time_offset_note(run));
    write_atomic(&folder.join("TrackerLag.xml"), lag.as_bytes())?;
    if let Some(chart) = run
        .lag_estimate
        .as_ref()
        .and_then(crate::report::tracked::lag::lag_chart)
    {
        write_atomic(
            &folder.join("lag_objective.png"),
            &crate::report::page::figures::png(&chart)?,
        )?;
    }
    let charts = crate::report::tracked::figures::charts(run, labels, plus);
    let gallery = crate::report::tracked::gallery::gallery(run, labels);
    let (html, tex, mut figures) = render_pages(run, labels, &summary, &charts, &gallery)?;
    if !gallery.is_empty() {
        std::fs::create_dir_all(folder.join("gallery")).map_err(|e| OutputError::io(folder.join("gallery"), e))?;
    }
    figures.extend(
        gallery
            .into_iter()
            .enumerate()
            .map(|(k, g)| (crate::report::tracked::gallery::file_name(k), g.jpeg)),
    );
    for (name, bytes) in figures {
        write_atomic(&folder.join(name), &bytes)?;
    }
    write_atomic(&folder.join("report.html"), html.as_bytes())?;
    write_atomic(&folder.join("report.tex"), tex.as_bytes())?;
    Ok(summary)
}

const TRACKED_TEMPLATE: &str = include_str!("../../../templates/tracked.html.tera");
const TRACKED_TEX_TEMPLATE: &str = include_str!("../../../templates/tracked.tex.tera");

/// The page's "what the validation score can tell" table; `null` when there is nothing in it.
fn resolution_rows(r: &ValidationResolution) -> serde_json::Value {
    let f3 = |x: f64| format!("{x:.3}");
    let range = |a: &AngleRange| format!("{:.1} / {:.1} / {:.1}", a.min, a.median, a.max);
    if r.bootstrap_pre3d_mm.is_none() && r.own_fit_pre3d_mm.is_none() && r.pose_coverage.is_none() {
        return serde_json::Value::Null;
    }
    serde_json::json!({
        "bootstrap": r.bootstrap_pre3d_mm.map(|b| serde_json::json!({
            "p5": f3(b.p5), "p50": f3(b.p50), "p95": f3(b.p95), "resamples": b.resamples, "block_frames": b.block_frames,
        })),
        "own_fit": r.own_fit_pre3d_mm.map(|s| format!("{} ± {} (n = {})", f3(s.mean), f3(s.std), s.n)),
        "coverage": r.pose_coverage.map(|c| serde_json::json!({
            "cal_lateral": range(&c.calibration.lateral_deg), "val_lateral": range(&c.validation.lateral_deg),
            "cal_axial": range(&c.calibration.axial_deg), "val_axial": range(&c.validation.axial_deg),
            "outside": c.validation_outside_calibration, "val_frames": c.validation.frames,
        })),
    })
}

/// The page of a tracked (sequence-file) run, from its summary.
/// The PRE3D table's rows: ours on validation and calibration frames, and with
/// PLUS's result, ours and PLUS's matrix on the same frames and PLUS as published.
fn pre3d_rows(summary: &TrackedSummary) -> Vec<serde_json::Value> {
    let f3 = |v: Option<f64>| v.map(|x| format!("{x:.3}")).unwrap_or_else(|| "—".into());
    // An absent count says so as the other absent cells do (never `null` in LaTeX).
    let n = |v: Option<MeanSd>| v.map_or_else(|| "—".to_string(), |s| s.n.to_string());
    let row = |estimate: &str, frames: &str, best: Option<MeanSd>, all: Option<MeanSd>| {
        serde_json::json!({
            "estimate": estimate, "frames": frames,
            "mean": f3(best.map(|s| s.mean)), "std": f3(best.map(|s| s.std)), "n": n(best),
            "mean_all": f3(all.map(|s| s.mean)), "std_all": f3(all.map(|s| s.std)), "n_all": n(all),
        })
    };
    let mut pre3d = vec![
        row(
            "probecal",
            "validation",
            summary.validation.pre3d_mm,
            summary.validation.pre3d_all_mm,
        ),
        row(
            "probecal",
            "calibration",
            summary.calibration.pre3d_mm,
            summary.calibration.pre3d_all_mm,
        ),
    ];
    if let Some(plus) = &summary.plus_result {
        let both = summary
            .validation
            .frames_compared
            .map(|c| format!("validation, the {} frames both segmented", c.both))
            .unwrap_or_else(|| "validation".into());
        pre3d.push(row(
            "probecal, same frames as PLUS's matrix",
            &both,
            summary.validation.same_frames_pre3d_mm,
            None,
        ));
        pre3d.push(row(
            "PLUS's ImageToProbe, same dots, poses and frames",
            &both,
            summary.validation.plus_matrix_pre3d_mm,
            summary.validation.plus_matrix_pre3d_all_mm,
        ));
        let published_frames = summary
            .validation
            .frames_compared
            .and_then(|c| c.plus)
            .map(|n| format!("validation, {n} frames PLUS segmented"))
            .unwrap_or_else(|| "validation".into());
        pre3d.push(serde_json::json!({
            "estimate": "PLUS as published (its own dots)", "frames": published_frames,
            "mean": f3(plus.published_validation_pre3d_mm.mean), "std": f3(plus.published_validation_pre3d_mm.std),
            "n": "—", "mean_all": "—", "std_all": "—", "n_all": "—",
        }));
    }
    if let Some(no_lag) = summary.validation.no_lag {
        pre3d.push(row(
            "probecal refitted with no lag",
            "validation, no lag",
            no_lag.pre3d_mm,
            None,
        ));
        if no_lag.plus_matrix_pre3d_mm.is_some() {
            pre3d.push(row(
                "PLUS's ImageToProbe with no lag",
                "validation, no lag, the same frames",
                no_lag.plus_matrix_pre3d_mm,
                None,
            ));
        }
    }
    pre3d
}

/// The matrix as fixed-width text, a row a line.
fn matrix_text(m: &Matrix4<f64>) -> String {
    (0..4)
        .map(|r| {
            (0..4)
                .map(|c| format!("{:>13.6}", m[(r, c)]))
                .collect::<Vec<_>>()
                .join(" ")
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// The matrix's cells, 6 decimals, for the LaTeX array.
fn matrix_cells(m: &Matrix4<f64>) -> Vec<Vec<String>> {
    (0..4)
        .map(|r| (0..4).map(|c| format!("{:.6}", m[(r, c)])).collect())
        .collect()
}

/// The rejected frames, each with its reason, and their count by check.
fn insert_rejections(ctx: &mut tera::Context, run: &TrackedRun) {
    let rejected: Vec<serde_json::Value> = run
        .frames
        .iter()
        .filter_map(|f| {
            f.rejected.as_ref().map(|r| {
                serde_json::json!({"sequence": format!("{:?}", f.role).to_lowercase(), "frame": f.index, "reason": r})
            })
        })
        .collect();
    ctx.insert("rejected", &rejected);
    let by_check: Vec<serde_json::Value> = crate::pipeline::sequence_frames::rejections_by_check(&run.frames)
        .into_iter()
        .map(|(check, frames)| serde_json::json!({"check": check, "frames": frames}))
        .collect();
    ctx.insert("rejected_by_check", &by_check);
}

/// The run's page in HTML and in LaTeX, from one context.
fn render_pages(
    run: &TrackedRun,
    labels: &TrackedLabels,
    summary: &TrackedSummary,
    charts: &[crate::report::page::figures::Chart],
    gallery: &[crate::report::page::gallery::GalleryImage],
) -> Result<(String, String, crate::report::tracked::figures::FigureFiles), OutputError> {
    let f3 = |v: Option<f64>| v.map(|x| format!("{x:.3}")).unwrap_or_else(|| "—".into());
    let mut ctx = tera::Context::new();
    ctx.insert("experiment", &labels.experiment);
    ctx.insert("dataset", &labels.dataset);
    ctx.insert("description", &labels.description);
    ctx.insert(
        "calibration_sequence",
        &labels.calibration_sequence.display().to_string(),
    );
    ctx.insert(
        "validation_sequence",
        &labels
            .validation_sequence
            .as_ref()
            .map(|p| p.display().to_string())
            .unwrap_or_else(|| "—".into()),
    );
    let definition = match &labels.plus_config {
        Some(path) => path.display().to_string(),
        None => "the manifest's patterns".to_string(),
    };
    ctx.insert("plus_config", &definition);
    ctx.insert("nwires", &labels.nwires.len());
    selection::insert_selection(&mut ctx, run);
    ctx.insert("folds", &run.selection.folds);
    ctx.insert("selection_frames", &run.selection.frames);
    ctx.insert("constraints", &run.constraints);
    ctx.insert("kept", &run.fit.inlier.iter().filter(|k| **k).count());
    ctx.insert("time_offset_ms", &format!("{:.0}", run.time_offset_s * 1000.0));
    ctx.insert("time_offset_note", &time_offset_note(run));
    ctx.insert("probecal_version", env!("CARGO_PKG_VERSION"));
    ctx.insert("opencv_version", &crate::report::page::provenance::opencv_version());
    let (cs, ct) = run.segmented(Role::Calibration);
    let (vs, vt) = run.segmented(Role::Validation);
    ctx.insert("cal_segmented", &cs);
    ctx.insert("cal_total", &ct);
    ctx.insert("val_segmented", &vs);
    ctx.insert("val_total", &vt);
    insert_rejections(&mut ctx, run);
    let m = run.fit.image_to_probe.matrix();
    ctx.insert("matrix_text", &matrix_text(&m));
    ctx.insert("matrix", &matrix_cells(&m));
    let s = run.fit.image_to_probe.spacing_mm_per_px;
    ctx.insert("spacing_u", &format!("{:.5}", s[0]));
    ctx.insert("spacing_v", &format!("{:.5}", s[1]));
    let e = crate::core::geometry::euler_zyx_deg(&run.fit.image_to_probe.marker_T_image);
    ctx.insert("euler", &format!("[{:.2}, {:.2}, {:.2}]", e[0], e[1], e[2]));
    let t = run.fit.image_to_probe.marker_T_image.translation.vector;
    ctx.insert("translation", &format!("[{:.2}, {:.2}, {:.2}]", t.x, t.y, t.z));
    let pre3d = pre3d_rows(summary);
    ctx.insert("pre3d", &pre3d);
    lag::insert_figure(&mut ctx, run, &summary.validation.across_lag_interval)?;
    let figures = crate::report::tracked::figures::insert(&mut ctx, charts)?;
    crate::report::tracked::gallery::insert(&mut ctx, gallery);
    let paired = summary
        .validation
        .ours_minus_plus_matrix_mm
        .map(|d| d.sentence("probecal", "PLUS's matrix"));
    ctx.insert("paired", &paired);
    ctx.insert("resolution", &resolution_rows(&summary.resolution));
    let volume = summary
        .reconstruction
        .as_ref()
        .map(crate::report::tracked::volume::page_context);
    ctx.insert("volume", &volume);
    let gates: Vec<serde_json::Value> = summary
        .gates
        .iter()
        .map(|g| serde_json::json!({"name": g.name, "value": f3(g.value), "limit": g.limit, "passed": g.passed}))
        .collect();
    ctx.insert("gates", &gates);
    let mut t = tera::Tera::default();
    crate::report::templating::register_tex_filter(&mut t);
    t.add_raw_templates(vec![
        ("tracked.html", TRACKED_TEMPLATE),
        ("tracked.tex", TRACKED_TEX_TEMPLATE),
    ])
    .and_then(|_| Ok((t.render("tracked.html", &ctx)?, t.render("tracked.tex", &ctx)?, figures)))
    .map_err(OutputError::from)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn itk_file_round_trips_to_the_matrix() {
        let m = Matrix4::new(
            0.0, 0.0745, 0.0, 11.2, -0.0803, 0.0, 0.0, 48.4, 0.0, 0.0, 0.0774, -0.4, 0.0, 0.0, 0.0, 1.0,
        );
        let text = itk_tfm(&m).unwrap();
        let line = text.lines().find(|l| l.starts_with("Parameters:")).unwrap();
        let p: Vec<f64> = line[11..].split_whitespace().map(|v| v.parse().unwrap()).collect();
        let mut back = Matrix4::identity();
        for r in 0..3 {
            for c in 0..3 {
                back[(r, c)] = p[r * 3 + c];
            }
            back[(r, 3)] = p[9 + r];
        }
        let f = Matrix4::from_diagonal(&nalgebra::Vector4::new(-1.0, -1.0, 1.0, 1.0));
        let recovered = (f * back * f).try_inverse().unwrap();
        assert!((recovered - m).abs().max() < 1e-9);
        assert!(plus_xml(&m).contains("From=\"Image\" To=\"Probe\""));
    }
}
