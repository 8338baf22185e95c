//! Live calibration from a folder being written: the camera rig's frames (a
//! photo and a B-scan each) are taken as they land in `<folder>/frames/`, each
//! one processed as soon as both of its files are complete, and the calibration,
//! its all-frames BRE and a running accuracy estimate updated after it.
//!
//! The folder is a dataset folder as `probecal run` reads it, filled while the
//! session runs: the camera's calibration views (or the manifest's intrinsics)
//! are there at the start; frame `N` is `frames/camera_N.<png|jpg>` and
//! `frames/bscan_N.<png|jpg>` (any number of digits). A file is complete when
//! its format's end marker is there (PNG's `IEND` chunk, JPEG's end-of-image),
//! so a writer needs no rename; a file that stays incomplete for the idle time
//! rejects its frame with that reason. The acquisition ends when the frame list
//! (`frames.csv`) appears and every frame it lists has been taken, or when no
//! new frame has arrived for the idle time. With the frame list, the batch
//! pipeline then runs on the whole folder, so the session ends with the
//! calibration `probecal run` gives, and the live all-frames fit can be compared
//! with the batch one.
//!
//! Each frame's error is predicted by the calibration of the frames before it
//! (its BRE under that calibration, the length of the per-axis vector): every
//! frame is held out from the calibration it is scored by. The running accuracy
//! is the mean of the latest predictions.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use crate::detect::board_pose::RigBoards;
use crate::estimate::correspondence::{self, Correspondence};
use crate::estimate::horn::HornFit;
use crate::io::dataset::FrameFiles;
use crate::manifest::{Dataset, DatasetSource, Manifest};
use crate::pipeline::error::RunError;
use crate::pipeline::frames::{process_frame, Targets};
use crate::pipeline::record::{DatasetRun, FrameRecord};
use crate::pipeline::settings;
use crate::pipeline::solve::{self, PairingInputs};

/// Predictions the running accuracy estimate pools (the latest).
pub const RUNNING_WINDOW: usize = 30;
/// Frames before the first calibration (Horn needs three points off a line).
pub const FIRST_FIT_FRAMES: usize = 3;

/// Where frames arrive and how long a silence ends the session.
#[derive(Debug, Clone, PartialEq)]
pub struct Watch {
    pub folder: PathBuf,
    /// No new frame for this long ends the acquisition, s.
    pub idle_s: f64,
    /// How often the folder is listed, ms.
    pub poll_ms: u64,
}

/// One frame's outcome, as it was shown.
#[derive(Debug, Clone, PartialEq)]
pub struct FolderFrame {
    pub frame: usize,
    /// When both its files were complete, s after the session started.
    pub arrival_s: f64,
    /// From the later of its two files' last write to its calibration update
    /// (the folder's polling included), ms.
    pub latency_ms: f64,
    /// Its processing: board poses, feature, prediction and refit, ms.
    pub processing_ms: f64,
    pub rejected: Option<String>,
    /// Its BRE under the calibration of the frames before it, mm.
    pub predicted_error_mm: Option<f64>,
    /// Mean of the latest predicted errors, mm.
    pub running_error_mm: Option<f64>,
    /// Frames in the calibration after it.
    pub frames_used: usize,
    /// All-frames BRE mean per axis after it, mm.
    pub bre_mean_mm: Option<[f64; 3]>,
}

/// Why the acquisition was taken to be over.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ending {
    /// The frame list appeared and every frame it lists was taken.
    FrameList,
    /// No new frame for the idle time.
    Idle,
}

/// A live session on a folder.
#[derive(Debug)]
pub struct FolderRun {
    pub frames: Vec<FolderFrame>,
    pub ending: Ending,
    /// The all-frames calibration the live fit reached.
    pub last_fit: Option<HornFit>,
    /// The batch pipeline on the whole folder (when the frame list is there).
    pub batch: Option<DatasetRun>,
}

/// The frame number of `camera_<N>.<ext>` or `bscan_<N>.<ext>` (PNG or JPEG).
fn frame_file(name: &str) -> Option<(&'static str, usize)> {
    let (stem, ext) = name.rsplit_once('.')?;
    if !matches!(ext.to_ascii_lowercase().as_str(), "png" | "jpg" | "jpeg") {
        return None;
    }
    for kind in ["camera", "bscan"] {
        if let Some(digits) = stem.strip_prefix(kind).and_then(|s| s.strip_prefix('_')) {
            if !digits.is_empty() && digits.len() <= 9 && digits.bytes().all(|b| b.is_ascii_digit()) {
                return digits.parse().ok().map(|n| (kind, n));
            }
        }
    }
    None
}

