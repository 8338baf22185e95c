//! `probecal reconstruct`: a tracked sequence and a PLUS device set into a volume,
//! stage by stage ([`crate::reconstruct`]), each stage timed.

use std::path::{Path, PathBuf};
use std::time::Instant;

use nalgebra::Matrix4;

use crate::io::plus::config::PlusConfig;
use crate::io::plus::sequence::{Deferred, Samples, Sequence};
use crate::io::plus::volume_config::VolumeSettings;
use crate::reconstruct::arrivals::Arrivals;
use crate::reconstruct::grid::{budget_fault, Grid};
use crate::reconstruct::holes::HoleStats;
use crate::reconstruct::paste::{PasteSettings, Slice};
use crate::reconstruct::poses::{frame_poses, FramePose, SkippedFrame};
use crate::reconstruct::{reconstruct, reconstruct_frames, ReconstructError, Sample, Volume};

/// What to reconstruct.
#[derive(Debug, Clone)]
pub struct ReconstructInputs {
    pub sequence: PathBuf,
    pub config: PathBuf,
    /// Worker threads (0 or `None`: all cores); the device set's
    /// `NumberOfThreads` is not needed, the volume is the same for any number.
    pub threads: Option<usize>,
    /// A PLUS device set with the phantom's N-wires and its registration
    /// (`PhantomToReference`): each wire's position, straightness and thickness
    /// in the volume are measured.
    pub wires: Option<PathBuf>,
    /// `ImageToProbe` given (a run's own calibration, a run folder's or a PLUS
    /// result's, with where it came from); it replaces the device set's.
    pub image_to_probe: Option<(Matrix4<f64>, String)>,
    /// The tracker's lag behind the images, s, given (a number or a run
    /// folder's `time_offset_s`, with where it came from); else none.
    pub tracker_lag_s: Option<(f64, String)>,
}

/// The volume, 8-bit or float as the input.
#[derive(Debug, Clone, PartialEq)]
pub enum AnyVolume {
    U8(Volume<u8>),
    F32(Volume<f32>),
}

impl AnyVolume {
    pub fn grid(&self) -> &Grid {
        match self {
            AnyVolume::U8(v) => &v.grid,
            AnyVolume::F32(v) => &v.grid,
        }
    }

    pub fn element_type(&self) -> &'static str {
        match self {
            AnyVolume::U8(_) => u8::ELEMENT_TYPE,
            AnyVolume::F32(_) => f32::ELEMENT_TYPE,
        }
    }

    /// Voxels as little-endian bytes.
    pub fn bytes(&self) -> Vec<u8> {
        let mut out = Vec::new();
        match self {
            AnyVolume::U8(v) => u8::write_le(&v.voxels, &mut out),
            AnyVolume::F32(v) => f32::write_le(&v.voxels, &mut out),
        }
        out
    }
}

/// A reconstruction and how it went.
#[derive(Debug, Clone)]
pub struct Reconstruction {
    pub inputs: ReconstructInputs,
    pub settings: VolumeSettings,
    pub volume: AnyVolume,
    /// Where `ImageToProbe` came from: the device set or the run folder.
    pub image_to_probe_source: String,
    pub image_to_probe: Option<Matrix4<f64>>,
    /// The tracker's lag applied, s, and where it came from.
    pub tracker_lag_s: f64,
    pub tracker_lag_source: String,
    pub frames_total: usize,
    pub frames_used: Vec<usize>,
    pub skipped: Vec<SkippedFrame>,
    pub pixels_inserted: u64,
    pub accumulator_saturated: u64,
    /// Voxels with a value from the distribution, and after hole filling.
    pub voxels_filled_before_holes: u64,
    pub voxels_filled_after_holes: u64,
    pub holes: HoleStats,
    pub threads: usize,
    /// (stage, seconds).
    pub timings: Vec<(String, f64)>,
    /// The phantom's wires in the volume, with `inputs.wires`.
    pub wires: Option<crate::evaluate::wire_profile::WireFigures>,
    /// Each inserted frame's clip rectangle in the volume's frame: its four
    /// corners (first column and row, last column, last row, first column)
    /// in mm, in the order the frames were inserted.
    pub frame_outlines_mm: Vec<[[f64; 3]; 4]>,
}

