//! A region's in-scene reference (docs/FORMATS.md "In-scene reference"): a region of
//! known material measured with the targets, which `classify` uses to calibrate the
//! polarimeter scale and the common angle offset (docs/CLASSIFY.md).
//!
//! ```toml
//! [[region]]
//! name = "slide"
//! rect = [300, 40, 60, 60]
//! reference = "N-BK7"            # a material of the built-in library
//! # or: reference_n = 1.5168, reference_k = 0.0   (k optional, default 0)
//! ```
//!
//! `reference` must name a material of the built-in library (`polarid library --list
//! builtin`); another material is given by its index, `reference_n` (finite, > 0) and
//! `reference_k` (finite, >= 0; default 0), the same at every band. A region has one or
//! the other, not both.

use super::{Parser, Result, Table};
use crate::library::Library;
use crate::table::measurements::Reference;

impl Parser<'_> {
    /// A region's `reference` or `reference_n`/`reference_k` (`None` without them).
    pub(super) fn region_reference(&self, t: &Table<'_>, pre: &str) -> Result<Option<Reference>> {
        let name = self.get(t, "reference");
        let n = self.opt_num(t, "reference_n", pre)?;
        let k = self.opt_num(t, "reference_k", pre)?;
        if let Some(v) = name {
            let field = format!("{pre}reference");
            if n.is_some() || k.is_some() {
                let other = if n.is_some() {
                    "reference_n"
                } else {
                    "reference_k"
                };
                return Err(self.err(
                    &v.span(),
                    &field,
                    format!(
                        "give either a material name (reference) or an index \
                         (reference_n, reference_k), not both (found {pre}{other} too)"
                    ),
                ));
            }
            let s = self.string(v, &field)?;
            let s = s.trim();
            if s.is_empty() {
                return Err(self.err(&v.span(), &field, "empty material name"));
            }
            let lib = Library::builtin()?;
            if !lib.names().contains(&s) {
                let why = lib.unknown_material(s);
                return Err(self.err(
                    &v.span(),
                    &field,
                    format!(
                        "{why}; for another material give its index as reference_n and \
                         reference_k"
                    ),
                ));
            }
            return Ok(Some(Reference::Material(s.to_string())));
        }
        match (n, k) {
            (None, None) => Ok(None),
            (None, Some((_, span))) => Err(self.err(
                &span,
                &format!("{pre}reference_k"),
                "reference_k needs reference_n (the real part of the reference's index)",
            )),
            (Some((n, span)), k) => {
                if !(n > 0.0) {
                    return Err(self.err(
                        &span,
                        &format!("{pre}reference_n"),
                        "the reference's n must be > 0",
                    ));
                }
                let k = match k {
                    Some((k, span)) if !(k >= 0.0) => {
                        return Err(self.err(
                            &span,
                            &format!("{pre}reference_k"),
                            "the reference's k must be >= 0",
                        ));
                    }
                    Some((k, _)) => k,
                    None => 0.0,
                };
                Ok(Some(Reference::Index { n, k }))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use crate::table::measurements::Reference;

    fn region(extra: &str) -> String {
        format!(
            "theta_r_deg = 60.0\n[[region]]\nname = \"A\"\nrect = [0, 0, 2, 2]\n{extra}\n\
             [[capture]]\ntheta_i_deg = 50.0\n\
             stokes = {{ s0 = \"s0.tif\", s1 = \"s1.tif\", s2 = \"s2.tif\" }}\n"
        )
    }

    fn parse(extra: &str) -> crate::error::Result<Option<Reference>> {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        for f in ["s0.tif", "s1.tif", "s2.tif"] {
            std::fs::write(dir.join(f), b"x").unwrap();
        }
        let m = super::super::parse(&dir.join("m.toml"), &region(extra));
        m.map(|m| m.regions[0].reference.clone())
    }

    #[test]
    fn references_are_parsed_and_checked() {
        assert_eq!(parse("").unwrap(), None);
        assert_eq!(
            parse("reference = \"N-BK7\"").unwrap(),
            Some(Reference::Material("N-BK7".into()))
        );
        assert_eq!(
            parse("reference_n = 1.5\nreference_k = 0.01").unwrap(),
            Some(Reference::Index { n: 1.5, k: 0.01 })
        );
        assert_eq!(
            parse("reference_n = 1.5").unwrap(),
            Some(Reference::Index { n: 1.5, k: 0.0 })
        );
        for (extra, field, value) in [
            ("reference = \"N-BK8\"", "region[1].reference", "N-BK8"),
            ("reference = \"\"", "region[1].reference", "\"\""),
            ("reference = 3", "region[1].reference", "3"),
            ("reference_n = -1.5", "region[1].reference_n", "-1.5"),
            (
                "reference_n = 1.5\nreference_k = -0.1",
                "region[1].reference_k",
                "-0.1",
            ),
            ("reference_k = 0.1", "region[1].reference_k", "0.1"),
            (
                "reference = \"N-BK7\"\nreference_n = 1.5",
                "region[1].reference",
                "N-BK7",
            ),
        ] {
            let e = parse(extra).unwrap_err().to_string();
            assert!(
                e.contains("m.toml") && e.contains(field) && e.contains(value),
                "{extra}: {e}"
            );
        }
        let e = parse("reference = \"N-BK8\"").unwrap_err().to_string();
        assert!(e.contains("N-BK7"), "suggests the near name: {e}");
    }

    #[test]
    fn the_column_text_round_trips() {
        for r in [
            Reference::Material("N-BK7".into()),
            Reference::Index { n: 1.5168, k: 0.0 },
            Reference::Index { n: 2.5, k: 1e-3 },
        ] {
            assert_eq!(Reference::parse(&r.text()), Some(r.clone()));
        }
        assert_eq!(Reference::parse(""), None);
        assert_eq!(
            Reference::parse("a+b"),
            Some(Reference::Material("a+b".into()))
        );
    }

    #[test]
    fn measure_carries_the_reference_into_the_rows() {
        let dir = tempfile::tempdir().unwrap();
        let (w, h) = (8, 6);
        for (k, v) in [(0, 1000.0f32), (1, 300.0), (2, 0.0)] {
            let data = vec![v; w * h];
            crate::image::write_tiff_f32(&dir.path().join(format!("s{k}.tif")), false, w, h, &data)
                .unwrap();
        }
        let text = "theta_r_deg = 50.0\n\
             [[region]]\nname = \"slide\"\nrect = [0, 0, 4, 4]\nreference = \"N-BK7\"\n\
             [[region]]\nname = \"A\"\nrect = [4, 0, 4, 4]\n\
             [[capture]]\ntheta_i_deg = 50.0\n\
             stokes = { s0 = \"s0.tif\", s1 = \"s1.tif\", s2 = \"s2.tif\" }\n";
        let path = dir.path().join("m.toml");
        std::fs::write(&path, text).unwrap();
        let m = crate::manifest::load(&path).unwrap();
        let rows = crate::measure::measure_manifest(&m, &mut |_| {}).unwrap();
        assert_eq!(rows[0].reference, Some(Reference::Material("N-BK7".into())));
        assert_eq!(rows[1].reference, None);
        let mut buf = Vec::new();
        crate::table::measurements::write(&mut buf, Path::new("m.csv"), &rows).unwrap();
        let csv = String::from_utf8(buf).unwrap();
        assert!(csv.lines().next().unwrap().ends_with(",reference"), "{csv}");
        assert!(csv.lines().nth(1).unwrap().ends_with(",N-BK7"), "{csv}");
    }
}
