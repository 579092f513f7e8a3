//! (being moved here from the CLI: see the crate documentation)
