//! The HTML page of a dataset run, from a prepared context (numbers already
//! formatted, mm with 3 decimals as in the thesis). The context is also written as
//! `report_context.json`, a stable target for tests. Templates live in
//! `templates/` and are compiled into the binary.

pub mod check;
pub mod compare;
pub mod figures;
pub mod gallery;
pub mod provenance;
pub mod thesis;
pub mod tracked;
pub mod write;

use plotters::prelude::*;
use serde::Serialize;

use crate::core::geometry::{euler_zyx_deg, to_rows};
use crate::evaluate::cutoff_label;
use crate::evaluate::{BreStats, STAT_ROWS};
use crate::pipeline::run::DatasetRun;

const RUN_TEMPLATE: &str = include_str!("../../templates/run.html.tera");
const INDEX_TEMPLATE: &str = include_str!("../../templates/index.html.tera");

fn mm(v: f64) -> String {
    if v.is_finite() {
        format!("{v:.3}")
    } else {
        "—".into()
    }
}

#[derive(Debug, Serialize, PartialEq)]
pub struct StatRow {
    pub parameter: String,
    pub values: Vec<String>,
}

#[derive(Debug, Serialize, PartialEq)]
pub struct AxisBlock {
    pub axis: String,
    pub rows: Vec<StatRow>,
}

#[derive(Debug, Serialize, PartialEq)]
pub struct Column {
    pub label: String,
    pub frames: usize,
}

#[derive(Debug, Serialize, PartialEq)]
pub struct Rejected {
    pub frame: usize,
    pub stage: String,
    pub reason: String,
}

#[derive(Debug, Serialize, PartialEq)]
pub struct KeyValue {
    pub key: String,
    pub value: String,
}

#[derive(Debug, Serialize, PartialEq)]
pub struct Gate {
    pub name: String,
    pub limit: String,
    pub value: String,
    pub passed: bool,
}

/// Everything the page shows, formatted.
#[derive(Debug, Serialize, PartialEq)]
pub struct RunContext {
    pub experiment: String,
    pub dataset: String,
    pub description: String,
    pub manifest: String,
    pub manifest_sha256: String,
    pub probecal_version: String,
    pub frames_total: usize,
    pub frames_used: usize,
    pub frames_rejected: usize,
    pub camera: Vec<KeyValue>,
    pub calibration_matrix: Vec<Vec<String>>,
    pub calibration: Vec<KeyValue>,
    /// The thesis's BRE table at the calibration cut-off: rows Std./Mean/Min/Max, columns x, y, z.
    pub bre_caption: String,
    pub bre_table: Vec<StatRow>,
    /// The thesis's threshold table: one column per cut-off.
    pub threshold_columns: Vec<Column>,
    pub threshold_blocks: Vec<AxisBlock>,
    pub truth: Vec<KeyValue>,
    pub truth_by_cutoff: Vec<StatRow>,
    pub gates: Vec<Gate>,
    pub rejected: Vec<Rejected>,
    pub bre_figure_svg: String,
    /// Other estimators on the same frames: name, description, frames, truth errors.
    pub methods: Vec<StatRow>,
    pub validation: Vec<KeyValue>,
    /// Manifest summary, software versions, inputs.
    pub setup: Vec<KeyValue>,
    /// B-scans with their detections: file beside the report (LaTeX), caption.
    pub gallery: Vec<GalleryEntry>,
    /// Further figures: PNG file beside the report (LaTeX), caption.
    pub figures: Vec<GalleryEntry>,
}

#[derive(Debug, Serialize, PartialEq)]
pub struct GalleryEntry {
    pub file: String,
    pub caption: String,
}

