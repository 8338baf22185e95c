//! Stage 4: the frames' point pairs (or wire dots paired with their wires) and
//! the all-frames calibration, with each frame's BRE under it.

use nalgebra::Point3;

use crate::core::geometry::Rigid;
use crate::estimate::correspondence::{self, Correspondence};
use crate::estimate::horn::HornFit;
use crate::estimate::sphere_fit::KnownSphere;
use crate::estimate::sphere_matching::{self, FrameArcs, NamedSphere, SeenArc};
use crate::estimate::start_basin::{self, StartGuess};
use crate::estimate::wire_matching::{self, FrameWireDots, WireAxis};
use crate::evaluate::{self, EvaluationInputs, ThresholdRow};
use crate::pipeline::error::RunError;
use crate::pipeline::frames::Targets;
pub use crate::pipeline::record::SolveSettings;
use crate::pipeline::record::{FrameRecord, Rejection};
use crate::spec::phantom::Sphere;

/// The basin's random starts: fixed, so a run is reproducible.
const BASIN_SEED: u64 = 17;

/// A frame that passed every stage and has poses and a feature.
fn usable(f: &FrameRecord) -> bool {
    f.rejection.is_none() && f.pose_pair().is_some() && !f.features_px.is_empty()
}

/// What pairing the frames needs besides the frames.
pub struct PairingInputs<'a> {
    pub dataset: &'a str,
    pub spacing_mm_per_px: [f64; 2],
    /// The rough `marker_T_image` wire dots are paired from.
    pub initial_marker_T_image: Option<Rigid>,
    pub min_frames: usize,
    /// Multi-sphere phantoms: the pairing's sphere fit also estimates the pixel size.
    pub fit_pixel_size: bool,
}

/// The usable frames' measurements. Point phantoms: one pair per frame. Wire
/// phantoms: dots paired with their wires (frames left unpaired are rejected
/// with the reason, and the paired dots and their wires kept on the record),
/// and the start guess's basin of convergence on these frames.
pub fn point_pairs(
    frames: &mut [FrameRecord],
    targets: Targets<'_>,
    inputs: &PairingInputs<'_>,
    log: &mut dyn FnMut(&str),
) -> Result<(Vec<Correspondence>, Option<StartGuess>), RunError> {
    match targets {
        Targets::Point(feature) => Ok((
            frames
                .iter()
                .filter(|f| usable(f))
                .filter_map(|f| {
                    let (camera_T_marker, camera_T_phantom) = f.pose_pair()?;
                    Some(Correspondence::point(
                        f.files.frame,
                        f.features_px[0],
                        Point3::from(nalgebra::Vector3::from(feature)),
                        camera_T_marker,
                        camera_T_phantom,
                    ))
                })
                .collect(),
            None,
        )),
        Targets::Spheres(spheres) => Ok((spheres_pairs(frames, spheres, inputs, log)?, None)),
        Targets::Wires(wires) => {
            let axes: Vec<WireAxis> = wires
                .iter()
                .map(|w| WireAxis {
                    name: w.name.clone(),
                    start_in_phantom_mm: Point3::from(w.start_in_phantom_mm),
                    end_in_phantom_mm: Point3::from(w.end_in_phantom_mm),
                })
                .collect();
            let dots: Vec<FrameWireDots> = frames
                .iter()
                .filter(|f| usable(f))
                .filter_map(|f| {
                    let (camera_T_marker, camera_T_phantom) = f.pose_pair()?;
                    Some(FrameWireDots {
                        frame: f.files.frame,
                        dots_px: f.features_px.clone(),
                        camera_T_marker,
                        camera_T_phantom,
                    })
                })
                .collect();
            let start = inputs.initial_marker_T_image.ok_or_else(|| {
                RunError::Unsupported("the four_wire phantom needs solve.initial_marker_T_image".into())
            })?;
            let matching =
                wire_matching::match_and_solve(&dots, &axes, &start, inputs.spacing_mm_per_px, inputs.min_frames)
                    .map_err(|source| RunError::Solve {
                        dataset: inputs.dataset.to_string(),
                        source,
                    })?;
            log(&format!(
                "wires: {} frames paired in {} rounds, {} left out",
                matching.correspondences.len(),
                matching.rounds,
                matching.rejected.len()
            ));
            for f in frames.iter_mut() {
                if let Some((_, reason)) = matching.rejected.iter().find(|(k, _)| *k == f.files.frame) {
                    f.rejection = Some(Rejection::Wires(reason.clone()));
                }
                if let Some((_, labels)) = matching.labels.iter().find(|(k, _)| *k == f.files.frame) {
                    f.wire_labels = labels.clone();
                }
                if let Some(c) = matching.correspondences.iter().find(|c| c.frame == f.files.frame) {
                    f.features_px = c.features.iter().map(|o| o.pixel).collect();
                }
            }
            let start_guess = start_basin::measure(
                &dots,
                &axes,
                &start,
                &matching.fit.target_T_source,
                inputs.spacing_mm_per_px,
                inputs.min_frames,
                BASIN_SEED,
            );
            Ok((matching.correspondences, Some(start_guess)))
        }
    }
}

