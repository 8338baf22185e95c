//! `probecal init`: a commented manifest written from what a recording shows.
//!
//! From a PLUS recording, everything is read: the transform names from the
//! sequence's first frame, the phantom, the pixel size and the segmentation
//! settings from the device set. From a folder of frames, what the files show is
//! read (which files there are, the tracker CSV's transform names, the B-scans'
//! size, the camera-calibration board's corner count), and what they cannot show
//! (the phantom's geometry, the boards on the probe and phantom, the B-scan's
//! pixel size) is written as a guess, each marked `GUESS` with what to measure.
//! Either manifest is validated as it would be read from its final place before
//! it is returned.

use std::collections::BTreeSet;
use std::fmt::Write as _;
use std::path::{Component, Path, PathBuf};

use super::{name_fault, tracked::TrackedManifest, Manifest};
use crate::detect::corners::{search_chessboard_reduced, Search, SubPix};
use crate::io::dataset::load_frame_list;
use crate::io::plus::config::PlusConfig;
use crate::io::plus::sequence::Sequence;
use crate::io::tracker_poses::TrackerPoses;

/// Why no manifest could be written.
#[derive(Debug, thiserror::Error)]
pub enum InitError {
    /// An input could not be read or does not hold what a manifest needs.
    #[error("{}: {message}", path.display())]
    Input { path: PathBuf, message: String },
    /// A reader's own error (it names its file and line).
    #[error("{0}")]
    Read(String),
    /// The written manifest does not validate (a bug of `init`, or an input the
    /// manifest's checks refuse): every error, located in the manifest's text.
    #[error("the manifest written for {} does not validate:\n{errors}", path.display())]
    Invalid { path: PathBuf, errors: String },
}

fn read(e: impl std::fmt::Display) -> InitError {
    InitError::Read(e.to_string())
}

fn input(path: &Path, message: impl Into<String>) -> InitError {
    InitError::Input {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

/// What `init` reads for a PLUS recording.
#[derive(Debug, Clone)]
pub struct PlusRecording<'a> {
    pub config: &'a Path,
    pub calibration: &'a Path,
    pub validation: Option<&'a Path>,
    /// Transform names, when the sequence's cannot be told apart by the device set's frames.
    pub probe_transform: Option<&'a str>,
    pub reference_transform: Option<&'a str>,
    /// PLUS's own calibration result of this recording, compared like for like.
    pub plus_result: Option<&'a Path>,
}

/// `path` as written in a manifest at `manifest`: relative to its folder where
/// both are on one tree, else absolute. Both are made absolute first.
pub fn relative_to_manifest(manifest: &Path, path: &Path) -> Result<String, InitError> {
    let absolute = |p: &Path| -> Result<PathBuf, InitError> {
        std::path::absolute(p).map_err(|e| input(p, format!("cannot make the path absolute: {e}")))
    };
    let target = absolute(path)?;
    let base = absolute(manifest)?.parent().map(Path::to_path_buf).unwrap_or_default();
    let normal = |p: &Path| -> Vec<String> {
        let mut parts: Vec<String> = Vec::new();
        for c in p.components() {
            match c {
                Component::ParentDir => {
                    parts.pop();
                }
                Component::Normal(s) => parts.push(s.to_string_lossy().into_owned()),
                _ => {}
            }
        }
        parts
    };
    let (t, b) = (normal(&target), normal(&base));
    let common = t.iter().zip(&b).take_while(|(x, y)| x == y).count();
    if common == 0 {
        return Ok(target.display().to_string());
    }
    let mut parts: Vec<String> = vec!["..".into(); b.len() - common];
    parts.extend(t[common..].iter().cloned());
    Ok(parts.join("/"))
}

/// A name for the run's folder from a file or folder name: letters, digits, `_`.
pub fn folder_name(path: &Path, fallback: &str) -> String {
    let stem = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let stem = stem.split('.').next().unwrap_or("");
    let mut name: String = stem
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() {
                c.to_ascii_lowercase()
            } else {
                '_'
            }
        })
        .collect();
    name.truncate(super::MAX_NAME_LEN);
    let name = name.trim_matches('_').to_string();
    if name_fault(&name).is_some() {
        fallback.to_string()
    } else {
        name
    }
}

