//! PLUS's per-frame segmentation results, read to score probecal's against:
//! a segmentation test baseline (`TestResults/TestCase`, one per frame:
//! `Input/@ImageSeqFrameIndex`, `Output/@SegmentationSuccess` and
//! `@SegmentationPoints`) or a calibration result (`ProbeCalibrationResult`:
//! `CalibrationData` and `ValidationData`, each `Frame` with its
//! `@SegmentationStatus` and `SegmentedPoints`).

use std::collections::BTreeMap;
use std::path::Path;

use super::config::{parse_xml, read_text, ConfigError, Xml};

/// One sequence's frames as PLUS segmented them: frame index → its points in
/// wire order (px), or `None` where PLUS's segmentation failed.
pub type FrameResults = BTreeMap<usize, Option<Vec<[f64; 2]>>>;

/// The sequences a file holds, by name (`frames` for a test baseline;
/// `calibration` and `validation` for a calibration result).
#[derive(Debug, Clone, PartialEq)]
pub struct PlusSegmentation {
    pub sections: Vec<(String, FrameResults)>,
}

/// Most frames one section may list.
const MAX_FRAMES: usize = 1_000_000;

impl PlusSegmentation {
    pub fn read(path: &Path) -> Result<PlusSegmentation, ConfigError> {
        let text = read_text(path)?;
        let doc = parse_xml(path, &text)?;
        PlusSegmentation::of_document(&Xml { path, doc: &doc })
    }

    /// The sections of a parsed file.
    pub(crate) fn of_document(x: &Xml) -> Result<PlusSegmentation, ConfigError> {
        let root = x.doc.root_element();
        let sections = match root.tag_name().name() {
            "TestResults" => vec![("frames".to_string(), test_cases(x, root)?)],
            "ProbeCalibrationResult" => {
                let mut out = Vec::new();
                for (tag, name) in [("CalibrationData", "calibration"), ("ValidationData", "validation")] {
                    if let Some(node) = root.descendants().find(|n| n.has_tag_name(tag)) {
                        out.push((name.to_string(), calibration_frames(x, node)?));
                    }
                }
                out
            }
            other => {
                return Err(x.fail(
                    root,
                    format!("<{other}>: expected PLUS's <TestResults> or <ProbeCalibrationResult>"),
                ))
            }
        };
        Ok(PlusSegmentation { sections })
    }

    /// The section of `name`.
    pub fn section(&self, name: &str) -> Option<&FrameResults> {
        self.sections.iter().find(|(n, _)| n == name).map(|(_, f)| f)
    }
}

fn insert(
    x: &Xml,
    node: roxmltree::Node,
    out: &mut FrameResults,
    frame: usize,
    points: Option<Vec<[f64; 2]>>,
) -> Result<(), ConfigError> {
    if out.len() >= MAX_FRAMES {
        return Err(x.fail(node, format!("more than {MAX_FRAMES} frames")));
    }
    if out.insert(frame, points).is_some() {
        return Err(x.fail(node, format!("frame {frame} is listed twice")));
    }
    Ok(())
}

fn frame_index(x: &Xml, node: roxmltree::Node, name: &str) -> Result<usize, ConfigError> {
    let text = x.attr(node, name)?;
    text.trim()
        .parse()
        .map_err(|_| x.fail(node, format!("`{name}` must be a frame index, got `{text}`")))
}

/// Pairs of finite numbers from `text` (every third dropped when `stride` is 3).
fn points(x: &Xml, node: roxmltree::Node, text: &str, stride: usize) -> Result<Vec<[f64; 2]>, ConfigError> {
    let values: Vec<f64> = text
        .split_whitespace()
        .map(|v| v.parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| x.fail(node, "a point holds a non-number".into()))?;
    if !values.len().is_multiple_of(stride) || values.iter().any(|v| !v.is_finite()) {
        return Err(x.fail(node, format!("points must be {stride} finite numbers each")));
    }
    Ok(values.chunks(stride).map(|p| [p[0], p[1]]).collect())
}

fn test_cases(x: &Xml, root: roxmltree::Node) -> Result<FrameResults, ConfigError> {
    let mut out = FrameResults::new();
    for case in root.children().filter(|n| n.has_tag_name("TestCase")) {
        let (Some(input), Some(output)) = (
            case.children().find(|n| n.has_tag_name("Input")),
            case.children().find(|n| n.has_tag_name("Output")),
        ) else {
            return Err(x.fail(case, "a <TestCase> needs <Input> and <Output>".into()));
        };
        let frame = frame_index(x, input, "ImageSeqFrameIndex")?;
        let found = output.attribute("SegmentationSuccess") == Some("1");
        let pts = if found {
            Some(points(
                x,
                output,
                output.attribute("SegmentationPoints").unwrap_or(""),
                2,
            )?)
        } else {
            None
        };
        insert(x, case, &mut out, frame, pts)?;
    }
    Ok(out)
}

