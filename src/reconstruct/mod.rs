//! Freehand 3D reconstruction: tracked B-scans into a voxel volume, as PLUS's
//! `VolumeReconstructor` does, so that a calibration can be seen at work.
//!
//! The stages, one file each, typed in and out:
//!
//! 1. [`poses`]: each frame's `reference_T_image` (pixel to mm in the Reference
//!    frame) from the sequence's tracker transforms and the device set's fixed
//!    ones; frames whose transforms are missing or not OK are skipped with the reason.
//! 2. [`grid`]: the output volume's origin, spacing and size, given or fitted to
//!    the clipped frames.
//! 3. [`paste`]: every kept pixel into the nearest voxel or the 8 around it,
//!    values compounded (mean, latest, maximum) with an accumulation buffer.
//! 4. [`holes`]: voxels no pixel reached, filled by PLUS's hole-filling elements.
//!
//! Each stage is deterministic and the volume is the same whatever the number of
//! threads: work is split by output slabs, and every voxel sees its pixels in
//! frame, row, column order.

pub mod arrivals;
pub mod grid;
pub mod holes;
pub mod near;
pub mod paste;
pub mod poses;

use std::path::PathBuf;

pub use grid::Grid;

/// A voxel or pixel value: 8-bit grey or 32-bit float, as PLUS reconstructs both.
pub trait Sample: Copy + Default + PartialOrd + Send + Sync + 'static {
    /// MetaImage element type.
    const ELEMENT_TYPE: &'static str;
    fn to_f64(self) -> f64;
    /// A computed value stored as PLUS stores it after an integer division
    /// (8-bit: the floor, clamped to 0–255).
    fn from_floor(v: f64) -> Self;
    /// A computed value stored rounded half up (8-bit: clamped to 0–255).
    fn from_round(v: f64) -> Self;
    /// Little-endian bytes of a slice of samples.
    fn write_le(values: &[Self], out: &mut Vec<u8>);
    /// Nearest-neighbour MEAN: `(value·add + old·acc) / (acc + add)`, stored as
    /// [`Sample::from_floor`] stores it (`acc + add > 0`).
    fn mean_update(value: Self, old: Self, acc: u32, add: u32) -> Self {
        Self::from_floor((value.to_f64() * f64::from(add) + old.to_f64() * f64::from(acc)) / f64::from(acc + add))
    }
}

impl Sample for u8 {
    const ELEMENT_TYPE: &'static str = "MET_UCHAR";
    fn to_f64(self) -> f64 {
        f64::from(self)
    }
    fn from_floor(v: f64) -> Self {
        v.floor().clamp(0.0, 255.0) as u8
    }
    fn from_round(v: f64) -> Self {
        (v + 0.5).floor().clamp(0.0, 255.0) as u8
    }
    fn write_le(values: &[Self], out: &mut Vec<u8>) {
        out.extend_from_slice(values);
    }
    /// The integer division itself (the same value as the floor of the quotient).
    /// A whole pixel onto whole pixels (`add` 256, `acc` k·256, PLUS's nearest
    /// neighbour without a mask) is `(value + old·k) / (k + 1)`, done as a
    /// multiplication by the exact reciprocal (a unit test holds the two equal).
    #[inline]
    fn mean_update(value: Self, old: Self, acc: u32, add: u32) -> Self {
        if add == 256 && acc.is_multiple_of(256) {
            let k = acc >> 8;
            let n = u64::from(value) + u64::from(old) * u64::from(k);
            return ((n * RECIPROCALS[k as usize]) >> 32) as u8;
        }
        ((u32::from(value) * add + u32::from(old) * acc) / (acc + add)) as u8
    }
}

/// `floor(2^32 / (k + 1)) + 1` for k = 0..=255: `(n · r_k) >> 32` is
/// `n / (k + 1)` floored for every n below 2^16 (the error stays under 2^-16,
/// less than 1/(k + 1)).
static RECIPROCALS: [u64; 256] = {
    let mut r = [0u64; 256];
    let mut k = 0;
    while k < 256 {
        r[k] = (1u64 << 32) / (k as u64 + 1) + 1;
        k += 1;
    }
    r
};

