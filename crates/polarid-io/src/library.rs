//! Material libraries: literature values of the complex index `N = n + ik` that estimates
//! are compared with (`polarid classify --library`), and a reader for the YAML files of
//! the refractiveindex.info database, to build a library for any filter band.
//!
//! # Library CSV
//!
//! `name,n,k` with optional `category` (`metal`, `dielectric`, `semiconductor`,
//! `other`), `reference` and `wavelength_nm`; other columns are ignored. A multi-band
//! library has `wavelength_nm` (the band's centre) and one row per material per band;
//! the rows of one `name` are the bands of one material ([`Library::multi_prototypes`]). When `n` / `k` are absent the
//! reader uses `n_band` / `k_band` (the band means of the shared
//! `library_650nm.csv` format), so that file can be used as it is.
//!
//! Two libraries are built into polarid (embedded in the binary):
//!
//! - `builtin` — 39 materials at 650 nm, the band means over 610–690 nm of
//!   `data/library_650nm.csv`, from the refractiveindex.info database (CC0; cite
//!   M. N. Polyanskiy, Sci. Data 11, 94 (2024) and the measurement in each row's
//!   `reference`);
//! - `paper2007` — the reference values of the paper's Table 1 (green paint, aluminum,
//!   copper; `data/paper_2007.csv`);
//! - `builtin-rgb` — the same 39 materials in the three bands of colour polarization
//!   sensors, 80 nm wide like the 650 nm band: 410–490 nm (`wavelength_nm` 450),
//!   510–590 nm (550) and 610–690 nm (650, the values of `builtin`), band means sampled
//!   every nm (`data/library_rgb.csv`, made by `polarid library --band 410:490 --band
//!   510:590 --band 610:690`, docs/BANDS.md). A material whose data do not cover a band
//!   lacks that band's row.
//!
//! Every built-in material carries its native surface layer as it is found (an oxide or
//! adsorbed contamination, [`crate::surfaces`], docs/MATERIALS.md): [`Material::layer`],
//! the layer's index evaluated over the same band as the bulk's. Library CSV files give
//! layers in the optional columns [`LAYER_COLUMNS`].
//!
//! `builtin`'s rows have no `wavelength_nm` column; as multi-band prototypes they are the
//! 650 nm band. Both built-in libraries of the refractiveindex.info materials can be
//! evaluated at any wavelength their data cover ([`Library::at_wavelengths`], from the
//! embedded files [`BUILTIN_SOURCES`]), so that data at 500 or 800 nm are compared with
//! the materials at 500 or 800 nm.
//!
//! # refractiveindex.info YAML
//!
//! [`RiiData`] reads one database file: `DATA` entries of type `tabulated nk`,
//! `tabulated n`, `tabulated k` and `formula 1` … `formula 9` (wavelengths in µm), and
//! evaluates `n(λ)`, `k(λ)` — tabulated data linearly interpolated, formulas evaluated
//! directly, never extrapolated, `k = 0` when the file gives only `n`.
//! [`RiiData::band_mean`] averages them over a band sampled every `step` nm, the method
//! of `library_650nm.csv` (610–690 nm, 1 nm steps, 81 samples).
//!
//! The formulas (coefficients `C1, C2, …`, `λ` in µm; missing trailing coefficients are
//! zero, as in the database):
//!
//! | type | formula |
//! |---|---|
//! | 1 Sellmeier | `n² − 1 = C1 + Σ C(2i) λ² / (λ² − C(2i+1)²)` |
//! | 2 Sellmeier-2 | `n² − 1 = C1 + Σ C(2i) λ² / (λ² − C(2i+1))` |
//! | 3 polynomial | `n² = C1 + Σ C(2i) λ^C(2i+1)` |
//! | 4 RefractiveIndex.INFO | `n² = C1 + C2 λ^C3/(λ² − C4^C5) + C6 λ^C7/(λ² − C8^C9) + Σ_{i≥5} C(2i) λ^C(2i+1)` |
//! | 5 Cauchy | `n = C1 + Σ C(2i) λ^C(2i+1)` |
//! | 6 gases | `n − 1 = C1 + Σ C(2i) / (C(2i+1) − λ⁻²)` |
//! | 7 Herzberger | `n = C1 + C2/(λ² − 0.028) + C3/(λ² − 0.028)² + C4 λ² + C5 λ⁴ + C6 λ⁶` |
//! | 8 Retro | `(n² − 1)/(n² + 2) = C1 + C2 λ²/(λ² − C3) + C4 λ²` |
//! | 9 Exotic | `n² = C1 + C2/(λ² − C3) + C4 (λ − C5)/((λ − C5)² + C6)` |

use std::path::Path;

use polarid_core::classify::{
    BandPoint, MultiPrototype, NativeLayer, Prototype, check_class_name, same_band,
};

use crate::error::{IoError, Result};
use crate::surfaces::{builtin_surface, layer_index, layer_index_builtin_band};
use crate::table::{BandedRow, CsvTable, fmt_f64, fmt_opt, write_banded};

pub use crate::rii::{Dispersion, RiiData, formula};
use crate::rii::{ParsedOnce, parsed_once};

/// The built-in 650 nm library (refractiveindex.info, CC0), as shipped.
pub const BUILTIN_CSV: &str = include_str!("../data/library_650nm.csv");
/// The paper's Table 1 reference values.
pub const PAPER_2007_CSV: &str = include_str!("../data/paper_2007.csv");
/// Columns written by [`Library::write_csv`].
pub const CSV_COLUMNS: [&str; 5] = ["name", "category", "n", "k", "reference"];
/// The surface-layer columns of a library CSV (optional on input; written after
/// [`CSV_COLUMNS`] when some material has a layer).
pub const LAYER_COLUMNS: [&str; 5] = [
    "layer",
    "layer_n",
    "layer_k",
    "layer_min_nm",
    "layer_max_nm",
];
/// The built-in three-band library (450, 550, 650 nm; refractiveindex.info, CC0).
pub const BUILTIN_RGB_CSV: &str = include_str!("../data/library_rgb.csv");
/// Names accepted by [`Library::load`] for the built-in libraries.
pub const BUILTIN_NAMES: [&str; 3] = ["builtin", "paper2007", "builtin-rgb"];
/// The band (nm) of the `builtin` library's values (means over 610–690 nm).
pub const BUILTIN_WAVELENGTH_NM: f64 = 650.0;

