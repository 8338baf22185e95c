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

/// An ArUco grid board: `markers[0] x markers[1]` markers of side `marker_mm`,
/// `separation_mm` apart, ids `first_id..` row by row from the top-left. Board
/// frame: origin on the top-left corner of the first marker, x right, y down
/// (OpenCV 4.6's convention), z into the board. A white margin of half a marker
/// surrounds the grid.
#[derive(Debug, Clone, PartialEq)]
pub struct ArucoLayout {
    pub dictionary: String,
    pub markers: [u32; 2],
    pub marker_mm: f64,
    pub separation_mm: f64,
    pub first_id: u32,
    /// Cells per marker side, border included.
    pub cells_side: usize,
    /// Per marker (in id order), its cells row by row, `true` = black.
    pub cells: Vec<Vec<bool>>,
}

impl ArucoLayout {
    /// Builds the layout, reading the marker patterns from OpenCV's dictionary.
    pub fn new(
        dictionary: &str,
        markers: [u32; 2],
        marker_mm: f64,
        separation_mm: f64,
        first_id: u32,
    ) -> Result<ArucoLayout, crate::detect::aruco::ArucoError> {
        let dict = crate::detect::aruco::predefined(dictionary)?;
        let mut cells = Vec::new();
        let mut side = 0;
        for k in 0..markers[0] * markers[1] {
            let (s, c) = crate::detect::aruco::marker_cells(&dict, (first_id + k) as i32)?;
            side = s;
            cells.push(c);
        }
        Ok(ArucoLayout {
            dictionary: dictionary.to_string(),
            markers,
            marker_mm,
            separation_mm,
            first_id,
            cells_side: side,
            cells,
        })
    }

    pub fn pitch_mm(&self) -> f64 {
        self.marker_mm + self.separation_mm
    }

    /// Width and height of the marker grid, mm.
    pub fn span_mm(&self) -> [f64; 2] {
        [0, 1].map(|i| self.markers[i] as f64 * self.marker_mm + (self.markers[i] as f64 - 1.0) * self.separation_mm)
    }

    pub fn ids(&self) -> std::ops::Range<u32> {
        self.first_id..self.first_id + self.markers[0] * self.markers[1]
    }

    /// The four corners (clockwise from top-left, as OpenCV reports them) of a marker id.
    pub fn marker_corners_mm(&self, id: u32) -> Option<[Point2<f64>; 4]> {
        if !self.ids().contains(&id) {
            return None;
        }
        let k = id - self.first_id;
        let (x, y) = (
            (k % self.markers[0]) as f64 * self.pitch_mm(),
            (k / self.markers[0]) as f64 * self.pitch_mm(),
        );
        let l = self.marker_mm;
        Some([
            Point2::new(x, y),
            Point2::new(x + l, y),
            Point2::new(x + l, y + l),
            Point2::new(x, y + l),
        ])
    }

    fn margin_mm(&self) -> f64 {
        (0.5 * self.marker_mm).max(self.separation_mm)
    }

    pub fn paper_bounds_mm(&self) -> [f64; 4] {
        let m = self.margin_mm();
        let [w, h] = self.span_mm();
        [-m, -m, w + m, h + m]
    }

    pub fn ink_at(&self, x_mm: f64, y_mm: f64) -> Option<Ink> {
        let [x0, y0, x1, y1] = self.paper_bounds_mm();
        if x_mm < x0 || y_mm < y0 || x_mm >= x1 || y_mm >= y1 {
            return None;
        }
        let p = self.pitch_mm();
        let (mx, my) = ((x_mm / p).floor(), (y_mm / p).floor());
        if mx < 0.0 || my < 0.0 || mx >= self.markers[0] as f64 || my >= self.markers[1] as f64 {
            return Some(Ink::White);
        }
        let (lx, ly) = (x_mm - mx * p, y_mm - my * p);
        if lx >= self.marker_mm || ly >= self.marker_mm {
            return Some(Ink::White);
        }
        let cell = self.marker_mm / self.cells_side as f64;
        let (cx, cy) = ((lx / cell) as usize, (ly / cell) as usize);
        let k = my as usize * self.markers[0] as usize + mx as usize;
        let black = self.cells[k][cy.min(self.cells_side - 1) * self.cells_side + cx.min(self.cells_side - 1)];
        Some(if black { Ink::Black } else { Ink::White })
    }
}

