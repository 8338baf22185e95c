//! `probecal ablate`: the error budget of a rendered rig as `ablation.json`,
//! `ablation.md` and `ablation.html`, with the thesis's Dataset 3 row beside it.

use std::fmt::Write as _;

use crate::pipeline::study::ablation::{Ablation, VariantResult};

fn methods_of(a: &Ablation) -> Vec<String> {
    let mut names: Vec<String> = Vec::new();
    for v in &a.variants {
        for t in &v.truth {
            if !names.contains(&t.method) {
                names.push(t.method.clone());
            }
        }
    }
    names
}

fn cell(v: Option<f64>) -> String {
    match v {
        Some(v) if v.is_finite() => format!("{v:.3}"),
        _ => "—".into(),
    }
}

fn row(v: &VariantResult, methods: &[String]) -> String {
    let [x, y, z] = v.bre_mean_all_frames_mm;
    let kept = v
        .kept
        .iter()
        .map(|k| k.frames.to_string())
        .collect::<Vec<_>>()
        .join(" / ");
    let truth: Vec<String> = methods
        .iter()
        .map(|m| cell(v.truth.iter().find(|t| &t.method == m).map(|t| t.corner_error_mm)))
        .collect();
    format!(
        "| {} | {:.3} | {:.3} | {:.3} | {} | {} | {} | {} |",
        v.variant,
        x,
        y,
        z,
        kept,
        cell(v.probe_pose_error_mm),
        cell(v.phantom_pose_error_mm),
        truth.join(" | ")
    )
}

/// The page's Markdown.
pub fn markdown(a: &Ablation) -> String {
    let methods = methods_of(a);
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# Error budget of {} (seed {}, {} frames)\n",
        a.experiment, a.seed, a.frames
    );
    let _ = writeln!(
        s,
        "Each row renders the same sweep again with the listed error sources of the manifest's \
         `render.realism` switched on or off. BRE: mean per axis of the phantom frame over all usable \
         frames, for the calibration from all of them (the thesis's first column). Kept: frames left \
         at the cut-offs. Pose error: mean error of the detected board poses (ground truth). The \
         estimators' columns: mean distance from the truth over the image's corners and centre, mm, \
         where the scanner's display truly puts those pixels.\n"
    );
    let cutoffs = a
        .variants
        .first()
        .map(|v| v.kept.iter().map(|k| k.cutoff.clone()).collect::<Vec<_>>().join(" / "))
        .unwrap_or_default();
    let _ = writeln!(
        s,
        "| variant | BRE x | BRE y | BRE z | kept {cutoffs} | probe pose (mm) | phantom pose (mm) | {} |",
        methods.join(" | ")
    );
    let _ = writeln!(s, "|{}", "---|".repeat(7 + methods.len()));
    let t = &crate::report::thesis::DATASET3_THESIS;
    let f = crate::report::thesis::DATASET3_THESIS_FRAMES;
    let _ = writeln!(
        s,
        "| thesis, Dataset 3 (published) | {:.3} | {:.3} | {:.3} | {} / {} / {} / {} | — | — |{}",
        t[0][1][0],
        t[1][1][0],
        t[2][1][0],
        f[0],
        f[1],
        f[2],
        f[3],
        " — |".repeat(methods.len())
    );
    for v in &a.variants {
        let _ = writeln!(s, "{}", row(v, &methods));
    }
    let _ = writeln!(s, "\n## The sources as rendered\n");
    let _ = writeln!(s, "| source | value |");
    let _ = writeln!(s, "|---|---|");
    if let Ok(value) = serde_json::to_value(&a.realism) {
        if let Some(map) = value.as_object() {
            for (k, v) in map {
                let _ = writeln!(s, "| {k} | {} |", v.to_string().replace('|', "\\|"));
            }
        }
    }
    s
}

/// Writes `ablation.json`, `ablation.md` and `ablation.html` into `out` (whole,
/// or nothing); the Markdown.
pub fn write(a: &Ablation, out: &std::path::Path) -> Result<String, crate::report::error::OutputError> {
    let json = crate::io::json::to_text(&crate::results::ablation::AblationFile::of(a))?;
    let md = markdown(a);
    crate::io::fs::write_all_atomic(
        out,
        &[
            ("ablation.json".into(), json.into_bytes()),
            ("ablation.md".into(), md.clone().into_bytes()),
            ("ablation.html".into(), crate::report::study::html(&md)?.into_bytes()),
        ],
    )?;
    Ok(md)
}
