//! Designing a dome phantom by the bound: candidate layouts (number of domes,
//! radius, spacing, offsets along the plane's normal, heights) in the manifest's
//! lab, each scored by the Cramér–Rao bound of its calibration over the
//! manifest's own sweep (`evaluate::sphere_bound`), and ranked.
//!
//! A layout is laid out around the lab's feature point (the world origin, the
//! renderer's), with the domes in a row across the sweep (the image's lateral
//! axis), staggered along the plane's normal (world y) from `-stagger` to
//! `+stagger` and in height by `±height_step / 2`. It is printable when its domes
//! stand at least `MIN_GAP_MM` apart and the sweep can be laid out with every cut
//! dome's arc inside the fan (the renderer's own placement decides).

use nalgebra::{Point2, Point3, Vector3};
use serde::Serialize;

use crate::core::geometry::{image_probe_points, Rigid};
use crate::detect::board_pose::RigBoards;
use crate::detect::camera_refinement::{self, BoardView};
use crate::estimate::edge_blur::SliceBlur;
use crate::estimate::edge_offset::EdgeOffset;
use crate::estimate::sphere_fit::KnownSphere;
use crate::evaluate::pose_noise::{self, PhotoNoise, SweepPhoto};
use crate::evaluate::sphere_bound::{self, BoundFrame, EdgeNoise};
use crate::io::camera_model::CameraIntrinsics;
use crate::manifest::Manifest;
use crate::spec::phantom::{Phantom, Sphere};
use crate::spec::render::RenderSpec;
use crate::synth::scene::{lab_layout, FrameKind};

/// The noise the bound is computed under. Every value was measured on the
/// default hemisphere run (`reports/hemisphere_checkerboard/dataset3`), the
/// same camera, boards and sweep; residual RMS values are scaled by
/// `√(n / (n − p))` for the `p` unknowns fitted to their `n` residuals:
/// - the edge points' SD about their circle: the median arc-fit RMS there,
///   0.62 px of 0.2 mm (`frames.csv`, `arc_rms_px`);
/// - an arc counts as 20 independent points (its noise is correlated along it;
///   the sphere fit weighs an arc so);
/// - a probe-board corner's SD per image axis: the median reprojection RMS of
///   the probe board's pose there, 0.0811 px (`probe_board_rms_px`, 100
///   corners, 6 unknowns);
/// - a phantom-board corner's: 0.0547 px likewise (`phantom_board_rms_px`);
/// - a camera-calibration corner's: the calibration's RMS there, 0.0767 px
///   (`summary.json`, `camera.rms_px`; 16 views of 54 corners, 9 intrinsics
///   and 16 poses).
///
/// The hand's motion between photo and B-scan is the sweep's stated tremor
/// (`render.sweep.tremor_mm`, `tremor_deg`).
pub const NOISE: BoundNoise = BoundNoise {
    edge_sd_mm: 0.124,
    points_per_arc: 20.0,
    probe_corner_sd_px: 0.0823,
    phantom_corner_sd_px: 0.0556,
    calibration_corner_sd_px: 0.0792,
};

/// [`NOISE`] with the edge points placed at their ridges' centres along the
/// normal (`bscan.arc_detection.peak: normal`): the median arc-fit RMS of the
/// default hemisphere run with that detector
/// (`probecal run experiments/measurements/hemisphere_normal_peak.yaml`, its
/// `frames.csv`), 0.2685 px of 0.2 mm. An arc is still taken as worth 20
/// independent points.
pub const NOISE_NORMAL_PEAK: BoundNoise = BoundNoise {
    edge_sd_mm: 0.0537,
    ..NOISE
};

/// The noise the bound assumes for the manifest's arc detector.
pub fn noise(manifest: &Manifest) -> BoundNoise {
    match manifest.arc_detection.peak {
        crate::manifest::EchoPeak::Column => NOISE,
        crate::manifest::EchoPeak::Normal => NOISE_NORMAL_PEAK,
    }
}

/// The noise of the arcs and of the camera's measurements.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct BoundNoise {
    /// SD of an edge point's distance from its sphere, mm.
    pub edge_sd_mm: f64,
    /// Independent points an arc is worth.
    pub points_per_arc: f64,
    /// SD of a board corner's position per image axis in a sweep photo, px.
    pub probe_corner_sd_px: f64,
    pub phantom_corner_sd_px: f64,
    /// SD of a corner's position per image axis in a camera-calibration view, px.
    pub calibration_corner_sd_px: f64,
}

