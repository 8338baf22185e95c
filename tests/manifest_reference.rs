//! `docs/manifest.md` names every key a manifest accepts. The keys are read from
//! the manifest types themselves: a key the types do not know is refused with the
//! list of keys they do (`unknown field `x`, expected one of ...`), so probing each
//! section with an unknown key walks the whole tree of both manifest kinds. A key
//! added to the types and not to the page fails this test.

mod common;

use std::collections::BTreeSet;
use std::path::Path;

use probecal::manifest::tracked::TrackedManifest;
use probecal::manifest::Manifest;

const PROBE: &str = "zz_not_a_key";
const MAX_DEPTH: usize = 6;

/// The YAML of `path` (keys; `name[]` a list of mappings) holding the flow
/// mapping `leaf`, in flow style.
fn nested(path: &[String], leaf: &str) -> String {
    let mut text = leaf.to_string();
    for key in path.iter().rev() {
        text = match key.strip_suffix("[]") {
            Some(list) => format!("{{{list}: [{text}]}}"),
            None => format!("{{{key}: {text}}}"),
        };
    }
    // The document itself as a block mapping, so a prefix line may precede it.
    let inner = &text[1..text.len() - 1];
    format!("{inner}\n")
}

/// The names serde lists after "expected" in `message`: `a`, `a` or `b`, one of `a`, `b`, ...
fn listed(message: &str) -> Option<Vec<String>> {
    let at = message.find("expected ")? + 9;
    let rest = &message[at..];
    let rest = rest.strip_prefix("one of ").unwrap_or(rest);
    let names: Vec<String> = rest
        .split('`')
        .enumerate()
        .take_while(|(i, s)| i % 2 == 1 || matches!(s.trim(), "" | "," | "or"))
        .filter(|(i, _)| i % 2 == 1)
        .map(|(_, s)| s.to_string())
        .collect();
    (!names.is_empty()).then_some(names)
}

/// The error message a manifest kind gives for `text`.
fn message(tracked: bool, text: &str) -> String {
    let path = Path::new("probe.yaml");
    let errors = if tracked {
        TrackedManifest::from_text(path, text).err()
    } else {
        Manifest::from_text(path, text).err()
    };
    errors.map(|e| e.to_string()).unwrap_or_default()
}

/// Every dotted key below `path`, found by probing.
fn walk(tracked: bool, path: &mut Vec<String>, keys: &mut BTreeSet<String>) {
    if path.len() >= MAX_DEPTH {
        return;
    }
    // A prefix that makes the tracked kind's text a tracked manifest.
    let prefix = |p: &[String]| {
        if tracked && p.first().map(String::as_str) != Some("tracking") {
            "tracking: {plus_sequence: {dataset: d, calibration: c}}\n".to_string()
        } else {
            String::new()
        }
    };
    let probe = |leaf: String| message(tracked, &(prefix(path) + &nested(path, &leaf)));
    let as_struct = probe(format!("{{{PROBE}: 1}}"));
    let names = if as_struct.contains(&format!("unknown field `{PROBE}`")) {
        listed(&as_struct)
    } else if probe(format!("{{{PROBE}: {{}}}}")).contains(&format!("unknown variant `{PROBE}`")) {
        // An enum written as a one-key map (`phantom: {hemisphere: ...}`).
        listed(&probe(format!("{{{PROBE}: {{}}}}")))
    } else if let Some(last) = path.last().filter(|k| !k.ends_with("[]")).cloned() {
        // A list of mappings (`datasets: [{name: ...}]`): its elements' keys.
        path.pop();
        path.push(format!("{last}[]"));
        let as_list = message(tracked, &(prefix(path) + &nested(path, &format!("{{{PROBE}: 1}}"))));
        let names = as_list
            .contains(&format!("unknown field `{PROBE}`"))
            .then(|| listed(&as_list))
            .flatten();
        if names.is_none() {
            path.pop();
            path.push(last);
        }
        names
    } else {
        None
    };
    for name in names.into_iter().flatten() {
        path.push(name);
        keys.insert(path.join("."));
        walk(tracked, path, keys);
        path.pop();
    }
}

fn all_keys() -> BTreeSet<String> {
    let mut keys = BTreeSet::new();
    walk(false, &mut Vec::new(), &mut keys);
    let mut tracked = BTreeSet::new();
    walk(true, &mut Vec::new(), &mut tracked);
    keys.extend(tracked);
    keys
}

#[test]
fn the_probe_finds_the_keys_of_both_kinds() {
    let keys = all_keys();
    for key in [
        "phantom.hemisphere.radius_mm",
        "rig.checkerboard.probe_board",
        "thresholds.gates",
        "tracking.plus_sequence.time_offset_s",
        "bscan.segmentation.threshold_percent",
    ] {
        assert!(
            keys.contains(key),
            "{key} not found among {} keys: {keys:?}",
            keys.len()
        );
    }
    assert!(!keys.iter().any(|k| k.contains(PROBE)));
}

#[test]
fn docs_manifest_md_names_every_key() {
    let page = std::fs::read_to_string(common::root().join("docs/manifest.md")).unwrap();
    let missing: Vec<String> = all_keys()
        .into_iter()
        .filter(|key| !page.contains(&format!("`{key}`")))
        .collect();
    assert!(
        missing.is_empty(),
        "docs/manifest.md does not name these keys (as `dotted.key`):\n{}",
        missing.join("\n")
    );
}
