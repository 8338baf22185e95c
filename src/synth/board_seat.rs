//! The printable model's seat for the phantom board. The board's print is glued
//! on a square mount (the scene's plate, `2·PLATE_HALF_MM` wide around the
//! pattern's centre, [`MOUNT_MM`] thick, the print on its front face); the seat
//! holds the mount's back on a backrest, its bottom edge on a ledge square to
//! the backrest, and its left edge (the side of the pattern's origin) against a
//! fence. A mount pushed into that corner puts the pattern's origin corner where
//! the phantom frame puts it relative to the domes.
//!
//! Each part is a prism: a profile across the board (in the plane of the board's
//! y and z axes, which holds the vertical since the board's x axis is level)
//! swept along the board's x axis, standing on the bed (z = 0 of the upright
//! frame). The backrest reaches from the mount's bottom edge to its centre.

use nalgebra::{Point3, Vector3};

use super::scene::PLATE_HALF_MM;
use crate::core::geometry::Rigid;
use crate::detect::board::PrintedBoard;
use crate::io::stl::Triangle;

/// The mount's thickness: a 3 mm aluminium composite panel, mm.
pub const MOUNT_MM: f64 = 3.0;
/// Material under the pocket's corner, behind the backrest's top, and the
/// fence's width along the board, mm.
pub const LEDGE_MM: f64 = 5.0;
pub const BACKREST_MM: f64 = 10.0;
pub const FENCE_MM: f64 = 5.0;
/// How far the fence reaches in front of the print (beside the paper, whose
/// margin leaves the mount's edge 5.5 mm from it on a 13 mm-square board), mm.
pub const FENCE_LIP_MM: f64 = 2.0;

/// The mount's edges in the phantom frame (the pattern's origin corner, x along
/// its rows, y down its columns, z into the board), mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mount {
    pub left_x_mm: f64,
    pub right_x_mm: f64,
    pub top_y_mm: f64,
    pub bottom_y_mm: f64,
}

impl Mount {
    /// The scene's plate under the board: `PLATE_HALF_MM` each way from the
    /// pattern's centre; refused if the board's paper overhangs it.
    pub fn of(board: &PrintedBoard) -> Result<Mount, SeatError> {
        let c = board.centre_mm();
        let mount = Mount {
            left_x_mm: c.x - PLATE_HALF_MM,
            right_x_mm: c.x + PLATE_HALF_MM,
            top_y_mm: c.y - PLATE_HALF_MM,
            bottom_y_mm: c.y + PLATE_HALF_MM,
        };
        let [x0, y0, x1, y1] = board.paper_bounds_mm();
        if x0 < mount.left_x_mm || y0 < mount.top_y_mm || x1 > mount.right_x_mm || y1 > mount.bottom_y_mm {
            return Err(SeatError::PaperOverhangs {
                paper_mm: [x1 - x0, y1 - y0],
            });
        }
        Ok(mount)
    }

    fn centre_y_mm(&self) -> f64 {
        (self.top_y_mm + self.bottom_y_mm) / 2.0
    }
}

/// A closed prism: `profile` (a simple polygon, in a plane square to `sweep`)
/// swept by `sweep`.
#[derive(Debug, Clone, PartialEq)]
pub struct Prism {
    pub profile: Vec<Point3<f64>>,
    pub sweep: Vector3<f64>,
}

/// The seat: where its parts are and what they hold.
#[derive(Debug, Clone, PartialEq)]
pub struct BoardSeat {
    pub mount: Mount,
    /// The upright frame from the phantom frame.
    pub upright_T_phantom: Rigid,
    /// The backrest with its ledge, then the fence.
    pub prisms: Vec<Prism>,
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SeatError {
    #[error("rig: the phantom board's paper ({:.0} x {:.0} mm) overhangs the {:.0} mm square mount the seat holds", paper_mm[0], paper_mm[1], 2.0 * PLATE_HALF_MM)]
    PaperOverhangs { paper_mm: [f64; 2] },
    #[error(
        "rig: the phantom board's x axis is not level in the lab (its z is {z:.3}); the seat's prisms need it level"
    )]
    NotLevel { z: f64 },
    #[error("rig: the phantom board leans forward in the lab; a seat that holds it from behind would not hold it")]
    LeansForward,
}

