//! Materials as they are found: the native surface layer (oxide or adsorbed
//! contamination) of each built-in library material, and the optical constants of those
//! layers (docs/MATERIALS.md gives the literature behind every entry).
//!
//! A real metal surface is its bulk under its own native layer: aluminum under a few nm
//! of amorphous Al₂O₃, copper under Cu₂O, silicon under SiO₂, gold and glass under a
//! nanometre or so of adsorbed hydrocarbons. [`BUILTIN_SURFACES`] gives, per built-in
//! material, the layer and the range of thicknesses found on real surfaces;
//! [`LAYER_SOURCES`] gives each layer's index: a refractiveindex.info file (CC0, embedded,
//! evaluated like the bulk files: band means or `n(λ)`, never extrapolated) or, where the
//! database has no visible data, a documented constant.
//!
//! The library reader fills these into the built-in libraries (`builtin`, `builtin-rgb`,
//! `paper2007`): each row's layer index is evaluated over the same band as the row's bulk
//! index (the 80 nm band centred on the row's wavelength, sampled every nm, as in
//! `library_650nm.csv`), so that the layer and the bulk are always at one wavelength.

use std::path::Path;

use crate::error::Result;
use crate::rii::{ParsedOnce, RiiData, parsed_once};

/// Where a layer's optical constants come from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LayerIndexSource {
    /// A refractiveindex.info YAML file, embedded.
    Data {
        /// Its path in the database (`shelf/book/nk/page.yml`).
        file: &'static str,
        /// The YAML text.
        text: &'static str,
    },
    /// A constant `n + ik` (no dispersion data in the database; see `reference`).
    Constant {
        /// Real part.
        n: f64,
        /// Imaginary part.
        k: f64,
    },
}

/// One layer material's optical constants.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LayerSource {
    /// Layer name, e.g. `Al2O3`, `contamination`.
    pub name: &'static str,
    /// Its index.
    pub index: LayerIndexSource,
    /// Literature reference of the index.
    pub reference: &'static str,
}

/// The [`LayerIndexSource::Data`] of the refractiveindex.info file `file`
/// (`shelf/book/nk/page.yml`) of `data/materials/<dir>`, embedded.
macro_rules! data {
    ($dir:literal, $file:literal) => {
        LayerIndexSource::Data {
            file: $file,
            text: include_str!(concat!("../../../data/materials/", $dir, "/", $file)),
        }
    };
}

/// The layer materials of the built-in surfaces.
pub const LAYER_SOURCES: [LayerSource; 14] = [
    LayerSource {
        name: "Al2O3",
        index: data!("layers", "main/Al2O3/nk/Franta.yml"),
        reference: "Franta et al. 2015 (amorphous e-beam Al2O3 film, 121.5 nm)",
    },
    LayerSource {
        name: "Cu2O",
        index: LayerIndexSource::Constant { n: 2.9, k: 0.1 },
        reference: "cuprite below its gap: n = 2.849 for the mineral (mineral data); ellipsometry of cuprite 250-850 nm: Roberts and Rastall 1978; k = 0.1 is a typical value, not from a specific measurement (constant; the database has Cu2O only from 2.5 um)",
    },
    LayerSource {
        name: "contamination",
        index: LayerIndexSource::Constant { n: 1.5, k: 0.0 },
        reference: "adsorbed hydrocarbons (adventitious carbon), n = 1.5: typical value, not from a specific measurement (constant)",
    },
    LayerSource {
        name: "SiO2",
        index: data!("refractiveindex", "main/SiO2/nk/Malitson.yml"),
        reference: "Malitson 1965 (fused silica)",
    },
    LayerSource {
        name: "NiO",
        index: LayerIndexSource::Constant { n: 2.3, k: 0.0 },
        reference: "typical value, not from a specific measurement; crystalline NiO (bunsenite) n = 2.37 (mineral data) (constant; no data in the database)",
    },
    LayerSource {
        name: "Cr2O3",
        index: LayerIndexSource::Constant { n: 2.3, k: 0.0 },
        reference: "typical value, not from a specific measurement; evaporated Cr2O3 films about 2.24 + 0.07i near 700 nm, depending on deposition (constant; no data in the database)",
    },
    LayerSource {
        name: "TiO2",
        index: data!("layers", "main/TiO2/nk/Jolivet-amorphous.yml"),
        reference: "Jolivet et al. 2023 (amorphous TiO2 film)",
    },
    LayerSource {
        name: "WO3",
        index: data!("layers", "main/WO3/nk/Kulikova.yml"),
        reference: "Kulikova et al. 2020 (WO3 film)",
    },
    LayerSource {
        name: "ZnO",
        index: data!("layers", "main/ZnO/nk/Aguilar.yml"),
        reference: "Aguilar et al. 2019 (ZnO thin film, from a Zn(1-x)Cd(x)O study)",
    },
    LayerSource {
        name: "PbO",
        index: LayerIndexSource::Constant { n: 2.6, k: 0.0 },
        reference: "typical value, not from a specific measurement; massicot (PbO) 2.51/2.61/2.71 (mineral data) (constant; no data in the database)",
    },
    LayerSource {
        name: "MgO",
        index: data!("layers", "main/MgO/nk/Stephens.yml"),
        reference: "Stephens and Malitson 1952 (MgO, 0.36-5.4 um formula)",
    },
    LayerSource {
        name: "Fe3O4",
        index: data!("refractiveindex", "main/Fe3O4/nk/Querry.yml"),
        reference: "Querry 1985 (magnetite)",
    },
    LayerSource {
        name: "GeO2",
        index: data!("layers", "main/GeO2/nk/Nunley.yml"),
        reference: "Nunley et al. 2016 (thermally grown GeO2)",
    },
    LayerSource {
        name: "GaAs_oxide",
        index: LayerIndexSource::Constant { n: 1.8, k: 0.0 },
        reference: "typical value, not from a specific measurement; Ga2O3/As2O3 native oxide, above arsenolite (As2O3, n = 1.755, mineral data) (constant; no data in the database)",
    },
];