fn setup_rows(run: &DatasetRun, manifest: &crate::manifest::Manifest) -> Vec<KeyValue> {
    use crate::manifest::CameraSource;
    use crate::spec::phantom::Phantom;
    let phantom = match &manifest.phantom {
        Phantom::Hemisphere {
            centre_in_phantom_mm: c,
            radius_mm,
        } => format!(
            "hemisphere, R = {radius_mm} mm, centre ({}, {}, {}) mm",
            c[0], c[1], c[2]
        ),
        Phantom::Point {
            position_in_phantom_mm: p,
            head_radius_mm,
        } => format!(
            "pin head, r = {head_radius_mm} mm, at ({}, {}, {}) mm",
            p[0], p[1], p[2]
        ),
        Phantom::FourWire {
            wires,
            wire_diameter_mm,
        } => {
            format!("{} wires of {wire_diameter_mm} mm", wires.len())
        }
    };
    let rig = match &manifest.camera {
        CameraSource::TrackerCsv(t) => format!(
            "tracker poses from {} ({}, {})",
            t.file, t.probe_transform, t.reference_transform
        ),
        _ => crate::report::compare::rig_label(&manifest.rig),
    };
    vec![
        kv("phantom", phantom),
        kv("pose source", rig),
        kv("camera", run.camera.source.clone()),
        kv(
            "dataset",
            match run.seed {
                Some(seed) => format!("{} (rendered, seed {seed})", run.dataset),
                None => format!("{} (recorded)", run.dataset),
            },
        ),
        kv(
            "B-scan pixel size (mm)",
            format!("{} x {}", run.spacing_mm_per_px[0], run.spacing_mm_per_px[1]),
        ),
        kv(
            "software",
            format!(
                "probecal {}, OpenCV {}",
                env!("CARGO_PKG_VERSION"),
                crate::report::provenance::opencv_version()
            ),
        ),
        kv(
            "inputs",
            format!("{} files; their SHA-256 in provenance.json", run.input_files.len()),
        ),
    ]
}

fn stat_rows(stats: &BreStats) -> Vec<StatRow> {
    let axes = stats.axes();
    STAT_ROWS
        .iter()
        .map(|(name, get)| StatRow {
            parameter: name.to_string(),
            values: axes.iter().map(|a| mm(get(a))).collect(),
        })
        .collect()
}

fn kv(key: &str, value: String) -> KeyValue {
    KeyValue {
        key: key.to_string(),
        value,
    }
}

/// Per-frame BRE along x, y, z (all-frames calibration) as an inline SVG.
/// The per-frame BRE along each axis (all-frames calibration).
fn bre_chart(run: &DatasetRun) -> crate::report::figures::Chart {
    let points: Vec<(usize, [f64; 3])> = run
        .frames
        .iter()
        .filter_map(|f| f.bre_mm.map(|b| (f.files.frame, b.0)))
        .collect();
    let colours = [RGBColor(200, 40, 40), RGBColor(40, 140, 40), RGBColor(40, 70, 200)];
    crate::report::figures::Chart {
        id: "bre_per_frame",
        caption: "Per-frame BRE along each axis of the phantom frame, all-frames calibration.".into(),
        x_desc: "frame".into(),
        y_desc: "BRE (mm)".into(),
        style: crate::report::figures::Style::Lines,
        series: ["x", "y", "z"]
            .iter()
            .enumerate()
            .map(|(a, name)| crate::report::figures::Series {
                name: name.to_string(),
                colour: colours[a],
                points: points.iter().map(|(f, b)| (*f as f64, b[a])).collect(),
            })
            .collect(),
        equal_axes: false,
    }
}

pub fn bre_figure(run: &DatasetRun) -> Result<String, String> {
    crate::report::figures::svg(&bre_chart(run))
}

/// The per-frame BRE plot as a PNG (for LaTeX, which cannot include SVG).
pub fn bre_figure_png(run: &DatasetRun) -> Result<Vec<u8>, String> {
    crate::report::figures::png(&bre_chart(run))
}

/// Where the bitmap figures' font is read from.
pub const FIGURE_FONT: &str = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";

/// Registers the figures' font once (plotters lays text out with it, SVG included).
pub(crate) fn register_font() -> Result<(), String> {
    static FONT: std::sync::OnceLock<Result<(), String>> = std::sync::OnceLock::new();
    FONT.get_or_init(|| {
        let bytes =
            std::fs::read(FIGURE_FONT).map_err(|e| format!("{FIGURE_FONT}: {e} (install fonts-dejavu-core)"))?;
        // The font lives as long as the program: figures are drawn until it ends.
        let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
        plotters::style::register_font("sans-serif", plotters::style::FontStyle::Normal, bytes)
            .map_err(|_| format!("{FIGURE_FONT}: not a TrueType font"))
    })
    .clone()
}

