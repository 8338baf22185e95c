//! PLUS's `UltrasoundImageOrientation` and the flip of an image to MF.

/// PLUS's `UltrasoundImageOrientation`: which way the image's columns run
/// (M: the probe's marked side at column 0; U: unmarked) and its rows (F: far
/// from the transducer at the last row, so depth grows downwards; N: near).
/// A third letter (the volume's slice axis) does not change a 2D frame.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Orientation {
    #[default]
    Mf,
    Mn,
    Uf,
    Un,
}

impl Orientation {
    pub fn parse(text: &str) -> Option<Orientation> {
        let t = text.trim().to_ascii_uppercase();
        if !(t.len() == 2 || t.len() == 3) || !t.is_ascii() {
            return None;
        }
        match &t[..2] {
            "MF" => Some(Orientation::Mf),
            "MN" => Some(Orientation::Mn),
            "UF" => Some(Orientation::Uf),
            "UN" => Some(Orientation::Un),
            _ => None,
        }
    }

    /// Flips every `width` x `height` frame of `pixels` in place so that it reads MF.
    pub fn flip_to_mf<T>(self, pixels: &mut [T], width: usize, height: usize) {
        let (columns, rows) = match self {
            Orientation::Mf => (false, false),
            Orientation::Mn => (false, true),
            Orientation::Uf => (true, false),
            Orientation::Un => (true, true),
        };
        let size = width * height;
        if size == 0 {
            return;
        }
        for frame in pixels.chunks_exact_mut(size) {
            if columns {
                for row in frame.chunks_exact_mut(width) {
                    row.reverse();
                }
            }
            if rows {
                for v in 0..height / 2 {
                    let (top, bottom) = frame.split_at_mut((height - 1 - v) * width);
                    top[v * width..(v + 1) * width].swap_with_slice(&mut bottom[..width]);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_orientation_flips_to_mf_and_others_are_refused() {
        // Two frames of 3x2: columns 0..3, rows 0..2.
        let frame = [1u8, 2, 3, 4, 5, 6];
        let flipped = |o: Orientation| {
            let mut p = [frame, frame].concat();
            o.flip_to_mf(&mut p, 3, 2);
            assert_eq!(p[..6], p[6..], "{o:?}: frames flipped alike");
            p[..6].to_vec()
        };
        assert_eq!(flipped(Orientation::Mf), vec![1, 2, 3, 4, 5, 6]);
        assert_eq!(flipped(Orientation::Uf), vec![3, 2, 1, 6, 5, 4]);
        assert_eq!(flipped(Orientation::Mn), vec![4, 5, 6, 1, 2, 3]);
        assert_eq!(flipped(Orientation::Un), vec![6, 5, 4, 3, 2, 1]);
        for (text, want) in [
            ("MFA", Some(Orientation::Mf)),
            ("un", Some(Orientation::Un)),
            ("UNA", Some(Orientation::Un)),
            ("MX", None),
            ("M", None),
            ("MFAA", None),
        ] {
            assert_eq!(Orientation::parse(text), want, "{text}");
        }
    }
}
