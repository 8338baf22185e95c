//! A tracked N-wire sweep rendered with a known tracker lag: B-scans of an
//! N-wire phantom as the probe moves over it, the tracker's poses recorded late
//! by a stated lag, written as a PLUS sequence file that the tracked pipeline
//! reads as it reads a real recording (its wire dots segmented from the pixels).
//!
//! What is rendered, each at a stated value:
//! - **The wires' echoes**: each wire's crossing of the image plane (the truth
//!   `ImageToProbe` and the probe's pose at the image's time) as a Gaussian spot
//!   of FWHM 0.5 mm along the beam and 1.0 mm across it, peak 200 grey levels
//!   (typical of a 7–10 MHz linear array imaging a monofilament wire in water;
//!   not measured on one scanner).
//! - **Speckle**: Rayleigh-distributed background of mean 12 grey levels (a water
//!   bath images dark), independent per pixel.
//! - **The tracker**: each frame's recorded probe pose is the probe's pose
//!   `tracker_lag_s` before the image's time (a tracker that lags the images),
//!   its position with Gaussian noise of 0.25 mm RMS in 3D (an optical tracker's
//!   stated accuracy, NDI Polaris Vicra: 0.25 mm RMS); the reference marker is
//!   still and recorded without noise.
//! - **The clock**: frames at exactly `1 / frames_per_s` apart.
//!
//! Left out: reverberation and side lobes, the beam's thickness across the image
//! plane, the speed of sound, timestamp jitter and dropped frames, rotational
//! tracker noise.
//!
//! The motion: the probe's pose at rest (`reference_T_probe`, e.g. a frame of a
//! real recording) moved along the wires, across them and tilted about the
//! wires' direction through the image's centre, each a sinusoid of the sweep's
//! period with its own phase.

use std::collections::BTreeMap;
use std::path::Path;

use nalgebra::{Matrix3, Matrix4, Point3, Unit, UnitQuaternion, Vector3};

use crate::core::geometry::Rigid;
use crate::core::rng::Rng;
use crate::io::plus::sequence::Sequence;
use crate::spec::nwire::NWire;

/// How the probe moves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SweepMotion {
    /// One back-and-forth, s.
    pub period_s: f64,
    /// Amplitudes: along the wires and across them (mm), tilt about the wires (deg).
    pub along_mm: f64,
    pub across_mm: f64,
    pub tilt_deg: f64,
}

/// One rendered sweep.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SweepSpec {
    pub frames_per_s: f64,
    pub duration_s: f64,
    /// How late the tracker records a pose, s.
    pub tracker_lag_s: f64,
    pub motion: SweepMotion,
    /// The probe marker's position noise, mm RMS in 3D ([`TRACKER_NOISE_RMS_MM`]
    /// for an optical tracker).
    pub tracker_noise_rms_mm: f64,
    pub seed: u64,
}

/// The phantom, the truth and the probe at rest.
#[derive(Debug, Clone)]
pub struct SweepScene<'a> {
    pub nwires: &'a [NWire],
    pub reference_T_phantom: Matrix4<f64>,
    /// The truth: pixel `(u, v, 0, 1)` to probe mm.
    pub image_to_probe: Matrix4<f64>,
    pub reference_T_probe: Rigid,
    pub tracker_T_reference: Rigid,
    pub width: usize,
    pub height: usize,
    /// Pixels every wire's spot must stay within: `[x0, y0, x1, y1]`.
    pub keep_within_px: [f64; 4],
}

/// The spot's FWHM along the beam and across it, mm; its peak, grey levels.
const AXIAL_FWHM_MM: f64 = 0.5;
const LATERAL_FWHM_MM: f64 = 1.0;
const PEAK: f64 = 200.0;
/// Mean of the Rayleigh speckle, grey levels.
const SPECKLE_MEAN: f64 = 12.0;
/// An optical tracker's position noise, mm RMS in 3D (NDI Polaris Vicra: 0.25 mm RMS).
pub const TRACKER_NOISE_RMS_MM: f64 = 0.25;

