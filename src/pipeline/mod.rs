//! The stages chained: a manifest's datasets run end to end.
pub mod run;
pub mod settings;
pub mod study;
pub mod tracked;
