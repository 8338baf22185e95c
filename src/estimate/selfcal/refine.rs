//! The search: Gauss–Newton on the sweeps' disagreement (standardised
//! voxel differences, whose mean square is `2 (1 − NCC)` per pair of sweeps),
//! restricted to the directions the sweeps hold.

use nalgebra::{Matrix6, SymmetricEigen, Vector6};

use super::compound::{common_voxels, correlation, splat, standardised, values_at, Comparison, Splat, SplatGrid};
use super::resample::{half_of, half_sample_standard_error, Subsets};
use super::{Frame0, Sweep, UNKNOWNS};
use crate::core::parallel::parallel_map;

/// How the search runs.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SearchSettings {
    pub comparison: Comparison,
    /// The finite-difference step on the finest grid, mm (at the image's
    /// corners for a turn); on a coarser grid it grows with the voxel.
    pub step_mm: f64,
    pub max_iterations: usize,
    /// The search stops when a step moves the calibration less than this, mm.
    pub tolerance_mm: f64,
    /// A direction is held by the sweeps when its curvature is at least this
    /// fraction of the largest one's.
    pub min_curvature_ratio: f64,
    /// A direction is held at the end when the solution's standard error along
    /// it (from resampled sweeps) is at most this, mm.
    pub max_standard_error_mm: f64,
    /// Resamples of the sweeps for the standard errors (each keeps half of
    /// every sweep's blocks of [`RESAMPLE_BLOCK_FRAMES`](super::resample::RESAMPLE_BLOCK_FRAMES) frames).
    pub resamples: usize,
    /// The farthest the search may go from the start, mm (an unknown's size);
    /// a solution at this edge is refused.
    pub max_correction_mm: f64,
    /// At most this many voxels enter the comparison (every k-th when more).
    pub max_voxels: usize,
    /// Grids searched, each half as fine as the next: `voxel_mm · 2^(levels−1)` first.
    pub levels: usize,
}

impl Default for SearchSettings {
    fn default() -> Self {
        SearchSettings {
            comparison: Comparison {
                voxel_mm: 1.0,
                min_weight: 1.0,
            },
            step_mm: 2.0,
            max_iterations: 8,
            tolerance_mm: 0.02,
            min_curvature_ratio: 0.05,
            max_standard_error_mm: 0.25,
            resamples: 16,
            max_correction_mm: 8.0,
            max_voxels: 400_000,
            levels: 3,
        }
    }
}

/// One direction of the six unknowns (an eigenvector of the disagreement's curvature).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Direction {
    /// Unit vector over the six unknowns ([`UNKNOWNS`] order).
    pub vector: [f64; 6],
    /// The disagreement's (`1 − NCC`) curvature along it, per mm².
    pub curvature_per_mm2: f64,
    /// Held by the sweeps (refined), or left at the start.
    pub held: bool,
    /// The unknowns that make it up, largest first (those above 0.3).
    pub mostly: String,
    /// The solution's standard error along it, mm, from resampled sweeps
    /// (none while searching, or where the curvature is not positive).
    pub standard_error_mm: Option<f64>,
}

/// The disagreement `1 − NCC` (mean over the pairs of sweeps) near one
/// correction, as a quadratic from its values on a stencil of steps.
#[derive(Debug, Clone)]
pub struct Quadratic {
    pub disagreement: f64,
    /// Per mm.
    pub gradient: Vector6<f64>,
    /// Per mm².
    pub hessian: Matrix6<f64>,
    /// Voxels compared (every sweep covers each at every point of the stencil).
    pub voxels: usize,
}

