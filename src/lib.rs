//! probecal: freehand 2D ultrasound probe calibration.
#![allow(non_snake_case)]

pub mod core;
pub mod detect;
pub mod estimate;
pub mod evaluate;
pub mod io;
pub mod manifest;
pub mod pipeline;
pub mod report;
pub mod spec;
pub mod synth;
