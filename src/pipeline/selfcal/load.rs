//! Tracked sequences into sweeps: each frame's `reference_T_probe` (PLUS's
//! transform chain with the calibration left out) and its pixels averaged in
//! blocks, the drawn overlay (bright in every frame) left out.

use std::path::{Path, PathBuf};

use nalgebra::Matrix4;

use crate::detect::overlay::Overlay;
use crate::estimate::selfcal::{Sweep, SweepFrame};
use crate::io::plus::config::PlusConfig;
use crate::io::plus::sequence::Sequence;
use crate::reconstruct::poses::{frame_poses, SkippedFrame};

use super::SelfcalError;

/// Where a sweep came from and what was left out of it.
#[derive(Debug, Clone)]
pub struct LoadedSweep {
    pub path: PathBuf,
    pub image_size_px: [usize; 2],
    pub frames_total: usize,
    pub skipped: Vec<SkippedFrame>,
    /// Blocks left out: touching the drawn overlay.
    pub blocks_left_out: usize,
    pub blocks: usize,
}

/// The frame names the transform chain runs between, and the clip rectangle
/// (column, row, width, height; the whole image when `None`).
#[derive(Debug, Clone)]
pub struct Framing {
    pub image_frame: String,
    pub reference_frame: String,
    pub clip_px: Option<[usize; 4]>,
}

/// Reads `path` into a sweep of `block_px`-square block means, poses read
/// `tracker_lag_s` after each image's time.
pub fn load(
    path: &Path,
    config: &PlusConfig,
    framing: &Framing,
    block_px: usize,
    background_blocks: usize,
    tracker_lag_s: f64,
) -> Result<(Sweep, LoadedSweep), SelfcalError> {
    let sequence = Sequence::read(path)?;
    if sequence.is_float() {
        return Err(SelfcalError::Input {
            path: path.to_path_buf(),
            message: "float pixels: selfcal compares 8-bit B-scans".into(),
        });
    }
    let (w, h) = (sequence.width, sequence.height);
    let [cx, cy, cw, ch] = framing.clip_px.unwrap_or([0, 0, w, h]);
    if cw == 0 || ch == 0 || cx + cw > w || cy + ch > h {
        return Err(SelfcalError::Input {
            path: path.to_path_buf(),
            message: format!(
                "the clip rectangle {:?} is not inside the {w}x{h} images",
                [cx, cy, cw, ch]
            ),
        });
    }
    let (poses, skipped) = frame_poses(
        &sequence,
        config,
        &framing.image_frame,
        &framing.reference_frame,
        1,
        Some(Matrix4::identity()),
        tracker_lag_s,
    );
    let overlay = Overlay::find(
        (0..sequence.frames.len()).map(|i| sequence.pixels(i)),
        [w, h],
        None,
        10.0,
        block_px,
    );
    let b = block_px.max(1);
    let (blocks, columns) = block_corners([cx, cy, cw, ch], b);
    let mean_of = |pixels: &[u8], (bx, by): (usize, usize)| -> f32 {
        let mut s = 0u32;
        for y in by..by + b {
            s += pixels[y * w + bx..y * w + bx + b]
                .iter()
                .map(|&p| u32::from(p))
                .sum::<u32>();
        }
        s as f32 / (b * b) as f32
    };
    let all: Vec<Vec<f32>> = poses
        .iter()
        .map(|p| {
            let means: Vec<f32> = blocks
                .iter()
                .map(|&blk| mean_of(sequence.pixels(p.index), blk))
                .collect();
            match background_blocks {
                0 => means,
                k => less_background(&means, columns, k),
            }
        })
        .collect();
    let keep = off_overlay(overlay.as_ref(), &blocks, b, w);
    let half = (b as f64 - 1.0) / 2.0;
    let samples_px = blocks
        .iter()
        .zip(&keep)
        .filter(|(_, &k)| k)
        .map(|(&(bx, by), _)| [bx as f64 + half, by as f64 + half])
        .collect();
    let frames = poses
        .iter()
        .zip(all)
        .map(|(p, values)| kept_frame(p, values, &keep))
        .collect();
    let sweep = Sweep {
        name: crate::io::fs::display_path(path),
        samples_px,
        frames,
    };
    let source = LoadedSweep {
        path: path.to_path_buf(),
        image_size_px: [w, h],
        frames_total: sequence.frames.len(),
        skipped,
        blocks_left_out: keep.iter().filter(|&&k| !k).count(),
        blocks: blocks.len(),
    };
    Ok((sweep, source))
}

/// A frame's pose and the values of its kept blocks.
fn kept_frame(pose: &crate::reconstruct::poses::FramePose, values: Vec<f32>, keep: &[bool]) -> SweepFrame {
    SweepFrame {
        index: pose.index,
        reference_T_probe: pose.reference_T_pixel,
        values: values
            .into_iter()
            .zip(keep)
            .filter(|(_, &k)| k)
            .map(|(v, _)| v)
            .collect(),
    }
}

/// Which blocks touch no pixel of the drawn overlay (all where none was found).
fn off_overlay(overlay: Option<&Overlay>, blocks: &[(usize, usize)], b: usize, w: usize) -> Vec<bool> {
    blocks
        .iter()
        .map(|&(bx, by)| !overlay.is_some_and(|o| (by..by + b).any(|y| (bx..bx + b).any(|x| o.mask[y * w + x]))))
        .collect()
}

/// The top-left pixels of the `b`-square blocks that fit in the clip
/// rectangle, row by row, and how many there are in a row.
fn block_corners([cx, cy, cw, ch]: [usize; 4], b: usize) -> (Vec<(usize, usize)>, usize) {
    let mut blocks = Vec::new();
    let mut columns = 0;
    for by in (cy..cy + ch + 1 - b.min(ch)).step_by(b) {
        columns = 0;
        for bx in (cx..cx + cw + 1 - b.min(cw)).step_by(b) {
            blocks.push((bx, by));
            columns += 1;
        }
    }
    (blocks, columns)
}

/// Each block less the mean of the `(2k+1)²` blocks around it (as many as lie
/// in the image): the echoes kept, the slow changes of brightness (gain with
/// depth, haze) taken away.
fn less_background(values: &[f32], columns: usize, k: usize) -> Vec<f32> {
    let rows = values.len() / columns.max(1);
    // Summed-area table.
    let mut sat = vec![0f64; (rows + 1) * (columns + 1)];
    for r in 0..rows {
        for c in 0..columns {
            sat[(r + 1) * (columns + 1) + c + 1] =
                f64::from(values[r * columns + c]) + sat[r * (columns + 1) + c + 1] + sat[(r + 1) * (columns + 1) + c]
                    - sat[r * (columns + 1) + c];
        }
    }
    let mut out = Vec::with_capacity(values.len());
    for r in 0..rows {
        for c in 0..columns {
            let (r0, r1) = (r.saturating_sub(k), (r + k + 1).min(rows));
            let (c0, c1) = (c.saturating_sub(k), (c + k + 1).min(columns));
            let sum = sat[r1 * (columns + 1) + c1] - sat[r0 * (columns + 1) + c1] - sat[r1 * (columns + 1) + c0]
                + sat[r0 * (columns + 1) + c0];
            let n = ((r1 - r0) * (c1 - c0)) as f64;
            out.push((f64::from(values[r * columns + c]) - sum / n) as f32);
        }
    }
    out
}
