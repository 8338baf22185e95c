//! What every page's rendering shares, below the pages themselves: the LaTeX
//! escape filter, the figures' font, and tera's errors with their causes.

pub use crate::report::error::error_chain;
use crate::report::error::{OutputError, ReadError};

/// Where the bitmap figures' font is read from.
pub const FIGURE_FONT: &str = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";

/// Registers the figures' font once (plotters lays text out with it, SVG included).
pub fn register_font() -> Result<(), OutputError> {
    static FONT: std::sync::OnceLock<Result<(), ReadError>> = std::sync::OnceLock::new();
    let path = std::path::Path::new(FIGURE_FONT);
    FONT.get_or_init(|| {
        let bytes = crate::io::fs::read_capped(path, 64 << 20)
            .map_err(|e| ReadError::new(path, format!("{e} (install fonts-dejavu-core)")))?;
        // The font lives as long as the program: figures are drawn until it ends.
        let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
        plotters::style::register_font("sans-serif", plotters::style::FontStyle::Normal, bytes)
            .map_err(|_| ReadError::new(path, "not a TrueType font"))
    })
    .clone()
    .map_err(OutputError::Read)
}

/// Adds the `tex` filter ([`tex_escape`]) to a template set.
pub fn register_tex_filter(t: &mut tera::Tera) {
    t.register_filter("tex", tex_filter);
}

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
