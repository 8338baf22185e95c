//! Bounds on a PLUS XML file before it is parsed, and checks of the device
//! set's values that PLUS itself takes on trust: every transform defined once,
//! affine, and rigid where it is used as a rigid one; wire coordinates and the
//! clip rectangle within physical ranges.

use std::path::Path;

use nalgebra::Matrix4;

use super::config_types::{ConfigError, FixedTransform};

/// Largest PLUS XML file read (a device set is kilobytes; a calibration result
/// listing every frame's dots a megabyte).
pub const MAX_XML_BYTES: u64 = 64 << 20;

/// Deepest element nesting accepted (a device set nests about six deep).
pub const MAX_XML_DEPTH: usize = 256;

/// Largest wire coordinate, mm: a phantom is smaller than two metres.
pub const MAX_WIRE_COORDINATE_MM: f64 = 2000.0;

/// Largest clip rectangle coordinate or size, px.
pub const MAX_CLIP_PX: f64 = 65_535.0;

/// A rigid transform's axes: unit length and square to each other within this.
const RIGID_TOLERANCE: f64 = 1e-3;

/// The deepest element nesting of `text`, counted from its tags without
/// parsing it (comments, CDATA, processing instructions and declarations
/// skipped; quoted attribute values may hold `>`); stops counting past `limit`.
pub fn nesting_depth(text: &str, limit: usize) -> usize {
    let bytes = text.as_bytes();
    let (mut depth, mut deepest, mut i) = (0usize, 0usize, 0usize);
    let skip_to = |from: usize, end: &str| {
        text[from..]
            .find(end)
            .map(|p| from + p + end.len())
            .unwrap_or(bytes.len())
    };
    while i < bytes.len() {
        if bytes[i] != b'<' {
            i += 1;
            continue;
        }
        let rest = &text[i..];
        if rest.starts_with("<!--") {
            i = skip_to(i, "-->");
        } else if rest.starts_with("<![CDATA[") {
            i = skip_to(i, "]]>");
        } else if rest.starts_with("<?") {
            i = skip_to(i, "?>");
        } else if rest.starts_with("<!") {
            i = skip_to(i, ">");
        } else if rest.starts_with("</") {
            depth = depth.saturating_sub(1);
            i = skip_to(i, ">");
        } else {
            // An opening tag: find its end outside quotes; `/>` closes it too.
            let mut j = i + 1;
            let mut quote = None;
            while j < bytes.len() {
                match (quote, bytes[j]) {
                    (None, b'"' | b'\'') => quote = Some(bytes[j]),
                    (Some(q), c) if c == q => quote = None,
                    (None, b'>') => break,
                    _ => {}
                }
                j += 1;
            }
            if j > i + 1 && bytes[j.min(bytes.len() - 1)] == b'>' && bytes[j - 1] != b'/' {
                depth += 1;
                deepest = deepest.max(depth);
                if deepest > limit {
                    return deepest;
                }
            }
            i = j + 1;
        }
    }
    deepest
}

/// Refuses a file too large or nested too deep to be a PLUS XML file, before
/// it is parsed (a parser recursing per level would overflow its stack).
pub fn check_size_and_depth(path: &Path, text: &str) -> Result<(), ConfigError> {
    let fail = |message: String| ConfigError {
        path: path.to_path_buf(),
        line: None,
        message,
    };
    if text.len() as u64 > MAX_XML_BYTES {
        return Err(fail(format!(
            "{} bytes: larger than any PLUS XML file probecal reads ({MAX_XML_BYTES} bytes)",
            text.len()
        )));
    }
    let depth = nesting_depth(text, MAX_XML_DEPTH);
    if depth > MAX_XML_DEPTH {
        return Err(fail(format!(
            "elements nested more than {MAX_XML_DEPTH} deep: not a PLUS XML file"
        )));
    }
    Ok(())
}

