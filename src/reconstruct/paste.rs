//! Pixels into voxels ("distribution"), with PLUS's arithmetic so that the
//! voxels come out as PLUS's do:
//!
//! - Positions: with `Optimization="FULL"` a pixel's continuous voxel index is
//!   computed in fixed point with 14 fractional bits (the matrix's coefficients
//!   rounded to 1/16384 of a voxel), otherwise in double precision.
//! - Nearest neighbour: the voxel at the index rounded half up. MEAN keeps an
//!   accumulation weight of 256 per pixel (16-bit, saturating) and stores
//!   `(in·256 + out·acc) / (acc + 256)`, an 8-bit value floored as an integer
//!   division floors it.
//! - Linear: the 8 voxels around the index with trilinear weights `w`; a pixel
//!   whose 8 voxels are not all inside the volume is left out. With fixed point
//!   the weights are fixed-point products too ([`corner_weight`]). MEAN stores
//!   `(w·in + r·out) / (w + r)` rounded half up, with `r = acc / 256`, and adds
//!   `round(256·w)` to the accumulator. MAXIMUM and LATEST update only voxels
//!   with `w >= 1/8`.
//!
//! A voxel counts as filled (for hole filling) when its accumulator is above zero.

use crate::io::plus::volume_config::{Compounding, Fan, Interpolation, Optimization};

use super::{Grid, Sample};

/// Accumulation weight of one nearest-neighbour pixel (PLUS's `ACCUMULATION_MULTIPLIER`).
pub const ACCUMULATION_UNIT: f64 = 256.0;
/// The accumulator's ceiling (16 bits).
pub const ACCUMULATION_MAX: u32 = 65535;
/// Fractional bits of the fixed-point positions.
const FIXED_BITS: u32 = 14;
const FIXED_ONE: f64 = (1u64 << FIXED_BITS) as f64;
/// Linear MAXIMUM and LATEST update a voxel only above this weight.
const LINEAR_UPDATE_WEIGHT: f64 = 0.125;

/// One frame to insert.
pub struct Slice<'a, T> {
    pub pixels: &'a [T],
    /// Pixel `(column, row, 0, 1)` to mm in the volume's frame.
    pub reference_T_pixel: nalgebra::Matrix4<f64>,
}

/// Which pixels of a frame are inserted, and how.
#[derive(Debug, Clone)]
pub struct PasteSettings {
    pub width: usize,
    pub height: usize,
    /// First and last column and row inserted (inclusive).
    pub clip_px: [usize; 4],
    pub fan: Option<Fan>,
    pub pixel_rejection_threshold: Option<f64>,
    pub interpolation: Interpolation,
    pub compounding: Compounding,
    pub optimization: Optimization,
    /// Per-pixel weights 0–255 (`width * height`), 0: not inserted.
    pub importance_mask: Option<Vec<u8>>,
}

/// The voxels and their accumulated weights.
#[derive(Debug, Clone, PartialEq)]
pub struct Pasted<T> {
    pub voxels: Vec<T>,
    pub weights: Vec<u16>,
    /// Pixels inserted (at least one voxel updated), and accumulator saturations.
    pub pixels_inserted: u64,
    pub saturated: u64,
}

/// Voxel index of pixel (x, y): `a·x + b·y + c` per axis, in fixed or floating point.
#[derive(Debug, Clone, Copy)]
enum Mapper {
    Fixed { a: [i64; 3], b: [i64; 3], c: [i64; 3] },
    Float { a: [f64; 3], b: [f64; 3], c: [f64; 3] },
}

impl Mapper {
    fn new(grid: &Grid, m: &nalgebra::Matrix4<f64>, optimization: Optimization) -> Mapper {
        let a = [0, 1, 2].map(|k| m[(k, 0)] / grid.spacing_mm[k]);
        let b = [0, 1, 2].map(|k| m[(k, 1)] / grid.spacing_mm[k]);
        let c = [0, 1, 2].map(|k| (m[(k, 3)] - grid.origin_mm[k]) / grid.spacing_mm[k]);
        match optimization {
            Optimization::Full => {
                let fix = |v: [f64; 3]| v.map(|x| (x * FIXED_ONE).round() as i64);
                Mapper::Fixed {
                    a: fix(a),
                    b: fix(b),
                    c: fix(c),
                }
            }
            _ => Mapper::Float { a, b, c },
        }
    }

