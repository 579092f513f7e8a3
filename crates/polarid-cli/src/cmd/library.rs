//! `polarid library YAML_OR_DIR... --band LO:HI [-o LIB.csv]`: build a material library
//! CSV for a filter band from refractiveindex.info YAML files, for
//! `polarid classify --library LIB.csv`.
//!
//! Each file gives one material: the arithmetic means of `n` and of `k` over the band,
//! sampled every `--step` nm ([`RiiData::band_mean`], the method of the built-in 650 nm
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

use std::collections::BTreeMap;
use std::fs;
use std::path::{Path, PathBuf};

use polarid_core::classify::check_class_name;
use polarid_io::IoError;
use polarid_io::library::{Library, Material, RiiData};
use polarid_io::table::CsvTable;

use crate::{BadInput, Ctx};

/// Categories recognised in folder names below a directory input.
const CATEGORIES: [&str; 4] = ["metal", "dielectric", "semiconductor", "other"];

/// Largest number of samples of one band mean (guards against `--step 1e-9`).
const MAX_SAMPLES: f64 = 1e6;

/// A wavelength band in nm, `lo <= hi` (`lo == hi`: one wavelength).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Band {
    /// Lower end, nm.
    pub lo: f64,
    /// Upper end, nm.
    pub hi: f64,
}

impl std::fmt::Display for Band {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.lo == self.hi {
            write!(f, "{} nm", self.lo)
        } else {
            write!(f, "{}–{} nm", self.lo, self.hi)
        }
    }
}

/// Parse `LO:HI` or `WL` (nm) into a [`Band`]; both ends finite and > 0, `LO <= HI`.
pub fn parse_band(s: &str) -> Result<Band, String> {
    let num = |t: &str, what: &str| -> Result<f64, String> {
        let v: f64 = t
            .trim()
            .parse()
            .map_err(|_| format!("{what} {t:?} is not a number (expected LO:HI or WL in nm)"))?;
        if !(v.is_finite() && v > 0.0) {
            return Err(format!("{what} {t:?} must be a finite wavelength > 0 nm"));
        }
        Ok(v)
    };
    let band = match s.split_once(':') {
        Some((a, b)) => Band {
            lo: num(a, "LO")?,
            hi: num(b, "HI")?,
        },
        None => {
            let wl = num(s, "WL")?;
            Band { lo: wl, hi: wl }
        }
    };
    if band.hi < band.lo {
        return Err(format!(
            "empty band: HI {} nm is below LO {} nm",
            band.hi, band.lo
        ));
    }
    Ok(band)
}

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
  polarid library ../shared/materials/refractiveindex --band 520:545 -o lib_532.csv
  polarid library main/Au/nk/Johnson.yml main/Cu/nk/Johnson.yml --band 532 --category metal
  polarid library mats/ --band 700:900 --step 5 --names names.csv --skip-missing -o nir.csv

Output columns: name,category,n,k,reference (reference: the map's, else the YAML path),
after a `#` comment line giving the band; read by `polarid classify --library LIB.csv`.")]
pub struct Args {
    /// refractiveindex.info YAML files (tabulated nk / n / k, formulas 1-9), or folders
    /// scanned recursively for *.yml and *.yaml.
    #[arg(required = true, value_name = "YAML_OR_DIR")]
    pub inputs: Vec<PathBuf>,
    /// Band in nm: `LO:HI` (n and k averaged over LO, LO+STEP, ... up to HI) or a single
    /// wavelength `WL` (e.g. 532 for a laser). The built-in library is `610:690`.
    #[arg(long, value_name = "LO:HI|WL", value_parser = parse_band)]
    pub band: Band,
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
}

/// One YAML file to read.
#[derive(Debug, Clone)]
struct Source {
    /// The file.
    path: PathBuf,
    /// Its path relative to the directory input it was found in (the path as given for a
    /// file input).
    rel: PathBuf,
    /// The directory input it was found in (`None` for a file input).
    root: Option<PathBuf>,
}

fn is_yaml(p: &Path) -> bool {
    p.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("yml") || e.eq_ignore_ascii_case("yaml"))
}

