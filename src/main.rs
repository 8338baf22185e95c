//! The `probecal` command: everything is in [`probecal::cli`].

#[global_allocator]
static ALLOCATOR: probecal::core::large_pages::LargePages = probecal::core::large_pages::LargePages;

fn main() -> std::process::ExitCode {
    probecal::cli::main()
}