fn validation_rows(run: &DatasetRun) -> Vec<KeyValue> {
    let Some(v) = &run.validation else { return Vec::new() };
    let b = &v.bootstrap;
    let iv = |i: crate::evaluate::resampling::Interval| format!("[{}, {}]", mm(i.low), mm(i.high));
    let mut rows = vec![
        kv(
            "PRE, leave-one-out: mean (PRA) ± SD (mm)",
            format!(
                "{} ± {} (n = {})",
                mm(v.leave_one_out.summary.mean),
                mm(v.leave_one_out.summary.std),
                v.leave_one_out.summary.n
            ),
        ),
        kv(
            "CR: corners and centre over half-split calibrations (mm)",
            format!(
                "{} ({} calibrations)",
                mm(v.reproducibility.cr_mm),
                v.reproducibility.calibrations
            ),
        ),
    ];
    for (k, axis) in ["x", "y", "z"].iter().enumerate() {
        rows.push(kv(
            &format!("bootstrap 95 % interval: translation {axis} (mm)"),
            iv(b.translation_mm[k]),
        ));
    }
    for (k, name) in ["roll x", "pitch y", "yaw z"].iter().enumerate() {
        rows.push(kv(
            &format!("bootstrap 95 % interval: {name} (°)"),
            iv(b.euler_zyx_deg[k]),
        ));
    }
    for (k, axis) in ["x", "y", "z"].iter().enumerate() {
        rows.push(kv(
            &format!("bootstrap 95 % interval: BRE mean {axis} (mm)"),
            iv(b.bre_mean_mm[k]),
        ));
    }
    rows.push(kv(
        "bootstrap: image corners moved, 95th percentile (mm)",
        format!("{} ({} resamples)", mm(b.corner_shift_p95_mm), b.resamples),
    ));
    rows
}

