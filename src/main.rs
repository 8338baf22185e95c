//! The `probecal` command: everything is in [`probecal::cli`].

fn main() -> std::process::ExitCode {
    probecal::cli::main()
}