#[derive(Debug, thiserror::Error)]
pub enum SweepError {
    #[error("frame {frame}: a wire's spot at ({u:.0}, {v:.0}) px leaves the image's kept area: the motion is too wide for this probe pose")]
    OutOfView { frame: usize, u: f64, v: f64 },
    #[error("frame {frame}: a wire runs in the image plane")]
    Parallel { frame: usize },
    #[error("{path}: {message}")]
    Write { path: String, message: String },
}

/// The probe's true pose at time `t` (s from the sweep's start).
pub fn reference_T_probe_at(scene: &SweepScene<'_>, motion: &SweepMotion, t: f64) -> Rigid {
    let w = std::f64::consts::TAU / motion.period_s;
    let phantom_rotation = scene.reference_T_phantom.fixed_view::<3, 3>(0, 0).into_owned();
    // The wires' direction and the across-wire direction in the image plane, reference frame.
    let along = (phantom_rotation * scene.nwires[0].wires[0].direction()).normalize();
    let image_to_reference = scene.reference_T_probe.to_homogeneous() * scene.image_to_probe;
    let lateral = image_to_reference.fixed_view::<3, 1>(0, 0).into_owned();
    let across = (lateral - along * lateral.dot(&along)).normalize();
    let centre_px = Point3::new(scene.width as f64 / 2.0, scene.height as f64 / 2.0, 0.0);
    let centre = image_to_reference.transform_point(&centre_px);
    let shift = along * motion.along_mm * (w * t).sin() + across * motion.across_mm * (w * t + 1.1).sin();
    let tilt = UnitQuaternion::from_axis_angle(
        &Unit::new_normalize(along),
        motion.tilt_deg.to_radians() * (w * t + 2.3).sin(),
    );
    let about_centre = Rigid::from_parts((centre.coords - tilt * centre.coords + shift).into(), tilt);
    about_centre * scene.reference_T_probe
}

/// Where each wire crosses the image plane of `image_to_reference`, px.
fn crossings(
    scene: &SweepScene<'_>,
    image_to_reference: &Matrix4<f64>,
    frame: usize,
) -> Result<Vec<[f64; 2]>, SweepError> {
    let origin = image_to_reference.fixed_view::<3, 1>(0, 3).into_owned();
    let a_u = image_to_reference.fixed_view::<3, 1>(0, 0).into_owned();
    let a_v = image_to_reference.fixed_view::<3, 1>(0, 1).into_owned();
    let mut out = Vec::new();
    for wire in scene.nwires.iter().flat_map(|n| n.wires.iter()) {
        let point = scene.reference_T_phantom.transform_point(&wire.front_in_phantom_mm);
        let direction = scene.reference_T_phantom.transform_vector(&wire.direction());
        let x = Matrix3::from_columns(&[a_u, a_v, -direction])
            .lu()
            .solve(&(point.coords - origin))
            .ok_or(SweepError::Parallel { frame })?;
        let [x0, y0, x1, y1] = scene.keep_within_px;
        if !(x[0] >= x0 && x[0] <= x1 && x[1] >= y0 && x[1] <= y1) {
            return Err(SweepError::OutOfView {
                frame,
                u: x[0],
                v: x[1],
            });
        }
        out.push([x[0], x[1]]);
    }
    Ok(out)
}

