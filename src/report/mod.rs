//! Results into pages and files: the typed results model ([`summary`]), the run
//! page's context ([`context`]) rendered to HTML and LaTeX ([`render`]), figures,
//! the B-scan gallery, the per-frame tables ([`write`]), the comparison, the
//! thesis chapter, the index, the regression gate ([`check`]) and provenance.

pub mod ablation;
pub mod baseline;
pub mod chapter_table;
pub mod check;
pub mod compare;
pub mod console;
pub mod context;
mod context_rows;
pub mod design;
pub mod error;
pub mod figures;
pub mod gallery;
pub mod index;
pub mod live;
pub mod live_folder;
pub mod live_igtl;
pub mod live_timing;
pub mod phantom;
pub mod provenance;
pub mod reconstruct;
pub mod render;
pub mod resolve;
pub mod rig_comparison;
pub mod segment;
pub mod study;
pub mod study_compare;
pub mod summary;
pub mod templating;
pub mod temporal;
pub mod thesis;
pub mod tracked;
pub mod tracked_figures;
pub mod tracked_gallery;
pub mod tracked_lag;
pub mod tracked_summary;
pub mod tracked_volume;
mod transform_files;
pub mod write;
pub mod writer;