/// The *.yml / *.yaml files below `dir`, sorted by path (symbolic links to folders are
/// not followed).
fn scan_dir(root: &Path, dir: &Path, out: &mut Vec<Source>) -> anyhow::Result<()> {
    let rd = fs::read_dir(dir).map_err(|e| IoError::io(dir, e))?;
    let mut entries: Vec<PathBuf> = Vec::new();
    for e in rd {
        entries.push(e.map_err(|e| IoError::io(dir, e))?.path());
    }
    entries.sort();
    for p in entries {
        let meta = fs::symlink_metadata(&p).map_err(|e| IoError::io(&p, e))?;
        if meta.is_dir() {
            scan_dir(root, &p, out)?;
        } else if is_yaml(&p) && p.is_file() {
            let rel = p.strip_prefix(root).unwrap_or(&p).to_path_buf();
            out.push(Source {
                path: p,
                rel,
                root: Some(root.to_path_buf()),
            });
        }
    }
    Ok(())
}

fn sources(inputs: &[PathBuf]) -> anyhow::Result<Vec<Source>> {
    let mut out: Vec<Source> = Vec::new();
    for input in inputs {
        if input.is_dir() {
            let before = out.len();
            scan_dir(input, input, &mut out)?;
            if out.len() == before {
                return Err(
                    BadInput(format!("{}: no *.yml or *.yaml files", input.display())).into(),
                );
            }
        } else {
            out.push(Source {
                path: input.clone(),
                rel: input.clone(),
                root: None,
            });
        }
    }
    // The same file given twice (a folder and a file in it) is read once.
    let mut seen = std::collections::HashSet::new();
    out.retain(|s| seen.insert(s.path.clone()));
    Ok(out)
}

/// Default material name: `BOOK_PAGE` for the database layout `.../BOOK/nk/PAGE.yml`
/// (also `n/`, `k/`), else the file stem; blanks become `_`.
fn default_name(path: &Path) -> String {
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let comps: Vec<String> = path
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    let name = match comps.as_slice() {
        [.., book, page_type, _file] if matches!(page_type.as_str(), "nk" | "n" | "k") => {
            format!("{book}_{stem}")
        }
        _ => stem,
    };
    name.split_whitespace().collect::<Vec<_>>().join("_")
}

/// The category given by the nearest folder of a file found in a directory input, up to
/// and including that directory, named like one of [`CATEGORIES`].
fn folder_category(s: &Source) -> Option<String> {
    let root = s.root.as_ref()?;
    let root_name = root
        .canonicalize()
        .ok()
        .and_then(|r| r.file_name().map(|n| n.to_string_lossy().into_owned()));
    let below = s
        .rel
        .parent()
        .into_iter()
        .flat_map(|p| p.components())
        .map(|c| c.as_os_str().to_string_lossy().into_owned());
    let folders: Vec<String> = root_name.into_iter().chain(below).collect();
    folders.iter().rev().find_map(|c| {
        CATEGORIES
            .iter()
            .find(|k| c.eq_ignore_ascii_case(k))
            .map(|k| k.to_string())
    })
}

/// Name, category and reference given by the map for one file.
#[derive(Debug, Clone, Default)]
struct Mapped {
    name: Option<String>,
    category: Option<String>,
    reference: Option<String>,
}

