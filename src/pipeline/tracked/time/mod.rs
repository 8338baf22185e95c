//! Time in the calibration: the tracker's poses as trajectories in time, the
//! tracker's lag behind the images estimated with the calibration
//! (spatio-temporal), from a sweep's motion, and from a reflector recording
//! (PLUS's temporal calibration).

pub mod lag;
pub mod lag_joint;
pub mod lag_span;
pub mod sweep_lag;
pub mod temporal;
