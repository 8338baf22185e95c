//! An error budget of a rendered rig (`probecal ablate`): the manifest's first
//! dataset rendered again with its error sources (`render.realism`) all on, all
//! off, each left out alone and each alone, and the thesis's table (BRE per axis
//! over all frames, frames kept at each cut-off) and every estimator's truth
//! error measured on each variant. Same seed, same sweep: only the sources differ.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::evaluate::cutoff_label;
use crate::manifest::{Dataset, DatasetSource, Manifest};
use crate::pipeline::error::RunError;
use crate::pipeline::run;
use crate::spec::realism::Realism;

/// One rendering of the rig.
#[derive(Debug, Clone, PartialEq)]
pub struct Variant {
    /// `all sources`, `ideal`, `without <source>`, `only <source>`.
    pub name: String,
    pub realism: Realism,
}

/// The variants of a rig, in the order of the table: all sources, none, then
/// each present source left out and alone.
pub fn variants(realism: &Realism) -> Vec<Variant> {
    let mut out = vec![
        Variant {
            name: "all sources".into(),
            realism: realism.clone(),
        },
        Variant {
            name: "ideal".into(),
            realism: Realism::default(),
        },
    ];
    for source in realism.present() {
        out.push(Variant {
            name: format!("without {source}"),
            realism: realism.without(source),
        });
    }
    for source in realism.present() {
        out.push(Variant {
            name: format!("only {source}"),
            realism: realism.only(source),
        });
    }
    out
}

/// Frames kept below one cut-off.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Kept {
    /// `<∞`, `<2`, ...
    pub cutoff: String,
    pub frames: usize,
}

/// What one variant gave.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VariantResult {
    pub variant: String,
    pub sources: Vec<String>,
    pub frames_used: usize,
    /// BRE mean per axis (x, y, z of the phantom frame) of the all-frames
    /// calibration, over all usable frames, mm.
    pub bre_mean_all_frames_mm: [f64; 3],
    pub bre_max_all_frames_mm: [f64; 3],
    pub kept: Vec<Kept>,
    /// Each estimator's mean error over the image's corners and centre (the
    /// reported calibration first).
    pub truth: Vec<MethodTruth>,
    /// Mean error of the probe board's and the phantom board's detected poses, mm.
    pub probe_pose_error_mm: Option<f64>,
    pub phantom_pose_error_mm: Option<f64>,
}

/// One estimator's ground-truth error on a variant.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MethodTruth {
    pub method: String,
    /// Mean distance from the truth over the image's corners and centre, mm.
    pub corner_error_mm: f64,
}

/// The ablation of one experiment.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Ablation {
    pub experiment: String,
    pub seed: u64,
    pub frames: usize,
    pub realism: Realism,
    pub variants: Vec<VariantResult>,
}

fn slug(name: &str) -> String {
    name.replace(' ', "_")
}