/// The lowest point the seat needs in the lab's frame: `LEDGE_MM` under the
/// pocket's corner (the mount's bottom edge at its back).
pub fn lowest_z_mm(world_T_phantom: &Rigid, mount: &Mount) -> f64 {
    (world_T_phantom * Point3::new(mount.left_x_mm, mount.bottom_y_mm, MOUNT_MM)).z - LEDGE_MM
}

/// The seat, once the upright frame (bed at z = 0) is fixed.
pub fn build(upright_T_phantom: Rigid, mount: Mount) -> Result<BoardSeat, SeatError> {
    let x_axis = upright_T_phantom * Vector3::x();
    if x_axis.z.abs() > 1e-9 {
        return Err(SeatError::NotLevel { z: x_axis.z });
    }
    let z_axis = upright_T_phantom * Vector3::z();
    let back = Vector3::new(z_axis.x, z_axis.y, 0.0).normalize();
    // Up the board (−y) must lead away from the camera, behind the print.
    if (upright_T_phantom * -Vector3::y()).dot(&back) <= 0.0 {
        return Err(SeatError::LeansForward);
    }
    // A profile at board x = `x_mm`: the ledge from `ledge_front_z` back to the
    // face at `face_z`, the face up to the mount's centre, the backrest behind it.
    let profile = |x_mm: f64, face_z: f64, ledge_front_z: f64| {
        let on_board = |y: f64, z: f64| upright_T_phantom * Point3::new(x_mm, y, z);
        let on_bed = |p: Point3<f64>| Point3::new(p.x, p.y, 0.0);
        let front = on_board(mount.bottom_y_mm, ledge_front_z);
        let corner = on_board(mount.bottom_y_mm, face_z);
        let face_top = on_board(mount.centre_y_mm(), face_z);
        let back_top = face_top + back * BACKREST_MM;
        let mut polygon = vec![on_bed(front)];
        if ledge_front_z != face_z {
            polygon.push(front);
        }
        polygon.extend([corner, face_top, back_top, on_bed(back_top)]);
        polygon
    };
    let along = |mm: f64| x_axis * mm;
    let prisms = vec![
        // The backrest and ledge, across the mount and 1 mm into the fence.
        Prism {
            profile: profile(mount.left_x_mm - 1.0, MOUNT_MM, 0.0),
            sweep: along(mount.right_x_mm - mount.left_x_mm + 1.0),
        },
        // The fence: beside the mount's left edge, its face in front of the print.
        Prism {
            profile: profile(mount.left_x_mm - FENCE_MM, -FENCE_LIP_MM, -FENCE_LIP_MM),
            sweep: along(FENCE_MM),
        },
    ];
    Ok(BoardSeat {
        mount,
        upright_T_phantom,
        prisms,
    })
}

impl Prism {
    /// Twice the profile's signed area, along the sweep (positive: counter-clockwise seen from its end).
    fn signed_double_area(&self) -> f64 {
        let axis = self.sweep.normalize();
        let p0 = self.profile[0];
        (1..self.profile.len() - 1)
            .map(|i| (self.profile[i] - p0).cross(&(self.profile[i + 1] - p0)).dot(&axis))
            .sum()
    }

    pub fn volume_mm3(&self) -> f64 {
        self.signed_double_area().abs() / 2.0 * self.sweep.norm()
    }

    /// The profile's vertices counter-clockwise seen from the sweep's end.
    fn counter_clockwise(&self) -> Vec<Point3<f64>> {
        let mut p = self.profile.clone();
        if self.signed_double_area() < 0.0 {
            p.reverse();
        }
        p
    }