/// The arcs' part of the manifest's [`noise`], with the growth of the edge
/// noise with the cut that its pose-prior fit weighs the arcs by.
pub fn edge_noise(manifest: &Manifest) -> EdgeNoise {
    let noise = noise(manifest);
    EdgeNoise {
        edge_sd_mm: noise.edge_sd_mm,
        points_per_arc: noise.points_per_arc,
        slice_blur: slice_blur_model(manifest),
    }
}

/// Domes closer than this (mm, surface to surface) are not printable apart.
pub const MIN_GAP_MM: f64 = 2.0;
/// Echo points are taken this far either side of an arc's top (the dome's
/// echo fades with the beam's incidence).
const ARC_HALF_SPAN_DEG: f64 = 55.0;

/// A candidate layout's parameters.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Layout {
    pub domes: usize,
    pub radius_mm: f64,
    /// Surface-to-surface gap between neighbours across the sweep.
    pub gap_mm: f64,
    /// The outer domes' offset along the plane's normal (the row runs from
    /// `-stagger` to `+stagger`).
    pub stagger_mm: f64,
    /// Neighbouring domes' difference in height.
    pub height_step_mm: f64,
}

impl Layout {
    /// The domes in the world frame (the lab's feature point at the origin).
    pub fn centres_world(&self) -> Vec<Point3<f64>> {
        let n = self.domes;
        let pitch = 2.0 * self.radius_mm + self.gap_mm;
        (0..n)
            .map(|k| {
                let t = if n > 1 { k as f64 / (n - 1) as f64 } else { 0.5 };
                let x = pitch * (k as f64 - (n as f64 - 1.0) / 2.0);
                let y = self.stagger_mm * (2.0 * t - 1.0);
                let z = if k % 2 == 0 { -0.5 } else { 0.5 } * self.height_step_mm;
                Point3::new(x, y, z)
            })
            .collect()
    }

    /// The phantom in the phantom frame of a lab (`world_T_phantom`).
    pub fn phantom(&self, world_T_phantom: &Rigid) -> Phantom {
        let phantom_T_world = world_T_phantom.inverse();
        let centres = self.centres_world();
        // Centred on the feature point exactly (the height steps may not cancel).
        let mean = centres.iter().fold(Vector3::zeros(), |acc, c| acc + c.coords) / centres.len() as f64;
        Phantom::Spheres {
            spheres: centres
                .iter()
                .enumerate()
                .map(|(k, c)| {
                    let p = phantom_T_world * Point3::from(c.coords - mean);
                    Sphere {
                        name: format!("dome{}", k + 1),
                        centre_in_phantom_mm: [p.x, p.y, p.z].map(|v| (v * 10.0).round() / 10.0),
                        radius_mm: self.radius_mm,
                    }
                })
                .collect(),
        }
    }
}

/// The candidates: 2 to 4 domes of 8 to 12.5 mm, two gaps, four staggers, two heights.
pub fn candidates() -> Vec<Layout> {
    let mut out = Vec::new();
    for domes in [2, 3, 4] {
        for radius_mm in [8.0, 10.0, 12.5] {
            for gap_mm in [MIN_GAP_MM, 6.0] {
                for stagger_mm in [0.0, 3.0, 5.0, 7.0] {
                    for height_step_mm in [0.0, 4.0] {
                        out.push(Layout {
                            domes,
                            radius_mm,
                            gap_mm,
                            stagger_mm,
                            height_step_mm,
                        });
                    }
                }
            }
        }
    }
    out
}

/// A phantom's bound over the manifest's sweep.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Bound {
    /// RMS error over the image corners and centre, mm.
    pub rms_mm: f64,
    pub frames: usize,
    pub arcs: usize,
}

/// What the camera calibration knows of the intrinsics: its board views, and
/// (when the manifest refines the camera with the frames) every photo's two boards.
fn intrinsics_information(
    manifest: &Manifest,
    scene: &crate::synth::scene::Scene,
    noise: &BoundNoise,
) -> Result<pose_noise::IntrinsicsInformation, BoundError> {
    let probe_corners = scene.probe_board.feature_points_mm();
    let phantom_corners = scene.phantom_board.feature_points_mm();
    let camera_T_phantom = scene.camera_T_world * scene.world_T_phantom;
    let mut intrinsics_information = pose_noise::calibration_information(
        &scene.camera,
        &scene.camera_T_calibration_board,
        &scene.calibration_board.corners_in_board_mm(),
        noise.calibration_corner_sd_px,
    )
    .ok_or(BoundError::Unusable("a camera-calibration view is behind the camera"))?;
    if refines_with_frames(manifest) {
        // Every photo's two boards are more calibration views (each with its own
        // pose): the information their corners hold on the intrinsics beyond
        // what they hold on their poses, which the frames' pose noise carries.
        // A board where an earlier photo saw it is that view again, counted
        // once, as the run's refinement counts it (`camera_refinement::repeats`).
        let marker_views: Vec<_> = scene
            .frames
            .iter()
            .map(|p| scene.camera_T_world * p.world_T_marker_photo)
            .collect();
        let phantom_views = vec![camera_T_phantom; scene.frames.len()];
        for (views, corners, sd) in [
            (&marker_views, &probe_corners, noise.probe_corner_sd_px),
            (&phantom_views, &phantom_corners, noise.phantom_corner_sd_px),
        ] {
            let behind = BoundError::Unusable("a frame's board is behind the camera");
            let distinct = distinct_views(&scene.camera, views, corners).ok_or(behind.clone())?;
            intrinsics_information +=
                pose_noise::calibration_information(&scene.camera, &distinct, corners, sd).ok_or(behind)?;
        }
    }
    Ok(intrinsics_information)
}

