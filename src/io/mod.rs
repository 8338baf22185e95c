//! Files in and out: atomic writes, images, dataset frame lists, ground truth,
//! tracker poses, camera models and PLUS's formats.
pub mod camera_model;
pub mod codec;
pub mod csv;
pub mod dataset;
pub mod fs;
pub mod igtl;
pub mod image;
pub mod jpeg;
pub mod json;
pub mod output;
pub mod plus;
pub mod png_codec;
pub mod stl;
pub mod storage;
pub mod tracker_poses;
pub mod truth;
pub mod unique_keys;
pub mod volume_file;
pub mod yaml_limits;
