//! probecal: freehand 2D ultrasound probe calibration.
//!
//! A tracked probe needs `marker_T_image`, the fixed transform from its B-scan
//! plane (U) to the marker on its casing (M). Photos of a board on the probe and a
//! board on the phantom give `camera_T_marker` and `camera_T_phantom` per frame;
//! the phantom feature seen in the B-scan and its known position give a point
//! pair; Horn's closed form solves for `marker_T_image`; the back-projection error
//! (BRE) per axis of the phantom frame says how good it is.
//!
//! See [`geometry`] for the conventions (frames, directions, units). One module per
//! pipeline stage: [`camera_calibration`] (1), [`board_pose`] (2),
//! [`arc_detection`] (3), [`horn`] (4), [`evaluate`] (5); [`run`] chains them,
//! [`synth`] renders datasets, [`output`] and [`report`] write the results.
#![allow(non_snake_case)]

pub mod arc_detection;
pub mod aruco;
pub mod board;
pub mod board_pose;
pub mod camera_calibration;
pub mod camera_model;
pub mod check;
pub mod compare;
pub mod corners;
pub mod dataset;
pub mod evaluate;
pub mod figures;
pub mod gallery;
pub mod geometry;
pub mod horn;
pub mod image;
pub mod image_to_probe;
pub mod lm;
pub mod manifest;
pub mod nwire;
pub mod output;
pub mod parallel;
pub mod plus;
pub mod progress;
pub mod provenance;
pub mod report;
pub mod rng;
pub mod robust;
pub mod run;
pub mod sphere_fit;
pub mod spot_detection;
pub mod study;
pub mod synth;
pub mod thesis;
pub mod tracked;
pub mod tracked_output;
pub mod tracker_poses;
pub mod truth;
pub mod validation;
pub mod wire_matching;
