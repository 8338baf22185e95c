//! Studies over many runs: the thesis's synthetic σ-table, and a Monte Carlo
//! accuracy study of every estimator against the truth and the Cramér–Rao bound.
//!
//! # σ-table protocol (the thesis's synthetic experiment)
//! A fixed point P in the phantom; per frame a random image point `p_k` (inside a
//! 100 x 80 mm image), a probe rotation tilted up to ±20° about X and Y with a
//! fixed rotation about Z, and the marker's translation chosen so that `p_k` lands
//! exactly on P (the thesis's eq. 6). Gaussian noise of SD σ (mm, each axis) is
//! added to the marker's translation, Horn's closed form is solved on the pairs,
//! and the residuals `|P − reconstruction|` per axis give the BRE table's Std
//! (pooled over x, y, z). 50 frames (Dataset 3's count), 200 repetitions, mean.
//!
//! # Monte Carlo and the Cramér–Rao bound
//! The default hemisphere experiment is rendered with many seeds; each estimator's
//! `marker_T_image` is compared with the truth at the image's four corners and
//! centre. The bound is that of the point-pair model the estimators assume:
//! `y_i = T x_i + e_i` (x_i the feature in the image, y_i the phantom feature in
//! the marker frame through the measured poses), `e_i ~ N(0, Σ)` independent per
//! frame, with Σ the covariance of the true residuals `y_i − T_true x_i` of the
//! frames the robust fit kept (measured per seed from the truth). The Fisher
//! information of the six pose parameters (a rotation vector applied on the left,
//! and the translation) is `F = Σ_i J_iᵀ Σ⁻¹ J_i` with `J_i = [−[T x_i]ₓ  I]`;
//! the bound on a probe point `q`'s mean squared error is `tr(J_q F⁻¹ J_qᵀ)`.

pub mod ablation;
pub mod shard;
use std::path::Path;

use nalgebra::{Matrix3, Matrix6, Point3, Vector3};
use serde::{Deserialize, Serialize};

use crate::core::geometry::{image_probe_points, pixel_to_image_mm, rigid_from_axis_angle, Rigid};
use crate::core::rng::Rng;
use crate::core::stats::{mean_sd, percentile};
use crate::estimate::correspondence::{self, Correspondence};
use crate::estimate::horn::Variant;
use crate::manifest::{Dataset, DatasetSource, Manifest};
use crate::pipeline::error::RunError;
use crate::pipeline::record::DatasetRun;
use crate::pipeline::run;

/// The thesis's published σ-table.
pub const THESIS_SIGMA_TABLE: [(f64, f64); 4] = [(0.0, 0.0), (0.5, 0.272), (1.0, 0.504), (2.0, 1.127)];

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SigmaRow {
    pub sigma_mm: f64,
    pub thesis_std_mm: f64,
    /// SD of the per-axis absolute residuals, pooled over x, y, z (mean over repetitions).
    pub std_per_axis_mm: f64,
    /// SD of the 3D residual distances (mean over repetitions).
    pub std_distance_mm: f64,
}

/// The σ-table by the protocol above.
pub fn sigma_table(frames: usize, repetitions: usize, seed: u64) -> Vec<SigmaRow> {
    let spacing = [1.0, 1.0];
    let point = Point3::new(120.0, 80.0, -30.0);
    let marker_T_image = rigid_from_axis_angle(Vector3::new(0.05, -0.02, 1.5), Vector3::new(-20.0, 160.0, 25.0));
    THESIS_SIGMA_TABLE
        .iter()
        .map(|&(sigma, thesis)| {
            let mut per_axis = Vec::new();
            let mut distance = Vec::new();
            for rep in 0..repetitions {
                let mut rng = Rng::fork(seed, rep as u64);
                let pairs: Vec<Correspondence> = (0..frames)
                    .map(|k| {
                        let px = [rng.uniform(0.0, 100.0), rng.uniform(0.0, 80.0)];
                        let tilt = Vector3::new(
                            rng.uniform(-20.0, 20.0).to_radians(),
                            rng.uniform(-20.0, 20.0).to_radians(),
                            0.3,
                        );
                        let phantom_R_image = rigid_from_axis_angle(tilt, Vector3::zeros()).rotation;
                        let t = point.coords - phantom_R_image * pixel_to_image_mm(px, spacing).coords;
                        let phantom_T_marker = Rigid::from_parts(t.into(), phantom_R_image) * marker_T_image.inverse();
                        let noise =
                            Vector3::new(rng.normal(0.0, sigma), rng.normal(0.0, sigma), rng.normal(0.0, sigma));
                        let measured = Rigid::from_parts(
                            (phantom_T_marker.translation.vector + noise).into(),
                            phantom_T_marker.rotation,
                        );
                        Correspondence::point(k, px, point, measured, Rigid::identity())
                    })
                    .collect();
                let Ok(fit) = correspondence::solve(&pairs, spacing, Variant::Rigid, None) else {
                    continue;
                };
                let mut axes = Vec::new();
                let mut norms = Vec::new();
                for f in &pairs {
                    let (a, n) = correspondence::bre(f, &fit, spacing);
                    axes.extend(a);
                    norms.push(n);
                }
                per_axis.push(mean_sd(&axes).std);
                distance.push(mean_sd(&norms).std);
            }
            SigmaRow {
                sigma_mm: sigma,
                thesis_std_mm: thesis,
                std_per_axis_mm: per_axis.iter().sum::<f64>() / per_axis.len().max(1) as f64,
                std_distance_mm: distance.iter().sum::<f64>() / distance.len().max(1) as f64,
            }
        })
        .collect()
}

