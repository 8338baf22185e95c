//! The architecture's fitness test: the layers of `src/` point down only.
//!
//! Every `crate::<module>` path in a top-level module's files (its test modules
//! left out) is an edge to that module. An edge to a module of the same or a
//! higher layer fails the test, and so does any cycle, among the top-level
//! modules or among the files of one folder (`super::<file>` and
//! `crate::<folder>::<file>` paths; a sub-folder counts as one file); so do a `main.rs` above
//! 20 lines (it calls `probecal::cli::main`) and a source file above 600. The checks themselves are tested on
//! planted graphs, so they can fail.

mod common;

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// The layers, lowest first (as the crate's documentation draws them).
const LAYERS: &[(&str, usize)] = &[
    ("core", 0),
    ("spec", 1),
    ("io", 2),
    ("detect", 3),
    ("estimate", 3),
    ("reconstruct", 3),
    ("evaluate", 4),
    ("synth", 4),
    ("manifest", 5),
    ("pipeline", 6),
    ("results", 7),
    ("report", 8),
    ("cli", 9),
];

type Graph = BTreeMap<String, BTreeSet<String>>;

/// A file's text without its `#[cfg(test)]` items (brace-matched).
fn without_tests(src: &str) -> String {
    let mut out = String::new();
    let mut rest = src;
    while let Some(at) = rest.find("#[cfg(test)]") {
        out.push_str(&rest[..at]);
        let after = &rest[at..];
        let Some(open) = after.find(['{', ';']) else { break };
        if after.as_bytes()[open] == b';' {
            rest = &after[open + 1..];
            continue;
        }
        let mut depth = 0usize;
        let mut end = after.len();
        for (i, c) in after.char_indices().skip(open) {
            match c {
                '{' => depth += 1,
                '}' => {
                    depth -= 1;
                    if depth == 0 {
                        end = i + 1;
                        break;
                    }
                }
                _ => {}
            }
        }
        rest = &after[end..];
    }
    out.push_str(rest);
    out
}

/// The modules named after `crate::` in a text, also inside `crate::{a, b}`.
fn crate_paths(src: &str) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    for (i, _) in src.match_indices("crate::") {
        let rest = &src[i + "crate::".len()..];
        if let Some(group) = rest.strip_prefix('{') {
            let inner = &group[..group.find('}').unwrap_or(group.len())];
            for item in inner.split(',') {
                let name: String = item
                    .trim()
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect();
                out.insert(name);
            }
        } else {
            out.insert(rest.chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect());
        }
    }
    out
}

