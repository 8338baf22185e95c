//! The manifest exactly as written in YAML. Unknown keys are refused.
//! Defaults are the ones the default experiments are built around; each says why.

use serde::{Deserialize, Serialize};

use super::CutoffRule;

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawManifest {
    /// Names the experiment and its run folder.
    pub experiment: String,
    #[serde(default)]
    pub description: String,
    #[serde(with = "serde_yaml::with::singleton_map")]
    pub phantom: Phantom,
    #[serde(with = "serde_yaml::with::singleton_map")]
    pub rig: Rig,
    /// The camera that photographs both boards; absent when `poses` come from a tracker.
    #[serde(default)]
    pub camera: Option<RawCamera>,
    /// Poses from a tracker instead of the camera stage.
    #[serde(default)]
    pub poses: Option<RawPoses>,
    pub bscan: RawBscan,
    #[serde(default)]
    pub thresholds: RawThresholds,
    #[serde(default)]
    pub solve: Solve,
    pub datasets: Vec<RawDataset>,
}

/// How `marker_T_image` is solved.
#[derive(Debug, Clone, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct Solve {
    /// `rigid` trusts the B-scan pixel spacing; `similarity` also estimates an
    /// isotropic scale on it (Horn's variant with scale, the thesis's eq. 4).
    pub variant: SolveVariant,
    /// A rough `marker_T_image` (e.g. from the probe clip's drawing) that starts the
    /// wire fit: dots are matched to the wires it predicts, then refined. Needed by
    /// the 4-wire phantom; a few millimetres and degrees off is enough.
    pub initial_marker_T_image: Option<TrueTransform>,
    /// RANSAC / LMedS over frames, reported beside the thesis's cut-offs.
    pub robust: crate::estimate::robust::RobustSettings,
    /// The hemisphere's arc edge points fitted to the sphere (no elevation bias).
    pub sphere_fit: SphereFitOptions,
    /// Bootstrap resamples and CR half-splits of the validation metrics.
    pub validation: ValidationOptions,
}

#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct SphereFitOptions {
    /// Prior spread of the plane's distance from the sphere centre (mm); absent: none.
    pub elevation_prior_sd_mm: Option<f64>,
    /// Estimate a constant offset of the echo edge from the sphere surface.
    pub fit_radius_offset: bool,
}

impl Default for SphereFitOptions {
    fn default() -> Self {
        // A careful sweep keeps the plane within about a millimetre of the centre.
        SphereFitOptions {
            elevation_prior_sd_mm: Some(1.0),
            fit_radius_offset: true,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct ValidationOptions {
    pub bootstrap_resamples: usize,
    pub cr_half_splits: usize,
    pub seed: u64,
}

impl Default for ValidationOptions {
    fn default() -> Self {
        ValidationOptions {
            bootstrap_resamples: 200,
            cr_half_splits: 10,
            seed: 7,
        }
    }
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SolveVariant {
    #[default]
    Rigid,
    Similarity,
}

/// The phantom and its features, in the phantom frame P (the phantom board's frame), mm.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Phantom {
    /// A hemisphere on a pillar, dome towards the probe; the feature is the sphere centre.
    Hemisphere {
        centre_in_phantom_mm: [f64; 3],
        radius_mm: f64,
    },
    /// A pin head in a silicone block; the feature is the head's centre.
    Point {
        position_in_phantom_mm: [f64; 3],
        /// The head's radius: its echo comes from the surface facing the probe, one
        /// radius before the centre along the beam.
        #[serde(default = "default_head_radius")]
        head_radius_mm: f64,
    },
    /// Two crossing and two parallel wires: each B-scan dot lies on its wire's
    /// axis; where the plane passes a crossing, on the crossing point.
    FourWire { wires: Vec<Wire>, wire_diameter_mm: f64 },
}

fn default_head_radius() -> f64 {
    1.0
}

#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Wire {
    pub name: String,
    pub start_in_phantom_mm: [f64; 3],
    pub end_in_phantom_mm: [f64; 3],
}

/// The marker rig that gives the poses of the probe marker M and the phantom P in the camera C.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Rig {
    Checkerboard {
        probe_board: Board,
        phantom_board: Board,
    },
    /// ArUco grid boards; the two boards are told apart by their marker ids.
    Aruco {
        /// OpenCV's predefined dictionary name, e.g. `DICT_4X4_50`.
        dictionary: String,
        probe_board: ArucoBoard,
        phantom_board: ArucoBoard,
        /// Sub-pixel corner refinement window (half size, px); 0 turns it off. It
        /// must stay below a marker cell's size in the image.
        #[serde(default = "default_aruco_window")]
        subpixel_half_window_px: u32,
        /// Fewest markers of a board for a pose.
        #[serde(default = "default_min_markers")]
        min_markers: usize,
    },
}

fn default_aruco_window() -> u32 {
    3
}
fn default_min_markers() -> usize {
    4
}

/// A grid board of ArUco markers with consecutive ids from `first_id`, row by row.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ArucoBoard {
    /// Markers `[columns, rows]`.
    pub markers: [u32; 2],
    pub marker_mm: f64,
    pub separation_mm: f64,
    pub first_id: u32,
}

