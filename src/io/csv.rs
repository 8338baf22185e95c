//! The plain CSV files probecal reads (frame lists, tracker poses): a header
//! line, then one record per line, fields split at commas and trimmed, blank
//! lines skipped. No quoting: no field of these files holds a comma.

/// One record: its 1-based line in the file and its fields.
#[derive(Debug, Clone, PartialEq)]
pub struct Record<'a> {
    pub line: usize,
    pub fields: Vec<&'a str>,
}

/// The header line (trimmed; empty for an empty file) and the records after it.
pub fn split(text: &str) -> (&str, Vec<Record<'_>>) {
    let mut lines = text.lines().enumerate();
    let header = lines.next().map(|(_, l)| l.trim()).unwrap_or("");
    let records = lines
        .filter(|(_, raw)| !raw.trim().is_empty())
        .map(|(i, raw)| Record {
            line: i + 1,
            fields: raw.split(',').map(str::trim).collect(),
        })
        .collect();
    (header, records)
}

/// A frame number field.
pub fn frame_number(field: &str) -> Result<usize, FrameNumberError> {
    field.parse().map_err(|_| FrameNumberError {
        field: field.to_string(),
    })
}

/// A frame field that is not a whole number.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("frame `{field}` is not a whole number")]
pub struct FrameNumberError {
    pub field: String,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_keep_their_line_numbers() {
        let (header, records) = split("a,b\n1, 2\n\n 3 ,4\n");
        assert_eq!(header, "a,b");
        assert_eq!(
            records,
            vec![
                Record {
                    line: 2,
                    fields: vec!["1", "2"]
                },
                Record {
                    line: 4,
                    fields: vec!["3", "4"]
                }
            ]
        );
        assert_eq!(split("").0, "");
        assert_eq!(frame_number("7"), Ok(7));
        assert_eq!(
            frame_number("x").unwrap_err().to_string(),
            "frame `x` is not a whole number"
        );
    }
}