/// One material of a library.
#[derive(Debug, Clone, PartialEq)]
pub struct Material {
    /// Material name (becomes the class name).
    pub name: String,
    /// Category (`metal`, `dielectric`, `semiconductor`, `other`), when given.
    pub category: Option<String>,
    /// Real part of the index.
    pub n: f64,
    /// Imaginary part of the index.
    pub k: f64,
    /// Literature reference, when given.
    pub reference: Option<String>,
    /// Line of the library file.
    pub line: u64,
    /// Centre wavelength of the band, nm (multi-band libraries).
    pub wavelength_nm: Option<f64>,
    /// The material's native surface layer as it is found (oxide or contamination), with
    /// its index at this row's band; `None`: no layer known.
    pub layer: Option<MaterialLayer>,
}

/// A material's native surface layer in one row of a library: the layer material, its
/// index at the row's band (the same band as the row's `n`, `k`) and the range of
/// thicknesses found on real surfaces.
#[derive(Debug, Clone, PartialEq)]
pub struct MaterialLayer {
    /// Layer material, e.g. `Al2O3`, `Cu2O`, `contamination`.
    pub name: String,
    /// Its index `(n, k)` at the row's band; `None` where its data do not cover the band.
    pub index: Option<(f64, f64)>,
    /// Thinnest layer found on real surfaces, nm (`>= 0`).
    pub min_nm: f64,
    /// Thickest layer found on real surfaces, nm (`>= min_nm`).
    pub max_nm: f64,
}

/// A material library.
#[derive(Debug, Clone, PartialEq)]
pub struct Library {
    /// `builtin`, `paper2007` or the file it was read from.
    pub source: String,
    /// The materials, in file order.
    pub materials: Vec<Material>,
}

impl Library {
    /// The built-in 650 nm library (39 materials, band means over 610–690 nm), with
    /// their native surfaces ([`crate::surfaces`]).
    pub fn builtin() -> Result<Self> {
        Self::from_csv_text("builtin", BUILTIN_CSV)?.with_builtin_surfaces()
    }

    /// The built-in three-band library (450, 550, 650 nm; see the module documentation),
    /// with the materials' native surfaces.
    pub fn builtin_rgb() -> Result<Self> {
        Self::from_csv_text("builtin-rgb", BUILTIN_RGB_CSV)?.with_builtin_surfaces()
    }

    /// The paper's Table 1 reference values, with the materials' native surfaces.
    pub fn paper_2007() -> Result<Self> {
        Self::from_csv_text("paper2007", PAPER_2007_CSV)?.with_builtin_surfaces()
    }

    /// Give every material without a layer that has a built-in native surface
    /// ([`crate::surfaces::BUILTIN_SURFACES`], by name) that surface, its layer index the
    /// band mean over the row's band (`wavelength_nm ± 40 nm`, every nm; rows without a
    /// wavelength are the 650 nm band), the band of the built-in bulk values.
    pub fn with_builtin_surfaces(mut self) -> Result<Self> {
        for m in &mut self.materials {
            let Some(s) = builtin_surface(&m.name).filter(|_| m.layer.is_none()) else {
                continue;
            };
            let wl = m.wavelength_nm.unwrap_or(BUILTIN_WAVELENGTH_NM);
            m.layer = Some(MaterialLayer {
                name: s.layer.to_string(),
                index: layer_index_builtin_band(s.layer, wl)?,
                min_nm: s.min_nm,
                max_nm: s.max_nm,
            });
        }
        Ok(self)
    }

