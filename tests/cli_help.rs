//! The command line's help is true and complete: every argument of every
//! subcommand has a help line, `--help` works for each, and `docs/cli.md` is what
//! the definitions say (`UPDATE_DOCS=1 cargo test --test cli_help` rewrites it).

mod common;

use probecal::cli::docs;

#[test]
fn every_argument_of_every_subcommand_has_help() {
    let missing = docs::arguments_without_help();
    assert!(missing.is_empty(), "arguments without help: {missing:?}");
}

#[test]
fn every_subcommand_answers_help() {
    let page = docs::markdown();
    let names: Vec<&str> = page.lines().filter_map(|l| l.strip_prefix("## ")).collect();
    assert!(names.len() >= 15, "{names:?}");
    for name in names {
        let out = common::probecal()
            .args(name.split(' ').chain(["--help"]))
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{name} --help: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(text.contains("Usage: probecal"), "{name} --help:\n{text}");
    }
}

#[test]
fn docs_cli_md_is_the_command_lines_own_help() {
    let path = common::root().join("docs/cli.md");
    let fresh = docs::markdown();
    if std::env::var_os("UPDATE_DOCS").is_some() {
        std::fs::write(&path, &fresh).unwrap();
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        committed == fresh,
        "docs/cli.md differs from the command line's help; run `UPDATE_DOCS=1 cargo test --test cli_help`"
    );
}