/// A ChArUco board as OpenCV 4.6's `CharucoBoard` lays it out and draws it:
/// `squares[0] x squares[1]` squares of `square_mm`, square (i, j) (column,
/// row from the top-left) black when `i + j` is even, a marker of `marker_mm`
/// centred in every white square, ids `first_id..` row by row from the top.
/// Board frame: origin on the board's top-left corner, x right, y down, z into
/// the board; the chessboard corners are the inner corners
/// `((i + 1) s, (j + 1) s)`, row by row (OpenCV's corner ids). A white margin of
/// half a square surrounds the squares.
#[derive(Debug, Clone, PartialEq)]
pub struct CharucoLayout {
    /// OpenCV's dictionary name or a dictionary file.
    pub dictionary: String,
    pub squares: [u32; 2],
    pub square_mm: f64,
    pub marker_mm: f64,
    pub first_id: u32,
    /// Cells per marker side, border included.
    pub cells_side: usize,
    /// Per marker (board order), its cells row by row, `true` = black.
    pub cells: Vec<Vec<bool>>,
}

impl CharucoLayout {
    /// Builds the layout, reading the marker patterns from the dictionary.
    pub fn new(board: &crate::spec::rig::CharucoBoard) -> Result<CharucoLayout, crate::detect::aruco::ArucoError> {
        let dict = crate::detect::aruco::dictionary(&board.dictionary)?;
        let mut cells = Vec::new();
        let mut side = 0;
        for k in 0..board.markers() {
            let (s, c) = crate::detect::aruco::marker_cells(&dict, (board.first_id + k) as i32)?;
            side = s;
            cells.push(c);
        }
        Ok(CharucoLayout {
            dictionary: board.dictionary.clone(),
            squares: board.squares,
            square_mm: board.square_mm,
            marker_mm: board.marker_mm,
            first_id: board.first_id,
            cells_side: side,
            cells,
        })
    }

    pub fn markers(&self) -> u32 {
        self.squares[0] * self.squares[1] / 2
    }

    pub fn ids(&self) -> std::ops::Range<u32> {
        self.first_id..self.first_id + self.markers()
    }

    /// The chessboard corners in corner-id order, mm.
    pub fn corners_mm(&self) -> Vec<Point2<f64>> {
        let [x, y] = self.squares;
        let s = self.square_mm;
        (1..y)
            .flat_map(|j| (1..x).map(move |i| Point2::new(i as f64 * s, j as f64 * s)))
            .collect()
    }

    pub fn paper_bounds_mm(&self) -> [f64; 4] {
        let m = 0.5 * self.square_mm;
        [
            -m,
            -m,
            self.squares[0] as f64 * self.square_mm + m,
            self.squares[1] as f64 * self.square_mm + m,
        ]
    }

    pub fn ink_at(&self, x_mm: f64, y_mm: f64) -> Option<Ink> {
        let [x0, y0, x1, y1] = self.paper_bounds_mm();
        if x_mm < x0 || y_mm < y0 || x_mm >= x1 || y_mm >= y1 {
            return None;
        }
        let s = self.square_mm;
        let (i, j) = ((x_mm / s).floor(), (y_mm / s).floor());
        if i < 0.0 || j < 0.0 || i >= self.squares[0] as f64 || j >= self.squares[1] as f64 {
            return Some(Ink::White);
        }
        let (i, j) = (i as usize, j as usize);
        if (i + j) % 2 == 0 {
            return Some(Ink::Black);
        }
        // The white square's marker: markers are counted over the white squares row by row.
        let columns = self.squares[0] as usize;
        let k = (j * columns + i) / 2;
        let inset = (s - self.marker_mm) / 2.0;
        let (lx, ly) = (x_mm - i as f64 * s - inset, y_mm - j as f64 * s - inset);
        if lx < 0.0 || ly < 0.0 || lx >= self.marker_mm || ly >= self.marker_mm {
            return Some(Ink::White);
        }
        let cell = self.marker_mm / self.cells_side as f64;
        let (cx, cy) = ((lx / cell) as usize, (ly / cell) as usize);
        let last = self.cells_side - 1;
        let black = self.cells[k][cy.min(last) * self.cells_side + cx.min(last)];
        Some(if black { Ink::Black } else { Ink::White })
    }
}

/// A printed board of either kind.
#[derive(Debug, Clone, PartialEq)]
pub enum PrintedBoard {
    Checkerboard(BoardLayout),
    Aruco(ArucoLayout),
    Charuco(CharucoLayout),
}

impl PrintedBoard {
    pub fn ink_at(&self, x_mm: f64, y_mm: f64) -> Option<Ink> {
        match self {
            PrintedBoard::Checkerboard(b) => b.ink_at(x_mm, y_mm),
            PrintedBoard::Aruco(b) => b.ink_at(x_mm, y_mm),
            PrintedBoard::Charuco(b) => b.ink_at(x_mm, y_mm),
        }
    }

    pub fn paper_bounds_mm(&self) -> [f64; 4] {
        match self {
            PrintedBoard::Checkerboard(b) => b.paper_bounds_mm(),
            PrintedBoard::Aruco(b) => b.paper_bounds_mm(),
            PrintedBoard::Charuco(b) => b.paper_bounds_mm(),
        }
    }

