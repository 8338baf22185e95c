//! Where the simulated lab puts things: the camera, the probe's pose for every
//! frame of the sweep (drawn until the boards are in view, apart and at a
//! working distance, and the feature is in the fan) and the calibration
//! board's views, all from the spec's seed.

use nalgebra::{Point3, Translation3, UnitQuaternion, Vector3};

use super::scene::{
    board_in_view, boxes_apart, domes_inside_fan, euler_deg, jitter, lab_layout, nominal_marker_T_image, plate_bounds,
    rotation_from_columns, true_transform, BscanGeometry, FrameKind, FramePlan, Occluder, Scene, SceneError,
    SceneInputs, Tank, PLATE_HALF_MM,
};
use super::shape::{segment_in_plane, Shape};
use crate::core::geometry::Rigid;
use crate::core::rng::Rng;
use crate::detect::board::BoardLayout;
use crate::io::camera_model::CameraIntrinsics;
use crate::spec::render::RenderSpec;

/// Draws the lab of `inputs`: the same spec and seed give the same scene.
pub fn build(inputs: &SceneInputs<'_>) -> Result<Scene, SceneError> {
    let spec = inputs.spec;
    let camera = camera_of(spec);
    let bscan = BscanGeometry::new(
        inputs.spacing_mm_per_px,
        spec.bscan.depth_mm,
        spec.bscan.fan_deg,
        spec.bscan.convex_radius_mm,
    );
    let (world_T_camera, world_T_phantom) = lab_layout(spec.board_distance_mm, &inputs.phantom_board);
    let camera_T_world = world_T_camera.inverse();
    // The lab is laid out around the feature at the world origin; the manifest says
    // where the feature is relative to the phantom board, and must agree.
    let (shape, feature_in_phantom) = Shape::from_phantom(inputs.phantom, &world_T_phantom);
    let feature_centre_world = world_T_phantom * Point3::from(Vector3::from(feature_in_phantom));
    check_feature(&shape, &feature_centre_world, &world_T_phantom)?;
    let tank = Tank {
        floor_z_mm: -30.0,
        wall_x_mm: 75.0,
        wall_y_mm: 60.0,
    };
    for (board, name) in [(&inputs.probe_board, "probe"), (&inputs.phantom_board, "phantom")] {
        let [x0, y0, x1, y1] = board.paper_bounds_mm();
        let [p0, q0, p1, q1] = plate_bounds(board);
        if x0 < p0 || y0 < q0 || x1 > p1 || y1 > q1 {
            return Err(SceneError::BoardTooLarge {
                board: name,
                plate_mm: 2.0 * PLATE_HALF_MM,
            });
        }
    }
    let marker_T_image = match &spec.marker_T_image {
        Some(t) => true_transform(t),
        None => nominal_marker_T_image(&inputs.probe_board, &bscan),
    };
    let camera_T_phantom = camera_T_world * world_T_phantom;
    let sweep = Sweep {
        spec,
        shape: &shape,
        bscan: &bscan,
        camera: &camera,
        camera_T_world,
        image_T_marker: marker_T_image.inverse(),
        phantom_box: board_in_view(&camera, &camera_T_phantom, plate_bounds(&inputs.phantom_board), 12.0),
        probe_plate: plate_bounds(&inputs.probe_board),
        feature_centre_world,
        reach_mm: echo_reach_mm(&shape),
    };
    let mut rng = Rng::fork(spec.seed, 1);
    let mut frames = Vec::with_capacity(spec.frames);
    for frame in 0..spec.frames {
        let kind = if rng.chance(spec.bscan.missing_rate) {
            FrameKind::Missing
        } else if rng.chance(spec.bscan.outlier_rate) {
            [FrameKind::OffCentre, FrameKind::Jerk, FrameKind::DomeBubbles][rng.below(3)]
        } else {
            FrameKind::Normal
        };
        frames.push(sweep.place(frame, kind, &mut rng)?);
    }
    let camera_T_calibration_board = calibration_views(spec, &camera, inputs.calibration_board)?;
    Ok(Scene {
        camera,
        camera_T_world,
        world_T_phantom,
        marker_T_image,
        feature_centre_world,
        shape,
        tank,
        probe_board: inputs.probe_board.clone(),
        phantom_board: inputs.phantom_board.clone(),
        bscan,
        frames,
        calibration_board: inputs.calibration_board,
        camera_T_calibration_board,
    })
}