    /// The continuous z index at (x, y), approximately (to skip rows far from a slab).
    #[inline]
    fn z(&self, x: usize, y: usize) -> f64 {
        match self {
            Mapper::Fixed { a, b, c } => (a[2] * x as i64 + b[2] * y as i64 + c[2]) as f64 / FIXED_ONE,
            Mapper::Float { a, b, c } => a[2] * x as f64 + b[2] * y as f64 + c[2],
        }
    }

    #[inline]
    fn nearest(&self, x: usize, y: usize) -> [i64; 3] {
        match self {
            Mapper::Fixed { a, b, c } => {
                let (x, y, half) = (x as i64, y as i64, 1i64 << (FIXED_BITS - 1));
                [
                    (a[0] * x + b[0] * y + c[0] + half) >> FIXED_BITS,
                    (a[1] * x + b[1] * y + c[1] + half) >> FIXED_BITS,
                    (a[2] * x + b[2] * y + c[2] + half) >> FIXED_BITS,
                ]
            }
            Mapper::Float { a, b, c } => {
                [0, 1, 2].map(|k| (a[k] * x as f64 + b[k] * y as f64 + c[k] + 0.5).floor() as i64)
            }
        }
    }

    /// The voxel below the position and the fractions towards the next one, in
    /// 1/16384 of a voxel for fixed point (`None` for floating point).
    fn linear(&self, x: usize, y: usize) -> ([i64; 3], [f64; 3], Option<[i64; 3]>) {
        match self {
            Mapper::Fixed { a, b, c } => {
                let p = [0, 1, 2].map(|k| a[k] * x as i64 + b[k] * y as i64 + c[k]);
                let fixed = p.map(|v| v & ((1 << FIXED_BITS) - 1));
                (
                    p.map(|v| v >> FIXED_BITS),
                    fixed.map(|f| f as f64 / FIXED_ONE),
                    Some(fixed),
                )
            }
            Mapper::Float { a, b, c } => {
                let p = [0, 1, 2].map(|k| a[k] * x as f64 + b[k] * y as f64 + c[k]);
                (p.map(|v| v.floor() as i64), p.map(|v| v - v.floor()), None)
            }
        }
    }
}

/// The trilinear weight of corner `o` (0 or 1 per axis) and its accumulation
/// increment. In fixed point as PLUS computes it: the y and z factors multiplied
/// and rounded to 1/16384, then the x factor; the increment is the weight in
/// 1/256 rounded. In floating point: the plain product, increment `round(256·w)`.
fn corner_weight(o: [usize; 3], frac: [f64; 3], fixed: Option<[i64; 3]>) -> (f64, u32) {
    match fixed {
        Some(f) => {
            let one = 1i64 << FIXED_BITS;
            let half = one >> 1;
            let g = [0, 1, 2].map(|k| if o[k] == 1 { f[k] } else { one - f[k] });
            let yz = (g[1] * g[2] + half) >> FIXED_BITS;
            let w = (yz * g[0] + half) >> FIXED_BITS;
            (
                w as f64 / FIXED_ONE,
                ((w + (1 << (FIXED_BITS - 9))) >> (FIXED_BITS - 8)) as u32,
            )
        }
        None => {
            let w: f64 = (0..3)
                .map(|k| if o[k] == 1 { frac[k] } else { 1.0 - frac[k] })
                .product();
            (w, (w * ACCUMULATION_UNIT).round() as u32)
        }
    }
}

