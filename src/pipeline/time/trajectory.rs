//! A sequence's tracked transform as a trajectory in time
//! ([`crate::core::trajectory`]): every path that pairs a pose with an image
//! reads it here, at the image's time plus the tracker's lag (the tracked run
//! and its live replays and streams; the reconstruction reads the same
//! trajectories through [`crate::core::trajectory`]).

use crate::core::geometry::Rigid;
use crate::core::trajectory::{self, Miss};
use crate::io::plus::sequence::Sequence;
use crate::pipeline::sequence_frames::{timestamp_s, PoseFault};

/// One named transform of a sequence, in time.
#[derive(Debug, Clone)]
pub struct Trajectory {
    name: String,
    path: trajectory::Trajectory<PoseFault>,
}

impl Trajectory {
    /// `name`'s samples in `sequence` (every frame; those with a timestamp in time).
    pub fn of(sequence: &Sequence, name: &str) -> Trajectory {
        Trajectory {
            name: name.to_string(),
            path: trajectory::Trajectory::from_samples((0..sequence.frames.len()).map(|frame| {
                (
                    frame,
                    timestamp_s(sequence, frame),
                    sequence.transform(frame, name).map_err(PoseFault::from),
                )
            })),
        }
    }

    /// The transform's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Frame `frame`'s own sample, whatever its time.
    pub fn own(&self, frame: usize) -> Option<Result<Rigid, PoseFault>> {
        self.path.own(frame)
    }

    /// The pose at `time_s`, for the image of frame `frame` (in the reasons).
    pub fn at(&self, time_s: f64, frame: usize) -> Result<Rigid, PoseFault> {
        self.path.at(time_s).map_err(|miss| match miss {
            Miss::Outside(side) => PoseFault::OutsideTrajectory {
                frame,
                transform: self.name.clone(),
                time_s,
                side,
            },
            Miss::Gap { gap_s, limit_s } => PoseFault::Gap {
                frame,
                transform: self.name.clone(),
                time_s,
                gap_s,
                limit_s,
            },
            Miss::Sample(fault) => fault,
        })
    }
}