/// The bound of `phantom` in the manifest's lab for a render spec: the
/// scene's frames (all but those where the probe moved between photo and
/// B-scan, or the plane misses), each cut dome's arc sampled one point per
/// pixel column within ±55° of its top; the boards' poses from their corners
/// in the scene's photos, with the intrinsics from the scene's calibration views.
/// The noise is the manifest's [`noise`].
pub fn bound_of(manifest: &Manifest, phantom: &Phantom, spec: &RenderSpec) -> Result<Bound, BoundError> {
    let noise = noise(manifest);
    let mut lab = crate::pipeline::settings::lab(manifest);
    lab.phantom = phantom;
    let scene = crate::synth::scene_of(&lab, spec).map_err(|e| BoundError::Scene(e.to_string()))?;
    if lab.calibration_board.is_none() {
        return Err(BoundError::Unusable(
            "the bound models a camera calibrated from board views (`camera.calibrate`)",
        ));
    }
    let photo_noise = PhotoNoise {
        probe_corner_sd_px: noise.probe_corner_sd_px,
        phantom_corner_sd_px: noise.phantom_corner_sd_px,
        tremor_sd_mm: spec.sweep.tremor_mm,
        tremor_sd_deg: spec.sweep.tremor_deg,
    };
    let probe_corners = scene.probe_board.feature_points_mm();
    let phantom_corners = scene.phantom_board.feature_points_mm();
    let camera_T_phantom = scene.camera_T_world * scene.world_T_phantom;
    let intrinsics_information = intrinsics_information(manifest, &scene, &noise)?;
    let spheres: Vec<KnownSphere> = crate::pipeline::settings::known_spheres(phantom).ok_or(BoundError::Unusable(
        "the bound is of dome phantoms (hemisphere, spheres)",
    ))?;
    let [sx, _] = manifest.bscan_spacing_mm_per_px;
    // The detector finds arcs down to this fraction of the radius.
    let min_fraction = manifest.arc_detection.radius_fraction[0];
    let half_span = ARC_HALF_SPAN_DEG.to_radians().sin();
    let phantom_T_world = scene.world_T_phantom.inverse();
    let mut frames = Vec::new();
    let mut arcs = 0;
    for plan in scene
        .frames
        .iter()
        .filter(|p| !matches!(p.kind, FrameKind::Jerk | FrameKind::Missing))
    {
        let phantom_T_marker = phantom_T_world * plan.world_T_marker_bscan;
        let image_T_phantom = (phantom_T_marker * scene.marker_T_image).inverse();
        let mut frame_arcs = Vec::new();
        for (k, s) in spheres.iter().enumerate() {
            let p = image_T_phantom * s.centre_in_phantom_mm;
            let r2 = s.radius_mm.powi(2) - p.z * p.z;
            if r2 <= (min_fraction * s.radius_mm).powi(2) {
                continue;
            }
            let r = r2.sqrt();
            let columns = (2.0 * r * half_span / sx).floor() as i64;
            let points: Vec<Point3<f64>> = (0..=columns)
                .map(|i| {
                    let dx = -r * half_span + i as f64 * sx;
                    Point3::new(p.x + dx, p.y - (r * r - dx * dx).max(0.0).sqrt(), 0.0)
                })
                .collect();
            frame_arcs.push((k, points));
        }
        if !frame_arcs.is_empty() {
            let photo = SweepPhoto {
                camera_T_marker: scene.camera_T_world * plan.world_T_marker_photo,
                camera_T_phantom,
                marker_corners_mm: &probe_corners,
                phantom_corners_mm: &phantom_corners,
            };
            let pose = pose_noise::frame_pose_noise(&scene.camera, &photo, &photo_noise)
                .ok_or(BoundError::Unusable("a board's pose is not determined by its corners"))?;
            arcs += frame_arcs.len();
            frames.push(BoundFrame {
                phantom_T_marker,
                arcs: frame_arcs,
                pose_cov: pose.cov,
                pose_from_intrinsics: pose.from_intrinsics,
            });
        }
    }
    let probes = image_probe_points(
        [scene.bscan.width_px, scene.bscan.height_px],
        manifest.bscan_spacing_mm_per_px,
    );
    let edge = edge_noise(manifest);
    let rms_mm = sphere_bound::corner_rms_bound(
        &scene.marker_T_image,
        &frames,
        &spheres,
        &edge,
        &intrinsics_information,
        edge_offset_model(manifest),
        &probes,
    )
    .ok_or(BoundError::Unusable("the layout leaves the calibration unobserved"))?;
    Ok(Bound {
        rms_mm,
        frames: frames.len(),
        arcs,
    })
}

