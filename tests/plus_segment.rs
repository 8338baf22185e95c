//! `probecal segment` on another scanner and phantom than fCal 2.0 (PLUS's VLC
//! segmentation test: a screen-grabbed Carolina Medical scanner over the iCal
//! phantom, two N's), with PLUS's settings from its device set and nothing tuned
//! here, against PLUS's own segmentation of every frame.

mod common;

use std::collections::BTreeMap;
use std::path::Path;

use common::{probecal, scratch, shared_data};

const SET: &str = "plus-segmentation-vlcus";

/// PLUS's baseline: frame → (segmented, points in wire order).
fn plus_baseline() -> BTreeMap<usize, (bool, Vec<[f64; 2]>)> {
    let text = std::fs::read_to_string(shared_data(
        SET,
        "SegmentationTest_VLCUS_RandomStepperMotionData2_Segmentation_baseline.xml",
    ))
    .unwrap();
    let doc = roxmltree::Document::parse(&text).unwrap();
    let mut out = BTreeMap::new();
    for case in doc.descendants().filter(|n| n.has_tag_name("TestCase")) {
        let input = case.children().find(|n| n.has_tag_name("Input")).unwrap();
        let output = case.children().find(|n| n.has_tag_name("Output")).unwrap();
        let frame: usize = input.attribute("ImageSeqFrameIndex").unwrap().parse().unwrap();
        let found = output.attribute("SegmentationSuccess") == Some("1");
        let numbers: Vec<f64> = output
            .attribute("SegmentationPoints")
            .unwrap_or("")
            .split_whitespace()
            .map(|v| v.parse().unwrap())
            .collect();
        out.insert(frame, (found, numbers.chunks(2).map(|p| [p[0], p[1]]).collect()));
    }
    out
}

/// Our `segmentation.csv`: frame → wire id → point.
fn ours(csv: &str) -> BTreeMap<usize, BTreeMap<String, [f64; 2]>> {
    let mut out: BTreeMap<usize, BTreeMap<String, [f64; 2]>> = BTreeMap::new();
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some("frame,found,wire,x_px,y_px"));
    for line in lines {
        let f: Vec<&str> = line.split(',').collect();
        let entry = out.entry(f[0].parse().unwrap()).or_default();
        if f[1] == "1" {
            entry.insert(f[2].to_string(), [f[3].parse().unwrap(), f[4].parse().unwrap()]);
        }
    }
    out
}

const DEVICE_SET: &str = "PlusDeviceSet_iCal_CalibrationOnly_VLCUS_FrameGrabber.xml";

/// `probecal segment` of the VLC sequence with `config`, into `out`.
fn segment(config: &Path, out: &Path) -> std::process::Output {
    probecal()
        .arg("segment")
        .arg(shared_data(
            SET,
            "SegmentationTest_VLCUS_RandomStepperMotionData2.igs.mha",
        ))
        .arg("--config")
        .arg(config)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap()
}

/// A copy of the VLC device set, as `path`, with each of `attributes` removed.
fn device_set_without(path: &Path, attributes: &[&str]) {
    let mut text = std::fs::read_to_string(shared_data(SET, DEVICE_SET)).unwrap();
    for attribute in attributes {
        assert!(text.contains(attribute), "`{attribute}` is not in the device set");
        text = text.replace(attribute, "");
    }
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(path, text).unwrap();
}

