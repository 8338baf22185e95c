//! Results into pages and files, from the typed results model
//! ([`crate::results`]), one room per application: what every run page is
//! made of ([`page`]), the camera-rig runs' thesis chapter and comparison
//! ([`thesis`]), tracked recordings ([`tracked`]), live sessions ([`live`]),
//! studies ([`study`]), the PLUS tools' pages ([`plus_tools`]), a reconstruction
//! ([`reconstruct`]) and what reads a folder of runs back ([`runs`]: the index, the
//! regression gate, resolve). [`writer`] writes a run's outputs; [`console`]
//! prints it.

pub mod console;
pub mod error;
pub mod live;
pub mod page;
pub mod plus_tools;
pub mod reconstruct;
pub mod runs;
pub mod study;
pub mod templating;
pub mod thesis;
pub mod tracked;
pub mod writer;
