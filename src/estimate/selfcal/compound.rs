//! Sweeps compounded on one grid, and their agreement.
//!
//! Each value is splatted trilinearly (its weight shared among the eight voxels
//! around its position), so a volume moves continuously with the calibration;
//! a voxel holds a sweep's value where that sweep's weight there is at least
//! [`Comparison::min_weight`].

use nalgebra::{Matrix4, Point3, Vector3};

use super::Sweep;

/// The largest grid accepted, voxels (two f32 per voxel per sweep).
pub const MAX_VOXELS: usize = 40_000_000;

/// The grid the sweeps are compounded on (axis-aligned in the Reference frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SplatGrid {
    pub origin_mm: [f64; 3],
    pub voxel_mm: f64,
    pub dims: [usize; 3],
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GridFault {
    #[error("the sweeps span {dims:?} voxels of {voxel_mm} mm, more than {MAX_VOXELS}: a larger voxel, or sweeps that belong together")]
    TooLarge { dims: [usize; 3], voxel_mm: f64 },
    #[error("the voxel size {0} mm is not a positive finite number")]
    Voxel(f64),
    #[error("a frame's pose or the calibration puts a pixel at a non-finite position")]
    NotFinite,
}

impl SplatGrid {
    /// The box around every sample of every sweep placed by `probe_T_pixel`,
    /// with `margin_mm` on each side.
    pub fn around(
        sweeps: &[Sweep],
        probe_T_pixel: &Matrix4<f64>,
        voxel_mm: f64,
        margin_mm: f64,
    ) -> Result<SplatGrid, GridFault> {
        if !(voxel_mm.is_finite() && voxel_mm > 0.0) {
            return Err(GridFault::Voxel(voxel_mm));
        }
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for sweep in sweeps {
            let corners = bounding_pixels(&sweep.samples_px);
            for frame in &sweep.frames {
                let m = frame.reference_T_probe * probe_T_pixel;
                for c in &corners {
                    let p = m.transform_point(&Point3::new(c[0], c[1], 0.0));
                    for k in 0..3 {
                        lo[k] = lo[k].min(p[k]);
                        hi[k] = hi[k].max(p[k]);
                    }
                }
            }
        }
        if lo.iter().chain(&hi).any(|v| !v.is_finite()) {
            return Err(GridFault::NotFinite);
        }
        let origin_mm = [lo[0] - margin_mm, lo[1] - margin_mm, lo[2] - margin_mm];
        let mut dims = [0usize; 3];
        for k in 0..3 {
            dims[k] = ((hi[k] - lo[k] + 2.0 * margin_mm) / voxel_mm).ceil() as usize + 2;
        }
        if dims
            .iter()
            .try_fold(1usize, |a, &d| a.checked_mul(d))
            .is_none_or(|n| n > MAX_VOXELS)
        {
            return Err(GridFault::TooLarge { dims, voxel_mm });
        }
        Ok(SplatGrid {
            origin_mm,
            voxel_mm,
            dims,
        })
    }

    pub fn voxels(&self) -> usize {
        self.dims[0] * self.dims[1] * self.dims[2]
    }
}

fn bounding_pixels(samples: &[[f64; 2]]) -> [[f64; 2]; 4] {
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for s in samples {
        for k in 0..2 {
            lo[k] = lo[k].min(s[k]);
            hi[k] = hi[k].max(s[k]);
        }
    }
    [[lo[0], lo[1]], [hi[0], lo[1]], [lo[0], hi[1]], [hi[0], hi[1]]]
}

/// A sweep compounded: weighted sums and weights per voxel.
pub struct Splat {
    pub sum: Vec<f32>,
    pub weight: Vec<f32>,
}

impl Splat {
    /// Nothing splatted on `grid` yet.
    pub fn empty(grid: &SplatGrid) -> Splat {
        Splat {
            sum: vec![0.0; grid.voxels()],
            weight: vec![0.0; grid.voxels()],
        }
    }
}

