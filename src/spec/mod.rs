//! What an experiment describes: the phantom and its features, the marker rig,
//! the simulated lab a dataset is rendered in. Plain data, read from the manifest
//! (which checks it) and by every stage that needs it.
pub mod nwire;
pub mod phantom;
pub mod realism;
pub mod render;
pub mod rig;
