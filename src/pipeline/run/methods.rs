//! Beside the reported calibration: the thesis's one-shot procedure, RANSAC and
//! LMedS over frames, Levenberg–Marquardt with the pixel size, the sphere fit;
//! and the resampling metrics (leave-one-out, half-splits, bootstrap) of the
//! reported calibration's frames. Each returns its parameters and numbers.

use nalgebra::Point3;

use crate::core::geometry::Calibration;
use crate::core::geometry::Rigid;
use crate::estimate::correspondence::{self, Correspondence};
use crate::estimate::horn::HornError;
use crate::estimate::image_to_probe::{self, Constraint};
use crate::estimate::robust::{self, RobustMethod, RobustSettings};
use crate::estimate::sphere_fit::{self, ArcFrame, SphereSettings};
use crate::evaluate::resampling::{self, FitInputs};
use crate::evaluate::{CutoffRule, ThresholdRow};
use crate::manifest::Manifest;
use crate::pipeline::record::{FrameRecord, Method, MethodResult, ResamplingSummary};

/// Leave-one-out PRE, CR over half-splits and bootstrap intervals of the frames
/// of the reported calibration.
pub fn resampling_stage(
    manifest: &Manifest,
    frames: &[Correspondence],
    primary: &ThresholdRow,
    inputs: &FitInputs<'_>,
) -> Result<ResamplingSummary, HornError> {
    let full = primary.fit.clone()?;
    let v = &manifest.validation;
    Ok(ResamplingSummary {
        leave_one_out: resampling::leave_one_out(frames, inputs)?,
        reproducibility: resampling::reproducibility(frames, inputs, v.cr_half_splits, v.seed)?,
        bootstrap: resampling::bootstrap(frames, &full, inputs, v.bootstrap_resamples, v.seed)?,
    })
}

/// The frames (their numbers) an estimator did not keep.
fn left_out(frames: &[Correspondence], kept: impl Fn(&Correspondence) -> bool) -> Vec<usize> {
    frames.iter().filter(|f| !kept(f)).map(|f| f.frame).collect()
}

/// The frames outside a robust estimator's consensus (`inliers` runs along `frames`).
fn outside_consensus(frames: &[Correspondence], inliers: &[bool]) -> Vec<usize> {
    frames
        .iter()
        .zip(inliers)
        .filter(|(_, k)| !**k)
        .map(|(f, _)| f.frame)
        .collect()
}

/// What the estimators share: the frames, the reported calibration's row and the
/// phantom's point feature (with the sphere's radius for a hemisphere).
pub struct MethodInputs<'a> {
    pub records: &'a [FrameRecord],
    pub frames: &'a [Correspondence],
    pub reported: &'a ThresholdRow,
    pub fit: &'a FitInputs<'a>,
    pub feature_in_phantom_mm: [f64; 3],
    pub sphere_radius_mm: Option<f64>,
}

impl MethodInputs<'_> {
    /// An estimator's result on these frames (scored against the truth, when
    /// there is one, after every estimate is made).
    fn result(
        &self,
        method: Method,
        frames_used: usize,
        frames_left_out: Vec<usize>,
        m: &Rigid,
        s: [f64; 2],
    ) -> MethodResult {
        MethodResult {
            method,
            frames_used,
            frames_left_out,
            marker_T_image: *m,
            spacing_mm_per_px: s,
            truth: None,
        }
    }
}

