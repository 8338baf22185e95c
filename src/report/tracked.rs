//! Outputs of a tracked (sequence-file) run: frames.csv/.parquet, summary.json,
//! `ImageToProbe.xml` (PLUS), `ImageToProbe.tfm` (ITK/Slicer) and report.html.

use std::path::Path;

use nalgebra::{Matrix3, Matrix4};
use polars::prelude::*;
use serde::Serialize;
use serde_json::{json, Value};

use crate::core::geometry::euler_zyx_deg;
use crate::io::fs::write_atomic;
use crate::io::plus::result::PlusResult;
use crate::manifest::tracked::TrackedManifest;
use crate::pipeline::tracked::{ErrorStats, Role, TrackedRun};
use crate::report::write::OutputError;

/// PRE3D of a general `ImageToProbe` matrix (e.g. PLUS's) on this run's segmented dots.
pub fn pre3d_of_matrix(
    run: &TrackedRun,
    manifest: &TrackedManifest,
    image_to_probe: &Matrix4<f64>,
    role: Role,
) -> Vec<f64> {
    let map = |pixel: [f64; 2]| image_to_probe.transform_point(&nalgebra::Point3::new(pixel[0], pixel[1], 0.0));
    run.frames
        .iter()
        .filter(|f| f.role == role && f.rejected.is_none())
        .flat_map(|f| crate::pipeline::tracked::pre3d(f, &manifest.nwires, map, &run.fit.phantom_correction))
        .collect()
}

fn rows(m: &Matrix4<f64>) -> Vec<Vec<f64>> {
    (0..4).map(|r| (0..4).map(|c| m[(r, c)]).collect()).collect()
}

fn stats_json(s: Option<ErrorStats>) -> Value {
    s.map(|s| json!({"mean": s.mean, "std": s.std, "n": s.n}))
        .unwrap_or(Value::Null)
}

/// A gate of a tracked run.
#[derive(Debug, Clone, Serialize)]
pub struct TrackedGate {
    pub name: String,
    pub value: Option<f64>,
    pub limit: f64,
    pub passed: bool,
}

pub fn gates(run: &TrackedRun, manifest: &TrackedManifest) -> Vec<TrackedGate> {
    let mut out = Vec::new();
    if let Some(limit) = manifest.gates.pre3d_mm {
        let value = ErrorStats::best_95(&run.pre3d(Role::Validation)).map(|s| s.mean);
        out.push(TrackedGate {
            name: "validation PRE3D (mean of best 95 %, mm)".into(),
            value,
            limit,
            passed: value.is_some_and(|v| v <= limit),
        });
    }
    out
}