/// Whether pixel (x, y) lies in the fan, tested as PLUS tests it:
/// - below the origin and between the edges, compared by the tangent (`dx/dy`
///   against `tan(angle)` in double precision, so that a pixel exactly on a 45°
///   edge, where `tan` falls short of 1, is outside);
/// - the arcs row by row: in a row, the pixels inside a circle are those strictly
///   between the first and the last pixel whose centre is inside it, that is,
///   those whose neighbour one pixel further from the origin's column is inside
///   (`(|dx| + 1)² + dy² <= radius²`). The start circle's inside is cut away, the
///   stop circle's inside kept.
pub fn in_fan(fan: &Fan, x: usize, y: usize) -> bool {
    let dx = x as f64 - fan.origin_px[0];
    let dy = y as f64 - fan.origin_px[1];
    if dy <= 0.0 {
        return false;
    }
    let outer_squared = (dx.abs() + 1.0).powi(2) + dy * dy;
    let inside = |radius: f64| outer_squared <= radius * radius;
    let slope = dx / dy;
    !inside(fan.radius_start_px)
        && inside(fan.radius_stop_px)
        && slope >= fan.angles_deg[0].to_radians().tan()
        && slope <= fan.angles_deg[1].to_radians().tan()
}

/// The columns inside the clip rectangle and the fan, per row (the same for every frame).
fn region(settings: &PasteSettings) -> Vec<(usize, Vec<usize>)> {
    let [x0, y0, x1, y1] = settings.clip_px;
    (y0..=y1)
        .map(|y| {
            let xs: Vec<usize> = (x0..=x1)
                .filter(|&x| settings.fan.as_ref().is_none_or(|fan| in_fan(fan, x, y)))
                .collect();
            (y, xs)
        })
        .filter(|(_, xs)| !xs.is_empty())
        .collect()
}

/// Pixel (x, y)'s weight (0–1), `None` when it is not inserted (darker than the
/// rejection threshold, or masked out).
#[inline]
fn pixel_weight<T: Sample>(settings: &PasteSettings, value: T, x: usize, y: usize) -> Option<f64> {
    if settings.pixel_rejection_threshold.is_some_and(|t| value.to_f64() < t) {
        return None;
    }
    match &settings.importance_mask {
        Some(mask) => match mask[y * settings.width + x] {
            0 => None,
            m => Some(f64::from(m) / 255.0),
        },
        None => Some(1.0),
    }
}

/// `n / d` rounded down (`d` not zero).
fn floor_div(n: i64, d: i64) -> i64 {
    let q = n / d;
    if n % d != 0 && ((n < 0) != (d < 0)) {
        q - 1
    } else {
        q
    }
}

/// `n / d` rounded up (`d` not zero).
fn ceil_div(n: i64, d: i64) -> i64 {
    -floor_div(-n, d)
}

/// One slab of the volume (z from `z0`, `voxels.len() / plane` planes) with its accumulator.
struct Slab<'a, T> {
    z0: i64,
    planes: i64,
    voxels: &'a mut [T],
    weights: &'a mut [u16],
    saturated: u64,
}

