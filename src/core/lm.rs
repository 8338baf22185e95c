//! A small Levenberg–Marquardt solver for dense least squares with a numeric
//! Jacobian (central differences). Problems here have a handful of unknowns and a
//! few thousand residuals.

use nalgebra::{DMatrix, DVector};

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LmError {
    #[error("the residuals are not finite at the start")]
    NotFiniteStart,
    #[error("fewer residuals ({residuals}) than unknowns ({unknowns})")]
    Underdetermined { residuals: usize, unknowns: usize },
}

#[derive(Debug, Clone)]
pub struct LmResult {
    pub x: DVector<f64>,
    /// Sum of squared residuals at `x`.
    pub cost: f64,
    pub iterations: usize,
    /// The step or the relative cost change fell below tolerance.
    pub converged: bool,
    /// `J^T J` at the solution (for covariances).
    pub normal_matrix: DMatrix<f64>,
}

/// Minimises `|f(x)|^2` from `x0`. `steps` are the finite-difference steps per unknown.
pub fn minimise(
    x0: DVector<f64>,
    steps: &DVector<f64>,
    max_iterations: usize,
    f: impl Fn(&DVector<f64>) -> DVector<f64>,
) -> Result<LmResult, LmError> {
    let mut x = x0;
    let mut r = f(&x);
    if r.iter().any(|v| !v.is_finite()) {
        return Err(LmError::NotFiniteStart);
    }
    if r.len() < x.len() {
        return Err(LmError::Underdetermined {
            residuals: r.len(),
            unknowns: x.len(),
        });
    }
    let rows = r.len();
    let jacobian = |x: &DVector<f64>| {
        let mut j = DMatrix::zeros(rows, x.len());
        for k in 0..x.len() {
            let mut plus = x.clone();
            let mut minus = x.clone();
            plus[k] += steps[k];
            minus[k] -= steps[k];
            let d = (f(&plus) - f(&minus)) / (2.0 * steps[k]);
            j.set_column(k, &d);
        }
        j
    };
    let mut cost = r.norm_squared();
    let mut lambda = 1e-3;
    let mut converged = false;
    let mut iterations = 0;
    let mut j = jacobian(&x);
    while iterations < max_iterations {
        iterations += 1;
        let jtj = j.transpose() * &j;
        let g = j.transpose() * &r;
        let mut improved = false;
        for _ in 0..12 {
            let mut a = jtj.clone();
            for k in 0..a.nrows() {
                a[(k, k)] += lambda * jtj[(k, k)].max(1e-12);
            }
            let Some(step) = a.cholesky().map(|c| c.solve(&(-&g))) else {
                lambda *= 10.0;
                continue;
            };
            let candidate = &x + &step;
            let r_new = f(&candidate);
            let cost_new = r_new.norm_squared();
            if cost_new.is_finite() && cost_new < cost {
                let small_step = step.norm() <= 1e-12 * (1.0 + x.norm());
                let small_change = (cost - cost_new) <= 1e-14 * cost.max(1e-300);
                x = candidate;
                r = r_new;
                cost = cost_new;
                lambda = (lambda / 10.0).max(1e-12);
                improved = true;
                if small_step || small_change {
                    converged = true;
                }
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            // No step lowers the cost: a minimum to working precision.
            converged = true;
        }
        if converged {
            break;
        }
        j = jacobian(&x);
    }
    let j = jacobian(&x);
    Ok(LmResult {
        normal_matrix: j.transpose() * &j,
        x,
        cost,
        iterations,
        converged,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fits_an_exponential_from_a_poor_start() {
        let ts: Vec<f64> = (0..20).map(|i| i as f64 * 0.25).collect();
        let ys: Vec<f64> = ts.iter().map(|t| 3.0 * (-0.7 * t).exp() + 0.5).collect();
        let f = |x: &DVector<f64>| {
            DVector::from_iterator(
                ts.len(),
                ts.iter().zip(&ys).map(|(t, y)| x[0] * (-x[1] * t).exp() + x[2] - y),
            )
        };
        let out = minimise(
            DVector::from_vec(vec![1.0, 0.1, 0.0]),
            &DVector::from_element(3, 1e-6),
            200,
            f,
        )
        .unwrap();
        assert!(out.converged);
        assert!(
            (out.x[0] - 3.0).abs() < 1e-6 && (out.x[1] - 0.7).abs() < 1e-6 && (out.x[2] - 0.5).abs() < 1e-6,
            "{:?}",
            out.x
        );
    }
}
