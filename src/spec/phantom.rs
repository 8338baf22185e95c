//! Phantoms: their features in the phantom frame P (the phantom board's frame), mm.

use serde::{Deserialize, Serialize};

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
    /// Several domes (hemispheres on pillars, dome towards the probe), each cut by
    /// the B-scan plane at its own offset: the arcs' radii observe the plane's
    /// elevation that one hemisphere cannot.
    Spheres { spheres: Vec<Sphere> },
}

/// One dome of a `spheres` phantom.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Sphere {
    pub name: String,
    pub centre_in_phantom_mm: [f64; 3],
    pub radius_mm: f64,
}

/// The point a multi-sphere phantom is laid out around: the mean of its centres.
pub fn spheres_centre(spheres: &[Sphere]) -> [f64; 3] {
    let n = spheres.len().max(1) as f64;
    let mut sum = [0.0; 3];
    for s in spheres {
        for (k, v) in s.centre_in_phantom_mm.iter().enumerate() {
            sum[k] += v / n;
        }
    }
    sum
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

/// The point a wire phantom is laid out around: the mean of its wires' midpoints.
pub fn wires_centre(wires: &[(nalgebra::Point3<f64>, nalgebra::Point3<f64>)]) -> nalgebra::Point3<f64> {
    let sum = wires.iter().fold(nalgebra::Vector3::zeros(), |acc, (a, b)| {
        acc + (a.coords + b.coords) / 2.0
    });
    nalgebra::Point3::from(sum / wires.len().max(1) as f64)
}
