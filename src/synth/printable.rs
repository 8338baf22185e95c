//! The printable model of a dome phantom: a base plate on the bed, a riser
//! whose top is the tank floor the renderer puts the domes over, for each sphere
//! a pillar of the sphere's radius capped by its dome, and the seat of the
//! phantom board ([`super::board_seat`]), in the lab's upright frame (z up,
//! millimetres; x and y as the lab's world axes), the bed at z = 0. The board
//! stands beside the tank and reaches below its floor, so the base lies under
//! the seat and the riser lifts the domes to the floor. The shells overlap
//! (pillars 1 mm into the riser, the riser 1 mm into the plate, the seat's
//! parts into the plate and each other) so that a slicer joins them. Each shell
//! is closed, with outward normals.

use nalgebra::{Point3, Vector3};

use super::board_seat::{self, BoardSeat, Mount, SeatError};
use super::scene::lab_layout;
use crate::core::geometry::Rigid;
use crate::io::stl::Triangle;
use crate::spec::phantom::Phantom;
use crate::spec::render::RenderSpec;

/// The plate's thickness and its margin around the domes, mm.
pub const PLATE_MM: f64 = 5.0;
pub const MARGIN_MM: f64 = 10.0;
/// The tank floor below the domes' mean centre (the renderer's), mm.
pub const FLOOR_BELOW_CENTRE_MM: f64 = 30.0;
/// Facets around a dome, and rings from its equator to its top.
const AROUND: usize = 64;
const RINGS: usize = 16;

/// A dome of the model: its sphere's name, its centre in the upright frame and its radius.
#[derive(Debug, Clone, PartialEq)]
pub struct PrintedDome {
    pub name: String,
    pub centre_mm: Point3<f64>,
    pub radius_mm: f64,
}

