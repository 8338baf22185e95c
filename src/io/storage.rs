//! OpenCV FileStorage files (camera intrinsics, ArUco dictionaries and detector
//! parameters) held to a size and a nesting depth before OpenCV parses them:
//! its YAML and XML parsers recurse per level and crash on a deep file.

use std::path::Path;

/// Largest FileStorage file read (an intrinsics file is a kilobyte).
pub const MAX_STORAGE_BYTES: u64 = 16 << 20;

/// Deepest nesting accepted: brackets, XML elements, or indentation columns.
pub const MAX_STORAGE_DEPTH: usize = 64;

/// Why `path` is refused before OpenCV reads it, if it is.
pub fn refusal(path: &Path) -> Option<String> {
    let size = std::fs::metadata(path).ok()?.len();
    if size > MAX_STORAGE_BYTES {
        return Some(format!(
            "{size} bytes: larger than any OpenCV FileStorage file probecal reads ({MAX_STORAGE_BYTES} bytes)"
        ));
    }
    let text = match crate::io::fs::read_capped(path, MAX_STORAGE_BYTES) {
        Ok(bytes) => String::from_utf8_lossy(&bytes).to_string(),
        // Unread here is unread by OpenCV too.
        Err(e) => return Some(format!("cannot read: {e}")),
    };
    let (mut depth, mut deepest) = (0usize, 0usize);
    for c in text.chars() {
        match c {
            '[' | '{' => {
                depth += 1;
                deepest = deepest.max(depth);
            }
            ']' | '}' => depth = depth.saturating_sub(1),
            _ => {}
        }
    }
    let xml = crate::io::plus::xml_limits::nesting_depth(&text, MAX_STORAGE_DEPTH);
    let indent = text
        .lines()
        .map(|l| l.len() - l.trim_start_matches([' ', '\t']).len())
        .max()
        .unwrap_or(0);
    let deep = deepest.max(xml).max(indent / 2);
    (deep > MAX_STORAGE_DEPTH)
        .then(|| format!("nested more than {MAX_STORAGE_DEPTH} deep: not an OpenCV FileStorage file probecal reads"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deep_files_are_refused_before_opencv_reads_them() {
        let dir = std::env::temp_dir().join(format!("probecal-storage-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let ok = dir.join("ok.yml");
        std::fs::write(
            &ok,
            "%YAML:1.0\n---\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   data: [ 1., 0., 2. ]\n",
        )
        .unwrap();
        assert_eq!(refusal(&ok), None);
        for (name, text) in [
            (
                "brackets.yml",
                format!("%YAML:1.0\na: {}{}\n", "[".repeat(100_000), "]".repeat(100_000)),
            ),
            (
                "elements.xml",
                format!(
                    "<opencv_storage>{}{}</opencv_storage>",
                    "<a>".repeat(5000),
                    "</a>".repeat(5000)
                ),
            ),
            (
                "indented.yml",
                (0..300).map(|k| format!("{}k{k}:\n", " ".repeat(k))).collect(),
            ),
        ] {
            let path = dir.join(name);
            std::fs::write(&path, text).unwrap();
            assert!(refusal(&path).unwrap().contains("nested more than 64 deep"), "{name}");
        }
        std::fs::remove_dir_all(&dir).ok();
    }
}