/// Prepares the page's context.
pub fn context(run: &DatasetRun, manifest: &crate::manifest::Manifest) -> RunContext {
    let fit = run.primary_fit();
    let primary = &run.thresholds[run.primary];
    let mut camera = vec![kv("source", run.camera.source.clone())];
    if let Some(k) = &run.camera.intrinsics {
        camera.push(kv("fx, fy (px)", format!("{:.2}, {:.2}", k.fx(), k.fy())));
        camera.push(kv("cx, cy (px)", format!("{:.2}, {:.2}", k.cx(), k.cy())));
        camera.push(kv(
            "k1, k2, p1, p2, k3",
            k.distortion
                .iter()
                .map(|v| format!("{v:.5}"))
                .collect::<Vec<_>>()
                .join(", "),
        ));
        if let Some(rms) = k.rms_px {
            camera.push(kv("RMS reprojection error (px)", format!("{rms:.3}")));
        }
    }
    if let Some(cal) = &run.camera.calibration {
        camera.push(kv(
            "views used",
            format!("{} of {}", cal.views.iter().filter(|v| v.used).count(), cal.views.len()),
        ));
    }
    let euler = euler_zyx_deg(&fit.target_T_source);
    let t = fit.target_T_source.translation.vector;
    let calibration = vec![
        kv(
            "frames used",
            format!(
                "{} (cut-off {} mm)",
                primary.frames.len(),
                cutoff_label(primary.cutoff_mm)
            ),
        ),
        kv(
            "Euler ZYX: roll x, pitch y, yaw z (°)",
            format!("{:.3}, {:.3}, {:.3}", euler[0], euler[1], euler[2]),
        ),
        kv("translation (mm)", format!("{:.3}, {:.3}, {:.3}", t.x, t.y, t.z)),
        kv(
            "pixel spacing sx, sy (mm/px)",
            format!("{}, {}", run.spacing_mm_per_px[0], run.spacing_mm_per_px[1]),
        ),
        kv(
            "solved as",
            format!("{:?}, scale {:.5}", manifest.solve_variant, fit.scale).to_lowercase(),
        ),
        kv("Horn RMS residual (mm)", mm(fit.rms_residual_mm)),
    ];
    let threshold_blocks = ["X", "Y", "Z"]
        .iter()
        .enumerate()
        .map(|(axis, name)| AxisBlock {
            axis: name.to_string(),
            rows: STAT_ROWS
                .iter()
                .map(|(pname, get)| StatRow {
                    parameter: pname.to_string(),
                    values: run
                        .thresholds
                        .iter()
                        .map(|r| {
                            r.stats
                                .map(|s| mm(get(&[s.x, s.y, s.z][axis])))
                                .unwrap_or_else(|| "—".into())
                        })
                        .collect(),
                })
                .collect(),
        })
        .collect();
    let mut truth = Vec::new();
    let mut truth_by_cutoff = Vec::new();
    if let Some(tr) = &run.truth {
        let c = &tr.calibration;
        truth.push(kv(
            "image corners and centre: mean error (mm)",
            mm(c.corner_error_mean_mm),
        ));
        truth.push(kv(
            "image corners and centre: max error (mm)",
            mm(c.corner_error_max_mm),
        ));
        truth.push(kv("rotation error (°)", mm(c.rotation_error_deg)));
        truth.push(kv("translation error (mm)", mm(c.translation_error_mm)));
        if let (Some(focal), Some(principal)) = (tr.camera_focal_error_px, tr.camera_principal_error_px) {
            truth.push(kv("camera focal length error (px)", mm(focal)));
            truth.push(kv("camera principal point error (px)", mm(principal)));
        }
        if let Some((mean, max)) = tr.arc_centre_error_px {
            truth.push(kv(
                "arc centre vs sphere-centre projection, normal frames: mean / max (px)",
                format!("{} / {}", mm(mean), mm(max)),
            ));
        }
        if let Some((mean, max)) = tr.probe_pose_translation_error_mm {
            truth.push(kv(
                "probe board position error: mean / max (mm)",
                format!("{} / {}", mm(mean), mm(max)),
            ));
        }
        if let Some((mean, max)) = tr.phantom_pose_translation_error_mm {
            truth.push(kv(
                "phantom board position error: mean / max (mm)",
                format!("{} / {}", mm(mean), mm(max)),
            ));
        }
        if let Some((mean, max)) = tr.probe_pose_rotation_error_deg {
            truth.push(kv(
                "probe board rotation error: mean / max (°)",
                format!("{} / {}", mm(mean), mm(max)),
            ));
        }
        truth_by_cutoff = vec![
            StatRow {
                parameter: "corner error mean (mm)".into(),
                values: run
                    .thresholds
                    .iter()
                    .map(|r| {
                        r.truth
                            .map(|t| mm(t.corner_error_mean_mm))
                            .unwrap_or_else(|| "—".into())
                    })
                    .collect(),
            },
            StatRow {
                parameter: "rotation error (°)".into(),
                values: run
                    .thresholds
                    .iter()
                    .map(|r| r.truth.map(|t| mm(t.rotation_error_deg)).unwrap_or_else(|| "—".into()))
                    .collect(),
            },
        ];
    }
    let used = run.used_frames();
    RunContext {
        experiment: run.experiment.clone(),
        dataset: run.dataset.clone(),
        description: manifest.description.clone(),
        manifest: manifest
            .path
            .file_name()
            .map(|n| n.to_string_lossy().to_string())
            .unwrap_or_default(),
        manifest_sha256: manifest.sha256.clone(),
        probecal_version: env!("CARGO_PKG_VERSION").into(),
        frames_total: run.frames.len(),
        frames_used: used,
        frames_rejected: run.frames.len() - used,
        camera,
        calibration_matrix: to_rows(&fit.target_T_source)
            .iter()
            .map(|r| r.iter().map(|v| format!("{v:.4}")).collect())
            .collect(),
        calibration,
        bre_caption: format!(
            "BRE along axes for dataset {} ({} frames, cut-off {} mm)",
            run.dataset,
            primary.frames.len(),
            cutoff_label(primary.cutoff_mm)
        ),
        bre_table: primary.stats.as_ref().map(stat_rows).unwrap_or_default(),
        threshold_columns: run
            .thresholds
            .iter()
            .map(|r| Column {
                label: cutoff_label(r.cutoff_mm),
                frames: r.frames.len(),
            })
            .collect(),
        threshold_blocks,
        truth,
        truth_by_cutoff,
        gates: run
            .gates
            .iter()
            .map(|g| Gate {
                name: g.name.clone(),
                limit: mm(g.limit),
                value: g.value.map(mm).unwrap_or_else(|| "—".into()),
                passed: g.passed,
            })
            .collect(),
        rejected: run
            .frames
            .iter()
            .filter_map(|f| {
                f.rejection.as_ref().map(|(s, r)| Rejected {
                    frame: f.files.frame,
                    stage: s.label().into(),
                    reason: r.clone(),
                })
            })
            .collect(),
        bre_figure_svg: bre_figure(run).unwrap_or_else(|e| format!("<p>figure not drawn: {e}</p>")),
        methods: run
            .methods
            .iter()
            .map(|m| StatRow {
                parameter: m.name.to_string(),
                values: vec![
                    m.description.clone(),
                    m.frames_used.to_string(),
                    if m.frames_left_out.is_empty() {
                        "—".into()
                    } else {
                        m.frames_left_out
                            .iter()
                            .map(|f| f.to_string())
                            .collect::<Vec<_>>()
                            .join(" ")
                    },
                    m.truth
                        .map(|t| mm(t.corner_error_mean_mm))
                        .unwrap_or_else(|| "—".into()),
                    m.truth.map(|t| mm(t.corner_error_max_mm)).unwrap_or_else(|| "—".into()),
                    m.truth.map(|t| mm(t.rotation_error_deg)).unwrap_or_else(|| "—".into()),
                ],
            })
            .collect(),
        validation: validation_rows(run),
        setup: setup_rows(run, manifest),
        gallery: Vec::new(),
        figures: Vec::new(),
    }
}