/// The spec's pinhole camera (principal point at the image centre plus its offset).
fn camera_of(spec: &RenderSpec) -> CameraIntrinsics {
    let cam = &spec.camera;
    let [w, h] = cam.image_size_px;
    CameraIntrinsics {
        image_size_px: [w, h],
        camera_matrix: [
            [cam.focal_px, 0.0, (w as f64 - 1.0) / 2.0 + cam.principal_offset_px[0]],
            [0.0, cam.focal_px, (h as f64 - 1.0) / 2.0 + cam.principal_offset_px[1]],
            [0.0, 0.0, 1.0],
        ],
        distortion: cam.distortion,
        rms_px: None,
        per_view_rms_px: Vec::new(),
    }
}

/// The feature must sit at the world origin (within 3 mm), where the lab is laid out.
fn check_feature(shape: &Shape, feature_centre_world: &Point3<f64>, world_T_phantom: &Rigid) -> Result<(), SceneError> {
    if feature_centre_world.coords.norm() <= 3.0 {
        return Ok(());
    }
    let expected = world_T_phantom.inverse() * Point3::origin();
    Err(SceneError::FeatureMisplaced {
        what: match shape {
            Shape::Hemisphere { .. } => "sphere centre",
            Shape::Point { .. } => "pin head",
            Shape::Wires { .. } => "centre of the wires (mean of their midpoints)",
            Shape::Spheres { .. } => "centre of the spheres (mean of their centres)",
        },
        off_mm: feature_centre_world.coords.norm(),
        expected: [expected.x, expected.y, expected.z].map(|v| (v * 10.0).round() / 10.0),
    })
}

/// How far the feature's echoes reach from its centre in the image, mm.
fn echo_reach_mm(shape: &Shape) -> f64 {
    match shape {
        Shape::Hemisphere { radius_mm } => *radius_mm,
        Shape::Point { head_radius_mm } => head_radius_mm + 6.0,
        Shape::Wires { .. } => 0.0,
        Shape::Spheres { domes_world } => domes_world.iter().map(|(_, r)| *r).fold(0.0, f64::max),
    }
}

/// Why one drawn pose was not taken.
enum Miss {
    Fan,
    OutOfView,
    PhantomOut,
    Overlapping,
    TooFar,
}

/// What every frame's placement shares.
struct Sweep<'a> {
    spec: &'a RenderSpec,
    shape: &'a Shape,
    bscan: &'a BscanGeometry,
    camera: &'a CameraIntrinsics,
    camera_T_world: Rigid,
    image_T_marker: Rigid,
    phantom_box: Option<[f64; 4]>,
    probe_plate: [f64; 4],
    feature_centre_world: Point3<f64>,
    reach_mm: f64,
}

