//! What reads a folder of finished runs back: the index of a reports folder
//! ([`index`]), the regression gate against a baseline ([`check`], [`baseline`])
//! and `probecal resolve` ([`resolve`]).

pub mod baseline;
pub mod check;
pub mod index;
pub mod resolve;