/// One seed's outcome.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SeedResult {
    pub seed: u64,
    /// (method, RMS error over the corners and centre, mm).
    pub rms_error_mm: Vec<(String, f64)>,
    /// The bound on that RMS error, mm.
    pub crlb_rms_mm: Option<f64>,
    pub frames_used: usize,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MethodAccuracy {
    pub method: String,
    pub mean_mm: f64,
    pub p95_mm: f64,
    pub rms_mm: f64,
    /// Seeds where this method's error is below 0.95 times the reported
    /// method's (the first listed), and above 1.05 times it.
    #[serde(default)]
    pub better_than_reported_seeds: usize,
    #[serde(default)]
    pub worse_than_reported_seeds: usize,
    /// `rms_mm` over the RMS of the bound, over the seeds that have both.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rms_over_bound: Option<f64>,
    /// Its 90 % interval: how far another set of as many seeds could move it
    /// (a paired bootstrap over the seeds, [`crate::core::stats::rms_ratio_interval`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rms_over_bound_90: Option<[f64; 2]>,
}

/// The level of a study's bootstrap intervals.
pub const INTERVAL_LEVEL: f64 = 0.9;

/// A method's error is "better" ("worse") than the reported method's below
/// (above) these multiples of it.
pub const BETTER_BELOW: f64 = 0.95;
pub const WORSE_ABOVE: f64 = 1.05;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MonteCarlo {
    pub experiment: String,
    pub seeds: Vec<SeedResult>,
    pub methods: Vec<MethodAccuracy>,
    /// RMS over seeds of the per-seed bound, mm.
    pub crlb_rms_mm: f64,
    /// Which model the bound is of (left out of the file for point pairs).
    #[serde(default, skip_serializing_if = "BoundModel::is_point_pairs")]
    pub bound: BoundModel,
}

/// The model a study's Cramér–Rao bound is that of.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BoundModel {
    /// Point pairs with independent Gaussian residuals (see the module's doc).
    #[default]
    PointPairs,
    /// The sphere fit's calibration from every arc's edge points, each frame's
    /// pose and the camera's intrinsics as nuisances ([`crate::evaluate::sphere_bound`]).
    SphereFit,
}

impl BoundModel {
    pub fn is_point_pairs(&self) -> bool {
        *self == BoundModel::PointPairs
    }

    /// The bound a study of `manifest` reports.
    pub fn of(manifest: &Manifest) -> BoundModel {
        match manifest.phantom {
            crate::spec::phantom::Phantom::Spheres { .. } => BoundModel::SphereFit,
            _ => BoundModel::PointPairs,
        }
    }
}

fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

fn jacobian(point_in_marker: &Vector3<f64>) -> nalgebra::Matrix3x6<f64> {
    let mut j = nalgebra::Matrix3x6::zeros();
    j.fixed_view_mut::<3, 3>(0, 0).copy_from(&(-skew(point_in_marker)));
    j.fixed_view_mut::<3, 3>(0, 3).copy_from(&Matrix3::identity());
    j
}