/// Every transform defined once (a pair and its inverse count as one), with
/// the last row `0 0 0 1` and an invertible 3x3 part.
pub fn check_transforms(path: &Path, transforms: &[FixedTransform]) -> Result<(), ConfigError> {
    let fail = |line: usize, message: String| ConfigError {
        path: path.to_path_buf(),
        line: Some(line),
        message,
    };
    for (i, t) in transforms.iter().enumerate() {
        if let Some(first) = transforms[..i]
            .iter()
            .find(|e| (e.from == t.from && e.to == t.to) || (e.from == t.to && e.to == t.from))
        {
            return Err(fail(
                t.line,
                format!(
                    "transform {}To{} is defined again (first as {}To{} on line {}); which one counts would be a guess",
                    t.from, t.to, first.from, first.to, first.line
                ),
            ));
        }
        if let Some(why) = affine_fault(&t.matrix) {
            return Err(fail(t.line, format!("transform {}To{}: {why}", t.from, t.to)));
        }
    }
    Ok(())
}

/// Why `matrix` is not rigid (a rotation and a translation), if it is not:
/// its axes' lengths and the largest departure from square, against the limit.
/// Why `matrix` is not a usable affine transform (the one check of every
/// reader of an `ImageToProbe` and of a device set's transforms): a value not
/// finite, a last row other than 0 0 0 1 (projective), or a singular 3x3 part
/// (all zero, or flattening space onto a plane).
pub fn affine_fault(matrix: &Matrix4<f64>) -> Option<String> {
    if matrix.iter().any(|v| !v.is_finite()) {
        return Some("a value is not a finite number".into());
    }
    let last = [matrix[(3, 0)], matrix[(3, 1)], matrix[(3, 2)], matrix[(3, 3)]];
    if last != [0.0, 0.0, 0.0, 1.0] {
        return Some(format!("the last row is {last:?}, not 0 0 0 1"));
    }
    let det = matrix.fixed_view::<3, 3>(0, 0).determinant();
    if !(det.is_finite() && det.abs() > 1e-12) {
        return Some(format!("it is singular (determinant {det:e})"));
    }
    None
}

pub fn rigid_fault(matrix: &Matrix4<f64>) -> Option<String> {
    let r = matrix.fixed_view::<3, 3>(0, 0);
    let departure = (r.transpose() * r - nalgebra::Matrix3::identity()).abs().max();
    if departure <= RIGID_TOLERANCE && r.determinant() > 0.0 {
        return None;
    }
    let lengths: Vec<String> = (0..3).map(|c| format!("{:.4}", r.column(c).norm())).collect();
    Some(format!(
        "not rigid: its axes are {} long (RᵀR departs from I by {departure:.4}, limit {RIGID_TOLERANCE}){}",
        lengths.join(", "),
        if r.determinant() < 0.0 { ", and it mirrors" } else { "" }
    ))
}

/// A wire end within [`MAX_WIRE_COORDINATE_MM`] of the phantom's origin.
pub fn wire_end_fault(end: &[f64]) -> Option<String> {
    end.iter()
        .any(|v| v.abs() > MAX_WIRE_COORDINATE_MM)
        .then(|| format!("a wire end at {end:?} mm is beyond ±{MAX_WIRE_COORDINATE_MM} mm of the phantom's origin"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn depth_is_counted_from_tags() {
        assert_eq!(nesting_depth("<a><b/><c x=\"1>2\"><d></d></c></a>", 100), 3);
        assert_eq!(
            nesting_depth("<?xml version=\"1.0\"?><!-- <x><y> --><a><![CDATA[<b><c>]]></a>", 100),
            1
        );
        let deep = "<a>".repeat(5000) + &"</a>".repeat(5000);
        assert_eq!(nesting_depth(&deep, 300), 301, "stops past the limit");
        assert!(check_size_and_depth(Path::new("d.xml"), &deep)
            .unwrap_err()
            .to_string()
            .starts_with("d.xml: elements nested more than 256 deep"));
    }

    #[test]
    fn rigid_transforms_are_told_from_scaled_and_mirrored_ones() {
        let mut m = Matrix4::new_rotation(nalgebra::Vector3::new(0.3, -0.2, 0.1));
        m[(0, 3)] = 12.0;
        assert_eq!(rigid_fault(&m), None);
        let scaled = m * Matrix4::new_scaling(2.0);
        let mut fixed = scaled;
        fixed[(3, 3)] = 1.0;
        let why = rigid_fault(&fixed).unwrap();
        assert!(why.contains("2.0000, 2.0000, 2.0000"), "{why}");
        let mirrored = Matrix4::from_diagonal(&nalgebra::Vector4::new(1.0, 1.0, -1.0, 1.0));
        assert!(rigid_fault(&mirrored).unwrap().contains("mirrors"));
    }
}
