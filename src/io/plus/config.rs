//! PLUS device-set configuration XML: `CoordinateDefinitions` (fixed transforms),
//! `PhantomDefinition` (N-wire patterns) and the `Segmentation` hints.

use super::xml_limits::{rigid_fault, wire_end_fault, MAX_CLIP_PX};
use std::path::{Path, PathBuf};

use nalgebra::{Matrix4, Point3};

use crate::spec::nwire::{NWire, WireSegment};

pub use super::config_types::{ConfigError, FixedTransform};

/// What probecal uses of a PLUS configuration.
#[derive(Debug, Clone, PartialEq)]
pub struct PlusConfig {
    pub path: PathBuf,
    pub transforms: Vec<FixedTransform>,
    /// N-wire patterns in file order, in the phantom frame (mm).
    pub nwires: Vec<NWire>,
    /// `Segmentation/@ApproximateSpacingMmPerPixel`.
    pub approximate_spacing_mm_per_px: Option<f64>,
    /// `Segmentation/@ClipRectangleOrigin` and `@ClipRectangleSize` (px).
    pub clip_rectangle_px: Option<([usize; 2], [usize; 2])>,
    /// Each wire's `Id` (its `Name` when it has none), patterns in file order.
    pub wire_ids: Vec<String>,
    /// The device's own segmentation settings, where the file gives them.
    pub segmentation: PlusSegmentation,
    /// The frames `vtkPlusProbeCalibrationAlgo` names (PLUS's defaults where absent).
    pub calibration_frames: CalibrationFrames,
}

/// The coordinate frames of PLUS's probe calibration (`vtkPlusProbeCalibrationAlgo`'s
/// `ProbeCoordinateFrame`, `ReferenceCoordinateFrame`, `PhantomCoordinateFrame`).
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationFrames {
    pub probe: String,
    pub reference: String,
    pub phantom: String,
}

impl Default for CalibrationFrames {
    fn default() -> Self {
        CalibrationFrames {
            probe: "Probe".into(),
            reference: "Reference".into(),
            phantom: "Phantom".into(),
        }
    }
}

/// `Segmentation` attributes of a device set that size the dot segmentation.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PlusSegmentation {
    /// `MorphologicalOpeningCircleRadiusMm`.
    pub opening_radius_mm: Option<f64>,
    /// `ThresholdImagePercent`.
    pub threshold_percent: Option<f64>,
    /// `CollinearPointsMaxDistanceFromLineMm`.
    pub collinear_tolerance_mm: Option<f64>,
    /// `NumberOfMaximumFiducialPointCandidates`.
    pub max_candidates: Option<usize>,
    /// `MaxLinePairDistanceErrorPercent`.
    pub row_gap_tolerance_percent: Option<f64>,
    /// `MaxLineShiftMm`.
    pub max_row_shift_mm: Option<f64>,
    /// `AngleToleranceDegrees`.
    pub angle_tolerance_deg: Option<f64>,
    /// `MaxAngleDifferenceDegrees`: read and checked; PLUS's N-wire labeling does
    /// not use it (`AngleToleranceDegrees` decides which rows are parallel).
    pub max_angle_difference_deg: Option<f64>,
    /// `MinThetaDegrees`, `MaxThetaDegrees`.
    pub theta_range_deg: Option<(f64, f64)>,
    /// `MorphologicalOpeningBarSizeMm`: the bars whose openings are subtracted
    /// before the disk's (`detect::nwire::clean`).
    pub opening_bar_size_mm: Option<f64>,
    /// `UseOriginalImageIntensityForDotIntensityScore`.
    pub original_intensity_score: Option<bool>,
}

impl PlusConfig {
    pub fn read(path: &Path) -> Result<PlusConfig, ConfigError> {
        PlusConfig::parse(path, &read_text(path)?)
    }

