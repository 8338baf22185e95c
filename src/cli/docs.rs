//! `docs/cli.md`, written from the command line's own definitions, so the page
//! and `--help` cannot say different things (`tests/cli_help.rs` compares them).

use std::fmt::Write as _;

use clap::CommandFactory;

use super::Cli;

/// One argument's line: its form, its help, its default.
fn argument(arg: &clap::Arg) -> String {
    let form = match (arg.get_long(), arg.get_value_names()) {
        (Some(long), Some(names)) if arg.get_action().takes_values() => {
            format!("--{long} <{}>", names.join("> <"))
        }
        (Some(long), _) => format!("--{long}"),
        (None, Some(names)) => format!("<{}>", names.join("> <")),
        (None, None) => format!("<{}>", arg.get_id().as_str().to_uppercase()),
    };
    let many = if arg.get_num_args().is_some_and(|n| n.max_values() > 1) {
        "..."
    } else {
        ""
    };
    let help = arg
        .get_long_help()
        .or(arg.get_help())
        .map(|h| h.to_string())
        .unwrap_or_default();
    let defaults: Vec<String> = arg
        .get_default_values()
        .iter()
        .map(|v| v.to_string_lossy().into_owned())
        .collect();
    let default = if defaults.is_empty() || !arg.get_action().takes_values() {
        String::new()
    } else {
        format!(" Default: `{}`.", defaults.join(" "))
    };
    let required = if arg.is_required_set() { " Required." } else { "" };
    let help = help.replace('\n', " ");
    let stop = if help.ends_with('.') || help.is_empty() {
        ""
    } else {
        "."
    };
    format!("- `{form}{many}`: {help}{stop}{required}{default}")
}

/// The Markdown page of every subcommand: what it does, its usage, every argument.
pub fn markdown() -> String {
    let mut cli = Cli::command();
    cli.build();
    let mut page = String::new();
    let _ = writeln!(page, "# Command line\n");
    let _ = writeln!(
        page,
        "Generated from `probecal --help` (`src/cli/`); `tests/cli_help.rs` fails when it drifts\n\
         (`UPDATE_DOCS=1 cargo test --test cli_help` writes it again). Exit codes: 0 success,\n\
         1 a dataset or a command's work failed, 2 bad manifest, input or usage, 3 an accuracy\n\
         gate failed (the outputs are written all the same).\n"
    );
    let mut commands: Vec<(String, clap::Command)> = Vec::new();
    for sub in cli.get_subcommands_mut() {
        let name = sub.get_name().to_string();
        commands.push((name.clone(), sub.clone()));
        for nested in sub.get_subcommands_mut() {
            commands.push((format!("{name} {}", nested.get_name()), nested.clone()));
        }
    }
    for (name, mut sub) in commands {
        if name == "help" || name.starts_with("help ") || name.ends_with(" help") {
            continue;
        }
        let sub = &mut sub;
        let about = sub
            .get_long_about()
            .or(sub.get_about())
            .map(|a| a.to_string())
            .unwrap_or_default();
        let usage = sub.render_usage().to_string();
        let usage = usage.trim_start_matches("Usage: ").to_string();
        let usage = if usage.starts_with("probecal") {
            usage
        } else {
            format!("probecal {usage}")
        };
        let about = about.replace('\n', " ");
        let stop = if about.ends_with('.') { "" } else { "." };
        let _ = writeln!(page, "## {name}\n\n{about}{stop}\n\n```text\n{usage}\n```\n");
        for arg in sub.get_arguments() {
            let id = arg.get_id().as_str();
            if id == "help" || id == "version" {
                continue;
            }
            let _ = writeln!(page, "{}", argument(arg));
        }
        let _ = writeln!(page);
    }
    page.trim_end().to_string() + "\n"
}

/// Every argument of every subcommand (nested ones too) without a help line,
/// as `subcommand argument`.
pub fn arguments_without_help() -> Vec<String> {
    fn walk(cmd: &clap::Command, path: &str, missing: &mut Vec<String>) {
        for sub in cmd.get_subcommands().filter(|s| s.get_name() != "help") {
            let name = format!("{path}{}", sub.get_name());
            if sub.get_about().is_none() {
                missing.push(format!("{name} (the command itself)"));
            }
            for arg in sub.get_arguments() {
                let id = arg.get_id().as_str();
                if id != "help" && id != "version" && arg.get_help().is_none() && arg.get_long_help().is_none() {
                    missing.push(format!("{name} {id}"));
                }
            }
            walk(sub, &format!("{name} "), missing);
        }
    }
    let mut cli = Cli::command();
    cli.build();
    let mut missing = Vec::new();
    walk(&cli, "", &mut missing);
    missing
}