/// A built-in material's native surface layer: the layer ([`LAYER_SOURCES`] name) and the
/// range of thicknesses found on real surfaces, nm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BuiltinSurface {
    /// The material's name in the built-in libraries.
    pub material: &'static str,
    /// The layer ([`LayerSource::name`]).
    pub layer: &'static str,
    /// Thinnest layer, nm.
    pub min_nm: f64,
    /// Thickest layer, nm.
    pub max_nm: f64,
}

const fn s(
    material: &'static str,
    layer: &'static str,
    min_nm: f64,
    max_nm: f64,
) -> BuiltinSurface {
    BuiltinSurface {
        material,
        layer,
        min_nm,
        max_nm,
    }
}

/// The native surfaces of the built-in materials (every material of `builtin`,
/// `builtin-rgb` and `paper2007`; docs/MATERIALS.md gives the references, and says which
/// ranges are typical values rather than taken from a specific measurement).
pub const BUILTIN_SURFACES: [BuiltinSurface; 40] = [
    s("aluminum", "Al2O3", 2.0, 5.0),
    s("copper", "Cu2O", 0.5, 3.0),
    s("gold", "contamination", 0.5, 1.5),
    s("silver", "contamination", 0.5, 2.0),
    s("iron", "Fe3O4", 1.5, 4.0),
    s("nickel", "NiO", 1.0, 2.0),
    s("chromium", "Cr2O3", 1.0, 3.0),
    s("titanium", "TiO2", 2.0, 6.0),
    s("tungsten", "WO3", 1.0, 3.0),
    s("zinc", "ZnO", 1.0, 3.0),
    s("lead", "PbO", 1.0, 5.0),
    s("magnesium", "MgO", 2.0, 5.0),
    s("platinum", "contamination", 0.5, 1.5),
    s("brass_Cu70Zn30", "ZnO", 1.0, 3.0),
    s("stainless_steel_austenitic", "Cr2O3", 1.0, 3.0),
    s("silicon", "SiO2", 1.0, 2.0),
    s("germanium", "GeO2", 0.5, 2.0),
    s("gallium_arsenide", "GaAs_oxide", 1.0, 3.0),
    s("graphite_o", "contamination", 0.0, 2.0),
    s("carbon_soot_acetylene", "contamination", 0.0, 2.0),
    s("hematite_Fe2O3_o", "contamination", 0.0, 2.0),
    s("magnetite_Fe3O4", "contamination", 0.0, 2.0),
    s("N-BK7", "contamination", 0.0, 2.0),
    s("fused_silica", "contamination", 0.0, 2.0),
    s("soda_lime_glass_clear", "contamination", 0.0, 2.0),
    s("sapphire_o", "contamination", 0.0, 2.0),
    s("water", "contamination", 0.0, 2.0),
    s("ice", "contamination", 0.0, 2.0),
    s("PMMA", "contamination", 0.0, 2.0),
    s("polycarbonate", "contamination", 0.0, 2.0),
    s("polystyrene", "contamination", 0.0, 2.0),
    s("PET", "contamination", 0.0, 2.0),
    s("PVC", "contamination", 0.0, 2.0),
    s("PDMS_silicone_Sylgard184", "contamination", 0.0, 2.0),
    s("cellulose", "contamination", 0.0, 2.0),
    s("polyimide_Kapton_HN", "contamination", 0.0, 2.0),
    s("TiO2_rutile_o", "contamination", 0.0, 2.0),
    s("ZnO_o", "contamination", 0.0, 2.0),
    s("CaCO3_calcite_o", "contamination", 0.0, 2.0),
    s("green_paint", "contamination", 0.0, 2.0),
];

/// Half width of the built-in libraries' bands, nm (80 nm wide: 610–690 nm for 650 nm).
pub const BUILTIN_BAND_HALF_WIDTH_NM: f64 = 40.0;

/// The native surface of built-in material `material`, if it has one.
pub fn builtin_surface(material: &str) -> Option<&'static BuiltinSurface> {
    BUILTIN_SURFACES.iter().find(|s| s.material == material)
}

