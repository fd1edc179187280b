//! Helpers shared by the end-to-end tests: run the `untangle` binary, read its output.

#![allow(dead_code)] // each test file uses part of this

use std::path::Path;
use std::process::{Command, Output};

/// Runs `untangle ARGS` in `dir`.
pub fn untangle(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_untangle"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("runs")
}

/// Standard error as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Standard output as text.
pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// A JSON file, parsed.
pub fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}
