//! The phantom's shape in the world frame, and where a B-scan plane meets a segment.

use crate::core::geometry::Rigid;
use nalgebra::Point3;

/// The phantom's echoing parts in the world frame, laid out around its feature at
/// the world origin.
#[derive(Debug, Clone, PartialEq)]
pub enum Shape {
    /// A hemisphere, dome up, its centre the feature.
    Hemisphere { radius_mm: f64 },
    /// A pin head (a small sphere) on a pin in a silicone block; the head's centre is the feature.
    Point { head_radius_mm: f64 },
    /// Domes (hemispheres on pillars, dome up): centres in the world frame and radii.
    Spheres { domes_world: Vec<(Point3<f64>, f64)> },
    /// Straight wires of one diameter, end points in the world frame.
    Wires {
        wires_world: Vec<(Point3<f64>, Point3<f64>)>,
        radius_mm: f64,
    },
}

impl Shape {
    /// The domes that echo like the hemisphere: centre (world) and radius.
    pub fn domes(&self, feature_centre_world: &Point3<f64>) -> Vec<(Point3<f64>, f64)> {
        match self {
            Shape::Hemisphere { radius_mm } => vec![(*feature_centre_world, *radius_mm)],
            Shape::Spheres { domes_world } => domes_world.clone(),
            Shape::Point { .. } | Shape::Wires { .. } => Vec::new(),
        }
    }

    /// From the manifest's phantom: the shape in the world frame and the feature
    /// the lab is laid out around (phantom frame).
    pub fn from_phantom(phantom: &crate::spec::phantom::Phantom, world_T_phantom: &Rigid) -> (Shape, [f64; 3]) {
        use crate::spec::phantom::Phantom;
        match phantom {
            Phantom::Hemisphere {
                centre_in_phantom_mm,
                radius_mm,
            } => (Shape::Hemisphere { radius_mm: *radius_mm }, *centre_in_phantom_mm),
            Phantom::Point {
                position_in_phantom_mm,
                head_radius_mm,
            } => (
                Shape::Point {
                    head_radius_mm: *head_radius_mm,
                },
                *position_in_phantom_mm,
            ),
            Phantom::Spheres { spheres } => (
                Shape::Spheres {
                    domes_world: spheres
                        .iter()
                        .map(|s| (world_T_phantom * Point3::from(s.centre_in_phantom_mm), s.radius_mm))
                        .collect(),
                },
                crate::spec::phantom::spheres_centre(spheres),
            ),
            Phantom::FourWire {
                wires,
                wire_diameter_mm,
            } => {
                let ends: Vec<(Point3<f64>, Point3<f64>)> = wires
                    .iter()
                    .map(|w| (Point3::from(w.start_in_phantom_mm), Point3::from(w.end_in_phantom_mm)))
                    .collect();
                let centre = crate::spec::phantom::wires_centre(&ends);
                let wires_world = ends
                    .iter()
                    .map(|(a, b)| (world_T_phantom * a, world_T_phantom * b))
                    .collect();
                (
                    Shape::Wires {
                        wires_world,
                        radius_mm: wire_diameter_mm / 2.0,
                    },
                    [centre.x, centre.y, centre.z],
                )
            }
        }
    }
}

/// Where a line segment meets a plane given as `world_T_image` (image z = 0), in
/// image millimetres, if it does.
pub fn segment_in_plane(world_T_image: &Rigid, a: &Point3<f64>, b: &Point3<f64>) -> Option<Point3<f64>> {
    let image_T_world = world_T_image.inverse();
    let (t, point) = crate::core::geometry::line_meets_image_plane(&(image_T_world * a), &(image_T_world * b))?;
    (0.0..=1.0).contains(&t).then_some(point)
}
