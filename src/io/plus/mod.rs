//! Files of the PLUS toolkit: tracked sequence files and device-set configurations.

pub mod config;
mod config_types;
pub mod orientation;
pub mod result;
pub mod segmentation;
pub mod sequence;
mod sequence_deferred;
mod sequence_header;
mod sequence_types;
mod sequence_writer;
pub mod volume_config;
pub mod xml_limits;
