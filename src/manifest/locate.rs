//! Finds the line of a dotted field path (`datasets[0].render.seed`) in block-style YAML.
//!
//! serde reports type errors with a position, but checks made after parsing
//! (a negative radius, thresholds out of order) only know the field path. This
//! walks the indentation of the text to find the line that path was written on;
//! where a part of the path is absent (a missing field), it answers with the
//! line of the deepest parent that is present.

/// One step of a field path.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Segment {
    Key(String),
    Index(usize),
}

/// Splits `a.b[2].c` into segments.
pub fn parse_path(path: &str) -> Vec<Segment> {
    let mut out = Vec::new();
    for part in path.split('.').filter(|p| !p.is_empty()) {
        let mut rest = part;
        if let Some(open) = rest.find('[') {
            let key = &rest[..open];
            if !key.is_empty() {
                out.push(Segment::Key(key.to_string()));
            }
            rest = &rest[open..];
            while let Some(stripped) = rest.strip_prefix('[') {
                let Some(close) = stripped.find(']') else { break };
                if let Ok(i) = stripped[..close].parse() {
                    out.push(Segment::Index(i));
                }
                rest = &stripped[close + 1..];
            }
        } else {
            out.push(Segment::Key(rest.to_string()));
        }
    }
    out
}

struct Line<'a> {
    number: usize,
    indent: usize,
    content: &'a str,
}

fn significant_lines(text: &str) -> Vec<Line<'_>> {
    text.lines()
        .enumerate()
        .filter_map(|(i, raw)| {
            let trimmed = raw.trim_start();
            if trimmed.is_empty() || trimmed.starts_with('#') || trimmed == "---" {
                return None;
            }
            Some(Line {
                number: i + 1,
                indent: raw.len() - trimmed.len(),
                content: trimmed,
            })
        })
        .collect()
}

fn key_of(content: &str) -> Option<&str> {
    let colon = content.find(':')?;
    let key = content[..colon].trim().trim_matches('"').trim_matches('\'');
    let after = &content[colon + 1..];
    (after.is_empty() || after.starts_with(' ')).then_some(key)
}

/// The 1-based line of `path` in `text`, or of its deepest present parent.
pub fn line_of(text: &str, path: &str) -> Option<usize> {
    let lines = significant_lines(text);
    let segments = parse_path(path);
    // The current block: a range of lines and the column its entries start at.
    let (mut start, mut end) = (0usize, lines.len());
    let mut column = lines.first().map(|l| l.indent)?;
    let mut found: Option<usize> = None;
    for segment in &segments {
        let hit = match segment {
            Segment::Key(key) => (start..end).find(|&i| {
                let line = &lines[i];
                let (indent, content) = strip_dash(line);
                indent == column && key_of(content) == Some(key.as_str())
            }),
            Segment::Index(index) => (start..end)
                .filter(|&i| lines[i].indent == column && lines[i].content.starts_with('-'))
                .nth(*index),
        };
        let Some(i) = hit else { break };
        found = Some(lines[i].number);
        // The block below this entry: following lines indented deeper than it.
        let (indent, content) = strip_dash(&lines[i]);
        let block_end = (i + 1..end)
            .find(|&j| lines[j].indent <= lines[i].indent)
            .unwrap_or(end);
        match segment {
            Segment::Index(_) => {
                // "- key: v" opens a mapping on the dash line itself.
                start = i;
                end = block_end;
                column = indent;
            }
            Segment::Key(_) => {
                let inline_value = content.split_once(':').map(|(_, v)| v.trim()).unwrap_or("");
                if !inline_value.is_empty() && !inline_value.starts_with('#') {
                    // A scalar or flow collection on the same line: nothing deeper to walk.
                    start = i + 1;
                    end = i + 1;
                } else {
                    start = i + 1;
                    end = block_end;
                    column = lines
                        .get(start)
                        .filter(|_| start < end)
                        .map(|l| l.indent)
                        .unwrap_or(column);
                }
            }
        }
    }
    found
}

/// For a line `- key: v`, the column and text of `key: v`.
fn strip_dash<'a>(line: &Line<'a>) -> (usize, &'a str) {
    match line.content.strip_prefix("- ") {
        Some(rest) => {
            let extra = line.content.len() - rest.len();
            let rest_trimmed = rest.trim_start();
            (line.indent + extra + (rest.len() - rest_trimmed.len()), rest_trimmed)
        }
        None => (line.indent, line.content),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TEXT: &str = "\
experiment: demo
# a comment
phantom:
  hemisphere:
    centre_in_phantom_mm: [1, 2, 3]
    radius_mm: -4
datasets:
  - name: first
    render:
      seed: 1
  - name: second
    folder: data/second
thresholds:
  bre_cutoffs_mm: [.inf, 2, 1.5]
";

    #[test]
    fn finds_nested_keys_and_list_items() {
        assert_eq!(line_of(TEXT, "experiment"), Some(1));
        assert_eq!(line_of(TEXT, "phantom.hemisphere.radius_mm"), Some(6));
        assert_eq!(line_of(TEXT, "datasets[0].render.seed"), Some(10));
        assert_eq!(line_of(TEXT, "datasets[1].name"), Some(11));
        assert_eq!(line_of(TEXT, "datasets[1].folder"), Some(12));
        assert_eq!(line_of(TEXT, "thresholds.bre_cutoffs_mm[2]"), Some(14));
    }

    #[test]
    fn missing_field_points_at_its_parent() {
        assert_eq!(line_of(TEXT, "datasets[1].render.seed"), Some(11));
        assert_eq!(line_of(TEXT, "phantom.hemisphere.height_mm"), Some(4));
    }
}
