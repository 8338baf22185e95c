//! A study's pages: `study.json` (typed, [`StudyFile`]), `study.md` and `study.html`.

pub mod ablation;
pub mod compare;
pub mod design;
use std::path::Path;

use crate::pipeline::study::{BoundModel, MonteCarlo, SigmaRow};
pub use crate::results::study::StudyFile;
use crate::results::summary::to_text;

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
        schema_version: crate::results::SCHEMA_VERSION,
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
