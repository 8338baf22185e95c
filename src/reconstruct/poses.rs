//! Each frame's `reference_T_pixel`: the chain of transforms from the image's
//! pixels to the Reference frame, from the sequence's per-frame tracker
//! transforms and the device set's fixed ones (`CoordinateDefinitions`), found
//! as PLUS's transform repository finds it: any path through the named frames.
//!
//! For the usual recording the path is
//! `ImageToReference = inverse(ReferenceToTracker) · ProbeToTracker · ImageToProbe`.

use std::collections::{BTreeMap, VecDeque};

use nalgebra::Matrix4;

use crate::core::trajectory::{Miss, Trajectory};
use crate::io::plus::config::PlusConfig;
use crate::io::plus::sequence::Sequence;

/// A frame to insert.
#[derive(Debug, Clone, PartialEq)]
pub struct FramePose {
    pub index: usize,
    /// Pixel `(column, row, 0, 1)` to mm in the Reference frame.
    pub reference_T_pixel: Matrix4<f64>,
}

/// A frame left out, and why.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SkippedFrame {
    pub index: usize,
    pub reason: String,
}

/// Why a frame has no pose.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PoseFault {
    #[error("ImageStatus is {0}, not OK")]
    ImageStatus(String),
    #[error("no chain of usable transforms from {image_frame} to {reference_frame}{}", unusable_list(.unusable))]
    NoChain {
        image_frame: String,
        reference_frame: String,
        /// Why each transform on the way was unusable.
        unusable: Vec<String>,
    },
    #[error("frame {index}: no timestamp to apply the tracker's lag at")]
    NoTimestamp { index: usize },
    #[error("no trajectory of `{0}`")]
    NoTrajectory(String),
    #[error("frame {index}: `{name}` is wanted at {at_s:.6} s, {side} of the recorded trajectory")]
    Outside {
        index: usize,
        name: String,
        at_s: f64,
        side: &'static str,
    },
    #[error("frame {index}: the samples of `{name}` around {at_s:.6} s are {gap_s:.3} s apart (limit {limit_s} s)")]
    Gap {
        index: usize,
        name: String,
        at_s: f64,
        gap_s: f64,
        limit_s: f64,
    },
    #[error("{0}")]
    Sample(String),
}

fn unusable_list(unusable: &[String]) -> String {
    if unusable.is_empty() {
        String::new()
    } else {
        format!(" ({})", unusable.join("; "))
    }
}

/// A transform between two named frames: `to_T_from`.
#[derive(Debug, Clone)]
struct Edge {
    from: String,
    to: String,
    matrix: Matrix4<f64>,
}

/// Splits `ProbeToTracker` into (`Probe`, `Tracker`) at the first `To` that
/// starts a capitalised name.
pub fn split_name(name: &str) -> Option<(&str, &str)> {
    let bytes = name.as_bytes();
    (1..name.len().saturating_sub(2)).find_map(|i| {
        (&name[i..i + 2] == "To" && bytes[i + 2].is_ascii_uppercase()).then(|| (&name[..i], &name[i + 2..]))
    })
}

/// The frames' poses: every `SkipInterval`-th frame, those whose image status and
/// needed transforms are OK. `image_to_probe` replaces the device set's
/// `ImageToProbe` (a calibration of one's own). With a tracker lag of `lag_s`
/// (PLUS's `LocalTimeOffsetSec` of the tracker), every tracked transform is read
/// along its recorded trajectory at the image's time plus the lag.
pub fn frame_poses(
    sequence: &Sequence,
    config: &PlusConfig,
    image_frame: &str,
    reference_frame: &str,
    skip_interval: usize,
    image_to_probe: Option<Matrix4<f64>>,
    lag_s: f64,
) -> (Vec<FramePose>, Vec<SkippedFrame>) {
    let mut fixed: Vec<Edge> = config
        .transforms
        .iter()
        .map(|t| Edge {
            from: t.from.clone(),
            to: t.to.clone(),
            matrix: t.matrix,
        })
        .collect();
    if let Some(m) = image_to_probe {
        fixed.retain(|e| {
            !matches!(
                (e.from.as_str(), e.to.as_str()),
                ("Image", "Probe") | ("Probe", "Image")
            )
        });
        fixed.push(Edge {
            from: "Image".into(),
            to: "Probe".into(),
            matrix: m,
        });
    }
    let lagged = (lag_s != 0.0).then(|| Lagged::of(sequence, lag_s));
    let mut kept = Vec::new();
    let mut skipped = Vec::new();
    for index in (0..sequence.frames.len()).step_by(skip_interval.max(1)) {
        let replaced_image = image_to_probe.is_some();
        match frame_pose(
            sequence,
            index,
            &fixed,
            image_frame,
            reference_frame,
            lagged.as_ref(),
            replaced_image,
        ) {
            Ok(reference_T_pixel) => kept.push(FramePose {
                index,
                reference_T_pixel,
            }),
            Err(fault) => skipped.push(SkippedFrame {
                index,
                reason: fault.to_string(),
            }),
        }
    }
    (kept, skipped)
}

