//! Hole filling: voxels whose accumulated weight is zero get a value from the
//! filled voxels around them. The elements of `<HoleFilling>` are tried in order
//! until one gives a value; a hole none can fill is left empty (zero). A hole
//! may hold a value: linear pixels whose weights round to nothing in the
//! accumulator's 1/256 steps still set it. PLUS's volumes have such holes empty
//! where no element fills them (`docs/results/reconstruction.md`).
//!
//! Every element reads the volume as the distribution left it (a filled hole is
//! never a source for another), so holes can be filled in any order and in
//! parallel with the same result.
//!
//! STICK (Vaughan et al., "Hole filling with oriented sticks in ultrasound volume
//! reconstruction", J. Med. Imaging 2015): from the hole, along each of the 13
//! directions of the 26-neighbourhood (both ways), the first filled voxel; a
//! direction with one on both sides is a stick, its value interpolated linearly
//! between its ends and stored as a voxel is (8-bit: floored). The shortest
//! stick wins, and sticks as short are averaged with it (`NumberOfSticksToUse`
//! = n > 1: the sticks as short as the n-th shortest, weighted by inverse
//! length). PLUS counts the backward half of each stick one step longer than it
//! is, in its length and its interpolation weights, and `StickLengthLimit`
//! bounds the whole stick so counted: ahead + behind + 1 steps at most.
//! probecal does the same, so that its volumes match PLUS's
//! (`docs/results/reconstruction.md` shows the measurement).
//!
//! A one-stick element is tabled rather than searched from every hole: per
//! direction, every voxel's steps to the first filled voxel either way follow
//! from its neighbour's in one pass over the slab ([`stick_table`]), the same
//! sticks the per-hole search finds (a unit test holds them equal).

use crate::io::plus::volume_config::HoleFilling;

use super::{Grid, Sample};

/// What hole filling did.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct HoleStats {
    /// Voxels with zero weight after distribution.
    pub holes_before: u64,
    /// Holes filled by each element, in the settings' order.
    pub filled_by_element: Vec<u64>,
    pub holes_after: u64,
}

/// A stick direction with what its searches need.
#[derive(Debug, Clone, Copy)]
struct Dir {
    /// Canonical index (the order among directions of one step length).
    index: usize,
    step: [i64; 3],
    /// Length of one step, voxels.
    unit: f64,
    /// Index offset of one step in the voxel array.
    stride: i64,
}

/// The 13 stick directions, one of each opposite pair of the 26-neighbourhood,
/// with their canonical index (z, then y, then x from −1 to 1), axes first,
/// then face and body diagonals.
fn stick_directions(dims: [usize; 3]) -> Vec<Dir> {
    let mut out = Vec::new();
    for dz in -1..=1 {
        for dy in -1..=1 {
            for dx in -1..=1 {
                let step = [dx, dy, dz];
                if step.iter().find(|c| **c != 0).is_some_and(|c| *c > 0) {
                    out.push(Dir {
                        index: out.len(),
                        step,
                        unit: ((dx * dx + dy * dy + dz * dz) as f64).sqrt(),
                        stride: dx + dy * dims[0] as i64 + dz * (dims[0] * dims[1]) as i64,
                    });
                }
            }
        }
    }
    out.sort_by(|a, b| a.unit.total_cmp(&b.unit).then(a.index.cmp(&b.index)));
    out
}

/// Read-only view of the distributed volume.
struct Source<'a, T> {
    grid: &'a Grid,
    voxels: &'a [T],
    weights: &'a [u16],
}

