//! `index.html`: one line per dataset run, and the studies and the thesis chapter beside them.

use std::path::Path;

use serde::Serialize;

use crate::io::fs::write_atomic;
use crate::report::error::OutputError;
use crate::report::page::render::tera;
use crate::results::summary::RunSummary;

/// One line of the index page.
#[derive(Debug, Serialize)]
pub struct IndexEntry {
    pub experiment: String,
    pub dataset: String,
    pub link: String,
    /// What was calibrated: a camera rig, tracker poses with B-scans, or a
    /// tracked recording (PLUS's).
    pub kind: &'static str,
    pub frames: String,
    /// The run's own accuracy, named: the largest per-axis mean BRE of a camera
    /// rig or tracker poses, the validation PRE3D of a tracked recording.
    pub accuracy: String,
    pub truth_corner: String,
    /// "pass", "FAIL" or "no gate" (none set).
    pub gates: &'static str,
}

fn f3(v: Option<f64>) -> String {
    v.map(|x| format!("{x:.3}")).unwrap_or_else(|| "—".into())
}

/// The index line of a run, from its summary.
pub fn index_entry(summary: &RunSummary) -> IndexEntry {
    let (experiment, dataset) = (summary.experiment(), summary.dataset());
    let link = format!("{experiment}/{dataset}/report.html");
    let gates = match summary.gates() {
        [] => "no gate",
        g if g.iter().all(|g| g.passed) => "pass",
        _ => "FAIL",
    };
    match summary {
        RunSummary::Camera(s) => IndexEntry {
            experiment: experiment.into(),
            dataset: dataset.into(),
            link,
            // A camera's intrinsics, or poses from a tracker's CSV and no camera.
            kind: if s.camera.fx_px.is_some() {
                "camera rig"
            } else {
                "tracker poses"
            },
            frames: format!("{} / {}", s.frames.used, s.frames.total),
            accuracy: s
                .bre_mm
                .map(|b| format!("max mean BRE {:.3}", b.max_mean()))
                .unwrap_or_else(|| "—".into()),
            truth_corner: {
                let reported = f3(s.truth.as_ref().map(|t| t.corner_error_mm.mean));
                match s.gated_truth() {
                    Some((name, t)) => format!("{reported}; {name} {:.3}", t.corner_error_mm.mean),
                    None => reported,
                }
            },
            gates,
        },
        RunSummary::Tracked(s) => IndexEntry {
            experiment: experiment.into(),
            dataset: dataset.into(),
            link,
            kind: "tracked recording",
            frames: match s.frames.validation.total {
                0 => format!(
                    "calibration {} / {}",
                    s.frames.calibration.segmented, s.frames.calibration.total
                ),
                _ => format!(
                    "calibration {} / {}, validation {} / {}",
                    s.frames.calibration.segmented,
                    s.frames.calibration.total,
                    s.frames.validation.segmented,
                    s.frames.validation.total
                ),
            },
            accuracy: match s.validation.pre3d_mm {
                Some(p) => format!("validation PRE3D {:.3}", p.mean),
                None => "—".into(),
            },
            truth_corner: "—".into(),
            gates,
        },
    }
}

/// The index page linking every dataset run, and `studies` (link, title) beside them.
pub fn render_index(entries: &[&IndexEntry], studies: &[(String, String)]) -> Result<String, OutputError> {
    let mut ctx = tera::Context::new();
    ctx.insert("entries", entries);
    ctx.insert("studies", studies);
    ctx.insert("probecal_version", env!("CARGO_PKG_VERSION"));
    Ok(tera()?.render("index.html", &ctx)?)
}

/// "N seeds", with their range when they run on without a gap (studies of one
/// experiment differ by their seeds).
fn seeds_phrase(seeds: &[u64]) -> String {
    let (Some(first), Some(last)) = (seeds.iter().min(), seeds.iter().max()) else {
        return "0 seeds".into();
    };
    let n = seeds.len();
    let unbroken = last - first + 1 == n as u64 && seeds.windows(2).all(|w| w[0] < w[1]);
    match n {
        1 => format!("seed {first}"),
        _ if unbroken => format!("{n} seeds, {first}–{last}"),
        _ => format!("{n} seeds"),
    }
}

