//! Bounds on a YAML file before it is parsed: its size, and how deep it nests
//! (a parser's time and stack grow with the depth; 100 000 levels abort it).

use std::path::Path;

use crate::core::limits::MAX_YAML_DEPTH;

/// Largest YAML file read (manifests, baselines and shard files are
/// kilobytes to a few megabytes).
pub const MAX_YAML_BYTES: u64 = 16 << 20;

/// Why a YAML file is not parsed: the line it is about (none for its size)
/// and what is wrong; the caller names the file.
#[derive(Debug, Clone, PartialEq)]
pub struct YamlRefusal {
    pub line: Option<usize>,
    pub message: String,
}

impl std::fmt::Display for YamlRefusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.line {
            Some(line) => write!(f, "line {line}: {}", self.message),
            None => f.write_str(&self.message),
        }
    }
}

/// The text of YAML file `path`, refused unread when it is larger than
/// [`MAX_YAML_BYTES`] and unparsed when it nests deeper than
/// [`MAX_YAML_DEPTH`].
/// `what` names the kind of file in the messages ("a manifest").
pub fn read(path: &Path, what: &str) -> Result<String, YamlRefusal> {
    let refusal = |line, message| YamlRefusal { line, message };
    let size = std::fs::metadata(path).map_err(|e| refusal(None, e.to_string()))?.len();
    if size > MAX_YAML_BYTES {
        return Err(refusal(
            None,
            format!("{size} bytes: larger than {what} can be ({MAX_YAML_BYTES} bytes)"),
        ));
    }
    let text = crate::io::fs::read_text_capped(path, MAX_YAML_BYTES).map_err(|e| refusal(None, e.to_string()))?;
    match too_deep(&text) {
        Some((line, depth)) => Err(refusal(
            Some(line),
            format!("nested {depth} levels deep; {what} nests at most {MAX_YAML_DEPTH}"),
        )),
        None => Ok(text),
    }
}

/// The first line (1-based) where the YAML nests deeper than [`MAX_YAML_DEPTH`]
/// (indented blocks and `[`/`{` inside each other), and how deep; checked before
/// parsing, whose time grows fast with the depth.
pub fn too_deep(text: &str) -> Option<(usize, usize)> {
    let mut indents: Vec<usize> = Vec::new();
    let mut flow = 0usize;
    for (i, line) in text.lines().enumerate() {
        let content = line.trim_start();
        if flow == 0 && !(content.is_empty() || content.starts_with('#')) {
            let indent = line.len() - content.len();
            while indents.last().is_some_and(|&top| top >= indent) {
                indents.pop();
            }
            indents.push(indent);
        }
        let mut quote = None;
        for c in content.chars() {
            match (quote, c) {
                (None, '#') => break,
                (None, '"' | '\'') => quote = Some(c),
                (Some(q), c) if c == q => quote = None,
                (None, '[' | '{') => flow += 1,
                (None, ']' | '}') => flow = flow.saturating_sub(1),
                _ => {}
            }
            let depth = indents.len() + flow;
            if depth > MAX_YAML_DEPTH {
                return Some((i + 1, depth));
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn depth_is_counted_in_blocks_and_brackets() {
        assert_eq!(too_deep("a:\n  b: [1, {c: 2}]\n"), None);
        let flow = format!("a: {}{}\n", "[".repeat(40), "]".repeat(40));
        assert_eq!(too_deep(&flow), Some((1, MAX_YAML_DEPTH + 1)));
        let blocks: String = (0..40).map(|k| format!("{}k{k}:\n", " ".repeat(k))).collect();
        assert_eq!(too_deep(&blocks).map(|(line, _)| line), Some(MAX_YAML_DEPTH + 1));
        assert_eq!(
            too_deep("a: '[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[['\n"),
            None,
            "quoted"
        );
    }
}
