//! The arcs' edge errors against the rendered truth, set against the noise
//! model the sphere fits and their bound assume ([`super::sphere_bound::EdgeNoise`]:
//! each edge point off its sphere by an independent error of one SD, an arc
//! worth a stated number of independent points).
//!
//! An arc informs the calibration through three numbers: its circle's radius
//! and its centre's two image coordinates. So each arc's errors against its
//! true circle (the true plane's cut of its sphere) are reduced to those three,
//! the least-squares fit of `e(θ) = a + s_u·sin θ − s_v·cos θ` to the edge
//! points' radial errors (`θ` the point's angle from the arc's top, towards +u;
//! `a` the radius error, `(s_u, s_v)` the centre's shift in the image, mm). The
//! model predicts their covariance arc by arc; the check compares the spread the
//! arcs actually show with it, by how far the plane cuts from the sphere's
//! centre (`|d| / R`), where a thick beam slice blurs an arc the more the more
//! obliquely it cuts.

use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

use super::sphere_bound::EdgeNoise;
use crate::estimate::edge_blur::{variance_factor, SliceBlur};

/// One arc's edge points and its sphere, both in the true image frame (mm).
#[derive(Debug, Clone, PartialEq)]
pub struct ArcAgainstTruth {
    pub edge_points_in_image_mm: Vec<[f64; 2]>,
    /// The sphere's centre in the true image frame: `(u, v, d)`, `d` the
    /// plane's distance from it.
    pub centre_in_image_mm: [f64; 3],
    pub radius_mm: f64,
}

/// The arcs of one range of cuts (`|d| / R` in `cut`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ArcNoiseBin {
    /// `[lowest, highest)` of `|d| / R`.
    pub cut: [f64; 2],
    pub arcs: usize,
    /// RMS of the edge points' distances from their arc's own fitted circle, mm
    /// (the per-point noise; the model's is its edge SD).
    pub point_rms_mm: f64,
    /// Mean of `(a, s_u, s_v)` over the arcs, mm: what every arc shares.
    pub bias_mm: [f64; 3],
    /// SD of each of `(a, s_u, s_v)` about that mean over the model's RMS SD:
    /// 1 when the model describes the arcs.
    pub sd_over_model: [f64; 3],
}

/// The check over every arc and by range of cut.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ArcNoiseCheck {
    /// The model's edge SD (mm) and independent points per arc.
    pub model_edge_sd_mm: f64,
    pub model_points_per_arc: f64,
    /// The model's growth of the edge noise with the cut, if it has one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model_slice_blur: Option<SliceBlur>,
    pub all: ArcNoiseBin,
    pub by_cut: Vec<ArcNoiseBin>,
}

/// The ranges of `|d| / R` the check reports apart.
pub const CUTS: [[f64; 2]; 3] = [[0.0, 0.3], [0.3, 0.5], [0.5, 1.0]];
/// An arc needs this many edge points to give its three numbers.
const MIN_POINTS: usize = 10;
/// A range needs this many arcs for a spread.
const MIN_ARCS: usize = 3;

/// One arc reduced: `(a, s_u, s_v)`, the model's covariance of them, the RMS
/// about the arc's own fit, its point count and `|d| / R`.
struct Reduced {
    coefficients: Vector3<f64>,
    model_cov: Matrix3<f64>,
    own_rms_mm: f64,
    points: usize,
    cut: f64,
}

fn reduce(arc: &ArcAgainstTruth, noise: &EdgeNoise) -> Option<Reduced> {
    let [cu, cv, d] = arc.centre_in_image_mm;
    let r_true_sq = arc.radius_mm.powi(2) - d * d;
    let n = arc.edge_points_in_image_mm.len();
    let positive = |v: f64| v > 0.0 && v.is_finite();
    if !positive(r_true_sq) || n < MIN_POINTS || !positive(noise.edge_sd_mm) || !positive(noise.points_per_arc) {
        return None;
    }
    let r_true = r_true_sq.sqrt();
    let mut normal = Matrix3::zeros();
    let mut rhs = Vector3::zeros();
    let mut rows = Vec::with_capacity(n);
    for p in &arc.edge_points_in_image_mm {
        let (du, dv) = (p[0] - cu, p[1] - cv);
        let rho = du.hypot(dv);
        // v grows away from the probe: the arc's top is at -v.
        let theta = du.atan2(-dv);
        let row = Vector3::new(1.0, theta.sin(), -theta.cos());
        let error = rho - r_true;
        normal += row * row.transpose();
        rhs += row * error;
        rows.push((row, error));
    }
    let inverse = normal.try_inverse()?;
    let coefficients = inverse * rhs;
    let own_ss: f64 = rows.iter().map(|(row, e)| (e - row.dot(&coefficients)).powi(2)).sum();
    // n points worth `points_per_arc` independent ones: each point's variance
    // scaled by n / points_per_arc.
    // The slice's growth of that variance with the cut, when the model has it.
    let factor = variance_factor(noise.slice_blur, arc.radius_mm, d);
    let model_cov = inverse * (noise.edge_sd_mm.powi(2) * factor * n as f64 / noise.points_per_arc);
    let values = coefficients.iter().chain(model_cov.iter()).copied().chain([own_ss]);
    if values.into_iter().any(|v| !v.is_finite()) {
        return None;
    }
    Some(Reduced {
        coefficients,
        model_cov,
        own_rms_mm: (own_ss / (n - 3) as f64).sqrt(),
        points: n,
        cut: d.abs() / arc.radius_mm,
    })
}

