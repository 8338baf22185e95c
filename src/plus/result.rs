//! PLUS's own calibration result file (`ProbeCalibrationResult` XML): its
//! `ImageToProbe` and its PRE3D statistics, read for comparison only.

use std::path::Path;

use nalgebra::Matrix4;

use super::config::ConfigError;

#[derive(Debug, Clone, PartialEq)]
pub struct PlusResult {
    pub image_to_probe: Matrix4<f64>,
    pub validation_mean_mm: Option<f64>,
    pub validation_std_mm: Option<f64>,
    pub calibration_mean_mm: Option<f64>,
    pub calibration_std_mm: Option<f64>,
}

impl PlusResult {
    pub fn read(path: &Path) -> Result<PlusResult, ConfigError> {
        let fail = |line: Option<usize>, message: String| ConfigError {
            path: path.to_path_buf(),
            line,
            message,
        };
        let text = std::fs::read_to_string(path).map_err(|e| fail(None, format!("cannot read: {e}")))?;
        let doc = roxmltree::Document::parse(&text)
            .map_err(|e| fail(Some(e.pos().row as usize), format!("not well-formed XML: {e}")))?;
        let transform = doc
            .descendants()
            .find(|n| {
                n.has_tag_name("Transform")
                    && n.attribute("From") == Some("Image")
                    && n.attribute("To") == Some("Probe")
            })
            .ok_or_else(|| fail(None, "no <Transform From=\"Image\" To=\"Probe\">".into()))?;
        let line = doc.text_pos_at(transform.range().start).row as usize;
        let numbers: Vec<f64> = transform
            .attribute("Matrix")
            .unwrap_or("")
            .split_whitespace()
            .map(|s| s.parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| fail(Some(line), "`Matrix` holds a non-number".into()))?;
        if numbers.len() != 16 {
            return Err(fail(
                Some(line),
                format!("`Matrix` has {} numbers, 16 expected", numbers.len()),
            ));
        }
        let stats = doc
            .descendants()
            .find(|n| n.has_tag_name("ReprojectionError3DStatistics"));
        let stat = |name: &str| {
            stats
                .and_then(|n| n.attribute(name))
                .and_then(|v| v.parse::<f64>().ok())
        };
        Ok(PlusResult {
            image_to_probe: Matrix4::from_fn(|r, c| numbers[r * 4 + c]),
            validation_mean_mm: stat("ValidationMeanMm"),
            validation_std_mm: stat("ValidationStdDevMm"),
            calibration_mean_mm: stat("CalibrationMeanMm"),
            calibration_std_mm: stat("CalibrationStdDevMm"),
        })
    }
}
