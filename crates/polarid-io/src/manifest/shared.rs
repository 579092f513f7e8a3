//! The calibrated-geometry tables of the manifest, parsed for other TOML files: the
//! scene files of `polarid simulate` describe the same `[camera]`, `[[plane]]` and
//! `[site]` tables, and list their light sources as tables holding one of `position`,
//! `direction` or `sun` (as a manifest capture's `source`). One parser, one set of
//! rules and error messages for both files.

use std::path::Path;

use super::calibration::{CameraSpec, PlaneSpec, SiteSpec, SourceSpec};
use super::{Parser, Result};

/// The `[camera]`, `[[plane]]` and `[site]` tables of a TOML document, validated as in a
/// manifest (the camera in front of every plane; without `[[plane]]`, the default plane).
#[derive(Debug, Clone, PartialEq)]
pub struct GeometryTables {
    /// The camera, if the document has a `[camera]` table.
    pub camera: Option<CameraSpec>,
    /// The planes (never empty).
    pub planes: Vec<PlaneSpec>,
    /// The site, if any.
    pub site: Option<SiteSpec>,
}

/// A light source of a list of sources (see [`parse_sources`]).
#[derive(Debug, Clone, PartialEq)]
pub struct SourceEntry {
    /// The source (a `sun` resolved at `[site]`).
    pub spec: SourceSpec,
    /// 1-based line of its `position`, `direction` or `sun` key.
    pub line: usize,
}

/// Parse the `[camera]`, `[[plane]]` and `[site]` tables of `text` (`path` labels
/// errors) with the manifest's rules and messages (docs/FORMATS.md, "Calibrated
/// geometry"). Unknown keys inside them are ignored here (the caller decides).
///
/// Errors: [`IoError::Manifest`](crate::IoError::Manifest) naming the line and the field (`camera.up`,
/// `plane[2].normal`, `site.latitude_deg`, ...).
pub fn parse_geometry_tables(path: &Path, text: &str) -> Result<GeometryTables> {
    let p = Parser::new(path, text, true);
    let root = p.parse_root()?;
    let root = root.get_ref();
    let camera = p.camera(root)?;
    let planes = p.planes(root, camera.as_ref())?;
    let site = p.site(root)?;
    Ok(GeometryTables {
        camera,
        planes,
        site,
    })
}

/// Parse the array of tables `key` of `text` as light sources: each table holds exactly
/// one of `position = [x, y, z]`, `direction = [x, y, z]` (normalized) or
/// `sun = "RFC 3339 time"` (resolved at `site` as in a manifest); its other keys are
/// ignored here. Fields are named `KEY[i].position` (1-based). An absent `key` gives an
/// empty list.
///
/// Errors: [`IoError::Manifest`](crate::IoError::Manifest) naming the line and the field.
pub fn parse_sources(
    path: &Path,
    text: &str,
    key: &str,
    site: Option<&SiteSpec>,
) -> Result<Vec<SourceEntry>> {
    let p = Parser::new(path, text, true);
    let root = p.parse_root()?;
    let Some(av) = p.get(root.get_ref(), key) else {
        return Ok(Vec::new());
    };
    let mut out = Vec::new();
    for (i, it) in p.array(av, key)?.iter().enumerate() {
        let field = format!("{key}[{}]", i + 1);
        let t = p.table(it, &field)?;
        let (spec, line) = p.source_spec(t, &field, &it.span(), site)?;
        out.push(SourceEntry { spec, line });
    }
    Ok(out)
}
