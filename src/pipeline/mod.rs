//! The stages chained: a manifest's datasets run end to end. Only this layer
//! reads manifests; it turns them into each stage's settings ([`settings`]).
//!
//! One room per application: the camera-rig runs ([`run`]), studies over many
//! runs ([`study`]), tracked recordings with the PLUS tools' counterparts
//! ([`tracked`]) and live sessions ([`live`]); beside them what they share (a
//! run's records, frames, the solve, a reconstruction) and [`experiment`], which
//! runs a manifest's datasets through the room they belong to.
pub mod error;
pub mod experiment;
pub mod frames;
pub mod labels;
pub mod live;
pub mod reconstruct;
pub mod record;
pub mod run;
pub mod selfcal;
pub mod sequence_frames;
pub mod settings;
pub mod solve;
pub mod study;
pub mod tracked;
