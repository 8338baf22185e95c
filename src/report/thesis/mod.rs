//! The thesis's results chapter, regenerated: its tables with the same rows and
//! columns, probecal's numbers from the default experiments' runs beside the
//! thesis's published ones, as `thesis.html` and `thesis.tex`.
//!
//! The runs are read back from their `summary.json` (the results model as
//! written), so the chapter can be laid out again from any output folder.

pub mod chapter_table;
pub mod compare;
pub mod phantom;
pub mod rig_comparison;
use std::path::Path;

use serde::Serialize;

use crate::evaluate::{AxisStats, STAT_ROWS};
use crate::report::thesis::chapter_table::{fmt, summary, Row, Table};
use crate::results::summary::{BreSummary, Summary};

/// One of the thesis's three-axis tables (Std./Mean/Min/Max × x, y, z).
struct AxisTable {
    title: &'static str,
    experiment: &'static str,
    dataset: &'static str,
    /// Rows Std., Mean, Min, Max; columns x, y, z.
    thesis: [[f64; 3]; 4],
    note: &'static str,
    /// Also say how many frames each cut-off kept (and the thesis's Dataset 3).
    show_kept: bool,
}

const ROWS: [&str; 4] = ["Std.", "Mean", "Min", "Max"];

const AXIS_TABLES: [AxisTable; 7] = [
    AxisTable {
        title: "BRE along axes for Dataset 1",
        experiment: "hemisphere_checkerboard_dataset1",
        dataset: "dataset1",
        thesis: AXIS_TABLES_THESIS[0],
        note: "Two boards of different sizes; all frames.",
        show_kept: false,
    },
    AxisTable {
        title: "BRE along axes for Dataset 2",
        experiment: "hemisphere_checkerboard_dataset2",
        dataset: "dataset2",
        thesis: AXIS_TABLES_THESIS[1],
        note: "8x8 squares of 16 mm, 20 frames; all frames.",
        show_kept: false,
    },
    AxisTable {
        title: "BRE along axes for Dataset ArUco",
        experiment: "hemisphere_aruco",
        dataset: "dataset3",
        thesis: AXIS_TABLES_THESIS[2],
        note: "ArUco boards; all frames.",
        show_kept: false,
    },
    AxisTable {
        title: "Twin of the thesis's rig: BRE along axes for Dataset 1",
        experiment: "thesis_twin_dataset1",
        dataset: "dataset1",
        thesis: AXIS_TABLES_THESIS[0],
        note: "The rendered lab with the real rig's error sources at physical values; all frames.",
        show_kept: false,
    },
    AxisTable {
        title: "Twin of the thesis's rig: BRE along axes for Dataset 2",
        experiment: "thesis_twin_dataset2",
        dataset: "dataset2",
        thesis: AXIS_TABLES_THESIS[1],
        note: "The rendered lab with the real rig's error sources at physical values; all frames.",
        show_kept: false,
    },
    AxisTable {
        title: "Twin of the thesis's rig: BRE along axes for Dataset 3 (all frames)",
        experiment: "thesis_twin_dataset3",
        dataset: "dataset3",
        thesis: [
            [0.959, 1.758, 0.444],
            [1.024, 1.704, 0.542],
            [0.005, 0.034, 0.016],
            [4.443, 6.743, 1.635],
        ],
        note: "The rendered lab with the real rig's error sources at physical values; all frames.",
        show_kept: true,
    },
    AxisTable {
        title: "Twin of the thesis's rig: BRE along axes for Dataset ArUco",
        experiment: "thesis_twin_aruco",
        dataset: "dataset3",
        thesis: AXIS_TABLES_THESIS[2],
        note: "The rendered lab with the real rig's error sources at physical values; all frames.",
        show_kept: false,
    },
];

/// The thesis's Dataset 1, Dataset 2 and ArUco tables (rows Std., Mean, Min, Max).
const AXIS_TABLES_THESIS: [[[f64; 3]; 4]; 3] = [
    [
        [16.7091, 3.5429, 12.2821],
        [17.9636, 5.1218, 20.3735],
        [0.0592, 0.2596, 0.6292],
        [54.8793, 11.7972, 46.9600],
    ],
    [
        [1.1225, 0.8118, 0.6235],
        [1.754, 0.926, 1.127],
        [0.276, 0.074, 0.011],
        [4.252, 2.311, 2.638],
    ],
    [
        [4.0703, 13.3303, 7.0075],
        [4.4380, 20.7976, 9.1536],
        [0.0908, 0.4992, 0.7023],
        [22.4928, 47.8121, 28.1625],
    ],
];