    pub fn parse(path: &Path, text: &str) -> Result<PlusConfig, ConfigError> {
        let doc = parse_xml(path, text)?;
        let x = Xml { path, doc: &doc };

        let transforms = fixed_transforms(&x)?;

        let mut nwires = Vec::new();
        let mut wire_ids = Vec::new();
        for pattern in doc.descendants().filter(|n| n.has_tag_name("Pattern")) {
            let kind = x.attr(pattern, "Type")?;
            if kind != "NWire" {
                return Err(x.fail(
                    pattern,
                    format!("pattern type `{kind}`: only NWire patterns are supported"),
                ));
            }
            let wires: Vec<WireSegment> = pattern
                .children()
                .filter(|n| n.has_tag_name("Wire"))
                .map(|w| {
                    wire_ids.push(w.attribute("Id").or(w.attribute("Name")).unwrap_or("").to_string());
                    let front = x.numbers(w, "EndPointFront", 3)?;
                    let back = x.numbers(w, "EndPointBack", 3)?;
                    if let Some(why) = wire_end_fault(&front).or_else(|| wire_end_fault(&back)) {
                        return Err(x.fail(w, why));
                    }
                    Ok(WireSegment {
                        name: w.attribute("Name").unwrap_or("").to_string(),
                        front_in_phantom_mm: Point3::new(front[0], front[1], front[2]),
                        back_in_phantom_mm: Point3::new(back[0], back[1], back[2]),
                    })
                })
                .collect::<Result<_, ConfigError>>()?;
            let [w1, w2, w3]: [WireSegment; 3] = wires.try_into().map_err(|w: Vec<WireSegment>| {
                x.fail(pattern, format!("an N-wire needs 3 wires, this one has {}", w.len()))
            })?;
            let nwire = NWire::new([w1, w2, w3]).map_err(|e| x.fail(pattern, e.to_string()))?;
            nwires.push(nwire);
        }

        let mut approximate_spacing_mm_per_px = None;
        let mut clip_rectangle_px = None;
        let mut segmentation = PlusSegmentation::default();
        if let Some(seg) = doc
            .descendants()
            .find(|n| n.has_tag_name("Segmentation") && n.attribute("ApproximateSpacingMmPerPixel").is_some())
        {
            let s = x.numbers(seg, "ApproximateSpacingMmPerPixel", 1)?[0];
            if !(0.001..=10.0).contains(&s) {
                return Err(x.fail(
                    seg,
                    format!("`ApproximateSpacingMmPerPixel` must be 0.001 to 10 mm per pixel, got {s}"),
                ));
            }
            approximate_spacing_mm_per_px = Some(s);
            if seg.attribute("ClipRectangleOrigin").is_some() {
                let o = x.numbers(seg, "ClipRectangleOrigin", 2)?;
                let z = x.numbers(seg, "ClipRectangleSize", 2)?;
                if o.iter()
                    .chain(&z)
                    .any(|v| *v < 0.0 || *v > MAX_CLIP_PX || v.fract() != 0.0)
                    || z.iter().any(|v| *v < 1.0)
                {
                    return Err(x.fail(
                        seg,
                        format!(
                            "the clip rectangle {o:?} + {z:?} must be whole pixels from 0 to {MAX_CLIP_PX}, its size at least 1"
                        ),
                    ));
                }
                clip_rectangle_px = Some(([o[0] as usize, o[1] as usize], [z[0] as usize, z[1] as usize]));
            }
            segmentation = segmentation_settings(&x, seg)?;
        }
        let mut calibration_frames = CalibrationFrames::default();
        if let Some(algo) = doc
            .descendants()
            .find(|n| n.has_tag_name("vtkPlusProbeCalibrationAlgo"))
        {
            let frame = |name: &str, default: String| algo.attribute(name).map(str::to_string).unwrap_or(default);
            calibration_frames = CalibrationFrames {
                probe: frame("ProbeCoordinateFrame", calibration_frames.probe),
                reference: frame("ReferenceCoordinateFrame", calibration_frames.reference),
                phantom: frame("PhantomCoordinateFrame", calibration_frames.phantom),
            };
        }
        Ok(PlusConfig {
            path: path.to_path_buf(),
            transforms,
            nwires,
            approximate_spacing_mm_per_px,
            clip_rectangle_px,
            wire_ids,
            segmentation,
            calibration_frames,
        })
    }

    /// The fixed transform `to_T_from` that must be rigid (a phantom's
    /// registration): refused, naming its line, when it scales or mirrors.
    pub fn rigid_transform(&self, from: &str, to: &str) -> Result<Matrix4<f64>, ConfigError> {
        let m = self.transform(from, to)?;
        match rigid_fault(&m) {
            None => Ok(m),
            Some(why) => Err(ConfigError {
                path: self.path.clone(),
                line: self
                    .transforms
                    .iter()
                    .find(|t| (t.from == from && t.to == to) || (t.from == to && t.to == from))
                    .map(|t| t.line),
                message: format!("transform {from}To{to} is {why}; a phantom's registration must be rigid"),
            }),
        }
    }

