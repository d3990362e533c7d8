//! The `frameless` binary: command-line parsing (clap) over the library; errors are
//! reported with `anyhow` here and typed everywhere below.

mod cli;

fn main() -> std::process::ExitCode {
    cli::main(std::env::args_os())
}