fn calibration_frames(x: &Xml, section: roxmltree::Node) -> Result<FrameResults, ConfigError> {
    let mut out = FrameResults::new();
    for frame in section.children().filter(|n| n.has_tag_name("Frame")) {
        let index = frame_index(x, frame, "Index")?;
        let pts = if frame.attribute("SegmentationStatus") == Some("OK") {
            let list = frame.children().find(|n| n.has_tag_name("SegmentedPoints"));
            let mut p = Vec::new();
            for point in list
                .iter()
                .flat_map(|l| l.children().filter(|n| n.has_tag_name("Point")))
            {
                p.extend(points(x, point, x.attr(point, "Position")?, 3)?);
            }
            Some(p)
        } else {
            None
        };
        insert(x, frame, &mut out, index, pts)?;
    }
    Ok(out)
}

/// How probecal's segmentation of a sequence compares with PLUS's.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SegmentationScore {
    /// Frames PLUS segmented, and how many of them probecal segmented too.
    pub plus_frames: usize,
    pub both_frames: usize,
    /// `both_frames / plus_frames`.
    pub recall: f64,
    /// Frames probecal segmented that PLUS did not (or did not list).
    pub extra_frames: Vec<usize>,
    /// Frames PLUS segmented that probecal did not.
    pub missed_frames: Vec<usize>,
    /// Distance between each of probecal's points and PLUS's point of the same
    /// wire, over the frames both segmented (px).
    pub point_distance_px: Option<crate::core::stats::MeanSd>,
    pub point_distance_max_px: Option<f64>,
    /// Frames both segmented whose point counts differ (not compared).
    pub count_mismatch_frames: Vec<usize>,
}

/// Scores `ours` (frame index → points in wire order, `None`: not segmented)
/// against `plus`.
pub fn score(ours: &BTreeMap<usize, Option<Vec<[f64; 2]>>>, plus: &FrameResults) -> SegmentationScore {
    let plus_found: Vec<usize> = plus.iter().filter(|(_, p)| p.is_some()).map(|(f, _)| *f).collect();
    let mut distances = Vec::new();
    let (mut both, mut missed, mut mismatch) = (0, Vec::new(), Vec::new());
    for f in &plus_found {
        match ours.get(f) {
            Some(Some(mine)) => {
                both += 1;
                let theirs = plus[f].as_deref().unwrap_or(&[]);
                if theirs.len() != mine.len() {
                    mismatch.push(*f);
                    continue;
                }
                distances.extend(
                    mine.iter()
                        .zip(theirs)
                        .map(|(a, b)| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()),
                );
            }
            _ => missed.push(*f),
        }
    }
    let extra_frames = ours
        .iter()
        .filter(|(f, p)| p.is_some() && !matches!(plus.get(f), Some(Some(_))))
        .map(|(f, _)| *f)
        .collect();
    SegmentationScore {
        plus_frames: plus_found.len(),
        both_frames: both,
        recall: if plus_found.is_empty() {
            f64::NAN
        } else {
            both as f64 / plus_found.len() as f64
        },
        extra_frames,
        missed_frames: missed,
        point_distance_px: crate::core::stats::mean_sd_of(&distances),
        point_distance_max_px: distances.iter().copied().reduce(f64::max),
        count_mismatch_frames: mismatch,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_both_kinds_and_scores_by_frame_and_wire() {
        let test = "<TestResults>\n<TestCase><Input ImageSeqFrameIndex=\"0\"/><Output SegmentationSuccess=\"1\" SegmentationPoints=\"1 2 3 4\"/></TestCase>\n<TestCase><Input ImageSeqFrameIndex=\"1\"/><Output SegmentationSuccess=\"0\"/></TestCase>\n</TestResults>";
        let dir = std::env::temp_dir().join(format!("probecal-plusseg-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("b.xml");
        std::fs::write(&path, test).unwrap();
        let b = PlusSegmentation::read(&path).unwrap();
        let frames = b.section("frames").unwrap();
        assert_eq!(frames[&0], Some(vec![[1.0, 2.0], [3.0, 4.0]]));
        assert_eq!(frames[&1], None);
        let ours = BTreeMap::from([(0, Some(vec![[1.0, 2.0], [3.0, 8.0]])), (1, Some(vec![[0.0, 0.0]]))]);
        let s = score(&ours, frames);
        assert_eq!((s.plus_frames, s.both_frames, s.extra_frames.clone()), (1, 1, vec![1]));
        assert_eq!(s.point_distance_max_px, Some(4.0));
        let result = "<ProbeCalibrationResult><ValidationData>\n<Frame Index=\"3\" SegmentationStatus=\"OK\"><SegmentedPoints><Point Position=\"5 6 0\"/></SegmentedPoints></Frame>\n<Frame Index=\"3\" SegmentationStatus=\"Failed\"/>\n</ValidationData></ProbeCalibrationResult>";
        std::fs::write(&path, result).unwrap();
        let e = PlusSegmentation::read(&path).unwrap_err();
        assert!(e.to_string().ends_with(":3: frame 3 is listed twice"), "{e}");
    }
}
