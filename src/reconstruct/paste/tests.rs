//! Unit tests of the distribution.

use super::*;

#[test]
fn frames_pasted_one_at_a_time_give_the_volume_of_all_at_once() {
    let grid = Grid::from_extent([0.0; 3], [1.0; 3], [0, 23, 0, 19, 0, 9]).unwrap();
    let (width, height) = (16, 12);
    let pixels: Vec<Vec<u8>> = (0..4u32)
        .map(|f| {
            (0..width * height)
                .map(|i| ((i as u32 * 13 + f * 31) % 251) as u8)
                .collect()
        })
        .collect();
    let slices: Vec<Slice<u8>> = pixels
        .iter()
        .enumerate()
        .map(|(f, p)| {
            let mut m = nalgebra::Matrix4::identity();
            m[(0, 0)] = 1.3;
            m[(1, 1)] = 1.1;
            m[(2, 1)] = 0.2;
            m[(0, 3)] = 1.5 + 0.3 * f as f64;
            m[(2, 3)] = 2.0 + 1.7 * f as f64;
            Slice {
                pixels: p,
                reference_T_pixel: m,
            }
        })
        .collect();
    // Two more frames, each partly outside the volume on both sides of
    // every axis, with indices falling along their rows and columns.
    let outside = [
        [[-1.9, 0.0, 20.0], [0.0, 2.1, -2.0], [0.4, 0.0, -1.0]],
        [[0.5, 1.0, -3.0], [-0.7, 1.9, 9.0], [-0.3, 0.9, 3.0]],
    ];
    let slices: Vec<Slice<u8>> = slices
        .into_iter()
        .chain(outside.iter().zip(&pixels).map(|(rows, p)| {
            let mut m = nalgebra::Matrix4::identity();
            for (r, [cx, cy, t]) in rows.iter().enumerate() {
                (m[(r, 0)], m[(r, 1)], m[(r, 3)]) = (*cx, *cy, *t);
            }
            Slice {
                pixels: p,
                reference_T_pixel: m,
            }
        }))
        .collect();
    for interpolation in [Interpolation::NearestNeighbor, Interpolation::Linear] {
        let settings = PasteSettings {
            width,
            height,
            clip_px: [0, 0, width - 1, height - 1],
            fan: None,
            pixel_rejection_threshold: None,
            interpolation,
            compounding: Compounding::Mean,
            optimization: Optimization::Full,
            importance_mask: None,
        };
        let all = paste(&grid, &slices, &settings, 2);
        let mut one_by_one = Pasted::zeroed(&grid);
        for s in slices.chunks(1) {
            paste_into(&grid, &mut one_by_one, s, &settings, 3);
        }
        assert!(all.pixels_inserted > 0);
        assert_eq!(all, one_by_one, "{interpolation:?}");
        if interpolation == Interpolation::NearestNeighbor {
            // A mask of full weight everywhere takes the per-pixel path: the
            // row path must give the same voxels, weights and counts.
            for compounding in [Compounding::Mean, Compounding::Maximum, Compounding::Latest] {
                let plain = PasteSettings {
                    compounding,
                    ..settings.clone()
                };
                let masked = PasteSettings {
                    importance_mask: Some(vec![255; width * height]),
                    ..plain.clone()
                };
                assert_eq!(
                    paste(&grid, &slices, &plain, 2),
                    paste(&grid, &slices, &masked, 2),
                    "{compounding:?}"
                );
            }
        }
    }
}

/// The fan's arcs are cut row by row: a pixel is inside a circle when the pixel
/// one further from the origin's column is (PLUS's rule), not when its own centre is.
#[test]
fn the_fan_arcs_are_cut_row_by_row() {
    let fan = Fan {
        angles_deg: [-80.0, 80.0],
        origin_px: [20.0, 0.0],
        radius_start_px: 5.0,
        radius_stop_px: 9.0,
    };
    // Row 2: the start circle spans |dx| <= 4.58, the stop circle |dx| <= 8.77.
    let kept: Vec<i64> = (0..40usize)
        .filter(|&x| in_fan(&fan, x, 2))
        .map(|x| x as i64 - 20)
        .collect();
    assert_eq!(
        kept,
        vec![-7, -6, -5, -4, 4, 5, 6, 7],
        "dx = ±4 (centre 4.47 from the origin) is kept, ±8 (8.25) is not"
    );
    // Row 4: the start circle meets the row at |dx| = 3 exactly, which is kept.
    assert!(in_fan(&fan, 23, 4) && !in_fan(&fan, 22, 4));
    // Above the origin's row, or on it, nothing.
    assert!(!in_fan(&fan, 27, 0));
}