    /// The points a pose is measured from, in the board frame (mm): the inner
    /// corners of a checkerboard, every marker's four corners of an ArUco board,
    /// the chessboard corners of a ChArUco board.
    pub fn feature_points_mm(&self) -> Vec<Point2<f64>> {
        match self {
            PrintedBoard::Checkerboard(b) => b.corners_in_board_mm(),
            PrintedBoard::Aruco(b) => b.ids().filter_map(|id| b.marker_corners_mm(id)).flatten().collect(),
            PrintedBoard::Charuco(b) => b.corners_mm(),
        }
    }

    /// Centre of the pattern in the board frame: where the board is mounted by.
    pub fn centre_mm(&self) -> Point2<f64> {
        match self {
            PrintedBoard::Checkerboard(b) => Point2::new(
                (b.inner_corners[0] as f64 - 1.0) * b.square_mm / 2.0,
                (b.inner_corners[1] as f64 - 1.0) * b.square_mm / 2.0,
            ),
            PrintedBoard::Aruco(b) => {
                let [w, h] = b.span_mm();
                Point2::new(w / 2.0, h / 2.0)
            }
            PrintedBoard::Charuco(b) => Point2::new(
                b.squares[0] as f64 * b.square_mm / 2.0,
                b.squares[1] as f64 * b.square_mm / 2.0,
            ),
        }
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

    #[test]
    fn aruco_layout_prints_opencvs_markers_where_their_corners_are() {
        let b = ArucoLayout::new("DICT_4X4_50", [4, 4], 30.0, 8.0, 16).unwrap();
        assert_eq!(b.cells_side, 6);
        assert_eq!(b.span_mm(), [144.0, 144.0]);
        assert_eq!(b.ids(), 16..32);
        let c = b.marker_corners_mm(21).unwrap();
        assert_eq!(c[0], Point2::new(38.0, 38.0));
        // The border cells are black, the separation and margin white.
        assert_eq!(b.ink_at(39.0, 39.0), Some(Ink::Black));
        assert_eq!(b.ink_at(36.0, 50.0), Some(Ink::White));
        assert_eq!(b.ink_at(-10.0, -10.0), Some(Ink::White));
        assert_eq!(b.ink_at(-16.0, 0.0), None);
        assert!(b.marker_corners_mm(15).is_none());
        let printed = PrintedBoard::Aruco(b);
        assert_eq!(printed.centre_mm(), Point2::new(72.0, 72.0));
    }

    #[test]
    fn charuco_layout_prints_what_opencv_draws() {
        use opencv::prelude::*;
        // 5x7 squares of 100 px: every square, marker and cell edge on a pixel edge.
        let spec = crate::spec::rig::CharucoBoard {
            squares: [5, 7],
            square_mm: 10.0,
            marker_mm: 6.0,
            dictionary: "DICT_4X4_50".into(),
            first_id: 0,
        };
        let layout = CharucoLayout::new(&spec).unwrap();
        let (_, mut board) = crate::detect::charuco_calibration::CharucoSpec {
            squares: spec.squares,
            square_mm: spec.square_mm,
            marker_mm: spec.marker_mm,
            dictionary: spec.dictionary.clone(),
        }
        .board()
        .unwrap();
        let mut drawn = opencv::core::Mat::default();
        board.draw(opencv::core::Size::new(500, 700), &mut drawn, 0, 1).unwrap();
        let mut differ = 0;
        for y in 0..700 {
            for x in 0..500 {
                let ink = layout.ink_at((x as f64 + 0.5) / 10.0, (y as f64 + 0.5) / 10.0).unwrap();
                let black = *drawn.at_2d::<u8>(y, x).unwrap() < 128;
                differ += usize::from(black != (ink == Ink::Black));
            }
        }
        assert_eq!(differ, 0, "pixels that differ from OpenCV's drawing");
        // OpenCV's corner ids and marker ids, row by row.
        assert_eq!(layout.corners_mm().len(), 24);
        assert_eq!(layout.corners_mm()[5], Point2::new(20.0, 20.0));
        assert_eq!(board.chessboard_corners().get(5).unwrap().x, 20.0);
        assert_eq!(layout.ids(), 0..17);
        let moved = CharucoLayout::new(&crate::spec::rig::CharucoBoard { first_id: 17, ..spec }).unwrap();
        assert_eq!(moved.ids(), 17..34);
        assert_ne!(moved.cells[0], layout.cells[0], "marker 17 is printed, not marker 0");
        assert_eq!(PrintedBoard::Charuco(layout).centre_mm(), Point2::new(25.0, 35.0));
    }
}