impl Quadratic {
    pub fn correlation(&self) -> f64 {
        1.0 - self.disagreement
    }
}
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SearchFault {
    #[error("the sweeps share {0} voxels under the start calibration: they do not overlap enough to compare (at least {MIN_VOXELS})")]
    NoOverlap(usize),
    #[error("the search reached the edge of its range ({limit_mm} mm from the start): {how}; not applied")]
    AtEdge { limit_mm: f64, how: String },
    #[error("only {used} of {of} resamples of the sweeps share enough voxels for the standard errors (at least half)")]
    FewResamples { used: usize, of: usize },
    #[error("fewer than two sweeps")]
    OneSweep,
    #[error("{0}")]
    Grid(#[from] super::compound::GridFault),
}

/// The fewest voxels the sweeps must share to be compared.
pub const MIN_VOXELS: usize = 100;

fn splats_at(grid: &SplatGrid, sweeps: &[Sweep], frame0: &Frame0, q: &Vector6<f64>, subsets: Subsets) -> Vec<Splat> {
    let m = frame0.calibration(q);
    sweeps
        .iter()
        .enumerate()
        .map(|(k, s)| splat(grid, s, &m, subsets.map(|f| f[k].as_slice())))
        .collect()
}

/// Every k-th voxel, so that at most `most` remain.
fn thinned(voxels: Vec<u32>, most: usize) -> Vec<u32> {
    if voxels.len() <= most {
        return voxels;
    }
    let k = voxels.len().div_ceil(most.max(1));
    voxels.into_iter().step_by(k).collect()
}

/// The mean normalised correlation over the pairs of sweeps at each of
/// `points`, all over the same voxels: those every sweep covers at `at` (at most
/// `max_voxels` of them) and at every point.
pub fn correlations_over(
    grid: &SplatGrid,
    sweeps: &[Sweep],
    frame0: &Frame0,
    at: &Vector6<f64>,
    points: &[Vector6<f64>],
    settings: &SearchSettings,
    subsets: Subsets,
) -> Result<(Vec<f64>, usize), SearchFault> {
    if sweeps.len() < 2 {
        return Err(SearchFault::OneSweep);
    }
    let min_w = settings.comparison.min_weight;
    let here = splats_at(grid, sweeps, frame0, at, subsets);
    let voxels = thinned(common_voxels(&here, min_w), settings.max_voxels);
    drop(here);
    if voxels.len() < MIN_VOXELS {
        return Err(SearchFault::NoOverlap(voxels.len()));
    }
    let sampled: Vec<Vec<(Vec<f64>, Vec<bool>)>> = parallel_map(points.len(), |e| {
        splats_at(grid, sweeps, frame0, &points[e], subsets)
            .iter()
            .map(|s| values_at(s, &voxels, min_w))
            .collect()
    });
    let keep: Vec<bool> = (0..voxels.len())
        .map(|i| sampled.iter().all(|ev| ev.iter().all(|(_, c)| c[i])))
        .collect();
    let compared = keep.iter().filter(|&&k| k).count();
    if compared < MIN_VOXELS {
        return Err(SearchFault::NoOverlap(compared));
    }
    let values = sampled
        .iter()
        .map(|ev| {
            let std: Vec<Vec<f64>> = ev.iter().map(|(v, _)| standardised(v, &keep)).collect();
            let (mut ncc, mut pairs) = (0.0, 0.0f64);
            for a in 0..std.len() {
                for b in a + 1..std.len() {
                    ncc += correlation(&std[a], &std[b]);
                    pairs += 1.0;
                }
            }
            ncc / pairs
        })
        .collect();
    Ok((values, compared))
}

/// The disagreement's quadratic at `q` from steps of `h` mm: the centre, `±h`
/// along each unknown and `+h` along each pair (28 points).
pub fn quadratic(
    grid: &SplatGrid,
    sweeps: &[Sweep],
    frame0: &Frame0,
    q: &Vector6<f64>,
    h: f64,
    settings: &SearchSettings,
    subsets: Subsets,
) -> Result<Quadratic, SearchFault> {
    let e = |k: usize| Vector6::from_fn(|i, _| if i == k { h } else { 0.0 });
    let mut points = vec![*q];
    for k in 0..6 {
        points.push(q + e(k));
        points.push(q - e(k));
    }
    let mut pairs = Vec::new();
    for i in 0..6 {
        for j in i + 1..6 {
            pairs.push((i, j));
            points.push(q + e(i) + e(j));
        }
    }
    let (ncc, voxels) = correlations_over(grid, sweeps, frame0, q, &points, settings, subsets)?;
    let d: Vec<f64> = ncc.iter().map(|c| 1.0 - c).collect();
    let mut gradient = Vector6::zeros();
    let mut hessian = Matrix6::zeros();
    for k in 0..6 {
        gradient[k] = (d[1 + 2 * k] - d[2 + 2 * k]) / (2.0 * h);
        hessian[(k, k)] = (d[1 + 2 * k] + d[2 + 2 * k] - 2.0 * d[0]) / (h * h);
    }
    for (n, &(i, j)) in pairs.iter().enumerate() {
        let v = (d[13 + n] - d[1 + 2 * i] - d[1 + 2 * j] + d[0]) / (h * h);
        hessian[(i, j)] = v;
        hessian[(j, i)] = v;
    }
    Ok(Quadratic {
        disagreement: d[0],
        gradient,
        hessian,
        voxels,
    })
}

/// The mean normalised correlation of the sweeps at `q` over the voxels all cover there.
pub fn agreement(
    grid: &SplatGrid,
    sweeps: &[Sweep],
    frame0: &Frame0,
    q: &Vector6<f64>,
    settings: &SearchSettings,
    subsets: Subsets,
) -> (f64, usize) {
    let min_w = settings.comparison.min_weight;
    let here = splats_at(grid, sweeps, frame0, q, subsets);
    let voxels = thinned(common_voxels(&here, min_w), settings.max_voxels);
    let keep = vec![true; voxels.len()];
    let std: Vec<Vec<f64>> = here
        .iter()
        .map(|s| standardised(&values_at(s, &voxels, min_w).0, &keep))
        .collect();
    let (mut ncc, mut pairs) = (0.0, 0.0f64);
    for a in 0..std.len() {
        for b in a + 1..std.len() {
            ncc += correlation(&std[a], &std[b]);
            pairs += 1.0;
        }
    }
    (ncc / pairs.max(1.0), voxels.len())
}

/// The curvature's eigen-directions, largest first, each marked held when
/// its curvature is at least `min_curvature_ratio` of the largest.
pub fn directions(quad: &Quadratic, min_curvature_ratio: f64) -> Vec<Direction> {
    let eig = SymmetricEigen::new(quad.hessian);
    let mut order: Vec<usize> = (0..6).collect();
    order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
    let largest = eig.eigenvalues[order[0]].max(0.0);
    order
        .iter()
        .map(|&k| {
            let mut v = eig.eigenvectors.column(k).into_owned();
            // A sign for each direction that does not depend on the solver: its largest entry positive.
            let big = (0..6).max_by(|&a, &b| v[a].abs().total_cmp(&v[b].abs())).unwrap_or(0);
            if v[big] < 0.0 {
                v = -v;
            }
            let curvature = eig.eigenvalues[k];
            let mut parts: Vec<(f64, usize)> = (0..6).map(|i| (v[i].abs(), i)).filter(|(a, _)| *a >= 0.3).collect();
            parts.sort_by(|a, b| b.0.total_cmp(&a.0));
            Direction {
                vector: [v[0], v[1], v[2], v[3], v[4], v[5]],
                curvature_per_mm2: curvature,
                held: largest > 0.0 && curvature >= min_curvature_ratio * largest,
                mostly: parts.iter().map(|(_, i)| UNKNOWNS[*i]).collect::<Vec<_>>().join(", "),
                standard_error_mm: None,
            }
        })
        .collect()
}

/// The damped Newton step along the held directions: `damping` times the
/// largest curvature added to each (0: the plain step).
fn step(quad: &Quadratic, held: &[Direction], damping: f64) -> Vector6<f64> {
    let largest = held.iter().map(|d| d.curvature_per_mm2).fold(0.0, f64::max);
    let mut s = Vector6::zeros();
    for d in held.iter().filter(|d| d.held && d.curvature_per_mm2 > 0.0) {
        let v = Vector6::from_column_slice(&d.vector);
        s -= v * (v.dot(&quad.gradient) / (d.curvature_per_mm2 + damping * largest));
    }
    s
}

/// The best point along the damped Newton direction: the plain step doubled
/// while the agreement grows, or damped while it does not.
#[allow(clippy::too_many_arguments)]
fn line_search(
    grid: &SplatGrid,
    sweeps: &[Sweep],
    frame0: &Frame0,
    level: &SearchSettings,
    subsets: Subsets,
    quad: &Quadratic,
    held: &[Direction],
    (q, current): (&Vector6<f64>, f64),
) -> Option<(Vector6<f64>, f64)> {
    let ncc_at = |trial: &Vector6<f64>| agreement(grid, sweeps, frame0, trial, level, subsets).0;
    for damping in [0.0, 0.03, 0.3, 3.0, 30.0] {
        let direction = step(quad, held, damping);
        let mut best: Option<(Vector6<f64>, f64)> = None;
        let mut scale = 1.0;
        while scale <= 16.0 {
            let trial = q + direction * scale;
            if trial.amax() >= level.max_correction_mm {
                break;
            }
            let ncc = ncc_at(&trial);
            if ncc <= best.map_or(current, |b| b.1) {
                break;
            }
            best = Some((trial, ncc));
            scale *= 2.0;
        }
        if best.is_some() {
            return best;
        }
    }
    None
}

/// Where the search went.
#[derive(Debug, Clone)]
pub struct Search {
    /// The correction found, along the held directions only.
    pub correction: Vector6<f64>,
    /// Where the search ended, before the directions not held were taken back.
    pub unprojected: Vector6<f64>,
    /// The directions at the solution on the finest grid: which are held.
    pub directions: Vec<Direction>,
    /// The agreement at the start, on the finest grid.
    pub start_correlation: f64,
    /// At the solution, on the finest grid.
    pub end: Quadratic,
    pub iterations: usize,
    /// The resamples the standard errors came from (those whose sweeps still overlap).
    pub resamples_used: usize,
    /// Each accepted step: the voxel size, the correction and the mean correlation there.
    pub path: Vec<(f64, Vector6<f64>, f64)>,
}

/// The grids of the levels, coarsest first.
pub fn level_grids(
    sweeps: &[Sweep],
    frame0: &Frame0,
    settings: &SearchSettings,
) -> Result<Vec<SplatGrid>, SearchFault> {
    (0..settings.levels.max(1))
        .rev()
        .map(|k| {
            let voxel = settings.comparison.voxel_mm * f64::from(1u32 << k.min(8));
            let margin = settings.max_correction_mm + 2.0 * voxel;
            SplatGrid::around(sweeps, &frame0.probe_T_pixel, voxel, margin).map_err(SearchFault::from)
        })
        .collect()
}

/// The finest grid alone (the last of [`level_grids`]).
pub fn finest_grid(sweeps: &[Sweep], frame0: &Frame0, settings: &SearchSettings) -> Result<SplatGrid, SearchFault> {
    let voxel = settings.comparison.voxel_mm;
    let margin = settings.max_correction_mm + 2.0 * voxel;
    SplatGrid::around(sweeps, &frame0.probe_T_pixel, voxel, margin).map_err(SearchFault::from)
}

fn at_level(settings: &SearchSettings, grid: &SplatGrid) -> SearchSettings {
    let mut s = *settings;
    s.comparison.voxel_mm = grid.voxel_mm;
    s.step_mm = settings.step_mm * grid.voxel_mm / settings.comparison.voxel_mm;
    s
}

/// The fewest frames of a sweep a coarse grid is compared on (fewer leave too
/// few voxels that every sweep covers).
pub const MIN_COARSE_FRAMES: usize = 12;

/// Every `n`-th frame of each sweep (of `subsets`' frames where given).
fn every_nth_frame(sweeps: &[Sweep], n: usize, subsets: Subsets) -> Vec<Vec<usize>> {
    sweeps
        .iter()
        .enumerate()
        .map(|(k, s)| match subsets {
            Some(f) => f[k].iter().copied().step_by(n.max(1)).collect(),
            None => (0..s.frames.len()).step_by(n.max(1)).collect(),
        })
        .collect()
}

/// Searches from the start, coarse grids first, each step along the
/// directions the sweeps hold there; at the end, the directions the finest grid
/// holds at the solution are kept and the correction along the others is
/// taken back (left at the start).
pub fn search(
    sweeps: &[Sweep],
    frame0: &Frame0,
    settings: &SearchSettings,
    subsets: Subsets,
) -> Result<Search, SearchFault> {
    let grids = level_grids(sweeps, frame0, settings)?;
    let finest = grids[grids.len() - 1];
    let mut q = Vector6::zeros();
    let start_correlation = agreement(&finest, sweeps, frame0, &q, settings, subsets).0;
    let mut path = Vec::new();
    let mut iterations = 0;
    for grid in &grids {
        let level = at_level(settings, grid);
        // A coarser grid needs fewer frames: every 2nd on twice the voxel, every
        // 4th on four times, while every sweep keeps at least MIN_COARSE_FRAMES.
        let fewest = (0..sweeps.len())
            .map(|k| subsets.map_or(sweeps[k].frames.len(), |f| f[k].len()))
            .min()
            .unwrap_or(0);
        let stride = ((grid.voxel_mm / settings.comparison.voxel_mm).round().max(1.0) as usize)
            .min((fewest / MIN_COARSE_FRAMES).max(1));
        let thinned = every_nth_frame(sweeps, stride, subsets);
        let subsets = if stride > 1 { Some(thinned.as_slice()) } else { subsets };
        let mut current = agreement(grid, sweeps, frame0, &q, &level, subsets).0;
        path.push((grid.voxel_mm, q, current));
        for _ in 0..settings.max_iterations {
            iterations += 1;
            let quad = match quadratic(grid, sweeps, frame0, &q, level.step_mm, &level, subsets) {
                // A coarse grid's fewer frames may share too few voxels: the finer grids go on.
                Err(SearchFault::NoOverlap(_)) if grid.voxel_mm > finest.voxel_mm => break,
                other => other?,
            };
            let held = directions(&quad, level.min_curvature_ratio);
            let accepted = line_search(grid, sweeps, frame0, &level, subsets, &quad, &held, (&q, current));
            let Some((next, ncc)) = accepted else { break };
            let moved = (next - q).norm();
            q = next;
            current = ncc;
            if q.amax() >= settings.max_correction_mm {
                return Err(SearchFault::AtEdge {
                    limit_mm: settings.max_correction_mm,
                    how: format!("correction {:.2?} mm", q.as_slice()),
                });
            }
            path.push((grid.voxel_mm, q, current));
            if moved < level.tolerance_mm {
                break;
            }
        }
    }
    let end = quadratic(&finest, sweeps, frame0, &q, settings.step_mm, settings, subsets)?;
    let mut held = directions(&end, settings.min_curvature_ratio);
    let (errors, resamples_used) = standard_errors(&finest, sweeps, frame0, &q, settings, &held, subsets)?;
    for (d, se) in held.iter_mut().zip(errors) {
        d.standard_error_mm = se;
        d.held = se.is_some_and(|se| se <= settings.max_standard_error_mm);
    }
    let mut kept = Vector6::zeros();
    for d in held.iter().filter(|d| d.held) {
        let v = Vector6::from_column_slice(&d.vector);
        kept += v * v.dot(&q);
    }
    Ok(Search {
        correction: kept,
        unprojected: q,
        directions: held,
        start_correlation,
        end,
        iterations,
        resamples_used,
        path,
    })
}

/// The solution's standard error along each direction, mm: on each resample
/// (half of each sweep's frame blocks) the Newton step from `q` along the
/// direction, whose spread over the resamples, divided by √2 (a half sample's
/// spread is √2 times the whole's), is the error. `None` where the curvature
/// is not positive. A resample whose halves share too few voxels is left out
/// (the count used is returned); fewer than half of them used is an error.
pub fn standard_errors(
    grid: &SplatGrid,
    sweeps: &[Sweep],
    frame0: &Frame0,
    q: &Vector6<f64>,
    settings: &SearchSettings,
    directions: &[Direction],
    subsets: Subsets,
) -> Result<(Vec<Option<f64>>, usize), SearchFault> {
    let h = settings.step_mm;
    let mut steps: Vec<Vec<f64>> = vec![Vec::new(); directions.len()];
    for r in 0..settings.resamples.max(2) {
        let halves = half_of(sweeps, subsets, 0x05e1_fca1 + r as u64);
        let mut points = vec![*q];
        for d in directions {
            let v = Vector6::from_column_slice(&d.vector);
            points.push(q + v * h);
            points.push(q - v * h);
        }
        let ncc = match correlations_over(grid, sweeps, frame0, q, &points, settings, Some(&halves)) {
            Ok((ncc, _)) => ncc,
            // Half of thin sweeps may not overlap: that resample is left out.
            Err(SearchFault::NoOverlap(_)) => continue,
            Err(e) => return Err(e),
        };
        for (k, d) in directions.iter().enumerate() {
            let slope = ((1.0 - ncc[1 + 2 * k]) - (1.0 - ncc[2 + 2 * k])) / (2.0 * h);
            steps[k].push(-slope / d.curvature_per_mm2);
        }
    }
    let used = steps.first().map_or(0, Vec::len);
    let wanted = settings.resamples.max(2);
    if used < (wanted / 2).max(2) {
        return Err(SearchFault::FewResamples { used, of: wanted });
    }
    Ok((
        directions
            .iter()
            .zip(steps)
            .map(|(d, s)| {
                (d.curvature_per_mm2 > 0.0)
                    .then(|| half_sample_standard_error(&s))
                    .flatten()
            })
            .collect(),
        used,
    ))
}