/// `<from>To<to>` names of the transforms every frame of `sequence` carries
/// (`Seq_FrameNNNN_<from>To<to>Transform`), read from its first frame.
fn sequence_transforms(sequence: &Sequence) -> BTreeSet<(String, String)> {
    sequence
        .transform_names()
        .iter()
        .filter_map(|n| split_transform_name(n))
        .collect()
}

/// `ToolToTracker` → (`Tool`, `Tracker`): split at the first `To` that follows a
/// frame name and starts another (a capital after it).
fn split_transform_name(name: &str) -> Option<(String, String)> {
    name.match_indices("To").find_map(|(at, _)| {
        let (from, to) = (&name[..at], &name[at + 2..]);
        (!from.is_empty() && to.starts_with(|c: char| c.is_ascii_uppercase()))
            .then(|| (from.to_string(), to.to_string()))
    })
}

/// The probe's and the reference's transforms to one common frame (the tracker).
fn pose_transforms(
    sequence: &Sequence,
    config: &PlusConfig,
    given: (Option<&str>, Option<&str>),
) -> Result<(String, String), InitError> {
    let names = sequence_transforms(sequence);
    let listed = || {
        names
            .iter()
            .map(|(f, t)| format!("{f}To{t}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    if let (Some(p), Some(r)) = given {
        for n in [p, r] {
            if !names.iter().any(|(f, t)| format!("{f}To{t}") == n) {
                return Err(input(
                    &sequence.path,
                    format!("frame 0 has no transform `{n}`; it has: {}", listed()),
                ));
            }
        }
        return Ok((p.to_string(), r.to_string()));
    }
    let frames = &config.calibration_frames;
    let common: Vec<&String> = names
        .iter()
        .filter(|(f, _)| *f == frames.probe)
        .map(|(_, t)| t)
        .filter(|t| names.contains(&(frames.reference.clone(), t.to_string())))
        .collect();
    match common.as_slice() {
        [to] => Ok((format!("{}To{to}", frames.probe), format!("{}To{to}", frames.reference))),
        _ => Err(input(
            &sequence.path,
            format!(
                "cannot tell the poses apart: the device set's probe frame `{}` and reference frame `{}` \
                 need transforms to one common frame, and frame 0 has: {} \
                 (name them with --probe-transform and --reference-transform)",
                frames.probe,
                frames.reference,
                listed()
            ),
        )),
    }
}

/// A tracked manifest for a PLUS recording, validated as if read from `out`.
pub fn plus_manifest(recording: &PlusRecording, out: &Path, experiment: &str) -> Result<String, InitError> {
    let config = PlusConfig::read(recording.config).map_err(read)?;
    if config.nwires.is_empty() {
        return Err(input(
            recording.config,
            "the device set defines no N-wire pattern (PhantomDefinition/Geometry/Pattern Type=\"NWire\")",
        ));
    }
    let sequence = Sequence::read(recording.calibration).map_err(read)?;
    let (probe, reference) = pose_transforms(
        &sequence,
        &config,
        (recording.probe_transform, recording.reference_transform),
    )?;
    let validation = match recording.validation {
        Some(v) => Some((v, Sequence::read(v).map_err(read)?)),
        None => None,
    };
    let rel = |p: &Path| relative_to_manifest(out, p);
    let mut t = plus_header(recording, &sequence, validation.as_ref());
    let _ = writeln!(t, "experiment: {experiment}");
    let _ = writeln!(t, "description: >-");
    let _ = writeln!(
        t,
        "  N-wire calibration of {} ({} N-wires from the device set).",
        folder_name(recording.calibration, "recording"),
        config.nwires.len()
    );
    let _ = writeln!(t, "tracking:\n  plus_sequence:");
    let _ = writeln!(t, "    dataset: {}", folder_name(recording.calibration, "calibration"));
    let _ = writeln!(t, "    calibration: {}", yaml_string(&rel(recording.calibration)?));
    match &validation {
        Some((path, _)) => {
            let _ = writeln!(
                t,
                "    validation: {}   # held-out frames: PRE3D is reported on them",
                yaml_string(&rel(path)?)
            );
        }
        None => {
            let _ = writeln!(
                t,
                "    # validation: path/to/validation.igs.mha   # held-out frames for PRE3D"
            );
        }
    }
    let _ = writeln!(
        t,
        "    # The poses, found in frame 0 ({} and {} are the device set's probe and reference frames).",
        config.calibration_frames.probe, config.calibration_frames.reference
    );
    let _ = writeln!(t, "    probe_transform: {probe}");
    let _ = writeln!(t, "    reference_transform: {reference}");
    let _ = writeln!(
        t,
        "    # The tracker's lag behind the images: `estimate` (from the calibration sweep's\n    \
         # own motion; none is applied when the sweep cannot resolve it), or seconds."
    );
    let _ = writeln!(t, "    time_offset_s: estimate");
    let _ = writeln!(t, "phantom:\n  nwire:");
    let _ = writeln!(
        t,
        "    # Wires, PhantomToReference and the segmentation settings: the device set's."
    );
    let _ = writeln!(t, "    plus_config: {}", yaml_string(&rel(recording.config)?));
    let frames = &config.calibration_frames;
    if frames.phantom != "Phantom" {
        let _ = writeln!(t, "    phantom_frame: {}", frames.phantom);
    }
    if frames.reference != "Reference" {
        let _ = writeln!(t, "    reference_frame: {}", frames.reference);
    }
    let _ = writeln!(
        t,
        "# bscan:\n#   segmentation: {{threshold_percent: 10}}   # any key replaces the device set's setting"
    );
    let _ = writeln!(
        t,
        "solve:\n  reject_sd: 3.0   # PLUS's outlier rule; the model is chosen on the calibration frames"
    );
    let _ = writeln!(t, "thresholds:\n  min_frames: 10");
    match recording.plus_result {
        Some(result) => {
            crate::io::plus::result::PlusResult::read(result).map_err(|e| input(result, e.to_string()))?;
            let _ = writeln!(
                t,
                "compare_with_plus_result: {}   # PLUS's own result, compared like for like",
                yaml_string(&relative_to_manifest(out, result)?)
            );
        }
        None => {
            let _ = writeln!(
                t,
                "# compare_with_plus_result: path/to/ProbeCalibrationResult.xml   # PLUS's own result (init --plus-result), compared like for like"
            );
        }
    }
    TrackedManifest::from_text(out, &t).map_err(|e| invalid(out, e))?;
    Ok(t)
}

/// The manifest's opening comment: what it was written from.
fn plus_header(recording: &PlusRecording, sequence: &Sequence, validation: Option<&(&Path, Sequence)>) -> String {
    let mut t = String::new();
    let _ = writeln!(t, "# Written by `probecal init` from a PLUS recording:");
    let _ = writeln!(t, "#   device set:  {}", recording.config.display());
    let _ = writeln!(
        t,
        "#   calibration: {} ({} frames of {}x{} px)",
        recording.calibration.display(),
        sequence.frames.len(),
        sequence.width,
        sequence.height
    );
    if let Some((path, v)) = validation {
        let _ = writeln!(t, "#   validation:  {} ({} frames)", path.display(), v.frames.len());
    }
    let _ = writeln!(
        t,
        "# Every key: docs/manifest.md. Check: probecal validate; run: probecal run."
    );
    t
}

fn invalid(out: &Path, errors: super::ManifestErrors) -> InitError {
    InitError::Invalid {
        path: out.to_path_buf(),
        errors: errors.0.iter().map(|e| format!("  {e}")).collect::<Vec<_>>().join("\n"),
    }
}

/// A YAML scalar for a path: quoted when plain YAML would read it otherwise.
fn yaml_string(s: &str) -> String {
    let plain = !s.is_empty()
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '/' | '.' | '_' | '-'))
        && !s.starts_with('-');
    if plain {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', "''"))
    }
}