/// Dataset 3's threshold table: cut-offs (∞, 2, 1.5, 1 mm), frames kept, and per
/// axis Std./Mean/Min/Max.
const DATASET3_EXPERIMENT: (&str, &str) = ("hemisphere_checkerboard", "dataset3");
pub const DATASET3_THESIS_FRAMES: [usize; 4] = [50, 32, 25, 14];
/// `[axis][row][cut-off]`.
pub const DATASET3_THESIS: [[[f64; 4]; 4]; 3] = [
    [
        [0.959, 0.342, 0.310, 0.242],
        [1.024, 0.449, 0.418, 0.298],
        [0.005, 0.020, 0.047, 0.027],
        [4.443, 1.741, 1.453, 0.795],
    ],
    [
        [1.758, 0.570, 0.281, 0.139],
        [1.704, 0.608, 0.392, 0.161],
        [0.034, 0.008, 0.012, 0.003],
        [6.743, 2.433, 0.944, 0.509],
    ],
    [
        [0.444, 0.285, 0.249, 0.202],
        [0.542, 0.350, 0.296, 0.256],
        [0.016, 0.008, 0.019, 0.066],
        [1.635, 1.132, 0.948, 0.833],
    ],
];

/// The whole chapter.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Chapter {
    pub tables: Vec<Table>,
    pub missing: Vec<String>,
}

/// The frames each cut-off kept, beside the thesis's Dataset 3.
fn kept_note(s: &Summary) -> String {
    let ours: Vec<String> = s
        .thresholds
        .iter()
        .map(|r| format!("{} {}", crate::evaluate::cutoff_label(r.cutoff_mm.0), r.frames))
        .collect();
    let thesis: Vec<String> = DATASET3_THESIS_FRAMES.iter().map(|f| f.to_string()).collect();
    format!(
        " Frames kept at the cut-offs: {} (thesis: {}).",
        ours.join(", "),
        thesis.join(" / ")
    )
}

fn truth_note(s: &Summary) -> String {
    match &s.truth {
        Some(t) => format!(
            " probecal's calibration (frames above {} mm removed) places the image corners within {:.3} mm of the truth on average.",
            s.calibration.cutoff_mm.written(),
            t.corner_error_mm.mean
        ),
        None => String::new(),
    }
}

/// One statistic of one axis of a BRE table, if the table is there.
fn stat(bre: Option<&BreSummary>, axis: usize, get: fn(&AxisStats) -> f64) -> Option<f64> {
    bre.map(|b| get(&b.axes()[axis]))
}

/// Lays out the chapter from the runs under `root` (`<experiment>/<dataset>/summary.json`).
pub fn chapter(root: &Path) -> Chapter {
    let mut tables = Vec::new();
    let mut missing = Vec::new();
    for t in &AXIS_TABLES {
        match summary(root, t.experiment, t.dataset) {
            Some(s) => tables.push(axis_table(t, &s)),
            None => missing.push(format!("{}/{}", t.experiment, t.dataset)),
        }
    }
    let (experiment, dataset) = DATASET3_EXPERIMENT;
    match summary(root, experiment, dataset) {
        Some(s) => tables.push(dataset3_table(&s)),
        None => missing.push(format!("{experiment}/{dataset}")),
    }
    match crate::report::thesis::rig_comparison::rigs_table(root) {
        Ok(t) => tables.push(t),
        Err(absent) => missing.extend(absent),
    }
    tables.push(sigma_table());
    Chapter { tables, missing }
}

/// A BRE-along-axes table over all frames, beside the thesis's.
fn axis_table(t: &AxisTable, s: &Summary) -> Table {
    // The thesis's tables for these datasets are over all frames: the first cut-off (∞).
    let all = s.thresholds.first();
    let frames = all.map_or(0, |r| r.frames);
    let bre = all.and_then(|r| r.bre_mm.as_ref());
    let rows = ROWS
        .iter()
        .zip(STAT_ROWS)
        .enumerate()
        .map(|(r, (label, (_, get)))| Row {
            label: label.to_string(),
            cells: (0..3)
                .flat_map(|a| [fmt(stat(bre, a, get)), fmt(Some(t.thesis[r][a]))])
                .collect(),
        })
        .collect();
    Table {
        id: t.experiment.to_string(),
        title: t.title.to_string(),
        note: format!(
            "{} probecal: {} ({frames} frames with a usable feature, all kept).{}{}",
            t.note,
            t.experiment,
            truth_note(s),
            if t.show_kept { kept_note(s) } else { String::new() }
        ),
        groups: vec!["x".into(), "y".into(), "z".into()],
        sub: vec!["probecal".into(), "thesis".into()],
        blocks: vec![(String::new(), rows)],
        spans: Vec::new(),
        thesis_columns: true,
    }
    .with_spans()
}