    /// A built-in library by name (`builtin`, `builtin-rgb`, `paper2007`), or else a
    /// library CSV file. A spec that is neither (no such file) is an error naming it, with
    /// the nearest built-in names (`bultin`: "did you mean `builtin`?").
    pub fn load(spec: &str) -> Result<Self> {
        match spec {
            "builtin" => Self::builtin(),
            "paper2007" => Self::paper_2007(),
            "builtin-rgb" => Self::builtin_rgb(),
            _ => {
                let path = Path::new(spec);
                match std::fs::symlink_metadata(path) {
                    // Not found: an operating-system "not found" error (exit status 2,
                    // Python's FileNotFoundError) whose message lists the built-in names.
                    Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                        return Err(IoError::io(
                            path,
                            std::io::Error::new(
                                std::io::ErrorKind::NotFound,
                                format!(
                                    "No such file, and not a built-in library ({}){}",
                                    BUILTIN_NAMES.join(", "),
                                    crate::suggest::did_you_mean(
                                        // A scene's spec arrives joined to the scene's folder.
                                        &path.file_name().map_or_else(
                                            || spec.to_string(),
                                            |f| f.to_string_lossy().into_owned()
                                        ),
                                        BUILTIN_NAMES
                                    )
                                ),
                            ),
                        ));
                    }
                    Err(e) => return Err(IoError::io(path, e)),
                    Ok(_) => {}
                }
                Self::read_csv(path)
            }
        }
    }

    /// The names of the materials, each once, in file order.
    pub fn names(&self) -> Vec<&str> {
        let mut out: Vec<&str> = Vec::new();
        for m in &self.materials {
            if !out.contains(&m.name.as_str()) {
                out.push(&m.name);
            }
        }
        out
    }

    /// The message for a material `name` that is not in this library: the library, the
    /// nearest names (edit distance or a shared word: `Gold (Au)` → `gold`) and how to
    /// list them all.
    pub fn unknown_material(&self, name: &str) -> String {
        let hint = crate::suggest::did_you_mean(name, self.names());
        format!(
            "no material {name:?} in library {}{hint} (`polarid library --list {}` lists \
             the names)",
            self.source, self.source
        )
    }

    /// Read a library CSV file.
    pub fn read_csv(path: &Path) -> Result<Self> {
        let t = CsvTable::read(path)?;
        Self::from_table(&t, path.display().to_string())
    }

    /// Parse library CSV text; `label` names it in errors and in [`Library::source`].
    pub fn from_csv_text(label: &str, text: &str) -> Result<Self> {
        let t = CsvTable::from_reader(Path::new(label), text.as_bytes())?;
        Self::from_table(&t, label.to_string())
    }

    fn from_table(t: &CsvTable, source: String) -> Result<Self> {
        let c_name = t.require("name")?;
        let c_n = match t.col("n") {
            Some(c) => c,
            None => t.col("n_band").map_or_else(|| t.require("n"), Ok)?,
        };
        let c_k = match t.col("k") {
            Some(c) => c,
            None => t.col("k_band").map_or_else(|| t.require("k"), Ok)?,
        };
        let c_cat = t.col("category");
        let c_ref = t.col("reference");
        let c_wl = t.col("wavelength_nm");
        let layer_cols = Self::layer_columns(t)?;
        let mut materials: Vec<Material> = Vec::with_capacity(t.rows.len());
        for r in 0..t.rows.len() {
            let name = t.name(r, c_name)?;
            if let Err(e) = check_class_name(&name) {
                return Err(t.err(r, c_name, e.to_string()));
            }
            let n = t.f64(r, c_n)?;
            if n <= 0.0 {
                return Err(t.err(r, c_n, "n must be > 0"));
            }
            let k = t.f64(r, c_k)?;
            if k < 0.0 {
                return Err(t.err(r, c_k, "k must be >= 0"));
            }
            let wavelength_nm = t.opt_f64(r, c_wl)?;
            if let Some(c) = c_wl {
                match wavelength_nm {
                    Some(w) if !(w.is_finite() && w > 0.0) => {
                        return Err(t.err(r, c, "wavelength must be finite and > 0 nm"));
                    }
                    None => {
                        return Err(t.err(
                            r,
                            c,
                            "missing wavelength (a multi-band library needs one on every row)",
                        ));
                    }
                    Some(w) => {
                        if let Some(m) = materials.iter().find(|m| {
                            m.name == name
                                && polarid_core::classify::same_band(m.wavelength_nm, Some(w))
                        }) {
                            return Err(t.err(
                                r,
                                c,
                                format!(
                                    "material {name:?} already has this band (line {})",
                                    m.line
                                ),
                            ));
                        }
                    }
                }
            }
            let layer = match layer_cols {
                Some(c) => Self::layer_cell(t, r, c)?,
                None => None,
            };
            if let Some(prev) = materials.iter().find(|m| m.name == name) {
                let same = match (&prev.layer, &layer) {
                    (None, None) => true,
                    (Some(a), Some(b)) => {
                        a.name == b.name && a.min_nm == b.min_nm && a.max_nm == b.max_nm
                    }
                    _ => false,
                };
                if !same {
                    // ok: layer columns exist when the layers differ.
                    let c = layer_cols.map_or(c_name, |c| c[0]);
                    return Err(t.err(
                        r,
                        c,
                        format!(
                            "material {name:?} has another surface layer on line {} (the rows \
                             of one material must give the same layer and thickness range)",
                            prev.line
                        ),
                    ));
                }
            }
            materials.push(Material {
                name,
                category: t.opt_text(r, c_cat),
                n,
                k,
                reference: t.opt_text(r, c_ref),
                line: t.rows[r].0, // ok: r < rows.len()
                wavelength_nm,
                layer,
            });
        }
        if materials.is_empty() {
            return Err(IoError::CsvStructure {
                path: t.path.clone(),
                reason: "the library has no materials".into(),
            });
        }
        Ok(Self { source, materials })
    }

    /// The columns [`LAYER_COLUMNS`], when the table has any of them (then it must have
    /// all five).
    fn layer_columns(t: &CsvTable) -> Result<Option<[usize; 5]>> {
        if LAYER_COLUMNS.iter().all(|c| t.col(c).is_none()) {
            return Ok(None);
        }
        let mut cols = [0; 5];
        for (slot, name) in cols.iter_mut().zip(LAYER_COLUMNS) {
            *slot = t.col(name).ok_or_else(|| IoError::CsvStructure {
                path: t.path.clone(),
                reason: format!(
                    "missing column `{name}`: a surface layer needs all of {} (columns are: \
                     {})",
                    LAYER_COLUMNS.join(","),
                    t.headers.join(",")
                ),
            })?;
        }
        Ok(Some(cols))
    }

    /// The layer of row `r`: empty `layer` cell → none (then the other layer cells must be
    /// empty); else `layer_min_nm`, `layer_max_nm` (`0 <= min <= max`), and `layer_n`,
    /// `layer_k` both given (`n > 0`, `k >= 0`) or both empty (no index at this band).
    fn layer_cell(t: &CsvTable, r: usize, c: [usize; 5]) -> Result<Option<MaterialLayer>> {
        let [c_layer, c_n, c_k, c_min, c_max] = c;
        let name = t.name(r, c_layer)?;
        if name.is_empty() {
            for &cc in &c[1..] {
                if !t.text(r, cc).is_empty() {
                    return Err(t.err(r, cc, "a layer value without a `layer` name"));
                }
            }
            return Ok(None);
        }
        let n = t.opt_f64(r, Some(c_n))?;
        let k = t.opt_f64(r, Some(c_k))?;
        let index = match (n, k) {
            (None, None) => None,
            (Some(n), Some(k)) => {
                if n <= 0.0 {
                    return Err(t.err(r, c_n, "layer n must be > 0"));
                }
                if k < 0.0 {
                    return Err(t.err(r, c_k, "layer k must be >= 0"));
                }
                Some((n, k))
            }
            (None, Some(_)) => {
                return Err(t.err(r, c_n, "missing value (layer_n and layer_k go together)"));
            }
            (Some(_), None) => {
                return Err(t.err(r, c_k, "missing value (layer_n and layer_k go together)"));
            }
        };
        let min_nm = t.f64(r, c_min)?;
        if min_nm < 0.0 {
            return Err(t.err(r, c_min, "layer thickness must be >= 0 nm"));
        }
        let max_nm = t.f64(r, c_max)?;
        if max_nm < min_nm {
            return Err(t.err(
                r,
                c_max,
                format!("layer_max_nm must be >= layer_min_nm ({min_nm})"),
            ));
        }
        Ok(Some(MaterialLayer {
            name,
            index,
            min_nm,
            max_nm,
        }))
    }

    /// Write the library as CSV with the columns [`CSV_COLUMNS`] (`name,category,n,k,reference`;
    /// empty cells for a missing category or reference; `wavelength_nm` after `category`
    /// when some material has one; the surface columns [`LAYER_COLUMNS`] last when some
    /// material has a layer), readable by [`Library::read_csv`].
    /// Each line of `comment` is written first as a `#` comment line, which the reader
    /// skips. `path` names the output in errors.
    pub fn write_csv<W: std::io::Write + ?Sized>(
        &self,
        w: &mut W,
        path: &Path,
        comment: Option<&str>,
    ) -> Result<()> {
        if let Some(c) = comment {
            for line in c.lines() {
                writeln!(w, "# {line}").map_err(|e| IoError::io(path, e))?;
            }
        }
        let rows = self.materials.iter().map(|m| BandedRow {
            cells: vec![
                m.name.clone(),
                m.category.clone().unwrap_or_default(),
                fmt_f64(m.n),
                fmt_f64(m.k),
                m.reference.clone().unwrap_or_default(),
            ],
            wavelength_nm: m.wavelength_nm,
            extra: m.layer.as_ref().map(|l| {
                vec![
                    l.name.clone(),
                    fmt_opt(l.index.map(|x| x.0)),
                    fmt_opt(l.index.map(|x| x.1)),
                    fmt_f64(l.min_nm),
                    fmt_f64(l.max_nm),
                ]
            }),
        });
        write_banded(w, path, &CSV_COLUMNS, &LAYER_COLUMNS, rows.collect())
    }

    /// The materials as classification prototypes with all their bands: the rows of one
    /// name are its bands (first-appearance order), class = name, no covariance, source
    /// `library <source> line <first line>`. The `builtin` library's rows are the 650 nm
    /// band ([`BUILTIN_WAVELENGTH_NM`]); rows of other libraries without `wavelength_nm`
    /// are single-band prototypes without a wavelength. A material's surface layer
    /// becomes [`MultiPrototype::surface`] (name and thickness range) and each band's
    /// [`BandPoint::layer`] (the layer's index at that band).
    pub fn multi_prototypes(&self) -> Vec<MultiPrototype> {
        let mut out: Vec<MultiPrototype> = Vec::new();
        for m in &self.materials {
            let wavelength_nm = m
                .wavelength_nm
                .or_else(|| (self.source == "builtin").then_some(BUILTIN_WAVELENGTH_NM));
            let band = BandPoint {
                wavelength_nm,
                n: m.n,
                k: m.k,
                cov: None,
                film: None,
                layer: m.layer.as_ref().and_then(|l| l.index),
            };
            match out.iter_mut().find(|p| p.class == m.name) {
                Some(p) if m.wavelength_nm.is_some() => p.bands.push(band),
                _ => out.push(MultiPrototype {
                    class: m.name.clone(),
                    category: m.category.clone(),
                    source: format!("library {} line {}", self.source, m.line),
                    bands: vec![band],
                    surface: m.layer.as_ref().map(|l| NativeLayer {
                        name: l.name.clone(),
                        min_nm: l.min_nm,
                        max_nm: l.max_nm,
                    }),
                }),
            }
        }
        out
    }

    /// The materials as classification prototypes (class = material name, no covariance,
    /// source `library <source> line <line>`).
    pub fn prototypes(&self) -> Vec<Prototype> {
        self.materials
            .iter()
            .map(|m| Prototype {
                class: m.name.clone(),
                n: m.n,
                k: m.k,
                cov: None,
                category: m.category.clone(),
                source: format!("library {} line {}", self.source, m.line),
            })
            .collect()
    }
}

