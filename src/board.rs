//! The printed layout of a checkerboard marker, shared by the renderer and the detector.
//!
//! Board frame (mm): origin on the first inner corner, x along a row of inner
//! corners, y along a column, z into the board. With `cols x rows` inner corners
//! the squares cover `[-s, cols*s] x [-s, rows*s]`; square `(i, j)` (counted from
//! the top-left square) is black when `i + j` is even, so all four corner squares
//! of an odd-by-odd board are black. A white margin one square wide surrounds
//! the squares. Identification dots (radius 0.3 s) sit in the margin: the first
//! in the margin corner beside the origin, the second (if any) in the top margin
//! above the second inner-corner column.

use nalgebra::Point2;

/// What a point of a board shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ink {
    Black,
    White,
}

/// Geometry of one printed board.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoardLayout {
    pub inner_corners: [u32; 2],
    pub square_mm: f64,
    pub id_dots: u8,
}

impl BoardLayout {
    /// The inner corners in the board frame, row by row (OpenCV's object points), mm.
    pub fn corners_in_board_mm(&self) -> Vec<Point2<f64>> {
        let [cols, rows] = self.inner_corners;
        (0..rows)
            .flat_map(|j| (0..cols).map(move |i| (i, j)))
            .map(|(i, j)| Point2::new(i as f64 * self.square_mm, j as f64 * self.square_mm))
            .collect()
    }

    /// Outer edge of the paper (margin included): `[x_min, y_min, x_max, y_max]`, mm.
    pub fn paper_bounds_mm(&self) -> [f64; 4] {
        let s = self.square_mm;
        [
            -2.0 * s,
            -2.0 * s,
            (self.inner_corners[0] as f64 + 1.0) * s,
            (self.inner_corners[1] as f64 + 1.0) * s,
        ]
    }

    /// Centres of the identification dots present on this board, mm.
    pub fn dot_centres_mm(&self) -> Vec<Point2<f64>> {
        Self::dot_slots_mm(self.square_mm)
            .into_iter()
            .take(self.id_dots as usize)
            .collect()
    }

    /// Where the first and second dot would be, whether printed or not.
    pub fn dot_slots_mm(square_mm: f64) -> [Point2<f64>; 2] {
        let s = square_mm;
        [Point2::new(-1.5 * s, -1.5 * s), Point2::new(1.0 * s, -1.5 * s)]
    }

    pub fn dot_radius_mm(&self) -> f64 {
        0.3 * self.square_mm
    }

    /// What is printed at a board point, or `None` off the paper.
    pub fn ink_at(&self, x_mm: f64, y_mm: f64) -> Option<Ink> {
        let [x0, y0, x1, y1] = self.paper_bounds_mm();
        if x_mm < x0 || y_mm < y0 || x_mm >= x1 || y_mm >= y1 {
            return None;
        }
        let s = self.square_mm;
        let inside_squares = x_mm >= -s && y_mm >= -s && x_mm < x1 - s && y_mm < y1 - s;
        if inside_squares {
            let i = ((x_mm + s) / s).floor() as i64;
            let j = ((y_mm + s) / s).floor() as i64;
            return Some(if (i + j) % 2 == 0 { Ink::Black } else { Ink::White });
        }
        let r2 = self.dot_radius_mm().powi(2);
        let on_dot = self
            .dot_centres_mm()
            .iter()
            .any(|c| (x_mm - c.x).powi(2) + (y_mm - c.y).powi(2) <= r2);
        Some(if on_dot { Ink::Black } else { Ink::White })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_has_black_origin_square_white_margin_and_dots() {
        let b = BoardLayout {
            inner_corners: [10, 10],
            square_mm: 13.0,
            id_dots: 2,
        };
        assert_eq!(b.ink_at(-6.5, -6.5), Some(Ink::Black));
        assert_eq!(b.ink_at(6.5, -6.5), Some(Ink::White));
        assert_eq!(b.ink_at(-19.5, -19.5), Some(Ink::Black), "first dot");
        assert_eq!(b.ink_at(13.0, -19.5), Some(Ink::Black), "second dot");
        assert_eq!(b.ink_at(-19.5, 50.0), Some(Ink::White), "margin");
        assert_eq!(b.ink_at(-30.0, 0.0), None);
        let one = BoardLayout { id_dots: 1, ..b };
        assert_eq!(one.ink_at(13.0, -19.5), Some(Ink::White));
        assert_eq!(b.corners_in_board_mm().len(), 100);
        assert_eq!(b.corners_in_board_mm()[11], Point2::new(13.0, 13.0));
    }
}
