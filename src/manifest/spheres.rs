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

/// The options of the multi-sphere fits (`solve.sphere_fit.pose_prior`,
/// `fit_pixel_size`): positive values, and a `spheres` phantom to fit.
pub(super) fn fit_options(c: &mut Checker<'_>, raw: &raw::RawManifest) {
    if let Some(prior) = &raw.solve.sphere_fit.pose_prior {
        let f = "solve.sphere_fit.pose_prior";
        c.positive(&format!("{f}.hand.speed_mm_per_s"), prior.hand.speed_mm_per_s);
        c.positive(&format!("{f}.hand.rotation_deg_per_s"), prior.hand.rotation_deg_per_s);
        c.positive(&format!("{f}.asynchrony_sd_s"), prior.asynchrony_sd_s);
        if let Some(blur) = &prior.slice_blur {
            c.positive(&format!("{f}.slice_blur.axial_sd_mm"), blur.axial_sd_mm);
            c.positive(&format!("{f}.slice_blur.elevation_sd_mm"), blur.elevation_sd_mm);
        }
    }
    let multi_sphere_only = [
        (
            "pose_prior",
            "the pose prior",
            raw.solve.sphere_fit.pose_prior.is_some(),
        ),
        (
            "fit_pixel_size",
            "the fitted pixel size",
            raw.solve.sphere_fit.fit_pixel_size,
        ),
    ];
    for (field, what, set) in multi_sphere_only {
        if set && !matches!(raw.phantom, crate::spec::phantom::Phantom::Spheres { .. }) {
            let message = format!("{what} belongs to the multi-sphere fit: `phantom: spheres:` only");
            c.fail(&format!("solve.sphere_fit.{field}"), message);
        }
    }
}