/// One built-in material's refractiveindex.info file, embedded in the binary (the files of
/// `data/materials/refractiveindex` named in `data/materials/builtin_names.csv`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BuiltinSource {
    /// The material's name in the built-in libraries.
    pub name: &'static str,
    /// The file's path in the database (`shelf/book/nk/page.yml`).
    pub file: &'static str,
    /// The YAML text.
    pub text: &'static str,
}

/// The [`BuiltinSource`]s of `name => file` pairs, `file` a file of
/// `data/materials/refractiveindex` (embedded).
macro_rules! builtin_sources {
    ($($name:literal => $file:literal,)*) => {
        [$(BuiltinSource {
            name: $name,
            file: $file,
            text: include_str!(concat!("../../../data/materials/refractiveindex/", $file)),
        },)*]
    };
}

/// The files behind the built-in libraries, in library order: [`Library::at_wavelengths`]
/// evaluates the built-in materials at any wavelength their data cover.
pub const BUILTIN_SOURCES: [BuiltinSource; 39] = builtin_sources! {
    "aluminum" => "main/Al/nk/Rakic.yml",
    "copper" => "main/Cu/nk/Johnson.yml",
    "gold" => "main/Au/nk/Johnson.yml",
    "silver" => "main/Ag/nk/Johnson.yml",
    "iron" => "main/Fe/nk/Johnson.yml",
    "nickel" => "main/Ni/nk/Johnson.yml",
    "chromium" => "main/Cr/nk/Johnson.yml",
    "titanium" => "main/Ti/nk/Johnson.yml",
    "tungsten" => "main/W/nk/Weaver.yml",
    "zinc" => "main/Zn/nk/Werner.yml",
    "lead" => "main/Pb/nk/Golovashkin-293K.yml",
    "magnesium" => "main/Mg/nk/Hagemann.yml",
    "platinum" => "main/Pt/nk/Rakic-BB.yml",
    "brass_Cu70Zn30" => "other/alloys/Cu-Zn/nk/Querry-Cu70Zn30.yml",
    "stainless_steel_austenitic" => "other/alloys/stainless steel/nk/Karlsson-austenitic.yml",
    "silicon" => "main/Si/nk/Aspnes.yml",
    "germanium" => "main/Ge/nk/Aspnes.yml",
    "gallium_arsenide" => "main/GaAs/nk/Aspnes.yml",
    "graphite_o" => "main/C/nk/Djurisic-o.yml",
    "carbon_soot_acetylene" => "other/soots/acetylene soot/nk/Dalzell.yml",
    "hematite_Fe2O3_o" => "main/Fe2O3/nk/Querry-o.yml",
    "magnetite_Fe3O4" => "main/Fe3O4/nk/Querry.yml",
    "N-BK7" => "specs/schott/optical/N-BK7.yml",
    "fused_silica" => "main/SiO2/nk/Malitson.yml",
    "soda_lime_glass_clear" => "glass/misc/soda-lime/nk/Rubin-clear.yml",
    "sapphire_o" => "main/Al2O3/nk/Malitson-o.yml",
    "water" => "main/H2O/nk/Hale.yml",
    "ice" => "main/H2O/nk/Warren-2008.yml",
    "PMMA" => "organic/(C5H8O2)n - poly(methyl methacrylate)/nk/Sultanova.yml",
    "polycarbonate" => "organic/(C16H14O3)n - polycarbonate/nk/Sultanova.yml",
    "polystyrene" => "organic/(C8H8)n - polystyrene/nk/Sultanova.yml",
    "PET" => "organic/(C10H8O4)n - polyethylene terephthalate/nk/Zhang.yml",
    "PVC" => "organic/(C2H3Cl)n - polyvinyl chloride/nk/Zhang.yml",
    "PDMS_silicone_Sylgard184" =>
        "organic/(C2H6OSi)n - polydimethylsiloxane/nk/Schneider-Sylgard184.yml",
    "cellulose" => "organic/(C6H10O5)n - cellulose/nk/Sultanova.yml",
    "polyimide_Kapton_HN" => "other/commercial polymers/Kapton/nk/French.yml",
    "TiO2_rutile_o" => "main/TiO2/nk/Devore-o.yml",
    "ZnO_o" => "main/ZnO/nk/Bond-o.yml",
    "CaCO3_calcite_o" => "main/CaCO3/nk/Ghosh-o.yml",
};

