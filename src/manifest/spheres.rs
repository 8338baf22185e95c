//! Validation of a `spheres` phantom.

use super::checker::Checker;
use super::raw;

/// The domes of a `spheres` phantom: finite, positive, apart, at least two, and
/// a rough calibration to tell which arc is which dome.
pub(super) fn check(c: &mut Checker<'_>, raw: &raw::RawManifest, spheres: &[crate::spec::phantom::Sphere]) {
    if !(2..=crate::core::limits::MAX_SPHERES).contains(&spheres.len()) {
        c.fail(
            "phantom.spheres.spheres",
            format!(
                "needs 2 to {} spheres (got {}): one sphere leaves the planes' elevation unobserved",
                crate::core::limits::MAX_SPHERES,
                spheres.len()
            ),
        );
    }
    for (i, s) in spheres.iter().enumerate() {
        let field = format!("phantom.spheres.spheres[{i}]");
        c.finite(&format!("{field}.centre_in_phantom_mm"), &s.centre_in_phantom_mm);
        c.positive(&format!("{field}.radius_mm"), s.radius_mm);
        if spheres[..i].iter().any(|o| o.name == s.name) {
            c.fail(&format!("{field}.name"), format!("`{}` names two spheres", s.name));
        }
        for (j, o) in spheres[..i].iter().enumerate() {
            let gap = (nalgebra::Vector3::from(s.centre_in_phantom_mm)
                - nalgebra::Vector3::from(o.centre_in_phantom_mm))
            .norm()
                - s.radius_mm
                - o.radius_mm;
            if gap.is_nan() || gap < 0.0 {
                c.fail(
                    &format!("{field}.centre_in_phantom_mm"),
                    format!("overlaps spheres[{j}] (`{}`)", o.name),
                );
            }
        }
    }
    if raw.solve.initial_marker_T_image.is_none() {
        c.fail(
            "solve.initial_marker_T_image",
            "the spheres phantom needs a rough marker_T_image to tell which arc is which sphere (rotation_deg, translation_mm)",
        );
    }
}