    /// The fixed transform `to_T_from`, found directly or as the inverse of `from_T_to`.
    pub fn transform(&self, from: &str, to: &str) -> Result<Matrix4<f64>, ConfigError> {
        if let Some(t) = self.transforms.iter().find(|t| t.from == from && t.to == to) {
            return Ok(t.matrix);
        }
        if let Some(t) = self.transforms.iter().find(|t| t.from == to && t.to == from) {
            return t.matrix.try_inverse().ok_or_else(|| ConfigError {
                path: self.path.clone(),
                line: Some(t.line),
                message: format!("transform {to}To{from} is singular"),
            });
        }
        Err(ConfigError {
            path: self.path.clone(),
            line: None,
            message: format!("CoordinateDefinitions has no transform {from}To{to} (nor its inverse)"),
        })
    }
}

/// The `CoordinateDefinitions` transforms, each defined once and affine.
fn fixed_transforms(x: &Xml) -> Result<Vec<FixedTransform>, ConfigError> {
    let mut transforms = Vec::new();
    for node in x.doc.descendants().filter(|n| n.has_tag_name("CoordinateDefinitions")) {
        for t in node.children().filter(|n| n.has_tag_name("Transform")) {
            let m = x.numbers(t, "Matrix", 16)?;
            transforms.push(FixedTransform {
                from: x.attr(t, "From")?.to_string(),
                to: x.attr(t, "To")?.to_string(),
                matrix: Matrix4::from_fn(|r, c| m[r * 4 + c]),
                line: x.line(t),
            });
        }
    }
    super::xml_limits::check_transforms(x.path, &transforms)?;
    Ok(transforms)
}

/// The `Segmentation` element's settings of the dot segmentation, each a
/// positive number up to a physical ceiling where given (sizes in mm, counts
/// whole), the percentages and tolerances below their ranges' ends.
fn segmentation_settings(x: &Xml, seg: roxmltree::Node) -> Result<PlusSegmentation, ConfigError> {
    let positive = |name: &str, most: f64| -> Result<Option<f64>, ConfigError> {
        if seg.attribute(name).is_none() {
            return Ok(None);
        }
        let v = x.numbers(seg, name, 1)?[0];
        if !(v.is_finite() && v > 0.0 && v <= most) {
            return Err(x.fail(seg, format!("`{name}` must be a positive number up to {most}, got {v}")));
        }
        Ok(Some(v))
    };
    let count = |name: &str, most: f64| -> Result<Option<usize>, ConfigError> {
        match positive(name, most)? {
            Some(v) if v.fract() != 0.0 => Err(x.fail(seg, format!("`{name}` must be a whole number, got {v}"))),
            v => Ok(v.map(|n| n as usize)),
        }
    };
    let segmentation = PlusSegmentation {
        opening_radius_mm: positive("MorphologicalOpeningCircleRadiusMm", 10.0)?,
        threshold_percent: positive("ThresholdImagePercent", 100.0)?,
        collinear_tolerance_mm: positive("CollinearPointsMaxDistanceFromLineMm", 50.0)?,
        max_candidates: count(
            "NumberOfMaximumFiducialPointCandidates",
            crate::spec::nwire::MAX_DOT_CANDIDATES as f64,
        )?,
        row_gap_tolerance_percent: positive("MaxLinePairDistanceErrorPercent", 100.0)?,
        max_row_shift_mm: positive("MaxLineShiftMm", 500.0)?,
        angle_tolerance_deg: positive("AngleToleranceDegrees", 90.0)?,
        max_angle_difference_deg: positive("MaxAngleDifferenceDegrees", 90.0)?,
        theta_range_deg: theta_range(x, seg)?,
        opening_bar_size_mm: positive("MorphologicalOpeningBarSizeMm", 50.0)?,
        original_intensity_score: match seg.attribute("UseOriginalImageIntensityForDotIntensityScore") {
            None => None,
            Some(v) if v.eq_ignore_ascii_case("true") || v == "1" => Some(true),
            Some(v) if v.eq_ignore_ascii_case("false") || v == "0" => Some(false),
            Some(v) => {
                return Err(x.fail(
                    seg,
                    format!("`UseOriginalImageIntensityForDotIntensityScore` must be TRUE or FALSE, got `{v}`"),
                ))
            }
        },
    };
    for (name, value, most) in [
        ("ThresholdImagePercent", segmentation.threshold_percent, 100.0),
        (
            "MaxLinePairDistanceErrorPercent",
            segmentation.row_gap_tolerance_percent,
            100.0,
        ),
        ("AngleToleranceDegrees", segmentation.angle_tolerance_deg, 90.0),
        ("MaxAngleDifferenceDegrees", segmentation.max_angle_difference_deg, 90.0),
    ] {
        if value.is_some_and(|v| v >= most) {
            return Err(x.fail(
                seg,
                format!("`{name}` must be below {most}, got {}", value.unwrap_or(0.0)),
            ));
        }
    }
    Ok(segmentation)
}

