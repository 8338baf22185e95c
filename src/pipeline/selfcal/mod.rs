//! `probecal selfcal`: two or more overlapping tracked sweeps and a starting
//! calibration into the correction of `ImageToProbe` that makes the sweeps
//! compound alike ([`crate::estimate::selfcal`]), with the directions they hold.

pub mod lag;
pub mod load;

use std::path::PathBuf;

use nalgebra::Matrix4;

use crate::estimate::selfcal::check::{consistency, CheckSettings, Consistency};
use crate::estimate::selfcal::compound::GridFault;
use crate::estimate::selfcal::overlay::{slices, OverlaySlice};
use crate::estimate::selfcal::profile::{profiles, Profile};
use crate::estimate::selfcal::refine::{level_grids, search, Search, SearchFault, SearchSettings};
use crate::estimate::selfcal::resample::Subsets;
use crate::estimate::selfcal::{Frame0, Sweep};
use crate::io::plus::config::PlusConfig;
use load::{Framing, LoadedSweep};

#[derive(Debug, thiserror::Error)]
pub enum SelfcalError {
    #[error(transparent)]
    Sequence(#[from] crate::io::plus::sequence::SequenceError),
    #[error(transparent)]
    Config(#[from] crate::io::plus::config::ConfigError),
    #[error("{}: {message}", crate::io::fs::display_path(path))]
    Input { path: PathBuf, message: String },
    #[error("{0}")]
    Grid(#[from] GridFault),
    #[error("{0}")]
    Search(#[from] SearchFault),
}

/// What to refine.
#[derive(Debug, Clone)]
pub struct SelfcalInputs {
    pub sequences: Vec<PathBuf>,
    pub config: PathBuf,
    pub framing: Framing,
    /// The start: pixel (column, row, 0, 1) to probe mm, and where it came from.
    pub start: (Matrix4<f64>, String),
    pub tracker_lag_s: f64,
    /// Pixels are averaged in squares of this side before compounding (`None`:
    /// about half the finest voxel, [`block_px_for`]).
    pub block_px: Option<usize>,
    /// Each block less the mean of the blocks within this distance of it, mm
    /// (`None`: kept as imaged).
    pub background_mm: Option<f64>,
    pub settings: SearchSettings,
    /// The check of the start against the sweeps.
    pub check: CheckSettings,
    /// The lags the agreement is profiled over at the refined calibration (none: not profiled).
    pub lag_scan: Option<lag::LagScan>,
}

/// The sweeps read, ready to compare.
#[derive(Debug, Clone)]
pub struct Prepared {
    pub sweeps: Vec<Sweep>,
    /// Each sweep's sequence and what was left out of it, in the same order.
    pub sources: Vec<LoadedSweep>,
    pub frame0: Frame0,
    pub block_px: usize,
    /// The background's reach in blocks (0: none).
    pub background_blocks: usize,
}

/// Reads the sweeps and sets the grid around them under the start calibration.
pub fn prepare(inputs: &SelfcalInputs) -> Result<Prepared, SelfcalError> {
    let config = PlusConfig::read(&inputs.config)?;
    let block_px = inputs
        .block_px
        .unwrap_or_else(|| block_px_for(&inputs.start.0, inputs.settings.comparison.voxel_mm));
    let pixel_mm = pixel_size_mm(&inputs.start.0);
    let background_blocks = inputs
        .background_mm
        .map_or(0, |mm| (mm / (block_px as f64 * pixel_mm)).round().max(1.0) as usize);
    let (mut sweeps, mut sources) = (Vec::new(), Vec::new());
    for path in &inputs.sequences {
        let (sweep, loaded) = load::load(
            path,
            &config,
            &inputs.framing,
            block_px,
            background_blocks,
            inputs.tracker_lag_s,
        )?;
        if sweep.frames.len() < 2 {
            return Err(SelfcalError::Input {
                path: path.clone(),
                message: format!(
                    "{} of {} frames have a pose{}",
                    sweep.frames.len(),
                    loaded.frames_total,
                    loaded
                        .skipped
                        .first()
                        .map(|s| format!("; frame {}: {}", s.index, s.reason))
                        .unwrap_or_default()
                ),
            });
        }
        sweeps.push(sweep);
        sources.push(loaded);
    }
    let size = sources.first().map_or([0, 0], |s| s.image_size_px);
    if let Some(other) = sources.iter().find(|s| s.image_size_px != size) {
        return Err(SelfcalError::Input {
            path: other.path.clone(),
            message: format!(
                "{:?} px images, the first sequence's are {size:?} px",
                other.image_size_px
            ),
        });
    }
    let frame0 = Frame0::new(inputs.start.0, size[0], size[1]);
    level_grids(&sweeps, &frame0, &inputs.settings)?;
    Ok(Prepared {
        sweeps,
        sources,
        frame0,
        block_px,
        background_blocks,
    })
}

/// The mean pixel size of a calibration, mm (its first two columns' lengths).
pub fn pixel_size_mm(probe_T_pixel: &Matrix4<f64>) -> f64 {
    let u = probe_T_pixel.fixed_view::<3, 1>(0, 0).norm();
    let v = probe_T_pixel.fixed_view::<3, 1>(0, 1).norm();
    (u + v) / 2.0
}

/// Blocks of about half the finest voxel: a voxel then averages a few blocks
/// of each frame that crosses it.
pub fn block_px_for(probe_T_pixel: &Matrix4<f64>, voxel_mm: f64) -> usize {
    let px = pixel_size_mm(probe_T_pixel);
    if px.is_finite() && px > 0.0 {
        ((voxel_mm / 2.0) / px).round().clamp(1.0, 64.0) as usize
    } else {
        1
    }
}

impl Prepared {
    /// The search from the start.
    pub fn search(&self, settings: &SearchSettings) -> Result<Search, SelfcalError> {
        self.search_from(&self.frame0, settings)
    }

    /// The search from another start on the same sweeps (trials from set-off starts).
    pub fn search_from(&self, start: &Frame0, settings: &SearchSettings) -> Result<Search, SelfcalError> {
        self.search_on(start, settings, None)
    }

    /// The search on some frames of each sweep (resampled sweeps).
    pub fn search_on(
        &self,
        start: &Frame0,
        settings: &SearchSettings,
        frames: Subsets,
    ) -> Result<Search, SelfcalError> {
        Ok(search(&self.sweeps, start, settings, frames)?)
    }
}

/// A refinement and what it read.
#[derive(Debug, Clone)]
pub struct SelfcalRun {
    pub inputs: SelfcalInputs,
    pub prepared: Prepared,
    pub search: Search,
    /// The start checked against the sweeps.
    pub check: Consistency,
    /// The agreement along each direction through the solution.
    pub profiles: Vec<Profile>,
    /// The agreement against the lag at the solution, when asked for.
    pub lag_profile: Option<lag::LagProfile>,
    /// The sweeps cut by a plane normal to each Reference axis, before and
    /// after the correction.
    pub overlays: Vec<OverlaySlice>,
}

impl SelfcalRun {
    /// The refined calibration: pixel (column, row, 0, 1) to probe mm.
    pub fn image_to_probe(&self) -> Matrix4<f64> {
        self.prepared.frame0.calibration(&self.search.correction)
    }
}

/// Reads the sweeps and searches; nothing is written here.
pub fn run(inputs: &SelfcalInputs) -> Result<SelfcalRun, SelfcalError> {
    if inputs.sequences.len() < 2 {
        return Err(SelfcalError::Search(SearchFault::OneSweep));
    }
    let prepared = prepare(inputs)?;
    let search = prepared.search(&inputs.settings)?;
    let check = consistency(&search, &prepared.frame0, &inputs.check);
    let profiles = profiles(
        &prepared.sweeps,
        &prepared.frame0,
        &search.correction,
        &search.directions,
        &inputs.settings,
    )?;
    let lag_profile = match &inputs.lag_scan {
        Some(scan) => Some(lag::profile(
            inputs,
            &prepared,
            inputs.tracker_lag_s,
            &search.correction,
            scan,
            lag::LAG_RESAMPLES,
        )?),
        None => None,
    };
    let overlays = slices(&prepared.sweeps, &prepared.frame0, &search.correction, &inputs.settings)?;
    Ok(SelfcalRun {
        inputs: inputs.clone(),
        prepared,
        search,
        check,
        profiles,
        lag_profile,
        overlays,
    })
}