/// The frames whose two files are both in `frames/`, by number.
fn listed(folder: &Path) -> BTreeMap<usize, FrameFiles> {
    let mut halves: BTreeMap<usize, (Option<PathBuf>, Option<PathBuf>)> = BTreeMap::new();
    if let Ok(entries) = std::fs::read_dir(folder.join("frames")) {
        for entry in entries.flatten() {
            let name = entry.file_name().to_string_lossy().to_string();
            if let Some((kind, n)) = frame_file(&name) {
                let slot = halves.entry(n).or_default();
                let path = folder.join("frames").join(&name);
                if kind == "camera" {
                    slot.0 = Some(path);
                } else {
                    slot.1 = Some(path);
                }
            }
        }
    }
    halves
        .into_iter()
        .filter_map(|(frame, (camera, bscan))| {
            Some((
                frame,
                FrameFiles {
                    frame,
                    camera_image: Some(camera?),
                    bscan_image: bscan?,
                },
            ))
        })
        .collect()
}

/// Time since the later of a frame's two files was last written, ms.
fn since_written_ms(files: &FrameFiles) -> Option<f64> {
    let written = |p: &Path| std::fs::metadata(p).and_then(|m| m.modified()).ok();
    let last = written(files.camera_image.as_deref()?)?.max(written(&files.bscan_image)?);
    Some(std::time::SystemTime::now().duration_since(last).ok()?.as_secs_f64() * 1e3)
}

fn complete(files: &FrameFiles) -> bool {
    files
        .camera_image
        .as_deref()
        .is_some_and(crate::io::image::file_complete)
        && crate::io::image::file_complete(&files.bscan_image)
}

struct State<'a> {
    manifest: &'a Manifest,
    feature: [f64; 3],
    pairs: Vec<Correspondence>,
    predicted: Vec<f64>,
    fit: Option<HornFit>,
}

impl State<'_> {
    /// Adds a processed frame: its prediction under the fit before it, then the refit.
    fn take(&mut self, mut record: FrameRecord) -> FolderFrame {
        let spacing = self.manifest.bscan_spacing_mm_per_px;
        let inputs = PairingInputs {
            dataset: "live",
            spacing_mm_per_px: spacing,
            initial_marker_T_image: None,
            min_frames: 0,
            fit_pixel_size: false,
        };
        let pair = solve::point_pairs(
            std::slice::from_mut(&mut record),
            Targets::Point(self.feature),
            &inputs,
            &mut |_| {},
        )
        .ok()
        .and_then(|(mut pairs, _)| pairs.pop());
        let mut predicted = None;
        if let Some(pair) = pair {
            if let Some(fit) = &self.fit {
                let (axes, _) = correspondence::bre(&pair, fit, spacing);
                let error = (axes[0].powi(2) + axes[1].powi(2) + axes[2].powi(2)).sqrt();
                if error.is_finite() {
                    predicted = Some(error);
                    self.predicted.push(error);
                }
            }
            let at = self.pairs.partition_point(|p| p.frame < pair.frame);
            self.pairs.insert(at, pair);
            if self.pairs.len() >= FIRST_FIT_FRAMES {
                let variant = settings::variant(self.manifest);
                if let Ok(fit) = correspondence::solve(&self.pairs, spacing, variant, None) {
                    self.fit = Some(fit);
                }
            }
        }
        let window = self.predicted.len().saturating_sub(RUNNING_WINDOW);
        let bre_mean_mm = self.fit.as_ref().map(|fit| {
            let mut sum = [0.0; 3];
            for p in &self.pairs {
                let (axes, _) = correspondence::bre(p, fit, spacing);
                for k in 0..3 {
                    sum[k] += axes[k];
                }
            }
            sum.map(|s| s / self.pairs.len().max(1) as f64)
        });
        FolderFrame {
            frame: record.files.frame,
            arrival_s: 0.0,
            latency_ms: 0.0,
            processing_ms: 0.0,
            rejected: record.rejection.as_ref().map(|r| r.to_string()),
            predicted_error_mm: predicted,
            running_error_mm: crate::core::stats::mean(self.predicted[window..].iter().copied()),
            frames_used: self.pairs.len(),
            bre_mean_mm,
        }
    }
}

