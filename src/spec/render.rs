//! The simulated lab a dataset is rendered in: camera, sweep, probe, tracker,
//! true calibration.

use serde::{Deserialize, Serialize};

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
    /// Named occluders of a handheld session (the hand, the probe cable, the
    /// tank rim), each at its stated rate; absent: none beyond `occlusion_rate`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub occluders: Option<SessionOccluders>,
    #[serde(default)]
    pub bscan: BscanRender,
    /// The true calibration; absent: the probe casing's nominal mount for the board size.
    #[serde(default)]
    pub marker_T_image: Option<TrueTransform>,
    /// The simulated tracker whose poses are written to `tracker_poses.csv`.
    #[serde(default)]
    pub tracker: TrackerNoise,
    /// Error sources of a real rig (absent: the ideal lab).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub realism: Option<super::realism::Realism>,
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

/// How often each occluder of a handheld session lies over a board in a photo
/// (fractions of photos, drawn independently per photo and occluder). The
/// shapes are stated in `synth::occluders`.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SessionOccluders {
    /// Two fingers of the hand holding the probe over the probe board's lower edge.
    pub hand_rate: f64,
    /// The probe's cable across the probe board.
    pub cable_rate: f64,
    /// The tank's rim over the phantom board's lower rows.
    pub rim_rate: f64,
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

/// The file every rendered dataset writes its simulated tracker's poses to.
pub const RENDERED_TRACKER_POSES: &str = "tracker_poses.csv";
