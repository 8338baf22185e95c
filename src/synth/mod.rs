//! `probecal synth`: renders a dataset (camera photos, B-scans, calibration views)
//! from a generator spec, deterministically from its seed, with the ground truth
//! written beside it in `ground_truth.json` (read by the evaluation only).
//!
//! A rendered dataset is cached: `render_spec.json` holds the exact inputs and
//! the dataset is rendered again only when they change. Rendering happens in a
//! temporary folder that is renamed into place when complete.

pub mod board_seat;
pub mod bscan_geometry;
pub mod bscan_render;
pub mod camera_render;
pub mod occluders;
pub mod placement;
pub mod printable;
pub mod realism;
pub mod render_cache;
pub mod scene;
pub mod shape;
pub mod sliced_sweeps;
pub mod tracked_sweep;

use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::core::geometry::{to_rows, Rigid};
use crate::core::parallel::parallel_map;
use crate::core::rng::Rng;
use crate::detect::board::BoardLayout;
use crate::detect::board_pose::RigBoards;
use crate::io::camera_model::CameraIntrinsics;
use crate::io::dataset::FRAME_LIST;
use crate::spec::phantom::Phantom;
use crate::spec::render::RenderSpec;
use crate::spec::rig::{CameraCalibrationBoard, Rig};
use bscan_render::{Bubble, EchoModel};
use camera_render::{Photometry, PlacedBoard, RayMap};
use scene::{FrameKind, SceneInputs};

/// Bumped whenever a change to the renderer changes its pixels.
pub const GENERATOR_VERSION: u32 = 4;

