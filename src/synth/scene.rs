//! The simulated lab: where the camera, the boards, the tank and the probe are.
//!
//! World frame W (used only here and in the renderers): origin at the phantom's
//! feature (sphere centre, pin head, centre of the wires), z up (towards the probe), x to the camera's right. The phantom board is
//! fixed beside the tank facing the camera; the probe board is on the probe casing,
//! parallel to the B-scan plane. The probe sweeps over the phantom with tilts
//! about the image's X (lateral) and Y (beam) axes and a small rotation about Z.

pub use super::bscan_geometry::BscanGeometry;
use super::shape::Shape;
use nalgebra::{Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};

use crate::core::geometry::Rigid;
use crate::core::rng::Rng;
use crate::detect::board::{BoardLayout, PrintedBoard};
use crate::io::camera_model::CameraIntrinsics;
use crate::spec::render::{RenderSpec, TrueTransform};

/// Why a frame is what it is (ground truth only).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FrameKind {
    /// Plane close to the sphere centre, photo and B-scan nearly simultaneous.
    Normal,
    /// Plane far from the centre: the arc is real but its centre is not the sphere's.
    OffCentre,
    /// The probe moved between the photo and the B-scan.
    Jerk,
    /// Air bubbles stuck on the phantom add bright echoes beside the feature.
    DomeBubbles,
    /// The plane misses the feature.
    Missing,
}

/// Tank walls and floor, world frame (mm).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Tank {
    pub floor_z_mm: f64,
    pub wall_x_mm: f64,
    pub wall_y_mm: f64,
}

/// One rendered frame's true geometry.
#[derive(Debug, Clone)]
pub struct FramePlan {
    pub kind: FrameKind,
    /// Probe marker pose when the photo was taken.
    pub world_T_marker_photo: Rigid,
    /// Probe marker pose when the B-scan was taken.
    pub world_T_marker_bscan: Rigid,
    /// Signed distance from the B-scan plane to the feature's centre, mm.
    pub elevation_offset_mm: f64,
    /// Pixel of the feature centre's projection onto the B-scan plane.
    pub centre_projection_px: [f64; 2],
    /// Something (a finger, a cable) across the probe board in the photo.
    pub occluder: Option<Occluder>,
}

/// A dark capsule lying on the probe board, relative to the board's centre (mm).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Occluder {
    pub from_centre_mm: [f64; 2],
    pub to_centre_mm: [f64; 2],
    pub width_mm: f64,
}

impl Occluder {
    /// Whether a board point (relative to the board's centre) is covered.
    pub fn covers(&self, x: f64, y: f64) -> bool {
        let [ax, ay] = self.from_centre_mm;
        let [bx, by] = self.to_centre_mm;
        let (dx, dy) = (bx - ax, by - ay);
        let t = (((x - ax) * dx + (y - ay) * dy) / (dx * dx + dy * dy).max(1e-12)).clamp(0.0, 1.0);
        let (px, py) = (ax + t * dx - x, ay + t * dy - y);
        px * px + py * py <= (self.width_mm / 2.0).powi(2)
    }
}

/// Half the side of the square plate each board is mounted on: the scene is laid
/// out for the plates, so the same seed gives the same motion whatever the boards.
pub const PLATE_HALF_MM: f64 = 90.0;

/// How far below the probe board's centre the transducer face is, mm.
pub const MOUNT_DROP_MM: f64 = 100.0;

pub(super) fn plate_bounds(board: &PrintedBoard) -> [f64; 4] {
    let c = board.centre_mm();
    [
        c.x - PLATE_HALF_MM,
        c.y - PLATE_HALF_MM,
        c.x + PLATE_HALF_MM,
        c.y + PLATE_HALF_MM,
    ]
}

