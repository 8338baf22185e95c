//! Every result number README and the pages of `docs/` state is tagged with the committed output it
//! comes from, `0.521<!-- plus_fcal2_nwire/fcal2_3nwires/summary.json#validation.pre3d_mm.mean -->`,
//! and must equal that value rounded to the digits written. `scripts/check-reports.sh`
//! checks that `reports/` regenerates byte-identical from a fresh run, so a README
//! number that drifts from what the code produces fails one or the other.
//!
//! A key is a path of object fields and selectors: `name[3]` (an index) or
//! `name[field=value]` (the element whose `field` is `value`); a trailing
//! `*1000` scales the value (seconds written as milliseconds).

mod common;

/// The tagged numbers of `text`: (line, written number, file, key).
fn claims(text: &str) -> Vec<(usize, String, String, String)> {
    let mut out = Vec::new();
    for (line_no, line) in text.lines().enumerate() {
        let mut rest = line;
        while let Some(at) = rest.find("<!-- ") {
            let before = &rest[..at];
            let number: String = before
                .chars()
                .rev()
                .take_while(|c| c.is_ascii_digit() || *c == '.' || *c == '-')
                .collect::<Vec<_>>()
                .into_iter()
                .rev()
                .collect();
            let after = &rest[at + 5..];
            let Some(end) = after.find(" -->") else { break };
            let tag = &after[..end];
            if let Some((file, key)) = tag.split_once('#') {
                if file.ends_with(".json") {
                    out.push((line_no + 1, number, file.to_string(), key.to_string()));
                }
            }
            rest = &after[end + 4..];
        }
    }
    out
}

/// The value at `key` in `json`.
fn lookup(json: &serde_json::Value, key: &str) -> Result<f64, String> {
    let (path, scale) = match key.split_once('*') {
        Some((p, s)) => (p, s.parse::<f64>().map_err(|e| format!("scale `{s}`: {e}"))?),
        None => (key, 1.0),
    };
    let mut value = json;
    for segment in path.split('.') {
        let (name, selector) = match segment.split_once('[') {
            Some((n, s)) => (n, Some(s.trim_end_matches(']'))),
            None => (segment, None),
        };
        if !name.is_empty() {
            value = value.get(name).ok_or_else(|| format!("no field `{name}`"))?;
        }
        if let Some(sel) = selector {
            value = match sel.split_once('=') {
                Some((field, want)) => value
                    .as_array()
                    .and_then(|a| a.iter().find(|e| e.get(field).and_then(|v| v.as_str()) == Some(want)))
                    .ok_or_else(|| format!("no element with {field} = {want}"))?,
                None => {
                    let k: usize = sel.parse().map_err(|e| format!("index `{sel}`: {e}"))?;
                    value.get(k).ok_or_else(|| format!("no element {k}"))?
                }
            };
        }
    }
    value
        .as_f64()
        .map(|v| v * scale)
        .ok_or_else(|| format!("`{key}` is not a number"))
}

/// `value` written with the decimals of `written`.
fn rounded_like(value: f64, written: &str) -> String {
    let decimals = written.split_once('.').map_or(0, |(_, d)| d.len());
    format!("{value:.decimals$}")
}

/// README.md and every Markdown page below `docs/`, sorted.
fn documents() -> Vec<std::path::PathBuf> {
    fn walk(dir: &std::path::Path, out: &mut Vec<std::path::PathBuf>) {
        for entry in std::fs::read_dir(dir).unwrap().flatten() {
            let path = entry.path();
            if path.is_dir() {
                walk(&path, out);
            } else if path.extension().is_some_and(|e| e == "md") {
                out.push(path);
            }
        }
    }
    let mut pages = Vec::new();
    walk(&common::root().join("docs"), &mut pages);
    pages.sort();
    pages.insert(0, common::root().join("README.md"));
    pages
}

#[test]
fn every_tagged_number_in_readme_and_docs_is_its_committed_output() {
    let root = common::root();
    let mut wrong = Vec::new();
    let mut total = 0;
    for page in documents() {
        let name = page.strip_prefix(root).unwrap().display().to_string();
        let text = std::fs::read_to_string(&page).unwrap();
        let found = claims(&text);
        total += found.len();
        for (line, written, file, key) in &found {
            let path = root.join("reports").join(file);
            let check = std::fs::read_to_string(&path)
                .map_err(|e| format!("{}: {e}", path.display()))
                .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).map_err(|e| e.to_string()))
                .and_then(|json| lookup(&json, key));
            match check {
                Ok(value) if !written.is_empty() && rounded_like(value, written) == *written => {}
                Ok(value) => wrong.push(format!(
                    "{name}:{line}: `{written}` but reports/{file}#{key} is {}",
                    rounded_like(value, if written.is_empty() { "0.000" } else { written })
                )),
                Err(e) => wrong.push(format!("{name}:{line}: reports/{file}#{key}: {e}")),
            }
        }
    }
    assert!(total >= 200, "only {total} tagged numbers in README.md and docs/");
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}

/// The front door stays a front door: README at most 20 KB, and the section on
/// one's own recording within its first 150 lines.
#[test]
fn readme_is_short_and_leads_to_ones_own_recording() {
    let readme = std::fs::read_to_string(common::root().join("README.md")).unwrap();
    assert!(readme.len() <= 20 * 1024, "README.md is {} bytes", readme.len());
    let at = readme
        .lines()
        .position(|l| l.starts_with("## Calibrate your own recording"))
        .expect("README has a section \"Calibrate your own recording\"");
    assert!(at < 150, "\"Calibrate your own recording\" starts at line {}", at + 1);
}

/// Every relative link of README and `docs/` names a file or folder that exists.
#[test]
fn every_relative_link_of_readme_and_docs_resolves() {
    let root = common::root();
    let mut broken = Vec::new();
    for page in documents() {
        let text = std::fs::read_to_string(&page).unwrap();
        let mut rest = text.as_str();
        while let Some(at) = rest.find("](") {
            rest = &rest[at + 2..];
            let Some(end) = rest.find(')') else { break };
            let target = rest[..end].split('#').next().unwrap_or("");
            if !target.is_empty() && !target.contains("://") && !page.parent().unwrap().join(target).exists() {
                broken.push(format!("{}: {target}", page.strip_prefix(root).unwrap().display()));
            }
        }
    }
    assert!(broken.is_empty(), "links to nothing:\n{}", broken.join("\n"));
}

#[test]
fn a_drifted_number_or_a_wrong_key_is_caught() {
    let json: serde_json::Value = serde_json::json!({
        "validation": {"pre3d_mm": {"mean": 0.52098}},
        "methods": [{"method": "ransac", "rms_mm": 0.54}],
        "time_offset_s": 0.05
    });
    let text = "ours 0.521<!-- x.json#validation.pre3d_mm.mean -->, lag 50<!-- x.json#time_offset_s*1000 --> ms\n\
                RANSAC 0.540<!-- x.json#methods[method=ransac].rms_mm --> and 0.54<!-- x.json#methods[0].rms_mm -->";
    let found = claims(text);
    assert_eq!(found.len(), 4);
    for (_, written, _, key) in &found {
        assert_eq!(rounded_like(lookup(&json, key).unwrap(), written), *written, "{key}");
    }
    assert_ne!(
        rounded_like(lookup(&json, "validation.pre3d_mm.mean").unwrap(), "0.520"),
        "0.520"
    );
    assert!(lookup(&json, "methods[method=lmeds].rms_mm").is_err());
    assert!(lookup(&json, "validation.pre3d").is_err());
}
