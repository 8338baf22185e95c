//! N-wire (Z-fiducial) phantoms: the geometry.
//!
//! An N is three wires in one plane of the phantom: wire 1 and wire 3 parallel,
//! wire 2 diagonal between them. A B-scan plane crossing the N shows three dots
//! p1, p2, p3 on a line. With `alpha = |p2 - p1| / |p3 - p1|` (a ratio along a line,
//! the same in pixels as in millimetres), the middle dot sits at
//! `W12 + alpha (W32 - W12)` in the phantom frame, where W12 (W32) is the crossing
//! of the infinite lines of wires 1 and 2 (3 and 2): similar triangles.

use nalgebra::{Point3, Vector3};

/// The most dot candidates (bright spots) a B-scan's N-wire search considers
/// (`NumberOfMaximumFiducialPointCandidates`): rows are every three of them, so
/// the search grows with the cube of this number.
pub const MAX_DOT_CANDIDATES: usize = 200;

/// One wire, as a segment in the phantom frame (mm).
#[derive(Debug, Clone, PartialEq)]
pub struct WireSegment {
    pub name: String,
    pub front_in_phantom_mm: Point3<f64>,
    pub back_in_phantom_mm: Point3<f64>,
}

impl WireSegment {
    pub fn direction(&self) -> Vector3<f64> {
        self.back_in_phantom_mm - self.front_in_phantom_mm
    }
}

/// One N: wires 1, 2 (diagonal), 3, and the crossings W12 and W32.
#[derive(Debug, Clone, PartialEq)]
pub struct NWire {
    pub wires: [WireSegment; 3],
    pub w12_in_phantom_mm: Point3<f64>,
    pub w32_in_phantom_mm: Point3<f64>,
}

/// Where two infinite lines cross (the midpoint of their closest points), and the
/// distance between them at that point.
fn crossing(a: &WireSegment, b: &WireSegment) -> Option<(Point3<f64>, f64)> {
    let (p, u) = (a.front_in_phantom_mm, a.direction());
    let (q, v) = (b.front_in_phantom_mm, b.direction());
    let w = p - q;
    let (aa, bb, cc, dd, ee) = (u.dot(&u), u.dot(&v), v.dot(&v), u.dot(&w), v.dot(&w));
    let den = aa * cc - bb * bb;
    if den.abs() < 1e-12 * aa * cc {
        return None;
    }
    let s = (bb * ee - cc * dd) / den;
    let t = (aa * ee - bb * dd) / den;
    let on_a = p + u * s;
    let on_b = q + v * t;
    Some((Point3::from((on_a.coords + on_b.coords) / 2.0), (on_a - on_b).norm()))
}

/// Why three wires do not form an N.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum NWireError {
    #[error("wire `{wire}` has equal end points")]
    EqualEnds { wire: String },
    #[error("wires `{first}` and `{third}` (the N's sides) are not parallel")]
    SidesNotParallel { first: String, third: String },
    #[error("wire `{diagonal}` is parallel to `{side}`: not an N")]
    DiagonalParallel { diagonal: String, side: String },
    #[error("the diagonal wire `{diagonal}` does not lie in the plane of the side wires ({first_off_mm:.3} / {third_off_mm:.3} mm off)")]
    OutOfPlane {
        diagonal: String,
        first_off_mm: f64,
        third_off_mm: f64,
    },
}

