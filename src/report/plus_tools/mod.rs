//! The pages of the PLUS tools' counterparts: `probecal segment` ([`segment`])
//! and `probecal temporal` ([`temporal`]).

pub mod segment;
pub mod temporal;
