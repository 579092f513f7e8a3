//! The subcommands, one module each.

pub mod classify;
pub mod common;
pub mod demo;
pub mod evaluate;
pub mod fit;
pub mod init;
pub mod library;
pub mod map;
pub mod measure;
pub mod model;
pub mod plan;
pub mod simulate;
pub mod stokes;
pub mod train;
pub mod wolff;