/// The parsed [`BUILTIN_SOURCES`] (parsed once per process).
fn builtin_dispersion() -> Result<&'static [RiiData]> {
    static DATA: ParsedOnce<RiiData> = ParsedOnce::new();
    parsed_once(&DATA, "builtin", || {
        BUILTIN_SOURCES
            .iter()
            .map(|s| RiiData::parse(Path::new(s.file), s.text))
            .collect()
    })
}

/// Built-in materials a wavelength could not be evaluated at ([`Library::at_wavelengths`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Uncovered {
    /// The wavelength, nm.
    pub wavelength_nm: f64,
    /// The materials whose data do not cover it (left out at that wavelength).
    pub names: Vec<String>,
}

impl Library {
    /// Whether `spec` names a built-in library of the refractiveindex.info materials
    /// (`builtin`, `builtin-rgb`), which [`Library::at_wavelengths`] can evaluate at any
    /// wavelength.
    pub fn is_dispersive_builtin(spec: &str) -> bool {
        matches!(spec, "builtin" | "builtin-rgb")
    }

    /// The bands of this library's rows: `wavelength_nm`, or [`BUILTIN_WAVELENGTH_NM`] for
    /// the `builtin` library's rows.
    fn band_of(&self, m: &Material) -> Option<f64> {
        m.wavelength_nm
            .or_else(|| (self.source == "builtin").then_some(BUILTIN_WAVELENGTH_NM))
    }