/// The index's words for a study folder: its experiment and seeds from
/// `study.json`, or the folder's name when that cannot be read.
pub fn study_label(study_json: &Path, folder: &str) -> String {
    let head = crate::results::study::StudyFile::read(study_json)
        .ok()
        .and_then(|s| s.monte_carlo);
    match head {
        Some(mc) => format!(
            "Monte Carlo accuracy study of {} ({})",
            mc.experiment,
            seeds_phrase(&mc.seeds.iter().map(|s| s.seed).collect::<Vec<_>>())
        ),
        None => format!("Study: {}", folder.replace('_', " ")),
    }
}

/// The pages beside the runs in `out`, as (link, title): the side-by-side
/// comparison, the thesis chapter (written here from the runs' summaries), the
/// study in `study/` and the further studies in `study/<name>/`.
pub fn pages_beside(out: &Path) -> (Vec<(String, String)>, Vec<String>) {
    let mut studies: Vec<(String, String)> = Vec::new();
    let mut errors = Vec::new();
    // The experiments side by side (`probecal compare`).
    if out.join("compare.html").is_file() {
        studies.push((
            "compare.html".into(),
            "The experiments side by side (also compare.md and compare.tex)".into(),
        ));
    }
    // The thesis's results chapter, from whichever of its experiments are in `out`.
    match crate::report::thesis::write(out) {
        Ok(Some(_)) => studies.push((
            "thesis.html".into(),
            "The thesis's results chapter, regenerated (also thesis.tex)".into(),
        )),
        Ok(None) => {}
        Err(e) => errors.push(format!("thesis chapter: {e}")),
    }
    if out.join("study/study.html").is_file() {
        studies.push((
            "study/study.html".into(),
            "The thesis's σ-table and the Monte Carlo accuracy study of every estimator".into(),
        ));
    }
    // Further studies (`probecal study <manifest> --out <out>/study/<name>`), e.g. the
    // error budget of `experiments/studies/`.
    let more = nested_folders_with(&out.join("study"), "study.html", STUDY_DEPTH);
    for name in more {
        studies.push((
            format!("study/{name}/study.html"),
            study_label(&out.join("study").join(&name).join("study.json"), &name),
        ));
    }
    // The dome layouts ranked by their bound (`probecal design --out <out>/design`).
    if out.join("design/design.md").is_file() {
        studies.push((
            "design/design.md".into(),
            "The multi-sphere layouts ranked by their Cramér–Rao bound (also design.json and the chosen layout's STL)"
                .into(),
        ));
    }
    // Error budgets (`probecal ablate <manifest> --out <out>/ablation/<experiment>`).
    let budgets = nested_folders_with(&out.join("ablation"), "ablation.html", 1);
    for name in budgets {
        studies.push((
            format!("ablation/{name}/ablation.html"),
            format!("Error budget of {name}: each error source of the rig left out and alone"),
        ));
    }
    (studies, errors)
}

/// How deep below `study/` further studies are looked for (`study/<group>/<name>`).
const STUDY_DEPTH: usize = 3;

/// The folders directly in `dir` (name, path), sorted by name; none when it cannot be read.
fn sub_folders(dir: &Path) -> Vec<(String, std::path::PathBuf)> {
    let mut folders: Vec<(String, std::path::PathBuf)> = std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .filter(|e| e.file_type().is_ok_and(|t| t.is_dir()))
        .filter_map(|e| e.file_name().to_str().map(|n| (n.to_string(), e.path())))
        .collect();
    folders.sort();
    folders
}

