//! `polarid library YAML_OR_DIR... --band LO:HI [--band LO:HI ...] [-o LIB.csv]`: build a
//! material library CSV for one or several filter bands from refractiveindex.info YAML
//! files, for `polarid classify --library LIB.csv`. With several `--band`s each material
//! gets one row per band, with `wavelength_nm` the band's centre (a colour camera's
//! library: `--band 410:490 --band 510:590 --band 610:690`, docs/BANDS.md).
//!
//! The workflow is [`polarid_pipeline::library`]; this command parses the options and
//! writes the CSV. Each file gives one material: the arithmetic means of `n` and of `k` over the band,
//! sampled every `--step` nm ([`RiiData::band_mean`](polarid_io::library::RiiData::band_mean), the method of the built-in 650 nm
//! library: `--band 610:690 --step 1` reproduces it). Nothing is extrapolated: a file whose
//! data do not cover the whole band is an error naming the file, the band and the data's
//! range (exit status 2), or is skipped with a warning under `--skip-missing`.
//!
//! Names: by default the file stem, prefixed with the material folder in the database's
//! layout `shelf/BOOK/nk/PAGE.yml` (`main/Au/nk/Johnson.yml` → `Au_Johnson`), blanks
//! replaced by `_`. `--names MAP.csv` (columns `file,name`, optional `category`,
//! `reference`) names files explicitly; `file` is matched against the end of each YAML
//! path, whole components only (`main/Au/nk/Johnson.yml` or `Au/nk/Johnson.yml`).
//!
//! Categories: the map's `category`, else the nearest folder named `metal`, `dielectric`,
//! `semiconductor` or `other` between a file and the directory input it was found in (that
//! directory included), else `--category`, else empty.
//!
//! Surfaces: the map's `layer`, `layer_min_nm`, `layer_max_nm` (optional `layer_n`,
//! `layer_k`), else the built-in surface of a built-in material's file or name
//! (docs/MATERIALS.md); written as the columns `layer,layer_n,layer_k,layer_min_nm,
//! layer_max_nm`, the layer's index averaged over the same band as the bulk.
//!
//! `polarid library --list [builtin|builtin-rgb|paper2007|LIB.csv]` prints a library's
//! material names with their category, bands and surface layer.

use std::path::{Path, PathBuf};

use polarid_io::library::Library;
use polarid_io::table::fmt_f64;
use polarid_pipeline::library::{Band, LibraryConfig, build_library, parse_band};

use super::common::{Bars, PipeResult, warn_all};
use crate::Ctx;
use crate::ctx::print_stdout;
use crate::render::join;

fn parse_step(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("{s:?} is not a step > 0 nm")),
    }
}

/// Arguments of `polarid library`.
#[derive(Debug, clap::Args)]
#[command(after_help = "\
Examples:
  polarid library data/materials/refractiveindex --band 520:545 -o lib_532.csv
  polarid library main/Au/nk/Johnson.yml main/Cu/nk/Johnson.yml --band 532 --category metal
  polarid library mats/ --band 700:900 --step 5 --names names.csv --skip-missing -o nir.csv
  polarid library data/materials/refractiveindex --band 410:490 --band 510:590 --band 610:690
  polarid library --list builtin-rgb