    /// A built-in library (`builtin`, `builtin-rgb`) at the wavelengths of the data:
    /// a multi-band library with one row per material per wavelength. At a wavelength
    /// within [`BAND_TOLERANCE_NM`](polarid_core::classify::BAND_TOLERANCE_NM) of one of
    /// the built-in bands (450, 550, 650 nm: `builtin-rgb`'s rows, of which `builtin` is
    /// the 650 nm band) the built-in row is kept (its band mean, e.g. 550 nm: 510–590 nm,
    /// the row `polarid simulate` gives a plate of that material at that wavelength);
    /// at any other wavelength `λ` the material's `n(λ)`, `k(λ)` from its
    /// refractiveindex.info file ([`BUILTIN_SOURCES`], [`RiiData::nk`]: tabulated data
    /// linearly interpolated, formulas evaluated, never extrapolated), and its surface
    /// layer's index at the same `λ` (no index there when the layer's data do not cover
    /// it). A material whose data do not cover `λ` has no row there; the [`Uncovered`]
    /// list names them.
    /// Wavelengths must be finite and > 0 (others are skipped). Other libraries are
    /// returned unchanged with an empty list.
    pub fn at_wavelengths(&self, wavelengths: &[f64]) -> Result<(Library, Vec<Uncovered>)> {
        if !Self::is_dispersive_builtin(&self.source) {
            return Ok((self.clone(), Vec::new()));
        }
        let data = builtin_dispersion()?;
        let mut wls: Vec<f64> = Vec::new();
        for &w in wavelengths {
            if w.is_finite() && w > 0.0 && !wls.iter().any(|&x| same_band(Some(x), Some(w))) {
                wls.push(w);
            }
        }
        let mut names: Vec<&str> = Vec::new();
        for m in &self.materials {
            if !names.contains(&m.name.as_str()) {
                names.push(&m.name);
            }
        }
        let mut uncovered: Vec<Uncovered> = wls
            .iter()
            .map(|&w| Uncovered {
                wavelength_nm: w,
                names: Vec::new(),
            })
            .collect();
        // `builtin` is `builtin-rgb`'s 650 nm band: at 450 and 550 nm the same library's
        // band means (gold's n is 0.458 over 510–590 nm but 0.424 at 550 nm, 8% of its
        // DoLP: a plate of the library's gold would not be the library's gold).
        let rgb = if self.source == "builtin" {
            Some(Self::builtin_rgb()?)
        } else {
            None
        };
        let mut materials = Vec::new();
        for name in names {
            let rows: Vec<&Material> = self.materials.iter().filter(|m| m.name == name).collect();
            // ok: `name` was taken from `self.materials`.
            let first = rows[0];
            let source = BUILTIN_SOURCES.iter().position(|s| s.name == name);
            for (wi, &w) in wls.iter().enumerate() {
                if let Some(m) = rows.iter().find(|m| same_band(self.band_of(m), Some(w))) {
                    materials.push(Material {
                        wavelength_nm: self.band_of(m),
                        ..(*m).clone()
                    });
                    continue;
                }
                if let Some(m) = rgb.as_ref().and_then(|r| {
                    r.materials
                        .iter()
                        .find(|m| m.name == name && same_band(m.wavelength_nm, Some(w)))
                }) {
                    materials.push(Material {
                        line: first.line,
                        ..m.clone()
                    });
                    continue;
                }
                match source.map(|i| data[i].nk(w / 1000.0)) {
                    Some(Ok((n, k))) => {
                        // The layer's index at the same wavelength as the bulk's.
                        let layer = match &first.layer {
                            Some(l) => Some(MaterialLayer {
                                index: layer_index(&l.name, w, w, 1.0)?,
                                ..l.clone()
                            }),
                            None => None,
                        };
                        materials.push(Material {
                            n,
                            k,
                            wavelength_nm: Some(w),
                            layer,
                            ..first.clone()
                        })
                    }
                    _ => uncovered[wi].names.push(name.to_string()),
                }
            }
        }
        uncovered.retain(|u| !u.names.is_empty());
        Ok((
            Library {
                source: self.source.clone(),
                materials,
            },
            uncovered,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtin_libraries_load() {
        let lib = Library::builtin().unwrap();
        assert_eq!(lib.materials.len(), 39);
        let al = lib.materials.iter().find(|m| m.name == "aluminum").unwrap();
        // Band means (n_band, k_band) are used when there is no n, k column.
        assert_eq!((al.n, al.k), (1.56483, 7.6998));
        assert_eq!(al.category.as_deref(), Some("metal"));
        assert_eq!(al.line, 3);
        let p = Library::paper_2007().unwrap();
        assert_eq!(p.materials.len(), 3);
        assert_eq!((p.materials[1].n, p.materials[1].k), (1.24, 6.60));
    }

    #[test]
    fn library_errors_name_line_and_value() {
        let e = Library::from_csv_text("lib.csv", "name,n,k\nfoo,1.5,-1\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("lib.csv") && e.contains("line 2") && e.contains("-1"),
            "{e}"
        );
        let e = Library::from_csv_text("lib.csv", "name,n\nfoo,1.5\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("`k`"), "{e}");
        let e = Library::from_csv_text("lib.csv", "name,n,k\nunknown,1.5,0\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("reserved"), "{e}");
    }

    #[test]
    fn library_csv_round_trips() {
        let lib = Library::builtin().unwrap();
        let mut buf = Vec::new();
        lib.write_csv(
            &mut buf,
            Path::new("out.csv"),
            Some("band 610-690 nm\nsecond line"),
        )
        .unwrap();
        let text = String::from_utf8(buf).unwrap();
        assert!(text.starts_with(
            "# band 610-690 nm\n# second line\nname,category,n,k,reference,layer,layer_n,\
             layer_k,layer_min_nm,layer_max_nm\n"
        ));
        let back = Library::from_csv_text("out.csv", &text).unwrap();
        assert_eq!(back.materials.len(), lib.materials.len());
        for (a, b) in lib.materials.iter().zip(&back.materials) {
            assert_eq!(
                (&a.name, &a.category, a.n, a.k, &a.reference),
                (&b.name, &b.category, b.n, b.k, &b.reference)
            );
        }
        // A name with a comma and a missing category survive.
        let lib = Library {
            source: "x".into(),
            materials: vec![Material {
                name: "brass, yellow".into(),
                category: None,
                n: 0.5,
                k: 3.25,
                reference: Some("a \"quoted\" ref".into()),
                line: 0,
                wavelength_nm: None,
                layer: None,
            }],
        };
        let mut buf = Vec::new();
        lib.write_csv(&mut buf, Path::new("out.csv"), None).unwrap();
        let back = Library::from_csv_text("out.csv", std::str::from_utf8(&buf).unwrap()).unwrap();
        let m = &back.materials[0];
        assert_eq!(
            (m.name.as_str(), m.category.as_deref(), m.n, m.k),
            ("brass, yellow", None, 0.5, 3.25)
        );
        assert_eq!(m.reference.as_deref(), Some("a \"quoted\" ref"));
    }

    #[test]
    fn builtin_materials_carry_their_surfaces() {
        for lib in [
            Library::builtin().unwrap(),
            Library::builtin_rgb().unwrap(),
            Library::paper_2007().unwrap(),
        ] {
            for m in &lib.materials {
                let l = m
                    .layer
                    .as_ref()
                    .unwrap_or_else(|| panic!("{} {}", lib.source, m.name));
                assert!(
                    l.index.is_some(),
                    "{} {} {:?}",
                    lib.source,
                    m.name,
                    m.wavelength_nm
                );
            }
            let protos = lib.multi_prototypes();
            for p in &protos {
                assert!(p.surface.is_some(), "{}", p.class);
                assert!(p.bands.iter().all(|b| b.layer.is_some()), "{}", p.class);
            }
        }
        let lib = Library::builtin().unwrap();
        let protos = lib.multi_prototypes();
        let get = |name: &str| protos.iter().find(|p| p.class == name).unwrap();
        let al = get("aluminum");
        let s = al.surface.as_ref().unwrap();
        assert_eq!((s.name.as_str(), s.min_nm, s.max_nm), ("Al2O3", 2.0, 5.0));
        let (n, k) = al.bands[0].layer.unwrap();
        assert!((1.6..1.7).contains(&n) && k < 1e-3, "{n} {k}");
        assert_eq!(get("copper").surface.as_ref().unwrap().name, "Cu2O");
        assert_eq!(get("gold").surface.as_ref().unwrap().name, "contamination");
        assert_eq!(get("gold").bands[0].layer, Some((1.5, 0.0)));
        assert_eq!(get("nickel").surface.as_ref().unwrap().name, "NiO");
        let si = get("silicon");
        assert_eq!(si.surface.as_ref().unwrap().name, "SiO2");
        assert!((si.bands[0].layer.unwrap().0 - 1.4566).abs() < 1e-3);
        assert_eq!(get("N-BK7").surface.as_ref().unwrap().min_nm, 0.0);
        // builtin-rgb: the layer index at each row's band (dispersive Al2O3: higher in the blue).
        let rgb = Library::builtin_rgb().unwrap().multi_prototypes();
        let al = rgb.iter().find(|p| p.class == "aluminum").unwrap();
        let n: Vec<f64> = al.bands.iter().map(|b| b.layer.unwrap().0).collect();
        assert_eq!(al.bands.len(), 3);
        assert!(n[0] > n[1] && n[1] > n[2], "{n:?}");
    }

    #[test]
    fn at_wavelengths_evaluates_the_layer_at_the_bulk_wavelength() {
        let lib = Library::builtin().unwrap();
        let (at, _) = lib.at_wavelengths(&[500.0, 650.0, 900.0]).unwrap();
        let rows = |name: &str| -> Vec<&Material> {
            at.materials.iter().filter(|m| m.name == name).collect()
        };
        let si = rows("silicon");
        let (n500, _) = si[0].layer.as_ref().unwrap().index.unwrap();
        let fused = RiiData::parse(Path::new("s"), BUILTIN_SOURCES[23].text).unwrap();
        assert_eq!(BUILTIN_SOURCES[23].name, "fused_silica");
        assert!((n500 - fused.nk(0.5).unwrap().0).abs() < 1e-12);
        // 650 nm: the library's own row (band mean) keeps its band-mean layer.
        assert_eq!(
            si[1].layer,
            lib.materials
                .iter()
                .find(|m| m.name == "silicon")
                .unwrap()
                .layer
        );
        // Titanium at 900 nm: the bulk is covered, the amorphous TiO2 data (to 827 nm) are
        // not: the surface stays, without an index at that band.
        let ti = rows("titanium");
        let l = ti.iter().find(|m| m.wavelength_nm == Some(900.0)).unwrap();
        let l = l.layer.as_ref().unwrap();
        assert_eq!((l.name.as_str(), l.index), ("TiO2", None));
        let p = at.multi_prototypes();
        let ti = p.iter().find(|p| p.class == "titanium").unwrap();
        assert_eq!(ti.surface.as_ref().unwrap().name, "TiO2");
        assert_eq!(ti.bands.iter().filter(|b| b.layer.is_none()).count(), 1);
    }

    #[test]
    fn at_wavelengths_keeps_the_builtin_bands_band_means() {
        // `builtin` at 550 nm is `builtin-rgb`'s 550 nm row (510–590 nm), the index
        // `polarid simulate` gives a plate of the material at 550 nm; at 540 nm n(540).
        let lib = Library::builtin().unwrap();
        let rgb = Library::builtin_rgb().unwrap();
        let (at, _) = lib.at_wavelengths(&[550.2, 540.0]).unwrap();
        for name in ["gold", "copper", "silicon", "aluminum"] {
            let want = rgb
                .materials
                .iter()
                .find(|m| m.name == name && m.wavelength_nm == Some(550.0))
                .unwrap();
            let got: Vec<&Material> = at.materials.iter().filter(|m| m.name == name).collect();
            assert_eq!(
                (got[0].n, got[0].k, &got[0].layer, got[0].wavelength_nm),
                (want.n, want.k, &want.layer, Some(550.0)),
                "{name}"
            );
            assert_eq!(got[1].wavelength_nm, Some(540.0));
        }
        let gold = at.materials.iter().find(|m| m.name == "gold").unwrap();
        assert!((gold.n - 0.458).abs() < 1e-3, "{}", gold.n);
    }

    #[test]
    fn layer_columns_round_trip_and_are_checked() {
        for lib in [Library::builtin().unwrap(), Library::builtin_rgb().unwrap()] {
            let mut buf = Vec::new();
            lib.write_csv(&mut buf, Path::new("out.csv"), None).unwrap();
            let text = String::from_utf8(buf).unwrap();
            assert!(
                text.lines()
                    .next()
                    .unwrap()
                    .ends_with("reference,layer,layer_n,layer_k,layer_min_nm,layer_max_nm")
            );
            let back = Library::from_csv_text("out.csv", &text).unwrap();
            for (a, b) in lib.materials.iter().zip(&back.materials) {
                assert_eq!(a.layer, b.layer, "{}", a.name);
            }
            assert_eq!(back.multi_prototypes().len(), lib.multi_prototypes().len());
        }
        let head = "name,n,k,layer,layer_n,layer_k,layer_min_nm,layer_max_nm\n";
        let ok = Library::from_csv_text(
            "l.csv",
            &format!("{head}al,1.5,7.7,Al2O3,1.65,0,2,5\nglass,1.5,0,,,,,\nx,1,1,ox,,,0,1\n"),
        )
        .unwrap();
        assert_eq!(ok.materials[1].layer, None);
        assert_eq!(ok.materials[2].layer.as_ref().unwrap().index, None);
        let p = ok.multi_prototypes();
        assert_eq!(p[0].bands[0].layer, Some((1.65, 0.0)));
        assert_eq!(p[0].surface.as_ref().unwrap().max_nm, 5.0);
        let bad = |rows: &str| {
            Library::from_csv_text("l.csv", &format!("{head}{rows}"))
                .unwrap_err()
                .to_string()
        };
        let e = bad("al,1.5,7.7,Al2O3,1.65,0,5,2\n");
        assert!(
            e.contains("l.csv")
                && e.contains("line 2")
                && e.contains("layer_max_nm")
                && e.contains('2'),
            "{e}"
        );
        let e = bad("al,1.5,7.7,Al2O3,-1.65,0,2,5\n");
        assert!(e.contains("layer_n") && e.contains("-1.65"), "{e}");
        let e = bad("al,1.5,7.7,Al2O3,1.65,,2,5\n");
        assert!(e.contains("layer_k") && e.contains("together"), "{e}");
        let e = bad("al,1.5,7.7,Al2O3,1.65,0,-1,5\n");
        assert!(e.contains("layer_min_nm") && e.contains("-1"), "{e}");
        let e = bad("al,1.5,7.7,,1.65,0,2,5\n");
        assert!(e.contains("layer_n") && e.contains("without"), "{e}");
        let e = bad("al,1.5,7.7,Al2O3,1.65,0,2,x\n");
        assert!(e.contains("layer_max_nm") && e.contains("\"x\""), "{e}");
        let e = Library::from_csv_text("l.csv", "name,n,k,layer\nal,1,1,x\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("layer_n"), "{e}");
        // The rows of one material agree on the layer.
        let e = Library::from_csv_text(
            "l.csv",
            "name,n,k,wavelength_nm,layer,layer_n,layer_k,layer_min_nm,layer_max_nm\n\
             al,1,7,550,Al2O3,1.66,0,2,5\nal,1.5,7.7,650,Al2O3,1.65,0,2,6\n",
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("line 3") && e.contains("line 2") && e.contains("surface"),
            "{e}"
        );
    }

    #[test]
    fn mistyped_names_get_suggestions() {
        let e = Library::load("bultin").unwrap_err();
        assert!(e.is_bad_input());
        // The operating system's "not found" (Python: FileNotFoundError).
        assert!(
            matches!(&e, IoError::Io { source, .. } if source.kind() == std::io::ErrorKind::NotFound),
            "{e:?}"
        );
        let e = crate::error::chain_message(&e);
        assert!(
            e.contains("bultin")
                && e.contains("No such file")
                && e.contains("did you mean `builtin`?"),
            "{e}"
        );
        let e =
            crate::error::chain_message(&Library::load("/some/scene/dir/builtin_rgb").unwrap_err());
        assert!(e.contains("did you mean `builtin-rgb`"), "{e}");
        let e = crate::error::chain_message(&Library::load("no_such_library.csv").unwrap_err());
        assert!(
            e.contains("No such file") && !e.contains("did you mean"),
            "{e}"
        );
        let rgb = Library::builtin_rgb().unwrap();
        assert_eq!(rgb.names().len(), 39);
        let m = rgb.unknown_material("Gold (Au)");
        assert!(
            m.contains("\"Gold (Au)\"")
                && m.contains("builtin-rgb")
                && m.contains("did you mean `gold`?"),
            "{m}"
        );
        assert!(m.contains("polarid library --list builtin-rgb"), "{m}");
        let m = rgb.unknown_material("Aluminium");
        assert!(m.contains("did you mean `aluminum`?"), "{m}");
    }

    #[test]
    fn formulas_match_hand_values() {
        // Formula 1, fused silica (Malitson 1965) at 0.65 µm.
        let c = [
            0.0, 0.6961663, 0.0684043, 0.4079426, 0.1162414, 0.8974794, 9.896161,
        ];
        let l2: f64 = 0.65 * 0.65;
        let mut n2 = 1.0;
        for i in 0..3 {
            n2 += c[1 + 2 * i] * l2 / (l2 - c[2 + 2 * i] * c[2 + 2 * i]);
        }
        assert!((formula(1, &c, 0.65) - n2.sqrt()).abs() < 1e-15);
        assert!((formula(1, &c, 0.65) - 1.45653).abs() < 5e-6);
        // Formula 5 (Cauchy) and 4 against direct evaluation.
        let cc = [1.5130, -0.003169, 2.0, 0.003962, -2.0];
        let v = 1.5130 - 0.003169 * l2 + 0.003962 / l2;
        assert!((formula(5, &cc, 0.65) - v).abs() < 1e-15);
        let c4 = [5.913, 0.2441, 0.0, 0.0803, 1.0, 0.0, 0.0, 0.0, 1.0];
        let v = (5.913 + 0.2441 / (l2 - 0.0803)).sqrt();
        assert!((formula(4, &c4, 0.65) - v).abs() < 1e-15);
        // Formula 7 and 8, 9, 6, 3 against their definitions.
        let c7 = [1.4, 0.01, 0.001, -0.002, 1e-5, 1e-7];
        let m = 1.0 / (l2 - 0.028);
        let v = 1.4 + 0.01 * m + 0.001 * m * m - 0.002 * l2 + 1e-5 * l2 * l2 + 1e-7 * l2 * l2 * l2;
        assert!((formula(7, &c7, 0.65) - v).abs() < 1e-15);
        let c8 = [0.2, 0.05, 0.01, -0.001];
        let b = 0.2 + 0.05 * l2 / (l2 - 0.01) - 0.001 * l2;
        assert!((formula(8, &c8, 0.65) - ((1.0 + 2.0 * b) / (1.0 - b)).sqrt()).abs() < 1e-15);
        let c9 = [2.0, 0.02, 0.03, 0.1, 0.5, 0.04];
        let d = 0.65 - 0.5;
        let v = (2.0 + 0.02 / (l2 - 0.03) + 0.1 * d / (d * d + 0.04)).sqrt();
        assert!((formula(9, &c9, 0.65) - v).abs() < 1e-15);
        let c6 = [0.0, 0.05792105, 238.0185, 0.00167917, 57.362];
        let v = 1.0 + 0.05792105 / (238.0185 - 1.0 / l2) + 0.00167917 / (57.362 - 1.0 / l2);
        assert!((formula(6, &c6, 0.65) - v).abs() < 1e-15);
        let c3 = [2.0, 0.1, 2.0, 0.01, -2.0];
        let v = (2.0 + 0.1 * l2 + 0.01 / l2).sqrt();
        assert!((formula(3, &c3, 0.65) - v).abs() < 1e-15);
        // Formula 2 is formula 1 with squared poles.
        let c2 = [0.0, 0.6961663, 0.0684043f64.powi(2)];
        assert!((formula(2, &c2, 0.65) - formula(1, &c[..3], 0.65)).abs() < 1e-15);
    }

    #[test]
    fn yaml_tabulated_interpolates_and_refuses_extrapolation() {
        let text = "DATA:\n  - type: tabulated nk\n    data: |\n        0.6 1.0 2.0\n        0.7 2.0 4.0\n";
        let d = RiiData::parse(Path::new("t.yml"), text).unwrap();
        let (n, k) = d.nk(0.65).unwrap();
        assert!((n - 1.5).abs() < 1e-15 && (k - 3.0).abs() < 1e-15);
        let (n, k) = d.band_mean(600.0, 700.0, 1.0).unwrap();
        assert!((n - 1.5).abs() < 1e-12 && (k - 3.0).abs() < 1e-12);
        let e = d.nk(0.75).unwrap_err().to_string();
        assert!(e.contains("t.yml") && e.contains("750.0 nm"), "{e}");
        // n only: k = 0.
        let text = "DATA:\n  - type: formula 5\n    wavelength_range: 0.3 1.0\n    coefficients: 1.5 0.01 -2\n";
        let d = RiiData::parse(Path::new("f.yml"), text).unwrap();
        let (n, k) = d.nk(0.5).unwrap();
        assert!((n - 1.54).abs() < 1e-12 && k == 0.0);
        let e = RiiData::parse(
            Path::new("x.yml"),
            "DATA:\n  - type: formula 12\n    coefficients: 1\n",
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("x.yml") && e.contains("formula 12"), "{e}");
    }
}
