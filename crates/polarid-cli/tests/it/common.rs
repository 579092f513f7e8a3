//! Helpers shared by the CLI integration tests (each test file includes this module
//! and uses what it needs).
#![allow(dead_code)]

use std::path::Path;
use std::process::{Command, Output};

/// The `polarid` binary under test, as a command to configure.
pub fn polarid_cmd() -> Command {
    Command::new(env!("CARGO_BIN_EXE_polarid"))
}

/// Run `polarid ARGS` in the current directory.
pub fn polarid(args: &[&str]) -> Output {
    polarid_cmd().args(args).output().expect("run polarid")
}

/// Run `polarid ARGS` in `dir`.
pub fn polarid_in(dir: &Path, args: &[&str]) -> Output {
    polarid_cmd()
        .current_dir(dir)
        .args(args)
        .output()
        .expect("run polarid")
}

/// Output bytes as text (lossy UTF-8).
pub fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// Rows of a CSV (no quoted fields), comment lines skipped, as header -> value maps.
pub fn csv_rows(path: &Path) -> Vec<std::collections::HashMap<String, String>> {
    let text = std::fs::read_to_string(path).expect("read CSV");
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let header: Vec<String> = lines
        .next()
        .expect("CSV header")
        .split(',')
        .map(str::to_string)
        .collect();
    lines
        .map(|l| {
            header
                .iter()
                .cloned()
                .zip(l.split(',').map(str::to_string))
                .collect()
        })
        .collect()
}