/// Inner-corner counts `init` tries on a camera-calibration photo, the common
/// printed boards first (OpenCV's sample board is 9x6).
const CALIBRATION_BOARDS: [[u32; 2]; 8] = [[9, 6], [8, 6], [7, 6], [10, 7], [7, 5], [11, 8], [6, 4], [9, 7]];

/// The first of [`CALIBRATION_BOARDS`] found in the first photo of `folder`.
fn calibration_board(folder: &Path) -> Option<([u32; 2], PathBuf)> {
    let images = crate::detect::camera_calibration::collect_images(&[folder.to_path_buf()]).ok()?;
    let first = images.first()?;
    let image = crate::io::image::read_gray(first).ok()?;
    CALIBRATION_BOARDS.iter().find_map(|board| {
        search_chessboard_reduced(&image, *board, SubPix::default(), 960, Search::Thorough)
            .ok()
            .flatten()
            .map(|_| (*board, first.clone()))
    })
}

/// The probe's and the phantom's transform names in a tracker CSV.
fn tracker_names(path: &Path) -> Result<(String, String), InitError> {
    let poses = TrackerPoses::read(path).map_err(read)?;
    let names: BTreeSet<&String> = poses.poses.values().flat_map(|m| m.keys()).collect();
    let find = |word: &str| names.iter().find(|n| n.contains(word)).map(|n| n.to_string());
    match (find("Probe"), find("Reference").or_else(|| find("Phantom"))) {
        (Some(p), Some(r)) if p != r => Ok((p, r)),
        _ => Err(input(
            path,
            format!(
                "cannot tell the probe's pose from the phantom's: expected a transform named \
                 *Probe* and one named *Reference* or *Phantom*, found {}",
                names.iter().map(|n| n.as_str()).collect::<Vec<_>>().join(", ")
            ),
        )),
    }
}