/// The echo edge's offset model the manifest's pose-prior fit solves (the
/// bound marginalises the same unknowns).
pub fn edge_offset_model(manifest: &Manifest) -> crate::estimate::edge_offset::EdgeOffset {
    manifest
        .sphere_fit
        .pose_prior
        .as_ref()
        .map(|p| p.edge_offset)
        .unwrap_or_default()
}

/// The growth of the edge noise with the cut that the manifest's pose-prior
/// fit weighs the arcs by (the bound assumes the same).
pub fn slice_blur_model(manifest: &Manifest) -> Option<SliceBlur> {
    manifest.sphere_fit.pose_prior.as_ref().and_then(|p| p.slice_blur)
}

/// Whether the manifest solves the camera again with the frames' boards.
/// The views of one board that are not a repeat of an earlier one as the
/// camera sees them (`camera_refinement::repeats`), or `None` if a corner is
/// behind the camera.
fn distinct_views(
    camera: &CameraIntrinsics,
    camera_T_views: &[Rigid],
    corners_mm: &[Point2<f64>],
) -> Option<Vec<Rigid>> {
    let views = camera_T_views
        .iter()
        .map(|pose| {
            let flat = crate::detect::projection::projections(camera, pose, corners_mm)?;
            Some(BoardView {
                label: String::new(),
                corners_mm: corners_mm.to_vec(),
                corners_px: flat.chunks(2).map(|p| [p[0], p[1]]).collect(),
            })
        })
        .collect::<Option<Vec<_>>>()?;
    Some(
        camera_refinement::repeats(&views)
            .iter()
            .zip(camera_T_views)
            .filter(|(r, _)| r.is_none())
            .map(|(_, pose)| *pose)
            .collect(),
    )
}

pub fn refines_with_frames(manifest: &Manifest) -> bool {
    matches!(&manifest.camera, crate::manifest::CameraSource::Calibrate { board, .. } if board.refine_with_frames)
}

/// Why a layout has no bound.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BoundError {
    #[error("{0}")]
    Scene(String),
    #[error("{0}")]
    Unusable(&'static str),
    #[error("seed {seed}: {source}")]
    Seed { seed: u64, source: Box<BoundError> },
}

/// A row's bound as the table's JSON gives it: `{"Ok": bound}` or `{"Err": reason}`.
pub fn bound_or_reason<S: serde::Serializer>(bound: &Result<Bound, BoundError>, s: S) -> Result<S::Ok, S::Error> {
    bound.as_ref().map_err(|e| e.to_string()).serialize(s)
}

/// One row of the design table.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DesignRow {
    pub layout: Layout,
    pub phantom: Phantom,
    /// The bound, or why the layout is not usable (does not fit the sweep).
    #[serde(serialize_with = "bound_or_reason")]
    pub bound: Result<Bound, BoundError>,
}

/// Sweeps a layout is designed over: the render spec with these seeds (not
/// the seeds of the experiment's dataset or of its study).
pub const DESIGN_SEEDS: std::ops::Range<u64> = 2000..2010;

/// A phantom's bound over several sweeps: the RMS of the sweeps' bounds (mean
/// frames and arcs); a sweep the layout does not fit makes it unusable.
pub fn bound_over_sweeps(
    manifest: &Manifest,
    phantom: &Phantom,
    spec: &RenderSpec,
    seeds: std::ops::Range<u64>,
) -> Result<Bound, BoundError> {
    let mut bounds = Vec::new();
    for seed in seeds {
        let mut spec = spec.clone();
        spec.seed = seed;
        bounds.push(bound_of(manifest, phantom, &spec).map_err(|e| BoundError::Seed {
            seed,
            source: Box::new(e),
        })?);
    }
    let n = bounds.len().max(1) as f64;
    Ok(Bound {
        rms_mm: (bounds.iter().map(|b| b.rms_mm.powi(2)).sum::<f64>() / n).sqrt(),
        frames: (bounds.iter().map(|b| b.frames).sum::<usize>() as f64 / n).round() as usize,
        arcs: (bounds.iter().map(|b| b.arcs).sum::<usize>() as f64 / n).round() as usize,
    })
}