impl<T: Sample> Slab<'_, T> {
    #[inline]
    fn offset(&self, grid: &Grid, v: [i64; 3]) -> Option<usize> {
        let z = v[2] - self.z0;
        (z >= 0 && z < self.planes).then(|| (z as usize * grid.dims[1] + v[1] as usize) * grid.dims[0] + v[0] as usize)
    }

    #[inline]
    fn add_weight(&mut self, i: usize, add: u32) {
        let total = u32::from(self.weights[i]) + add;
        if total > ACCUMULATION_MAX {
            self.saturated += 1;
        }
        self.weights[i] = total.min(ACCUMULATION_MAX) as u16;
    }

    /// Every frame's pixels that can reach this slab, in order; the pixels counted here.
    fn insert_all(
        &mut self,
        grid: &Grid,
        frames: &dyn Frames<T>,
        mappers: &[Mapper],
        region: &[(usize, Vec<usize>)],
        settings: &PasteSettings,
    ) -> u64 {
        let mut inserted = 0u64;
        let (lo, hi) = (self.z0 as f64 - 2.0, (self.z0 + self.planes) as f64 + 1.0);
        for (k, mapper) in mappers.iter().enumerate() {
            // A frame that will never come (its decoding failed): the caller reports why.
            let Some(pixels) = frames.pixels(k) else {
                break;
            };
            for (y, xs) in region {
                let (z_first, z_last) = (mapper.z(xs[0], *y), mapper.z(xs[xs.len() - 1], *y));
                if z_first.max(z_last) < lo || z_first.min(z_last) > hi {
                    continue;
                }
                // z is linear along the row: the pixels near this slab are one run of it.
                let (start, end) = if z_last >= z_first {
                    (
                        xs.partition_point(|&x| mapper.z(x, *y) < lo),
                        xs.partition_point(|&x| mapper.z(x, *y) <= hi),
                    )
                } else {
                    (
                        xs.partition_point(|&x| mapper.z(x, *y) > hi),
                        xs.partition_point(|&x| mapper.z(x, *y) >= lo),
                    )
                };
                let run = &xs[start..end.max(start)];
                if let (Interpolation::NearestNeighbor, Mapper::Fixed { a, b, c }, None) =
                    (settings.interpolation, mapper, &settings.importance_mask)
                {
                    let row = &pixels[y * settings.width..(y + 1) * settings.width];
                    inserted += self.nearest_run_fixed(grid, [*a, *b, *c], *y, run, row, settings);
                    continue;
                }
                for &x in run {
                    let value = pixels[y * settings.width + x];
                    let Some(mask) = pixel_weight(settings, value, x, *y) else {
                        continue;
                    };
                    let here = match settings.interpolation {
                        Interpolation::NearestNeighbor => {
                            self.nearest(grid, mapper.nearest(x, *y), value, mask, settings.compounding)
                        }
                        Interpolation::Linear => {
                            self.linear(grid, mapper.linear(x, *y), value, mask, settings.compounding)
                        }
                    };
                    inserted += u64::from(here);
                }
            }
        }
        inserted
    }

    /// The pixels `run` of row `y` into their nearest voxels, in fixed point and
    /// without a mask: [`Slab::nearest`] with what does not change along the row
    /// taken out of the loop (the same voxels; this is the common case, and the
    /// one PLUS's NN regression settings use). The pixels inserted in this slab.
    fn nearest_run_fixed(
        &mut self,
        grid: &Grid,
        [a, b, c]: [[i64; 3]; 3],
        y: usize,
        run: &[usize],
        row: &[T],
        settings: &PasteSettings,
    ) -> u64 {
        let half = 1i64 << (FIXED_BITS - 1);
        let base = [0, 1, 2].map(|k| b[k] * y as i64 + c[k] + half);
        let dims = grid.dims.map(|d| d as u64);
        let (nx, plane) = (grid.dims[0], grid.dims[0] * grid.dims[1]);
        let add = ACCUMULATION_UNIT as u32;
        let mut inserted = 0;
        // Each index is linear in x: the pixels whose voxel is in the volume and
        // in this slab are those of one interval of x, found once for the row.
        let slab = [self.z0.max(0), (self.z0 + self.planes).min(dims[2] as i64)];
        let (mut x_min, mut x_max) = (i64::MIN, i64::MAX);
        for (k, [lo, hi]) in [[0, dims[0] as i64], [0, dims[1] as i64], slab].into_iter().enumerate() {
            // lo <= (a·x + base) >> FIXED_BITS < hi, as bounds on a·x.
            let (low, high) = ((lo << FIXED_BITS) - base[k], (hi << FIXED_BITS) - 1 - base[k]);
            match a[k].signum() {
                1 => (x_min, x_max) = (x_min.max(ceil_div(low, a[k])), x_max.min(floor_div(high, a[k]))),
                -1 => (x_min, x_max) = (x_min.max(ceil_div(high, a[k])), x_max.min(floor_div(low, a[k]))),
                _ if low > 0 || high < 0 => return 0,
                _ => {}
            }
        }
        let first = run.partition_point(|&x| (x as i64) < x_min);
        let last = run.partition_point(|&x| (x as i64) <= x_max);
        for &x in &run[first..last.max(first)] {
            let value = row[x];
            if settings.pixel_rejection_threshold.is_some_and(|t| value.to_f64() < t) {
                continue;
            }
            let v = [0, 1, 2].map(|k| (a[k] * x as i64 + base[k]) >> FIXED_BITS);
            debug_assert!((0..3).all(|k| (v[k] as u64) < dims[k]) && v[2] >= slab[0] && v[2] < slab[1]);
            let i = (v[2] - self.z0) as usize * plane + v[1] as usize * nx + v[0] as usize;
            match settings.compounding {
                Compounding::Mean => {
                    self.voxels[i] = T::mean_update(value, self.voxels[i], u32::from(self.weights[i]), add);
                }
                Compounding::Latest => self.voxels[i] = value,
                Compounding::Maximum => {
                    if value > self.voxels[i] || self.weights[i] == 0 {
                        self.voxels[i] = value;
                    }
                }
            }
            self.add_weight(i, add);
            inserted += 1;
        }
        inserted
    }

    /// Inserts a pixel into its nearest voxel if that is in this slab; true then.
    #[inline]
    fn nearest(&mut self, grid: &Grid, v: [i64; 3], value: T, mask: f64, mode: Compounding) -> bool {
        if (0..3).any(|k| v[k] < 0 || v[k] >= grid.dims[k] as i64) {
            return false;
        }
        let Some(i) = self.offset(grid, v) else {
            return false;
        };
        let add = if mask < 1.0 {
            (ACCUMULATION_UNIT * mask).round() as u32
        } else {
            ACCUMULATION_UNIT as u32
        };
        let acc = u32::from(self.weights[i]);
        match mode {
            Compounding::Mean => {
                if add + acc > 0 {
                    self.voxels[i] = T::mean_update(value, self.voxels[i], acc, add);
                }
            }
            Compounding::Latest => self.voxels[i] = value,
            Compounding::Maximum => {
                if value > self.voxels[i] || self.weights[i] == 0 {
                    self.voxels[i] = value;
                }
            }
        }
        self.add_weight(i, add);
        true
    }

    /// Inserts a pixel into those of its 8 voxels in this slab; true when all 8
    /// are in the volume and the lowest is in this slab (the pixel counts here).
    fn linear(
        &mut self,
        grid: &Grid,
        position: ([i64; 3], [f64; 3], Option<[i64; 3]>),
        value: T,
        mask: f64,
        mode: Compounding,
    ) -> bool {
        let (base, frac, fixed) = position;
        let far = [0, 1, 2].map(|k| base[k] + i64::from(frac[k] > 0.0));
        if (0..3).any(|k| base[k] < 0 || far[k] >= grid.dims[k] as i64) {
            return false;
        }
        for corner in 0..8 {
            let o = [corner & 1, (corner >> 1) & 1, (corner >> 2) & 1];
            let (w, add) = corner_weight(o, frac, fixed);
            let (w, add) = if mask < 1.0 {
                (w * mask, (f64::from(add) * mask).round() as u32)
            } else {
                (w, add)
            };
            if w <= 0.0 {
                continue;
            }
            let Some(i) = self.offset(grid, [0, 1, 2].map(|k| base[k] + o[k] as i64)) else {
                continue;
            };
            match mode {
                Compounding::Mean => {
                    let r = f64::from(self.weights[i]) / ACCUMULATION_UNIT;
                    self.voxels[i] = T::from_round((w * value.to_f64() + r * self.voxels[i].to_f64()) / (w + r));
                    self.add_weight(i, add);
                }
                Compounding::Maximum | Compounding::Latest if w >= LINEAR_UPDATE_WEIGHT => {
                    if mode == Compounding::Latest || value > self.voxels[i] || self.weights[i] == 0 {
                        self.voxels[i] = value;
                    }
                    self.add_weight(i, add);
                }
                _ => {}
            }
        }
        base[2] >= self.z0 && base[2] < self.z0 + self.planes
    }
}