fn tera() -> Result<tera::Tera, tera::Error> {
    let mut t = tera::Tera::default();
    t.add_raw_templates(vec![
        ("run.html", RUN_TEMPLATE),
        ("index.html", INDEX_TEMPLATE),
        ("run.tex", RUN_TEX_TEMPLATE),
    ])?;
    register_tex_filter(&mut t);
    Ok(t)
}

/// Adds the `tex` filter ([`tex_escape`]) to a template set.
pub(crate) fn register_tex_filter(t: &mut tera::Tera) {
    t.register_filter("tex", tex_filter);
}

const RUN_TEX_TEMPLATE: &str = include_str!("../../templates/run.tex.tera");

/// Text made safe for LaTeX: its special characters escaped, and the symbols the
/// reports use written as LaTeX commands (pdflatex's inputenc lacks most of them).
pub fn tex_escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '\\' => out.push_str("\\textbackslash{}"),
            '{' | '}' | '$' | '&' | '#' | '_' | '%' => {
                out.push('\\');
                out.push(c);
            }
            '^' => out.push_str("\\textasciicircum{}"),
            '~' => out.push_str("\\textasciitilde{}"),
            '<' => out.push_str("\\textless{}"),
            '>' => out.push_str("\\textgreater{}"),
            '°' => out.push_str("\\textdegree{}"),
            '±' => out.push_str("\\ensuremath{\\pm}"),
            '×' => out.push_str("\\ensuremath{\\times}"),
            '·' => out.push_str("\\ensuremath{\\cdot}"),
            '−' => out.push_str("\\ensuremath{-}"),
            '—' => out.push_str("---"),
            '–' => out.push_str("--"),
            '…' => out.push_str("\\ldots{}"),
            '∞' => out.push_str("\\ensuremath{\\infty}"),
            '≈' => out.push_str("\\ensuremath{\\approx}"),
            '≤' => out.push_str("\\ensuremath{\\le}"),
            '≥' => out.push_str("\\ensuremath{\\ge}"),
            '→' => out.push_str("\\ensuremath{\\rightarrow}"),
            '←' => out.push_str("\\ensuremath{\\leftarrow}"),
            'σ' => out.push_str("\\ensuremath{\\sigma}"),
            'µ' | 'μ' => out.push_str("\\ensuremath{\\mu}"),
            '²' => out.push_str("\\ensuremath{^2}"),
            'ᵀ' => out.push_str("\\ensuremath{^T}"),
            '\'' | '’' => out.push('\''),
            _ => out.push(c),
        }
    }
    out
}

