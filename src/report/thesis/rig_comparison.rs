//! The thesis's future work asks for a better marker rig: the three rigs
//! (checkerboard, ArUco grid, ChArUco) on the same rendered sweep side by
//! side, clear and with the boards partly hidden by the hand, the cable and
//! the tank rim, as a table of the regenerated chapter.

use std::path::Path;

use crate::report::thesis::chapter_table::{fmt, summary, Row, Table};
use crate::results::summary::Summary;

/// The rigs' experiments: (rig, clear, occluded), all on `dataset3`.
pub const RIG_EXPERIMENTS: [(&str, &str, &str); 3] = [
    (
        "checkerboard",
        "hemisphere_checkerboard",
        "hemisphere_checkerboard_occluded",
    ),
    ("ArUco", "hemisphere_aruco", "hemisphere_aruco_occluded"),
    ("ChArUco", "hemisphere_charuco", "hemisphere_charuco_occluded"),
];
const DATASET: &str = "dataset3";

type Cell = fn(&Summary) -> String;

const ROWS: [(&str, Cell); 8] = [
    ("frames kept / total", |s| {
        format!("{} / {}", s.frames.used, s.frames.total)
    }),
    ("BRE mean x, all frames kept (mm)", |s| bre_mean(s, 0)),
    ("BRE mean y, all frames kept (mm)", |s| bre_mean(s, 1)),
    ("BRE mean z, all frames kept (mm)", |s| bre_mean(s, 2)),
    ("truth: image corners mean (mm)", |s| {
        fmt(s.truth.as_ref().map(|t| t.corner_error_mm.mean))
    }),
    ("truth: image corners max (mm)", |s| {
        fmt(s.truth.as_ref().map(|t| t.corner_error_mm.max))
    }),
    ("truth: rotation (°)", |s| {
        fmt(s.truth.as_ref().map(|t| t.rotation_error_deg))
    }),
    ("truth: probe board pose, mean (mm)", |s| {
        fmt(s.truth.as_ref().and_then(|t| t.probe_pose_error_mm.map(|e| e.mean)))
    }),
];

/// The occluded experiments' stated rates, in words, from their summaries.
fn occluder_rates(runs: &[Summary]) -> String {
    let all: Vec<Option<[f64; 3]>> = [1, 3, 5]
        .iter()
        .map(|&k| {
            runs[k]
                .occluders
                .as_ref()
                .map(|o| [o.hand_rate, o.cable_rate, o.rim_rate])
        })
        .collect();
    match all[0] {
        Some(r) if all.iter().all(|a| *a == Some(r)) => format!(
            "two fingers over the probe board in {:.0} % of the photos, the probe cable across it in {:.0} %, \
             the tank rim over the phantom board's lower rows in {:.0} %",
            100.0 * r[0],
            100.0 * r[1],
            100.0 * r[2]
        ),
        _ => "the occluders their manifests state (the rigs' rates differ or are not written)".into(),
    }
}

fn bre_mean(s: &Summary, axis: usize) -> String {
    fmt(s
        .thresholds
        .first()
        .and_then(|r| r.bre_mm.as_ref())
        .map(|b| b.axes()[axis].mean))
}

/// The table, or the runs it needs that are not under `root`.
pub fn rigs_table(root: &Path) -> Result<Table, Vec<String>> {
    let mut runs = Vec::new();
    let mut missing = Vec::new();
    for (_, clear, occluded) in RIG_EXPERIMENTS {
        for experiment in [clear, occluded] {
            match summary(root, experiment, DATASET) {
                Some(s) => runs.push(s),
                None => missing.push(format!("{experiment}/{DATASET}")),
            }
        }
    }
    if !missing.is_empty() {
        return Err(missing);
    }
    let rows = ROWS
        .iter()
        .map(|(label, cell)| Row {
            label: label.to_string(),
            cells: runs.iter().map(cell).collect(),
        })
        .collect();
    let kept = |k: usize| {
        let s = &runs[k];
        100.0 * s.frames.used as f64 / s.frames.total.max(1) as f64
    };
    Ok(Table {
        id: "rigs".into(),
        title: "Marker rigs side by side: checkerboard, ArUco grid, ChArUco".into(),
        note: format!(
            "probecal's own table (the thesis's future work asks for a better rig). The same rendered lab, seed, \
             sweep and B-scans for every column; the rigs' boards cover about the same area (143-144 mm). \
             Occluded: the same frames with {} (stated rates; shapes in docs/manifest.md). Occlusion keeps \
             {:.0} % of the checkerboard rig's frames, {:.0} % of the ArUco rig's and {:.0} % of the ChArUco \
             rig's. One seed each; the rigs over ten seeds, paired, are in docs/results/rigs.md. probecal: {}.",
            occluder_rates(&runs),
            kept(1),
            kept(3),
            kept(5),
            RIG_EXPERIMENTS
                .iter()
                .flat_map(|(_, a, b)| [*a, *b])
                .collect::<Vec<_>>()
                .join(", ")
        ),
        groups: RIG_EXPERIMENTS.iter().map(|(rig, _, _)| rig.to_string()).collect(),
        sub: vec!["clear".into(), "occluded".into()],
        blocks: vec![(String::new(), rows)],
        spans: Vec::new(),
        thesis_columns: false,
    }
    .with_spans())
}