/// Dataset 3's BRE at every cut-off, beside the thesis's.
fn dataset3_table(s: &Summary) -> Table {
    let (experiment, _) = DATASET3_EXPERIMENT;
    let rows = &s.thresholds;
    let groups: Vec<String> = rows
        .iter()
        .zip(DATASET3_THESIS_FRAMES)
        .map(|(r, thesis_frames)| {
            let cutoff = crate::evaluate::cutoff_label(r.cutoff_mm.0);
            format!("{cutoff} ({} / {thesis_frames})", r.frames)
        })
        .collect();
    let blocks = ["X", "Y", "Z"]
        .iter()
        .enumerate()
        .map(|(a, axis)| {
            let rows = ROWS
                .iter()
                .zip(STAT_ROWS)
                .enumerate()
                .map(|(r, (label, (_, get)))| Row {
                    label: label.to_string(),
                    cells: rows
                        .iter()
                        .enumerate()
                        .flat_map(|(c, row)| {
                            [
                                fmt(stat(row.bre_mm.as_ref(), a, get)),
                                fmt(DATASET3_THESIS[a].get(r).and_then(|v| v.get(c)).copied()),
                            ]
                        })
                        .collect(),
                })
                .collect();
            (axis.to_string(), rows)
        })
        .collect();
    Table {
        id: experiment.to_string(),
        title: "BRE along axes for Dataset 3".into(),
        note: format!(
            "11x11 squares of 13 mm, 50 frames; frames above each cut-off removed and the calibration solved \
             again (column heads: frames kept, probecal / thesis). probecal: {experiment}.{}",
            truth_note(s)
        ),
        groups,
        sub: vec!["probecal".into(), "thesis".into()],
        blocks,
        spans: Vec::new(),
        thesis_columns: true,
    }
    .with_spans()
}

/// The thesis's synthetic experiment: the residuals' SD at each noise level.
fn sigma_table() -> Table {
    let sigma = crate::pipeline::study::sigma_table(50, 200, 1);
    Table {
        id: "sigma".into(),
        title: "Error in synthetic data with varying noise".into(),
        note: "Gaussian noise of SD σ on each axis of the marker's position, 50 frames, Horn's closed form, 200 \
               repetitions (the protocol is stated on the page of probecal study). Std.: SD of the per-axis absolute \
               residuals."
            .into(),
        groups: vec!["Std.".into()],
        sub: vec!["probecal".into(), "thesis".into()],
        blocks: vec![(
            String::new(),
            sigma
                .iter()
                .map(|r| Row {
                    label: format!("σ = {}", r.sigma_mm),
                    cells: vec![fmt(Some(r.std_per_axis_mm)), fmt(Some(r.thesis_std_mm))],
                })
                .collect(),
        )],
        spans: Vec::new(),
        thesis_columns: true,
    }
    .with_spans()
}

/// The layout of the chapter without its numbers: what the golden test pins.
pub fn layout(chapter: &Chapter) -> String {
    let mut out = String::new();
    for t in &chapter.tables {
        out.push_str(&format!("table {} | {}\n", t.id, t.title));
        // Frame counts in the cut-off heads are numbers too.
        let groups: Vec<String> = t
            .groups
            .iter()
            .map(|g| g.split(" (").next().unwrap_or(g).to_string())
            .collect();
        out.push_str(&format!("  columns {} x [{}]\n", groups.join(", "), t.sub.join(", ")));
        for (block, rows) in &t.blocks {
            for r in rows {
                let cells: Vec<&str> = r
                    .cells
                    .iter()
                    .map(|c| {
                        let count = |v: &str| !v.is_empty() && v.chars().all(|ch| ch.is_ascii_digit());
                        if c.parse::<f64>().is_ok() && c.split('.').nth(1).is_some_and(|d| d.len() == 3) {
                            "#.###"
                        } else if c.split_once(" / ").is_some_and(|(a, b)| count(a) && count(b)) {
                            "# / #"
                        } else {
                            "?"
                        }
                    })
                    .collect();
                out.push_str(&format!("  {block:>1} {:<8} {}\n", r.label, cells.join(" ")));
            }
        }
    }
    out
}

use crate::report::error::OutputError;

const HTML_TEMPLATE: &str = include_str!("../../../templates/thesis.html.tera");
const TEX_TEMPLATE: &str = include_str!("../../../templates/thesis.tex.tera");

/// The chapter and its pages (HTML, LaTeX) from the runs under `root`; `None`
/// when none of the chapter's experiments has a run there.
pub fn render(root: &Path) -> Result<Option<(Chapter, String, String)>, OutputError> {
    let chapter = chapter(root);
    // The σ-table is always there (it is computed, not read): no chapter
    // unless one of the thesis's experiments ran into `root`.
    if chapter.tables.len() <= 1 {
        return Ok(None);
    }
    let mut t = tera::Tera::default();
    t.add_raw_templates(vec![("thesis.html", HTML_TEMPLATE), ("thesis.tex", TEX_TEMPLATE)])?;
    crate::report::templating::register_tex_filter(&mut t);
    let mut ctx = tera::Context::from_serialize(&chapter)?;
    ctx.insert("probecal_version", env!("CARGO_PKG_VERSION"));
    let html = t.render("thesis.html", &ctx)?;
    let tex = t.render("thesis.tex", &ctx)?;
    Ok(Some((chapter, html, tex)))
}

/// Writes `thesis.html` and `thesis.tex` into `root` (see [`render`]).
pub fn write(root: &Path) -> Result<Option<Chapter>, OutputError> {
    let Some((chapter, html, tex)) = render(root)? else {
        return Ok(None);
    };
    for (file, text) in [("thesis.html", html), ("thesis.tex", tex)] {
        crate::io::fs::write_atomic(&root.join(file), text.as_bytes())?;
    }
    Ok(Some(chapter))
}
