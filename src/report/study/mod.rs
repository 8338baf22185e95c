//! A study's pages: `study.json` (typed, [`StudyFile`]), `study.md` and `study.html`.

pub mod ablation;
pub mod compare;
pub mod design;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::pipeline::study::{BoundModel, MonteCarlo, SigmaRow};
use crate::results::summary::to_text;

/// `study.json`: the σ-table and, when seeds were run, the Monte Carlo study.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StudyFile {
    pub sigma_table: Vec<SigmaRow>,
    pub monte_carlo: Option<MonteCarlo>,
}

impl StudyFile {
    /// Reads a `study.json`.
    pub fn read(path: &Path) -> Result<StudyFile, crate::report::error::ReadError> {
        let fail = |e: &dyn std::fmt::Display| crate::report::error::ReadError::new(path, e);
        let text =
            crate::io::fs::read_text_capped(path, crate::core::limits::MAX_TEXT_FILE_BYTES).map_err(|e| fail(&e))?;
        let file: StudyFile = crate::io::unique_keys::json(&text).map_err(|e| fail(&e))?;
        if let Some(why) = file.monte_carlo.as_ref().and_then(seeds_refusal) {
            return Err(fail(&why));
        }
        Ok(file)
    }
}

/// Why a study's seeds cannot be read as a sample: a seed listed twice (it
/// would count twice in every mean and pairing), or an error that is not a
/// finite distance (negative, infinite or not a number).
fn seeds_refusal(mc: &MonteCarlo) -> Option<String> {
    let mut seen = std::collections::BTreeSet::new();
    for s in &mc.seeds {
        if !seen.insert(s.seed) {
            return Some(format!("monte_carlo.seeds: seed {} is listed twice", s.seed));
        }
        if let Some((method, e)) = s.rms_error_mm.iter().find(|(_, e)| !(e.is_finite() && *e >= 0.0)) {
            return Some(format!(
                "monte_carlo.seeds: seed {}, method `{method}`: rms error {e} mm is not a finite distance (≥ 0)",
                s.seed
            ));
        }
    }
    None
}

/// The study's tables as Markdown (also the body of the HTML page).
pub fn markdown(sigma: &[SigmaRow], monte_carlo: Option<&MonteCarlo>) -> String {
    let mut md = String::from("# Studies\n\n## The thesis's synthetic experiment (σ-table)\n\n");
    md.push_str(
        "Protocol: a fixed phantom point; per frame a random image point, a probe tilted up to ±20° about X and Y \
         with a fixed rotation about Z, and the marker placed so the image point lands on the phantom point; Gaussian \
         noise of SD σ on each axis of the marker's position; Horn's closed form; 50 frames, 200 repetitions.\n\n",
    );
    md.push_str("| σ (mm) | thesis: Std (mm) | probecal: Std of \\|residual\\| per axis (mm) | probecal: Std of 3D residual (mm) |\n|---|---|---|---|\n");
    for r in sigma {
        md.push_str(&format!(
            "| {} | {:.3} | {:.3} | {:.3} |\n",
            r.sigma_mm, r.thesis_std_mm, r.std_per_axis_mm, r.std_distance_mm
        ));
    }
    if let Some(mc) = monte_carlo {
        md.push_str(&format!(
            "\n## Monte Carlo accuracy study: `{}`, {} seeds\n\n",
            mc.experiment,
            mc.seeds.len()
        ));
        md.push_str(
            "Each seed renders the experiment's dataset anew (photos, B-scans, outlier and missing frames) and runs the \
             whole pipeline; the error is the RMS distance of the image's four corners and centre from the truth. ",
        );
        md.push_str(match mc.bound {
            BoundModel::PointPairs => {
                "The Cramér–Rao bound is that of the point-pair model (independent Gaussian pair residuals with the \
                 covariance of the true residuals of the inlier frames, measured per seed).\n\n"
            }
            BoundModel::SphereFit => {
                "The Cramér–Rao bound is that of the sphere fit's calibration over each seed's sweep (every arc's edge \
                 points on its sphere; each frame's pose from its boards' corners and the hand's motion, and the camera's \
                 intrinsics, as nuisances; `probecal design`'s noise model).\n\n"
            }
        });
        md.push_str(&format!(
            "RMS / CRLB is over the seeds that have a bound; in brackets its {:.0} % confidence interval for the \
             population of seeds, a bootstrap over these {}.\n\n",
            crate::pipeline::study::INTERVAL_LEVEL * 100.0,
            mc.seeds.len()
        ));
        let reported = mc.methods.first().map(|m| m.method.as_str()).unwrap_or("—");
        md.push_str(&format!(
            "| method | mean (mm) | 95th percentile (mm) | RMS (mm) | RMS / CRLB | seeds better / worse than {reported} by > 5 % |\n|---|---|---|---|---|---|\n"
        ));
        for m in &mc.methods {
            let ratio = match (m.rms_over_bound, m.rms_over_bound_90) {
                (Some(r), Some([lo, hi])) => format!("{r:.2} ({lo:.2}–{hi:.2})"),
                (Some(r), None) => format!("{r:.2}"),
                _ => "—".into(),
            };
            md.push_str(&format!(
                "| {} | {:.3} | {:.3} | {:.3} | {} | {} / {} |\n",
                m.method,
                m.mean_mm,
                m.p95_mm,
                m.rms_mm,
                ratio,
                m.better_than_reported_seeds,
                m.worse_than_reported_seeds
            ));
        }
        md.push_str(&format!(
            "| Cramér–Rao bound of {} | | | {:.3} | 1.00 | |\n",
            match mc.bound {
                BoundModel::PointPairs => "the point-pair model (independent frames)",
                BoundModel::SphereFit => "the sphere fit (poses and intrinsics as nuisances)",
            },
            mc.crlb_rms_mm
        ));
    }
    md
}

