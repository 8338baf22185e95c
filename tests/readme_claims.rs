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
            if let Some((file, key)) = tag.split_once('#').filter(|_| !tag.starts_with("paired ")) {
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
    select(json, path)?
        .as_f64()
        .map(|v| v * scale)
        .ok_or_else(|| format!("`{key}` is not a number"))
}

/// The element at `path` in `json`.
fn select<'a>(json: &'a serde_json::Value, path: &str) -> Result<&'a serde_json::Value, String> {
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
    Ok(value)
}

/// The paired comparisons a page's words rest on: `<!-- paired lower: file#key -->`
/// after a claim that the second study's error is lower than the first's
/// (`higher`, or `none` for a claim of no difference), `key` the method's entry
/// of a `probecal study compare` file. (line, word, file, key).
fn paired_claims(text: &str) -> Vec<(usize, String, String, String)> {
    let mut out = Vec::new();
    for (line_no, line) in text.lines().enumerate() {
        let mut rest = line;
        while let Some(at) = rest.find("<!-- paired ") {
            let after = &rest[at + "<!-- paired ".len()..];
            let Some(end) = after.find(" -->") else { break };
            let tag = &after[..end];
            let (word, target) = tag.split_once(": ").unwrap_or((tag, ""));
            let (file, key) = target.split_once('#').unwrap_or((target, ""));
            out.push((line_no + 1, word.to_string(), file.to_string(), key.to_string()));
            rest = &after[end + 4..];
        }
    }
    out
}

/// Whether the words agree with the paired interval: `lower` and `higher` need
/// an interval on that side of zero, `none` one that holds it.
fn words_agree(word: &str, entry: &serde_json::Value) -> Result<(), String> {
    let [low, high] = [0, 1].map(|i| entry["interval_90_mm"][i].as_f64());
    let (Some(low), Some(high)) = (low, high) else {
        return Err("no `interval_90_mm`".into());
    };
    let agrees = match word {
        "lower" => high < 0.0,
        "higher" => low > 0.0,
        "none" => low <= 0.0 && high >= 0.0,
        other => return Err(format!("`{other}` is not lower, higher or none")),
    };
    if agrees {
        Ok(())
    } else {
        Err(format!(
            "says `{word}`, but the 90 % interval is {low:+.3} … {high:+.3} mm"
        ))
    }
}

/// Paragraphs (blank-line separated) with their first line's number.
fn paragraphs(text: &str) -> Vec<(usize, String)> {
    let mut out: Vec<(usize, String)> = Vec::new();
    let mut open = false;
    for (i, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            open = false;
        } else if open {
            let last = out.last_mut().unwrap();
            last.1.push('\n');
            last.1.push_str(line);
        } else {
            out.push((i + 1, line.to_string()));
            open = true;
        }
    }
    out
}

/// A paragraph that quotes a paired difference must say which way it goes:
/// every `<file>#methods[method=M].mean_difference_mm` it cites has a
/// `paired` tag on the same file and method.
fn unclaimed_differences(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    for (line, paragraph) in paragraphs(text) {
        let paired: Vec<(String, String)> = paired_claims(&paragraph)
            .into_iter()
            .map(|(_, _, file, key)| (file, key))
            .collect();
        for (_, _, file, key) in claims(&paragraph) {
            if let Some(entry) = key.strip_suffix(".mean_difference_mm") {
                if !paired.iter().any(|(f, k)| *f == file && k == entry) {
                    out.push(format!("line {line}: {file}#{key} without its paired verdict"));
                }
            }
        }
    }
    out
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

/// Every comparative claim with a paired tag agrees with its interval, and
/// every quoted paired difference carries one.
#[test]
fn every_paired_claim_agrees_with_its_interval() {
    let root = common::root();
    let mut wrong = Vec::new();
    let mut total = 0;
    for page in documents() {
        let name = page.strip_prefix(root).unwrap().display().to_string();
        let text = std::fs::read_to_string(&page).unwrap();
        for (line, word, file, key) in paired_claims(&text) {
            total += 1;
            let path = root.join("reports").join(&file);
            let check = std::fs::read_to_string(&path)
                .map_err(|e| format!("{}: {e}", path.display()))
                .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).map_err(|e| e.to_string()))
                .and_then(|json| select(&json, &key).cloned())
                .and_then(|entry| words_agree(&word, &entry));
            if let Err(e) = check {
                wrong.push(format!("{name}:{line}: reports/{file}#{key}: {e}"));
            }
        }
        wrong.extend(unclaimed_differences(&text).into_iter().map(|e| format!("{name}: {e}")));
    }
    assert!(total >= 5, "only {total} paired claims in README.md and docs/");
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}

