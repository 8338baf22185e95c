//! `probecal segment`: the N-wire dot segmentation of a PLUS sequence on its own,
//! for any scanner and phantom the device set describes. The settings come from
//! the device set's `Segmentation` element where it gives them (opening radius,
//! threshold percentage, collinearity, candidates), PLUS's defaults otherwise;
//! each frame's threshold follows its own brightness; images are flipped to MF
//! as the file's `UltrasoundImageOrientation` says.

use std::path::{Path, PathBuf};

use crate::detect::nwire::Segmentation;
use crate::detect::overlay::Overlay;
use crate::io::plus::config::PlusConfig;
use crate::io::plus::sequence::{Orientation, Sequence};
use crate::pipeline::sequence_frames::{clip_or_overlay, segment_frames, Role, SegmentationInputs, TrackedFrame};
use crate::pipeline::tracked::TrackedError;

/// A segmented sequence.
#[derive(Debug, Clone)]
pub struct SegmentRun {
    pub sequence: PathBuf,
    pub config: PathBuf,
    pub frames: Vec<TrackedFrame>,
    /// The wires' ids, three per pattern in the device set's order.
    pub wire_ids: Vec<String>,
    pub clip_rectangle_px: [usize; 4],
    /// The screen overlay left out, when the device set gives no clip rectangle.
    pub overlay: Option<Overlay>,
    pub image_size_px: [usize; 2],
    pub orientation: Orientation,
    pub segmentation: Segmentation,
    pub spacing_guess_mm_per_px: f64,
    /// The sequence read (its images, flipped to MF), for the report's gallery.
    pub images: Sequence,
}

/// The segmentation settings a device set gives, over PLUS's defaults.
pub fn settings_of(config: &PlusConfig) -> Segmentation {
    Segmentation::from_device_set(config)
}

/// Segments every frame of `sequence` with the phantom and settings of `config`.
pub fn run(sequence: &Path, config: &Path) -> Result<SegmentRun, TrackedError> {
    let config_file = PlusConfig::read(config)?;
    let spacing = config_file
        .approximate_spacing_mm_per_px
        .ok_or_else(|| TrackedError::Config(missing(config, "Segmentation/@ApproximateSpacingMmPerPixel")))?;
    if config_file.nwires.is_empty() {
        return Err(TrackedError::Config(missing(
            config,
            "PhantomDefinition's NWire patterns",
        )));
    }
    let file = Sequence::read(sequence)?;
    let segmentation = settings_of(&config_file);
    let given = config_file.clip_rectangle_px.map(|(o, s)| [o[0], o[1], s[0], s[1]]);
    let (clip, overlay) = clip_or_overlay(&file, given, &segmentation, spacing)?;
    let inputs = SegmentationInputs {
        nwires: &config_file.nwires,
        spacing_guess_mm_per_px: spacing,
        segmentation: &segmentation,
        clip,
        overlay: overlay.as_ref(),
    };
    let frames = segment_frames(&file, Role::Calibration, &inputs);
    Ok(SegmentRun {
        sequence: sequence.to_path_buf(),
        config: config.to_path_buf(),
        frames,
        wire_ids: config_file.wire_ids.clone(),
        clip_rectangle_px: clip,
        overlay,
        image_size_px: [file.width, file.height],
        orientation: file.orientation,
        segmentation,
        spacing_guess_mm_per_px: spacing,
        images: file,
    })
}

fn missing(config: &Path, what: &str) -> crate::io::plus::config::ConfigError {
    crate::io::plus::config::ConfigError {
        path: config.to_path_buf(),
        line: None,
        message: format!("the device set has no {what}, which the segmentation needs"),
    }
}