/// A camera (or tracker-CSV) manifest for a recorded folder, validated as if
/// read from `out`.
pub fn folder_manifest(folder: &Path, out: &Path, experiment: &str) -> Result<String, InitError> {
    let frames = load_frame_list(folder).map_err(read)?;
    let tracker = folder.join("tracker_poses.csv");
    // The list's paths are the folder's already (relative to it, joined to it).
    let first_bscan = frames[0].bscan_image.clone();
    let bscan = crate::io::image::read_gray(&first_bscan).map_err(|e| input(&first_bscan, e.to_string()))?;
    let size = opencv::core::MatTraitConst::size(&bscan).map_err(|e| input(&first_bscan, e.to_string()))?;
    let mut t = String::new();
    let _ = writeln!(t, "# Written by `probecal init` from the folder {}:", folder.display());
    let _ = writeln!(
        t,
        "#   {} frames; B-scans of {}x{} px. Each `GUESS` below is what the files cannot",
        frames.len(),
        size.width,
        size.height
    );
    let _ = writeln!(t, "#   show: measure it. Every key: docs/manifest.md.");
    let _ = writeln!(t, "experiment: {experiment}");
    let _ = writeln!(
        t,
        "description: Calibration of the recording {}.",
        folder_name(folder, "recording")
    );
    let _ = writeln!(t, "phantom:\n  hemisphere:");
    let _ = writeln!(
        t,
        "    # GUESS (the source study's phantom): the sphere's centre in the phantom board's frame, mm."
    );
    let _ = writeln!(t, "    centre_in_phantom_mm: [285.7, 76.2, -26.5]");
    let _ = writeln!(t, "    radius_mm: 15.0   # GUESS");
    let _ = writeln!(t, "rig:\n  checkerboard:");
    let _ = writeln!(
        t,
        "    # GUESS (the source study's boards): inner corners, square size in mm, id dots."
    );
    let _ = writeln!(
        t,
        "    probe_board: {{inner_corners: [10, 10], square_mm: 13.0, id_dots: 1}}"
    );
    let _ = writeln!(
        t,
        "    phantom_board: {{inner_corners: [10, 10], square_mm: 13.0, id_dots: 2}}"
    );
    let photos = frames.iter().any(|f| f.camera_image.is_some())
        && (folder.join("camera_calibration").is_dir() || INTRINSICS_FILES.iter().any(|n| folder.join(n).is_file()));
    let tracker_poses = if tracker.is_file() {
        let (probe, reference) = tracker_names(&tracker)?;
        Some(format!(
            "poses:\n  tracker_csv:\n    file: tracker_poses.csv\n    probe_transform: {probe}\n    \
             reference_transform: {reference}\n"
        ))
    } else {
        None
    };
    match (photos, tracker_poses) {
        (true, other) => {
            camera_section(&mut t, folder, out)?;
            if let Some(poses) = other {
                let _ = writeln!(
                    t,
                    "# tracker_poses.csv is there too; these lines instead of `camera:` take the poses from it:"
                );
                for line in poses.lines() {
                    let _ = writeln!(t, "# {line}");
                }
            }
        }
        (false, Some(poses)) => {
            let _ = writeln!(t, "# The poses come from tracker_poses.csv; no photo is read.");
            t.push_str(&poses);
        }
        (false, None) => camera_section(&mut t, folder, out)?,
    }
    let _ = writeln!(t, "bscan:");
    let _ = writeln!(
        t,
        "  spacing_mm_per_px: [0.2, 0.2]   # GUESS: the scanner's pixel size at this depth setting"
    );
    let _ = writeln!(t, "thresholds:\n  min_frames: 10");
    let _ = writeln!(t, "datasets:");
    let _ = writeln!(t, "  - name: {}", folder_name(folder, "recording"));
    let _ = writeln!(t, "    folder: {}", yaml_string(&relative_to_manifest(out, folder)?));
    Manifest::from_text(out, &t).map_err(|e| invalid(out, e))?;
    Ok(t)
}

