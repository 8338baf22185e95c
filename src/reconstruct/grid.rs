//! The output volume's geometry: where voxel (0, 0, 0) is, the spacing and the
//! size, given by the settings or fitted to the clipped frames as PLUS fits it.

use nalgebra::{Matrix4, Vector4};

/// The largest volume accepted, in voxels (2^30: 1 GiB of 8-bit voxels plus
/// 2 GiB of accumulation buffer). A bigger one is a typo in the spacing or the
/// extent, or needs a coarser spacing.
pub const MAX_VOXELS: usize = 1 << 30;

/// Bytes a reconstruction may hold at once, the frames it is made from
/// included: 6 GiB, within an 8 GiB address space with the program's own.
pub const MAX_WORK_BYTES: u64 = 6 << 30;

/// Bytes the work on a volume of `voxels` holds: the voxels (`sample_bytes`
/// each), their weights (2), the copy written out, and with hole filling the
/// copy it reads from and its reach mask (1).
pub fn volume_work_bytes(voxels: usize, sample_bytes: u64, hole_filling: bool) -> u64 {
    let per_voxel = 2 * sample_bytes + 2 + if hole_filling { sample_bytes + 1 } else { 0 };
    (voxels as u64).saturating_mul(per_voxel)
}

/// Why a volume of `voxels` cannot be made beside `frames_bytes` of frames
/// within [`MAX_WORK_BYTES`], if it cannot.
pub fn budget_fault(voxels: usize, sample_bytes: u64, hole_filling: bool, frames_bytes: u64) -> Option<String> {
    let volume = volume_work_bytes(voxels, sample_bytes, hole_filling);
    let gib = |b: u64| b as f64 / (1u64 << 30) as f64;
    (volume.saturating_add(frames_bytes) > MAX_WORK_BYTES).then(|| {
        format!(
            "the volume's {voxels} voxels need {:.2} GiB (voxels, weights{}, the written copy) beside the frames' {:.2} GiB: \
             more than the {:.0} GiB a reconstruction may hold; increase OutputSpacing or give a smaller OutputExtent",
            gib(volume),
            if hole_filling { ", hole filling" } else { "" },
            gib(frames_bytes),
            gib(MAX_WORK_BYTES)
        )
    })
}

/// A regular grid in the Reference frame, axes parallel to its axes.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Grid {
    /// Centre of voxel (0, 0, 0), mm (MetaImage `Offset`).
    pub origin_mm: [f64; 3],
    pub spacing_mm: [f64; 3],
    pub dims: [usize; 3],
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GridError {
    #[error(
        "the volume would have {voxels} voxels ({dims:?}), more than the {MAX_VOXELS} allowed: \
         increase OutputSpacing or give a smaller OutputExtent"
    )]
    TooLarge { dims: [u64; 3], voxels: u128 },
    #[error("the frames' extent is not finite: a transform holds an absurd value")]
    NotFinite,
}

impl Grid {
    pub fn voxels(&self) -> usize {
        self.dims.iter().product()
    }

    /// The grid `OutputOrigin` and `OutputExtent` describe: voxel index `i` of
    /// the extent `[lo, hi]` is at `origin + i · spacing`.
    pub fn from_extent(origin_mm: [f64; 3], spacing_mm: [f64; 3], extent: [i64; 6]) -> Result<Grid, GridError> {
        let dims = [0, 1, 2].map(|a| (extent[2 * a + 1] - extent[2 * a] + 1) as u64);
        Grid::checked(
            [0, 1, 2].map(|a| origin_mm[a] + extent[2 * a] as f64 * spacing_mm[a]),
            spacing_mm,
            dims,
        )
    }

    /// The grid that holds every frame's clip rectangle: origin at the smallest
    /// corner coordinate, `round(size / spacing) + 1` voxels per axis.
    ///
    /// The rectangle's corners are those PLUS uses: from `clip_origin` to
    /// `clip_origin + clip_size`, bounded by the frame's last column and row; its
    /// reference volumes' geometry comes out of exactly these corners and this
    /// rounding (`docs/reconstruction.md`).
    pub fn fit(
        reference_T_pixel: &[Matrix4<f64>],
        clip_origin_px: [usize; 2],
        clip_far_px: [usize; 2],
        spacing_mm: [f64; 3],
    ) -> Result<Grid, GridError> {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        let (x0, y0) = (clip_origin_px[0] as f64, clip_origin_px[1] as f64);
        let (x1, y1) = (clip_far_px[0] as f64, clip_far_px[1] as f64);
        for m in reference_T_pixel {
            for (x, y) in [(x0, y0), (x1, y0), (x0, y1), (x1, y1)] {
                let p = m * Vector4::new(x, y, 0.0, 1.0);
                for a in 0..3 {
                    lo[a] = lo[a].min(p[a]);
                    hi[a] = hi[a].max(p[a]);
                }
            }
        }
        if lo.iter().chain(&hi).any(|v| !v.is_finite()) {
            return Err(GridError::NotFinite);
        }
        // `as` saturates a huge quotient; the sum must not overflow past it.
        let dims = [0, 1, 2].map(|a| (((hi[a] - lo[a]) / spacing_mm[a]).round() as u64).saturating_add(1));
        Grid::checked(lo, spacing_mm, dims)
    }

    fn checked(origin_mm: [f64; 3], spacing_mm: [f64; 3], dims: [u64; 3]) -> Result<Grid, GridError> {
        let voxels = dims.iter().map(|&d| u128::from(d)).product::<u128>();
        if voxels > MAX_VOXELS as u128 || dims.contains(&0) {
            return Err(GridError::TooLarge { dims, voxels });
        }
        Ok(Grid {
            origin_mm,
            spacing_mm,
            dims: dims.map(|d| d as usize),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fit_holds_the_corners_and_refuses_absurd_sizes() {
        // One frame, 0.1 mm pixels, shifted by (5, 6, 7) mm.
        let m = Matrix4::new(
            0.1, 0.0, 0.0, 5.0, 0.0, 0.1, 0.0, 6.0, 0.0, 0.0, 0.1, 7.0, 0.0, 0.0, 0.0, 1.0,
        );
        let g = Grid::fit(&[m], [0, 0], [99, 49], [0.5, 0.5, 0.5]).unwrap();
        assert_eq!(g.origin_mm, [5.0, 6.0, 7.0]);
        assert_eq!(g.dims, [21, 11, 1], "9.9 mm / 0.5 mm: 19.8, 20 steps, 21 voxels");
        let tiny = [1e-4, 1e-4, 1e-4];
        assert!(matches!(
            Grid::fit(&[m], [0, 0], [99, 49], tiny),
            Err(GridError::TooLarge { .. })
        ));
        // A spacing that makes the count leave u64: refused, not overflowed.
        assert!(matches!(
            Grid::fit(&[m], [0, 0], [99, 49], [1e-300; 3]),
            Err(GridError::TooLarge { .. })
        ));
        let g = Grid::from_extent([1.0, 2.0, 3.0], [0.5, 0.5, 0.5], [2, 11, 0, 9, -1, 1]).unwrap();
        assert_eq!((g.origin_mm, g.dims), ([2.0, 2.0, 2.5], [10, 10, 3]));
    }
}