impl Sweep<'_> {
    /// Draws poses for frame `frame` until one fits (at most 400), or says why none did.
    fn place(&self, frame: usize, kind: FrameKind, rng: &mut Rng) -> Result<FramePlan, SceneError> {
        let tries = 400;
        let (mut out_of_view, mut phantom_out, mut overlapping, mut too_far, mut fan) = (0, 0, 0, 0, 0);
        for _ in 0..tries {
            match self.attempt(kind, rng) {
                Ok(plan) => return Ok(plan),
                Err(Miss::Fan) => fan += 1,
                Err(Miss::OutOfView) => out_of_view += 1,
                Err(Miss::PhantomOut) => phantom_out += 1,
                Err(Miss::Overlapping) => overlapping += 1,
                Err(Miss::TooFar) => too_far += 1,
            }
        }
        Err(SceneError::FrameDoesNotFit {
            frame,
            tries,
            out_of_view,
            phantom_out,
            overlapping,
            distance: too_far,
            fan,
        })
    }

    /// One drawn pose of the image plane and the photo's probe pose, checked.
    fn attempt(&self, kind: FrameKind, rng: &mut Rng) -> Result<FramePlan, Miss> {
        let world_T_image = self.image_pose(kind, rng).ok_or(Miss::Fan)?;
        let sweep = &self.spec.sweep;
        let world_T_marker_bscan = world_T_image * self.image_T_marker;
        let (tremor_mm, tremor_deg) = if kind == FrameKind::Jerk {
            (rng.uniform(2.0, 4.0) / 1.7, rng.uniform(1.0, 2.0) / 1.7)
        } else {
            (sweep.tremor_mm, sweep.tremor_deg)
        };
        let world_T_marker_photo = world_T_marker_bscan * jitter(rng, tremor_mm, tremor_deg);
        let camera_T_marker = self.camera_T_world * world_T_marker_photo;
        let probe_box = board_in_view(self.camera, &camera_T_marker, self.probe_plate, 12.0).ok_or(Miss::OutOfView)?;
        let phantom_box = self.phantom_box.ok_or(Miss::PhantomOut)?;
        if !boxes_apart(probe_box, phantom_box, 15.0) {
            return Err(Miss::Overlapping);
        }
        let distance = camera_T_marker.translation.vector.norm();
        let [near, far] = self.spec.board_distance_mm;
        if distance < near || distance > far + 150.0 {
            return Err(Miss::TooFar);
        }
        let occluder = rng.chance(self.spec.occlusion_rate).then(|| {
            let angle = rng.uniform(0.0, std::f64::consts::PI);
            let (cx, cy) = (rng.uniform(-40.0, 40.0), rng.uniform(-40.0, 40.0));
            let half = rng.uniform(35.0, 60.0);
            Occluder {
                from_centre_mm: [cx - half * angle.cos(), cy - half * angle.sin()],
                to_centre_mm: [cx + half * angle.cos(), cy + half * angle.sin()],
                width_mm: rng.uniform(8.0, 14.0),
            }
        });
        // Where the actual feature is relative to this plane (the manifest's centre
        // may sit a fraction of a millimetre from the nominal one).
        let actual = world_T_image.inverse() * self.feature_centre_world;
        Ok(FramePlan {
            kind,
            world_T_marker_photo,
            world_T_marker_bscan,
            elevation_offset_mm: actual.z,
            centre_projection_px: [
                actual.x / self.bscan.spacing_mm_per_px[0],
                actual.y / self.bscan.spacing_mm_per_px[1],
            ],
            occluder,
        })
    }

    /// A drawn pose of the image plane with the feature in the fan, or `None`.
    fn image_pose(&self, kind: FrameKind, rng: &mut Rng) -> Option<Rigid> {
        let bscan = self.bscan;
        let lateral_mm = if matches!(self.shape, Shape::Wires { .. } | Shape::Spheres { .. }) {
            10.0
        } else {
            30.0
        };
        let u_c = bscan.width_mm() / 2.0 + rng.uniform(-lateral_mm, lateral_mm);
        let v_c = rng.uniform(35.0, 90.0);
        let (r_polar, angle) = bscan.polar(u_c, v_c);
        if angle.abs() > bscan.half_fan_rad - 10f64.to_radians()
            || r_polar + self.reach_mm > bscan.convex_radius_mm + bscan.depth_mm
        {
            return None;
        }
        let elevation = self.elevation_mm(kind, rng);
        let rotation = tilted(&self.spec.sweep, rng);
        let centre_in_image = Vector3::new(u_c, v_c, elevation);
        let world_T_image = Rigid::from_parts(
            Translation3::from(Vector3::zeros() - rotation * centre_in_image),
            rotation,
        );
        let missing = kind == FrameKind::Missing;
        match self.shape {
            // Every wire must cross the plane inside the fan, away from its edges.
            Shape::Wires { wires_world, .. } if !missing => wires_world
                .iter()
                .all(|(a, b)| {
                    segment_in_plane(&world_T_image, a, b).is_some_and(|p| {
                        let (r, angle) = bscan.polar(p.x, p.y);
                        angle.abs() < bscan.half_fan_rad - 5f64.to_radians()
                            && r > bscan.convex_radius_mm + 10.0
                            && r < bscan.convex_radius_mm + bscan.depth_mm - 10.0
                    })
                })
                .then_some(world_T_image),
            Shape::Spheres { domes_world } if !missing => {
                domes_inside_fan(bscan, &world_T_image, domes_world).then_some(world_T_image)
            }
            _ => Some(world_T_image),
        }
    }

    /// The plane's distance from the feature's centre for a frame of `kind`, mm.
    fn elevation_mm(&self, kind: FrameKind, rng: &mut Rng) -> f64 {
        let spec = self.spec;
        let sign = if rng.chance(0.5) { 1.0 } else { -1.0 };
        match (self.shape, kind) {
            (Shape::Hemisphere { .. }, FrameKind::OffCentre) => sign * rng.uniform(7.0, 11.0),
            (Shape::Hemisphere { radius_mm }, FrameKind::Missing) => {
                sign * rng.uniform(radius_mm + 1.5, radius_mm + 6.0)
            }
            // Still in the beam's slice, but beside the head.
            (Shape::Point { head_radius_mm }, FrameKind::OffCentre) => {
                sign * rng.uniform(0.6, 1.0) * (head_radius_mm + spec.bscan.slice_thickness_mm / 2.0)
            }
            (Shape::Point { head_radius_mm }, FrameKind::Missing) => {
                sign * rng.uniform(head_radius_mm + 3.0, head_radius_mm + 8.0)
            }
            // Along the wires: anywhere over the middle of the phantom, or past their ends.
            (Shape::Wires { .. }, FrameKind::Missing) => sign * rng.uniform(45.0, 60.0),
            (Shape::Wires { .. }, _) => rng.uniform(-spec.sweep.wire_travel_mm, spec.sweep.wire_travel_mm),
            // Past every dome.
            (Shape::Spheres { domes_world }, FrameKind::Missing) => {
                let reach = domes_world
                    .iter()
                    .map(|(centre, r)| centre.y.abs() + r)
                    .fold(0.0, f64::max);
                sign * rng.uniform(reach + 1.5, reach + 6.0)
            }
            _ => rng.normal(0.0, spec.sweep.elevation_offset_sd_mm),
        }
    }
}