/// Multi-sphere phantoms: arcs paired with their spheres (frames left unpaired
/// are rejected with the reason); each record keeps its paired arcs first, in
/// the order of its features, and their spheres' names.
fn spheres_pairs(
    frames: &mut [FrameRecord],
    spheres: &[Sphere],
    inputs: &PairingInputs<'_>,
    log: &mut dyn FnMut(&str),
) -> Result<Vec<Correspondence>, RunError> {
    let named: Vec<NamedSphere> = spheres
        .iter()
        .map(|s| NamedSphere {
            name: s.name.clone(),
            sphere: KnownSphere {
                centre_in_phantom_mm: Point3::from(s.centre_in_phantom_mm),
                radius_mm: s.radius_mm,
            },
        })
        .collect();
    let seen: Vec<FrameArcs> = frames
        .iter()
        .filter(|f| usable(f))
        .filter_map(|f| {
            let (camera_T_marker, camera_T_phantom) = f.pose_pair()?;
            Some(FrameArcs {
                frame: f.files.frame,
                arcs: f
                    .arcs
                    .iter()
                    .map(|a| SeenArc {
                        centre_px: a.centre_px,
                        radius_mm: a.radius_mm,
                        edge_px: a.arc_points_px.clone(),
                    })
                    .collect(),
                camera_T_marker,
                camera_T_phantom,
            })
        })
        .collect();
    let start = inputs
        .initial_marker_T_image
        .ok_or_else(|| RunError::Unsupported("the spheres phantom needs solve.initial_marker_T_image".into()))?;
    let matching = sphere_matching::match_and_solve(
        &seen,
        &named,
        &start,
        inputs.spacing_mm_per_px,
        inputs.fit_pixel_size,
        inputs.min_frames,
    )
    .map_err(|e| RunError::Solve {
        dataset: inputs.dataset.to_string(),
        source: crate::estimate::horn::HornError::Refinement(e.to_string()),
    })?;
    let arcs_used: usize = matching.labels.iter().map(|(_, l)| l.len()).sum();
    log(&format!(
        "spheres: {} arcs of {} frames paired in {} rounds, {} frames left out; sphere fit RMS {:.3} mm",
        arcs_used,
        matching.correspondences.len(),
        matching.rounds,
        matching.rejected.len(),
        matching.fit.rms_mm
    ));
    for f in frames.iter_mut() {
        if let Some((_, reason)) = matching.rejected.iter().find(|(k, _)| *k == f.files.frame) {
            f.rejection = Some(Rejection::Spheres(reason.clone()));
        }
        if let Some((_, labels)) = matching.labels.iter().find(|(k, _)| *k == f.files.frame) {
            let mut ordered: Vec<_> = labels.iter().map(|(_, j)| f.arcs[*j].clone()).collect();
            ordered.extend(
                f.arcs
                    .iter()
                    .enumerate()
                    .filter(|(j, _)| labels.iter().all(|(_, used)| used != j))
                    .map(|(_, a)| a.clone()),
            );
            f.features_px = ordered[..labels.len()].iter().map(|a| a.centre_px).collect();
            f.arc = ordered.first().cloned();
            f.arcs = ordered;
            f.wire_labels = labels.iter().map(|(name, _)| name.clone()).collect();
        }
    }
    Ok(matching.correspondences)
}