#[derive(Debug, thiserror::Error)]
pub enum SynthError {
    #[error("{0}")]
    Scene(#[from] scene::SceneError),
    #[error("{0}")]
    Image(#[from] crate::io::image::ImageError),
    #[error("{path}: {message}")]
    Io { path: PathBuf, message: String },
    #[error("rendering needs {what}, which this manifest does not describe")]
    Unsupported { what: &'static str },
}

fn io_err(path: &Path) -> impl Fn(std::io::Error) -> SynthError + '_ {
    move |e| SynthError::Io {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

/// Everything that determines a rendered dataset's bytes.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct RenderInputs {
    pub generator_version: u32,
    pub spec: RenderSpec,
    pub rig: Rig,
    pub calibration_board: [u32; 2],
    pub calibration_square_mm: f64,
    pub phantom: Phantom,
    pub spacing_mm_per_px: [f64; 2],
}

/// What of an experiment the renderer needs: the rig, the phantom, the B-scan's
/// pixel size and the camera calibration board (when the camera is calibrated
/// from views; other experiments still get views of a 9x6 board of 30 mm).
#[derive(Debug, Clone, Copy)]
pub struct Lab<'a> {
    pub rig: &'a Rig,
    pub phantom: &'a Phantom,
    pub spacing_mm_per_px: [f64; 2],
    pub calibration_board: Option<&'a CameraCalibrationBoard>,
    /// The file that describes the lab (named in errors).
    pub described_in: &'a Path,
}

/// The lab's boards as the renderer draws them.
struct Boards {
    rig: RigBoards,
    calibration: BoardLayout,
}

fn boards(lab: &Lab<'_>) -> Result<Boards, SynthError> {
    let rig = RigBoards::from_rig(lab.rig).map_err(|e| SynthError::Io {
        path: lab.described_in.to_path_buf(),
        message: e.to_string(),
    })?;
    let calibration = match lab.calibration_board {
        Some(board) => BoardLayout {
            inner_corners: board.inner_corners,
            square_mm: board.square_mm,
            id_dots: 0,
        },
        // A file gives the intrinsics, or a tracker the poses; the views are still
        // rendered for inspection.
        None => BoardLayout {
            inner_corners: [9, 6],
            square_mm: 30.0,
            id_dots: 0,
        },
    };
    Ok(Boards { rig, calibration })
}

/// The exact inputs of a dataset render.
pub fn render_inputs(lab: &Lab<'_>, spec: &RenderSpec) -> Result<RenderInputs, SynthError> {
    let boards = boards(lab)?;
    Ok(RenderInputs {
        generator_version: GENERATOR_VERSION,
        spec: spec.clone(),
        rig: lab.rig.clone(),
        calibration_board: boards.calibration.inner_corners,
        calibration_square_mm: boards.calibration.square_mm,
        phantom: lab.phantom.clone(),
        spacing_mm_per_px: lab.spacing_mm_per_px,
    })
}

/// What a render did.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum RenderOutcome {
    Rendered,
    UpToDate,
    /// The cached dataset was damaged (the reason) and was rendered again.
    Repaired(String),
}

/// Every rendered file's SHA-256, size and path, checked before a cached dataset
/// is reused: a deleted, truncated or altered file has it rendered again.
pub const RENDERED_FILES: &str = "rendered_files.sha256";

/// The files of a rendered folder, relative and sorted (the listing and the spec aside).
fn rendered_files(folder: &Path) -> Result<Vec<String>, SynthError> {
    fn walk(dir: &Path, root: &Path, out: &mut Vec<String>) -> std::io::Result<()> {
        for entry in std::fs::read_dir(dir)? {
            let path = entry?.path();
            if path.is_dir() {
                walk(&path, root, out)?;
            } else if let Ok(rel) = path.strip_prefix(root) {
                out.push(crate::io::fs::display_path(rel));
            }
        }
        Ok(())
    }
    let mut out = Vec::new();
    walk(folder, folder, &mut out).map_err(io_err(folder))?;
    out.retain(|f| f != RENDERED_FILES && f != "render_spec.json");
    out.sort();
    Ok(out)
}

/// The listing of a rendered folder: `sha256 size path` per file.
fn listing(folder: &Path) -> Result<String, SynthError> {
    let mut text = String::new();
    for rel in rendered_files(folder)? {
        let (size, sha) = crate::io::fs::file_sha256(&folder.join(&rel)).map_err(io_err(folder))?;
        text.push_str(&format!("{sha} {size} {rel}\n"));
    }
    Ok(text)
}

/// What is wrong with a cached rendered folder against its listing, if anything.
fn damage(folder: &Path) -> Option<String> {
    let Ok(listed) =
        crate::io::fs::read_text_capped(&folder.join(RENDERED_FILES), crate::core::limits::MAX_TEXT_FILE_BYTES)
    else {
        return Some(format!("{RENDERED_FILES} is missing"));
    };
    let mut entries = Vec::new();
    for line in listed.lines() {
        let mut parts = line.splitn(3, ' ');
        let (Some(sha), Some(size), Some(rel)) = (parts.next(), parts.next(), parts.next()) else {
            return Some(format!("{RENDERED_FILES} has a malformed line"));
        };
        entries.push((sha, size, rel));
    }
    // The files are hashed on every core; the first damaged one in listing order is reported.
    parallel_map(entries.len(), |i| {
        let (sha, size, rel) = entries[i];
        match crate::io::fs::file_sha256(&folder.join(rel)) {
            Err(_) => Some(format!("{rel} is missing")),
            Ok((n, _)) if n.to_string() != size => Some(format!("{rel} has {n} bytes, {size} were rendered")),
            Ok((_, h)) if h != sha => Some(format!("{rel} differs from what was rendered")),
            Ok(_) => None,
        }
    })
    .into_iter()
    .flatten()
    .next()
}

/// Renders `spec` into `folder` unless the folder already holds exactly this render.
pub fn ensure_rendered(lab: &Lab<'_>, spec: &RenderSpec, folder: &Path) -> Result<RenderOutcome, SynthError> {
    let inputs = render_inputs(lab, spec)?;
    let inputs_json = serde_json::to_string_pretty(&inputs).map_err(|e| SynthError::Io {
        path: folder.to_path_buf(),
        message: e.to_string(),
    })?;
    let spec_file = folder.join("render_spec.json");
    let mut outcome = RenderOutcome::Rendered;
    if crate::io::fs::read_text_capped(&spec_file, crate::core::limits::MAX_TEXT_FILE_BYTES)
        .ok()
        .as_deref()
        == Some(inputs_json.as_str())
    {
        match damage(folder) {
            None => return Ok(RenderOutcome::UpToDate),
            Some(reason) => outcome = RenderOutcome::Repaired(reason),
        }
    }
    let parent = folder.parent().map(Path::to_path_buf).unwrap_or_default();
    std::fs::create_dir_all(&parent).map_err(io_err(&parent))?;
    let name = folder
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_default();
    let partial = parent.join(format!(".{name}.partial"));
    if partial.exists() {
        std::fs::remove_dir_all(&partial).map_err(io_err(&partial))?;
    }
    let cache = render_cache::entry(&inputs_json);
    let cached = match &cache {
        Some(entry) => render_cache::fetch(entry, &inputs_json, &partial)?,
        None => false,
    };
    if !cached {
        render_into(lab, spec, &partial)?;
        let files = listing(&partial)?;
        std::fs::write(partial.join(RENDERED_FILES), files).map_err(io_err(&partial))?;
        std::fs::write(partial.join("render_spec.json"), &inputs_json).map_err(io_err(&partial))?;
        if let Some(entry) = &cache {
            render_cache::store(&partial, entry)?;
        }
    }
    if folder.exists() {
        std::fs::remove_dir_all(folder).map_err(io_err(folder))?;
    }
    std::fs::rename(&partial, folder).map_err(io_err(folder))?;
    Ok(outcome)
}

#[derive(Serialize)]
struct GroundTruthFrame {
    frame: usize,
    kind: FrameKind,
    camera_T_marker_photo: [[f64; 4]; 4],
    camera_T_marker_bscan: [[f64; 4]; 4],
    elevation_offset_mm: f64,
    centre_projection_px: [f64; 2],
    /// Wire phantoms: where each wire's axis crosses the B-scan plane, px.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    wire_dots_px: Vec<crate::io::truth::WireDot>,
    bubbles: Vec<Bubble>,
    occluder: Option<scene::Occluder>,
    /// The session's named occluders in this photo (`render.occluders`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    stated_occluders: Vec<occluders::PlacedOccluder>,
}

#[derive(Serialize)]
struct GroundTruthFile {
    generator_version: u32,
    seed: u64,
    camera: CameraIntrinsics,
    marker_T_image: [[f64; 4]; 4],
    camera_T_phantom: [[f64; 4]; 4],
    phantom: Phantom,
    bscan_size_px: [usize; 2],
    bscan_apex_mm: [f64; 2],
    /// True range per displayed range (written when it is not 1).
    #[serde(skip_serializing_if = "is_one")]
    range_scale: f64,
    frames: Vec<GroundTruthFrame>,
    camera_calibration_views: Vec<[[f64; 4]; 4]>,
}

/// The lab's scene for a render spec: where everything is in every frame
/// (the geometry only; nothing is drawn).
pub fn scene_of(lab: &Lab<'_>, spec: &RenderSpec) -> Result<scene::Scene, SynthError> {
    Ok(realised(lab, spec)?.scene)
}

/// The scene with the rig's error sources applied, and what the renderer needs of them.
struct Realised {
    scene: scene::Scene,
    /// The spec as rendered (the lens applied).
    spec: RenderSpec,
    systematic: realism::Systematic,
    motions: Vec<Option<camera_render::BoardMotion>>,
}

fn realised(lab: &Lab<'_>, spec: &RenderSpec) -> Result<Realised, SynthError> {
    let spec = realism::effective_spec(spec);
    let systematic = realism::systematic(&spec, lab.phantom);
    let Boards { rig, calibration } = boards(lab)?;
    let mut scene = placement::build(&SceneInputs {
        spec: &spec,
        probe_board: rig.probe,
        phantom_board: rig.phantom,
        calibration_board: calibration,
        phantom: &systematic.phantom,
        spacing_mm_per_px: lab.spacing_mm_per_px,
    })?;
    let motions = realism::apply_to_frames(&spec, &mut scene);
    Ok(Realised {
        scene,
        spec,
        systematic,
        motions,
    })
}

/// The truth of where each wire or cut dome shows in a B-scan (its centre's
/// projection, displayed at the scanner's range scale), px.
fn truth_dots(
    phantom: &Phantom,
    scene: &scene::Scene,
    world_T_image: &Rigid,
    range_scale: f64,
) -> Vec<crate::io::truth::WireDot> {
    match (phantom, &scene.shape) {
        (Phantom::FourWire { wires, .. }, shape::Shape::Wires { wires_world, .. }) => wires
            .iter()
            .zip(wires_world)
            .filter_map(|(w, (a, b))| {
                let p = shape::segment_in_plane(world_T_image, a, b)?;
                let [sx, sy] = scene.bscan.spacing_mm_per_px;
                let (u, v) = scene.bscan.displayed(p.x, p.y, range_scale);
                Some(crate::io::truth::WireDot {
                    wire: w.name.clone(),
                    pixel: [u / sx, v / sy],
                })
            })
            .collect(),
        // Each dome the plane cuts: its centre's projection (the arc's centre).
        (Phantom::Spheres { spheres }, shape::Shape::Spheres { domes_world }) => spheres
            .iter()
            .zip(domes_world)
            .filter_map(|(s, (centre, r))| {
                let p = world_T_image.inverse() * centre;
                let [sx, sy] = scene.bscan.spacing_mm_per_px;
                let (u, v) = scene.bscan.displayed(p.x, p.y, range_scale);
                (p.z.abs() < *r).then(|| crate::io::truth::WireDot {
                    wire: s.name.clone(),
                    pixel: [u / sx, v / sy],
                })
            })
            .collect(),
        _ => Vec::new(),
    }
}

/// The camera-calibration photos: a plain board in each view, each on a core.
fn render_calibration_views(
    scene: &scene::Scene,
    rays: &RayMap,
    photometry: Photometry,
    seed: u64,
    calib_dir: &Path,
    progress: &crate::core::progress::Progress,
) -> Result<(), SynthError> {
    let calibration_board = crate::detect::board::PrintedBoard::Checkerboard(scene.calibration_board);
    let results = parallel_map(
        scene.camera_T_calibration_board.len(),
        |view| -> Result<(), SynthError> {
            let mut rng = Rng::fork(seed, 1000 + view as u64);
            let board = PlacedBoard {
                camera_T_board: scene.camera_T_calibration_board[view],
                layout: &calibration_board,
                occluders: Vec::new(),
                print_scale: 1.0,
                bow_mm: 0.0,
                motion: None,
            };
            let image = camera_render::render_photo(&scene.camera, rays, &[board], photometry, &mut rng)?;
            image.write_png(&calib_dir.join(format!("view_{view:03}.png")))?;
            progress.inc();
            Ok(())
        },
    );
    results.into_iter().collect::<Result<Vec<_>, _>>()?;
    Ok(())
}

/// The dataset's frame list: each frame's photo and B-scan.
fn write_frame_list(folder: &Path, frames: usize, jpeg: Option<u8>) -> Result<(), SynthError> {
    let mut list = String::from("frame,camera_image,bscan_image\n");
    for k in 0..frames {
        list.push_str(&format!("{k},frames/{},frames/bscan_{k:03}.png\n", photo_name(k, jpeg)));
    }
    let list_path = folder.join(FRAME_LIST);
    std::fs::write(&list_path, list).map_err(io_err(&list_path))
}

/// Writes `value` as pretty JSON at `path`.
fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<(), SynthError> {
    let text = serde_json::to_string_pretty(value).map_err(|e| SynthError::Io {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    std::fs::write(path, text).map_err(io_err(path))
}

/// The two boards of frame photo: the probe board where the marker is (with
/// the plan's and the session's occluders), the phantom board where it stands.
fn frame_boards<'a>(
    scene: &'a scene::Scene,
    camera_T_marker_photo: Rigid,
    plan: &scene::FramePlan,
    stated: &occluders::PhotoOccluders,
    systematic: &realism::Systematic,
    motion: Option<camera_render::BoardMotion>,
) -> [PlacedBoard<'a>; 2] {
    let camera_T_phantom = scene.camera_T_world * scene.world_T_phantom;
    [
        PlacedBoard {
            camera_T_board: camera_T_marker_photo,
            layout: &scene.probe_board,
            occluders: plan.occluder.into_iter().chain(stated.probe()).collect(),
            print_scale: systematic.print_scale[0],
            bow_mm: systematic.bow_mm[0],
            motion,
        },
        PlacedBoard {
            camera_T_board: camera_T_phantom,
            layout: &scene.phantom_board,
            occluders: stated.phantom().collect(),
            print_scale: systematic.print_scale[1],
            bow_mm: systematic.bow_mm[1],
            motion: None,
        },
    ]
}

fn render_into(lab: &Lab<'_>, spec: &RenderSpec, folder: &Path) -> Result<(), SynthError> {
    let Realised {
        scene,
        spec,
        systematic,
        motions,
    } = realised(lab, spec)?;
    let spec = &spec;
    let range_scale = realism::range_scale(spec);
    let jpeg = realism::of(spec).jpeg.map(|j| j.quality);
    let frames_dir = folder.join("frames");
    let calib_dir = folder.join("camera_calibration");
    std::fs::create_dir_all(&frames_dir).map_err(io_err(&frames_dir))?;
    std::fs::create_dir_all(&calib_dir).map_err(io_err(&calib_dir))?;
    let rays = RayMap::new(&scene.camera);
    let photometry = Photometry {
        noise_grey_levels: spec.camera.noise_grey_levels,
        blur_sigma_px: spec.camera.blur_sigma_px,
        lighting_gradient: spec.camera.lighting_gradient,
    };
    let echo = EchoModel {
        slice_thickness_mm: spec.bscan.slice_thickness_mm,
        bubble_rate: spec.bscan.bubble_rate,
        range_scale,
    };

    let progress =
        crate::core::progress::Progress::new(scene.camera_T_calibration_board.len() + scene.frames.len(), "rendering");
    render_calibration_views(&scene, &rays, photometry, spec.seed, &calib_dir, &progress)?;

    let camera_T_phantom = scene.camera_T_world * scene.world_T_phantom;
    let frame_results = parallel_map(scene.frames.len(), |k| -> Result<GroundTruthFrame, SynthError> {
        let plan = &scene.frames[k];
        let mut rng = Rng::fork(spec.seed, 10_000 + k as u64);
        let camera_T_marker_photo = scene.camera_T_world * plan.world_T_marker_photo;
        let stated = occluders::draw(
            spec.occluders.as_ref(),
            &scene.probe_board,
            &scene.phantom_board,
            spec.seed,
            k,
        );
        let boards = frame_boards(&scene, camera_T_marker_photo, plan, &stated, &systematic, motions[k]);
        let photo = camera_render::render_photo(&scene.camera, &rays, &boards, photometry, &mut rng)?;
        let photo_path = frames_dir.join(photo_name(k, jpeg));
        match jpeg {
            Some(quality) => photo.write_jpeg(&photo_path, quality)?,
            None => photo.write_png(&photo_path)?,
        }
        let world_T_image: Rigid = plan.world_T_marker_bscan * scene.marker_T_image;
        let bubbles = bscan_render::draw_bubbles(&scene, &world_T_image, plan.kind, echo, &mut rng);
        let bscan = bscan_render::render_bscan(&scene, &world_T_image, &bubbles, echo, &mut rng)?;
        let wire_dots_px = truth_dots(lab.phantom, &scene, &world_T_image, range_scale);
        bscan.write_png(&frames_dir.join(format!("bscan_{k:03}.png")))?;
        progress.inc();
        Ok(GroundTruthFrame {
            frame: k,
            kind: plan.kind,
            camera_T_marker_photo: to_rows(&camera_T_marker_photo),
            camera_T_marker_bscan: to_rows(&(scene.camera_T_world * plan.world_T_marker_bscan)),
            elevation_offset_mm: plan.elevation_offset_mm,
            centre_projection_px: plan.centre_projection_px,
            wire_dots_px,
            bubbles,
            occluder: plan.occluder,
            stated_occluders: stated.all,
        })
    });
    progress.finish();
    let truth_frames = frame_results.into_iter().collect::<Result<Vec<_>, _>>()?;

    write_frame_list(folder, scene.frames.len(), jpeg)?;
    write_tracker_poses(spec, &scene, camera_T_phantom, folder)?;

    let truth = GroundTruthFile {
        generator_version: GENERATOR_VERSION,
        seed: spec.seed,
        camera: scene.camera.clone(),
        marker_T_image: to_rows(&scene.marker_T_image),
        camera_T_phantom: to_rows(&camera_T_phantom),
        phantom: systematic.phantom.clone(),
        bscan_size_px: [scene.bscan.width_px, scene.bscan.height_px],
        bscan_apex_mm: scene.bscan.apex_mm,
        range_scale,
        frames: truth_frames,
        camera_calibration_views: scene.camera_T_calibration_board.iter().map(to_rows).collect(),
    };
    write_json(&folder.join(crate::io::truth::GROUND_TRUTH_FILE), &truth)
}

fn is_one(v: &f64) -> bool {
    *v == 1.0
}

/// A frame's photo: PNG, or JPEG when the rig's camera saves JPEG.
fn photo_name(k: usize, jpeg: Option<u8>) -> String {
    match jpeg {
        Some(_) => format!("camera_{k:03}.jpg"),
        None => format!("camera_{k:03}.png"),
    }
}

/// The simulated optical tracker: its frame is the camera's, its poses are the
/// marker's at the moment of the B-scan and the phantom's, each with Gaussian
/// noise of the spec's size (in the marker's own frame), from a stream of its own.
fn write_tracker_poses(
    spec: &RenderSpec,
    scene: &scene::Scene,
    camera_T_phantom: Rigid,
    folder: &Path,
) -> Result<(), SynthError> {
    let noise = &spec.tracker;
    let jitter = |rng: &mut Rng| {
        let r = noise.rotation_sd_deg.to_radians();
        let t = noise.position_sd_mm;
        crate::core::geometry::rigid_from_axis_angle(
            nalgebra::Vector3::new(rng.normal(0.0, r), rng.normal(0.0, r), rng.normal(0.0, r)),
            nalgebra::Vector3::new(rng.normal(0.0, t), rng.normal(0.0, t), rng.normal(0.0, t)),
        )
    };
    let mut rows = Vec::new();
    for (k, plan) in scene.frames.iter().enumerate() {
        let mut rng = Rng::fork(spec.seed, 20_000 + k as u64);
        let tracker_T_marker = scene.camera_T_world * plan.world_T_marker_bscan * jitter(&mut rng);
        let tracker_T_phantom = camera_T_phantom * jitter(&mut rng);
        rows.push((k, "ProbeToTracker", tracker_T_marker));
        rows.push((k, "ReferenceToTracker", tracker_T_phantom));
    }
    let path = folder.join(crate::spec::render::RENDERED_TRACKER_POSES);
    crate::io::tracker_poses::write(&path, &rows).map_err(io_err(&path))
}

/// Where a rendered dataset lives.
pub fn dataset_folder(datasets_root: &Path, experiment: &str, dataset: &str) -> PathBuf {
    datasets_root.join(format!("{experiment}__{dataset}"))
}