/// The tracker's lag to apply and where it came from: given (a number, or a
/// run folder's `time_offset_s`), or none.
fn tracker_lag(inputs: &ReconstructInputs) -> (f64, String) {
    match &inputs.tracker_lag_s {
        Some((lag, source)) => (*lag, source.clone()),
        None => (0.0, "none given".into()),
    }
}

/// The clip rectangle's first and last inserted column and row: PLUS's
/// rectangle runs from the origin to origin + size, both included (within the
/// frame), in the pixels it inserts as in the corners it fits the volume to.
fn clip(settings: &VolumeSettings, width: usize, height: usize) -> Result<[usize; 4], ReconstructError> {
    let [ox, oy] = settings.clip_origin_px;
    let [sx, sy] = match settings.clip_size_px {
        [0, 0] => [width, height],
        s => s,
    };
    // PLUS clips a rectangle reaching past the frames to them without a word;
    // probecal asks for the rectangle meant.
    if ox + sx > width || oy + sy > height || sx == 0 || sy == 0 {
        return Err(ReconstructError::Input {
            path: settings.path.clone(),
            message: format!(
                "line {}: clip rectangle at ({ox}, {oy}) size {sx}x{sy} reaches beyond the {width}x{height} frames",
                settings.line
            ),
        });
    }
    Ok([ox, oy, (ox + sx).min(width - 1), (oy + sy).min(height - 1)])
}

fn importance_mask(
    settings: &VolumeSettings,
    width: usize,
    height: usize,
) -> Result<Option<Vec<u8>>, ReconstructError> {
    let Some(path) = &settings.importance_mask else {
        return Ok(None);
    };
    let fail = |message: String| ReconstructError::Input {
        path: path.clone(),
        message,
    };
    use opencv::prelude::{MatTraitConst, MatTraitConstManual};
    let mat = crate::io::image::read_gray(path).map_err(|e| fail(e.to_string()))?;
    if mat.cols() as usize != width || mat.rows() as usize != height {
        return Err(fail(format!(
            "importance mask is {}x{}, the frames are {width}x{height}",
            mat.cols(),
            mat.rows()
        )));
    }
    Ok(Some(mat.data_bytes().map_err(|e| fail(e.to_string()))?.to_vec()))
}

/// The output grid (given, or fitted to the clipped frames) and how pixels are pasted.
fn grid_and_paste(
    settings: &VolumeSettings,
    sequence: &Sequence,
    poses: &[FramePose],
) -> Result<(Grid, PasteSettings), ReconstructError> {
    let (width, height) = (sequence.width, sequence.height);
    let clip_px = clip(settings, width, height)?;
    let grid = match (settings.origin_mm, settings.extent) {
        (Some(origin), Some(extent)) => Grid::from_extent(origin, settings.spacing_mm, extent),
        _ => {
            let matrices: Vec<_> = poses.iter().map(|p| p.reference_T_pixel).collect();
            Grid::fit(
                &matrices,
                [clip_px[0], clip_px[1]],
                [clip_px[2], clip_px[3]],
                settings.spacing_mm,
            )
        }
    }
    .map_err(|e| ReconstructError::Input {
        path: settings.path.clone(),
        message: format!("line {}: {e}", settings.line),
    })?;
    Ok((grid, paste_settings(settings, width, height)?))
}

/// How the pixels of `width` x `height` frames are pasted under `settings`.
pub fn paste_settings(
    settings: &VolumeSettings,
    width: usize,
    height: usize,
) -> Result<PasteSettings, ReconstructError> {
    let clip_px = clip(settings, width, height)?;
    Ok(PasteSettings {
        width,
        height,
        clip_px,
        fan: settings.fan,
        pixel_rejection_threshold: settings.pixel_rejection_threshold,
        interpolation: settings.interpolation,
        compounding: settings.compounding,
        optimization: settings.optimization,
        importance_mask: importance_mask(settings, width, height)?,
    })
}

