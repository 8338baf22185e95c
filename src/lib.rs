//! probecal: freehand 2D ultrasound probe calibration.
//!
//! A tracked probe needs `marker_T_image`, the fixed transform from its B-scan
//! plane to the marker on its casing. Photos of a board on the probe and a board
//! on the phantom give `camera_T_marker` and `camera_T_phantom` per frame; the
//! phantom's feature seen in the B-scan and its known position give a point pair;
//! Horn's closed form solves for `marker_T_image`; the back-projection error (BRE)
//! per axis of the phantom frame says how good it is.
//!
//! # Layers
//!
//! Each folder is a layer; a module imports only from the layers below it (the
//! test `tests/architecture.rs` fails on an upward import or a cycle):
//!
//! | layer | modules | what |
//! |---|---|---|
//! | 9 | [`cli`] | the command line: arguments, dispatch, exit codes |
//! | 8 | [`report`] | results into pages and files, the regression gate |
//! | 7 | [`results`] | the results model: each run's outcome typed, `summary.json` |
//! | 6 | [`pipeline`] | the stages chained; the only reader of manifests' settings |
//! | 5 | [`manifest`] | YAML in, a validated experiment out |
//! | 4 | [`evaluate`], [`synth`] | BRE, cut-offs, truth, resampling; the rendered lab |
//! | 3 | [`detect`], [`estimate`], [`reconstruct`] | features from pixels; `marker_T_image` from pairs; B-scans into volumes |
//! | 2 | [`io`] | files: images, frame lists, tracker poses, PLUS formats |
//! | 1 | [`spec`] | what an experiment describes: phantoms, rigs, the lab |
//! | 0 | [`core`] | geometry, statistics, solvers, threads |
//!
//! # Conventions
//!
//! - `a_T_b` maps coordinates in frame `b` to frame `a` (the thesis writes
//!   `T_{b→a}`); `points_in_a` are points in frame `a`. Transforms are rigid
//!   ([`core::geometry::Rigid`]); a pixel size is kept apart
//!   ([`core::geometry::Calibration`]).
//! - Frames, one name each:
//!   - `image` (U): the B-scan plane; pixel `(u, v)` (u = column, v = row) is at
//!     `(sx·u, sy·v, 0)` mm.
//!   - `marker` (M): the probe's marker (the board on its casing, or the tracked
//!     rigid body). PLUS calls it `Probe`, and `marker_T_image` `ImageToProbe`.
//!   - `camera` (C): OpenCV's, x right, y down, z forward.
//!   - `phantom` (P): the phantom's frame (its board's: origin on the first inner
//!     corner, x along a row, y along a column, z into the board); the features'
//!     positions are given in it.
//!   - `tracker` (T): an optical tracker's; it takes the camera's place when the
//!     poses come from a tracker (`tracker_T_marker`, `tracker_T_phantom`).
//!   - `reference` (R): PLUS's reference marker on the phantom;
//!     `reference_T_phantom` is PLUS's `PhantomToReference`.
//! - Units: millimetres, degrees (radians only inside solvers), pixels, seconds.
//!   Names carry them (`_mm`, `_deg`, `_px`, `_s`).
//! - BRE of a frame: `|p − phantom_T_camera · camera_T_marker · marker_T_image ·
//!   (sx·u, sy·v, 0)|` per axis of P, where `p` is the feature's known position.
#![allow(non_snake_case)]
// Functions fit on a screen (`clippy.toml` sets the limit to 100 lines).
#![deny(clippy::too_many_lines)]

pub mod cli;
pub mod core;
pub mod detect;
pub mod estimate;
pub mod evaluate;
pub mod io;
pub mod manifest;
pub mod pipeline;
pub mod reconstruct;
pub mod report;
pub mod results;
pub mod spec;
pub mod synth;