/// The whole simulated setup of one dataset.
#[derive(Debug, Clone)]
pub struct Scene {
    pub camera: CameraIntrinsics,
    pub camera_T_world: Rigid,
    pub world_T_phantom: Rigid,
    pub marker_T_image: Rigid,
    /// The phantom's feature (sphere centre, pin head, centre of the wires), world frame.
    pub feature_centre_world: Point3<f64>,
    pub shape: Shape,
    pub tank: Tank,
    pub probe_board: PrintedBoard,
    pub phantom_board: PrintedBoard,
    pub bscan: BscanGeometry,
    pub frames: Vec<FramePlan>,
    /// Poses of the camera-calibration board, one per view.
    pub calibration_board: BoardLayout,
    pub camera_T_calibration_board: Vec<Rigid>,
}

pub(super) fn rotation_from_columns(x: Vector3<f64>, y: Vector3<f64>, z: Vector3<f64>) -> UnitQuaternion<f64> {
    UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, z])))
}

pub(super) fn euler_deg(rx: f64, ry: f64, rz: f64) -> UnitQuaternion<f64> {
    UnitQuaternion::from_euler_angles(rx.to_radians(), ry.to_radians(), rz.to_radians())
}

/// The true calibration of a transform given in a manifest.
pub fn true_transform(t: &TrueTransform) -> Rigid {
    let [rx, ry, rz] = t.rotation_deg;
    Rigid::from_parts(
        Translation3::from(Vector3::from(t.translation_mm)),
        euler_deg(rx, ry, rz),
    )
}

/// The probe casing's nominal mount: board centred over the array, parallel to the
/// B-scan plane 25 mm in front of it, its centre 100 mm above the array.
pub fn nominal_marker_T_image(board: &PrintedBoard, bscan: &BscanGeometry) -> Rigid {
    let centre = board.centre_mm();
    let x = centre.x - bscan.width_mm() / 2.0;
    let y = centre.y + MOUNT_DROP_MM;
    Rigid::from_parts(Translation3::new(x, y, 25.0), euler_deg(1.5, -2.0, 1.0))
}

/// A small random rigid motion.
pub(super) fn jitter(rng: &mut Rng, sigma_mm: f64, sigma_deg: f64) -> Rigid {
    let axis_angle =
        Vector3::new(rng.normal(0.0, 1.0), rng.normal(0.0, 1.0), rng.normal(0.0, 1.0)) * sigma_deg.to_radians();
    let shift = Vector3::new(rng.normal(0.0, 1.0), rng.normal(0.0, 1.0), rng.normal(0.0, 1.0)) * sigma_mm;
    Rigid::new(shift, axis_angle)
}

/// Pixels bounding a board region `[x0, y0, x1, y1]` (board mm), if it is wholly in
/// view and faces the camera.
pub fn board_in_view(
    camera: &CameraIntrinsics,
    camera_T_board: &Rigid,
    bounds_mm: [f64; 4],
    margin_px: f64,
) -> Option<[f64; 4]> {
    let facing = (camera_T_board.rotation * Vector3::z()).dot(&camera_T_board.translation.vector.normalize());
    if facing < 0.35 {
        return None; // seen at more than ~70° or from behind
    }
    let [x0, y0, x1, y1] = bounds_mm;
    let [w, h] = [camera.image_size_px[0] as f64, camera.image_size_px[1] as f64];
    let mut bbox = [f64::MAX, f64::MAX, f64::MIN, f64::MIN];
    for (x, y) in [(x0, y0), (x1, y0), (x0, y1), (x1, y1)] {
        let p = camera.project(&(camera_T_board * Point3::new(x, y, 0.0)))?;
        if p[0] < margin_px || p[1] < margin_px || p[0] > w - margin_px || p[1] > h - margin_px {
            return None;
        }
        bbox = [
            bbox[0].min(p[0]),
            bbox[1].min(p[1]),
            bbox[2].max(p[0]),
            bbox[3].max(p[1]),
        ];
    }
    Some(bbox)
}

pub(super) fn boxes_apart(a: [f64; 4], b: [f64; 4], gap: f64) -> bool {
    a[2] + gap < b[0] || b[2] + gap < a[0] || a[3] + gap < b[1] || b[3] + gap < a[1]
}

