//! Templates to pages: the tera set (compiled into the binary), the LaTeX escape
//! filter, the figures' font, and tera's errors with their causes.

use super::context::RunContext;

const RUN_TEMPLATE: &str = include_str!("../../templates/run.html.tera");
pub(super) const INDEX_TEMPLATE: &str = include_str!("../../templates/index.html.tera");

/// Where the bitmap figures' font is read from.
pub const FIGURE_FONT: &str = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";

/// Registers the figures' font once (plotters lays text out with it, SVG included).
pub fn register_font() -> Result<(), String> {
    static FONT: std::sync::OnceLock<Result<(), String>> = std::sync::OnceLock::new();
    FONT.get_or_init(|| {
        let bytes =
            std::fs::read(FIGURE_FONT).map_err(|e| format!("{FIGURE_FONT}: {e} (install fonts-dejavu-core)"))?;
        // The font lives as long as the program: figures are drawn until it ends.
        let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
        plotters::style::register_font("sans-serif", plotters::style::FontStyle::Normal, bytes)
            .map_err(|_| format!("{FIGURE_FONT}: not a TrueType font"))
    })
    .clone()
}

pub(super) fn tera() -> Result<tera::Tera, tera::Error> {
    let mut t = tera::Tera::default();
    t.add_raw_templates(vec![
        ("run.html", RUN_TEMPLATE),
        ("index.html", INDEX_TEMPLATE),
        ("run.tex", RUN_TEX_TEMPLATE),
    ])?;
    register_tex_filter(&mut t);
    Ok(t)
}

/// Adds the `tex` filter ([`tex_escape`]) to a template set.
pub fn register_tex_filter(t: &mut tera::Tera) {
    t.register_filter("tex", tex_filter);
}

const RUN_TEX_TEMPLATE: &str = include_str!("../../templates/run.tex.tera");

/// Text made safe for LaTeX: its special characters escaped, and the symbols the
/// reports use written as LaTeX commands (pdflatex's inputenc lacks most of them).
pub fn tex_escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '\\' => out.push_str("\\textbackslash{}"),
            '{' | '}' | '$' | '&' | '#' | '_' | '%' => {
                out.push('\\');
                out.push(c);
            }
            '^' => out.push_str("\\textasciicircum{}"),
            '~' => out.push_str("\\textasciitilde{}"),
            '<' => out.push_str("\\textless{}"),
            '>' => out.push_str("\\textgreater{}"),
            '°' => out.push_str("\\textdegree{}"),
            '±' => out.push_str("\\ensuremath{\\pm}"),
            '×' => out.push_str("\\ensuremath{\\times}"),
            '·' => out.push_str("\\ensuremath{\\cdot}"),
            '−' => out.push_str("\\ensuremath{-}"),
            '—' => out.push_str("---"),
            '–' => out.push_str("--"),
            '…' => out.push_str("\\ldots{}"),
            '∞' => out.push_str("\\ensuremath{\\infty}"),
            '≈' => out.push_str("\\ensuremath{\\approx}"),
            '≤' => out.push_str("\\ensuremath{\\le}"),
            '≥' => out.push_str("\\ensuremath{\\ge}"),
            '→' => out.push_str("\\ensuremath{\\rightarrow}"),
            '←' => out.push_str("\\ensuremath{\\leftarrow}"),
            'µ' => out.push_str("\\ensuremath{\\mu}"),
            '²' => out.push_str("\\ensuremath{^2}"),
            'ᵀ' => out.push_str("\\ensuremath{^T}"),
            '\'' | '’' => out.push('\''),
            '“' => out.push_str("``"),
            '”' => out.push_str("''"),
            // Greek letters as math; anything else the T1 fonts lack as its code
            // point, so that no text can stop pdflatex.
            _ => match greek(c) {
                Some(name) => out.push_str(&format!("\\ensuremath{{\\{name}}}")),
                None if (c as u32) > 0xFF => out.push_str(&format!("\\texttt{{U+{:04X}}}", c as u32)),
                None => out.push(c),
            },
        }
    }
    out
}

/// A lowercase Greek letter's LaTeX name.
fn greek(c: char) -> Option<&'static str> {
    const NAMES: [&str; 25] = [
        "alpha", "beta", "gamma", "delta", "epsilon", "zeta", "eta", "theta", "iota", "kappa", "lambda", "mu", "nu",
        "xi", "o", "pi", "rho", "varsigma", "sigma", "tau", "upsilon", "phi", "chi", "psi", "omega",
    ];
    let k = (c as u32).checked_sub('α' as u32)? as usize;
    NAMES.get(k).copied().filter(|n| *n != "o")
}

fn tex_filter(value: &tera::Value, _: &std::collections::HashMap<String, tera::Value>) -> tera::Result<tera::Value> {
    let text = match value {
        tera::Value::String(s) => s.clone(),
        other => other.to_string(),
    };
    Ok(tera::Value::String(tex_escape(&text)))
}

/// The run's report as LaTeX (its figure, `bre_per_frame.png`, is written beside it).
pub fn render_tex(context: &RunContext) -> Result<String, String> {
    let ctx = tera::Context::from_serialize(context).map_err(|e| error_chain(&e))?;
    tera()
        .and_then(|t| t.render("run.tex", &ctx))
        .map_err(|e| error_chain(&e))
}

pub fn error_chain(e: &tera::Error) -> String {
    let mut text = e.to_string();
    let mut source = std::error::Error::source(e);
    while let Some(s) = source {
        text.push_str(&format!(": {s}"));
        source = s.source();
    }
    text
}

/// The dataset run's HTML page.
/// The page; `gallery_uris` and `figure_svgs` follow `context.gallery` and
/// `context.figures` (kept out of the context's JSON).
pub fn render_html(context: &RunContext, gallery_uris: &[String], figure_svgs: &[String]) -> Result<String, String> {
    let mut ctx = tera::Context::from_serialize(context).map_err(|e| error_chain(&e))?;
    ctx.insert("gallery_uris", gallery_uris);
    ctx.insert("figure_svgs", figure_svgs);
    tera()
        .and_then(|t| t.render("run.html", &ctx))
        .map_err(|e| error_chain(&e))
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