/// Refuses a dataset with fewer usable frames than the manifest asks for,
/// listing every rejection.
pub fn enough_frames(
    frames: &[FrameRecord],
    pairs: &[Correspondence],
    min_frames: usize,
    dataset: &str,
) -> Result<(), RunError> {
    if pairs.len() >= min_frames {
        return Ok(());
    }
    let reasons = frames
        .iter()
        .filter_map(|f| {
            f.rejection
                .as_ref()
                .map(|r| format!("  frame {}: {}: {r}", f.files.frame, r.stage().label()))
        })
        .collect::<Vec<_>>()
        .join("\n");
    Err(RunError::TooFewFrames {
        dataset: dataset.to_string(),
        used: pairs.len(),
        total: frames.len(),
        needed: min_frames,
        reasons,
    })
}

/// The calibrations of a dataset: on all frames, and at each cut-off.
#[derive(Debug)]
pub struct Calibrations {
    pub all_frames_fit: HornFit,
    /// Where line fits start at the cut-offs (the all-frames fit, for wires).
    pub start: Option<Rigid>,
    pub thresholds: Vec<ThresholdRow>,
    /// Index into `thresholds` of the calibration that is the result.
    pub primary: usize,
}

impl Calibrations {
    /// The reported calibration (the all-frames fit if its cut-off left too few frames).
    pub fn reported(&self) -> &HornFit {
        match &self.thresholds[self.primary].fit {
            Ok(fit) => fit,
            Err(_) => &self.all_frames_fit,
        }
    }
}

/// Solves `pairs` on all frames, then at every cut-off (frames above it removed
/// worst first). The run and `probecal resolve` both solve through here.
pub fn calibrate(pairs: &[Correspondence], settings: &SolveSettings, dataset: &str) -> Result<Calibrations, RunError> {
    let spacing = settings.spacing_mm_per_px;
    let all_frames_fit = correspondence::solve(
        pairs,
        spacing,
        settings.variant,
        settings.initial_marker_T_image.as_ref(),
    )
    .map_err(|source| RunError::Solve {
        dataset: dataset.to_string(),
        source,
    })?;
    let start = settings.initial_marker_T_image.map(|_| all_frames_fit.target_T_source);
    let inputs = EvaluationInputs {
        start,
        spacing,
        cutoffs_mm: &settings.cutoffs_mm,
        rule: settings.rule,
        min_frames: settings.min_frames,
        variant: settings.variant,
    };
    let thresholds = evaluate::threshold_table(pairs, &inputs)?;
    let primary = thresholds
        .iter()
        .position(|r| r.cutoff_mm == settings.calibration_cutoff_mm)
        .unwrap_or(0);
    if let Err(e) = &thresholds[primary].fit {
        return Err(RunError::Cutoff {
            dataset: dataset.to_string(),
            cutoff: evaluate::cutoff_label(thresholds[primary].cutoff_mm),
            kept: thresholds[primary].frames.len(),
            source: e.clone(),
        });
    }
    Ok(Calibrations {
        all_frames_fit,
        start,
        thresholds,
        primary,
    })
}

/// Each frame's BRE under the all-frames calibration, kept on its record.
pub fn record_bre(frames: &mut [FrameRecord], pairs: &[Correspondence], fit: &HornFit, spacing: [f64; 2]) {
    for f in frames.iter_mut() {
        if let Some(c) = pairs.iter().find(|c| c.frame == f.files.frame) {
            f.bre_mm = Some(correspondence::bre(c, fit, spacing));
        }
    }
}
