//! `probecal temporal` on PLUS's water-tank recording against PLUS's own result
//! (its `TrackerLagSec` and the line it found in each B-scan), within PLUS's own
//! test tolerances.

mod common;

use common::{probecal, scratch, shared_data};

const SET: &str = "plus-temporal-watertank";
const VIDEO: &str = "WaterTankBottomTranslationVideoBuffer.igs.mha";
const TRACKER: &str = "WaterTankBottomTranslationTrackerBuffer.igs.mha";

/// PLUS's line per frame: (origin, direction).
fn plus_lines() -> Vec<([f64; 2], [f64; 2])> {
    let text = std::fs::read_to_string(shared_data(SET, "LineSegmentationResultsBaseline.xml")).unwrap();
    let doc = roxmltree::Document::parse(&text).unwrap();
    let pair = |s: &str| {
        let v: Vec<f64> = s.split_whitespace().map(|x| x.parse().unwrap()).collect();
        [v[0], v[1]]
    };
    doc.descendants()
        .filter(|n| n.has_tag_name("Frame"))
        .map(|f| {
            (
                pair(f.attribute("LineOriginPointPx").unwrap()),
                pair(f.attribute("LineDirectionVectorPx").unwrap()),
            )
        })
        .collect()
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn tracker_lag_and_lines_agree_with_plus() {
    let out = scratch("plus_temporal", "watertank");
    let r = probecal()
        .arg("temporal")
        .arg("--tracker")
        .arg(shared_data(SET, TRACKER))
        .arg("--video")
        .arg(shared_data(SET, VIDEO))
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let text = std::fs::read_to_string(out.join("summary.json")).unwrap();
    // The typed model holds every field written: read back, it writes the same values.
    let typed: probecal::results::temporal::TemporalSummary = serde_json::from_str(&text).unwrap();
    let summary: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(serde_json::to_value(&typed).unwrap(), summary);
    let lag = summary["tracker_lag_s"].as_f64().unwrap();
    println!("tracker lag {lag:.4} s (PLUS: -0.0648266 s)");
    assert!((lag - -0.0648266).abs() <= 0.005, "{lag}");

    let plus = plus_lines();
    assert_eq!(plus.len(), 201);
    let csv = std::fs::read_to_string(out.join("lines.csv")).unwrap();
    let mut close = 0;
    for line in csv.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        if f[2] != "1" {
            continue;
        }
        let frame: usize = f[0].parse().unwrap();
        let num = |k: usize| f[k].parse::<f64>().unwrap();
        let (origin, d) = ([num(3), num(4)], [num(5), num(6)]);
        let (po, pd) = plus[frame];
        let distance = ((po[0] - origin[0]) * d[1] - (po[1] - origin[1]) * d[0]).abs();
        let angle = (d[0] * pd[0] + d[1] * pd[1]).abs().min(1.0).acos().to_degrees();
        if distance <= 10.0 && angle <= 3.0 {
            close += 1;
        }
    }
    println!("{close} of 201 lines within 10 px and 3 degrees of PLUS's");
    assert!(close as f64 >= 0.95 * 201.0, "{close}");
    assert!(std::fs::read_to_string(out.join("report.html"))
        .unwrap()
        .contains("<polyline"));
}

#[test]
#[ignore = "needs ../shared/data (full tier: scripts/test.sh)"]
fn a_video_without_timestamps_is_a_clear_error() {
    let dir = scratch("plus_temporal", "no_timestamps");
    std::fs::create_dir_all(&dir).unwrap();
    let bytes = std::fs::read(shared_data(SET, VIDEO)).unwrap();
    let marker = b"ElementDataFile = LOCAL\n";
    let at = bytes.windows(marker.len()).position(|w| w == marker).unwrap();
    let header = String::from_utf8(bytes[..at].to_vec()).unwrap();
    let edited: String = header
        .lines()
        .filter(|l| !l.starts_with("Seq_Frame0004_Timestamp"))
        .map(|l| format!("{l}\n"))
        .collect();
    let video = dir.join("no_timestamp.igs.mha");
    std::fs::write(&video, [edited.as_bytes(), &bytes[at..]].concat()).unwrap();
    let r = probecal()
        .arg("temporal")
        .arg("--tracker")
        .arg(shared_data(SET, TRACKER))
        .arg("--video")
        .arg(&video)
        .arg("--out")
        .arg(dir.join("out"))
        .output()
        .unwrap();
    assert_eq!(r.status.code(), Some(1));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        err.contains("no_timestamp.igs.mha") && err.contains("frame 4") && err.contains("Timestamp"),
        "{err}"
    );
    assert!(!dir.join("out").exists());
}
