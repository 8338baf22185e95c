//! The pages of the PLUS tools' counterparts: `probecal segment` ([`segment`]),
//! `probecal temporal` ([`temporal`]) and `probecal selfcal` ([`selfcal`]).

pub mod segment;
pub mod selfcal;
pub mod selfcal_overlay;
pub mod temporal;