/// A printed checkerboard with a white margin one square wide. Its identification
/// dots sit in the margin beside the origin corner: the first dot fixes which inner
/// corner is the origin (the same in every frame), the number of dots tells the
/// probe's board from the phantom's.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Board {
    /// Inner corners `[columns, rows]` (OpenCV's pattern size): 11x11 squares have 10x10.
    pub inner_corners: [u32; 2],
    pub square_mm: f64,
    /// 1 or 2 dots; the probe's and the phantom's board must differ.
    pub id_dots: u8,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawCamera {
    /// OpenCV FileStorage file with `camera_matrix` and `distortion_coefficients`.
    pub intrinsics_file: Option<String>,
    pub calibrate: Option<CameraCalibrationBoard>,
}

/// Where the poses come from when not from the camera.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawPoses {
    pub tracker_csv: TrackerCsv,
}

/// A plain CSV of 4x4 matrices per frame (see [`crate::io::tracker_poses`]).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct TrackerCsv {
    /// File name inside each dataset folder (rendered datasets write `tracker_poses.csv`).
    pub file: String,
    /// `tracker_T_marker`: the probe's marker.
    #[serde(default = "default_probe_transform")]
    pub probe_transform: String,
    /// `tracker_T_phantom`: the phantom's reference marker, the frame of the phantom geometry.
    #[serde(default = "default_reference_transform")]
    pub reference_transform: String,
}

fn default_probe_transform() -> String {
    "ProbeToTracker".into()
}
fn default_reference_transform() -> String {
    "ReferenceToTracker".into()
}

/// Camera calibration from views of a plain checkerboard.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct CameraCalibrationBoard {
    /// Folder of board images; absent: the dataset's own `camera_calibration/` folder.
    #[serde(default)]
    pub images: Option<String>,
    pub inner_corners: [u32; 2],
    pub square_mm: f64,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawBscan {
    /// Millimetres per pixel along u (columns) and v (rows).
    pub spacing_mm_per_px: [f64; 2],
    #[serde(default)]
    pub arc_detection: ArcDetection,
}

/// Settings of the hemisphere arc detector.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct ArcDetection {
    /// Arc radii searched, as fractions of the sphere radius: a plane at distance d
    /// from the centre cuts a circle of radius sqrt(R^2 - d^2), so the low end sets
    /// how far off-centre a plane may pass.
    pub radius_fraction: [f64; 2],
    /// Smallest angular span of the inlier arc; shorter arcs give unstable centres.
    pub min_span_deg: f64,
    /// Largest RMS distance of the inlier echoes to the fitted circle.
    pub max_rms_px: f64,
    /// Fewest inlier echo points.
    pub min_points: usize,
    /// Fit the arc with the sphere's radius (`known`) or with a free radius (`free`).
    /// A free radius lets the centre of a short arc slide along the arc's axis.
    pub fit_radius: FitRadius,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FitRadius {
    Known,
    Free,
}