/// Inputs of the scene besides the render spec.
pub struct SceneInputs<'a> {
    pub spec: &'a RenderSpec,
    pub probe_board: PrintedBoard,
    pub phantom_board: PrintedBoard,
    pub calibration_board: BoardLayout,
    pub phantom: &'a crate::spec::phantom::Phantom,
    pub spacing_mm_per_px: [f64; 2],
}

/// Why a scene could not be laid out.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("could not place frame {frame} after {tries} tries (probe board out of view {out_of_view}, phantom board out of view {phantom_out}, boards overlapping {overlapping}, too far or near {distance}, feature outside the fan {fan})")]
    FrameDoesNotFit {
        frame: usize,
        tries: usize,
        out_of_view: usize,
        phantom_out: usize,
        overlapping: usize,
        distance: usize,
        fan: usize,
    },
    #[error("could not place calibration view {view} in the image after {tries} tries")]
    CalibrationViewDoesNotFit { view: usize, tries: usize },
    #[error("the {board} board does not fit on the {plate_mm} mm plate the simulated lab mounts boards on")]
    BoardTooLarge { board: &'static str, plate_mm: f64 },
    #[error("the phantom's {what} is {off_mm:.1} mm from where the simulated lab has it: for this phantom board it is [{}, {}, {}] (phantom frame)", expected[0], expected[1], expected[2])]
    FeatureMisplaced {
        what: &'static str,
        off_mm: f64,
        expected: [f64; 3],
    },
}

/// Where the camera and the phantom board stand in the world frame: the camera in
/// front of the tank and above it, looking down at the scene; the phantom board
/// beside the tank, turned 15° away from facing the camera squarely.
pub fn lab_layout(board_distance_mm: [f64; 2], phantom_board: &PrintedBoard) -> (Rigid, Rigid) {
    let [near, far] = board_distance_mm;
    let target = Vector3::new(-100.0, -40.0, 70.0);
    let view_dir = Vector3::new(0.0, 520.0, -260.0).normalize();
    let camera_position = target - view_dir * ((near + far) / 2.0 + 110.0);
    let z_c = view_dir;
    let x_c = z_c.cross(&Vector3::z()).normalize();
    let y_c = z_c.cross(&x_c);
    let world_T_camera = Rigid::from_parts(
        Translation3::from(camera_position),
        rotation_from_columns(x_c, y_c, z_c),
    );

    let board_centre_world = Vector3::new(-215.0, -80.0, 0.0);
    let to_camera = (camera_position - board_centre_world).normalize();
    let n = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 15f64.to_radians()) * to_camera;
    let z_p = -n;
    let down = -Vector3::z();
    let y_p = (down - z_p * down.dot(&z_p)).normalize();
    let x_p = y_p.cross(&z_p);
    let r_wp = rotation_from_columns(x_p, y_p, z_p);
    let centre = phantom_board.centre_mm();
    let centre_in_board = Vector3::new(centre.x, centre.y, 0.0);
    let world_T_phantom = Rigid::from_parts(Translation3::from(board_centre_world - r_wp * centre_in_board), r_wp);
    (world_T_camera, world_T_phantom)
}

/// Every dome the plane cuts has its whole arc inside the fan, away from its edges.
pub(super) fn domes_inside_fan(
    bscan: &BscanGeometry,
    world_T_image: &Rigid,
    domes_world: &[(Point3<f64>, f64)],
) -> bool {
    let image_T_world = world_T_image.inverse();
    domes_world.iter().all(|(centre, radius)| {
        let p = image_T_world * centre;
        if p.z.abs() >= *radius {
            return true;
        }
        let arc = (radius * radius - p.z * p.z).sqrt();
        let (r, angle) = bscan.polar(p.x, p.y);
        let half_width = (arc / r.max(1.0)).min(1.0).asin();
        angle.abs() + half_width < bscan.half_fan_rad - 4f64.to_radians()
            && r - arc > bscan.convex_radius_mm + 8.0
            && r < bscan.convex_radius_mm + bscan.depth_mm - 8.0
    })
}
