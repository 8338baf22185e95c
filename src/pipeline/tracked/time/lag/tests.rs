//! The coarse search's pieces.

use super::*;

#[test]
fn the_minimum_is_the_parabolas_vertex_between_grid_points() {
    let lags: Vec<f64> = (0..11).map(|i| i as f64 * 0.01).collect();
    let curve: Vec<f64> = lags.iter().map(|l| (l - 0.0437).powi(2)).collect();
    let (k, lag) = minimum(&lags, &curve).unwrap();
    assert_eq!(k, 4);
    assert!((lag - 0.0437).abs() < 1e-9, "{lag}");
}

#[test]
fn a_ridge_above_the_noise_separates_two_minima() {
    let curve = [5.0, 3.0, 1.0, 2.0, 4.0, 1.2, 6.0];
    assert!(separated(&curve, 2, 5, 1.0));
    assert!(!separated(&curve, 2, 5, 3.0));
    // A wiggle on the floor is no ridge.
    let floor = [3.0, 1.02, 1.0, 1.01, 1.0, 3.0];
    assert!(!separated(&floor, 2, 4, 0.1));
}

#[test]
fn a_share_sum_fits_the_affine_map_and_its_residual() {
    let map = Matrix3::new(0.08, 0.001, 0.002, -0.0005, 0.075, 0.001, 11.0, 48.0, -0.4);
    let mut total = Share::ZERO;
    for (i, (u, v)) in [
        (10.0, 20.0),
        (400.0, 30.0),
        (50.0, 500.0),
        (700.0, 600.0),
        (300.0, 300.0),
    ]
    .into_iter()
    .enumerate()
    {
        let x = Vector3::new(u, v, 1.0);
        let mut p = map.transpose() * x;
        if i == 4 {
            p.x += 1.0;
        }
        total.add(
            &Share {
                g: x * x.transpose(),
                b: x * p.transpose(),
                c: p.norm_squared(),
                n: 1.0,
            },
            1.0,
        );
    }
    let (_, ssr) = total.solve().unwrap();
    assert!(ssr > 0.05 && ssr < 1.0, "{ssr}");
}