/// Read the `--names` map and assign its rows to the sources (index → entry).
fn read_names(map: &Path, srcs: &[Source]) -> anyhow::Result<BTreeMap<usize, Mapped>> {
    let t = CsvTable::read(map)?;
    let c_file = t.require("file")?;
    let c_name = t.require("name")?;
    let c_cat = t.col("category");
    let c_ref = t.col("reference");
    let mut out: BTreeMap<usize, Mapped> = BTreeMap::new();
    let mut line_of: BTreeMap<usize, u64> = BTreeMap::new();
    for r in 0..t.rows.len() {
        let file = t.text(r, c_file);
        if file.is_empty() {
            return Err(t.err(r, c_file, "empty file").into());
        }
        let name = t.text(r, c_name).to_string();
        if let Err(e) = check_class_name(&name) {
            return Err(t.err(r, c_name, e.to_string()).into());
        }
        let hits: Vec<usize> = srcs
            .iter()
            .enumerate()
            .filter(|(_, s)| s.path.ends_with(file))
            .map(|(i, _)| i)
            .collect();
        let i = match hits.as_slice() {
            [i] => *i,
            [] => {
                return Err(t
                    .err(r, c_file, "matches none of the input YAML files")
                    .into());
            }
            many => {
                let list: Vec<String> = many
                    .iter()
                    .filter_map(|&i| srcs.get(i))
                    .map(|s| s.path.display().to_string())
                    .collect();
                return Err(t
                    .err(
                        r,
                        c_file,
                        format!(
                            "matches {} input files ({}); give more of the path",
                            many.len(),
                            list.join(", ")
                        ),
                    )
                    .into());
            }
        };
        let line = t.rows.get(r).map_or(0, |row| row.0);
        if let Some(prev) = line_of.insert(i, line) {
            return Err(t
                .err(r, c_file, format!("names the same file as line {prev}"))
                .into());
        }
        out.insert(
            i,
            Mapped {
                name: Some(name),
                category: t.opt_text(r, c_cat),
                reference: t.opt_text(r, c_ref),
            },
        );
    }
    Ok(out)
}

/// Sample wavelengths (nm) of the band mean: first and last, and their count, exactly as
/// [`RiiData::band_mean`] takes them.
fn samples(band: Band, step: f64) -> (f64, f64, usize) {
    let count = ((band.hi - band.lo) / step + 1e-9).floor() as usize + 1;
    (band.lo, band.lo + (count - 1) as f64 * step, count)
}

fn nm(x_um: f64) -> String {
    format!("{:.1}", x_um * 1e3)
}

/// Build the library (without writing it). Returns the library and the warnings of the
/// skipped files.
fn build(args: &Args, srcs: &[Source]) -> anyhow::Result<(Library, Vec<String>)> {
    let mapped = match &args.names {
        Some(map) => read_names(map, srcs)?,
        None => BTreeMap::new(),
    };
    if args
        .category
        .as_deref()
        .is_some_and(|c| c.trim().is_empty())
    {
        return Err(BadInput("--category: empty category name".into()).into());
    }
    let (first, last, _) = samples(args.band, args.step);
    let mut materials: Vec<Material> = Vec::new();
    let mut warnings = Vec::new();
    let mut names: BTreeMap<String, PathBuf> = BTreeMap::new();
    for (i, s) in srcs.iter().enumerate() {
        let data = RiiData::read(&s.path)?;
        let (lo_um, hi_um) = data.range_um();
        if !(first / 1e3 >= lo_um && last / 1e3 <= hi_um) {
            let what = format!(
                "band {} is not covered by the data, whose range is {}–{} nm \
                 (no extrapolation)",
                args.band,
                nm(lo_um),
                nm(hi_um)
            );
            if args.skip_missing {
                warnings.push(format!("{}: {what}; skipped", s.path.display()));
                continue;
            }
            return Err(IoError::Model {
                path: s.path.clone(),
                reason: format!("{what}; choose another band or pass --skip-missing"),
            }
            .into());
        }
        let (n, k) = data.band_mean(args.band.lo, args.band.hi, args.step)?;
        if !(n > 0.0 && k >= 0.0) {
            return Err(IoError::Model {
                path: s.path.clone(),
                reason: format!(
                    "band mean n = {n}, k = {k} over {} is not a usable index \
                     (need n > 0, k >= 0)",
                    args.band
                ),
            }
            .into());
        }
        let m = mapped.get(&i).cloned().unwrap_or_default();
        let name = m.name.unwrap_or_else(|| default_name(&s.path));
        check_class_name(&name).map_err(|e| {
            BadInput(format!(
                "{}: default name {name:?}: {e}; name it with --names",
                s.path.display()
            ))
        })?;
        if let Some(prev) = names.insert(name.clone(), s.path.clone()) {
            return Err(BadInput(format!(
                "{}: name {name:?} is also the name of {}; name them with --names MAP.csv",
                s.path.display(),
                prev.display()
            ))
            .into());
        }
        let category = m
            .category
            .or_else(|| folder_category(s))
            .or_else(|| args.category.clone());
        let reference = m.reference.or_else(|| Some(s.rel.display().to_string()));
        materials.push(Material {
            name,
            category,
            n,
            k,
            reference,
            line: 0,
        });
    }
    if materials.is_empty() {
        return Err(BadInput(format!(
            "no material covers the band {}: every input file was skipped",
            args.band
        ))
        .into());
    }
    let source = args
        .output
        .as_ref()
        .map_or_else(|| "stdout".to_string(), |p| p.display().to_string());
    Ok((Library { source, materials }, warnings))
}