/// The Cramér–Rao bound on the RMS error over `probes` (mm) for pairs `x_i` (image)
/// with residual covariance `sigma`, at the true transform.
pub fn crlb_rms(
    truth: &Rigid,
    points_in_image: &[Point3<f64>],
    sigma: &Matrix3<f64>,
    probes: &[Point3<f64>],
) -> Option<f64> {
    let info = sigma.try_inverse()?;
    let mut fisher = Matrix6::zeros();
    for x in points_in_image {
        let j = jacobian(&(truth * x).coords);
        fisher += j.transpose() * info * j;
    }
    let cov = fisher.try_inverse()?;
    let mean_trace = probes
        .iter()
        .map(|q| {
            let j = jacobian(&(truth * q).coords);
            (j * cov * j.transpose()).trace()
        })
        .sum::<f64>()
        / probes.len() as f64;
    Some(mean_trace.sqrt())
}

/// RMS distance over `probes` between two calibrations, mm.
fn rms_error(
    estimate: &Rigid,
    spacing: [f64; 2],
    truth: &crate::evaluate::TrueCalibration,
    true_spacing: [f64; 2],
) -> f64 {
    let est = image_probe_points(truth.image_size_px, spacing);
    let tru = truth.points_in_image_mm(true_spacing);
    let sum: f64 = est
        .iter()
        .zip(&tru)
        .map(|(e, t)| (estimate * e - truth.marker_T_image * t).norm_squared())
        .sum();
    (sum / 5.0).sqrt()
}

/// One seed: the bound from the truth residuals of the frames the robust fit kept.
fn seed_bound(run: &DatasetRun, truth: &Rigid, size: [usize; 2]) -> Option<f64> {
    let ransac = run.methods.iter().find(|m| m.method.name() == "ransac")?;
    let feature = Point3::from(Vector3::from(run.feature_in_phantom_mm?));
    let spacing = run.spacing_mm_per_px;
    // The frames RANSAC keeps are those near its calibration; rebuild their pairs.
    let mut xs = Vec::new();
    let mut residuals = Vec::new();
    for f in run.frames.iter().filter(|f| f.rejection.is_none()) {
        let (Some((camera_T_marker, camera_T_phantom)), Some(px)) = (f.pose_pair(), f.features_px.first()) else {
            continue;
        };
        let c = Correspondence::point(f.files.frame, *px, feature, camera_T_marker, camera_T_phantom);
        let x = pixel_to_image_mm(*px, spacing);
        let y = c.marker_T_phantom() * feature;
        let fit = crate::estimate::horn::HornFit {
            target_T_source: ransac.marker_T_image,
            scale: 1.0,
            rms_residual_mm: 0.0,
        };
        // Outliers (not part of the Gaussian model) are left out as RANSAC leaves them.
        if correspondence::bre(&c, &fit, spacing).1 > 2.0 {
            continue;
        }
        residuals.push(y - truth * x);
        xs.push(x);
    }
    if xs.len() < 6 {
        return None;
    }
    let n = residuals.len() as f64;
    let mean = residuals.iter().sum::<Vector3<f64>>() / n;
    let sigma = residuals
        .iter()
        .map(|r| (r - mean) * (r - mean).transpose())
        .sum::<Matrix3<f64>>()
        / (n - 1.0);
    crlb_rms(truth, &xs, &sigma, &image_probe_points(size, spacing))
}

/// Renders and runs the manifest's first dataset once per seed; rendered folders
/// are removed after each run unless `keep` is set.
pub fn monte_carlo(
    manifest: &Manifest,
    seeds: &[u64],
    datasets_root: &Path,
    keep: bool,
    log: &mut dyn FnMut(&str),
) -> Result<MonteCarlo, RunError> {
    let results = seed_results(manifest, seeds, datasets_root, keep, log)?;
    Ok(summarise(&manifest.experiment, BoundModel::of(manifest), results))
}

