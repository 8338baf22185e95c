//! The stages chained: a manifest's datasets run end to end. Only this layer
//! reads manifests; it turns them into each stage's settings ([`settings`]).
pub mod ablation;
pub mod camera;
pub mod design;
pub mod error;
pub mod experiment;
pub mod frames;
pub mod live;
pub mod live_folder;
pub mod methods;
pub mod reconstruct;
pub mod record;
pub mod resolve;
pub mod run;
pub mod segment;
pub mod sequence_frames;
pub mod settings;
pub mod shard;
pub mod solve;
pub mod sphere_pose;
pub mod study;
pub mod sweep_lag;
pub mod temporal;
pub mod tracked;
pub mod tracked_resolution;
pub mod truth;