/// Inserts the slices in order into a zeroed volume, split over `threads` slabs of
/// z planes (the result does not depend on `threads`).
pub fn paste<T: Sample>(grid: &Grid, slices: &[Slice<T>], settings: &PasteSettings, threads: usize) -> Pasted<T> {
    let mut pasted = Pasted::zeroed(grid);
    paste_into(grid, &mut pasted, slices, settings, threads);
    pasted
}

impl<T: Sample> Pasted<T> {
    /// An empty volume of `grid`: no voxel reached.
    pub fn zeroed(grid: &Grid) -> Pasted<T> {
        Pasted {
            voxels: vec![T::default(); grid.voxels()],
            weights: vec![0u16; grid.voxels()],
            pixels_inserted: 0,
            saturated: 0,
        }
    }
}

/// Inserts the slices in order into `pasted` (a volume of `grid`): frames
/// inserted one call at a time give the volume one call with all of them gives.
pub fn paste_into<T: Sample>(
    grid: &Grid,
    pasted: &mut Pasted<T>,
    slices: &[Slice<T>],
    settings: &PasteSettings,
    threads: usize,
) {
    let matrices: Vec<_> = slices.iter().map(|s| s.reference_T_pixel).collect();
    paste_frames(grid, pasted, &matrices, &slices, settings, threads);
}