/// Each seed's outcome, in the order of `seeds` (what [`monte_carlo`] summarises;
/// a slice of the seeds can run on another machine, [`summarise`] joins them).
pub fn seed_results(
    manifest: &Manifest,
    seeds: &[u64],
    datasets_root: &Path,
    keep: bool,
    log: &mut dyn FnMut(&str),
) -> Result<Vec<SeedResult>, RunError> {
    let Some(DatasetSource::Render(spec)) = manifest.datasets.first().map(|d| &d.source) else {
        return Err(RunError::Unsupported(
            "the Monte Carlo study needs a manifest whose first dataset is rendered".into(),
        ));
    };
    let mut results = Vec::new();
    for &seed in seeds {
        let mut spec = spec.clone();
        spec.seed = seed;
        let dataset = Dataset {
            name: format!("mc{seed}"),
            source: DatasetSource::Render(spec.clone()),
        };
        let run = run::run_dataset(manifest, &dataset, datasets_root, &mut |_| {})?;
        let folder = run.dataset_folder.clone();
        let truth = crate::io::truth::GroundTruth::load(&folder)
            .map_err(|source| RunError::Truth {
                dataset: dataset.name.clone(),
                source,
            })?
            .ok_or_else(|| RunError::Unsupported("a rendered dataset without ground truth".into()))?;
        let size = truth.bscan_size_px;
        let rms_error_mm: Vec<(String, f64)> = run
            .methods
            .iter()
            .map(|m| {
                (
                    m.method.name().to_string(),
                    rms_error(
                        &m.marker_T_image,
                        m.spacing_mm_per_px,
                        &run::true_calibration(&truth),
                        run.spacing_mm_per_px,
                    ),
                )
            })
            .collect();
        // Dome phantoms fitted on their arcs' edges: the bound of that model over
        // this seed's sweep; point pairs: the bound from their residuals.
        let crlb = match BoundModel::of(manifest) {
            BoundModel::SphereFit => crate::pipeline::run::design::bound_of(manifest, &manifest.phantom, &spec)
                .ok()
                .map(|b| b.rms_mm),
            BoundModel::PointPairs => seed_bound(&run, &truth.marker_T_image, size),
        };
        log(&format!(
            "seed {seed}: {} | bound {}",
            rms_error_mm
                .iter()
                .map(|(m, e)| format!("{m} {e:.3}"))
                .collect::<Vec<_>>()
                .join(", "),
            crlb.map(|c| format!("{c:.3}")).unwrap_or_else(|| "—".into())
        ));
        results.push(SeedResult {
            seed,
            rms_error_mm,
            crlb_rms_mm: crlb,
            frames_used: run.used_frames(),
        });
        if !keep {
            // The seed's folder and its claim are this study's alone.
            let _ = std::fs::remove_dir_all(&folder);
            let _ = std::fs::remove_file(run::claim_file(&folder));
        }
    }
    Ok(results)
}

