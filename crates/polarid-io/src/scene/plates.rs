//! The `[[plate]]` tables: unique names, optics `(n, k, σ, ρd)`, a rectangle inside the
//! frame that overlaps no other plate, and a measured region inside it (by default
//! [`default_region`]).

use std::collections::HashSet;

use polarid_core::region::Rect;
use polarid_core::simulate::PlateOptics;
use toml::Spanned;

use super::colour::MaterialSource;
use super::context::Ctx;
use super::raw::RawPlate;
use super::{Placement, Plate, SceneBand};
use crate::error::Result;

/// The default measured region of a plate: the plate inset by an eighth of its smaller
/// side (at least 2 pixels), with an even corner and even size so that it holds whole
/// 2×2 DoFP super-pixels.
pub fn default_region(rect: Rect) -> Option<Rect> {
    let inset = (rect.width.min(rect.height) / 8).max(2);
    let x = (rect.x + inset).next_multiple_of(2);
    let y = (rect.y + inset).next_multiple_of(2);
    let x1 = (rect.x + rect.width).checked_sub(inset)?;
    let y1 = (rect.y + rect.height).checked_sub(inset)?;
    let w = x1.checked_sub(x)? / 2 * 2;
    let h = y1.checked_sub(y)? / 2 * 2;
    (w >= 2 && h >= 2).then_some(Rect {
        x,
        y,
        width: w,
        height: h,
    })
}

/// What the plates' values depend on: the capture's bands (colour scenes), the scene's
/// wavelength and its library (for `material`).
pub(super) struct PlateContext<'a> {
    pub(super) bands: Option<&'a [SceneBand]>,
    pub(super) wavelength_nm: Option<f64>,
    pub(super) materials: &'a MaterialSource<'a>,
}

/// What every plate gives, far field or calibrated: name, class, optics, line.
pub(super) struct PlateBasics {
    pub(super) name: String,
    pub(super) class: Option<String>,
    pub(super) optics: PlateOptics,
    pub(super) bands: Vec<PlateOptics>,
    pub(super) material: Option<String>,
    pub(super) line: usize,
    pub(super) name_span: std::ops::Range<usize>,
}

impl PlateBasics {
    /// The plate of these basics with its bounding box `rect`, measured `region` and
    /// (calibrated scenes) `placement`.
    pub(super) fn into_plate(
        self,
        rect: Rect,
        region: Rect,
        placement: Option<Placement>,
    ) -> Plate {
        Plate {
            name: self.name,
            class: self.class,
            optics: self.optics,
            bands: self.bands,
            material: self.material,
            rect,
            region,
            placement,
            line: self.line,
        }
    }
}