/// Reads the inputs and reconstructs; nothing is written here.
pub fn run(inputs: &ReconstructInputs) -> Result<Reconstruction, ReconstructError> {
    let mut timings = Vec::new();
    let mut clock = Instant::now();
    let mut lap = |name: &str, timings: &mut Vec<(String, f64)>| {
        timings.push((name.to_string(), clock.elapsed().as_secs_f64()));
        clock = Instant::now();
    };
    let settings = VolumeSettings::read(&inputs.config)?;
    let config = PlusConfig::read(&inputs.config)?;
    let image_to_probe = inputs.image_to_probe.as_ref().map(|(matrix, _)| *matrix);
    let (tracker_lag_s, tracker_lag_source) = tracker_lag(inputs);
    // A compressed 8-bit sequence's frames are decoded while they are pasted.
    let (sequence, deferred) = Sequence::read_any_deferred(&inputs.sequence)?;
    lap("read", &mut timings);
    let (poses, skipped) = frame_poses(
        &sequence,
        &config,
        &settings.image_frame,
        &settings.reference_frame,
        settings.skip_interval,
        image_to_probe,
        tracker_lag_s,
    );
    if poses.is_empty() {
        let why = skipped
            .first()
            .map(|s| s.reason.clone())
            .unwrap_or("the sequence has no frames".into());
        return Err(ReconstructError::NoFrames(format!(
            "{} frames, none usable; frame 0: {why}",
            sequence.frames.len()
        )));
    }
    let (grid, paste_settings) = grid_and_paste(&settings, &sequence, &poses)?;
    let frame_outlines_mm = outlines(&poses, paste_settings.clip_px);
    check_budget(&settings, &sequence, deferred.as_ref(), &grid)?;
    lap("poses and grid", &mut timings);
    // PLUS's volume depends on its NumberOfThreads; probecal's does not, so it
    // uses every core unless told otherwise.
    let threads = match inputs.threads.unwrap_or(0) {
        0 => crate::core::parallel::threads(),
        n => n,
    };
    let (volume, stats) = reconstruct_any(&sequence, deferred, &grid, &poses, &paste_settings, &settings, threads)?;
    timings.extend(stats.timings);
    let wires = match &inputs.wires {
        Some(path) => {
            let figures = wire_figures(path, &settings.reference_frame, &volume)?;
            lap("wires", &mut timings);
            Some(figures)
        }
        None => None,
    };
    let holes_filled: u64 = stats.holes.filled_by_element.iter().sum();
    let voxels = grid.voxels() as u64;
    // A volume no pixel reached is no reconstruction (every pixel clipped,
    // rejected by the threshold, or placed outside a given extent).
    if stats.pixels_inserted == 0 || voxels == stats.holes.holes_before {
        return Err(ReconstructError::NoFrames(format!(
            "{} frames placed, but no pixel was inserted into the {}x{}x{} volume \
             (clip rectangle, fan, PixelRejectionThreshold or OutputExtent leave none)",
            poses.len(),
            grid.dims[0],
            grid.dims[1],
            grid.dims[2]
        )));
    }
    Ok(Reconstruction {
        inputs: inputs.clone(),
        image_to_probe_source: match &inputs.image_to_probe {
            Some((_, source)) => source.clone(),
            None => format!(
                "{} (CoordinateDefinitions)",
                crate::io::fs::display_path(&inputs.config)
            ),
        },
        image_to_probe,
        tracker_lag_s,
        tracker_lag_source,
        settings,
        volume,
        frames_total: sequence.frames.len(),
        frames_used: poses.iter().map(|p| p.index).collect(),
        skipped,
        pixels_inserted: stats.pixels_inserted,
        accumulator_saturated: stats.saturated,
        voxels_filled_before_holes: voxels - stats.holes.holes_before,
        voxels_filled_after_holes: voxels - stats.holes.holes_before + holes_filled,
        holes: stats.holes,
        threads,
        timings,
        wires,
        frame_outlines_mm,
    })
}