/// Watches `watch.folder` and calibrates as frames arrive; `show` sees each
/// frame's outcome. Point-feature phantoms (hemisphere, point) with a camera.
pub fn run(manifest: &Manifest, watch: &Watch, show: &mut dyn FnMut(&FolderFrame)) -> Result<FolderRun, RunError> {
    let (detector, targets) = settings::detector(manifest);
    let Targets::Point(feature) = targets else {
        return Err(RunError::Unsupported(
            "live calibration from a folder takes a point-feature phantom (hemisphere or point)".into(),
        ));
    };
    if matches!(&manifest.camera, crate::manifest::CameraSource::Calibrate { board, .. } if board.refine_with_frames) {
        return Err(RunError::Unsupported(
            "camera.calibrate.refine_with_frames solves the camera again once every frame is in; live calibration uses the calibration views' intrinsics: set it to false for `live`".into(),
        ));
    }
    let name = manifest.datasets.first().map(|d| d.name.clone()).unwrap_or_default();
    if !watch.folder.is_dir() {
        return Err(RunError::Unsupported(format!(
            "{}: the watched folder does not exist",
            watch.folder.display()
        )));
    }
    let camera = crate::pipeline::run::camera::camera_stage(manifest, &name, &watch.folder)?;
    if camera.intrinsics.is_none() {
        return Err(RunError::Unsupported(
            "live calibration from a folder needs the camera (photos), not tracker poses".into(),
        ));
    }
    let rig = RigBoards::from_rig(&manifest.rig).map_err(|e| RunError::Unsupported(e.to_string()))?;
    let mut state = State {
        manifest,
        feature,
        pairs: Vec::new(),
        predicted: Vec::new(),
        fit: None,
    };
    let start = Instant::now();
    let mut last_new = Instant::now();
    let mut taken: BTreeSet<usize> = BTreeSet::new();
    let mut frames = Vec::new();
    let idle = Duration::from_secs_f64(watch.idle_s.max(0.0));
    let ending = loop {
        let mut progressed = false;
        for (frame, files) in listed(&watch.folder) {
            if taken.contains(&frame) || taken.len() >= crate::core::limits::MAX_FRAMES {
                continue;
            }
            let stale = last_new.elapsed() >= idle;
            if !complete(&files) && !stale {
                continue;
            }
            let arrived = Instant::now();
            let record = process_frame(&files, &camera, &rig, &detector)?;
            let mut outcome = state.take(record);
            outcome.arrival_s = arrived.duration_since(start).as_secs_f64();
            outcome.processing_ms = arrived.elapsed().as_secs_f64() * 1e3;
            outcome.latency_ms = since_written_ms(&files).unwrap_or(outcome.processing_ms);
            show(&outcome);
            frames.push(outcome);
            taken.insert(frame);
            progressed = true;
        }
        if progressed {
            last_new = Instant::now();
        }
        if let Ok(list) = crate::io::dataset::load_frame_list(&watch.folder) {
            if list.iter().all(|f| taken.contains(&f.frame)) {
                break Ending::FrameList;
            }
        }
        if last_new.elapsed() >= idle && !progressed {
            break Ending::Idle;
        }
        std::thread::sleep(Duration::from_millis(watch.poll_ms.max(1)));
    };
    let batch = match ending {
        Ending::FrameList => {
            let mut whole = manifest.clone();
            whole.datasets = vec![Dataset {
                name: name.clone(),
                source: DatasetSource::Folder(watch.folder.clone()),
            }];
            let dataset = whole.datasets[0].clone();
            Some(crate::pipeline::run::run_dataset(
                &whole,
                &dataset,
                &watch.folder,
                &mut |_| {},
            )?)
        }
        Ending::Idle => None,
    };
    Ok(FolderRun {
        frames,
        ending,
        last_fit: state.fit,
        batch,
    })
}

#[cfg(test)]
mod tests {
    use super::frame_file;

    #[test]
    fn frame_files_are_told_by_name() {
        assert_eq!(frame_file("camera_007.png"), Some(("camera", 7)));
        assert_eq!(frame_file("bscan_12.JPG"), Some(("bscan", 12)));
        for name in [
            "camera_.png",
            "camera_7.png.tmp",
            "bscan_x1.png",
            "view_001.png",
            "camera_0001234567890.png",
        ] {
            assert_eq!(frame_file(name), None, "{name}");
        }
    }
}
