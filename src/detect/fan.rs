//! What the B-scan detectors share about the ultrasound fan.

/// Echoes this close below the transducer's face (the near field: ring-down and
/// the face's own reverberation) are not searched.
pub const NEAR_FIELD_MM: f64 = 6.0;
/// Pixels this close to the fan's edge are not searched (the edge is a bright
/// artefact of the scan conversion, not an echo).
pub const FAN_EDGE_MM: f64 = 1.5;