/// The folders below `dir`, at most `depth` levels down, that hold `file`, as
/// `/`-joined paths relative to `dir`, sorted; a folder holding `file` is
/// listed and also searched further (a group of studies may sit beside one).
fn nested_folders_with(dir: &Path, file: &str, depth: usize) -> Vec<String> {
    let mut out = Vec::new();
    if depth == 0 {
        return out;
    }
    for (name, path) in sub_folders(dir) {
        if path.join(file).is_file() {
            out.push(name.clone());
        }
        out.extend(
            nested_folders_with(&path, file, depth - 1)
                .into_iter()
                .map(|below| format!("{name}/{below}")),
        );
    }
    out
}

/// The runs already in `out` (`<experiment>/<dataset>/summary.json`) that are
/// not among `entries`, sorted by experiment and dataset: an earlier run into
/// the same folder stays linked. A summary that cannot be read is an error named.
fn earlier_runs(out: &Path, entries: &[IndexEntry]) -> (Vec<IndexEntry>, Vec<String>) {
    let (mut found, mut errors) = (Vec::new(), Vec::new());
    for (experiment, dir) in sub_folders(out) {
        for (dataset, run) in sub_folders(&dir) {
            let summary = run.join("summary.json");
            let listed = entries
                .iter()
                .any(|e| e.experiment == experiment && e.dataset == dataset);
            if listed || !summary.is_file() || crate::results::is_not_a_run(&summary) {
                continue;
            }
            match RunSummary::read(&summary) {
                Ok(s) if s.experiment() == experiment && s.dataset() == dataset => found.push(index_entry(&s)),
                Ok(_) => errors.push(format!(
                    "{}: names another experiment or dataset than its folder; not linked",
                    summary.display()
                )),
                Err(e) => errors.push(format!("{}: {e}; not linked", summary.display())),
            }
        }
    }
    (found, errors)
}

/// Writes `out/index.html` for `entries`, the runs already in `out` and the
/// pages beside them; the errors met.
pub fn write(out: &Path, entries: &[IndexEntry]) -> Vec<String> {
    let (studies, mut errors) = pages_beside(out);
    let (earlier, unread) = earlier_runs(out, entries);
    errors.extend(unread);
    let all: Vec<&IndexEntry> = entries.iter().chain(&earlier).collect();
    match render_index(&all, &studies) {
        Ok(html) => {
            if let Err(e) = write_atomic(&out.join("index.html"), html.as_bytes()) {
                errors.push(e.to_string());
            }
        }
        Err(e) => errors.push(format!("index page: {e}")),
    }
    errors
}

#[cfg(test)]
mod tests {
    use super::{nested_folders_with, seeds_phrase};

    #[test]
    fn studies_in_groups_are_found_down_to_the_depth_limit() {
        let dir = std::env::temp_dir().join(format!("probecal-index-studies-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        for folder in ["a", "g/b", "g/c", "a/inner", "x", "d1/d2/d3/d4"] {
            std::fs::create_dir_all(dir.join(folder)).unwrap();
        }
        for folder in ["a", "g/b", "a/inner", "d1/d2/d3/d4"] {
            std::fs::write(dir.join(folder).join("study.html"), "").unwrap();
        }
        // A file named like a folder is not one.
        std::fs::write(dir.join("g/study.html.d"), "").unwrap();
        assert_eq!(
            nested_folders_with(&dir, "study.html", 3),
            ["a", "a/inner", "g/b"].map(String::from).to_vec()
        );
        assert_eq!(
            nested_folders_with(&dir, "study.html", 1),
            ["a"].map(String::from).to_vec()
        );
        assert!(nested_folders_with(&dir, "study.html", 4).contains(&"d1/d2/d3/d4".to_string()));
        assert!(nested_folders_with(&dir.join("missing"), "study.html", 3).is_empty());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_study_is_named_by_its_seeds() {
        assert_eq!(seeds_phrase(&[2000, 2001, 2002]), "3 seeds, 2000–2002");
        assert_eq!(seeds_phrase(&[1000, 1002]), "2 seeds");
        assert_eq!(seeds_phrase(&[1001, 1000]), "2 seeds");
        assert_eq!(seeds_phrase(&[7]), "seed 7");
        assert_eq!(seeds_phrase(&[]), "0 seeds");
    }
}
