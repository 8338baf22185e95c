//! The run page's templates to pages: the tera set (compiled into the binary)
//! and the HTML and LaTeX run pages.

use crate::report::error::OutputError;
use crate::report::page::context::RunContext;
pub use crate::report::templating::{error_chain, register_font, register_tex_filter, tex_escape, FIGURE_FONT};

const RUN_TEMPLATE: &str = include_str!("../../../templates/run.html.tera");
pub(in crate::report) const INDEX_TEMPLATE: &str = include_str!("../../../templates/index.html.tera");

pub(in crate::report) fn tera() -> Result<tera::Tera, tera::Error> {
    let mut t = tera::Tera::default();
    t.add_raw_templates(vec![
        ("run.html", RUN_TEMPLATE),
        ("index.html", INDEX_TEMPLATE),
        ("run.tex", RUN_TEX_TEMPLATE),
    ])?;
    register_tex_filter(&mut t);
    Ok(t)
}

const RUN_TEX_TEMPLATE: &str = include_str!("../../../templates/run.tex.tera");

/// The run's report as LaTeX (its figure, `bre_per_frame.png`, is written beside it).
pub fn render_tex(context: &RunContext) -> Result<String, OutputError> {
    let ctx = tera::Context::from_serialize(context)?;
    Ok(tera()?.render("run.tex", &ctx)?)
}

/// The dataset run's HTML page.
/// The page; `gallery_uris` and `figure_svgs` follow `context.gallery` and
/// `context.figures` (kept out of the context's JSON).
pub fn render_html(
    context: &RunContext,
    gallery_uris: &[String],
    figure_svgs: &[String],
) -> Result<String, OutputError> {
    let mut ctx = tera::Context::from_serialize(context)?;
    ctx.insert("gallery_uris", gallery_uris);
    ctx.insert("figure_svgs", figure_svgs);
    Ok(tera()?.render("run.html", &ctx)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Whatever the text, the escaped LaTeX holds no character beyond Latin-1
    /// (the T1 fonts' range), so no description can stop pdflatex.
    #[test]
    fn escaped_text_stays_within_the_fonts() {
        let text = "χ² 99 % of σ = 0.40 mm; αβγ ω µ ≤ ≥ — “quotes” ✓ é";
        let out = tex_escape(text);
        assert!(out.chars().all(|c| (c as u32) <= 0xFF), "{out}");
        assert!(out.contains(r"\ensuremath{\chi}\ensuremath{^2}"), "{out}");
        assert!(
            out.contains(r"\ensuremath{\omega}") && out.contains(r"\texttt{U+2713}"),
            "{out}"
        );
        assert!(out.contains('é'));
    }
}
