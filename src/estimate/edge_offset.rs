//! Where an arc's echo edge sits relative to its sphere: the model the
//! multi-sphere fit (`sphere_bundle`) and its Cramér–Rao bound may
//! solve with the calibration.
//!
//! A B-scan's slice has a thickness (the beam's elevation width). Cut
//! obliquely, a dome meets the slice over a range of depths; the part of the
//! surface that faces the beam most squarely echoes strongest, and the edge the
//! detector finds moves outward the more oblique the cut. The offset is
//! `a + b·(d / R)² + c·d² / (R·r)`, `d` the sphere centre's distance from the
//! plane, `R` its radius and `r = √(R² − d²)` the arc's: `a` a constant (the
//! echo's leading edge, whatever the cut), `b` the obliquity's share, and `c`
//! the slice's: a shift `δz` across the slice moves the cut circle by
//! `−d·δz / r`, and the echo's weight across the slice tilts towards the
//! centre by an amount proportional to `d / R`. None has a prior: each is
//! solved from the arcs, which the domes cut at many offsets.

use super::sphere_fit::KnownSphere;

/// Which of the offset's terms `(a, b, c)` are unknowns of the fit.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum EdgeOffset {
    /// No offset: the edge on the sphere.
    #[default]
    None,
    /// `a` only.
    Constant,
    /// `b` only.
    Obliquity,
    /// `a` and `b`.
    ConstantAndObliquity,
    /// `c` only.
    Slice,
}

pub use super::sphere_fit::{EdgeTerms, TERMS};

impl EdgeOffset {
    /// Every model, as a manifest names it.
    pub const NAMES: [&'static str; 5] = ["none", "constant", "obliquity", "constant_and_obliquity", "slice"];

    /// Which of `(a, b, c)` the model solves.
    fn solves(self) -> [bool; TERMS] {
        match self {
            EdgeOffset::None => [false, false, false],
            EdgeOffset::Constant => [true, false, false],
            EdgeOffset::Obliquity => [false, true, false],
            EdgeOffset::ConstantAndObliquity => [true, true, false],
            EdgeOffset::Slice => [false, false, true],
        }
    }

    /// The model's name, as a manifest names it.
    pub fn name(self) -> &'static str {
        match self {
            EdgeOffset::None => Self::NAMES[0],
            EdgeOffset::Constant => Self::NAMES[1],
            EdgeOffset::Obliquity => Self::NAMES[2],
            EdgeOffset::ConstantAndObliquity => Self::NAMES[3],
            EdgeOffset::Slice => Self::NAMES[4],
        }
    }

    /// How many unknowns the model adds.
    pub fn unknowns(self) -> usize {
        self.solves().iter().filter(|s| **s).count()
    }

    /// The offset's derivative by each unknown for an arc of `sphere` whose
    /// plane lies `elevation_mm` from the centre: 1 for `a`, `(d / R)²` for
    /// `b`, `d² / (R·r)` for `c`.
    pub fn terms(self, sphere: &KnownSphere, elevation_mm: f64) -> Vec<f64> {
        all_terms(sphere, elevation_mm)
            .iter()
            .zip(self.solves())
            .filter(|(_, s)| *s)
            .map(|(t, _)| *t)
            .collect()
    }

    /// `(a, b, c)` from the solved unknowns `free` (the terms not solved are 0).
    pub fn expand(self, free: &[f64]) -> EdgeTerms {
        let mut out = [0.0; TERMS];
        let mut values = free.iter();
        for (o, s) in out.iter_mut().zip(self.solves()) {
            if s {
                *o = values.next().copied().unwrap_or(0.0);
            }
        }
        out
    }
}

/// Each term's factor for an arc of `sphere` whose plane lies `elevation_mm`
/// from the centre: `1`, `(d / R)²`, `d² / (R·r)` (`r` kept above R/20: the
/// detector finds no arc that small).
fn all_terms(sphere: &KnownSphere, elevation_mm: f64) -> EdgeTerms {
    let radius = sphere.radius_mm;
    let squared = (elevation_mm / radius).powi(2);
    let arc_radius = (radius * radius - elevation_mm * elevation_mm)
        .max((0.05 * radius).powi(2))
        .sqrt();
    [1.0, squared, squared * radius / arc_radius]
}

/// The edge's offset outside `sphere`, mm, for a plane `elevation_mm` from its
/// centre, under the offsets `(a, b, c)`.
pub fn offset_mm(offsets: &EdgeTerms, sphere: &KnownSphere, elevation_mm: f64) -> f64 {
    all_terms(sphere, elevation_mm)
        .iter()
        .zip(offsets)
        .map(|(t, o)| t * o)
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Point3;

    const SPHERE: KnownSphere = KnownSphere {
        centre_in_phantom_mm: Point3::new(0.0, 0.0, 0.0),
        radius_mm: 10.0,
    };

    #[test]
    fn each_model_solves_its_own_terms_and_expands_back() {
        // d = 6 mm: (d/R)² = 0.36, r = 8 mm, d²/(R·r) = 0.45.
        for (model, terms, expanded) in [
            (EdgeOffset::None, vec![], [0.0, 0.0, 0.0]),
            (EdgeOffset::Constant, vec![1.0], [0.5, 0.0, 0.0]),
            (EdgeOffset::Obliquity, vec![0.36], [0.0, 0.5, 0.0]),
            (EdgeOffset::ConstantAndObliquity, vec![1.0, 0.36], [0.5, 0.7, 0.0]),
            (EdgeOffset::Slice, vec![0.45], [0.0, 0.0, 0.5]),
        ] {
            let got = model.terms(&SPHERE, 6.0);
            assert_eq!(got.len(), terms.len(), "{model:?}");
            assert!(
                got.iter().zip(&terms).all(|(g, t)| (g - t).abs() < 1e-12),
                "{model:?}: {got:?}"
            );
            assert_eq!(model.unknowns(), terms.len(), "{model:?}");
            assert_eq!(model.expand(&[0.5, 0.7][..model.unknowns()]), expanded, "{model:?}");
        }
    }

    #[test]
    fn the_offset_is_linear_in_its_terms() {
        let o = [0.02, 0.2, 0.1];
        let d = 7.5;
        let t = all_terms(&SPHERE, d);
        assert!((offset_mm(&o, &SPHERE, d) - (o[0] * t[0] + o[1] * t[1] + o[2] * t[2])).abs() < 1e-15);
        assert!((offset_mm(&o, &SPHERE, -d) - offset_mm(&o, &SPHERE, d)).abs() < 1e-15);
        // Past the detector's smallest arc the slice term stays finite.
        assert!(offset_mm(&o, &SPHERE, 10.0).is_finite());
    }

    #[test]
    fn names_are_the_manifest_spelling() {
        for model in [
            EdgeOffset::None,
            EdgeOffset::Constant,
            EdgeOffset::Obliquity,
            EdgeOffset::ConstantAndObliquity,
            EdgeOffset::Slice,
        ] {
            let yaml = format!("{}\n", model.name());
            let back: EdgeOffset = serde_yaml::from_str(&yaml).unwrap();
            assert_eq!(back, model);
        }
    }
}
