//! What a tracked run's summary says of the reconstruction of the sweep its
//! manifest names (`reconstruct:`), made with the run's own `ImageToProbe`.

use serde::{Deserialize, Serialize};

use crate::evaluate::wire_profile::WireFigures;

/// The run folder's subfolder that holds the reconstruction.
pub const FOLDER: &str = "reconstruction";

/// What the run's summary says of its reconstruction.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrackedVolume {
    /// The subfolder of the run folder (volume.mha, pictures, report.html).
    pub folder: String,
    pub sweep: String,
    pub config: String,
    pub frames_used: usize,
    pub frames_total: usize,
    pub dims: [usize; 3],
    pub spacing_mm: [f64; 3],
    /// The phantom's wires in the volume, when the phantom came from a device set.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wires: Option<WireFigures>,
}