/// Camera intrinsics files `init` looks for beside the frames (OpenCV FileStorage).
const INTRINSICS_FILES: [&str; 2] = ["camera_intrinsics.yml", "intrinsics.yml"];

/// `camera:` for a folder: calibrated from `camera_calibration/` (the board's
/// corner count found in its first photo), or an intrinsics file beside the frames.
fn camera_section(t: &mut String, folder: &Path, out: &Path) -> Result<(), InitError> {
    let calibration = folder.join("camera_calibration");
    for name in INTRINSICS_FILES {
        if folder.join(name).is_file() && !calibration.is_dir() {
            let file = relative_to_manifest(out, &folder.join(name))?;
            let _ = writeln!(t, "camera:\n  intrinsics_file: {}", yaml_string(&file));
            return Ok(());
        }
    }
    if !calibration.is_dir() {
        return Err(input(
            folder,
            "no tracker_poses.csv, no camera_calibration/ folder of board photos and no camera_intrinsics.yml: \
             the manifest needs one of them for the poses",
        ));
    }
    let _ = writeln!(t, "camera:\n  calibrate:");
    match calibration_board(&calibration) {
        Some((board, photo)) => {
            let _ = writeln!(
                t,
                "    inner_corners: [{}, {}]   # found in {}",
                board[0],
                board[1],
                photo.display()
            );
        }
        None => {
            let _ = writeln!(
                t,
                "    inner_corners: [9, 6]   # GUESS: no common board was found in the first photo; count yours"
            );
        }
    }
    let _ = writeln!(
        t,
        "    square_mm: 30.0   # GUESS: the lens's intrinsics do not depend on it; measure it all the same"
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn transform_names_split_where_a_frame_name_starts() {
        let split = |n: &str| split_transform_name(n).map(|(a, b)| format!("{a}|{b}"));
        assert_eq!(split("ToolToTracker").as_deref(), Some("Tool|Tracker"));
        assert_eq!(split("ProbeToReference").as_deref(), Some("Probe|Reference"));
        assert_eq!(
            split("TransducerHolderToOpticalCamera").as_deref(),
            Some("TransducerHolder|OpticalCamera")
        );
        assert_eq!(split("Tracker"), None);
        assert_eq!(split("ProbeTotal"), None);
    }

    #[test]
    fn paths_are_written_relative_to_the_manifest_where_they_share_a_tree() {
        let rel = |m: &str, p: &str| relative_to_manifest(Path::new(m), Path::new(p)).unwrap();
        assert_eq!(rel("/a/b/m.yaml", "/a/b/c/s.mha"), "c/s.mha");
        assert_eq!(rel("/a/b/m.yaml", "/a/d/s.mha"), "../d/s.mha");
        assert_eq!(rel("/a/m.yaml", "/z/s.mha"), "/z/s.mha");
    }

    #[test]
    fn folder_names_are_run_folder_names() {
        assert_eq!(folder_name(Path::new("/x/fCal Test.igs.mha"), "f"), "fcal_test");
        assert_eq!(folder_name(Path::new("/x/..."), "fallback"), "fallback");
        assert_eq!(name_fault(&folder_name(Path::new("/x/Ünïcode-Scan.mha"), "f")), None);
    }
}