/// The study of the seeds' outcomes (in seed order): each method's mean, 95th
/// percentile and RMS error, its seeds better and worse than the reported
/// method's, and the bound.
pub fn summarise(experiment: &str, bound: BoundModel, results: Vec<SeedResult>) -> MonteCarlo {
    let names: Vec<String> = results
        .first()
        .map(|r| r.rms_error_mm.iter().map(|(m, _)| m.clone()).collect())
        .unwrap_or_default();
    let methods = names
        .iter()
        .map(|name| {
            let errors: Vec<f64> = results
                .iter()
                .filter_map(|r| r.rms_error_mm.iter().find(|(m, _)| m == name).map(|(_, e)| *e))
                .collect();
            let versus: Vec<(f64, f64)> = results
                .iter()
                .filter_map(|r| {
                    let of = |n: &str| r.rms_error_mm.iter().find(|(m, _)| m == n).map(|(_, e)| *e);
                    Some((of(name)?, of(names.first()?)?))
                })
                .collect();
            let against_bound: Vec<(f64, f64)> = results
                .iter()
                .filter_map(|r| {
                    let error = r.rms_error_mm.iter().find(|(m, _)| m == name)?.1;
                    Some((error, r.crlb_rms_mm?))
                })
                .collect();
            MethodAccuracy {
                method: name.clone(),
                rms_over_bound: crate::core::stats::rms_ratio(&against_bound),
                rms_over_bound_90: crate::core::stats::rms_ratio_interval(&against_bound, INTERVAL_LEVEL),
                better_than_reported_seeds: versus.iter().filter(|(e, r)| *e < BETTER_BELOW * r).count(),
                worse_than_reported_seeds: versus.iter().filter(|(e, r)| *e > WORSE_ABOVE * r).count(),
                mean_mm: errors.iter().sum::<f64>() / errors.len().max(1) as f64,
                p95_mm: if errors.is_empty() {
                    f64::NAN
                } else {
                    percentile(&errors, 0.95)
                },
                rms_mm: (errors.iter().map(|e| e * e).sum::<f64>() / errors.len().max(1) as f64).sqrt(),
            }
        })
        .collect();
    let bounds: Vec<f64> = results.iter().filter_map(|r| r.crlb_rms_mm).collect();
    MonteCarlo {
        experiment: experiment.to_string(),
        methods,
        crlb_rms_mm: (bounds.iter().map(|b| b * b).sum::<f64>() / bounds.len().max(1) as f64).sqrt(),
        bound,
        seeds: results,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sigma_table_is_zero_without_noise_and_grows_linearly() {
        let rows = sigma_table(50, 40, 3);
        assert!(rows[0].std_per_axis_mm < 1e-9, "{rows:?}");
        let ratio = rows[3].std_per_axis_mm / rows[1].std_per_axis_mm;
        assert!((ratio - 4.0).abs() < 0.4, "{rows:?}");
        // Half-normal per axis, a little less for the six fitted parameters: ≈ 0.59 σ.
        assert!((rows[2].std_per_axis_mm - 0.59).abs() < 0.05, "{rows:?}");
    }

    #[test]
    fn each_method_carries_its_ratio_to_the_bound_with_an_interval_only_where_seeds_have_bounds() {
        let seed = |seed: u64, errors: [f64; 2], bound: Option<f64>| SeedResult {
            seed,
            rms_error_mm: vec![("a".into(), errors[0]), ("b".into(), errors[1])],
            crlb_rms_mm: bound,
            frames_used: 40,
        };
        let bounded: Vec<SeedResult> = (0..6)
            .map(|k| seed(k, [0.1 + 0.02 * k as f64, 0.3], Some(0.1)))
            .collect();
        let study = summarise("x", BoundModel::SphereFit, bounded);
        for m in &study.methods {
            let ratio = m.rms_over_bound.unwrap();
            assert!((ratio - m.rms_mm / study.crlb_rms_mm).abs() < 1e-12, "{m:?}");
            let [lo, hi] = m.rms_over_bound_90.unwrap();
            assert!(lo <= ratio && ratio <= hi, "{m:?}");
        }
        // Errors that do not vary over the seeds leave nothing to resample.
        let [lo, hi] = study.methods[1].rms_over_bound_90.unwrap();
        assert!((lo - 3.0).abs() < 1e-12 && (hi - 3.0).abs() < 1e-12, "{lo} {hi}");
        let unbounded: Vec<SeedResult> = (0..6).map(|k| seed(k, [0.1, 0.3], None)).collect();
        let study = summarise("x", BoundModel::PointPairs, unbounded);
        assert!(study
            .methods
            .iter()
            .all(|m| m.rms_over_bound.is_none() && m.rms_over_bound_90.is_none()));
    }

    #[test]
    fn horn_reaches_the_bound_on_its_own_model() {
        // Pairs with isotropic Gaussian noise: Horn is the ML estimator, so its RMS
        // error over many trials matches the Cramér–Rao bound.
        let truth = rigid_from_axis_angle(Vector3::new(0.1, -0.2, 1.4), Vector3::new(-20.0, 160.0, 25.0));
        let sigma = 0.5;
        let mut rng = Rng::new(12);
        let xs: Vec<Point3<f64>> = (0..40)
            .map(|_| Point3::new(rng.uniform(0.0, 100.0), rng.uniform(0.0, 80.0), 0.0))
            .collect();
        let probes = [Point3::new(0.0, 0.0, 0.0), Point3::new(100.0, 80.0, 0.0)];
        let bound = crlb_rms(&truth, &xs, &(Matrix3::identity() * sigma * sigma), &probes).unwrap();
        let mut sum = 0.0;
        let trials = 400;
        for _ in 0..trials {
            let ys: Vec<Point3<f64>> = xs
                .iter()
                .map(|x| {
                    truth * x + Vector3::new(rng.normal(0.0, sigma), rng.normal(0.0, sigma), rng.normal(0.0, sigma))
                })
                .collect();
            let fit = crate::estimate::horn::solve(xs.as_slice(), &ys, Variant::Rigid).unwrap();
            sum += probes
                .iter()
                .map(|q| (fit.apply(q) - truth * q).norm_squared())
                .sum::<f64>()
                / probes.len() as f64;
        }
        let rms = (sum / trials as f64).sqrt();
        assert!(rms >= 0.9 * bound && rms <= 1.1 * bound, "rms {rms}, bound {bound}");
    }
}
