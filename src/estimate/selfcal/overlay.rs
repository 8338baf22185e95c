//! The sweeps' volumes cut by planes, before and after the correction: what
//! the page overlays to show whether the sweeps came together.
//!
//! The first sweep is one layer and the other sweeps, compounded together, the
//! second; both on the finest grid (set by the start, so before and after share
//! it), with the values the comparison uses (block-averaged, less the
//! background when asked). Each plane is normal to one of the Reference
//! frame's axes and passes through the centroid of the voxels both layers
//! cover under the refined calibration.

use nalgebra::Vector6;

use super::compound::{correlation, splat, standardise, Splat, SplatGrid};
use super::refine::{finest_grid, SearchFault, SearchSettings};
use super::{Frame0, Sweep};

/// The axes of the Reference frame, by index.
pub const AXES: [char; 3] = ['x', 'y', 'z'];

/// One layer of a slice: a value per pixel where the layer covers it.
pub type Layer = Vec<Option<f32>>;

/// The two layers in one plane under one calibration, and their agreement there.
#[derive(Debug, Clone, PartialEq)]
pub struct Cut {
    /// The first sweep, then the others compounded together.
    pub layers: [Layer; 2],
    /// The normalised correlation of the layers over the pixels both cover
    /// (`None` when fewer than [`MIN_SLICE_PIXELS`] are).
    pub correlation: Option<f64>,
    pub pixels_compared: usize,
}

/// Fewer common pixels than this in a slice give no correlation.
pub const MIN_SLICE_PIXELS: usize = 20;

/// One plane of the grid, cut before and after the correction.
#[derive(Debug, Clone, PartialEq)]
pub struct OverlaySlice {
    /// The Reference axis the plane is normal to (an index into [`AXES`]), and
    /// the axes across and down the picture.
    pub normal: usize,
    pub across: usize,
    pub down: usize,
    /// The plane's position along its normal, Reference mm.
    pub position_mm: f64,
    /// Pixels across and down (one voxel each).
    pub size: [usize; 2],
    pub voxel_mm: f64,
    pub before: Cut,
    pub after: Cut,
}

/// The first sweep and the rest, each as one volume.
fn two_layers(grid: &SplatGrid, sweeps: &[Sweep], frame0: &Frame0, q: &Vector6<f64>) -> [Splat; 2] {
    let m = frame0.calibration(q);
    let mut splats = sweeps.iter().map(|s| splat(grid, s, &m, None));
    let first = splats.next().unwrap_or_else(|| Splat::empty(grid));
    let rest = splats.fold(Splat::empty(grid), |mut acc, s| {
        for (a, b) in acc.sum.iter_mut().zip(&s.sum) {
            *a += b;
        }
        for (a, b) in acc.weight.iter_mut().zip(&s.weight) {
            *a += b;
        }
        acc
    });
    [first, rest]
}

fn value(s: &Splat, i: usize, min_weight: f32) -> Option<f32> {
    (s.weight[i] >= min_weight && s.weight[i] > 0.0).then(|| s.sum[i] / s.weight[i])
}

/// The voxel nearest the centroid of the voxels both layers cover (`None`
/// when they share none).
fn common_centre(grid: &SplatGrid, layers: &[Splat; 2], min_weight: f32) -> Option<[usize; 3]> {
    let [nx, ny, _] = grid.dims;
    let (mut sum, mut n) = ([0.0f64; 3], 0usize);
    for i in 0..grid.voxels() {
        if value(&layers[0], i, min_weight).is_some() && value(&layers[1], i, min_weight).is_some() {
            let (x, y, z) = (i % nx, (i / nx) % ny, i / (nx * ny));
            for (s, c) in sum.iter_mut().zip([x, y, z]) {
                *s += c as f64;
            }
            n += 1;
        }
    }
    (n > 0).then(|| sum.map(|s| (s / n as f64).round() as usize))
}

fn cut(grid: &SplatGrid, layers: &[Splat; 2], normal: usize, index: usize, min_weight: f32) -> Cut {
    let (across, down) = in_plane(normal);
    let d = grid.dims;
    let mut picked: [Layer; 2] = [Vec::new(), Vec::new()];
    for row in 0..d[down] {
        for col in 0..d[across] {
            let mut at = [0usize; 3];
            at[normal] = index;
            at[across] = col;
            at[down] = row;
            let i = (at[2] * d[1] + at[1]) * d[0] + at[0];
            for (p, l) in picked.iter_mut().zip(layers) {
                p.push(value(l, i, min_weight));
            }
        }
    }
    let (a, b): (Vec<f64>, Vec<f64>) = picked[0]
        .iter()
        .zip(&picked[1])
        .filter_map(|(a, b)| Some((f64::from((*a)?), f64::from((*b)?))))
        .unzip();
    let pixels_compared = a.len();
    let correlation = (pixels_compared >= MIN_SLICE_PIXELS).then(|| correlation(&standardise(a), &standardise(b)));
    Cut {
        layers: picked,
        correlation,
        pixels_compared,
    }
}

/// The axes across and down a plane normal to `normal`.
pub fn in_plane(normal: usize) -> (usize, usize) {
    match normal {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    }
}