fn frame_pose(
    sequence: &Sequence,
    index: usize,
    fixed: &[Edge],
    image_frame: &str,
    reference_frame: &str,
    lagged: Option<&Lagged>,
    replaced_image: bool,
) -> Result<Matrix4<f64>, PoseFault> {
    if let Some(status) = sequence.frame_field(index, "ImageStatus") {
        if status != "OK" {
            return Err(PoseFault::ImageStatus(status.to_string()));
        }
    }
    let mut edges = fixed.to_vec();
    let mut unusable = Vec::new();
    for name in sequence.frames[index].fields.keys() {
        let Some(transform) = name.strip_suffix("Transform") else {
            continue;
        };
        let Some((from, to)) = split_name(transform) else {
            continue;
        };
        let of_image = from == image_frame || to == image_frame;
        // A calibration given in place of the device set's places the image:
        // the frames' own transforms of the image frame would go around it.
        if of_image && replaced_image {
            continue;
        }
        let matrix = match lagged {
            // A tracker's pose must be rigid (the tracked run's check); only a
            // transform of the image frame carries the pixels' scale. The
            // recorded matrix is pasted with, as PLUS does.
            None if !of_image => sequence
                .transform(index, transform)
                .and_then(|_| sequence.matrix(index, transform))
                .map_err(|e| e.to_string()),
            None => sequence.matrix(index, transform).map_err(|e| e.to_string()),
            Some(lagged) => lagged.at(sequence, index, transform).map_err(|e| e.to_string()),
        };
        match matrix {
            Ok(matrix) => edges.push(Edge {
                from: from.to_string(),
                to: to.to_string(),
                matrix,
            }),
            Err(fault) => unusable.push(fault),
        }
    }
    path(&edges, image_frame, reference_frame).ok_or_else(|| PoseFault::NoChain {
        image_frame: image_frame.to_string(),
        reference_frame: reference_frame.to_string(),
        unusable,
    })
}

/// Every tracked transform of a sequence as a trajectory, read at the image's
/// time plus a lag.
struct Lagged {
    lag_s: f64,
    paths: BTreeMap<String, Trajectory<String>>,
}

impl Lagged {
    fn of(sequence: &Sequence, lag_s: f64) -> Lagged {
        let names: std::collections::BTreeSet<&str> = sequence
            .frames
            .iter()
            .flat_map(|f| f.fields.keys())
            .filter_map(|k| k.strip_suffix("Transform"))
            .collect();
        let paths = names
            .into_iter()
            .map(|name| {
                let samples = (0..sequence.frames.len()).map(|i| {
                    (
                        i,
                        sequence.timestamp_s(i),
                        sequence.transform(i, name).map_err(|e| e.to_string()),
                    )
                });
                (name.to_string(), Trajectory::from_samples(samples))
            })
            .collect();
        Lagged { lag_s, paths }
    }

    /// Frame `index`'s `name` at its time plus the lag.
    fn at(&self, sequence: &Sequence, index: usize, name: &str) -> Result<Matrix4<f64>, PoseFault> {
        let time = sequence.timestamp_s(index).ok_or(PoseFault::NoTimestamp { index })?;
        let path = self
            .paths
            .get(name)
            .ok_or_else(|| PoseFault::NoTrajectory(name.to_string()))?;
        let at_s = time + self.lag_s;
        let name = name.to_string();
        path.at(at_s).map(|p| p.to_homogeneous()).map_err(|miss| match miss {
            Miss::Outside(side) => PoseFault::Outside {
                index,
                name,
                at_s,
                side,
            },
            Miss::Gap { gap_s, limit_s } => PoseFault::Gap {
                index,
                name,
                at_s,
                gap_s,
                limit_s,
            },
            Miss::Sample(fault) => PoseFault::Sample(fault),
        })
    }
}

/// `to_T_from` through the edges (each usable both ways), breadth first.
fn path(edges: &[Edge], from: &str, to: &str) -> Option<Matrix4<f64>> {
    let mut reached: BTreeMap<&str, Matrix4<f64>> = BTreeMap::new();
    reached.insert(from, Matrix4::identity());
    let mut queue = VecDeque::from([from]);
    while let Some(at) = queue.pop_front() {
        if at == to {
            return reached.get(to).copied();
        }
        let at_T_from = reached[at];
        for e in edges {
            let step = if e.from == at {
                Some((e.to.as_str(), e.matrix))
            } else if e.to == at {
                e.matrix.try_inverse().map(|inv| (e.from.as_str(), inv))
            } else {
                None
            };
            if let Some((next, next_T_at)) = step {
                if !reached.contains_key(next) {
                    reached.insert(next, next_T_at * at_T_from);
                    queue.push_back(next);
                }
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_split_at_the_capitalised_to() {
        assert_eq!(split_name("ProbeToTracker"), Some(("Probe", "Tracker")));
        assert_eq!(split_name("StylusTipToStylus"), Some(("StylusTip", "Stylus")));
        assert_eq!(split_name("Tomato"), None);
        assert_eq!(split_name("To"), None);
    }

    #[test]
    fn the_chain_is_found_through_inverses() {
        let shift = |x: f64| Matrix4::new_translation(&nalgebra::Vector3::new(x, 0.0, 0.0));
        let edges = vec![
            Edge {
                from: "Image".into(),
                to: "Probe".into(),
                matrix: shift(1.0),
            },
            Edge {
                from: "Probe".into(),
                to: "Tracker".into(),
                matrix: shift(10.0),
            },
            Edge {
                from: "Reference".into(),
                to: "Tracker".into(),
                matrix: shift(100.0),
            },
        ];
        let m = path(&edges, "Image", "Reference").unwrap();
        assert_eq!(m[(0, 3)], 1.0 + 10.0 - 100.0);
        assert!(path(&edges, "Image", "Stylus").is_none());
    }
}