impl<T: Sample> Source<'_, T> {
    fn index(&self, p: [i64; 3]) -> Option<usize> {
        let d = self.grid.dims;
        (0..3)
            .all(|k| p[k] >= 0 && p[k] < d[k] as i64)
            .then(|| (p[2] as usize * d[1] + p[1] as usize) * d[0] + p[0] as usize)
    }

    /// First filled voxel from voxel `i` at `p` along `dir` (backwards when
    /// `sign` is −1), within `limit` steps and the volume: (steps, value).
    fn first_filled(&self, i: usize, p: [i64; 3], dir: &Dir, sign: i64, limit: usize) -> Option<(f64, f64)> {
        let d = self.grid.dims;
        let mut room = limit as i64;
        for a in 0..3 {
            match dir.step[a] * sign {
                1 => room = room.min(d[a] as i64 - 1 - p[a]),
                -1 => room = room.min(p[a]),
                _ => {}
            }
        }
        let stride = dir.stride * sign;
        let mut j = i as i64;
        for k in 1..=room {
            j += stride;
            let w = self.weights[j as usize];
            if w > 0 {
                return Some((k as f64, self.voxels[j as usize].to_f64()));
            }
        }
        None
    }

    /// (length, value) of the stick along `dir`, if it has both ends, at most
    /// `limit` steps (ahead + behind + 1) and is not longer than `at_most`.
    fn one_stick(&self, i: usize, p: [i64; 3], dir: &Dir, limit: usize, at_most: f64) -> Option<(f64, f64)> {
        // Steps (ahead + behind + 1) that keep the stick within both bounds.
        let steps = ((at_most / dir.unit) + 1e-9).min(limit as f64) as usize;
        if steps < 3 {
            return None;
        }
        let (ahead, v_ahead) = self.first_filled(i, p, dir, 1, steps - 2)?;
        let room = steps - 1 - ahead as usize;
        let (behind, v_behind) = self.first_filled(i, p, dir, -1, room)?;
        let behind = behind + 1.0;
        Some((
            (ahead + behind) * dir.unit,
            stick_value::<T>(ahead, behind, v_ahead, v_behind),
        ))
    }

    /// The mean value of the shortest sticks: those as short as the shortest
    /// (`use_sticks` > 1: as the `use_sticks`-th shortest, weighted by inverse
    /// length). `dirs` come shortest unit first, so the bound tightens early.
    fn stick(&self, i: usize, p: [i64; 3], limit: usize, use_sticks: usize, dirs: &[Dir]) -> Option<f64> {
        let mut sticks: Vec<(f64, f64)> = Vec::with_capacity(dirs.len());
        for dir in dirs {
            // With one stick to use, none longer than the shortest so far counts.
            let bound = match use_sticks {
                0 | 1 => sticks.iter().map(|s| s.0).fold(f64::INFINITY, f64::min),
                _ => f64::INFINITY,
            };
            sticks.extend(self.one_stick(i, p, dir, limit, bound));
        }
        if sticks.is_empty() {
            return None;
        }
        sticks.sort_by(|a, b| a.0.total_cmp(&b.0));
        let cutoff = sticks[use_sticks.clamp(1, sticks.len()) - 1].0;
        // Weights relative to the cutoff: sticks of one length weigh exactly 1.
        let used = sticks.iter().filter(|s| s.0 <= cutoff).map(|s| (cutoff / s.0, s.1));
        let total: f64 = used.clone().map(|(w, _)| w).sum();
        Some(used.map(|(w, v)| w * v).sum::<f64>() / total)
    }

    /// Weighted mean of the filled voxels of the `size`³ cube around `p`, if at
    /// least `min_ratio` of the cube is filled; `weight(offset², accumulated)`.
    fn kernel(&self, p: [i64; 3], size: usize, min_ratio: f64, weight: &dyn Fn(f64, f64) -> f64) -> Option<f64> {
        let h = (size / 2) as i64;
        let (mut known, mut sum, mut total) = (0usize, 0.0, 0.0);
        for dz in -h..=h {
            for dy in -h..=h {
                for dx in -h..=h {
                    let Some(i) = self.index([p[0] + dx, p[1] + dy, p[2] + dz]) else {
                        continue;
                    };
                    if self.weights[i] == 0 {
                        continue;
                    }
                    known += 1;
                    let w = weight((dx * dx + dy * dy + dz * dz) as f64, f64::from(self.weights[i]));
                    sum += w * self.voxels[i].to_f64();
                    total += w;
                }
            }
        }
        let ratio = known as f64 / (size * size * size) as f64;
        (known > 0 && ratio >= min_ratio && total > 0.0).then(|| sum / total)
    }

    fn element(&self, i: usize, p: [i64; 3], element: &HoleFilling, dirs: &[Dir]) -> Option<f64> {
        match *element {
            HoleFilling::Stick {
                length_limit,
                sticks_to_use,
            } => self.stick(i, p, length_limit, sticks_to_use, dirs),
            HoleFilling::Gaussian {
                size,
                stdev,
                min_known_ratio,
            } => self.kernel(p, size, min_known_ratio, &|d2, _| (-d2 / (2.0 * stdev * stdev)).exp()),
            HoleFilling::GaussianAccumulation {
                size,
                stdev,
                min_known_ratio,
            } => self.kernel(p, size, min_known_ratio, &|d2, acc| {
                acc * (-d2 / (2.0 * stdev * stdev)).exp()
            }),
            HoleFilling::NearestNeighbor { size, min_known_ratio } => (3..=size)
                .step_by(2)
                .find_map(|s| self.kernel(p, s, min_known_ratio, &|_, _| 1.0)),
            HoleFilling::DistanceWeightInverse { size, min_known_ratio } => {
                self.kernel(p, size, min_known_ratio, &|d2, _| 1.0 / d2.sqrt())
            }
        }
    }
}