/// Every candidate's bound in the manifest's lab, over the sweeps of
/// [`DESIGN_SEEDS`] (the first rendered dataset's sweep settings), best first;
/// layouts that do not fit come last.
pub fn design(manifest: &Manifest, spec: &RenderSpec) -> Result<Vec<DesignRow>, BoundError> {
    let rig = RigBoards::from_rig(&manifest.rig).map_err(|e| BoundError::Scene(e.to_string()))?;
    let (_, world_T_phantom) = lab_layout(spec.board_distance_mm, &rig.phantom);
    let layouts = candidates();
    let mut rows: Vec<DesignRow> = crate::core::parallel::parallel_map(layouts.len(), |i| {
        let layout = layouts[i];
        let phantom = layout.phantom(&world_T_phantom);
        let bound = bound_over_sweeps(manifest, &phantom, spec, DESIGN_SEEDS);
        DesignRow { layout, phantom, bound }
    });
    rows.sort_by(|a, b| match (&a.bound, &b.bound) {
        (Ok(x), Ok(y)) => x.rms_mm.total_cmp(&y.rms_mm),
        (Ok(_), Err(_)) => std::cmp::Ordering::Less,
        (Err(_), Ok(_)) => std::cmp::Ordering::Greater,
        (Err(_), Err(_)) => std::cmp::Ordering::Equal,
    });
    Ok(rows)
}

/// A design study: the ranked layouts with the manifest's own phantom and the
/// thesis's hemisphere beside them (`design.json`).
#[derive(Debug, Clone, Serialize)]
pub struct DesignStudy {
    pub experiment: String,
    pub seeds: [u64; 2],
    pub frames: usize,
    pub noise: BoundNoise,
    /// The intrinsics also solved from the boards in the frames' photos.
    pub camera_refined_with_frames: bool,
    /// The terms of the echo edge's offset solved with the calibration
    /// (nuisances of the bound; absent: none).
    #[serde(skip_serializing_if = "is_no_offset")]
    pub edge_offset: EdgeOffset,
    /// The growth of the edge noise with the cut (absent: every arc alike).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub slice_blur: Option<SliceBlur>,
    /// The manifest's own phantom.
    #[serde(serialize_with = "bound_or_reason")]
    pub manifest_phantom: Result<Bound, BoundError>,
    /// The thesis's hemisphere (R = 15 mm) at the lab's feature point.
    #[serde(serialize_with = "bound_or_reason")]
    pub hemisphere: Result<Bound, BoundError>,
    pub layouts: Vec<DesignRow>,
}

fn is_no_offset(o: &EdgeOffset) -> bool {
    *o == EdgeOffset::None
}

/// The study of the ranked `rows`: the manifest's own phantom and the thesis's
/// hemisphere beside them.
pub fn study(manifest: &Manifest, spec: &RenderSpec, rows: &[DesignRow]) -> DesignStudy {
    let hemisphere = match crate::detect::board_pose::RigBoards::from_rig(&manifest.rig) {
        Ok(rig) => {
            let (_, world_T_phantom) = crate::synth::scene::lab_layout(spec.board_distance_mm, &rig.phantom);
            let c = world_T_phantom.inverse() * nalgebra::Point3::origin();
            bound_over_sweeps(
                manifest,
                &Phantom::Hemisphere {
                    centre_in_phantom_mm: [c.x, c.y, c.z],
                    radius_mm: 15.0,
                },
                spec,
                DESIGN_SEEDS,
            )
        }
        Err(e) => Err(BoundError::Scene(e.to_string())),
    };
    DesignStudy {
        experiment: manifest.experiment.clone(),
        seeds: [DESIGN_SEEDS.start, DESIGN_SEEDS.end - 1],
        frames: spec.frames,
        noise: noise(manifest),
        camera_refined_with_frames: refines_with_frames(manifest),
        edge_offset: edge_offset_model(manifest),
        slice_blur: slice_blur_model(manifest),
        manifest_phantom: bound_over_sweeps(manifest, &manifest.phantom, spec, DESIGN_SEEDS),
        hemisphere,
        layouts: rows.to_vec(),
    }
}