/// Every estimator on the same frames, the reported one first.
pub fn methods_stage(manifest: &Manifest, inputs: &MethodInputs<'_>, log: &mut dyn FnMut(&str)) -> Vec<MethodResult> {
    let MethodInputs { frames, reported, .. } = *inputs;
    let spacing = inputs.fit.spacing;
    let mut out = Vec::new();
    if let Ok(fit) = &reported.fit {
        out.push(inputs.result(
            Method::CutoffWorstFirst {
                cutoff_mm: reported.cutoff_mm,
            },
            reported.frames.len(),
            left_out(frames, |f| reported.frames.contains(&f.frame)),
            &fit.target_T_source,
            spacing,
        ));
    }
    out.extend(thesis_one_shot(manifest, inputs));
    let (robust, ransac) = robust_methods(manifest, inputs, log);
    out.extend(robust);
    let Some(ransac) = ransac else { return out };
    let ransac_left_out = outside_consensus(frames, &ransac.inliers);
    let inliers: Vec<&Correspondence> = frames
        .iter()
        .zip(&ransac.inliers)
        .filter(|(_, k)| **k)
        .map(|(f, _)| f)
        .collect();
    // Levenberg–Marquardt with the pixel size as two more unknowns.
    let constraints: Vec<Constraint> = inliers.iter().flat_map(|f| f.constraints()).collect();
    let start = Calibration::new(ransac.fit.target_T_source, spacing);
    let settings = image_to_probe::RefineSettings {
        pixel_model: image_to_probe::PixelModel::Anisotropic,
        reject_sd: None,
        refine_phantom: false,
    };
    match image_to_probe::refine(&start, &constraints, &settings) {
        Ok(fit) => {
            let m = &fit.image_to_probe;
            out.push(inputs.result(
                Method::RansacLmScales,
                inliers.len(),
                ransac_left_out.clone(),
                &m.marker_T_image,
                m.spacing_mm_per_px,
            ));
        }
        Err(e) => log(&format!("LM with pixel scales: {e}")),
    }
    if let Some(radius_mm) = inputs.sphere_radius_mm {
        let fitted = ransac_sphere_fit(manifest, inputs, &ransac, &inliers, radius_mm);
        match fitted {
            Ok((method, arcs, fit)) => {
                out.push(inputs.result(method, arcs, ransac_left_out, &fit.marker_T_image, spacing))
            }
            Err(e) => log(&format!("sphere fit: {e}")),
        }
    }
    out
}

/// The thesis's own procedure: one Horn fit on all frames, every frame whose BRE
/// under it exceeds the cut-off dropped at once, Horn again.
fn thesis_one_shot(manifest: &Manifest, inputs: &MethodInputs<'_>) -> Option<MethodResult> {
    let MethodInputs { frames, reported, .. } = *inputs;
    let (spacing, variant) = (inputs.fit.spacing, inputs.fit.variant);
    if !reported.cutoff_mm.is_finite() {
        return None;
    }
    let all = correspondence::solve(frames, spacing, variant, None).ok()?;
    let kept: Vec<Correspondence> = frames
        .iter()
        .filter(|f| {
            let (axes, norm) = correspondence::bre(f, &all, spacing);
            let value = manifest.thresholds.cutoff_rule.measure(&axes, norm);
            CutoffRule::below(value, reported.cutoff_mm)
        })
        .cloned()
        .collect();
    let fit = correspondence::solve(&kept, spacing, variant, None).ok()?;
    Some(inputs.result(
        Method::ThesisOneShot {
            cutoff_mm: reported.cutoff_mm,
        },
        kept.len(),
        left_out(frames, |f| kept.iter().any(|c| c.frame == f.frame)),
        &fit.target_T_source,
        spacing,
    ))
}

/// RANSAC and LMedS on the frames; RANSAC's fit is kept for the methods that start from it.
fn robust_methods(
    manifest: &Manifest,
    inputs: &MethodInputs<'_>,
    log: &mut dyn FnMut(&str),
) -> (Vec<MethodResult>, Option<robust::RobustFit>) {
    let frames = inputs.frames;
    let (spacing, variant) = (inputs.fit.spacing, inputs.fit.variant);
    let mut out = Vec::new();
    let mut ransac = None;
    for method in [RobustMethod::Ransac, RobustMethod::Lmeds] {
        let settings = RobustSettings {
            method,
            ..manifest.robust
        };
        match robust::solve(frames, spacing, variant, &settings) {
            Ok(r) => {
                let used = r.inliers.iter().filter(|k| **k).count();
                let named = match method {
                    RobustMethod::Ransac => Method::Ransac {
                        threshold_mm: r.threshold_mm,
                        noise_sd_mm: settings.threshold_mm.is_none().then_some(settings.noise_sd_mm),
                    },
                    RobustMethod::Lmeds => Method::Lmeds {
                        threshold_mm: r.threshold_mm,
                    },
                };
                out.push(inputs.result(
                    named,
                    used,
                    outside_consensus(frames, &r.inliers),
                    &r.fit.target_T_source,
                    spacing,
                ));
                if method == RobustMethod::Ransac {
                    ransac = Some(r);
                }
            }
            Err(e) => log(&format!("{method:?}: {e}")),
        }
    }
    (out, ransac)
}