/// `summary.json`.
pub fn summary(run: &TrackedRun, manifest: &TrackedManifest, plus: Option<&PlusResult>) -> Value {
    let fit = &run.fit.image_to_probe;
    let matrix = fit.matrix();
    let (cal_used, cal_total) = run.segmented(Role::Calibration);
    let (val_used, val_total) = run.segmented(Role::Validation);
    let validation = run.pre3d(Role::Validation);
    let calibration = run.pre3d(Role::Calibration);
    let mut s = json!({
        "experiment": manifest.experiment,
        "dataset": manifest.dataset,
        "kind": "tracked_sequence",
        "frames": {
            "calibration": {"segmented": cal_used, "total": cal_total},
            "validation": {"segmented": val_used, "total": val_total},
            "rejected": (cal_total - cal_used) + (val_total - val_used),
        },
        "constraints": {"model": manifest.model, "count": run.constraints, "kept": run.fit.inlier.iter().filter(|k| **k).count()},
        "time_offset_s": run.time_offset_s,
        "image_to_probe": {
            "matrix": rows(&matrix),
            "spacing_mm_per_px": fit.spacing_mm_per_px,
            "rotation_zyx_deg": euler_zyx_deg(&fit.probe_T_image),
            "translation_mm": fit.probe_T_image.translation.vector.as_slice(),
            "sd": {
                "rotation_mrad": run.fit.sd.iter().take(3).map(|v| v * 1000.0).collect::<Vec<_>>(),
                "translation_mm": run.fit.sd.iter().skip(3).take(3).copied().collect::<Vec<_>>(),
                "spacing_mm_per_px": run.fit.sd.iter().skip(6).take(2).copied().collect::<Vec<_>>(),
            },
        },
        "validation": {
            "pre3d_mm": stats_json(ErrorStats::best_95(&validation)),
            "pre3d_all_mm": stats_json(ErrorStats::of(&validation)),
        },
        "calibration": {
            "pre3d_mm": stats_json(ErrorStats::best_95(&calibration)),
            "pre3d_all_mm": stats_json(ErrorStats::of(&calibration)),
        },
        "gates": gates(run, manifest),
        "regression_tolerances": {
            "pre3d_mm": manifest.regression.pre3d_mm,
            "frames_rejected": manifest.regression.frames_rejected,
        },
    });
    if let Some(p) = plus {
        let on_ours = pre3d_of_matrix(run, manifest, &p.image_to_probe, Role::Validation);
        s["plus_result"] = json!({
            "matrix": rows(&p.image_to_probe),
            "published_validation_pre3d_mm": {"mean": p.validation_mean_mm, "std": p.validation_std_mm},
            "published_calibration_pre3d_mm": {"mean": p.calibration_mean_mm, "std": p.calibration_std_mm},
            "validation_pre3d_on_our_dots_mm": stats_json(ErrorStats::best_95(&on_ours)),
            "validation_pre3d_all_on_our_dots_mm": stats_json(ErrorStats::of(&on_ours)),
        });
    }
    s
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
        Column::new("frame".into(), f.iter().map(|r| r.index as u32).collect::<Vec<_>>()),
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
            "reason".into(),
            f.iter().map(|r| r.rejected.clone()).collect::<Vec<_>>(),
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

/// PLUS's XML form of the result (a `CoordinateDefinitions` transform).
pub fn plus_xml(matrix: &Matrix4<f64>) -> String {
    let mut text = String::from("<CoordinateDefinitions>\n  <Transform From=\"Image\" To=\"Probe\"\n    Matrix=\"\n");
    for r in 0..4 {
        let row: Vec<String> = (0..4).map(|c| format!("{:.9}", matrix[(r, c)])).collect();
        text += &format!("      {}\n", row.join(" "));
    }
    text += "    \" />\n</CoordinateDefinitions>\n";
    text
}

/// An ITK transform file that 3D Slicer loads as the `ImageToProbe` linear transform.
/// ITK files hold the resampling (inverse) transform in LPS; Slicer works in RAS,
/// so the file holds `F * inverse(ImageToProbe) * F` with `F = diag(-1, -1, 1)`.
pub fn itk_tfm(matrix: &Matrix4<f64>) -> Option<String> {
    let inverse = matrix.try_inverse()?;
    let f = Matrix4::from_diagonal(&nalgebra::Vector4::new(-1.0, -1.0, 1.0, 1.0));
    let m = f * inverse * f;
    let a: Matrix3<f64> = m.fixed_view::<3, 3>(0, 0).into_owned();
    let mut params: Vec<String> = Vec::new();
    for r in 0..3 {
        for c in 0..3 {
            params.push(format!("{:.12}", a[(r, c)]));
        }
    }
    for r in 0..3 {
        params.push(format!("{:.12}", m[(r, 3)]));
    }
    Some(format!(
        "#Insight Transform File V1.0\n#Transform 0\nTransform: AffineTransform_double_3_3\nParameters: {}\nFixedParameters: 0 0 0\n",
        params.join(" ")
    ))
}

/// Writes the run's files into `folder`.
pub fn write(
    run: &TrackedRun,
    manifest: &TrackedManifest,
    plus: Option<&PlusResult>,
    folder: &Path,
) -> Result<Value, OutputError> {
    std::fs::create_dir_all(folder).map_err(|e| OutputError::Io {
        path: folder.to_path_buf(),
        message: e.to_string(),
    })?;
    let mut table = frames_table(run, manifest.nwires.len())?;
    let mut csv = Vec::new();
    CsvWriter::new(&mut csv).finish(&mut table)?;
    write_atomic(&folder.join("frames.csv"), &csv)?;
    let mut parquet = Vec::new();
    ParquetWriter::new(&mut parquet).finish(&mut table)?;
    write_atomic(&folder.join("frames.parquet"), &parquet)?;
    let summary = summary(run, manifest, plus);
    let text = serde_json::to_string_pretty(&summary).map_err(|e| OutputError::Report(e.to_string()))? + "\n";
    write_atomic(&folder.join("summary.json"), text.as_bytes())?;
    let matrix = run.fit.image_to_probe.matrix();
    write_atomic(&folder.join("ImageToProbe.xml"), plus_xml(&matrix).as_bytes())?;
    let tfm = itk_tfm(&matrix).ok_or_else(|| OutputError::Report("ImageToProbe is singular".into()))?;
    write_atomic(&folder.join("ImageToProbe.tfm"), tfm.as_bytes())?;
    let html = crate::report::render_tracked(run, manifest, &summary)?;
    write_atomic(&folder.join("report.html"), html.as_bytes())?;
    Ok(summary)
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
