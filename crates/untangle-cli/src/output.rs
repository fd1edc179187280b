//! Shared output helpers: quiet mode, safe output paths, progress bars.

use anyhow::{bail, Result};
use std::path::{Path, PathBuf};

/// Options every command sees.
pub struct Context {
    /// Print nothing but errors.
    pub quiet: bool,
}

impl Context {
    /// Prints a summary line unless quiet.
    pub fn say(&self, s: impl AsRef<str>) {
        if !self.quiet {
            println!("{}", s.as_ref());
        }
    }

    /// A progress bar (hidden when quiet or not on a terminal).
    #[allow(dead_code)]
    pub fn progress(&self, len: u64, msg: &str) -> indicatif::ProgressBar {
        if self.quiet {
            return indicatif::ProgressBar::hidden();
        }
        let pb = indicatif::ProgressBar::new(len);
        pb.set_style(
            indicatif::ProgressStyle::with_template(
                "{msg} [{bar:30}] {pos}/{len} {per_sec} eta {eta}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
            .progress_chars("=> "),
        );
        pb.set_message(msg.to_string());
        pb
    }
}

fn canonical(p: &Path) -> Option<PathBuf> {
    std::fs::canonicalize(p).ok()
}

/// Refuses an output path that is one of the inputs (outputs never overwrite inputs).
pub fn check_output(out: &Path, inputs: &[&Path]) -> Result<()> {
    if let Some(co) = canonical(out) {
        for i in inputs {
            if canonical(i).as_ref() == Some(&co) {
                bail!("{}: refusing to overwrite an input file", out.display());
            }
        }
    }
    Ok(())
}