    /// Fan triangles of the profile, from the first vertex whose fan lies inside
    /// it (a star-shaped profile); none if there is none.
    fn cap(&self) -> Option<Vec<[Point3<f64>; 3]>> {
        let p = self.counter_clockwise();
        let axis = self.sweep.normalize();
        let n = p.len();
        (0..n).find_map(|apex| {
            let fan: Vec<[Point3<f64>; 3]> = (1..n - 1)
                .map(|k| [p[apex], p[(apex + k) % n], p[(apex + k + 1) % n]])
                .collect();
            fan.iter()
                .all(|t| (t[1] - t[0]).cross(&(t[2] - t[0])).dot(&axis) > 1e-9)
                .then_some(fan)
        })
    }

    /// The closed shell's triangles, outward; `None` if the profile is not star-shaped.
    pub fn triangles(&self) -> Option<Vec<Triangle>> {
        let p = self.counter_clockwise();
        let s = self.sweep;
        let mut out = Vec::new();
        for t in self.cap()? {
            // The far end faces along the sweep, the near end against it.
            out.push([t[0] + s, t[1] + s, t[2] + s]);
            out.push([t[0], t[2], t[1]]);
        }
        for (i, &a) in p.iter().enumerate() {
            let b = p[(i + 1) % p.len()];
            out.push([a, b, b + s]);
            out.push([a, b + s, a + s]);
        }
        Some(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_prism_is_closed_outward_and_of_its_volume() {
        // An L-shaped profile (one reflex corner) swept 2 mm along +x.
        let profile = [(0.0, 0.0), (3.0, 0.0), (3.0, 1.0), (1.0, 1.0), (1.0, 2.0), (0.0, 2.0)]
            .iter()
            .map(|&(y, z)| Point3::new(0.0, y, z))
            .collect();
        let prism = Prism {
            profile,
            sweep: Vector3::new(2.0, 0.0, 0.0),
        };
        assert!((prism.volume_mm3() - 8.0).abs() < 1e-12);
        let triangles = prism.triangles().unwrap();
        // Outward: the divergence theorem gives the volume, positive.
        let volume: f64 = triangles
            .iter()
            .map(|t| t[0].coords.dot(&t[1].coords.cross(&t[2].coords)) / 6.0)
            .sum();
        assert!((volume - 8.0).abs() < 1e-9, "{volume}");
        // Closed: every edge is used once each way.
        let key = |p: &Point3<f64>| [p.x, p.y, p.z].map(|v| (v * 1e6).round() as i64);
        let mut edges = std::collections::BTreeMap::new();
        for t in &triangles {
            for i in 0..3 {
                *edges.entry((key(&t[i]), key(&t[(i + 1) % 3]))).or_insert(0) += 1;
            }
        }
        for ((a, b), n) in &edges {
            assert_eq!(edges.get(&(*b, *a)), Some(n), "edge {a:?}-{b:?}");
        }
    }

    #[test]
    fn a_board_whose_paper_overhangs_the_mount_is_refused() {
        let board = |square_mm: f64| {
            PrintedBoard::Checkerboard(crate::detect::board::BoardLayout {
                inner_corners: [10, 10],
                square_mm,
                id_dots: 2,
            })
        };
        // 10x10 inner corners: 13 squares of paper with its margins, 156 mm at
        // 12 mm (on the 180 mm mount), 182 mm at 14 mm (over it).
        let fits = Mount::of(&board(12.0)).unwrap();
        assert!(fits.right_x_mm - fits.left_x_mm == 2.0 * PLATE_HALF_MM);
        match Mount::of(&board(14.0)) {
            Err(SeatError::PaperOverhangs { paper_mm }) => assert_eq!(paper_mm, [182.0, 182.0]),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn a_profile_that_is_not_star_shaped_gives_no_shell() {
        // A U whose arms no single vertex sees both of.
        let profile = [
            (0.0, 0.0),
            (5.0, 0.0),
            (5.0, 3.0),
            (4.0, 3.0),
            (4.0, 1.0),
            (1.0, 1.0),
            (1.0, 3.0),
            (0.0, 3.0),
        ]
        .iter()
        .map(|&(y, z)| Point3::new(0.0, y, z))
        .collect();
        let prism = Prism {
            profile,
            sweep: Vector3::new(1.0, 0.0, 0.0),
        };
        assert!(prism.triangles().is_none());
    }
}
