//! PLUS's own calibration result file (`ProbeCalibrationResult` XML): its
//! `Calibration` and its PRE3D statistics, read for comparison only.

use std::path::Path;

use nalgebra::Matrix4;

use super::config::{parse_xml, read_text, ConfigError, Xml};

#[derive(Debug, Clone, PartialEq)]
pub struct PlusResult {
    pub image_to_probe: Matrix4<f64>,
    pub validation_mean_mm: Option<f64>,
    pub validation_std_mm: Option<f64>,
    pub calibration_mean_mm: Option<f64>,
    pub calibration_std_mm: Option<f64>,
    /// The frames PLUS's segmentation found in the calibration and the
    /// validation sequence, where the file lists them per frame.
    pub calibration_frames_segmented: Option<std::collections::BTreeSet<usize>>,
    pub validation_frames_segmented: Option<std::collections::BTreeSet<usize>>,
}

impl PlusResult {
    pub fn read(path: &Path) -> Result<PlusResult, ConfigError> {
        let text = read_text(path)?;
        let doc = parse_xml(path, &text)?;
        let x = Xml { path, doc: &doc };
        let mut found = doc.descendants().filter(|n| {
            n.has_tag_name("Transform") && n.attribute("From") == Some("Image") && n.attribute("To") == Some("Probe")
        });
        let transform = found.next().ok_or_else(|| ConfigError {
            path: path.to_path_buf(),
            line: None,
            message: "no <Transform From=\"Image\" To=\"Probe\">".into(),
        })?;
        if let Some(second) = found.next() {
            return Err(x.fail(
                second,
                format!(
                    "a second <Transform From=\"Image\" To=\"Probe\"> (the first is on line {}): which one is PLUS's result?",
                    x.line(transform)
                ),
            ));
        }
        let numbers = x.numbers(transform, "Matrix", 16)?;
        let image_to_probe = Matrix4::from_fn(|r, c| numbers[r * 4 + c]);
        if let Some(why) = super::xml_limits::affine_fault(&image_to_probe) {
            return Err(x.fail(transform, format!("ImageToProbe's Matrix: {why}")));
        }
        let stats = doc
            .descendants()
            .find(|n| n.has_tag_name("ReprojectionError3DStatistics"));
        let stat = |name: &str| {
            stats
                .and_then(|n| n.attribute(name))
                .and_then(|v| v.parse::<f64>().ok())
        };
        // A bare transform (`<CoordinateDefinitions>`, as `probecal run` and
        // `selfcal` write ImageToProbe.xml) or a device set lists no frames.
        let per_frame = match doc.root_element().tag_name().name() {
            "CoordinateDefinitions" | "PlusConfiguration" => None,
            _ => Some(super::segmentation::PlusSegmentation::of_document(&x)?),
        };
        let found = |name: &str| {
            per_frame
                .as_ref()?
                .section(name)
                .map(|frames| frames.iter().filter(|(_, p)| p.is_some()).map(|(f, _)| *f).collect())
        };
        Ok(PlusResult {
            calibration_frames_segmented: found("calibration"),
            validation_frames_segmented: found("validation"),
            image_to_probe,
            validation_mean_mm: stat("ValidationMeanMm"),
            validation_std_mm: stat("ValidationStdDevMm"),
            calibration_mean_mm: stat("CalibrationMeanMm"),
            calibration_std_mm: stat("CalibrationStdDevMm"),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_image_to_probe_is_refused_at_its_line() {
        let dir = std::env::temp_dir().join(format!("probecal-result-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("result.xml");
        let t = "<Transform From=\"Image\" To=\"Probe\" Matrix=\"1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1\"/>";
        std::fs::write(
            &path,
            format!("<R>\n<CalibrationResults>\n{t}\n{t}\n</CalibrationResults>\n</R>\n"),
        )
        .unwrap();
        let e = PlusResult::read(&path).unwrap_err().to_string();
        assert!(e.ends_with(":4: a second <Transform From=\"Image\" To=\"Probe\"> (the first is on line 3): which one is PLUS's result?"), "{e}");
        std::fs::remove_dir_all(&dir).ok();
    }
}
