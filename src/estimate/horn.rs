//! Stage 4: absolute orientation by Horn's closed form (unit quaternions, 1987).
//!
//! Given pairs `source_i -> target_i`, finds `target_T_source` (and optionally a
//! scale `s`) minimising `sum |target_i - (s R source_i + t)|^2`. For the probe
//! calibration the sources are B-scan points in the image frame (mm, all on
//! z = 0) and the targets are the phantom features mapped into the marker frame,
//! so the result is `marker_T_image`.

use nalgebra::{Matrix3, Matrix4, Point3, Quaternion, SymmetricEigen, UnitQuaternion, Vector3};

use crate::core::geometry::Rigid;

/// Why no transform could be computed.
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
pub enum HornError {
    #[error("need at least 3 point pairs, got {0}")]
    TooFewPairs(usize),
    #[error("source and target point counts differ ({sources} vs {targets})")]
    LengthMismatch { sources: usize, targets: usize },
    #[error("a point has a non-finite coordinate (pair {0})")]
    NotFinite(usize),
    #[error("{0} points are collinear or coincident: the rotation about their line is undetermined")]
    Degenerate(&'static str),
    /// The nonlinear fit used for line targets (wires) failed.
    #[error("point-to-line refinement: {0}")]
    Refinement(String),
}

/// Result of a fit.
#[derive(Debug, Clone)]
pub struct HornFit {
    /// Maps source coordinates into the target frame (rotation and translation only).
    pub target_T_source: Rigid,
    /// Isotropic scale (1 for the rigid variant).
    pub scale: f64,
    /// Root mean square of the residuals `|target - (s R source + t)|`, mm.
    pub rms_residual_mm: f64,
}

impl HornFit {
    /// Applies the fitted similarity to a source point.
    pub fn apply(&self, source: &Point3<f64>) -> Point3<f64> {
        let rotated = self.target_T_source.rotation * (source.coords * self.scale);
        Point3::from(rotated + self.target_T_source.translation.vector)
    }
}

/// Whether the scale is fixed to 1 (rigid) or estimated (similarity).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Variant {
    Rigid,
    Similarity,
}

/// Relative size of the second principal spread below which points count as collinear.
const COLLINEAR_RATIO: f64 = 1e-6;

fn check_spread(centred: &[Vector3<f64>], which: &'static str) -> Result<(), HornError> {
    let mut cov = Matrix3::zeros();
    for p in centred {
        cov += p * p.transpose();
    }
    let mut values: Vec<f64> = SymmetricEigen::new(cov).eigenvalues.iter().copied().collect();
    values.sort_by(|a, b| b.total_cmp(a));
    if values[0] <= 0.0 || values[1] / values[0] < COLLINEAR_RATIO * COLLINEAR_RATIO {
        return Err(HornError::Degenerate(which));
    }
    Ok(())
}