Output columns: name,category,n,k,reference (reference: the map's, else the YAML path),
after a `#` comment line giving the band; with several --band, name,category,wavelength_nm,
n,k,reference, one row per material per band (wavelength_nm: the band's centre); then
layer,layer_n,layer_k,layer_min_nm,layer_max_nm when a material has a surface layer (from
--names, or the built-in surface of a built-in material's file, docs/MATERIALS.md).
Read by `polarid classify --library LIB.csv`.")]
pub struct Args {
    /// refractiveindex.info YAML files (tabulated nk / n / k, formulas 1-9), or folders
    /// scanned recursively for *.yml and *.yaml.
    #[arg(required_unless_present = "list", value_name = "YAML_OR_DIR")]
    pub inputs: Vec<PathBuf>,
    /// Band in nm: `LO:HI` (n and k averaged over LO, LO+STEP, ... up to HI) or a single
    /// wavelength `WL` (e.g. 532 for a laser). The built-in library is `610:690`. Give it
    /// several times for a multi-band library (one row per material per band).
    #[arg(long, value_name = "LO:HI|WL", value_parser = parse_band, required_unless_present = "list")]
    pub band: Vec<Band>,
    /// Sampling step of the band mean, nm.
    #[arg(long, value_name = "NM", default_value = "1", value_parser = parse_step)]
    pub step: f64,
    /// Category (e.g. metal, dielectric) of the materials that get none from --names or
    /// from their folder: the nearest folder named metal, dielectric, semiconductor or
    /// other between a file and the directory input (included) gives its category.
    #[arg(long, value_name = "NAME")]
    pub category: Option<String>,
    /// CSV naming the materials: columns `file,name`, optional `category`, `reference`.
    /// `file` matches the end of a YAML path, whole components (e.g. `Au/nk/Johnson.yml`);
    /// each row must match exactly one input file. Unmatched files keep their default name
    /// (BOOK_PAGE for the database layout shelf/BOOK/nk/PAGE.yml, else the file stem).
    #[arg(long, value_name = "MAP.csv")]
    pub names: Option<PathBuf>,
    /// Skip, with a warning, files whose data do not cover the whole band (default: such a
    /// file is an error).
    #[arg(long)]
    pub skip_missing: bool,
    /// Output library CSV (default: standard output).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Print the material names of a library (`builtin`, the default; `builtin-rgb`,
    /// `paper2007` or a library CSV) with their category, bands and surface layer, and
    /// build nothing.
    #[arg(
        long,
        value_name = "LIBRARY",
        num_args = 0..=1,
        default_missing_value = "builtin",
        conflicts_with_all = ["inputs", "band", "names", "output", "category", "skip_missing"]
    )]
    pub list: Option<String>,
}

/// The listing of `polarid library --list`: one line per material (name, category, bands
/// in nm, surface layer with its thickness range), aligned, after a `#` title line.
pub fn list_text(lib: &Library) -> String {
    let mut rows: Vec<[String; 4]> = Vec::new();
    for name in lib.names() {
        let ms: Vec<_> = lib.materials.iter().filter(|m| m.name == name).collect();
        let first = ms[0]; // ok: `name` comes from the materials
        let bands: Vec<String> = ms
            .iter()
            .filter_map(|m| m.wavelength_nm.map(fmt_f64))
            .collect();
        let bands = if bands.is_empty() {
            if lib.source == "builtin" || lib.source == "paper2007" {
                "650".to_string()
            } else {
                "-".to_string()
            }
        } else {
            bands.join(",")
        };
        let layer = first.layer.as_ref().map_or_else(
            || "-".to_string(),
            |l| format!("{} {}–{} nm", l.name, fmt_f64(l.min_nm), fmt_f64(l.max_nm)),
        );
        rows.push([
            name.to_string(),
            first.category.clone().unwrap_or_else(|| "-".into()),
            bands,
            layer,
        ]);
    }
    let head = ["name", "category", "bands_nm", "surface_layer"];
    let width = |i: usize| {
        rows.iter()
            .map(|r| r[i].chars().count())
            .chain([head[i].len()])
            .max()
            .unwrap_or(0)
    };
    let w = [width(0), width(1), width(2)];
    let line = |r: [&str; 4]| {
        format!(
            "{:<w0$}  {:<w1$}  {:<w2$}  {}\n",
            r[0],
            r[1],
            r[2],
            r[3],
            w0 = w[0],
            w1 = w[1],
            w2 = w[2]
        )
    };
    let mut out = format!("# library {}: {} materials\n", lib.source, rows.len());
    out.push_str(&line(head));
    for r in &rows {
        out.push_str(&line([&r[0], &r[1], &r[2], &r[3]]));
    }
    out
}

/// Run `polarid library`.
pub fn run(args: Args, ctx: &Ctx) -> anyhow::Result<()> {
    if let Some(spec) = &args.list {
        let lib = Library::load(spec)?;
        return print_stdout(list_text(&lib).as_bytes());
    }
    let cfg = LibraryConfig::new(
        args.band.clone(),
        args.step,
        args.category.clone(),
        args.skip_missing,
    )
    .cli()?;
    let bars = Bars::new(ctx);
    let built = build_library(&cfg, &args.inputs, args.names.as_deref(), &|s, d, t| {
        bars.report(s, d, t)
    })
    .cli()?;
    drop(bars);
    warn_all(ctx, &built.warnings);
    let source = args
        .output
        .as_ref()
        .map_or_else(|| "stdout".to_string(), |p| p.display().to_string());
    let lib = Library {
        source,
        materials: built.materials,
    };
    let mut inputs: Vec<&Path> = built.files.iter().map(PathBuf::as_path).collect();
    if let Some(m) = &args.names {
        inputs.push(m.as_path());
    }
    let comment = cfg.comment();
    ctx.write_output(args.output.as_deref(), &inputs, |w, p| {
        lib.write_csv(w, p, Some(&comment))
    })?;
    let mut names: Vec<&str> = lib.materials.iter().map(|m| m.name.as_str()).collect();
    names.dedup();
    ctx.info(format!(
        "polarid library: {} materials, band{} {}{}",
        names.len(),
        if args.band.len() > 1 { "s" } else { "" },
        join(&args.band, ", "),
        if built.skipped == 0 {
            String::new()
        } else {
            format!(", {} file(s) skipped", built.skipped)
        }
    ));
    Ok(())
}