fn rust_files(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap().flatten() {
        let path = entry.path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The graph of the crate's top-level modules.
fn graph(src: &Path) -> Graph {
    let tops: BTreeSet<String> = LAYERS.iter().map(|(m, _)| m.to_string()).collect();
    let mut g = Graph::new();
    for top in &tops {
        let mut files = Vec::new();
        let folder = src.join(top);
        if folder.is_dir() {
            rust_files(&folder, &mut files);
        } else {
            files.push(src.join(format!("{top}.rs")));
        }
        let edges = g.entry(top.clone()).or_default();
        for f in files {
            let text = std::fs::read_to_string(&f).unwrap();
            for m in crate_paths(&without_tests(&text)) {
                if tops.contains(&m) && &m != top {
                    edges.insert(m);
                }
            }
        }
    }
    g
}

/// The names a text reaches below `prefix` (`super::` or `crate::<folder>::`),
/// also inside `prefix{a, b}`; a `super::` preceded by another path segment
/// (`super::super::x`) is not the folder's.
fn paths_below(src: &str, prefix: &str) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    let name = |s: &str| -> String {
        s.trim()
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect()
    };
    for (i, _) in src.match_indices(prefix) {
        let before = src[..i].chars().next_back();
        if before.is_some_and(|c| c == ':' || c.is_alphanumeric() || c == '_') {
            continue;
        }
        let rest = &src[i + prefix.len()..];
        match rest.strip_prefix('{') {
            Some(group) => {
                for item in group[..group.find('}').unwrap_or(group.len())].split(',') {
                    out.insert(name(item));
                }
            }
            None => {
                out.insert(name(rest));
            }
        }
    }
    out.retain(|n| !n.is_empty() && n != "super" && n != "self");
    out
}

/// The graph of the files of every folder below the layers' folders, at any
/// depth, as `folder/file` (`io/plus/sequence`): each file of a folder, and
/// each of its sub-folders as one member.
fn file_graph(src: &Path) -> Graph {
    let mut g = Graph::new();
    for (folder, _) in LAYERS {
        folder_graph(src, &src.join(folder), &mut g);
    }
    g
}

/// Adds the edges among the members of `dir` (and of every folder below it).
fn folder_graph(src: &Path, dir: &Path, g: &mut Graph) {
    if !dir.is_dir() {
        return;
    }
    let folder = dir.strip_prefix(src).unwrap().to_string_lossy().replace('\\', "/");
    let module = folder.replace('/', "::");
    // Each file of the folder, and each sub-folder as one member: its name,
    // its sources and whether they are the folder's own files (whose `super::`
    // is this folder).
    let mut members: BTreeMap<String, (Vec<std::path::PathBuf>, bool)> = BTreeMap::new();
    for entry in std::fs::read_dir(dir).unwrap().flatten() {
        let path = entry.path();
        let stem = path.file_stem().unwrap().to_string_lossy().to_string();
        if path.is_dir() {
            let mut files = Vec::new();
            rust_files(&path, &mut files);
            members.insert(stem, (files, false));
            folder_graph(src, &path, g);
        } else if path.extension().is_some_and(|e| e == "rs") && stem != "mod" {
            members.insert(stem, (vec![path], true));
        }
    }
    for (name, (files, own)) in &members {
        let key = format!("{folder}/{name}");
        let edges = g.entry(key).or_default();
        for f in files {
            let text = without_tests(&std::fs::read_to_string(f).unwrap());
            let mut reached = paths_below(&text, &format!("crate::{module}::"));
            if *own {
                reached.extend(paths_below(&text, "super::"));
            }
            for other in reached {
                if &other != name && members.contains_key(&other) {
                    edges.insert(format!("{folder}/{other}"));
                }
            }
        }
    }
}

#[test]
fn no_file_imports_from_a_file_that_imports_it_back() {
    let g = file_graph(&common::root().join("src"));
    assert!(
        g.get("pipeline/run").is_some_and(|e| e.contains("pipeline/frames")),
        "the reader finds edges between files: {g:?}"
    );
    assert!(
        g.get("io/plus/sequence")
            .is_some_and(|e| e.contains("io/plus/sequence_header")),
        "the reader looks into folders at every depth: {g:?}"
    );
    assert_eq!(cycle(&g), None, "files of one folder that import each other");
}

/// Edges that point to a module of the same or a higher layer.
fn upward(g: &Graph, layers: &BTreeMap<String, usize>) -> Vec<String> {
    let mut out = Vec::new();
    for (from, to) in g {
        for t in to {
            if layers[t] >= layers[from] {
                out.push(format!("{from} (layer {}) -> {t} (layer {})", layers[from], layers[t]));
            }
        }
    }
    out
}

/// A cycle, if the graph has one: the modules along it.
fn cycle(g: &Graph) -> Option<Vec<String>> {
    fn visit(n: &str, g: &Graph, path: &mut Vec<String>, done: &mut BTreeSet<String>) -> Option<Vec<String>> {
        if let Some(at) = path.iter().position(|p| p == n) {
            return Some(path[at..].to_vec());
        }
        if done.contains(n) {
            return None;
        }
        path.push(n.to_string());
        for next in g.get(n).into_iter().flatten() {
            if let Some(c) = visit(next, g, path, done) {
                return Some(c);
            }
        }
        path.pop();
        done.insert(n.to_string());
        None
    }
    let mut done = BTreeSet::new();
    g.keys().find_map(|n| visit(n, g, &mut Vec::new(), &mut done))
}

fn layers() -> BTreeMap<String, usize> {
    LAYERS.iter().map(|(m, l)| (m.to_string(), *l)).collect()
}

#[test]
fn layers_point_down_and_nothing_cycles() {
    let src = common::root().join("src");
    let on_disk: BTreeSet<String> = std::fs::read_dir(&src)
        .unwrap()
        .flatten()
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().to_string();
            let name = name.strip_suffix(".rs").map(str::to_string).unwrap_or(name);
            (name != "main" && name != "lib").then_some(name)
        })
        .collect();
    let known: BTreeSet<String> = layers().into_keys().collect();
    assert_eq!(
        on_disk, known,
        "every top-level module of src/ has a layer here, and no other"
    );
    let g = graph(&src);
    assert!(g["pipeline"].contains("detect"), "the reader finds edges: {g:?}");
    let up = upward(&g, &layers());
    assert!(up.is_empty(), "imports that point up or sideways:\n{}", up.join("\n"));
    assert_eq!(cycle(&g), None);
}