/// Solves the absolute orientation problem `target ≈ s R source + t`.
pub fn solve(source: &[Point3<f64>], target: &[Point3<f64>], variant: Variant) -> Result<HornFit, HornError> {
    if source.len() != target.len() {
        return Err(HornError::LengthMismatch {
            sources: source.len(),
            targets: target.len(),
        });
    }
    let n = source.len();
    if n < 3 {
        return Err(HornError::TooFewPairs(n));
    }
    for (i, (a, b)) in source.iter().zip(target).enumerate() {
        if !(a.coords.iter().chain(b.coords.iter()).all(|v| v.is_finite())) {
            return Err(HornError::NotFinite(i));
        }
    }
    let centroid = |pts: &[Point3<f64>]| pts.iter().fold(Vector3::zeros(), |acc, p| acc + p.coords) / n as f64;
    let source_centroid = centroid(source);
    let target_centroid = centroid(target);
    let a: Vec<Vector3<f64>> = source.iter().map(|p| p.coords - source_centroid).collect();
    let b: Vec<Vector3<f64>> = target.iter().map(|p| p.coords - target_centroid).collect();
    check_spread(&a, "source")?;
    check_spread(&b, "target")?;

    // S = sum a b^T; Horn's symmetric 4x4 matrix N; its top eigenvector is the rotation.
    let mut s = Matrix3::zeros();
    for (ai, bi) in a.iter().zip(&b) {
        s += ai * bi.transpose();
    }
    let (sxx, sxy, sxz) = (s[(0, 0)], s[(0, 1)], s[(0, 2)]);
    let (syx, syy, syz) = (s[(1, 0)], s[(1, 1)], s[(1, 2)]);
    let (szx, szy, szz) = (s[(2, 0)], s[(2, 1)], s[(2, 2)]);
    #[rustfmt::skip]
    let horn_n = Matrix4::new(
        sxx + syy + szz, syz - szy,        szx - sxz,        sxy - syx,
        syz - szy,       sxx - syy - szz,  sxy + syx,        szx + sxz,
        szx - sxz,       sxy + syx,        -sxx + syy - szz, syz + szy,
        sxy - syx,       szx + sxz,        syz + szy,        -sxx - syy + szz,
    );
    let eigen = SymmetricEigen::new(horn_n);
    let best = eigen
        .eigenvalues
        .iter()
        .enumerate()
        .max_by(|x, y| x.1.total_cmp(y.1))
        .map(|(i, _)| i)
        .unwrap_or(0);
    let q = eigen.eigenvectors.column(best);
    let rotation = UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]));

    let scale = match variant {
        Variant::Rigid => 1.0,
        Variant::Similarity => {
            let num: f64 = a.iter().zip(&b).map(|(ai, bi)| bi.dot(&(rotation * ai))).sum();
            let den: f64 = a.iter().map(|ai| ai.norm_squared()).sum();
            num / den
        }
    };
    let translation = target_centroid - rotation * (source_centroid * scale);
    let target_T_source = Rigid::from_parts(translation.into(), rotation);
    let mut fit = HornFit {
        target_T_source,
        scale,
        rms_residual_mm: 0.0,
    };
    let sum_sq: f64 = source
        .iter()
        .zip(target)
        .map(|(p, q)| (fit.apply(p) - q).norm_squared())
        .sum();
    fit.rms_residual_mm = (sum_sq / n as f64).sqrt();
    Ok(fit)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::geometry::rigid_from_axis_angle;
    use crate::core::rng::Rng;
    use nalgebra::SVD;

    fn planar_points(rng: &mut Rng, n: usize) -> Vec<Point3<f64>> {
        (0..n)
            .map(|_| Point3::new(rng.uniform(0.0, 150.0), rng.uniform(20.0, 120.0), 0.0))
            .collect()
    }

    /// Arun/Umeyama SVD solution, written independently of Horn's quaternion route.
    fn svd_rigid(source: &[Point3<f64>], target: &[Point3<f64>]) -> Rigid {
        let n = source.len() as f64;
        let ca = source.iter().fold(Vector3::zeros(), |s, p| s + p.coords) / n;
        let cb = target.iter().fold(Vector3::zeros(), |s, p| s + p.coords) / n;
        let mut h = Matrix3::zeros();
        for (p, q) in source.iter().zip(target) {
            h += (p.coords - ca) * (q.coords - cb).transpose();
        }
        let svd = SVD::new(h, true, true);
        let (u, v_t) = (svd.u.unwrap(), svd.v_t.unwrap());
        let mut d = Matrix3::identity();
        if (v_t.transpose() * u.transpose()).determinant() < 0.0 {
            d[(2, 2)] = -1.0;
        }
        let r = v_t.transpose() * d * u.transpose();
        crate::core::geometry::rigid_from_parts(&r, &(cb - r * ca))
    }

    #[test]
    fn recovers_known_transform_exactly_without_noise() {
        let mut rng = Rng::new(7);
        let truth = rigid_from_axis_angle(Vector3::new(0.4, -1.1, 2.0), Vector3::new(-30.0, 55.0, 120.0));
        let source = planar_points(&mut rng, 12);
        let target: Vec<_> = source.iter().map(|p| truth * p).collect();
        let fit = solve(&source, &target, Variant::Rigid).expect("fit");
        let angle = crate::core::geometry::rotation_angle_between_deg(&fit.target_T_source, &truth);
        let shift = (fit.target_T_source.translation.vector - truth.translation.vector).norm();
        assert!(angle < 1e-9, "rotation error {angle} deg");
        assert!(shift < 1e-9, "translation error {shift} mm");
        assert!(fit.rms_residual_mm < 1e-9);
    }

    #[test]
    fn similarity_recovers_scale() {
        let mut rng = Rng::new(8);
        let truth = rigid_from_axis_angle(Vector3::new(-0.3, 0.2, 0.9), Vector3::new(5.0, -8.0, 40.0));
        let source = planar_points(&mut rng, 8);
        let target: Vec<_> = source.iter().map(|p| truth * Point3::from(p.coords * 1.07)).collect();
        let fit = solve(&source, &target, Variant::Similarity).expect("fit");
        assert!((fit.scale - 1.07).abs() < 1e-12, "scale {}", fit.scale);
        assert!(crate::core::geometry::rotation_angle_between_deg(&fit.target_T_source, &truth) < 1e-9);
    }

    #[test]
    fn agrees_with_independent_svd_solution_under_noise() {
        let mut rng = Rng::new(9);
        let truth = rigid_from_axis_angle(Vector3::new(1.2, 0.3, -0.7), Vector3::new(10.0, 20.0, 30.0));
        let source = planar_points(&mut rng, 40);
        let target: Vec<_> = source
            .iter()
            .map(|p| truth * p + Vector3::new(rng.normal(0.0, 1.0), rng.normal(0.0, 1.0), rng.normal(0.0, 1.0)))
            .collect();
        let fit = solve(&source, &target, Variant::Rigid).expect("fit");
        let svd = svd_rigid(&source, &target);
        let angle = crate::core::geometry::rotation_angle_between_deg(&fit.target_T_source, &svd);
        let shift = (fit.target_T_source.translation.vector - svd.translation.vector).norm();
        assert!(angle < 1e-8, "Horn and SVD differ by {angle} deg");
        assert!(shift < 1e-6, "Horn and SVD differ by {shift} mm");
        // And the noisy fit is still close to the truth.
        assert!(crate::core::geometry::rotation_angle_between_deg(&fit.target_T_source, &truth) < 1.0);
    }

    #[test]
    fn degenerate_input_is_an_error_not_a_panic() {
        let p = |x: f64, y: f64| Point3::new(x, y, 0.0);
        assert_eq!(
            solve(&[p(0.0, 0.0), p(1.0, 0.0)], &[p(0.0, 0.0), p(1.0, 0.0)], Variant::Rigid).unwrap_err(),
            HornError::TooFewPairs(2)
        );
        let line = [p(0.0, 0.0), p(1.0, 1.0), p(2.0, 2.0), p(5.0, 5.0)];
        assert_eq!(
            solve(&line, &line, Variant::Rigid).unwrap_err(),
            HornError::Degenerate("source")
        );
        let same = [p(3.0, 3.0); 4];
        assert_eq!(
            solve(&same, &same, Variant::Similarity).unwrap_err(),
            HornError::Degenerate("source")
        );
        let good = [p(0.0, 0.0), p(1.0, 0.0), p(0.0, 1.0)];
        assert!(matches!(
            solve(&good, &line[..3], Variant::Rigid).unwrap_err(),
            HornError::Degenerate("target")
        ));
        let nan = [p(0.0, 0.0), p(f64::NAN, 0.0), p(0.0, 1.0)];
        assert_eq!(solve(&nan, &good, Variant::Rigid).unwrap_err(), HornError::NotFinite(1));
        assert!(matches!(
            solve(&good, &good[..2], Variant::Rigid).unwrap_err(),
            HornError::LengthMismatch { .. }
        ));
    }
}