/// Run `polarid library`.
pub fn run(args: Args, ctx: &Ctx) -> anyhow::Result<()> {
    let (_, _, count) = samples(args.band, args.step);
    if count as f64 > MAX_SAMPLES {
        return Err(BadInput(format!(
            "--step {}: {count} samples over the band {} (at most {MAX_SAMPLES})",
            args.step, args.band
        ))
        .into());
    }
    let srcs = sources(&args.inputs)?;
    let (lib, warnings) = build(&args, &srcs)?;
    for w in &warnings {
        if !ctx.quiet {
            eprintln!("polarid: warning: {w}");
        }
    }
    let sampling = if count == 1 {
        format!("n, k at {} nm", args.band.lo)
    } else {
        format!(
            "n, k over {}: mean of {count} samples every {} nm",
            args.band, args.step
        )
    };
    let comment = format!(
        "polarid library: refractiveindex.info data (CC0; cite M. N. Polyanskiy, Sci. Data \
         11, 94 (2024) and each file's REFERENCES). {sampling}; tabulated data linearly \
         interpolated, k = 0 where only n is given"
    );
    let mut inputs: Vec<&Path> = srcs.iter().map(|s| s.path.as_path()).collect();
    if let Some(m) = &args.names {
        inputs.push(m.as_path());
    }
    let label = args
        .output
        .clone()
        .unwrap_or_else(|| PathBuf::from("<stdout>"));
    ctx.write_output(args.output.as_deref(), &inputs, |w| {
        lib.write_csv(w, &label, Some(&comment))
    })?;
    ctx.info(format!(
        "polarid library: {} materials, band {}{}",
        lib.materials.len(),
        args.band,
        if warnings.is_empty() {
            String::new()
        } else {
            format!(", {} file(s) skipped", warnings.len())
        }
    ));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn band_syntax() {
        assert_eq!(
            parse_band("520:545"),
            Ok(Band {
                lo: 520.0,
                hi: 545.0
            })
        );
        assert_eq!(
            parse_band("532"),
            Ok(Band {
                lo: 532.0,
                hi: 532.0
            })
        );
        assert!(parse_band("545:520").unwrap_err().contains("empty band"));
        assert!(parse_band("5x0:545").unwrap_err().contains("\"5x0\""));
        assert!(parse_band("-5").unwrap_err().contains("> 0"));
        assert!(parse_band("nan").is_err());
    }

    #[test]
    fn default_names() {
        assert_eq!(
            default_name(Path::new("/db/main/Au/nk/Johnson.yml")),
            "Au_Johnson"
        );
        assert_eq!(
            default_name(Path::new("specs/schott/optical/N-BK7.yml")),
            "N-BK7"
        );
        assert_eq!(
            default_name(Path::new("other/soots/acetylene soot/nk/Dalzell.yml")),
            "acetylene_soot_Dalzell"
        );
        assert_eq!(default_name(Path::new("gold.yaml")), "gold");
    }

    #[test]
    fn samples_match_band_mean() {
        let b = Band {
            lo: 610.0,
            hi: 690.0,
        };
        assert_eq!(samples(b, 1.0), (610.0, 690.0, 81));
        assert_eq!(samples(b, 30.0), (610.0, 670.0, 3));
        assert_eq!(
            samples(
                Band {
                    lo: 532.0,
                    hi: 532.0
                },
                1.0
            ),
            (532.0, 532.0, 1)
        );
    }
}
