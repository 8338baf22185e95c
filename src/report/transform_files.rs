//! The calibration as files other tools load: PLUS's `CoordinateDefinitions`
//! transform and an ITK transform file for 3D Slicer.

use nalgebra::{Matrix3, Matrix4};

/// PLUS's XML form of the result (a `CoordinateDefinitions` transform).
pub fn plus_xml(matrix: &Matrix4<f64>) -> String {
    let mut text = String::from("<CoordinateDefinitions>\n  <Transform From=\"Image\" To=\"Probe\"\n    Matrix=\"\n");
    for r in 0..4 {
        let row: Vec<String> = (0..4).map(|c| format!("{:.9}", matrix[(r, c)])).collect();
        text += &format!("      {}\n", row.join(" "));
    }
    text += "    \" />\n</CoordinateDefinitions>\n";
    text
}

/// An ITK transform file that 3D Slicer loads as the `Calibration` linear transform.
/// ITK files hold the resampling (inverse) transform in LPS; Slicer works in RAS,
/// so the file holds `F * inverse(Calibration) * F` with `F = diag(-1, -1, 1)`.
pub fn itk_tfm(matrix: &Matrix4<f64>) -> Option<String> {
    let inverse = matrix.try_inverse()?;
    let f = Matrix4::from_diagonal(&nalgebra::Vector4::new(-1.0, -1.0, 1.0, 1.0));
    let m = f * inverse * f;
    let a: Matrix3<f64> = m.fixed_view::<3, 3>(0, 0).into_owned();
    let mut params: Vec<String> = Vec::new();
    for r in 0..3 {
        for c in 0..3 {
            params.push(format!("{:.12}", a[(r, c)]));
        }
    }
    for r in 0..3 {
        params.push(format!("{:.12}", m[(r, 3)]));
    }
    Some(format!(
        "#Insight Transform File V1.0\n#Transform 0\nTransform: AffineTransform_double_3_3\nParameters: {}\nFixedParameters: 0 0 0\n",
        params.join(" ")
    ))
}
