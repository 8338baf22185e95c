//! A study's pages: `study.json` (typed, [`StudyFile`]), `study.md` and `study.html`.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::pipeline::study::{BoundModel, MonteCarlo, SigmaRow};
use crate::report::summary::to_text;

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

fn escape_html(text: &str) -> String {
    text.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

/// A self-contained HTML page from the Markdown tables.
pub(super) fn html(md: &str) -> String {
    let mut body = String::new();
    let mut in_table = false;
    for line in md.lines() {
        if line.starts_with('|') {
            let cells: Vec<String> = line
                .trim_matches('|')
                .split(" | ")
                .map(|c| escape_html(c.trim()).replace("\\|", "|"))
                .collect();
            if cells.iter().all(|c| c.chars().all(|ch| ch == '-')) {
                continue;
            }
            if !in_table {
                body.push_str("<table><thead><tr>");
                body.push_str(&cells.iter().map(|c| format!("<th>{c}</th>")).collect::<String>());
                body.push_str("</tr></thead><tbody>\n");
                in_table = true;
            } else {
                body.push_str("<tr>");
                body.push_str(&cells.iter().map(|c| format!("<td>{c}</td>")).collect::<String>());
                body.push_str("</tr>\n");
            }
            continue;
        }
        if in_table {
            body.push_str("</tbody></table>\n");
            in_table = false;
        }
        if let Some(h) = line.strip_prefix("## ") {
            body.push_str(&format!("<h2>{}</h2>\n", escape_html(h).replace('`', "")));
        } else if let Some(h) = line.strip_prefix("# ") {
            body.push_str(&format!("<h1>{}</h1>\n", escape_html(h)));
        } else if !line.trim().is_empty() {
            body.push_str(&format!("<p>{}</p>\n", escape_html(line).replace('`', "")));
        }
    }
    if in_table {
        body.push_str("</tbody></table>\n");
    }
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>probecal studies</title>\n<style>body{{font-family:sans-serif;max-width:60rem;margin:2rem auto;padding:0 1rem}}table{{border-collapse:collapse;margin:1rem 0}}td,th{{border:1px solid #bbb;padding:.3rem .6rem;text-align:right}}td:first-child,th:first-child{{text-align:left}}</style></head><body>\n{body}</body></html>\n"
    )
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
    let html = html(&md);
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