/// A stick's value: its ends' values interpolated at the hole (`ahead` and
/// `behind` steps away, `behind` counted one longer), stored as a voxel is.
fn stick_value<T: Sample>(ahead: f64, behind: f64, v_ahead: f64, v_behind: f64) -> f64 {
    let t = behind / (ahead + behind);
    T::from_floor(v_ahead * t + v_behind * (1.0 - t)).to_f64()
}

/// The longest `StickLengthLimit` the table below takes (a stick's half, at most
/// two steps shorter, is counted in a byte); a longer one is searched voxel by voxel.
const TABLE_MAX_LIMIT: usize = 254;

/// The most steps either end of a stick can be from its hole under `limit`
/// (ahead + behind + 1 steps at most, each end at least one step away).
fn half_reach(limit: usize) -> usize {
    limit.saturating_sub(2)
}

/// The most voxels a volume may have for its sticks to be tabled (at most 28
/// bytes a voxel more, under 2 GiB: each hole's place, best stick so far and
/// whether it is settled, and the steps either way in the slab being tabled); a
/// bigger one is searched voxel by voxel.
const TABLE_MAX_VOXELS: usize = 1 << 26;

/// Whether a stick element's searches can come from [`stick_table`]: one stick,
/// a limit that fits a byte, and a volume whose table fits the bound.
fn tabled(element: &HoleFilling, voxels: usize) -> Option<usize> {
    match *element {
        HoleFilling::Stick {
            length_limit,
            sticks_to_use,
        } if sticks_to_use <= 1 && length_limit <= TABLE_MAX_LIMIT && voxels <= TABLE_MAX_VOXELS => Some(length_limit),
        _ => None,
    }
}

/// The one-stick element's value for every hole of the planes `z0..z1`, found as
/// [`Source::stick`] finds it, but for all holes at once: per direction, each
/// voxel's steps to the first filled voxel ahead come from its neighbour's
/// (`ahead[v] = 1` when `v + d` is filled, else `ahead[v + d] + 1`, none past
/// the [`half_reach`]), and likewise behind; a stick whose steps exceed `limit`
/// is dropped. The planes within reach of the slab are included, so the steps of
/// the slab's own voxels are whole.
fn stick_table<T: Sample>(source: &Source<'_, T>, z0: usize, z1: usize, limit: usize, dirs: &[Dir]) -> StickValues {
    let [nx, ny, nz] = source.grid.dims;
    let plane = nx * ny;
    let side = half_reach(limit);
    let (lo, hi) = (z0.saturating_sub(side), (z1 + side).min(nz));
    let sub = [nx, ny, hi - lo];
    // 1 where the planes `lo..hi` are filled, 0 where not.
    let filled: Vec<u8> = source.weights[lo * plane..hi * plane]
        .iter()
        .map(|&w| u8::from(w > 0))
        .collect();
    // The slab's holes that a stick may reach (indices from its first voxel),
    // the only voxels looked at below.
    let reach = super::near::within_cube(&filled, sub, side);
    let holes: Vec<u32> = (0..(z1 - z0) * plane)
        .filter(|&k| side > 0 && reach[(z0 - lo) * plane + k] != 0 && filled[(z0 - lo) * plane + k] == 0)
        .map(|k| k as u32)
        .collect();
    let mut best_len = vec![f64::INFINITY; holes.len()];
    // The sum of the values of the sticks as short as the shortest, and how many
    // (0: no stick yet).
    let mut best_sum = vec![0.0f64; holes.len()];
    let mut best_count = vec![0u8; holes.len()];
    // The holes a later direction may still give a better stick (by position in `holes`).
    let mut open: Vec<u32> = (0..holes.len() as u32).collect();
    let mut ahead = vec![0u8; sub[2] * plane];
    let mut behind = vec![0u8; sub[2] * plane];
    for (d, dir) in dirs.iter().enumerate() {
        if open.is_empty() {
            break;
        }
        steps_to_filled(&filled, sub, dir.step, side, &mut ahead);
        steps_to_filled(&filled, sub, dir.step.map(|c| -c), side, &mut behind);
        for &h in &open {
            let h = h as usize;
            let i = z0 * plane + holes[h] as usize;
            let local = i - lo * plane;
            let (a, b) = (ahead[local], behind[local]);
            if a == 0 || b == 0 || usize::from(a) + usize::from(b) + 1 > limit {
                continue;
            }
            let (ahead_steps, behind_steps) = (f64::from(a), f64::from(b) + 1.0);
            let length = (ahead_steps + behind_steps) * dir.unit;
            if length <= best_len[h] {
                let v_ahead = source.voxels[(i as i64 + i64::from(a) * dir.stride) as usize].to_f64();
                let v_behind = source.voxels[(i as i64 - i64::from(b) * dir.stride) as usize].to_f64();
                let value = stick_value::<T>(ahead_steps, behind_steps, v_ahead, v_behind);
                if length < best_len[h] {
                    (best_len[h], best_sum[h], best_count[h]) = (length, value, 1);
                } else {
                    best_sum[h] += value;
                    best_count[h] += 1;
                }
            }
        }
        // The shortest stick a later direction can give is three of its steps
        // (one ahead, two behind), and `dirs` come shortest step first: a hole
        // whose stick is shorter than that is settled.
        if let Some(next) = dirs.get(d + 1) {
            let shortest = 3.0 * next.unit;
            open.retain(|&h| best_len[h as usize] >= shortest);
        }
    }
    let best_value = best_sum
        .iter()
        .zip(&best_count)
        .map(|(s, &n)| s / f64::from(n.max(1)))
        .collect();
    StickValues {
        holes,
        best_count,
        best_value,
        cursor: 0,
    }
}