/// The probe's nominal orientation (image X along world X, beam down) tilted
/// about the image's X and Y and turned about its Z by the sweep's drawn angles.
fn tilted(sweep: &crate::spec::render::Sweep, rng: &mut Rng) -> UnitQuaternion<f64> {
    let r_nominal = rotation_from_columns(Vector3::x(), -Vector3::z(), Vector3::y());
    let about = |axis: nalgebra::Unit<Vector3<f64>>, half_range_deg: f64, rng: &mut Rng| {
        UnitQuaternion::from_axis_angle(&axis, rng.uniform(-half_range_deg, half_range_deg).to_radians())
    };
    let x = about(Vector3::x_axis(), sweep.tilt_x_deg, rng);
    let y = about(Vector3::y_axis(), sweep.tilt_y_deg, rng);
    let z = about(Vector3::z_axis(), sweep.rotation_z_deg, rng);
    r_nominal * x * y * z
}

/// Camera-calibration views: a plain board anywhere over the central 70 % of the
/// image, at the lab's working distances, tilted up to 35°.
fn calibration_views(spec: &RenderSpec, camera: &CameraIntrinsics, cb: BoardLayout) -> Result<Vec<Rigid>, SceneError> {
    let mut calib_rng = Rng::fork(spec.seed, 2);
    let [w, h] = spec.camera.image_size_px;
    let [near, far] = spec.board_distance_mm;
    let cb_centre = Vector3::new(
        (cb.inner_corners[0] as f64 - 1.0) * cb.square_mm / 2.0,
        (cb.inner_corners[1] as f64 - 1.0) * cb.square_mm / 2.0,
        0.0,
    );
    let mut views = Vec::new();
    for view in 0..spec.calibration_views {
        let tries = 2000;
        let mut placed = None;
        for _ in 0..tries {
            let depth = calib_rng.uniform(near, far + 100.0);
            let (fx, fy) = (camera.fx(), camera.fy());
            let px = calib_rng.uniform(0.15, 0.85) * w as f64;
            let py = calib_rng.uniform(0.15, 0.85) * h as f64;
            let centre = Vector3::new((px - camera.cx()) / fx * depth, (py - camera.cy()) / fy * depth, depth);
            let rotation = euler_deg(
                calib_rng.uniform(-35.0, 35.0),
                calib_rng.uniform(-35.0, 35.0),
                calib_rng.uniform(-20.0, 20.0),
            );
            let pose = Rigid::from_parts(Translation3::from(centre - rotation * cb_centre), rotation);
            if board_in_view(camera, &pose, cb.paper_bounds_mm(), 15.0).is_some() {
                placed = Some(pose);
                break;
            }
        }
        views.push(placed.ok_or(SceneError::CalibrationViewDoesNotFit { view, tries })?);
    }
    Ok(views)
}