/// The sphere fit of RANSAC's inliers' arcs from RANSAC's calibration (its
/// elevation prior from the data when the manifest says so): the method, the
/// arcs used and the fit.
fn ransac_sphere_fit(
    manifest: &Manifest,
    inputs: &MethodInputs<'_>,
    ransac: &robust::RobustFit,
    inliers: &[&Correspondence],
    radius_mm: f64,
) -> Result<(Method, usize, sphere_fit::SphereFit), sphere_fit::SphereFitError> {
    let arcs: Vec<ArcFrame> = inliers
        .iter()
        .filter_map(|c| {
            let record = inputs.records.iter().find(|r| r.files.frame == c.frame)?;
            Some(ArcFrame {
                frame: c.frame,
                sphere: 0,
                edge_px: record.arc.as_ref()?.arc_points_px.clone(),
                camera_T_marker: c.camera_T_marker,
                camera_T_phantom: c.camera_T_phantom,
            })
        })
        .collect();
    let mut settings = SphereSettings {
        spheres: vec![sphere_fit::KnownSphere {
            centre_in_phantom_mm: Point3::from(nalgebra::Vector3::from(inputs.feature_in_phantom_mm)),
            radius_mm,
        }],
        spacing_mm_per_px: inputs.fit.spacing,
        elevation_prior_sd_mm: manifest.sphere_fit.elevation_prior_sd_mm,
        fit_radius_offset: manifest.sphere_fit.fit_radius_offset,
        points_per_frame: 20.0,
        fit_pixel_size: false,
    };
    let mut fitted = sphere_fit::refine(&ransac.fit.target_T_source, &arcs, &settings);
    if manifest.sphere_fit.elevation_prior_from_data {
        // The planes' spread from the data: the fitted elevations' RMS.
        if let Ok(first) = &fitted {
            let n = first.elevation_mm.len().max(1) as f64;
            let rms = (first.elevation_mm.iter().map(|(_, d)| d * d).sum::<f64>() / n).sqrt();
            if rms.is_finite() && rms > 0.0 {
                settings.elevation_prior_sd_mm = Some(rms);
                fitted = sphere_fit::refine(&ransac.fit.target_T_source, &arcs, &settings);
            }
        }
    }
    let fit = fitted?;
    let method = Method::RansacSphereFit {
        elevation_prior_sd_mm: settings.elevation_prior_sd_mm,
        edge_offset_mm: fit.radius_offset_mm,
    };
    Ok((method, arcs.len(), fit))
}

/// The arcs of the reported calibration's frames, each on the sphere its label names.
fn sphere_arcs(inputs: &MethodInputs<'_>, spheres: &[crate::spec::phantom::Sphere]) -> Vec<ArcFrame> {
    let reported = inputs.reported;
    inputs
        .frames
        .iter()
        .filter(|c| reported.frames.contains(&c.frame))
        .filter_map(|c| {
            let record = inputs.records.iter().find(|r| r.files.frame == c.frame)?;
            Some(
                record
                    .wire_labels
                    .iter()
                    .zip(&record.arcs)
                    .filter_map(|(name, arc)| {
                        Some(ArcFrame {
                            frame: c.frame,
                            sphere: spheres.iter().position(|s| &s.name == name)?,
                            edge_px: arc.arc_points_px.clone(),
                            camera_T_marker: c.camera_T_marker,
                            camera_T_phantom: c.camera_T_phantom,
                        })
                    })
                    .collect::<Vec<_>>(),
            )
        })
        .flatten()
        .collect()
}

