//! Live reconstruction while a stream is calibrated, as PlusServer's live
//! volume reconstruction does: each received frame with a pose is pasted into a
//! volume as it is finished, placed by its own transforms and the live
//! calibration of that moment (frames before the first calibration wait
//! outside), and every N inserted frames the volume, its holes filled as the
//! device set says, is sent as an IMAGE message. The volume's grid comes from the
//! device set's `OutputOrigin` and `OutputExtent` (a live volume cannot be fitted
//! to frames that have not arrived); the rest of `<VolumeReconstruction>` is read
//! as `probecal reconstruct` reads it.

use std::path::{Path, PathBuf};

use nalgebra::Matrix4;

use crate::io::plus::sequence::Sequence;
use crate::io::plus::volume_config::VolumeSettings;
use crate::pipeline::reconstruct::paste_settings;
use crate::reconstruct::grid::Grid;
use crate::reconstruct::paste::{paste_into, PasteSettings, Pasted, Slice};
use crate::reconstruct::Volume;

/// What to reconstruct while the stream arrives.
#[derive(Debug, Clone, PartialEq)]
pub struct VolumeRequest {
    /// A PLUS device set with a `<VolumeReconstruction>` element.
    pub config: PathBuf,
    /// Send the volume every this many inserted frames.
    pub every: usize,
    /// The IMAGE messages' device.
    pub device: String,
}

/// Largest voxel count of a live volume (it is sent whole, every N frames).
pub const MAX_LIVE_VOXELS: usize = 1 << 27;

/// Why a live volume cannot be set up (each names the device set and line).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum VolumeSetupError {
    /// The device set's `<VolumeReconstruction>` could not be read.
    #[error("{0}")]
    Settings(String),
    #[error("{at}: a live volume needs OutputOrigin and OutputExtent (its grid cannot be fitted to frames that have not arrived)")]
    NoGrid { at: String },
    #[error("{at}: {reason}")]
    Grid { at: String, reason: String },
    #[error("{at}: a live volume of {}x{}x{} voxels is sent whole every N frames: at most {MAX_LIVE_VOXELS} voxels and {} a side", .dims[0], .dims[1], .dims[2], u16::MAX)]
    TooLarge { at: String, dims: [usize; 3] },
    #[error("--volume-every 0: send the volume every N ≥ 1 inserted frames")]
    EveryZero,
}

/// A volume being filled.
pub struct LiveVolume {
    pub settings: VolumeSettings,
    pub grid: Grid,
    paste: Option<PasteSettings>,
    pasted: Option<Pasted<u8>>,
    /// Frames inserted, and frames not inserted with why (the first few).
    pub inserted: usize,
    pub not_inserted: usize,
    pub not_inserted_reasons: Vec<String>,
    since_sent: usize,
    pub every: usize,
    /// Voxels some pixel reached, at the last snapshot.
    pub voxels_reached: usize,
}

impl LiveVolume {
    /// Reads the device set's reconstruction settings; its grid must be given.
    pub fn open(request: &VolumeRequest) -> Result<LiveVolume, VolumeSetupError> {
        let settings = VolumeSettings::read(&request.config).map_err(|e| VolumeSetupError::Settings(e.to_string()))?;
        let at = format!("{}: line {}", request.config.display(), settings.line);
        let (Some(origin), Some(extent)) = (settings.origin_mm, settings.extent) else {
            return Err(VolumeSetupError::NoGrid { at });
        };
        let grid = match Grid::from_extent(origin, settings.spacing_mm, extent) {
            Ok(grid) => grid,
            Err(e) => {
                return Err(VolumeSetupError::Grid {
                    at,
                    reason: e.to_string(),
                })
            }
        };
        if grid.voxels() > MAX_LIVE_VOXELS || grid.dims.iter().any(|&d| d > u16::MAX as usize) {
            return Err(VolumeSetupError::TooLarge { at, dims: grid.dims });
        }
        if request.every == 0 {
            return Err(VolumeSetupError::EveryZero);
        }
        Ok(LiveVolume {
            settings,
            grid,
            paste: None,
            pasted: None,
            inserted: 0,
            not_inserted: 0,
            not_inserted_reasons: Vec::new(),
            since_sent: 0,
            every: request.every,
            voxels_reached: 0,
        })
    }