/// Segments the VLC sequence with `config` into `out` and compares with PLUS's
/// segmentation of every frame; the summary.
fn segment_and_compare(config: &Path, out: &Path, name: &str) -> serde_json::Value {
    let r = segment(config, out);
    assert!(r.status.success(), "{name}: {}", String::from_utf8_lossy(&r.stderr));
    let ours = ours(&std::fs::read_to_string(out.join("segmentation.csv")).unwrap());
    assert_eq!(ours.len(), 201, "{name}: every frame has a row");
    let plus = plus_baseline();
    let plus_found: Vec<usize> = plus.iter().filter(|(_, (ok, _))| *ok).map(|(f, _)| *f).collect();
    assert_eq!(plus_found.len(), 196);
    let mut distances = Vec::new();
    let mut found = 0;
    for f in &plus_found {
        let points = &ours[f];
        if points.is_empty() {
            continue;
        }
        found += 1;
        for (k, p) in plus[f].1.iter().enumerate() {
            let q = points[&(k + 1).to_string()];
            distances.push(((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt());
        }
    }
    let mean = distances.iter().sum::<f64>() / distances.len() as f64;
    let worst = distances.iter().copied().fold(0.0, f64::max);
    println!("{name}: {found} of 196 frames PLUS segmented are found; mean distance {mean:.3} px, worst {worst:.2} px");
    // The image cleaned as PLUS cleans it (bars, then the disk): every frame PLUS
    // segmented, no other, and no dot on a line PLUS's bars remove (the disk
    // alone found 195 of them, 3 others, and one dot 11 px from PLUS's).
    assert_eq!(found, 196, "{name}: {found} of 196");
    let extra: Vec<&usize> = ours
        .iter()
        .filter(|(f, p)| !p.is_empty() && !plus.get(f).is_some_and(|b| b.0))
        .map(|(f, _)| f)
        .collect();
    assert!(extra.is_empty(), "{name}: frames PLUS did not segment: {extra:?}");
    assert!(mean <= 0.6, "{name}: mean distance to PLUS's points {mean} px");
    assert!(worst <= 3.0, "{name}: a dot {worst} px from PLUS's");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["frames"], 201);
    for miss in summary["not_found"].as_array().unwrap() {
        assert!(
            miss["reason"].as_str().unwrap().starts_with("segmentation: "),
            "{name}: {miss}"
        );
    }
    summary
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn segments_another_scanner_and_phantom_as_plus_does() {
    let config = shared_data(SET, DEVICE_SET);
    // Without the device set's clip rectangle, the screen grab's text, rulers
    // and depth markers are found from the recording itself.
    let unclipped = scratch("plus_segment", "vlc_unclipped_config").join("device_set.xml");
    device_set_without(
        &unclipped,
        &["ClipRectangleOrigin=\"68 145\"", "ClipRectangleSize=\"390 300\""],
    );
    let text = std::fs::read_to_string(&unclipped).unwrap();
    assert_eq!(text.matches("ClipRectangle").count(), 0, "the clip was not removed");
    let unclipped_out = scratch("plus_segment", "vlc_unclipped");
    let summary = segment_and_compare(&unclipped, &unclipped_out, "without the clip rectangle");
    assert!(
        summary["overlay"]["pixels"].as_u64().unwrap() > 0,
        "{}",
        summary["overlay"]
    );
    let out = scratch("plus_segment", "vlc");
    let summary = segment_and_compare(&config, &out, "with the device set's clip rectangle");
    assert!(
        summary["overlay"].is_null(),
        "a clip rectangle given, no overlay is searched"
    );
    let page = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(page.contains("id=\"not-found\""));
    // The gallery: every frame drawn, the failed ones first with their reason.
    for frame in 0..201 {
        let picture = out.join(format!("gallery/frame_{frame:04}.jpg"));
        assert!(
            std::fs::metadata(&picture).unwrap().len() > 1000,
            "{}",
            picture.display()
        );
    }
    // The page is escaped by its template (`/` as `&#x2F;`, which a browser reads as `/`).
    let page = page.replace("&#x2F;", "/");
    let first_figure = page.find("<figure>").unwrap();
    let first_miss = summary["not_found"][0]["frame"].as_u64().unwrap();
    assert!(
        page[first_figure..].starts_with(&format!("<figure><img src=\"gallery/frame_{first_miss:04}.jpg\"")),
        "a failed frame leads the gallery"
    );
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn a_device_set_without_a_pixel_size_is_a_clear_error() {
    let dir = scratch("plus_segment", "no_spacing");
    let config = dir.join("no_spacing.xml");
    device_set_without(&config, &["ApproximateSpacingMmPerPixel=\"0.21\""]);
    let r = segment(&config, &dir.join("out"));
    assert_eq!(r.status.code(), Some(1));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        err.contains("no_spacing.xml") && err.contains("ApproximateSpacingMmPerPixel"),
        "{err}"
    );
    assert!(!dir.join("out").exists(), "nothing written on an error");
}