impl Ctx<'_> {
    /// The name (unique among `names`), class and optics of plate `i` (0-based).
    pub(super) fn plate_basics(
        &self,
        p: &RawPlate,
        i: usize,
        names: &mut HashSet<String>,
        cx: &PlateContext<'_>,
    ) -> Result<PlateBasics> {
        let pre = format!("plate[{}].", i + 1);
        let f = |k: &str| format!("{pre}{k}");
        let name_v = p
            .name
            .as_ref()
            .ok_or_else(|| self.missing(None, &f("name"), "plate name"))?;
        let near = Some(name_v.span());
        let near = near.as_ref();
        let name = self.name(name_v, &f("name"))?;
        if !names.insert(name.clone()) {
            return Err(self.err(&name_v.span(), &f("name"), "duplicate plate name"));
        }
        let class = match &p.class {
            Some(v) if v.get_ref().trim().is_empty() => None,
            Some(v) => Some(self.name(v, &f("class"))?),
            None => None,
        };
        let sigma_v = p
            .sigma
            .as_ref()
            .ok_or_else(|| self.missing(near, &f("sigma"), "roughness `sigma`"))?;
        let sigma = self.num_in(
            sigma_v,
            &f("sigma"),
            |x| (1e-3..=10.0).contains(&x),
            "in [0.001, 10] (slope standard deviation)",
        )?;
        let nb = cx.bands.map_or(1, <[SceneBand]>::len);
        let rho_d = match &p.rho_d {
            Some(v) => self.per_band(
                v,
                &f("rho_d"),
                cx.bands,
                |x| (0.0..=1.0).contains(&x),
                "in [0, 1]",
            )?,
            None => vec![0.0; nb],
        };
        let nk: Vec<(f64, f64)> = match &p.material {
            Some(m) => {
                for (key, v) in [("n", &p.n), ("k", &p.k)] {
                    if let Some(v) = v {
                        return Err(self.err(
                            &v.span(),
                            &f(key),
                            "give either `material` (the index from the library) or `n` and \
                             `k`, not both",
                        ));
                    }
                }
                self.material_nk(cx.materials, m, &f("material"), cx.bands, cx.wavelength_nm)?
            }
            None => {
                let req = |v: &Option<Spanned<toml::Value>>, key: &str, what: &str| {
                    v.as_ref()
                        .ok_or_else(|| self.missing(near, &f(key), what))
                        .cloned()
                };
                let n = self.per_band(
                    &req(
                        &p.n,
                        "n",
                        "real part of the index `n` (or a library `material`)",
                    )?,
                    &f("n"),
                    cx.bands,
                    |x| x > 0.0 && x <= 100.0,
                    "in (0, 100]",
                )?;
                let k = self.per_band(
                    &req(&p.k, "k", "imaginary part of the index `k`")?,
                    &f("k"),
                    cx.bands,
                    |x| (0.0..=100.0).contains(&x),
                    "in [0, 100]",
                )?;
                n.into_iter().zip(k).collect()
            }
        };
        let per_band: Vec<PlateOptics> = nk
            .iter()
            .zip(&rho_d)
            .map(|(&(n, k), &rho_d)| PlateOptics { n, k, sigma, rho_d })
            .collect();
        let optics = per_band[0];
        let class = class.or_else(|| p.material.as_ref().map(|m| m.get_ref().clone()));
        Ok(PlateBasics {
            name,
            class,
            optics,
            bands: if cx.bands.is_some() {
                per_band
            } else {
                Vec::new()
            },
            material: p.material.as_ref().map(|m| m.get_ref().clone()),
            line: self.line(name_v.span().start),
            name_span: name_v.span(),
        })
    }

    /// The plates of `raw` (at least one): each one is what `plate` makes of its table
    /// and its [`PlateBasics`], given the plates made before it and the table's field
    /// names (`plate[2].rect`).
    pub(super) fn each_plate<T>(
        &self,
        raw: &[RawPlate],
        cx: &PlateContext<'_>,
        mut plate: impl FnMut(&[T], &RawPlate, PlateBasics, &dyn Fn(&str) -> String) -> Result<T>,
    ) -> Result<Vec<T>> {
        if raw.is_empty() {
            return Err(self.missing(None, "plate", "[[plate]]: at least one plate is needed"));
        }
        let mut names = HashSet::new();
        let mut out = Vec::with_capacity(raw.len());
        for (i, p) in raw.iter().enumerate() {
            let f = |k: &str| format!("plate[{}].{k}", i + 1);
            let b = self.plate_basics(p, i, &mut names, cx)?;
            out.push(plate(&out, p, b, &f)?);
        }
        Ok(out)
    }

    /// The far-field plates: each one in its `rect`, overlapping no other.
    pub(super) fn plates(
        &self,
        raw: &[RawPlate],
        width: usize,
        height: usize,
        cx: &PlateContext<'_>,
    ) -> Result<Vec<Plate>> {
        self.each_plate(raw, cx, |plates: &[Plate], p, b, f| {
            let near = Some(b.name_span.clone());
            let near = near.as_ref();
            self.refuse(
                [
                    ("plane", p.plane.as_ref().map(|v| v.span())),
                    ("center", p.center.as_ref().map(|v| v.span())),
                    ("size", p.size.as_ref().map(|v| v.span())),
                    ("axis", p.axis.as_ref().map(|v| v.span())),
                ],
                f,
                "plates are placed on planes only in calibrated scenes (with a [camera] \
                 table); a far-field plate takes `rect`",
            )?;
            let rect_v = p
                .rect
                .as_ref()
                .ok_or_else(|| self.missing(near, &f("rect"), "plate rectangle `rect`"))?;
            let rect = self.rect(rect_v, &f("rect"))?;
            if let Err(e) = rect.check(width, height) {
                return Err(self.err(&rect_v.span(), &f("rect"), e.to_string()));
            }
            for q in plates {
                let overlap = rect.x < q.rect.x + q.rect.width
                    && q.rect.x < rect.x + rect.width
                    && rect.y < q.rect.y + q.rect.height
                    && q.rect.y < rect.y + rect.height;
                if overlap {
                    return Err(self.err(
                        &rect_v.span(),
                        &f("rect"),
                        format!("overlaps plate {:?}", q.name),
                    ));
                }
            }
            let region = match &p.region {
                Some(v) => {
                    let r = self.rect(v, &f("region"))?;
                    let inside = r.x >= rect.x
                        && r.y >= rect.y
                        && r.x + r.width <= rect.x + rect.width
                        && r.y + r.height <= rect.y + rect.height;
                    if !inside {
                        return Err(self.err(
                            &v.span(),
                            &f("region"),
                            format!(
                                "the region must lie inside the plate's rect [{}, {}, {}, {}]",
                                rect.x, rect.y, rect.width, rect.height
                            ),
                        ));
                    }
                    r
                }
                None => default_region(rect).ok_or_else(|| {
                    self.err(
                        &rect_v.span(),
                        &f("rect"),
                        "plate too small for a default region; give `region`",
                    )
                })?,
            };
            Ok(b.into_plate(rect, region, None))
        })
    }
}
