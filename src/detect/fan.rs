//! What the B-scan detectors share about the ultrasound fan.

/// Echoes this close below the transducer's face (the near field: ring-down and
/// the face's own reverberation) are not searched.
pub const NEAR_FIELD_MM: f64 = 6.0;
/// Pixels this close to the fan's edge are not searched (the edge is a bright
/// artefact of the scan conversion, not an echo).
pub const FAN_EDGE_MM: f64 = 1.5;

/// The first row of each column of a `width x height` image where `inside(row *
/// width + column)` holds (`None` for a column without one). The image is read
/// row by row, in memory order.
pub fn first_rows(width: usize, height: usize, inside: impl Fn(usize) -> bool) -> Vec<Option<usize>> {
    let mut top = vec![None; width];
    let mut open = width;
    for y in 0..height {
        if open == 0 {
            break;
        }
        for (x, first) in top.iter_mut().enumerate() {
            if first.is_none() && inside(y * width + x) {
                *first = Some(y);
                open -= 1;
            }
        }
    }
    top
}

/// The fan's interior, eroded by `edge_px = [columns, rows]`: pixel `(x, y)` of a
/// `width x height` image is interior when it and the pixels `edge_px` to its
/// left, right, above and below are all inside the fan, none of them off the
/// image. Row-major, like `inside`.
pub fn eroded(width: usize, height: usize, inside: &[bool], edge_px: [usize; 2]) -> Vec<bool> {
    let [ex, ey] = edge_px;
    let mut interior = vec![false; width * height];
    if width <= 2 * ex || height <= 2 * ey || inside.len() != width * height {
        return interior;
    }
    for y in ey..height - ey {
        let row = &inside[y * width..(y + 1) * width];
        let up = &inside[(y - ey) * width..(y - ey + 1) * width];
        let down = &inside[(y + ey) * width..(y + ey + 1) * width];
        let out = &mut interior[y * width..(y + 1) * width];
        for x in ex..width - ex {
            // `&` rather than `&&`: no branches, so the loop vectorises.
            out[x] = row[x] & row[x - ex] & row[x + ex] & up[x] & down[x];
        }
    }
    interior
}

#[cfg(test)]
mod tests {
    #[test]
    fn eroded_is_the_five_point_test() {
        let (w, h) = (23, 17);
        let inside: Vec<bool> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f64, (i / w) as f64);
                (x - 11.0).powi(2) / 100.0 + (y - 3.0).powi(2) / 150.0 < 1.0 && (i * 7919) % 13 != 0
            })
            .collect();
        for edge in [[0, 0], [1, 2], [3, 1], [12, 1], [1, 9]] {
            let [ex, ey] = edge;
            let at = |x: usize, y: usize| inside[y * w + x];
            let slow = |x: usize, y: usize| {
                x >= ex
                    && x + ex < w
                    && y >= ey
                    && y + ey < h
                    && at(x, y)
                    && at(x - ex, y)
                    && at(x + ex, y)
                    && at(x, y - ey)
                    && at(x, y + ey)
            };
            let fast = super::eroded(w, h, &inside, edge);
            for y in 0..h {
                for x in 0..w {
                    assert_eq!(fast[y * w + x], slow(x, y), "edge {edge:?} at ({x}, {y})");
                }
            }
            assert!(
                fast.iter().any(|v| *v) || ex >= 6 || ey >= 8,
                "edge {edge:?}: the test shape has an interior"
            );
        }
    }

    #[test]
    fn first_rows_are_the_columnwise_search() {
        let (w, h) = (7, 5);
        let inside = |i: usize| {
            let (x, y) = (i % w, i / w);
            x != 3 && y * 2 >= x
        };
        let by_column: Vec<Option<usize>> = (0..w).map(|x| (0..h).find(|&y| inside(y * w + x))).collect();
        assert_eq!(super::first_rows(w, h, inside), by_column);
        assert_eq!(by_column[3], None);
    }
}