/// Splats every frame of `sweep` placed by `probe_T_pixel` (frames outside the
/// grid are clipped voxel by voxel).
pub fn splat(grid: &SplatGrid, sweep: &Sweep, probe_T_pixel: &Matrix4<f64>, frames: Option<&[usize]>) -> Splat {
    let n = grid.voxels();
    let mut out = Splat {
        sum: vec![0.0; n],
        weight: vec![0.0; n],
    };
    let [nx, ny, nz] = grid.dims;
    let inv = 1.0 / grid.voxel_mm;
    let o = Vector3::from(grid.origin_mm);
    let all: Vec<usize>;
    let chosen = match frames {
        Some(f) => f,
        None => {
            all = (0..sweep.frames.len()).collect();
            &all
        }
    };
    for &fi in chosen {
        let frame = &sweep.frames[fi];
        let m = frame.reference_T_probe * probe_T_pixel;
        let base = (m.fixed_view::<3, 1>(0, 3).into_owned() - o) * inv;
        let du = m.fixed_view::<3, 1>(0, 0).into_owned() * inv;
        let dv = m.fixed_view::<3, 1>(0, 1).into_owned() * inv;
        for (s, &value) in sweep.samples_px.iter().zip(&frame.values) {
            let g = base + du * s[0] + dv * s[1];
            let (fx, fy, fz) = (g[0].floor(), g[1].floor(), g[2].floor());
            if !(fx >= 0.0 && fy >= 0.0 && fz >= 0.0) {
                continue;
            }
            let (ix, iy, iz) = (fx as usize, fy as usize, fz as usize);
            if ix + 1 >= nx || iy + 1 >= ny || iz + 1 >= nz {
                continue;
            }
            let (ax, ay, az) = ((g[0] - fx) as f32, (g[1] - fy) as f32, (g[2] - fz) as f32);
            let i0 = (iz * ny + iy) * nx + ix;
            for (dz, wz) in [(0, 1.0 - az), (nx * ny, az)] {
                for (dy, wy) in [(0, 1.0 - ay), (nx, ay)] {
                    let w = wz * wy;
                    let i = i0 + dz + dy;
                    out.sum[i] += w * (1.0 - ax) * value;
                    out.weight[i] += w * (1.0 - ax);
                    out.sum[i + 1] += w * ax * value;
                    out.weight[i + 1] += w * ax;
                }
            }
        }
    }
    out
}

/// How the sweeps are compared.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Comparison {
    pub voxel_mm: f64,
    /// A voxel counts for a sweep where its splatted weight is at least this
    /// (in samples: 1 is one sample's whole weight).
    pub min_weight: f32,
}

/// Which voxels every sweep covers under one calibration.
pub fn common_voxels(splats: &[Splat], min_weight: f32) -> Vec<u32> {
    let n = splats.first().map_or(0, |s| s.weight.len());
    (0..n)
        .filter(|&i| splats.iter().all(|s| s.weight[i] >= min_weight))
        .map(|i| i as u32)
        .collect()
}

/// A sweep's values at `voxels` (0 where it has no weight), and whether it
/// covers each.
pub fn values_at(splat: &Splat, voxels: &[u32], min_weight: f32) -> (Vec<f64>, Vec<bool>) {
    voxels
        .iter()
        .map(|&i| {
            let w = splat.weight[i as usize];
            let v = if w > 0.0 {
                f64::from(splat.sum[i as usize] / w)
            } else {
                0.0
            };
            (v, w >= min_weight)
        })
        .unzip()
}

/// `values` standardised (mean 0, SD 1) over the entries `keep` marks.
pub fn standardised(values: &[f64], keep: &[bool]) -> Vec<f64> {
    standardise(values.iter().zip(keep).filter(|(_, &k)| k).map(|(v, _)| *v).collect())
}

pub fn standardise(mut v: Vec<f64>) -> Vec<f64> {
    let n = v.len().max(1) as f64;
    let mean = v.iter().sum::<f64>() / n;
    let sd = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n).sqrt();
    let scale = if sd > 0.0 { 1.0 / sd } else { 0.0 };
    for x in &mut v {
        *x = (*x - mean) * scale;
    }
    v
}

/// The normalised correlation of two standardised vectors.
pub fn correlation(a: &[f64], b: &[f64]) -> f64 {
    if a.is_empty() {
        return 0.0;
    }
    a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>() / a.len() as f64
}