#[test]
fn the_checks_catch_planted_faults() {
    let planted = |edges: &[(&str, &str)]| {
        let mut g = Graph::new();
        for (a, b) in edges {
            g.entry(a.to_string()).or_default().insert(b.to_string());
            g.entry(b.to_string()).or_default();
        }
        g
    };
    let g = planted(&[("core", "report"), ("pipeline", "detect")]);
    assert_eq!(upward(&g, &layers()), vec!["core (layer 0) -> report (layer 8)"]);
    let g = planted(&[("detect", "estimate")]);
    assert_eq!(
        upward(&g, &layers()).len(),
        1,
        "a sideways edge in one layer is refused"
    );
    let g = planted(&[("io", "detect"), ("detect", "evaluate"), ("evaluate", "io")]);
    assert_eq!(cycle(&g).map(|c| c.len()), Some(3));
    assert_eq!(cycle(&planted(&[("report", "core")])), None);
    let src =
        "use crate::core::geometry;\nuse crate::{io, spec::rig};\n#[cfg(test)]\nmod tests {\n use crate::report;\n}\n";
    let found = crate_paths(&without_tests(src));
    let below = paths_below(
        "use super::{a, b::C};\nuse super::super::x;\nlet y = crate::io::z::w;",
        "super::",
    );
    assert_eq!(below, ["a", "b"].iter().map(|s| s.to_string()).collect());
    assert_eq!(found, ["core", "io", "spec"].iter().map(|s| s.to_string()).collect());
}

#[test]
fn files_stay_small_and_main_only_dispatches() {
    let mut files = Vec::new();
    rust_files(&common::root().join("src"), &mut files);
    let lines = |p: &Path| std::fs::read_to_string(p).unwrap().lines().count();
    let long: Vec<String> = files
        .iter()
        .filter(|f| lines(f) > 600)
        .map(|f| format!("{} ({} lines)", f.display(), lines(f)))
        .collect();
    assert!(long.is_empty(), "source files above 600 lines: {long:?}");
    let main = lines(&common::root().join("src/main.rs"));
    assert!(
        main <= 20,
        "src/main.rs has {main} lines; it only calls probecal::cli::main"
    );
}

/// The lines of `files` (tests and comments aside) holding any of `needles`.
fn lines_holding(files: &[std::path::PathBuf], needles: &[&str]) -> Vec<String> {
    let mut found = Vec::new();
    for f in files {
        let text = without_tests(&std::fs::read_to_string(f).unwrap());
        for line in text.lines().filter(|l| !l.trim_start().starts_with("//")) {
            if needles.iter().any(|n| line.contains(n)) {
                found.push(format!("{}: {}", f.display(), line.trim()));
            }
        }
    }
    found
}

/// The whole-file reads of `src` outside `io/fs.rs` (tests aside): each reader
/// goes through `io::fs::read_capped`, which reads no more than its limit
/// whatever the file's metadata says (`/dev/zero` claims 0 bytes and never ends).
fn unbounded_reads(files: &[std::path::PathBuf]) -> Vec<String> {
    let outside: Vec<std::path::PathBuf> = files.iter().filter(|f| !f.ends_with("io/fs.rs")).cloned().collect();
    lines_holding(&outside, &["fs::read(", "fs::read_to_string("])
}

#[test]
fn every_whole_file_read_has_a_limit() {
    let mut files = Vec::new();
    rust_files(&common::root().join("src"), &mut files);
    let found = unbounded_reads(&files);
    assert!(
        found.is_empty(),
        "whole-file reads without a limit (use io::fs::read_capped or read_text_capped): {found:#?}"
    );
    // The check sees a planted read.
    let dir = common::scratch("architecture", "reads");
    std::fs::create_dir_all(&dir).unwrap();
    let planted = dir.join("planted.rs");
    std::fs::write(&planted, "fn f() { let _ = std::fs::read_to_string(\"x\"); }\n#[cfg(test)]\nmod tests { fn g() { let _ = std::fs::read(\"y\"); } }\n").unwrap();
    assert_eq!(unbounded_reads(&[planted]).len(), 1);
}

/// Lines of `src` (tests aside) that write HTML tags: pages are rendered from
/// templates, where one escaping applies.
fn html_in_rust(files: &[std::path::PathBuf]) -> Vec<String> {
    lines_holding(
        files,
        &[
            "<html", "<p>", "<table", "<tr>", "<td", "<th", "<h1", "<h2", "<div", "<img", "<figure", "<svg", "<ul",
            "<li>",
        ],
    )
}

#[test]
fn pages_are_written_by_templates_not_rust_strings() {
    let mut files = Vec::new();
    rust_files(&common::root().join("src"), &mut files);
    let found = html_in_rust(&files);
    assert!(
        found.is_empty(),
        "HTML written in Rust (use a template in templates/): {found:#?}"
    );
    let dir = common::scratch("architecture", "html");
    std::fs::create_dir_all(&dir).unwrap();
    let planted = dir.join("planted.rs");
    std::fs::write(&planted, "fn f() -> String { format!(\"<tr><td>{}</td></tr>\", 1) }\n").unwrap();
    assert_eq!(html_in_rust(&[planted]).len(), 1);
}

