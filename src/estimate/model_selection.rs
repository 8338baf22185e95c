//! Choosing an N-wire calibration's model on the calibration frames alone.
//!
//! PLUS's model family is offered: the constraints the dots give (each N's
//! middle dot only, or every dot on its wire) times the pixel grid's map
//! (isotropic, anisotropic, affine). Each candidate is scored by K-fold
//! cross-validation over contiguous blocks of calibration frames (neighbouring
//! frames are alike, so a random split would leak): fit on K − 1 blocks, measure
//! the held-out frames' PRE3D (the middle dots' 3D error, PLUS's figure), pool
//! the held-out errors and take PLUS's best-95 % mean. The one-standard-error
//! rule chooses: the simplest candidate (listed first) whose score is within one
//! standard error of the lowest score, so that an unknown which buys less than
//! the noise is not fitted. The validation sequence never enters.

use serde::Serialize;

use crate::core::geometry::Calibration;
use crate::core::stats::{best_95, MeanSd};
use crate::estimate::image_to_probe::{self, Constraint, ConstraintModel, Fit, FitError, PixelModel, RefineSettings};

/// One calibration frame's constraints: each N's middle dot on its point, and
/// (for the wire model) each dot on its wire.
#[derive(Debug, Clone, Default)]
pub struct FrameConstraints {
    pub points: Vec<Constraint>,
    pub lines: Vec<Constraint>,
}

/// A model of the family.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct Candidate {
    pub constraints: ConstraintModel,
    pub pixel_model: PixelModel,
}

impl Candidate {
    /// Every candidate, simplest first; a setting the manifest fixes is kept.
    pub fn family(constraints: Option<ConstraintModel>, pixel_model: Option<PixelModel>) -> Vec<Candidate> {
        let constraint_models = match constraints {
            Some(c) => vec![c],
            None => vec![ConstraintModel::MiddlePoints, ConstraintModel::Wires],
        };
        let pixel_models = match pixel_model {
            Some(p) => vec![p],
            None => PixelModel::ALL.to_vec(),
        };
        let mut out = Vec::new();
        for &pixel_model in &pixel_models {
            for &constraints in &constraint_models {
                out.push(Candidate {
                    constraints,
                    pixel_model,
                });
            }
        }
        out
    }

    /// The constraints this candidate fits on.
    fn constraints_of<'a>(&self, frames: impl Iterator<Item = &'a FrameConstraints>) -> Vec<Constraint> {
        frames
            .flat_map(|f| {
                let lines: &[Constraint] = match self.constraints {
                    ConstraintModel::MiddlePoints => &[],
                    ConstraintModel::Wires => &f.lines,
                };
                f.points.iter().chain(lines).copied()
            })
            .collect()
    }
}

/// How a fit drops outliers and what else it corrects.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitSettings {
    pub reject_sd: Option<f64>,
    pub refine_phantom: bool,
}

/// A fit and its closed-form start.
#[derive(Debug, Clone)]
pub struct CandidateFit {
    pub closed_form: Calibration,
    pub fit: Fit,
    /// Constraints fitted (before outlier rejection).
    pub constraints: usize,
}

/// Fits `candidate` on `frames`: the closed-form start on the middle dots, then
/// the refinement of the candidate's unknowns.
pub fn fit<'a>(
    frames: impl Iterator<Item = &'a FrameConstraints> + Clone,
    candidate: Candidate,
    settings: FitSettings,
) -> Result<CandidateFit, FitError> {
    let points: Vec<Constraint> = frames.clone().flat_map(|f| f.points.iter().copied()).collect();
    let closed_form = image_to_probe::closed_form(&points)?;
    let all = candidate.constraints_of(frames);
    let refine = RefineSettings {
        pixel_model: candidate.pixel_model,
        reject_sd: settings.reject_sd,
        refine_phantom: settings.refine_phantom,
    };
    let fit = image_to_probe::refine(&closed_form, &all, &refine)?;
    Ok(CandidateFit {
        closed_form,
        fit,
        constraints: all.len(),
    })
}

/// A candidate's cross-validated PRE3D, or why it could not be had.
#[derive(Debug, Clone, Serialize)]
pub struct Scored {
    pub candidate: Candidate,
    /// Held-out middle dots' PRE3D, PLUS's best-95 % mean and SD, mm.
    pub cv_pre3d_mm: Option<MeanSd>,
    /// Why a fold's fit failed (the candidate is then out).
    pub failure: Option<String>,
}

/// The candidates scored and the one chosen.
#[derive(Debug, Clone, Serialize)]
pub struct Selection {
    pub folds: usize,
    pub frames: usize,
    pub scored: Vec<Scored>,
    /// Index into `scored`.
    pub chosen: usize,
}

impl Selection {
    pub fn chosen(&self) -> Candidate {
        self.scored[self.chosen].candidate
    }
}

/// Frame `k` of `n` falls in this fold of `folds` contiguous blocks.
fn fold_of(k: usize, n: usize, folds: usize) -> usize {
    k * folds / n.max(1)
}