/// A slab's tabled sticks: its holes (offsets from the slab's first voxel,
/// ascending) and each one's value, looked up in ascending order.
struct StickValues {
    holes: Vec<u32>,
    /// The sticks averaged (0 where the hole has none).
    best_count: Vec<u8>,
    best_value: Vec<f64>,
    cursor: usize,
}

impl StickValues {
    /// The value at `offset`; offsets must come in ascending order.
    fn at(&mut self, offset: usize) -> Option<f64> {
        while self.cursor < self.holes.len() && (self.holes[self.cursor] as usize) < offset {
            self.cursor += 1;
        }
        let c = self.cursor;
        (self.holes.get(c).is_some_and(|&h| h as usize == offset) && self.best_count[c] > 0).then(|| self.best_value[c])
    }
}

/// Into `steps` (of `filled`'s planes): each voxel's steps along `step` to the
/// first filled voxel, 0 when none is within `limit` steps and the planes. Voxels
/// are visited so that `v + step` comes before `v`: a row whose next voxels are
/// in another row in one branch-free pass over a copy of that row (which the
/// compiler vectorises), a step along x voxel by voxel.
fn steps_to_filled(filled: &[u8], sub: [usize; 3], step: [i64; 3], limit: usize, steps: &mut [u8]) {
    let [nx, ny, nz] = sub;
    let plane = nx * ny;
    // The k-th index visited along an axis of n when the step there is d.
    let visit = |k: usize, n: usize, d: i64| if d > 0 { n - 1 - k } else { k };
    let inside = |c: usize, d: i64, n: usize| {
        let next = c as i64 + d;
        next >= 0 && next < n as i64
    };
    let limit = limit as u8;
    // The steps of the row the current row's steps continue.
    let mut ahead_row = vec![0u8; nx];
    for zk in 0..nz {
        let z = visit(zk, nz, step[2]);
        for yk in 0..ny {
            let y = visit(yk, ny, step[1]);
            let row = z * plane + y * nx;
            if !(inside(z, step[2], nz) && inside(y, step[1], ny)) {
                steps[row..row + nx].fill(0);
                continue;
            }
            // The row of the voxels one step on, as if x did not move.
            let next_row = (row as i64 + step[1] * nx as i64 + step[2] * plane as i64) as usize;
            let (first, last) = match step[0] {
                1 => {
                    steps[row + nx - 1] = 0;
                    (0, nx - 1)
                }
                -1 => {
                    steps[row] = 0;
                    (1, nx)
                }
                _ => (0, nx),
            };
            let len = last - first;
            let src = ((next_row + first) as i64 + step[0]) as usize;
            if step[1] != 0 || step[2] != 0 {
                ahead_row[..len].copy_from_slice(&steps[src..src + len]);
                let out = &mut steps[row + first..row + first + len];
                for ((o, &s), &f) in out.iter_mut().zip(&ahead_row[..len]).zip(&filled[src..src + len]) {
                    // Masks (0 or 0xFF) rather than branches: the filled voxels
                    // fall where they may.
                    let grow = 0u8.wrapping_sub(u8::from(s > 0) & u8::from(s < limit));
                    let here = 0u8.wrapping_sub(f);
                    *o = (s.wrapping_add(1) & grow & !here) | (1 & here);
                }
                continue;
            }
            for xk in 0..len {
                let x = if step[0] > 0 { last - 1 - xk } else { first + xk };
                let next = ((next_row + x) as i64 + step[0]) as usize;
                let s = steps[next];
                steps[row + x] = if filled[next] > 0 {
                    1
                } else if s > 0 && s < limit {
                    s + 1
                } else {
                    0
                };
            }
        }
    }
}