impl Default for ArcDetection {
    fn default() -> Self {
        // 0.55 R admits planes up to 0.83 R off-centre; 1.15 R allows for the
        // widening of the echo by the beam's slice thickness.
        ArcDetection {
            radius_fraction: [0.55, 1.15],
            min_span_deg: 40.0,
            max_rms_px: 2.5,
            min_points: 25,
            fit_radius: FitRadius::Known,
        }
    }
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawThresholds {
    /// The thesis's BRE cut-offs: all frames, then < 2, 1.5, 1 mm.
    #[serde(default = "default_cutoffs")]
    pub bre_cutoffs_mm: Vec<f64>,
    #[serde(default = "default_rule")]
    pub cutoff_rule: CutoffRule,
    /// Which cut-off's calibration is the result (default: all frames).
    #[serde(default)]
    pub calibration_cutoff_mm: Option<f64>,
    #[serde(default = "default_min_frames")]
    pub min_frames: usize,
    #[serde(default)]
    pub gates: Gates,
    #[serde(default)]
    pub regression: Regression,
}

/// How much a metric may grow over its baseline before `probecal check` calls it a
/// regression (written into the baseline by `probecal check --update`).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct Regression {
    pub bre_mean_mm: f64,
    pub truth_corner_error_mm: f64,
    pub truth_rotation_error_deg: f64,
    pub frames_rejected: f64,
    pub pre3d_mm: f64,
}

impl Default for Regression {
    fn default() -> Self {
        // Well above the run-to-run spread of a fixed seed (zero: runs are
        // deterministic) and of platform floating-point differences, well below what
        // a worse detector or a broken stage does.
        Regression {
            bre_mean_mm: 0.05,
            truth_corner_error_mm: 0.05,
            truth_rotation_error_deg: 0.05,
            frames_rejected: 2.0,
            pre3d_mm: 0.02,
        }
    }
}

fn default_cutoffs() -> Vec<f64> {
    vec![f64::INFINITY, 2.0, 1.5, 1.0]
}
fn default_rule() -> CutoffRule {
    CutoffRule::MaxAxis
}
fn default_min_frames() -> usize {
    3
}

impl Default for RawThresholds {
    fn default() -> Self {
        RawThresholds {
            bre_cutoffs_mm: default_cutoffs(),
            cutoff_rule: default_rule(),
            calibration_cutoff_mm: None,
            min_frames: default_min_frames(),
            gates: Gates::default(),
            regression: Regression::default(),
        }
    }
}

/// Accuracy gates: a run that misses one reports it and exits non-zero.
#[derive(Debug, Clone, PartialEq, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Gates {
    /// Mean distance of the image corners and centre mapped by estimate vs truth (rendered data).
    pub truth_corner_error_mm: Option<f64>,
    /// Rotation between estimated and true marker_T_image (rendered data).
    pub truth_rotation_error_deg: Option<f64>,
    /// Mean BRE along any axis, at the calibration cut-off.
    pub bre_mean_mm: Option<f64>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawDataset {
    pub name: String,
    pub render: Option<RenderSpec>,
    pub folder: Option<String>,
}

/// How to render a dataset. Every default describes the simulated lab of the
/// default experiments (a Dataset-3-like setup of the thesis).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct RenderSpec {
    pub seed: u64,
    #[serde(default = "default_frames")]
    pub frames: usize,
    #[serde(default = "default_calibration_views")]
    pub calibration_views: usize,
    #[serde(default)]
    pub camera: TrueCamera,
    /// Camera-to-board distances the scene is laid out for.
    #[serde(default = "default_distance")]
    pub board_distance_mm: [f64; 2],
    #[serde(default)]
    pub sweep: Sweep,
    /// Fraction of photos with something (a finger, a cable) across the probe board.
    #[serde(default = "default_occlusion")]
    pub occlusion_rate: f64,
    #[serde(default)]
    pub bscan: BscanRender,
    /// The true calibration; absent: the probe casing's nominal mount for the board size.
    #[serde(default)]
    pub marker_T_image: Option<TrueTransform>,
    /// The simulated tracker whose poses are written to `tracker_poses.csv`.
    #[serde(default)]
    pub tracker: TrackerNoise,
}

/// Noise of the simulated optical tracker, per marker pose and frame (Gaussian).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrackerNoise {
    /// SD of each translation component, mm.
    pub position_sd_mm: f64,
    /// SD of the rotation about each axis, degrees.
    pub rotation_sd_deg: f64,
}