#[test]
fn a_better_whose_interval_holds_zero_is_caught() {
    let within = serde_json::json!({"interval_90_mm": [-0.028, 0.005]});
    let below = serde_json::json!({"interval_90_mm": [-0.05, -0.01]});
    assert!(words_agree("lower", &within).is_err());
    assert!(words_agree("none", &within).is_ok());
    assert!(words_agree("lower", &below).is_ok());
    assert!(words_agree("none", &below).is_err());
    assert!(words_agree("higher", &below).is_err());
    assert!(words_agree("better", &below).is_err());
    let text = "Lower by -0.011<!-- s/a_vs_b.json#methods[method=m].mean_difference_mm -->\n\n\
                Lower by -0.011<!-- s/a_vs_b.json#methods[method=m].mean_difference_mm --> \
                (<!-- paired lower: s/a_vs_b.json#methods[method=m] -->)";
    assert_eq!(unclaimed_differences(text).len(), 1);
    let tags = paired_claims(text);
    assert_eq!(tags.len(), 1);
    assert_eq!((tags[0].1.as_str(), tags[0].3.as_str()), ("lower", "methods[method=m]"));
    // A paired tag is not taken for a number.
    assert_eq!(claims(text).len(), 2);
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

/// `scripts/readme-numbers.py --check` on a copy of the pages: exit 0 while
/// every tagged number matches reports/, exit 1 naming the page, line and key
/// at a planted drift, and the page left as it was.
#[test]
fn the_numbers_script_checks_without_writing_and_names_the_drift() {
    let root = common::root();
    let copy = common::scratch("readme_claims", "check");
    std::fs::create_dir_all(copy.join("docs")).unwrap();
    let copy_tree = |from: &std::path::Path, to: &std::path::Path| {
        for entry in walk(from) {
            let target = to.join(entry.strip_prefix(from).unwrap());
            std::fs::create_dir_all(target.parent().unwrap()).unwrap();
            std::fs::copy(&entry, &target).unwrap();
        }
    };
    copy_tree(&root.join("docs"), &copy.join("docs"));
    std::fs::copy(root.join("README.md"), copy.join("README.md")).unwrap();
    std::os::unix::fs::symlink(root.join("reports"), copy.join("reports")).unwrap();
    let check = || {
        std::process::Command::new("/usr/bin/python3")
            .arg(root.join("scripts/readme-numbers.py"))
            .args(["--check", "--root"])
            .arg(&copy)
            .output()
            .unwrap()
    };
    let r = check();
    assert_eq!(r.status.code(), Some(0), "{}", String::from_utf8_lossy(&r.stderr));
    // Plant a drift in the first tagged number of the README.
    let readme = std::fs::read_to_string(copy.join("README.md")).unwrap();
    let (line, number, file, key) = claims(&readme).into_iter().next().expect("a tagged number");
    let planted = readme.replacen(
        &format!("{number}<!-- {file}#{key} -->"),
        &format!("{number}9<!-- {file}#{key} -->"),
        1,
    );
    assert_ne!(planted, readme);
    std::fs::write(copy.join("README.md"), &planted).unwrap();
    let r = check();
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains(&format!("README.md:{line}:")) && stderr.contains(&key),
        "{stderr}"
    );
    assert_eq!(std::fs::read_to_string(copy.join("README.md")).unwrap(), planted);
}

/// Every file below `dir`.
fn walk(dir: &std::path::Path) -> Vec<std::path::PathBuf> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            out.extend(walk(&path));
        } else {
            out.push(path);
        }
    }
    out
}
