//! The stages chained: a manifest's datasets run end to end. Only this layer
//! reads manifests; it turns them into each stage's settings ([`settings`]).
pub mod error;
pub mod experiment;
pub mod frames;
pub mod live;
pub mod reconstruct;
pub mod record;
pub mod run;
pub mod sequence_frames;
pub mod settings;
pub mod solve;
pub mod study;
pub mod tracked;
