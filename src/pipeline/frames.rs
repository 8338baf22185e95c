//! Stages 2 and 3 per frame: both board poses from the photo (or the tracker's
//! poses) and the phantom's feature in the B-scan. A frame that fails a stage is
//! kept with the stage and the reason.

use opencv::prelude::MatTraitConst;

use crate::core::parallel::parallel_map;
use crate::detect::arc::{self, ArcSettings};
use crate::detect::board_pose::{self, RigBoards};
use crate::detect::spot::{self, Spot, SpotSettings};
use crate::io::dataset::FrameFiles;
use crate::io::image::{read_gray, read_gray_sized, ImageError};
use crate::pipeline::error::RunError;
use crate::pipeline::record::{CameraStage, FrameRecord, Implausible, Rejection};
use crate::spec::phantom::{Sphere, Wire};

/// The B-scan feature detector of a phantom.
#[derive(Debug, Clone, Copy)]
pub enum Detector {
    Arc(ArcSettings),
    /// Up to this many arcs (one per sphere).
    Arcs(ArcSettings, usize),
    PinHead(SpotSettings),
    WireDots(SpotSettings),
}

/// Where a phantom's features lie: one known point, or on known wires.
#[derive(Debug, Clone, Copy)]
pub enum Targets<'a> {
    Point([f64; 3]),
    Wires(&'a [Wire]),
    Spheres(&'a [Sphere]),
}

/// Two pin-head candidates closer in strength than this make the pin head ambiguous.
const PIN_HEAD_MIN_STRENGTH_RATIO: f64 = 1.5;

/// The echoes that look like a pin head of radius `r`: no wider across the beam
/// than the head plus the beam's blur, followed by a comet tail (the head's
/// reverberation) along the beam. Strongest first.
fn pin_head_candidates(spots: &[Spot], r: f64) -> Vec<Spot> {
    spots
        .iter()
        .filter(|s| s.width_mm <= 2.0 * r + 1.0 && s.length_mm >= 2.0 * r + 1.5)
        .cloned()
        .collect()
}

fn detect_frame(
    files: &FrameFiles,
    camera: &CameraStage,
    rig: &RigBoards,
    detector: &Detector,
) -> Result<FrameRecord, RunError> {
    let mut record = blank_record(files);
    if let Err(rejection) = frame_poses(files, camera, rig, &mut record)? {
        record.rejection = Some(rejection);
        return Ok(record);
    }
    let bscan = match read_gray(&files.bscan_image) {
        Ok(m) => m,
        Err(e) => {
            record.rejection = Some(Rejection::BscanImage(e));
            return Ok(record);
        }
    };
    record.bscan_size_px = Some([bscan.cols() as usize, bscan.rows() as usize]);
    if let Err(rejection) = bscan_features(&bscan, detector, &mut record) {
        record.rejection = Some(rejection);
    }
    Ok(record)
}

/// A frame's record before any stage has run.
fn blank_record(files: &FrameFiles) -> FrameRecord {
    FrameRecord {
        files: files.clone(),
        rejection: None,
        poses: None,
        tracked: None,
        arc: None,
        arcs: Vec::new(),
        spots: Vec::new(),
        features_px: Vec::new(),
        wire_labels: Vec::new(),
        bre_mm: None,
        bscan_size_px: None,
    }
}

/// Stage 2: the frame's poses, from its photo's boards or from the tracker
/// (the inner `Err` is the frame's rejection).
fn frame_poses(
    files: &FrameFiles,
    camera: &CameraStage,
    rig: &RigBoards,
    record: &mut FrameRecord,
) -> Result<Result<(), Rejection>, RunError> {
    match (&camera.intrinsics, &camera.tracker) {
        (Some(intrinsics), _) => {
            let Some(photo_file) = &files.camera_image else {
                return Ok(Err(Rejection::NoCameraImage));
            };
            let photo = match read_gray_sized(photo_file, intrinsics.image_size_px) {
                Ok(m) => m,
                Err(e) => return Ok(Err(Rejection::CameraImage(e))),
            };
            match crate::detect::rig_pose::estimate(&photo, intrinsics, rig)? {
                Ok(poses) => record.poses = Some(poses),
                Err(reason) => return Ok(Err(Rejection::BoardPose(reason))),
            }
        }
        (None, Some(t)) => match t.poses.frame(files.frame, &t.probe_transform, &t.reference_transform) {
            Ok(tracked) => record.tracked = Some(tracked),
            Err(reason) => return Ok(Err(Rejection::TrackerPose(reason))),
        },
        (None, None) => {
            return Err(RunError::Unsupported(
                "neither a camera nor a tracker gives the poses".into(),
            ))
        }
    }
    Ok(Ok(()))
}

/// Stage 3: the phantom's features in the B-scan (arcs, a pin head, wire dots);
/// `Err` is the frame's rejection.
fn bscan_features(bscan: &opencv::core::Mat, detector: &Detector, record: &mut FrameRecord) -> Result<(), Rejection> {
    let spots = match detector {
        Detector::Arc(arc) => {
            let feature = arc::detect(bscan, arc)
                .map_err(Rejection::BscanImage)?
                .map_err(Rejection::Arc)?;
            record.features_px = vec![feature.centre_px];
            record.arc = Some(feature);
            return Ok(());
        }
        Detector::Arcs(arc, count) => {
            let (arcs, reason) = arc::detect_many(bscan, arc, *count).map_err(Rejection::BscanImage)?;
            if let (None, Some(reason)) = (arcs.first(), reason) {
                return Err(Rejection::Arc(reason));
            }
            record.features_px = arcs.iter().map(|a| a.centre_px).collect();
            record.arc = arcs.first().cloned();
            record.arcs = arcs;
            return Ok(());
        }
        Detector::PinHead(settings) | Detector::WireDots(settings) => {
            spot::detect(bscan, settings).map_err(Rejection::BscanImage)?
        }
    };
    record.spots = spots.spots.clone();
    match detector {
        Detector::PinHead(settings) => match pin_head_candidates(&spots.spots, settings.object_radius_mm).as_slice() {
            [] => Err(Rejection::NoPinHead {
                compact: spots.spots.len(),
                surfaces: spots.surfaces,
            }),
            [first, second, ..] if first.strength < PIN_HEAD_MIN_STRENGTH_RATIO * second.strength => {
                Err(Rejection::AmbiguousPinHead {
                    first_px: first.echo_px,
                    second_px: second.echo_px,
                })
            }
            [first, ..] => {
                record.features_px = vec![first.centre_px];
                Ok(())
            }
        },
        _ if spots.spots.len() < 2 => Err(Rejection::TooFewWireDots {
            compact: spots.spots.len(),
            surfaces: spots.surfaces,
        }),
        _ => {
            record.features_px = spots.spots.iter().map(|s| s.centre_px).collect();
            Ok(())
        }
    }
}

/// The names of a record's two poses, for its plausibility check.
fn pose_names(record: &FrameRecord) -> [&'static str; 2] {
    match record.tracked {
        Some(_) => ["tracker_T_marker", "tracker_T_phantom"],
        None => ["camera_T_marker", "camera_T_phantom"],
    }
}

/// Poses a frame's two checkerboards again from their corners with other
/// intrinsics (the corners do not move). A pose that now fails the
/// reprojection limit or the plausibility check rejects the frame, unless a
/// later stage had rejected it already.
pub fn pose_again(
    record: &mut FrameRecord,
    camera: &crate::io::camera_model::CameraIntrinsics,
    rig: &board_pose::RigLayout,
) -> Result<(), RunError> {
    let Some(poses) = &record.poses else { return Ok(()) };
    let probe = board_pose::solve_pose(camera, &rig.probe, &poses.camera_T_marker.corners_px)?;
    let phantom = board_pose::solve_pose(camera, &rig.phantom, &poses.camera_T_phantom.corners_px)?;
    let limit_px = board_pose::MAX_REPROJECTION_RMS_PX;
    let failed = [
        ("probe", probe.reprojection_rms_px),
        ("phantom", phantom.reprojection_rms_px),
    ]
    .into_iter()
    .find(|(_, rms_px)| rms_px.is_nan() || *rms_px > limit_px);
    record.poses = Some(board_pose::FramePoses {
        camera_T_marker: probe,
        camera_T_phantom: phantom,
    });
    if record.rejection.is_some() {
        return Ok(());
    }
    if let Some((board, rms_px)) = failed {
        record.rejection = Some(Rejection::BoardPose(board_pose::BoardRejection::Reprojection {
            board,
            rms_px,
            limit_px,
        }));
    } else if let Some(fault) = Implausible::of(record.pose_pair(), pose_names(record), &record.features_px) {
        record.rejection = Some(Rejection::Implausible(fault));
    }
    Ok(())
}

/// One frame through stages 2 and 3; poses and feature pixels that are not finite
/// or not physically possible reject the frame at the stage boundary.
pub fn process_frame(
    files: &FrameFiles,
    camera: &CameraStage,
    rig: &RigBoards,
    detector: &Detector,
) -> Result<FrameRecord, RunError> {
    let mut record = detect_frame(files, camera, rig, detector)?;
    if record.rejection.is_none() {
        if let Some(fault) = Implausible::of(record.pose_pair(), pose_names(&record), &record.features_px) {
            record.rejection = Some(Rejection::Implausible(fault));
        }
    }
    Ok(record)
}

/// Every frame through stages 2 and 3, in parallel; the records in frame-list order.
pub fn process_all(
    files: &[FrameFiles],
    camera: &CameraStage,
    rig: &RigBoards,
    detector: &Detector,
) -> Result<Vec<FrameRecord>, RunError> {
    let progress = crate::core::progress::Progress::new(files.len(), "board poses and B-scan features");
    let frames = parallel_map(files.len(), |i| {
        let record = process_frame(&files[i], camera, rig, detector);
        progress.inc();
        record
    })
    .into_iter()
    .collect::<Result<Vec<_>, _>>()?;
    progress.finish();
    let mut frames = frames;
    one_bscan_size(&mut frames);
    Ok(frames)
}

/// A dataset's B-scans are one image size (its pixel size and geometry hold for
/// one): a frame whose B-scan is not the size most of them have is rejected.
fn one_bscan_size(frames: &mut [FrameRecord]) {
    let mut counts: Vec<([usize; 2], usize)> = Vec::new();
    for size in frames.iter().filter_map(|f| f.bscan_size_px) {
        match counts.iter_mut().find(|(s, _)| *s == size) {
            Some((_, n)) => *n += 1,
            None => counts.push((size, 1)),
        }
    }
    let Some(&(common, _)) = counts.iter().rev().max_by_key(|(_, n)| *n) else {
        return;
    };
    for f in frames.iter_mut() {
        if let Some(size) = f.bscan_size_px.filter(|s| *s != common) {
            if f.rejection.is_none() {
                f.rejection = Some(Rejection::BscanImage(ImageError::WrongSize {
                    path: f.files.bscan_image.clone(),
                    got_w: size[0] as i32,
                    got_h: size[1] as i32,
                    want_w: common[0] as u32,
                    want_h: common[1] as u32,
                }));
            }
        }
    }
}