fn tex_filter(value: &tera::Value, _: &std::collections::HashMap<String, tera::Value>) -> tera::Result<tera::Value> {
    let text = match value {
        tera::Value::String(s) => s.clone(),
        other => other.to_string(),
    };
    Ok(tera::Value::String(tex_escape(&text)))
}

/// The run's report as LaTeX (its figure, `bre_per_frame.png`, is written beside it).
pub fn render_tex(context: &RunContext) -> Result<String, String> {
    let ctx = tera::Context::from_serialize(context).map_err(|e| error_chain(&e))?;
    tera()
        .and_then(|t| t.render("run.tex", &ctx))
        .map_err(|e| error_chain(&e))
}

pub(crate) fn error_chain(e: &tera::Error) -> String {
    let mut text = e.to_string();
    let mut source = std::error::Error::source(e);
    while let Some(s) = source {
        text.push_str(&format!(": {s}"));
        source = s.source();
    }
    text
}

/// The dataset run's HTML page.
/// The page; `gallery_uris` and `figure_svgs` follow `context.gallery` and
/// `context.figures` (kept out of the context's JSON).
pub fn render_html(context: &RunContext, gallery_uris: &[String], figure_svgs: &[String]) -> Result<String, String> {
    let mut ctx = tera::Context::from_serialize(context).map_err(|e| error_chain(&e))?;
    ctx.insert("gallery_uris", gallery_uris);
    ctx.insert("figure_svgs", figure_svgs);
    tera()
        .and_then(|t| t.render("run.html", &ctx))
        .map_err(|e| error_chain(&e))
}

/// One line of the index page.
#[derive(Debug, Serialize)]
pub struct IndexEntry {
    pub experiment: String,
    pub dataset: String,
    pub link: String,
    pub frames: String,
    pub bre_mean: String,
    pub truth_corner: String,
    pub passed: bool,
}

/// The index page linking every dataset run, and `studies` (link, title) beside them.
pub fn render_index(entries: &[IndexEntry], studies: &[(String, String)]) -> Result<String, String> {
    let mut ctx = tera::Context::new();
    ctx.insert("entries", entries);
    ctx.insert("studies", studies);
    ctx.insert("probecal_version", env!("CARGO_PKG_VERSION"));
    tera()
        .and_then(|t| t.render("index.html", &ctx))
        .map_err(|e| error_chain(&e))
}

const TRACKED_TEMPLATE: &str = include_str!("../../templates/tracked.html.tera");

