//! The calibration as files other tools load: PLUS's `CoordinateDefinitions`
//! transform, an ITK transform file for 3D Slicer, and the tracker's lag as
//! PLUS's device setting with a note for tools that have none.

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

/// The tracker's lag as PLUS's device setting, with the note beside the
/// `.tfm` (`TrackerLag.xml`): PLUS puts a device's sample stamped `local` at
/// `global = local + LocalTimeOffsetSec`; a tracker that lags the images by
/// `lag` stamps the probe's pose at time `t` as `t + lag`, so its
/// `LocalTimeOffsetSec` is `-lag` (or, equally, the video device's is `+lag`).
pub fn tracker_lag_xml(lag_s: f64, how: &str) -> String {
    format!(
        "<!-- The tracker lags the images by {lag:+.6} s ({ms:+.1} ms): {how}.\n\
         \x20    ImageToProbe.xml was fitted with each image's poses read at its time plus this lag,\n\
         \x20    so apply both together. PLUS puts a device's sample stamped `local` at\n\
         \x20    global = local + LocalTimeOffsetSec: give the tracker's <Device> element\n\
         \x20    LocalTimeOffsetSec=\"{tracker:.6}\" (or the video device's {video:.6}) in the\n\
         \x20    device set PlusServer runs with. 3D Slicer's ImageToProbe.tfm holds no time:\n\
         \x20    a recording replayed there needs its tracker shifted by the lag the same way. -->\n\
         <Device LocalTimeOffsetSec=\"{tracker:.6}\" />\n",
        lag = lag_s,
        ms = lag_s * 1000.0,
        how = how.replace("--", "- -"),
        tracker = -lag_s + 0.0,
        video = lag_s,
    )
}