/// The layer material named `name`.
pub fn layer_source(name: &str) -> Option<&'static LayerSource> {
    LAYER_SOURCES.iter().find(|s| s.name == name)
}

/// The parsed data of [`LAYER_SOURCES`] (`None` for constants), parsed once per process.
fn layer_data() -> Result<&'static [Option<RiiData>]> {
    static DATA: ParsedOnce<Option<RiiData>> = ParsedOnce::new();
    parsed_once(&DATA, "builtin layers", || {
        LAYER_SOURCES
            .iter()
            .map(|s| match s.index {
                LayerIndexSource::Data { file, text } => {
                    RiiData::parse(Path::new(file), text).map(Some)
                }
                LayerIndexSource::Constant { .. } => Ok(None),
            })
            .collect()
    })
}

/// The index `(n, k)` of layer `name` ([`LAYER_SOURCES`]) as the band mean over
/// `lo_nm ..= hi_nm` sampled every `step_nm` ([`RiiData::band_mean`]; `lo_nm = hi_nm`:
/// the value at that wavelength). `Ok(None)` when the layer is unknown or its data do not
/// cover the band (nothing is extrapolated); a constant layer has its constant everywhere.
pub fn layer_index(name: &str, lo_nm: f64, hi_nm: f64, step_nm: f64) -> Result<Option<(f64, f64)>> {
    let Some(i) = LAYER_SOURCES.iter().position(|s| s.name == name) else {
        return Ok(None);
    };
    if let LayerIndexSource::Constant { n, k } = LAYER_SOURCES[i].index {
        return Ok(Some((n, k)));
    }
    let data = layer_data()?;
    let Some(Some(d)) = data.get(i) else {
        return Ok(None);
    };
    let (lo_um, hi_um) = d.range_um();
    if !(lo_nm / 1e3 >= lo_um && hi_nm / 1e3 <= hi_um) {
        return Ok(None);
    }
    d.band_mean(lo_nm, hi_nm, step_nm).map(Some)
}

/// The index of layer `name` at a built-in band centred on `wavelength_nm` (the band mean
/// over `wavelength_nm ± 40 nm`, every nm, like the built-in libraries' bulk values).
pub fn layer_index_builtin_band(name: &str, wavelength_nm: f64) -> Result<Option<(f64, f64)>> {
    layer_index(
        name,
        wavelength_nm - BUILTIN_BAND_HALF_WIDTH_NM,
        wavelength_nm + BUILTIN_BAND_HALF_WIDTH_NM,
        1.0,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_surface_names_a_layer_with_a_sane_range() {
        for s in &BUILTIN_SURFACES {
            assert!(
                layer_source(s.layer).is_some(),
                "{}: {}",
                s.material,
                s.layer
            );
            assert!(
                0.0 <= s.min_nm && s.min_nm <= s.max_nm && s.max_nm <= 10.0,
                "{s:?}"
            );
        }
        let mut names: Vec<&str> = BUILTIN_SURFACES.iter().map(|s| s.material).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), BUILTIN_SURFACES.len());
    }

    #[test]
    fn the_names_map_gives_the_same_surfaces() {
        let text = include_str!("../../../data/materials/builtin_names.csv");
        let t =
            crate::table::CsvTable::from_reader(Path::new("builtin_names.csv"), text.as_bytes())
                .unwrap();
        let c = |n: &str| t.require(n).unwrap();
        assert_eq!(t.rows.len(), 39);
        for r in 0..t.rows.len() {
            let s = builtin_surface(t.text(r, c("name"))).unwrap();
            assert_eq!(t.text(r, c("layer")), s.layer);
            assert_eq!(t.f64(r, c("layer_min_nm")).unwrap(), s.min_nm);
            assert_eq!(t.f64(r, c("layer_max_nm")).unwrap(), s.max_nm);
        }
    }

    #[test]
    fn layer_data_cover_the_rgb_bands() {
        for l in &LAYER_SOURCES {
            for w in [450.0, 550.0, 650.0] {
                let (n, k) = layer_index_builtin_band(l.name, w)
                    .unwrap()
                    .unwrap_or_else(|| panic!("{} at {w} nm", l.name));
                assert!(
                    n > 1.0 && n < 3.5 && (0.0..0.5).contains(&k),
                    "{} {w}: {n} {k}",
                    l.name
                );
            }
        }
        // Amorphous alumina near 650 nm: about 1.65 (Franta et al. 2015).
        let (n, k) = layer_index_builtin_band("Al2O3", 650.0).unwrap().unwrap();
        assert!((n - 1.651).abs() < 0.005 && k < 1e-3, "{n} {k}");
        // Fused silica (Malitson): 1.4565 at 650 nm.
        let (n, _) = layer_index("SiO2", 650.0, 650.0, 1.0).unwrap().unwrap();
        assert!((n - 1.45653).abs() < 1e-4, "{n}");
        // No extrapolation: TiO2 (Jolivet) ends at 827 nm.
        assert_eq!(layer_index("TiO2", 900.0, 900.0, 1.0).unwrap(), None);
        assert_eq!(layer_index("nope", 650.0, 650.0, 1.0).unwrap(), None);
    }
}
