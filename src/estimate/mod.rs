//! Solving for `marker_T_image`: Horn's closed form, robust estimators over
//! frames, wire matching, Levenberg–Marquardt with pixel scales, the sphere fit.
mod bundle_frame;
pub mod correspondence;
pub mod edge_blur;
pub mod edge_offset;
pub mod horn;
pub mod image_to_probe;
pub mod model_selection;
pub mod robust;
pub mod selfcal;
pub mod sphere_bundle;
pub mod sphere_fit;
pub mod sphere_matching;
pub mod start_basin;
pub mod wire_matching;