/// Multi-sphere phantoms: the reported calibration, and the sphere fit of the
/// arcs of its frames, each arc on its own sphere (paired in stage 4).
pub fn spheres_methods(
    inputs: &MethodInputs<'_>,
    spheres: &[crate::spec::phantom::Sphere],
    fit_pixel_size: bool,
    pose: Option<&crate::pipeline::run::sphere_pose::PoseInputs<'_>>,
    log: &mut dyn FnMut(&str),
) -> Vec<MethodResult> {
    let spacing = inputs.fit.spacing;
    let reported = inputs.reported;
    let Ok(fit) = &reported.fit else {
        return Vec::new();
    };
    let mut out = vec![inputs.result(
        Method::CutoffWorstFirst {
            cutoff_mm: reported.cutoff_mm,
        },
        reported.frames.len(),
        left_out(inputs.frames, |f| reported.frames.contains(&f.frame)),
        &fit.target_T_source,
        spacing,
    )];
    let arcs = sphere_arcs(inputs, spheres);
    let settings = SphereSettings {
        spheres: spheres
            .iter()
            .map(|s| sphere_fit::KnownSphere {
                centre_in_phantom_mm: Point3::from(s.centre_in_phantom_mm),
                radius_mm: s.radius_mm,
            })
            .collect(),
        spacing_mm_per_px: spacing,
        elevation_prior_sd_mm: None,
        fit_radius_offset: false,
        points_per_frame: 20.0,
        fit_pixel_size,
    };
    let first = match sphere_fit::refine(&fit.target_T_source, &arcs, &settings) {
        Ok(first) => first,
        Err(e) => {
            log(&format!("sphere fit: {e}"));
            return out;
        }
    };
    // A frame whose edge points sit far off their spheres (the probe moved between
    // photo and B-scan, an echo beside the dome) is left out and the fit repeated.
    let limit = outlier_limit(&first.frame_rms_mm);
    let kept: Vec<ArcFrame> = arcs
        .iter()
        .filter(|a| first.frame_rms_mm.iter().any(|(k, rms)| *k == a.frame && *rms <= limit))
        .cloned()
        .collect();
    let frames_kept = first.frame_rms_mm.iter().filter(|(_, rms)| *rms <= limit).count();
    let kept_left_out = left_out(inputs.frames, |f| {
        reported.frames.contains(&f.frame) && kept.iter().any(|a| a.frame == f.frame)
    });
    let sphere = match sphere_fit::refine(&first.marker_T_image, &kept, &settings) {
        Ok(sphere) => sphere,
        Err(e) => {
            log(&format!("sphere fit: {e}"));
            return out;
        }
    };
    out.push(inputs.result(
        Method::SphereFit {
            arcs: kept.len(),
            rms_mm: sphere.rms_mm,
            rms_limit_mm: limit,
            pixel_size_fitted: fit_pixel_size,
        },
        frames_kept,
        kept_left_out.clone(),
        &sphere.marker_T_image,
        sphere.spacing_mm_per_px,
    ));
    if let Some(pose) = pose {
        // The pose-prior fit maps pixels with the sphere fit's pixel size.
        let settings = SphereSettings {
            spacing_mm_per_px: sphere.spacing_mm_per_px,
            fit_pixel_size: false,
            ..settings
        };
        match crate::pipeline::run::sphere_pose::fit(&sphere.marker_T_image, &kept, inputs.records, &settings, pose) {
            Ok((posed, noise)) => out.push(inputs.result(
                Method::SphereFitPosePrior {
                    arcs: kept.len(),
                    rms_mm: posed.rms_mm,
                    noise,
                    pixel_size_fitted: fit_pixel_size,
                },
                frames_kept,
                kept_left_out,
                &posed.marker_T_image,
                posed.spacing_mm_per_px,
            )),
            Err(e) => log(&format!("sphere fit with pose priors: {e}")),
        }
    }
    out
}

/// The frame RMS above which a frame is an outlier of the sphere fit: the
/// median plus three robust standard deviations (1.4826 MAD).
fn outlier_limit(frame_rms_mm: &[(usize, f64)]) -> f64 {
    let mut values: Vec<f64> = frame_rms_mm.iter().map(|(_, r)| *r).collect();
    let median = crate::core::stats::median(&mut values);
    let mut deviations: Vec<f64> = values.iter().map(|v| (v - median).abs()).collect();
    median + 3.0 * 1.4826 * crate::core::stats::median(&mut deviations)
}