/// One B-scan: speckle and the wires' spots at `spots` (px), spot sizes from
/// the pixel sizes of `image_to_probe`.
fn render_frame(scene: &SweepScene<'_>, spots: &[[f64; 2]], rng: &mut Rng) -> Vec<u8> {
    let (w, h) = (scene.width, scene.height);
    let spacing_u = scene.image_to_probe.fixed_view::<3, 1>(0, 0).norm();
    let spacing_v = scene.image_to_probe.fixed_view::<3, 1>(0, 1).norm();
    let sigma = |fwhm_mm: f64, spacing: f64| fwhm_mm / (8.0 * 2f64.ln()).sqrt() / spacing;
    let (su, sv) = (sigma(LATERAL_FWHM_MM, spacing_u), sigma(AXIAL_FWHM_MM, spacing_v));
    let rayleigh_sigma = SPECKLE_MEAN / (std::f64::consts::PI / 2.0).sqrt();
    let mut image: Vec<f64> = (0..w * h)
        .map(|_| rayleigh_sigma * (-2.0 * (1.0 - rng.unit()).ln()).sqrt())
        .collect();
    for [cu, cv] in spots {
        let (u0, u1) = (
            (cu - 4.0 * su).floor().max(0.0) as usize,
            ((cu + 4.0 * su).ceil() as usize).min(w - 1),
        );
        let (v0, v1) = (
            (cv - 4.0 * sv).floor().max(0.0) as usize,
            ((cv + 4.0 * sv).ceil() as usize).min(h - 1),
        );
        for v in v0..=v1 {
            for u in u0..=u1 {
                let d = ((u as f64 - cu) / su).powi(2) + ((v as f64 - cv) / sv).powi(2);
                image[v * w + u] += PEAK * (-0.5 * d).exp();
            }
        }
    }
    image.iter().map(|x| x.round().clamp(0.0, 255.0) as u8).collect()
}

fn matrix_text(m: &Matrix4<f64>) -> String {
    (0..16)
        .map(|i| format!("{}", m[(i / 4, i % 4)]))
        .collect::<Vec<_>>()
        .join(" ")
}

/// Renders the sweep and writes it to `path` as a PLUS sequence file with
/// `ProbeToTracker` and `ReferenceToTracker` per frame.
pub fn render(scene: &SweepScene<'_>, spec: &SweepSpec, path: &Path) -> Result<(), SweepError> {
    let frames = (spec.duration_s * spec.frames_per_s).round() as usize;
    let mut sequence = Sequence::empty(path, scene.width, scene.height);
    let mut rng = Rng::new(spec.seed);
    let noise_sd = spec.tracker_noise_rms_mm / 3f64.sqrt();
    let start_s = 1000.0;
    for frame in 0..frames {
        let t = frame as f64 / spec.frames_per_s;
        let truth = reference_T_probe_at(scene, &spec.motion, t);
        let spots = crossings(scene, &(truth.to_homogeneous() * scene.image_to_probe), frame)?;
        let pixels = render_frame(scene, &spots, &mut rng);
        // The tracker records the pose the probe had `lag` before the image.
        let mut recorded = reference_T_probe_at(scene, &spec.motion, t - spec.tracker_lag_s);
        recorded.translation.vector += Vector3::new(
            rng.normal(0.0, noise_sd),
            rng.normal(0.0, noise_sd),
            rng.normal(0.0, noise_sd),
        );
        let tracker_T_probe = scene.tracker_T_reference * recorded;
        let fields = BTreeMap::from([
            ("Timestamp".to_string(), format!("{:.6}", start_s + t)),
            ("ImageStatus".to_string(), "OK".to_string()),
            (
                "ProbeToTrackerTransform".to_string(),
                matrix_text(&tracker_T_probe.to_homogeneous()),
            ),
            ("ProbeToTrackerTransformStatus".to_string(), "OK".to_string()),
            (
                "ReferenceToTrackerTransform".to_string(),
                matrix_text(&scene.tracker_T_reference.to_homogeneous()),
            ),
            ("ReferenceToTrackerTransformStatus".to_string(), "OK".to_string()),
        ]);
        sequence.push_frame(fields, &pixels).map_err(|e| SweepError::Write {
            path: path.display().to_string(),
            message: e.to_string(),
        })?;
    }
    crate::io::fs::write_atomic(path, &sequence.to_file_bytes()).map_err(|e| SweepError::Write {
        path: path.display().to_string(),
        message: e.to_string(),
    })
}
