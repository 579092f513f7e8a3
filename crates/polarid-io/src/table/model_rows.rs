//! Rows of `polarid model` (to be written).