/// A plane normal to each Reference axis through the refined calibration's
/// common centroid, cut under the start (`before`) and under `q` (`after`).
/// Empty when the layers share no voxel under `q`.
pub fn slices(
    sweeps: &[Sweep],
    frame0: &Frame0,
    q: &Vector6<f64>,
    settings: &SearchSettings,
) -> Result<Vec<OverlaySlice>, SearchFault> {
    let grid = finest_grid(sweeps, frame0, settings)?;
    let min_weight = settings.comparison.min_weight;
    let before = two_layers(&grid, sweeps, frame0, &Vector6::zeros());
    let after = two_layers(&grid, sweeps, frame0, q);
    let Some(centre) = common_centre(&grid, &after, min_weight) else {
        return Ok(Vec::new());
    };
    Ok((0..3)
        .rev()
        .map(|normal| {
            let (across, down) = in_plane(normal);
            cropped(OverlaySlice {
                normal,
                across,
                down,
                position_mm: grid.origin_mm[normal] + centre[normal] as f64 * grid.voxel_mm,
                size: [grid.dims[across], grid.dims[down]],
                voxel_mm: grid.voxel_mm,
                before: cut(&grid, &before, normal, centre[normal], min_weight),
                after: cut(&grid, &after, normal, centre[normal], min_weight),
            })
        })
        .collect())
}

/// Pixels kept around what any layer covers when a slice is cropped.
pub const CROP_MARGIN_PX: usize = 2;

/// The slice cut down to the box around the pixels any layer covers before or
/// after, with [`CROP_MARGIN_PX`] around it (as it was when none is covered).
fn cropped(mut s: OverlaySlice) -> OverlaySlice {
    let [w, h] = s.size;
    let (mut lo, mut hi) = ([usize::MAX; 2], [0usize; 2]);
    for c in [&s.before, &s.after] {
        for layer in &c.layers {
            for (i, _) in layer.iter().enumerate().filter(|(_, v)| v.is_some()) {
                let (x, y) = (i % w, i / w);
                lo = [lo[0].min(x), lo[1].min(y)];
                hi = [hi[0].max(x), hi[1].max(y)];
            }
        }
    }
    if lo[0] > hi[0] {
        return s;
    }
    let x0 = lo[0].saturating_sub(CROP_MARGIN_PX);
    let y0 = lo[1].saturating_sub(CROP_MARGIN_PX);
    let x1 = (hi[0] + CROP_MARGIN_PX).min(w - 1);
    let y1 = (hi[1] + CROP_MARGIN_PX).min(h - 1);
    for c in [&mut s.before, &mut s.after] {
        for layer in &mut c.layers {
            *layer = (y0..=y1)
                .flat_map(|y| (x0..=x1).map(move |x| (x, y)))
                .map(|(x, y)| layer[y * w + x])
                .collect();
        }
    }
    s.size = [x1 - x0 + 1, y1 - y0 + 1];
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid() -> SplatGrid {
        SplatGrid {
            origin_mm: [0.0; 3],
            voxel_mm: 1.0,
            dims: [4, 3, 2],
        }
    }

    #[test]
    fn a_cut_reads_the_plane_it_names_and_correlates_only_common_pixels() {
        let g = grid();
        let n = g.voxels();
        // Layer 0 holds its voxel index, layer 1 twice it; layer 1 misses voxel 0.
        let l0 = Splat {
            sum: (0..n).map(|i| i as f32).collect(),
            weight: vec![1.0; n],
        };
        let mut l1 = Splat {
            sum: (0..n).map(|i| 2.0 * i as f32).collect(),
            weight: vec![1.0; n],
        };
        l1.weight[0] = 0.0;
        let layers = [l0, l1];
        // z = 1: x across, y down; index (1*3 + y)*4 + x.
        let c = cut(&g, &layers, 2, 1, 0.5);
        assert_eq!(c.layers[0].len(), 12);
        assert_eq!(c.layers[0][5], Some(17.0));
        // x = 2: y across, z down.
        let c = cut(&g, &layers, 0, 2, 0.5);
        assert_eq!(c.layers[0].len(), 6);
        assert_eq!(c.layers[0][4], Some(((3 + 1) * 4 + 2) as f32));
        // y = 0 on z = 0 holds voxel 0, which layer 1 misses.
        let c = cut(&g, &layers, 1, 0, 0.5);
        assert_eq!(c.layers[1][0], None);
        assert_eq!(c.pixels_compared, 7);
        assert_eq!(c.correlation, None, "7 pixels are fewer than the minimum");
    }

    #[test]
    fn the_centre_is_that_of_the_common_voxels() {
        let g = grid();
        let n = g.voxels();
        let mut a = Splat {
            sum: vec![1.0; n],
            weight: vec![0.0; n],
        };
        let b = Splat {
            sum: vec![1.0; n],
            weight: vec![1.0; n],
        };
        // Only voxels (3, 2, 1) and (3, 0, 1) of layer 0.
        a.weight[(3 + 2) * 4 + 3] = 1.0;
        a.weight[3 * 4 + 3] = 1.0;
        assert_eq!(common_centre(&g, &[a, b], 0.5), Some([3, 1, 1]));
    }

    #[test]
    fn a_slice_is_cropped_to_what_its_layers_cover() {
        // 8 x 6 pixels, layer 1 of `after` covering (5, 4) alone, layer 0 of
        // `before` covering (3, 3) alone.
        let empty = || Cut {
            layers: [vec![None; 48], vec![None; 48]],
            correlation: None,
            pixels_compared: 0,
        };
        let (mut before, mut after) = (empty(), empty());
        before.layers[0][3 * 8 + 3] = Some(1.0);
        after.layers[1][4 * 8 + 5] = Some(2.0);
        let s = cropped(OverlaySlice {
            normal: 2,
            across: 0,
            down: 1,
            position_mm: 0.0,
            size: [8, 6],
            voxel_mm: 1.0,
            before,
            after,
        });
        // x 1..=7, y 1..=5 (the margin stops at the edge).
        assert_eq!(s.size, [7, 5]);
        assert_eq!(s.before.layers[0].len(), 35);
        assert_eq!(s.before.layers[0][2 * 7 + 2], Some(1.0));
        assert_eq!(s.after.layers[1][3 * 7 + 4], Some(2.0));
    }
}
