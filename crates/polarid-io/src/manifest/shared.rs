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
        let kinds: Vec<(&str, _)> = ["position", "direction", "sun"]
            .into_iter()
            .filter_map(|k| p.get(t, k).map(|v| (k, v)))
            .collect();
        let [(kind, v)] = kinds[..] else {
            return Err(p.err(
                &it.span(),
                &field,
                "a source needs exactly one of `position`, `direction` or `sun`",
            ));
        };
        let kfield = format!("{field}.{kind}");
        let spec = match kind {
            "position" => SourceSpec::Position(p.numbers::<3>(v, &kfield)?),
            "direction" => {
                let d = p.numbers::<3>(v, &kfield)?;
                let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                if !(n.is_finite() && n > 0.0) {
                    return Err(p.err(&v.span(), &kfield, "direction must be non-zero"));
                }
                SourceSpec::Direction([d[0] / n, d[1] / n, d[2] / n])
            }
            _ => {
                let s = p.string(v, &kfield)?;
                if s.trim().is_empty() {
                    return Err(p.err(&v.span(), &kfield, "empty time"));
                }
                let Some(site) = site else {
                    return Err(p.err(
                        &v.span(),
                        &kfield,
                        "a `sun` source needs a [site] table (latitude_deg, longitude_deg, ...)",
                    ));
                };
                p.sun(s, site, v, &kfield)?
            }
        };
        out.push(SourceEntry {
            spec,
            line: p.line(v.span().start),
        });
    }
    Ok(out)
}