impl NWire {
    /// Checks the wires form an N: 1 and 3 parallel, 2 crossing both in one plane.
    pub fn new(wires: [WireSegment; 3]) -> Result<NWire, NWireError> {
        for w in &wires {
            if w.direction().norm() < 1e-9 {
                return Err(NWireError::EqualEnds { wire: w.name.clone() });
            }
        }
        let (d1, d3) = (wires[0].direction().normalize(), wires[2].direction().normalize());
        if d1.cross(&d3).norm() > 1e-3 {
            return Err(NWireError::SidesNotParallel {
                first: wires[0].name.clone(),
                third: wires[2].name.clone(),
            });
        }
        let parallel = |side: &WireSegment| NWireError::DiagonalParallel {
            diagonal: wires[1].name.clone(),
            side: side.name.clone(),
        };
        let (w12, gap12) = crossing(&wires[0], &wires[1]).ok_or_else(|| parallel(&wires[0]))?;
        let (w32, gap32) = crossing(&wires[2], &wires[1]).ok_or_else(|| parallel(&wires[2]))?;
        if gap12 > 1e-3 || gap32 > 1e-3 {
            return Err(NWireError::OutOfPlane {
                diagonal: wires[1].name.clone(),
                first_off_mm: gap12,
                third_off_mm: gap32,
            });
        }
        Ok(NWire {
            wires,
            w12_in_phantom_mm: w12,
            w32_in_phantom_mm: w32,
        })
    }

    /// The middle dot's position in the phantom frame from the three dots' pixels.
    pub fn middle_in_phantom_mm(&self, dots_px: &[[f64; 2]; 3]) -> Point3<f64> {
        let alpha = middle_ratio(dots_px);
        self.w12_in_phantom_mm + (self.w32_in_phantom_mm - self.w12_in_phantom_mm) * alpha
    }

    /// Distance between the side wires, mm.
    /// The pattern's plane: a point of it and its unit normal (phantom frame).
    pub fn plane(&self) -> (Point3<f64>, Vector3<f64>) {
        let d = self.wires[0].direction();
        let across = self.wires[2].front_in_phantom_mm - self.wires[0].front_in_phantom_mm;
        (self.wires[0].front_in_phantom_mm, d.cross(&across).normalize())
    }

    /// Distance of `next`'s plane from this pattern's, mm.
    pub fn distance_to(&self, next: &NWire) -> f64 {
        let (p, n) = self.plane();
        (next.wires[0].front_in_phantom_mm - p).dot(&n).abs()
    }

    pub fn width_mm(&self) -> f64 {
        let d = self.wires[0].direction().normalize();
        let w = self.wires[2].front_in_phantom_mm - self.wires[0].front_in_phantom_mm;
        (w - d * w.dot(&d)).norm()
    }
}

/// `|p2 - p1| / |p3 - p1|`.
pub fn middle_ratio(dots_px: &[[f64; 2]; 3]) -> f64 {
    let d = |a: [f64; 2], b: [f64; 2]| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt();
    d(dots_px[1], dots_px[0]) / d(dots_px[2], dots_px[0])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wire(x0: f64, x1: f64, z: f64) -> WireSegment {
        WireSegment {
            name: String::new(),
            front_in_phantom_mm: Point3::new(x0, 0.0, z),
            back_in_phantom_mm: Point3::new(x1, 40.0, z),
        }
    }

    #[test]
    fn middle_dot_follows_similar_triangles() {
        let n = NWire::new([wire(30.0, 30.0, 20.0), wire(55.0, 35.0, 20.0), wire(60.0, 60.0, 20.0)]).unwrap();
        assert!((n.w12_in_phantom_mm - Point3::new(30.0, 50.0, 20.0)).norm() < 1e-9);
        assert!((n.w32_in_phantom_mm - Point3::new(60.0, -10.0, 20.0)).norm() < 1e-9);
        // A plane y = 12 crosses the wires at x = 30, 49, 60.
        let x = n.middle_in_phantom_mm(&[[300.0, 5.0], [490.0, 5.0], [600.0, 5.0]]);
        assert!((x - Point3::new(49.0, 12.0, 20.0)).norm() < 1e-9);
        assert!((n.width_mm() - 30.0).abs() < 1e-12);
        assert!(NWire::new([wire(30.0, 30.0, 20.0), wire(55.0, 35.0, 25.0), wire(60.0, 60.0, 20.0)]).is_err());
    }
}
