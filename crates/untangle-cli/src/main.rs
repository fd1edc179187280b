//! The `untangle` command-line tool: argument parsing, progress display, files and exit codes on
//! top of the `untangle` library.
//!
//! Exit codes: 0 success (nothing left intersecting), 1 intersections found or left, 2 error.

mod commands;
mod output;
mod pictures;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// Find, classify and remove self- and inter-penetrations in cloth and garment meshes.
#[derive(Parser, Debug)]
#[command(name = "untangle", version, about, long_about = None)]
struct Cli {
    /// Print nothing but errors (no summary, no progress bar).
    #[arg(long, short, global = true)]
    quiet: bool,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long, global = true)]
    threads: Option<usize>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Analyse meshes: find, trace, classify and colour every tanglement.
    Check(commands::check::Args),
    /// Remove self-intersections by simulation (Cha & Ko 2022).
    Fix(commands::fix::Args),
    /// Write a procedural test scene with a known answer.
    Scene(commands::scene::Args),
    /// Simulate cloth (implicit, with full-proof collision handling) and write the result.
    Simulate(commands::simulate::Args),
    /// Run the main job on a built-in tangled example; results go to ./untangle-demo/.
    Demo(commands::demo::Args),
    /// Dress a body in layered garments and untangle them implicitly (Buffet et al. 2019).
    Layers(commands::layers::Args),
}

/// A clap message on one line: without its "error: " prefix, usage and help hints.
fn one_line(msg: &str) -> String {
    msg.lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with("Usage:") && !l.starts_with("For more"))
        .map(|l| l.strip_prefix("error: ").unwrap_or(l))
        .collect::<Vec<_>>()
        .join(" ")
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            if !e.use_stderr() {
                // --help, --version
                let _ = e.print();
                return ExitCode::SUCCESS;
            }
            eprintln!("error: command line: {}", one_line(&e.to_string()));
            return ExitCode::from(2);
        }
    };
    if let Some(n) = cli.threads {
        if let Err(e) = rayon::ThreadPoolBuilder::new()
            .num_threads(n.max(1))
            .build_global()
        {
            eprintln!("error: cannot start {n} threads: {e}");
            return ExitCode::from(2);
        }
    }
    let ctx = output::Context { quiet: cli.quiet };
    let result = match cli.command {
        Command::Check(a) => commands::check::run(a, &ctx),
        Command::Fix(a) => commands::fix::run(a, &ctx),
        Command::Scene(a) => commands::scene::run(a, &ctx),
        Command::Demo(a) => commands::demo::run(a, &ctx),
        Command::Layers(a) => commands::layers::run(a, &ctx),
        Command::Simulate(a) => commands::simulate::run(a, &ctx),
    };
    match result {
        Ok(code) => ExitCode::from(code),
        Err(e) => {
            // One line: what is wrong and where. A cause whose text its context already quotes
            // (library errors include their source) is not repeated.
            let mut msg = String::new();
            for cause in e.chain() {
                let text = cause.to_string();
                if !msg.contains(&text) {
                    if !msg.is_empty() {
                        msg.push_str(": ");
                    }
                    msg.push_str(&text);
                }
            }
            let msg = msg.replace('\n', " ");
            eprintln!("error: {msg}");
            ExitCode::from(2)
        }
    }
}