/// The clip rectangle `[first column, first row, last column, last row]` of
/// each frame, placed by its pose.
fn outlines(poses: &[FramePose], clip_px: [usize; 4]) -> Vec<[[f64; 3]; 4]> {
    let [u0, v0, u1, v1] = clip_px.map(|c| c as f64);
    poses
        .iter()
        .map(|p| {
            [[u0, v0], [u1, v0], [u1, v1], [u0, v1]].map(|[u, v]| {
                let q = p.reference_T_pixel * nalgebra::Vector4::new(u, v, 0.0, 1.0);
                [q[0], q[1], q[2]]
            })
        })
        .collect()
}

/// The wires of the device set at `path` (its N-wire patterns, placed in the
/// volume's `reference_frame` by its rigid `PhantomTo<reference>`), measured in
/// `volume`.
fn wire_figures(
    path: &Path,
    reference_frame: &str,
    volume: &AnyVolume,
) -> Result<crate::evaluate::wire_profile::WireFigures, ReconstructError> {
    use crate::evaluate::wire_profile::{measure, VolumeView, Wire};
    let config = PlusConfig::read(path)?;
    if config.nwires.is_empty() {
        return Err(ReconstructError::Input {
            path: path.to_path_buf(),
            message: "no N-wire <Pattern> in its <PhantomDefinition>: no wires to measure".into(),
        });
    }
    let reference_T_phantom = config.rigid_transform(&config.calibration_frames.phantom, reference_frame)?;
    let place = |p: &nalgebra::Point3<f64>| (reference_T_phantom * p.to_homogeneous()).xyz().into();
    let wires: Vec<Wire> = config
        .nwires
        .iter()
        .flat_map(|n| n.wires.iter())
        .map(|w| Wire {
            name: w.name.clone(),
            front_mm: place(&w.front_in_phantom_mm),
            back_mm: place(&w.back_in_phantom_mm),
        })
        .collect();
    Ok(match volume {
        AnyVolume::U8(v) => measure(
            &VolumeView {
                grid: &v.grid,
                values: &v.voxels,
            },
            &wires,
        ),
        AnyVolume::F32(v) => measure(
            &VolumeView {
                grid: &v.grid,
                values: &v.voxels,
            },
            &wires,
        ),
    })
}

/// The volume's work within the one budget beside the frames held, refused at
/// the device set's line before anything is allocated for it.
fn check_budget(
    settings: &VolumeSettings,
    sequence: &Sequence,
    deferred: Option<&crate::io::plus::sequence::Deferred>,
    grid: &Grid,
) -> Result<(), ReconstructError> {
    let frames_bytes = sequence.held_bytes() + deferred.map_or(0, |d| d.held_bytes());
    let sample_bytes = if sequence.is_float() { 4 } else { 1 };
    let hole_filling = !settings.hole_filling.is_empty();
    match budget_fault(grid.voxels(), sample_bytes, hole_filling, frames_bytes as u64) {
        None => Ok(()),
        Some(why) => Err(ReconstructError::Input {
            path: settings.path.clone(),
            message: format!("line {}: {why}", settings.line),
        }),
    }
}

/// What the stages report, apart from the voxels.
struct Stats {
    pixels_inserted: u64,
    saturated: u64,
    holes: HoleStats,
    timings: Vec<(String, f64)>,
}

impl Stats {
    fn of<T>(out: &crate::reconstruct::Output<T>) -> Stats {
        Stats {
            pixels_inserted: out.pixels_inserted,
            saturated: out.accumulator_saturated,
            holes: out.holes.clone(),
            timings: out.timings.clone(),
        }
    }
}