/// The held-out PRE3D of `candidate` over `folds` contiguous blocks of `frames`.
pub fn cross_validate(
    frames: &[FrameConstraints],
    candidate: Candidate,
    folds: usize,
    settings: FitSettings,
) -> Result<MeanSd, CrossValidationError> {
    let n = frames.len();
    if n < 2 * folds {
        return Err(CrossValidationError::TooFewFrames { frames: n, folds });
    }
    let mut held_out = Vec::new();
    for fold in 0..folds {
        let training = frames
            .iter()
            .enumerate()
            .filter(|(k, _)| fold_of(*k, n, folds) != fold)
            .map(|(_, f)| f);
        let trained = fit(training, candidate, settings)
            .map_err(|source| CrossValidationError::Fold { fold: fold + 1, source })?;
        for (_, frame) in frames.iter().enumerate().filter(|(k, _)| fold_of(*k, n, folds) == fold) {
            held_out.extend(frame.points.iter().map(|c| {
                c.residual_with(&trained.fit.image_to_probe, &trained.fit.phantom_correction)
                    .norm()
            }));
        }
    }
    best_95(&held_out).ok_or(CrossValidationError::NoHeldOutPoint)
}

/// Why a candidate could not be cross-validated.
#[derive(Debug, thiserror::Error)]
pub enum CrossValidationError {
    #[error("{frames} frames are too few for {folds} folds")]
    TooFewFrames { frames: usize, folds: usize },
    #[error("fold {fold}: {source}")]
    Fold { fold: usize, source: FitError },
    #[error("no held-out point")]
    NoHeldOutPoint,
}

/// Scores every candidate and chooses by the one-standard-error rule; `None`
/// when no candidate could be scored (each one's reason is in the scores).
pub fn select(
    frames: &[FrameConstraints],
    candidates: &[Candidate],
    folds: usize,
    settings: FitSettings,
) -> (Vec<Scored>, Option<usize>) {
    let scored: Vec<Scored> = candidates
        .iter()
        .map(|&candidate| match cross_validate(frames, candidate, folds, settings) {
            Ok(s) => Scored {
                candidate,
                cv_pre3d_mm: Some(s),
                failure: None,
            },
            Err(e) => Scored {
                candidate,
                cv_pre3d_mm: None,
                failure: Some(e.to_string()),
            },
        })
        .collect();
    let finite = |s: &Scored| s.cv_pre3d_mm.filter(|m| m.mean.is_finite() && m.std.is_finite());
    let best = scored
        .iter()
        .filter_map(finite)
        .min_by(|a, b| a.mean.total_cmp(&b.mean));
    let chosen = best.and_then(|b| {
        let within = b.mean + b.std / (b.n.max(1) as f64).sqrt();
        scored.iter().position(|s| finite(s).is_some_and(|m| m.mean <= within))
    });
    (scored, chosen)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::geometry::rigid_from_axis_angle;
    use crate::core::rng::Rng;
    use crate::estimate::image_to_probe::Target;
    use nalgebra::{Matrix4, Vector3};

    /// Frames of middle-dot points from a sheared pixel grid (or not).
    fn frames(shear: f64, seed: u64) -> Vec<FrameConstraints> {
        let truth = Calibration {
            marker_T_image: rigid_from_axis_angle(Vector3::new(0.3, -1.4, 0.2), Vector3::new(11.0, 48.0, -0.4)),
            spacing_mm_per_px: [0.0803, 0.0745],
            shear_mm_per_px: shear,
        };
        let mut rng = Rng::new(seed);
        (0..60)
            .map(|_| FrameConstraints {
                points: (0..3)
                    .map(|_| {
                        let pixel = [rng.uniform(100.0, 700.0), rng.uniform(100.0, 550.0)];
                        let noise = Vector3::new(rng.normal(0.0, 0.1), rng.normal(0.0, 0.1), rng.normal(0.0, 0.1));
                        Constraint {
                            pixel,
                            elevation_mm: 0.0,
                            marker_T_phantom: Matrix4::identity(),
                            target_in_phantom: Target::Point(truth.apply(pixel) + noise),
                        }
                    })
                    .collect(),
                lines: Vec::new(),
            })
            .collect()
    }

    const SETTINGS: FitSettings = FitSettings {
        reject_sd: Some(3.0),
        refine_phantom: false,
    };

    #[test]
    fn cross_validation_finds_a_shear_and_prefers_the_simpler_model_without_one() {
        let family = Candidate::family(Some(ConstraintModel::MiddlePoints), None);
        assert_eq!(family.len(), 3);
        let (scored, chosen) = select(&frames(0.004, 3), &family, 5, SETTINGS);
        assert_eq!(
            scored[chosen.unwrap()].candidate.pixel_model,
            PixelModel::Affine,
            "{scored:?}"
        );
        // Without a shear and with anisotropic pixels, the isotropic model is
        // clearly worse; the affine one's extra unknown buys less than the noise.
        let (scored, chosen) = select(&frames(0.0, 4), &family, 5, SETTINGS);
        let mean = |k: usize| scored[k].cv_pre3d_mm.unwrap().mean;
        assert!(mean(0) > mean(1) + 0.05, "{scored:?}");
        assert_eq!(chosen, Some(1), "{scored:?}");
    }

    #[test]
    fn too_few_frames_for_the_folds_is_a_failure_not_a_score() {
        let few: Vec<FrameConstraints> = frames(0.0, 5).into_iter().take(7).collect();
        let family = Candidate::family(Some(ConstraintModel::MiddlePoints), Some(PixelModel::Anisotropic));
        let (scored, chosen) = select(&few, &family, 5, SETTINGS);
        assert_eq!(chosen, None);
        assert_eq!(scored[0].failure.as_deref(), Some("7 frames are too few for 5 folds"));
    }

    #[test]
    fn folds_are_contiguous_blocks_covering_every_frame() {
        let n = 23;
        let of: Vec<usize> = (0..n).map(|k| fold_of(k, n, 5)).collect();
        assert!(of.windows(2).all(|w| w[1] == w[0] || w[1] == w[0] + 1));
        assert_eq!((of[0], of[n - 1]), (0, 4));
    }
}