/// Runs every variant of the manifest's first (rendered) dataset.
pub fn ablate(
    manifest: &Manifest,
    datasets_root: &Path,
    keep: bool,
    only: &[String],
    log: &mut dyn FnMut(&str),
) -> Result<Ablation, RunError> {
    let Some((dataset, DatasetSource::Render(spec))) = manifest.datasets.first().map(|d| (d, &d.source)) else {
        return Err(RunError::Unsupported(
            "an ablation needs a manifest whose first dataset is rendered".into(),
        ));
    };
    let Some(realism) = spec.realism.clone().filter(|r| !r.present().is_empty()) else {
        return Err(RunError::Unsupported(format!(
            "dataset `{}` has no error sources to ablate (render.realism)",
            dataset.name
        )));
    };
    let all = variants(&realism);
    if let Some(unknown) = only.iter().find(|o| !all.iter().any(|v| &v.name == *o)) {
        return Err(RunError::Unsupported(format!(
            "no variant `{unknown}`; the variants are: {}",
            all.iter().map(|v| v.name.as_str()).collect::<Vec<_>>().join(", ")
        )));
    }
    let mut results = Vec::new();
    for variant in all.into_iter().filter(|v| only.is_empty() || only.contains(&v.name)) {
        let mut spec = spec.clone();
        spec.realism = Some(variant.realism.clone());
        let dataset = Dataset {
            name: format!("ablation_{}", slug(&variant.name)),
            source: DatasetSource::Render(spec),
        };
        let run = run::run_dataset(manifest, &dataset, datasets_root, &mut |_| {})?;
        let all = &run.thresholds[0];
        let stats = all.stats.map(|s| s.axes());
        let truth = run.truth.as_ref();
        let result = VariantResult {
            variant: variant.name.clone(),
            sources: variant.realism.present().into_iter().map(str::to_string).collect(),
            frames_used: run.used_frames(),
            bre_mean_all_frames_mm: stats.map(|a| a.map(|s| s.mean)).unwrap_or([f64::NAN; 3]),
            bre_max_all_frames_mm: stats.map(|a| a.map(|s| s.max)).unwrap_or([f64::NAN; 3]),
            kept: run
                .thresholds
                .iter()
                .map(|row| Kept {
                    cutoff: cutoff_label(row.cutoff_mm),
                    frames: row.frames.len(),
                })
                .collect(),
            truth: run
                .methods
                .iter()
                .filter_map(|m| {
                    Some(MethodTruth {
                        method: m.method.name().to_string(),
                        corner_error_mm: m.truth?.corner_error_mean_mm,
                    })
                })
                .collect(),
            probe_pose_error_mm: truth.and_then(|t| t.probe_pose_translation_error_mm.map(|p| p.0)),
            phantom_pose_error_mm: truth.and_then(|t| t.phantom_pose_translation_error_mm.map(|p| p.0)),
        };
        log(&format!(
            "{}: BRE mean {:.3}/{:.3}/{:.3} mm, kept {}, truth {}",
            result.variant,
            result.bre_mean_all_frames_mm[0],
            result.bre_mean_all_frames_mm[1],
            result.bre_mean_all_frames_mm[2],
            result
                .kept
                .iter()
                .map(|k| k.frames.to_string())
                .collect::<Vec<_>>()
                .join("/"),
            result
                .truth
                .iter()
                .map(|t| format!("{} {:.3}", t.method, t.corner_error_mm))
                .collect::<Vec<_>>()
                .join(", ")
        ));
        results.push(result);
        if !keep {
            let folder = run.dataset_folder.clone();
            let _ = std::fs::remove_dir_all(&folder);
            let _ = std::fs::remove_file(run::claim_file(&folder));
        }
    }
    Ok(Ablation {
        experiment: manifest.experiment.clone(),
        seed: spec.seed,
        frames: spec.frames,
        realism,
        variants: results,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spec::realism::{Jpeg, SpeedOfSound};

    #[test]
    fn variants_toggle_one_source_at_a_time() {
        let rig = Realism {
            speed_of_sound: Some(SpeedOfSound {
                scanner_m_per_s: 1540.0,
                medium_m_per_s: 1482.0,
            }),
            jpeg: Some(Jpeg { quality: 90 }),
            ..Realism::default()
        };
        let v = variants(&rig);
        let names: Vec<&str> = v.iter().map(|v| v.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "all sources",
                "ideal",
                "without speed_of_sound",
                "without jpeg",
                "only speed_of_sound",
                "only jpeg"
            ]
        );
        assert_eq!(v[0].realism.present(), ["speed_of_sound", "jpeg"]);
        assert!(v[1].realism.present().is_empty());
        assert_eq!(v[2].realism.present(), ["jpeg"]);
        assert_eq!(v[4].realism.present(), ["speed_of_sound"]);
        assert_eq!(v[5].realism.jpeg, rig.jpeg);
    }
}