/// The volume of the kept frames, in the sequence's element type; a deferred
/// sequence's frames decoded while they are pasted.
fn reconstruct_any(
    sequence: &Sequence,
    deferred: Option<Deferred>,
    grid: &Grid,
    poses: &[FramePose],
    paste_settings: &PasteSettings,
    settings: &VolumeSettings,
    threads: usize,
) -> Result<(AnyVolume, Stats), ReconstructError> {
    Ok(match (deferred, sequence.samples(poses[0].index)) {
        (Some(deferred), _) => {
            let (out, decoding_s) = reconstruct_decoding(&deferred, grid, poses, paste_settings, settings, threads)?;
            let mut stats = Stats::of(&out);
            stats
                .timings
                .insert(0, ("decoding, alongside the distribution".into(), decoding_s));
            (AnyVolume::U8(out.volume), stats)
        }
        (None, Samples::U8(_)) => {
            let slices = slices(sequence, poses, |s| match s {
                Samples::U8(p) => Some(p),
                Samples::F32(_) => None,
            });
            let out = reconstruct(grid, &slices, paste_settings, &settings.hole_filling, threads);
            let stats = Stats::of(&out);
            (AnyVolume::U8(out.volume), stats)
        }
        (None, Samples::F32(_)) => {
            let slices = slices(sequence, poses, |s| match s {
                Samples::F32(p) => Some(p),
                Samples::U8(_) => None,
            });
            let out = reconstruct(grid, &slices, paste_settings, &settings.hole_filling, threads);
            let stats = Stats::of(&out);
            (AnyVolume::F32(out.volume), stats)
        }
    })
}

/// Reconstructs while a thread decodes the frames, each pasted as soon as it
/// is decoded; the decoding's error if it fails. The decoding's seconds too.
fn reconstruct_decoding(
    deferred: &Deferred,
    grid: &Grid,
    poses: &[FramePose],
    paste_settings: &PasteSettings,
    settings: &VolumeSettings,
    threads: usize,
) -> Result<(crate::reconstruct::Output<u8>, f64), ReconstructError> {
    let mut pixels = vec![0u8; deferred.expected()];
    let matrices: Vec<_> = poses.iter().map(|p| p.reference_T_pixel).collect();
    let arrivals = Arrivals::new(poses.iter().map(|p| p.index).collect());
    let (out, decoded) = std::thread::scope(|scope| {
        let decoder = scope.spawn(|| {
            let _close = arrivals.closer();
            let clock = Instant::now();
            deferred
                .decode(&mut pixels, |frame| arrivals.arrive(frame))
                .map(|()| clock.elapsed().as_secs_f64())
        });
        let out = reconstruct_frames(
            grid,
            &matrices,
            &arrivals,
            paste_settings,
            &settings.hole_filling,
            threads,
        );
        (out, decoder.join())
    });
    let decoding_s = decoded.unwrap_or_else(|panic| std::panic::resume_unwind(panic))?;
    Ok((out, decoding_s))
}

/// The kept frames' pixels of one element type, with their poses.
fn slices<'a, T>(
    sequence: &'a Sequence,
    poses: &[FramePose],
    pick: impl Fn(Samples<'a>) -> Option<&'a [T]>,
) -> Vec<Slice<'a, T>> {
    poses
        .iter()
        .filter_map(|p| {
            pick(sequence.samples(p.index)).map(|pixels| Slice {
                pixels,
                reference_T_pixel: p.reference_T_pixel,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frames_outline_is_its_clip_rectangle_placed_by_its_pose() {
        // 0.2 mm pixels, the image's columns along y, its rows along -x, moved to (5, 6, 7) mm.
        let mut m = Matrix4::identity();
        m.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&nalgebra::Matrix3::new(0.0, -0.2, 0.0, 0.2, 0.0, 0.0, 0.0, 0.0, 0.2));
        m.fixed_view_mut::<3, 1>(0, 3)
            .copy_from(&nalgebra::Vector3::new(5.0, 6.0, 7.0));
        let poses = [FramePose {
            index: 3,
            reference_T_pixel: m,
        }];
        let [corners] = outlines(&poses, [10, 20, 109, 219])[..] else {
            panic!("one frame, one outline");
        };
        let expected = [[1.0, 8.0, 7.0], [1.0, 27.8, 7.0], [-38.8, 27.8, 7.0], [-38.8, 8.0, 7.0]];
        for (got, want) in corners.iter().zip(expected) {
            for a in 0..3 {
                assert!((got[a] - want[a]).abs() < 1e-9, "{corners:?}");
            }
        }
    }
}