/// Frames to paste, by their place in the paste order.
pub trait Frames<T>: Sync {
    /// Frame `k`'s pixels (`width * height`), waited for if they are still being
    /// decoded; `None` when they will not come (their decoding failed).
    fn pixels(&self, k: usize) -> Option<&[T]>;
}

impl<T: Sync> Frames<T> for &[Slice<'_, T>] {
    fn pixels(&self, k: usize) -> Option<&[T]> {
        self.get(k).map(|s| s.pixels)
    }
}

/// [`paste_into`] with the frames' poses (`reference_T_pixel`, in paste order)
/// apart from their pixels, which `frames` gives as they come: each slab takes
/// the frames in order, so the volume is the one all frames at once give. A
/// frame that does not come ends the pasting there.
pub fn paste_frames<T: Sample>(
    grid: &Grid,
    pasted: &mut Pasted<T>,
    reference_T_pixel: &[nalgebra::Matrix4<f64>],
    frames: &dyn Frames<T>,
    settings: &PasteSettings,
    threads: usize,
) {
    let plane = grid.dims[0] * grid.dims[1];
    let region = region(settings);
    let mappers: Vec<Mapper> = reference_T_pixel
        .iter()
        .map(|m| Mapper::new(grid, m, settings.optimization))
        .collect();
    // One slab per worker (each maps only the run of a row that reaches it).
    let planes_per_slab = grid.dims[2].div_ceil(threads.max(1)).max(1);
    let (voxels, weights) = (&mut pasted.voxels, &mut pasted.weights);
    let (saturated, pixels_inserted): (u64, u64) = super::in_pool(threads, || {
        use rayon::prelude::*;
        voxels
            .par_chunks_mut(plane * planes_per_slab)
            .zip(weights.par_chunks_mut(plane * planes_per_slab))
            .enumerate()
            .map(|(n, (voxels, weights))| {
                let mut slab = Slab {
                    z0: (n * planes_per_slab) as i64,
                    planes: (voxels.len() / plane) as i64,
                    voxels,
                    weights,
                    saturated: 0,
                };
                let inserted = slab.insert_all(grid, frames, &mappers, &region, settings);
                (slab.saturated, inserted)
            })
            .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
    });
    pasted.pixels_inserted += pixels_inserted;
    pasted.saturated += saturated;
}

#[cfg(test)]
mod tests;