impl Sample for f32 {
    const ELEMENT_TYPE: &'static str = "MET_FLOAT";
    fn to_f64(self) -> f64 {
        f64::from(self)
    }
    fn from_floor(v: f64) -> Self {
        v as f32
    }
    fn from_round(v: f64) -> Self {
        v as f32
    }
    fn write_le(values: &[Self], out: &mut Vec<u8>) {
        for v in values {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
}

/// A reconstructed volume: voxels x fastest, then y, then z.
#[derive(Debug, Clone, PartialEq)]
pub struct Volume<T> {
    pub grid: Grid,
    pub voxels: Vec<T>,
}

/// Why a reconstruction could not be made (nothing is written then).
#[derive(Debug, thiserror::Error)]
pub enum ReconstructError {
    #[error(transparent)]
    Sequence(#[from] crate::io::plus::sequence::SequenceError),
    #[error(transparent)]
    Config(#[from] crate::io::plus::config::ConfigError),
    #[error("{path}: {message}")]
    Input { path: PathBuf, message: String },
    #[error("{0}")]
    Grid(#[from] grid::GridError),
    #[error("no frame can be inserted: {0}")]
    NoFrames(String),
}

/// Runs `job` on a pool of `threads` workers (its parallel loops split the
/// volume into pieces whose results do not depend on who computes them).
pub(crate) fn in_pool<R: Send>(threads: usize, job: impl FnOnce() -> R + Send) -> R {
    match rayon::ThreadPoolBuilder::new().num_threads(threads.max(1)).build() {
        Ok(pool) => pool.install(job),
        Err(_) => job(),
    }
}

/// A volume and what its stages did.
#[derive(Debug, Clone, PartialEq)]
pub struct Output<T> {
    pub volume: Volume<T>,
    pub pixels_inserted: u64,
    /// Voxel updates that hit the accumulator's ceiling.
    pub accumulator_saturated: u64,
    pub holes: holes::HoleStats,
    /// (stage, seconds).
    pub timings: Vec<(String, f64)>,
}

/// Distribution then hole filling, over `threads` workers (the volume does not
/// depend on their number).
pub fn reconstruct<T: Sample>(
    grid: &Grid,
    slices: &[paste::Slice<T>],
    settings: &paste::PasteSettings,
    hole_filling: &[crate::io::plus::volume_config::HoleFilling],
    threads: usize,
) -> Output<T> {
    let matrices: Vec<_> = slices.iter().map(|s| s.reference_T_pixel).collect();
    reconstruct_frames(grid, &matrices, &slices, settings, hole_filling, threads)
}

/// [`reconstruct`] with the frames' poses apart from their pixels, which may
/// still be arriving ([`paste::paste_frames`]).
pub fn reconstruct_frames<T: Sample>(
    grid: &Grid,
    reference_T_pixel: &[nalgebra::Matrix4<f64>],
    frames: &dyn paste::Frames<T>,
    settings: &paste::PasteSettings,
    hole_filling: &[crate::io::plus::volume_config::HoleFilling],
    threads: usize,
) -> Output<T> {
    let clock = std::time::Instant::now();
    let mut pasted = paste::Pasted::zeroed(grid);
    paste::paste_frames(grid, &mut pasted, reference_T_pixel, frames, settings, threads);
    let paste_s = clock.elapsed().as_secs_f64();
    let clock = std::time::Instant::now();
    let mut voxels = pasted.voxels;
    let holes = holes::fill(grid, &mut voxels, &pasted.weights, hole_filling, threads);
    Output {
        volume: Volume { grid: *grid, voxels },
        pixels_inserted: pasted.pixels_inserted,
        accumulator_saturated: pasted.saturated,
        holes,
        timings: vec![
            ("paste".to_string(), paste_s),
            ("hole filling".to_string(), clock.elapsed().as_secs_f64()),
        ],
    }
}

#[cfg(test)]
mod tests {
    use super::Sample;

    #[test]
    fn the_whole_pixel_mean_is_the_integer_division() {
        let mut wrong = Vec::new();
        for k in 0..=255u32 {
            for old in 0..=255u8 {
                for value in 0..=255u8 {
                    let want = ((u32::from(value) * 256 + u32::from(old) * k * 256) / (k * 256 + 256)) as u8;
                    if u8::mean_update(value, old, k * 256, 256) != want {
                        wrong.push((k, old, value));
                    }
                }
            }
        }
        assert!(wrong.is_empty(), "{} cases, first {:?}", wrong.len(), wrong.first());
        // Other weights take the division.
        assert_eq!(
            u8::mean_update(200, 100, 300, 128),
            ((200 * 128 + 100 * 300) / 428) as u8
        );
    }
}