/// The model: the base plate's corners (min, max), the riser's (absent when the
/// floor is the plate's top), the domes and the board's seat.
#[derive(Debug, Clone, PartialEq)]
pub struct PrintableModel {
    pub plate_min_mm: Point3<f64>,
    pub plate_max_mm: Point3<f64>,
    pub riser: Option<[Point3<f64>; 2]>,
    pub domes: Vec<PrintedDome>,
    pub seat: BoardSeat,
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PrintableError {
    #[error("phantom: only dome phantoms (hemisphere, spheres) are printable models here")]
    NotDomes,
    #[error("phantom.spheres.spheres[{index}] (`{name}`): its dome's top half sits {below_mm:.1} mm below the tank floor (centre at most {FLOOR_BELOW_CENTRE_MM} mm under the mean centre)")]
    BelowFloor { index: usize, name: String, below_mm: f64 },
    #[error("{0}")]
    Seat(#[from] SeatError),
    #[error("the board seat's profile is not star-shaped; its shell cannot be closed")]
    SeatShell,
}

/// The model of the manifest's phantom in its lab (`render` gives the camera
/// distance the lab is laid out for; the phantom board fixes its frame).
pub fn model(
    phantom: &Phantom,
    phantom_board: &crate::detect::board::PrintedBoard,
    render: &RenderSpec,
) -> Result<PrintableModel, PrintableError> {
    let (_, world_T_phantom) = lab_layout(render.board_distance_mm, phantom_board);
    let spheres: Vec<(String, Point3<f64>, f64)> = match phantom {
        Phantom::Spheres { spheres } => spheres
            .iter()
            .map(|s| {
                (
                    s.name.clone(),
                    world_T_phantom * Point3::from(s.centre_in_phantom_mm),
                    s.radius_mm,
                )
            })
            .collect(),
        Phantom::Hemisphere {
            centre_in_phantom_mm,
            radius_mm,
        } => vec![(
            "hemisphere".into(),
            world_T_phantom * Point3::from(*centre_in_phantom_mm),
            *radius_mm,
        )],
        Phantom::Point { .. } | Phantom::FourWire { .. } => return Err(PrintableError::NotDomes),
    };
    let n = spheres.len() as f64;
    let mean = spheres.iter().fold(Vector3::zeros(), |acc, (_, c, _)| acc + c.coords) / n;
    // Upright frame: the bed at z = 0 under the lower of the plate under the
    // floor and the seat's bottom; x and y centred on the domes.
    let floor_z = mean.z - FLOOR_BELOW_CENTRE_MM;
    let mount = Mount::of(phantom_board)?;
    let bed_z = (floor_z - PLATE_MM).min(board_seat::lowest_z_mm(&world_T_phantom, &mount));
    let offset = Vector3::new(-mean.x, -mean.y, -bed_z);
    let floor_mm = floor_z - bed_z;
    let mut domes = Vec::new();
    for (index, (name, centre, radius_mm)) in spheres.iter().enumerate() {
        let centre_mm = centre + offset;
        if centre_mm.z < floor_mm {
            return Err(PrintableError::BelowFloor {
                index,
                name: name.clone(),
                below_mm: floor_mm - centre_mm.z,
            });
        }
        domes.push(PrintedDome {
            name: name.clone(),
            centre_mm,
            radius_mm: *radius_mm,
        });
    }
    let reach = |k: usize, sign: f64| {
        domes
            .iter()
            .map(|d| sign * d.centre_mm[k] + d.radius_mm + MARGIN_MM)
            .fold(f64::NEG_INFINITY, f64::max)
            * sign
    };
    let riser_min = Point3::new(reach(0, -1.0), reach(1, -1.0), PLATE_MM - 1.0);
    let riser_max = Point3::new(reach(0, 1.0), reach(1, 1.0), floor_mm);
    let upright_T_phantom = Rigid::translation(offset.x, offset.y, offset.z) * world_T_phantom;
    let seat = board_seat::build(upright_T_phantom, mount)?;
    let mut plate_min_mm = Point3::new(riser_min.x, riser_min.y, 0.0);
    let mut plate_max_mm = Point3::new(riser_max.x, riser_max.y, PLATE_MM);
    for prism in &seat.prisms {
        for p in prism.profile.iter().flat_map(|&p| [p, p + prism.sweep]) {
            for k in 0..2 {
                plate_min_mm[k] = plate_min_mm[k].min(p[k] - MARGIN_MM);
                plate_max_mm[k] = plate_max_mm[k].max(p[k] + MARGIN_MM);
            }
        }
    }
    Ok(PrintableModel {
        plate_min_mm,
        plate_max_mm,
        riser: (floor_mm > PLATE_MM).then_some([riser_min, riser_max]),
        domes,
        seat,
    })
}

impl PrintableModel {
    /// The tank floor's height, mm: the riser's top, or the plate's.
    pub fn floor_mm(&self) -> f64 {
        self.riser.map_or(PLATE_MM, |[_, hi]| hi.z)
    }

    /// The model's top, mm: the highest dome or the seat's backrest.
    pub fn top_mm(&self) -> f64 {
        let domes = self.domes.iter().map(|d| d.centre_mm.z + d.radius_mm);
        let seat = self.seat.prisms.iter().flat_map(|p| p.profile.iter().map(|q| q.z));
        domes.chain(seat).fold(0.0, f64::max)
    }

    /// How many closed shells the model has.
    pub fn shells(&self) -> usize {
        1 + usize::from(self.riser.is_some()) + self.domes.len() + self.seat.prisms.len()
    }

    /// The closed shells' triangles: the plate, the riser, each pillar with its
    /// dome, then the seat's parts.
    pub fn triangles(&self) -> Result<Vec<Triangle>, PrintableError> {
        let mut out = box_triangles(self.plate_min_mm, self.plate_max_mm);
        if let Some([lo, hi]) = self.riser {
            out.extend(box_triangles(lo, hi));
        }
        for d in &self.domes {
            out.extend(dome_triangles(d, self.floor_mm() - 1.0));
        }
        for prism in &self.seat.prisms {
            out.extend(prism.triangles().ok_or(PrintableError::SeatShell)?);
        }
        Ok(out)
    }

    /// The enclosed volume of the shells, mm³ (of the smooth shapes, each shell on its own).
    pub fn volume_mm3(&self) -> f64 {
        let box_volume = |lo: Point3<f64>, hi: Point3<f64>| (hi - lo).product();
        let floor = self.floor_mm();
        box_volume(self.plate_min_mm, self.plate_max_mm)
            + self.riser.map_or(0.0, |[lo, hi]| box_volume(lo, hi))
            + self.seat.prisms.iter().map(|p| p.volume_mm3()).sum::<f64>()
            + self
                .domes
                .iter()
                .map(|d| {
                    let pillar = d.centre_mm.z - (floor - 1.0);
                    std::f64::consts::PI * d.radius_mm.powi(2) * pillar
                        + 2.0 / 3.0 * std::f64::consts::PI * d.radius_mm.powi(3)
                })
                .sum::<f64>()
    }
}

/// A box's 12 triangles, outward.
fn box_triangles(lo: Point3<f64>, hi: Point3<f64>) -> Vec<Triangle> {
    let v = |i: usize| {
        Point3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        )
    };
    // Each face as a quad, counter-clockwise seen from outside.
    let quads = [
        [0, 2, 3, 1], // bottom (z = lo)
        [4, 5, 7, 6], // top
        [0, 1, 5, 4], // y = lo
        [2, 6, 7, 3], // y = hi
        [0, 4, 6, 2], // x = lo
        [1, 3, 7, 5], // x = hi
    ];
    quads
        .iter()
        .flat_map(|q| [[v(q[0]), v(q[1]), v(q[2])], [v(q[0]), v(q[2]), v(q[3])]])
        .collect()
}

/// A pillar from `bottom_z` up to the dome's centre, capped by the dome.
fn dome_triangles(d: &PrintedDome, bottom_z: f64) -> Vec<Triangle> {
    let c = d.centre_mm;
    let r = d.radius_mm;
    let ring = |k: usize| {
        // Ring k: 0 at the equator, RINGS at the top (a single point).
        let polar = std::f64::consts::FRAC_PI_2 * k as f64 / RINGS as f64;
        (r * polar.cos(), c.z + r * polar.sin())
    };
    let at = |radius: f64, z: f64, j: usize| {
        let a = std::f64::consts::TAU * (j % AROUND) as f64 / AROUND as f64;
        Point3::new(c.x + radius * a.cos(), c.y + radius * a.sin(), z)
    };
    let bottom_centre = Point3::new(c.x, c.y, bottom_z);
    let top = Point3::new(c.x, c.y, c.z + r);
    let mut out = Vec::new();
    for j in 0..AROUND {
        // Bottom disc (facing down), pillar wall.
        out.push([bottom_centre, at(r, bottom_z, j + 1), at(r, bottom_z, j)]);
        out.push([at(r, bottom_z, j), at(r, bottom_z, j + 1), at(r, c.z, j + 1)]);
        out.push([at(r, bottom_z, j), at(r, c.z, j + 1), at(r, c.z, j)]);
        // Dome rings.
        for k in 0..RINGS - 1 {
            let (r0, z0) = ring(k);
            let (r1, z1) = ring(k + 1);
            out.push([at(r0, z0, j), at(r0, z0, j + 1), at(r1, z1, j + 1)]);
            out.push([at(r0, z0, j), at(r1, z1, j + 1), at(r1, z1, j)]);
        }
        let (r0, z0) = ring(RINGS - 1);
        out.push([at(r0, z0, j), at(r0, z0, j + 1), top]);
    }
    out
}