/// `MinThetaDegrees` and `MaxThetaDegrees`, both or neither, each within ±90°
/// and the first below the second.
fn theta_range(x: &Xml, seg: roxmltree::Node) -> Result<Option<(f64, f64)>, ConfigError> {
    match (seg.attribute("MinThetaDegrees"), seg.attribute("MaxThetaDegrees")) {
        (None, None) => Ok(None),
        (Some(_), Some(_)) => {
            let lo = x.numbers(seg, "MinThetaDegrees", 1)?[0];
            let hi = x.numbers(seg, "MaxThetaDegrees", 1)?[0];
            if !(-90.0..=90.0).contains(&lo) || !(-90.0..=90.0).contains(&hi) || lo >= hi {
                return Err(x.fail(
                    seg,
                    format!("`MinThetaDegrees` {lo} and `MaxThetaDegrees` {hi} must lie within ±90 with the first below the second"),
                ));
            }
            Ok(Some((lo, hi)))
        }
        _ => Err(x.fail(
            seg,
            "give both `MinThetaDegrees` and `MaxThetaDegrees`, or neither".into(),
        )),
    }
}

/// A PLUS XML file's text, an error naming the file when it cannot be read.
pub(crate) fn read_text(path: &Path) -> Result<String, ConfigError> {
    let fail = |message: String| ConfigError {
        path: path.to_path_buf(),
        line: None,
        message,
    };
    let size = std::fs::metadata(path)
        .map_err(|e| fail(format!("cannot read: {e}")))?
        .len();
    if size > super::xml_limits::MAX_XML_BYTES {
        return Err(fail(format!(
            "{size} bytes: larger than any PLUS XML file probecal reads ({} bytes)",
            super::xml_limits::MAX_XML_BYTES
        )));
    }
    crate::io::fs::read_text_capped(path, super::xml_limits::MAX_XML_BYTES)
        .map_err(|e| fail(format!("cannot read: {e}")))
}

/// Parses XML, a syntax error naming the file and line.
pub(crate) fn parse_xml<'input>(path: &Path, text: &'input str) -> Result<roxmltree::Document<'input>, ConfigError> {
    super::xml_limits::check_size_and_depth(path, text)?;
    roxmltree::Document::parse(text).map_err(|e| ConfigError {
        path: path.to_path_buf(),
        line: Some(e.pos().row as usize),
        message: format!("not well-formed XML: {e}"),
    })
}

/// Attribute access with errors that name the file and the element's line.
pub(crate) struct Xml<'a, 'input> {
    pub(crate) path: &'a Path,
    pub(crate) doc: &'a roxmltree::Document<'input>,
}

impl Xml<'_, '_> {
    pub(crate) fn line(&self, node: roxmltree::Node) -> usize {
        self.doc.text_pos_at(node.range().start).row as usize
    }

    pub(crate) fn fail(&self, node: roxmltree::Node, message: String) -> ConfigError {
        ConfigError {
            path: self.path.to_path_buf(),
            line: Some(self.line(node)),
            message,
        }
    }

    pub(crate) fn attr<'n>(&self, node: roxmltree::Node<'n, '_>, name: &str) -> Result<&'n str, ConfigError> {
        node.attribute(name)
            .ok_or_else(|| self.fail(node, format!("<{}> has no attribute `{name}`", node.tag_name().name())))
    }

    pub(crate) fn numbers(&self, node: roxmltree::Node, name: &str, count: usize) -> Result<Vec<f64>, ConfigError> {
        let text = self.attr(node, name)?;
        let values: Vec<f64> = text
            .split_whitespace()
            .map(|s| s.parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| self.fail(node, format!("`{name}` holds a non-number")))?;
        if values.len() != count || values.iter().any(|v| !v.is_finite()) {
            return Err(self.fail(
                node,
                format!("`{name}` must hold {count} finite numbers, has {}", values.len()),
            ));
        }
        Ok(values)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn errors_name_the_line() {
        let text = "<PlusConfiguration>\n<CoordinateDefinitions>\n<Transform From=\"A\" To=\"B\" Matrix=\"1 0 0\"/>\n</CoordinateDefinitions>\n</PlusConfiguration>";
        let e = PlusConfig::parse(Path::new("c.xml"), text).unwrap_err();
        assert_eq!(e.to_string(), "c.xml:3: `Matrix` must hold 16 finite numbers, has 3");
        let e = PlusConfig::parse(Path::new("c.xml"), "<a>\n<b></a>").unwrap_err();
        assert!(e.to_string().starts_with("c.xml:2: not well-formed XML"), "{e}");
    }
}
