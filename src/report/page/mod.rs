//! What a run's page is made of, whatever the run: its context ([`context`],
//! `context_rows`) rendered to HTML and LaTeX ([`render`]), the figures drawn
//! with plotters ([`figures`]), the B-scan gallery ([`gallery`]), the per-frame
//! tables and the page's files (`write`), and the provenance block.

pub mod context;
mod context_rows;
pub mod figures;
pub mod gallery;
pub mod provenance;
pub mod render;
pub mod write;