/// The page of a tracked (sequence-file) run, from its summary.
pub fn render_tracked(
    run: &crate::pipeline::tracked::TrackedRun,
    manifest: &crate::manifest::tracked::TrackedManifest,
    summary: &serde_json::Value,
) -> Result<String, crate::report::write::OutputError> {
    use crate::pipeline::tracked::Role;
    let f3 = |v: &serde_json::Value| v.as_f64().map(|x| format!("{x:.3}")).unwrap_or_else(|| "—".into());
    let mut ctx = tera::Context::new();
    ctx.insert("experiment", &manifest.experiment);
    ctx.insert("dataset", &manifest.dataset);
    ctx.insert("description", &manifest.description);
    ctx.insert(
        "calibration_sequence",
        &manifest.calibration_sequence.display().to_string(),
    );
    ctx.insert(
        "validation_sequence",
        &manifest
            .validation_sequence
            .as_ref()
            .map(|p| p.display().to_string())
            .unwrap_or_else(|| "—".into()),
    );
    let definition = match &manifest.plus_config {
        Some(path) => path.display().to_string(),
        None => "the manifest's patterns".to_string(),
    };
    ctx.insert("plus_config", &definition);
    ctx.insert("nwires", &manifest.nwires.len());
    ctx.insert("model", &format!("{:?}", manifest.model));
    ctx.insert("constraints", &run.constraints);
    ctx.insert("kept", &run.fit.inlier.iter().filter(|k| **k).count());
    ctx.insert("time_offset_ms", &format!("{:.0}", run.time_offset_s * 1000.0));
    ctx.insert("probecal_version", env!("CARGO_PKG_VERSION"));
    ctx.insert("opencv_version", &crate::report::provenance::opencv_version());
    let (cs, ct) = run.segmented(Role::Calibration);
    let (vs, vt) = run.segmented(Role::Validation);
    ctx.insert("cal_segmented", &cs);
    ctx.insert("cal_total", &ct);
    ctx.insert("val_segmented", &vs);
    ctx.insert("val_total", &vt);
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
    let m = run.fit.image_to_probe.matrix();
    let matrix_text = (0..4)
        .map(|r| {
            (0..4)
                .map(|c| format!("{:>13.6}", m[(r, c)]))
                .collect::<Vec<_>>()
                .join(" ")
        })
        .collect::<Vec<_>>()
        .join("\n");
    ctx.insert("matrix_text", &matrix_text);
    let s = run.fit.image_to_probe.spacing_mm_per_px;
    ctx.insert("spacing_u", &format!("{:.5}", s[0]));
    ctx.insert("spacing_v", &format!("{:.5}", s[1]));
    let e = crate::core::geometry::euler_zyx_deg(&run.fit.image_to_probe.probe_T_image);
    ctx.insert("euler", &format!("[{:.2}, {:.2}, {:.2}]", e[0], e[1], e[2]));
    let t = run.fit.image_to_probe.probe_T_image.translation.vector;
    ctx.insert("translation", &format!("[{:.2}, {:.2}, {:.2}]", t.x, t.y, t.z));
    let row = |estimate: &str, frames: &str, best: &serde_json::Value, all: &serde_json::Value| {
        serde_json::json!({
            "estimate": estimate, "frames": frames,
            "mean": f3(&best["mean"]), "std": f3(&best["std"]), "n": best["n"],
            "mean_all": f3(&all["mean"]), "std_all": f3(&all["std"]), "n_all": all["n"],
        })
    };
    let mut pre3d = vec![
        row(
            "probecal",
            "validation",
            &summary["validation"]["pre3d_mm"],
            &summary["validation"]["pre3d_all_mm"],
        ),
        row(
            "probecal",
            "calibration",
            &summary["calibration"]["pre3d_mm"],
            &summary["calibration"]["pre3d_all_mm"],
        ),
    ];
    let plus = &summary["plus_result"];
    if !plus.is_null() {
        pre3d.push(row(
            "PLUS's ImageToProbe, our dots",
            "validation",
            &plus["validation_pre3d_on_our_dots_mm"],
            &plus["validation_pre3d_all_on_our_dots_mm"],
        ));
        pre3d.push(serde_json::json!({
            "estimate": "PLUS as published (its own dots)", "frames": "validation",
            "mean": f3(&plus["published_validation_pre3d_mm"]["mean"]), "std": f3(&plus["published_validation_pre3d_mm"]["std"]),
            "n": "—", "mean_all": "—", "std_all": "—", "n_all": "—",
        }));
    }
    ctx.insert("pre3d", &pre3d);
    let gates: Vec<serde_json::Value> = summary["gates"]
        .as_array()
        .cloned()
        .unwrap_or_default()
        .into_iter()
        .map(|g| serde_json::json!({"name": g["name"], "value": f3(&g["value"]), "limit": g["limit"], "passed": g["passed"]}))
        .collect();
    ctx.insert("gates", &gates);
    let mut t = tera::Tera::default();
    t.add_raw_template("tracked.html", TRACKED_TEMPLATE)
        .and_then(|_| t.render("tracked.html", &ctx))
        .map_err(|e| crate::report::write::OutputError::Report(error_chain(&e)))
}
