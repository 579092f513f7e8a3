//! docs/COMMANDS.md is the command synopsis, generated from the program's own help: this
//! test rebuilds the page from `polarid --help` and `polarid COMMAND --help` and fails when
//! the committed page differs, so the page cannot drift from clap's definitions.
//!
//! After a deliberate change of an option or its help text:
//! `POLARID_BLESS=1 cargo test --release -p polarid-cli --test it commands_page::`.

use crate::common;

use std::path::Path;

const PAGE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/COMMANDS.md");

/// `polarid ARGS` with a fixed help width, as text.
fn help(args: &[&str]) -> String {
    let out = common::polarid_cmd()
        .args(args)
        .env("COLUMNS", "100")
        .output()
        .expect("run polarid");
    assert!(out.status.success(), "polarid {args:?} failed");
    common::text(&out.stdout).trim_end().to_string()
}

/// The subcommands listed under "Commands:" in the top-level help (without `help`), each
/// with its description (a wrapped description's continuation lines joined).
fn subcommands(top: &str) -> Vec<(String, String)> {
    let mut out: Vec<(String, String)> = Vec::new();
    let listed = top
        .lines()
        .skip_while(|l| !l.starts_with("Commands:"))
        .skip(1)
        .take_while(|l| l.starts_with("  "));
    for l in listed {
        if l.starts_with("   ") {
            if let Some((_, what)) = out.last_mut() {
                what.push(' ');
                what.push_str(l.trim());
            }
            continue;
        }
        let mut it = l.trim_start().splitn(2, ' ');
        let c = it.next().unwrap_or_default().to_string();
        out.push((c, it.next().unwrap_or_default().trim().to_string()));
    }
    out.retain(|(c, _)| c != "help");
    out
}

fn page() -> String {
    let top = help(&["--help"]);
    let cmds = subcommands(&top);
    assert!(cmds.len() >= 10, "too few commands found in:\n{top}");
    let mut s = String::from(
        "# polarid commands\n\n\
         The synopsis of every command, exactly as `polarid --help` and\n\
         `polarid COMMAND --help` print it (this page is generated from the program and a\n\
         test keeps it current). The file formats the commands read and write are in\n\
         [FORMATS.md](FORMATS.md); the exit statuses in\n\
         [FORMATS.md](FORMATS.md#exit-statuses).\n\n",
    );
    s.push_str("| command | what |\n| --- | --- |\n");
    for (c, what) in &cmds {
        s.push_str(&format!("| [`{c}`](#polarid-{c}) | {what} |\n"));
    }
    s.push_str("\n## polarid\n\n```text\n");
    s.push_str(&top);
    s.push_str("\n```\n");
    for (c, _) in &cmds {
        s.push_str(&format!("\n## polarid {c}\n\n```text\n"));
        s.push_str(&help(&[c, "--help"]));
        s.push_str("\n```\n");
    }
    s
}

#[test]
fn commands_page_matches_the_programs_help() {
    let want = page();
    if std::env::var_os("POLARID_BLESS").is_some() {
        std::fs::write(PAGE, &want).expect("write docs/COMMANDS.md");
        return;
    }
    let got = std::fs::read_to_string(Path::new(PAGE)).unwrap_or_default();
    if got != want {
        let first = got
            .lines()
            .zip(want.lines())
            .position(|(a, b)| a != b)
            .unwrap_or(got.lines().count().min(want.lines().count()));
        panic!(
            "docs/COMMANDS.md differs from the program's help from line {} on; \
             regenerate it: POLARID_BLESS=1 cargo test --release -p polarid-cli --test it \
             commands_page::",
            first + 1
        );
    }
}
