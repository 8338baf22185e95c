//! The occluders of a handheld session (`render.occluders`), drawn per photo
//! at their stated rates from their own random stream (seed, frame), so a
//! manifest with occluders renders the same sweep, poses and B-scans as
//! without, and only the boards' visible parts differ.
//!
//! Shapes, in the board's frame relative to its centre (mm); the board's
//! lower edge is its +y edge:
//! - **hand**: two fingers of [`FINGER_BREADTH_MM`] side by side (centre lines
//!   [`FINGER_PITCH_MM`] apart) reaching 15-45 mm over the probe board's lower
//!   edge, within ±20° of square to it, anywhere along the middle 70 % of it;
//! - **cable**: the probe cable, [`CABLE_DIAMETER_MM`] thick, straight across
//!   the probe board at any angle through a point of the board's middle half;
//! - **rim**: the tank's rim over the phantom board's lower 10-40 mm, tilted
//!   up to ±3° against the board's rows.

use serde::Serialize;

use super::scene::Occluder;
use crate::core::rng::Rng;
use crate::detect::board::PrintedBoard;
use crate::spec::render::SessionOccluders;

/// An adult finger's breadth, mm (index and middle fingers, about 18 mm).
pub const FINGER_BREADTH_MM: f64 = 18.0;
/// Centre-line distance of two fingers side by side, mm.
pub const FINGER_PITCH_MM: f64 = 19.0;
/// An ultrasound probe cable's diameter, mm (typically 7-10 mm).
pub const CABLE_DIAMETER_MM: f64 = 9.0;
/// Stream label of the occluders' random draws (apart from the frame plan's).
const STREAM: u64 = 30_000;

/// One occluder in one photo.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PlacedOccluder {
    /// `hand`, `cable` or `rim`.
    pub what: &'static str,
    /// `probe` or `phantom`.
    pub board: &'static str,
    pub shape: Occluder,
}

/// The session's occluders of one photo.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PhotoOccluders {
    pub all: Vec<PlacedOccluder>,
}

impl PhotoOccluders {
    pub fn probe(&self) -> impl Iterator<Item = Occluder> + '_ {
        self.on("probe")
    }

    pub fn phantom(&self) -> impl Iterator<Item = Occluder> + '_ {
        self.on("phantom")
    }

    fn on(&self, board: &'static str) -> impl Iterator<Item = Occluder> + '_ {
        self.all.iter().filter(move |o| o.board == board).map(|o| o.shape)
    }
}

/// The paper's half-extents about the board's centre: `[x_min, y_min, x_max, y_max]`.
fn paper_about_centre(board: &PrintedBoard) -> [f64; 4] {
    let [x0, y0, x1, y1] = board.paper_bounds_mm();
    let c = board.centre_mm();
    [x0 - c.x, y0 - c.y, x1 - c.x, y1 - c.y]
}

/// Draws the occluders of photo `frame` (none when `spec` is absent).
pub fn draw(
    spec: Option<&SessionOccluders>,
    probe: &PrintedBoard,
    phantom: &PrintedBoard,
    seed: u64,
    frame: usize,
) -> PhotoOccluders {
    let Some(spec) = spec else {
        return PhotoOccluders::default();
    };
    let mut rng = Rng::fork(seed, STREAM + frame as u64);
    let mut all = Vec::new();
    // Every draw is made whether or not its occluder occurs, so one rate does
    // not move another occluder's shape.
    let hand = rng.chance(spec.hand_rate);
    let fingers = hand_shape(paper_about_centre(probe), &mut rng);
    if hand {
        all.extend(fingers.into_iter().map(|shape| PlacedOccluder {
            what: "hand",
            board: "probe",
            shape,
        }));
    }
    let cable = rng.chance(spec.cable_rate);
    let cable_shape = cable_shape(paper_about_centre(probe), &mut rng);
    if cable {
        all.push(PlacedOccluder {
            what: "cable",
            board: "probe",
            shape: cable_shape,
        });
    }
    let rim = rng.chance(spec.rim_rate);
    let rim_shape = rim_shape(paper_about_centre(phantom), &mut rng);
    if rim {
        all.push(PlacedOccluder {
            what: "rim",
            board: "phantom",
            shape: rim_shape,
        });
    }
    PhotoOccluders { all }
}

/// Two fingers over the lower edge.
fn hand_shape(paper: [f64; 4], rng: &mut Rng) -> [Occluder; 2] {
    let [x0, _, x1, y1] = paper;
    let width = x1 - x0;
    let along = rng.uniform(x0 + 0.15 * width, x1 - 0.15 * width);
    let reach = rng.uniform(15.0, 45.0);
    let angle = rng.uniform(-20.0, 20.0).to_radians();
    // Pointing up the board (−y), turned by `angle`.
    let (dx, dy) = (angle.sin(), -angle.cos());
    let (nx, ny) = (-dy, dx);
    std::array::from_fn(|k| {
        let side = (k as f64 - 0.5) * FINGER_PITCH_MM;
        let base = [along + side * nx, y1 + side * ny];
        // The finger comes from the handle, well below the paper, to its tip.
        let tip = [base[0] + reach * dx, base[1] + reach * dy];
        let from = [base[0] - 80.0 * dx, base[1] - 80.0 * dy];
        Occluder {
            from_centre_mm: from,
            to_centre_mm: tip,
            width_mm: FINGER_BREADTH_MM,
        }
    })
}