fn bin(cut: [f64; 2], arcs: &[&Reduced]) -> Option<ArcNoiseBin> {
    if arcs.len() < MIN_ARCS {
        return None;
    }
    let k = arcs.len() as f64;
    let mean: Vector3<f64> = arcs.iter().map(|a| a.coefficients).sum::<Vector3<f64>>() / k;
    let mut sd_over_model = [0.0; 3];
    for (j, ratio) in sd_over_model.iter_mut().enumerate() {
        let spread = arcs.iter().map(|a| (a.coefficients[j] - mean[j]).powi(2)).sum::<f64>() / (k - 1.0);
        let model = arcs.iter().map(|a| a.model_cov[(j, j)]).sum::<f64>() / k;
        *ratio = (spread / model).sqrt();
    }
    let points: usize = arcs.iter().map(|a| a.points - 3).sum();
    let own_ss: f64 = arcs.iter().map(|a| a.own_rms_mm.powi(2) * (a.points - 3) as f64).sum();
    Some(ArcNoiseBin {
        cut,
        arcs: arcs.len(),
        point_rms_mm: (own_ss / points as f64).sqrt(),
        bias_mm: [mean[0], mean[1], mean[2]],
        sd_over_model,
    })
}

/// The check, or `None` with fewer than three usable arcs (an arc is usable
/// with ten edge points and its plane inside its sphere).
pub fn check(arcs: &[ArcAgainstTruth], noise: &EdgeNoise) -> Option<ArcNoiseCheck> {
    let reduced: Vec<Reduced> = arcs.iter().filter_map(|a| reduce(a, noise)).collect();
    let all: Vec<&Reduced> = reduced.iter().collect();
    let all = bin([0.0, 1.0], &all)?;
    let by_cut = CUTS
        .iter()
        .filter_map(|cut| {
            let inside: Vec<&Reduced> = reduced.iter().filter(|a| a.cut >= cut[0] && a.cut < cut[1]).collect();
            bin(*cut, &inside)
        })
        .collect();
    Some(ArcNoiseCheck {
        model_edge_sd_mm: noise.edge_sd_mm,
        model_points_per_arc: noise.points_per_arc,
        model_slice_blur: noise.slice_blur,
        all,
        by_cut,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::rng::Rng;

    /// The model the test arcs are drawn from: 40 independent points of 0.12 mm.
    const MODEL: EdgeNoise = EdgeNoise {
        edge_sd_mm: 0.12,
        points_per_arc: 40.0,
        slice_blur: None,
    };

    /// `count` arcs of a 10 mm sphere cut at `|d|` spread over the sphere, each
    /// with `points` edge points over ±55° whose radial errors are independent
    /// with SD `sd`, plus a per-arc radius error of SD `arc_sd` and a common `bias`.
    fn arcs(count: usize, points: usize, sd: f64, arc_sd: f64, bias: f64, seed: u64) -> Vec<ArcAgainstTruth> {
        arcs_cut(count, points, sd, arc_sd, bias, seed, 4.0, None)
    }

    /// The same, cut from `-reach` to `reach`, each point's variance grown by
    /// `blur`'s factor for its cut.
    #[allow(clippy::too_many_arguments)]
    fn arcs_cut(
        count: usize,
        points: usize,
        sd: f64,
        arc_sd: f64,
        bias: f64,
        seed: u64,
        reach: f64,
        blur: Option<SliceBlur>,
    ) -> Vec<ArcAgainstTruth> {
        let mut rng = Rng::new(seed);
        (0..count)
            .map(|i| {
                let d = 2.0 * reach * (i as f64 / count as f64) - reach;
                let r = (100.0f64 - d * d).sqrt();
                let sd = sd * variance_factor(blur, 10.0, d).sqrt();
                let centre = [40.0 + rng.uniform(-5.0, 5.0), 60.0, d];
                let arc_error = rng.normal(0.0, arc_sd);
                let edge_points_in_image_mm = (0..points)
                    .map(|k| {
                        let theta = (-55.0 + 110.0 * k as f64 / (points - 1) as f64).to_radians();
                        let rho = r + bias + arc_error + rng.normal(0.0, sd);
                        [centre[0] + rho * theta.sin(), centre[1] - rho * theta.cos()]
                    })
                    .collect();
                ArcAgainstTruth {
                    edge_points_in_image_mm,
                    centre_in_image_mm: centre,
                    radius_mm: 10.0,
                }
            })
            .collect()
    }

    #[test]
    fn independent_edge_errors_match_their_model() {
        let noise = MODEL;
        let check = check(&arcs(400, 40, 0.12, 0.0, 0.0, 7), &noise).unwrap();
        assert_eq!(check.all.arcs, 400);
        for ratio in check.all.sd_over_model {
            assert!((0.9..1.1).contains(&ratio), "{check:?}");
        }
        assert!((check.all.point_rms_mm - 0.12).abs() < 0.005, "{check:?}");
        assert!(check.all.bias_mm.iter().all(|b| b.abs() < 0.01), "{check:?}");
    }

    #[test]
    fn a_model_that_overcounts_points_is_exposed() {
        // 40 independent points per arc, claimed worth 160: each coefficient's
        // spread is twice the model's.
        let noise = EdgeNoise {
            points_per_arc: 160.0,
            ..MODEL
        };
        let check = check(&arcs(400, 40, 0.12, 0.0, 0.0, 8), &noise).unwrap();
        for ratio in check.all.sd_over_model {
            assert!((1.8..2.2).contains(&ratio), "{check:?}");
        }
    }

    #[test]
    fn a_per_arc_error_shows_in_the_radius_and_a_common_one_in_the_bias() {
        let noise = MODEL;
        let check = check(&arcs(400, 40, 0.12, 0.3, 0.05, 9), &noise).unwrap();
        let [radius, along_u, _] = check.all.sd_over_model;
        assert!(radius > 1.5, "{check:?}");
        assert!((0.9..1.1).contains(&along_u), "{check:?}");
        assert!((check.all.bias_mm[0] - 0.05).abs() < 0.04, "{check:?}");
        // The per-point noise about each arc's own circle is unchanged.
        assert!((check.all.point_rms_mm - 0.12).abs() < 0.005, "{check:?}");
    }

    #[test]
    fn arcs_are_split_by_how_far_the_plane_cuts_from_the_centre() {
        let noise = MODEL;
        let check = check(&arcs(100, 40, 0.12, 0.0, 0.0, 10), &noise).unwrap();
        // |d| from 0 to 4 mm of a 10 mm sphere: the first two ranges only.
        let cuts: Vec<[f64; 2]> = check.by_cut.iter().map(|b| b.cut).collect();
        assert_eq!(cuts, vec![CUTS[0], CUTS[1]]);
        assert_eq!(check.by_cut.iter().map(|b| b.arcs).sum::<usize>(), 100);
    }

    #[test]
    fn unusable_arcs_give_no_check() {
        let noise = MODEL;
        let mut few = arcs(2, 40, 0.12, 0.0, 0.0, 11);
        assert!(check(&few, &noise).is_none());
        // A plane outside its sphere, or too few points: not counted.
        few.extend(arcs(3, 40, 0.12, 0.0, 0.0, 12).into_iter().map(|mut a| {
            a.centre_in_image_mm[2] = 10.5;
            a
        }));
        few.extend(arcs(3, 5, 0.12, 0.0, 0.0, 13));
        assert!(check(&few, &noise).is_none());
    }

    #[test]
    fn oblique_arcs_noisier_by_the_slice_match_a_model_with_it_and_not_one_without() {
        let blur = SliceBlur {
            axial_sd_mm: 0.3,
            elevation_sd_mm: 0.5,
        };
        let drawn = arcs_cut(600, 40, 0.12, 0.0, 0.0, 14, 8.0, Some(blur));
        let with = check(
            &drawn,
            &EdgeNoise {
                slice_blur: Some(blur),
                ..MODEL
            },
        )
        .unwrap();
        assert_eq!(with.model_slice_blur, Some(blur));
        for bin in &with.by_cut {
            for ratio in bin.sd_over_model {
                assert!((0.85..1.15).contains(&ratio), "{with:?}");
            }
        }
        let without = check(&drawn, &MODEL).unwrap();
        let oblique = without.by_cut.last().unwrap();
        assert_eq!(oblique.cut, CUTS[2]);
        for ratio in oblique.sd_over_model {
            assert!(ratio > 1.5, "{without:?}");
        }
    }
}
