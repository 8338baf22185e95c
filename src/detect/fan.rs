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

#[cfg(test)]
mod tests {
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
