//! The numeric core: frames and rigid transforms, the random generator, the
//! Levenberg–Marquardt solver, statistics, the thread pool and progress bars,
//! and the command's allocator.
pub mod geometry;
pub mod large_pages;
pub mod limits;
pub mod lm;
pub mod parallel;
pub mod progress;
pub mod rng;
pub mod stats;
pub mod timing;
pub mod trajectory;