/// One block of a study's Markdown: a heading, a paragraph or a table.
#[derive(serde::Serialize)]
struct Block {
    kind: &'static str,
    text: String,
    head: Vec<String>,
    rows: Vec<Vec<String>>,
}

/// The Markdown's headings, paragraphs and tables, in order (code marks dropped).
fn blocks(md: &str) -> Vec<Block> {
    let mut out: Vec<Block> = Vec::new();
    let mut in_table = false;
    let text = |kind, text: &str| Block {
        kind,
        text: text.replace('`', ""),
        head: Vec::new(),
        rows: Vec::new(),
    };
    for line in md.lines() {
        if line.starts_with('|') {
            // The row under the head (`|---|:--|`) only marks it.
            let rule = |c: &str| !c.trim().is_empty() && c.trim().chars().all(|ch| ch == '-' || ch == ':');
            if line.trim_matches('|').split('|').all(rule) {
                continue;
            }
            let cells: Vec<String> = line
                .trim_matches('|')
                .split(" | ")
                .map(|c| c.trim().replace("\\|", "|"))
                .collect();
            match out.last_mut() {
                Some(table) if in_table => table.rows.push(cells),
                _ => out.push(Block {
                    kind: "table",
                    text: String::new(),
                    head: cells,
                    rows: Vec::new(),
                }),
            }
            in_table = true;
            continue;
        }
        in_table = false;
        if let Some(h) = line.strip_prefix("## ") {
            out.push(text("h2", h));
        } else if let Some(h) = line.strip_prefix("# ") {
            out.push(Block {
                text: h.to_string(),
                ..text("h1", "")
            });
        } else if !line.trim().is_empty() {
            out.push(text("p", line));
        }
    }
    out
}

const TEMPLATE: &str = include_str!("../../../templates/study.html.tera");

/// A self-contained HTML page of the Markdown's tables, from `templates/study.html.tera`.
pub fn html(md: &str) -> Result<String, tera::Error> {
    let mut ctx = tera::Context::new();
    ctx.insert("blocks", &blocks(md));
    tera::Tera::one_off(TEMPLATE, &ctx, true)
}

/// The files a study writes into its folder.
pub const STUDY_FILES: [&str; 3] = ["study.json", "study.md", "study.html"];

/// Writes `study.json`, `study.md` and `study.html` into `out`.
pub fn write(out: &Path, sigma: &[SigmaRow], monte_carlo: Option<&MonteCarlo>) -> std::io::Result<()> {
    std::fs::create_dir_all(out)?;
    let file = StudyFile {
        sigma_table: sigma.to_vec(),
        monte_carlo: monte_carlo.cloned(),
    };
    let json = to_text(&file).map_err(std::io::Error::other)?;
    let md = markdown(sigma, monte_carlo);
    let html = html(&md).map_err(std::io::Error::other)?;
    // Each file is swapped in whole: an earlier study stays readable until then.
    for (name, bytes) in [
        ("study.json", json.as_bytes()),
        ("study.md", md.as_bytes()),
        ("study.html", html.as_bytes()),
    ] {
        crate::io::fs::write_atomic(&out.join(name), bytes).map_err(std::io::Error::other)?;
    }
    Ok(())
}

/// The σ-table as every study writes it: 50 frames, 200 repetitions, seed 1.
pub fn sigma_table() -> Vec<SigmaRow> {
    crate::pipeline::study::sigma_table(50, 200, 1)
}