/// Voxels with a filled voxel within `radius` steps along every axis (a cube):
/// elsewhere no stick can reach a filled voxel, and the search is skipped.
fn near_filled(grid: &Grid, weights: &[u16], radius: usize) -> Vec<bool> {
    let filled: Vec<u8> = weights.iter().map(|&w| u8::from(w > 0)).collect();
    let near = super::near::within_cube(&filled, grid.dims, radius);
    near.into_iter().map(|c| c > 0).collect()
}

/// Fills the holes of `voxels` (weights zero) with the elements, in parallel over
/// `threads` slabs of z planes; the holes they leave are set to zero (with no
/// elements, nothing changes).
pub fn fill<T: Sample>(
    grid: &Grid,
    voxels: &mut [T],
    weights: &[u16],
    elements: &[HoleFilling],
    threads: usize,
) -> HoleStats {
    let holes_before = weights.iter().filter(|w| **w == 0).count() as u64;
    if elements.is_empty() || holes_before == 0 {
        return HoleStats {
            holes_before,
            filled_by_element: vec![0; elements.len()],
            holes_after: holes_before,
        };
    }
    let original = voxels.to_vec();
    let source = Source {
        grid,
        voxels: &original,
        weights,
    };
    let dirs = stick_directions(grid.dims);
    // Only stick elements, some searched hole by hole: the search for holes no
    // stick can reach is skipped (tabled sticks need no such help).
    let all_tabled = elements.iter().all(|e| tabled(e, original.len()).is_some());
    let reach = elements
        .iter()
        .map(|e| match e {
            HoleFilling::Stick { length_limit, .. } => Some(*length_limit),
            _ => None,
        })
        .collect::<Option<Vec<usize>>>()
        .filter(|_| !all_tabled)
        .map(|limits| near_filled(grid, weights, half_reach(limits.into_iter().max().unwrap_or(0))));
    let plane = grid.dims[0] * grid.dims[1];
    let nz = grid.dims[2];
    // A slab of planes per thread; each tables its one-stick elements.
    let per_slab = nz.div_ceil(threads.max(1)).max(1);
    let counts: Vec<Vec<u64>> = super::in_pool(threads, || {
        use rayon::prelude::*;
        voxels
            .par_chunks_mut(plane * per_slab)
            .enumerate()
            .map(|(slab, out)| {
                let mut filled = vec![0u64; elements.len()];
                let first = slab * per_slab * plane;
                let (z0, z1) = (slab * per_slab, (slab * per_slab + out.len() / plane).min(nz));
                let mut tables: Vec<Option<StickValues>> = elements
                    .iter()
                    .map(|e| tabled(e, original.len()).map(|limit| stick_table(&source, z0, z1, limit, &dirs)))
                    .collect();
                for (offset, voxel) in out.iter_mut().enumerate() {
                    let i = first + offset;
                    if weights[i] != 0 {
                        continue;
                    }
                    // The position, for the elements searched hole by hole.
                    let p = || [i % grid.dims[0], (i / grid.dims[0]) % grid.dims[1], i / plane].map(|c| c as i64);
                    let beyond_reach = reach.as_ref().is_some_and(|r| !r[i]);
                    let found = elements
                        .iter()
                        .enumerate()
                        .filter(|_| !beyond_reach)
                        .find_map(|(k, e)| {
                            match &mut tables[k] {
                                Some(table) => table.at(offset),
                                None => source.element(i, p(), e, &dirs),
                            }
                            .map(|v| (k, v))
                        });
                    // A hole no element fills is left empty.
                    *voxel = match found {
                        Some((k, v)) => {
                            filled[k] += 1;
                            T::from_floor(v)
                        }
                        None => T::default(),
                    };
                }
                filled
            })
            .collect()
    });
    let filled_by_element: Vec<u64> = (0..elements.len()).map(|k| counts.iter().map(|c| c[k]).sum()).collect();
    HoleStats {
        holes_before,
        holes_after: holes_before - filled_by_element.iter().sum::<u64>(),
        filled_by_element,
    }
}

#[cfg(test)]
mod tests;