    fn skip(&mut self, reason: String) {
        self.not_inserted += 1;
        if self.not_inserted_reasons.len() < 20 {
            self.not_inserted_reasons.push(reason);
        }
    }

    /// Inserts frame `index` of `sequence` with `image_to_probe` (none yet: it
    /// waits outside); true when the volume is due to be sent.
    pub fn insert(
        &mut self,
        sequence: &Sequence,
        index: usize,
        transforms: [&str; 2],
        image_to_probe: Option<&Matrix4<f64>>,
    ) -> bool {
        let Some(image_to_probe) = image_to_probe else {
            self.skip(format!("frame {index}: no calibration yet"));
            return false;
        };
        let [probe, reference] = transforms;
        let pose = sequence
            .matrix(index, probe)
            .and_then(|p| sequence.matrix(index, reference).map(|r| (p, r)));
        let (probe_to_tracker, reference_to_tracker) = match pose {
            Ok(p) => p,
            Err(e) => {
                self.skip(format!("frame {index}: {e}"));
                return false;
            }
        };
        let Some(tracker_to_reference) = reference_to_tracker.try_inverse() else {
            self.skip(format!("frame {index}: {reference}Transform is singular"));
            return false;
        };
        if self.paste.is_none() {
            match paste_settings(&self.settings, sequence.width, sequence.height) {
                Ok(p) => self.paste = Some(p),
                Err(e) => {
                    self.skip(format!("frame {index}: {e}"));
                    return false;
                }
            }
        }
        let (Some(paste), pasted) = (
            &self.paste,
            self.pasted.get_or_insert_with(|| Pasted::zeroed(&self.grid)),
        ) else {
            return false;
        };
        let slice = Slice {
            pixels: sequence.pixels(index),
            reference_T_pixel: tracker_to_reference * probe_to_tracker * image_to_probe,
        };
        paste_into(&self.grid, pasted, &[slice], paste, crate::core::parallel::threads());
        self.inserted += 1;
        self.since_sent += 1;
        self.since_sent >= self.every
    }

    /// Frames inserted since the volume was last sent.
    pub fn unsent(&self) -> usize {
        self.since_sent
    }

    /// The volume so far, its holes filled (a copy: insertion goes on).
    pub fn snapshot(&mut self) -> Option<Volume<u8>> {
        let pasted = self.pasted.as_ref()?;
        self.since_sent = 0;
        self.voxels_reached = pasted.weights.iter().filter(|&&w| w > 0).count();
        let mut voxels = pasted.voxels.clone();
        crate::reconstruct::holes::fill(
            &self.grid,
            &mut voxels,
            &pasted.weights,
            &self.settings.hole_filling,
            crate::core::parallel::threads(),
        );
        Some(Volume {
            grid: self.grid,
            voxels,
        })
    }
}

/// The IMAGE message of a volume, its first voxel at the grid's origin.
pub fn volume_message(device: &str, timestamp_s: f64, volume: &Volume<u8>) -> Vec<u8> {
    let g = &volume.grid;
    let body = crate::io::igtl::message::image_body(g.dims, g.spacing_mm, g.origin_mm, &volume.voxels);
    crate::io::igtl::message::encode("IMAGE", device, timestamp_s, &body)
}

/// `path` shown as the device set's.
pub fn describe(request: &VolumeRequest) -> String {
    format!(
        "{} every {} frames as IMAGE `{}`",
        Path::new(&request.config).display(),
        request.every,
        request.device
    )
}