/// The cable straight across the board.
fn cable_shape(paper: [f64; 4], rng: &mut Rng) -> Occluder {
    let [x0, y0, x1, y1] = paper;
    let through = [rng.uniform(x0 / 2.0, x1 / 2.0), rng.uniform(y0 / 2.0, y1 / 2.0)];
    let angle = rng.uniform(0.0, std::f64::consts::PI);
    let half = (x1 - x0).hypot(y1 - y0);
    let (dx, dy) = (angle.cos(), angle.sin());
    Occluder {
        from_centre_mm: [through[0] - half * dx, through[1] - half * dy],
        to_centre_mm: [through[0] + half * dx, through[1] + half * dy],
        width_mm: CABLE_DIAMETER_MM,
    }
}

/// The rim over the lower rows: a capsule whose near side is the rim's edge.
fn rim_shape(paper: [f64; 4], rng: &mut Rng) -> Occluder {
    let [x0, _, x1, y1] = paper;
    let depth = rng.uniform(10.0, 40.0);
    let tilt = rng.uniform(-3.0, 3.0).to_radians();
    let (dx, dy) = (tilt.cos(), tilt.sin());
    // The capsule's axis lies `far` below the rim's edge; its half-width reaches the edge.
    let far = 1000.0;
    let edge_mid = [(x0 + x1) / 2.0, y1 - depth];
    let axis_mid = [edge_mid[0] - far * dy, edge_mid[1] + far * dx];
    let half = 4.0 * (x1 - x0) + far;
    Occluder {
        from_centre_mm: [axis_mid[0] - half * dx, axis_mid[1] - half * dy],
        to_centre_mm: [axis_mid[0] + half * dx, axis_mid[1] + half * dy],
        width_mm: 2.0 * far,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::board::BoardLayout;

    fn board() -> PrintedBoard {
        PrintedBoard::Checkerboard(BoardLayout {
            inner_corners: [10, 10],
            square_mm: 13.0,
            id_dots: 1,
        })
    }

    #[test]
    fn shapes_cover_what_they_state() {
        let paper = paper_about_centre(&board());
        let mut rng = Rng::new(7);
        for _ in 0..200 {
            // The rim covers the lower edge's middle and leaves the board's centre.
            let rim = rim_shape(paper, &mut rng);
            assert!(rim.covers(0.0, paper[3] - 1.0));
            assert!(!rim.covers(0.0, 0.0));
            assert!(!rim.covers(0.0, paper[3] - 45.0));
            // The fingertips lie over the board, 15-45 mm (and the fingers'
            // spread) above its lower edge, and nothing is covered beyond.
            let fingers = hand_shape(paper, &mut rng);
            for f in &fingers {
                let up = paper[3] - f.to_centre_mm[1];
                assert!(
                    (15.0 * 20f64.to_radians().cos() - 3.3..=45.0 + 3.3).contains(&up),
                    "{up}"
                );
                assert!(!f.covers(f.to_centre_mm[0], paper[3] - 60.0));
            }
            // The cable crosses the board through its middle half.
            let cable = cable_shape(paper, &mut rng);
            let mid = [
                (cable.from_centre_mm[0] + cable.to_centre_mm[0]) / 2.0,
                (cable.from_centre_mm[1] + cable.to_centre_mm[1]) / 2.0,
            ];
            assert!(mid[0].abs() <= paper[2] / 2.0 + 1e-9 && mid[1].abs() <= paper[3] / 2.0 + 1e-9);
        }
    }

    #[test]
    fn rates_are_kept_and_absent_spec_draws_nothing() {
        let (b, spec) = (
            board(),
            SessionOccluders {
                hand_rate: 0.3,
                cable_rate: 0.2,
                rim_rate: 0.25,
            },
        );
        assert!(draw(None, &b, &b, 1, 0).all.is_empty());
        let n = 4000;
        let mut counts = [0usize; 3];
        for k in 0..n {
            let o = draw(Some(&spec), &b, &b, 1, k);
            for (i, what) in ["hand", "cable", "rim"].iter().enumerate() {
                counts[i] += usize::from(o.all.iter().any(|p| p.what == *what));
            }
            assert_eq!(o, draw(Some(&spec), &b, &b, 1, k), "deterministic");
        }
        for (count, rate) in counts.iter().zip([0.3, 0.2, 0.25]) {
            let share = *count as f64 / n as f64;
            assert!((share - rate).abs() < 0.03, "{share} vs {rate}");
        }
    }
}
