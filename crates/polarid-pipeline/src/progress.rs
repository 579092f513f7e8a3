//! Progress reports and warnings: how a workflow talks to its caller without printing.

/// A progress callback: called with `(stage, done, total)` as work advances, e.g.
/// `("captures", 3, 10)`. `total` may be 0 when unknown. Front ends draw a bar (CLI) or
/// forward it to a Python callable; tests count the calls.
pub type Progress<'a> = &'a (dyn Fn(&str, u64, u64) + Sync);

/// A progress callback that ignores every report.
pub fn no_progress(_stage: &str, _done: u64, _total: u64) {}

/// Something the caller should tell the user, although the work succeeded (a saturated
/// region, a class absent from the model, targets left unclassified...).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Warning(pub String);

impl std::fmt::Display for Warning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}