impl Default for TrackerNoise {
    fn default() -> Self {
        // An optical tracker's marker pose: ~0.25 mm RMS over the three axes, and the
        // rotation jitter of a ~60 mm marker.
        TrackerNoise {
            position_sd_mm: 0.15,
            rotation_sd_deg: 0.1,
        }
    }
}

fn default_occlusion() -> f64 {
    0.08
}
fn default_frames() -> usize {
    50
}
fn default_calibration_views() -> usize {
    16
}
fn default_distance() -> [f64; 2] {
    [350.0, 600.0]
}

/// The simulated camera (ground truth; the pipeline calibrates it from pixels).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrueCamera {
    pub image_size_px: [u32; 2],
    pub focal_px: f64,
    /// Offset of the principal point from the image centre, px.
    pub principal_offset_px: [f64; 2],
    /// OpenCV order: k1, k2, p1, p2, k3.
    pub distortion: [f64; 5],
    pub noise_grey_levels: f64,
    pub blur_sigma_px: f64,
    /// Strength of the uneven lighting (0: flat).
    pub lighting_gradient: f64,
}

impl Default for TrueCamera {
    fn default() -> Self {
        // A 1080p machine-vision camera with a ~8 mm lens: f ≈ 1400 px, mild barrel distortion.
        TrueCamera {
            image_size_px: [1920, 1080],
            focal_px: 1400.0,
            principal_offset_px: [6.5, -4.0],
            distortion: [-0.12, 0.05, 0.0, 0.0, 0.0],
            noise_grey_levels: 3.0,
            blur_sigma_px: 0.8,
            lighting_gradient: 0.35,
        }
    }
}

/// The freehand sweep: tilts about the image's X (lateral) and Y (beam) axes,
/// a small rotation about Z, and where the plane cuts the sphere.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct Sweep {
    pub tilt_x_deg: f64,
    pub tilt_y_deg: f64,
    pub rotation_z_deg: f64,
    /// Spread of the distance between the B-scan plane and the sphere centre.
    pub elevation_offset_sd_mm: f64,
    /// Hand motion between the photo and the B-scan.
    pub tremor_mm: f64,
    pub tremor_deg: f64,
    /// Wire phantoms: how far along the wires (either way from their middle) the plane travels.
    pub wire_travel_mm: f64,
}

impl Default for Sweep {
    fn default() -> Self {
        Sweep {
            tilt_x_deg: 15.0,
            tilt_y_deg: 15.0,
            rotation_z_deg: 8.0,
            elevation_offset_sd_mm: 0.5,
            tremor_mm: 0.1,
            tremor_deg: 0.03,
            wire_travel_mm: 12.0,
        }
    }
}

/// The simulated convex probe and the phantom's echoes.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct BscanRender {
    pub depth_mm: f64,
    pub fan_deg: f64,
    pub convex_radius_mm: f64,
    /// Elevation (out-of-plane) thickness of the beam.
    pub slice_thickness_mm: f64,
    /// Fraction of frames that are misleading (plane far off-centre, bubbles on
    /// the dome, a jerk between photo and B-scan).
    pub outlier_rate: f64,
    /// Fraction of frames where the plane misses the hemisphere.
    pub missing_rate: f64,
    /// Chance of air bubbles in a frame.
    pub bubble_rate: f64,
}

impl Default for BscanRender {
    fn default() -> Self {
        // A curved abdominal probe (like the thesis's XC6-1): 60° fan, 40 mm radius, 120 mm depth.
        BscanRender {
            depth_mm: 120.0,
            fan_deg: 60.0,
            convex_radius_mm: 40.0,
            slice_thickness_mm: 1.5,
            outlier_rate: 0.1,
            missing_rate: 0.04,
            bubble_rate: 0.3,
        }
    }
}

/// A rigid transform given as ZYX Euler angles (deg) and a translation (mm).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct TrueTransform {
    /// `[roll_x, pitch_y, yaw_z]`, `R = Rz Ry Rx`.
    pub rotation_deg: [f64; 3],
    pub translation_mm: [f64; 3],
}