/// The `Result<_, String>` lines of the files, tests and comments left out.
fn string_errors(files: &[std::path::PathBuf]) -> Vec<String> {
    let mut found = Vec::new();
    for f in files {
        let text = without_tests(&std::fs::read_to_string(f).unwrap());
        for line in text.lines().filter(|l| !l.trim_start().starts_with("//")) {
            let at = line.find("Result<");
            if at.is_some_and(|a| line[a..].contains(", String>")) {
                found.push(format!("{}: {}", f.display(), line.trim()));
            }
        }
    }
    found
}

#[test]
fn string_errors_do_not_grow() {
    let mut files = Vec::new();
    rust_files(&common::root().join("src"), &mut files);
    // Errors carried as bare strings, tests aside: none (each error has a type
    // whose message is what the console prints; clap's value parsers take one too).
    let found = string_errors(&files);
    assert!(
        found.is_empty(),
        "`Result<_, String>` in src (give each error a type): {found:#?}"
    );
    // The check sees a planted one, and not one in a test module.
    let dir = common::scratch("architecture", "string_errors");
    std::fs::create_dir_all(&dir).unwrap();
    let planted = dir.join("planted.rs");
    std::fs::write(
        &planted,
        "fn f() -> Result<u8, String> { Ok(1) }\n#[cfg(test)]\nmod tests { fn g() -> Result<u8, String> { Ok(1) } }\n",
    )
    .unwrap();
    assert_eq!(string_errors(&[planted]).len(), 1);
}

/// The folders of `layer` (itself included) holding more than `most` `.rs` files
/// directly.
fn crowded_folders(layer: &Path, most: usize) -> Vec<String> {
    let mut crowded = Vec::new();
    let mut folders = vec![layer.to_path_buf()];
    while let Some(folder) = folders.pop() {
        let mut files = 0;
        for entry in std::fs::read_dir(&folder).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                folders.push(path);
            } else if path.extension().is_some_and(|e| e == "rs") {
                files += 1;
            }
        }
        if files > most {
            crowded.push(format!("{} ({files} files)", folder.display()));
        }
    }
    crowded.sort();
    crowded
}

/// The stage layers that hold applications (`pipeline/`, `report/`) keep one
/// room (a sub-folder) per application: at most 12 files directly in each.
#[test]
fn application_layers_are_sorted_into_rooms() {
    let src = common::root().join("src");
    for layer in ["pipeline", "report"] {
        let crowded = crowded_folders(&src.join(layer), 12);
        assert!(
            crowded.is_empty(),
            "more than 12 files directly in a folder (sort them into rooms): {crowded:?}"
        );
    }
    // The check sees a crowded layer and a crowded room.
    let dir = common::scratch("architecture", "rooms");
    std::fs::create_dir_all(dir.join("layer/room")).unwrap();
    for i in 0..13 {
        std::fs::write(dir.join(format!("layer/room/f{i}.rs")), "").unwrap();
    }
    assert_eq!(crowded_folders(&dir.join("layer"), 12).len(), 1);
    for i in 0..13 {
        std::fs::write(dir.join(format!("layer/f{i}.rs")), "").unwrap();
    }
    assert_eq!(crowded_folders(&dir.join("layer"), 12).len(), 2);
}

/// Lines of the files (tests and comments aside) that name the manifest module.
fn manifest_reads(files: &[std::path::PathBuf]) -> Vec<String> {
    lines_holding(files, &["crate::manifest", "manifest::", "manifest.yaml"])
}

/// The pages render from the results model and the labels `pipeline::labels`
/// reads from a manifest once: nothing in `report/` names the manifest.
#[test]
fn report_reads_no_manifest() {
    let mut files = Vec::new();
    rust_files(&common::root().join("src/report"), &mut files);
    let found = manifest_reads(&files);
    assert!(found.is_empty(), "report/ reads a manifest: {found:#?}");
    let dir = common::scratch("architecture", "manifest_reads");
    std::fs::create_dir_all(&dir).unwrap();
    let planted = dir.join("planted.rs");
    std::fs::write(
        &planted,
        "use crate::manifest::Manifest;\n// crate::manifest in a comment\nlet copy = run.join(\"manifest.yaml\");\n",
    )
    .unwrap();
    assert_eq!(manifest_reads(&[planted]).len(), 2);
}
