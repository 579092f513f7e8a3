//! The YAML files of a library build, their default names and categories, and the
//! `--names` map.

use std::collections::BTreeMap;
use std::fs;
use std::path::{Path, PathBuf};

use polarid_core::classify::check_class_name;
use polarid_io::IoError;
use polarid_io::table::CsvTable;

use crate::error::{PipelineError, Result};

/// Categories recognised in folder names below a directory input.
const CATEGORIES: [&str; 4] = ["metal", "dielectric", "semiconductor", "other"];

/// One YAML file to read.
#[derive(Debug, Clone)]
pub(crate) struct Source {
    /// The file.
    pub path: PathBuf,
    /// Its path relative to the directory input it was found in (the path as given for
    /// a file input).
    pub rel: PathBuf,
    /// The directory input it was found in (`None` for a file input).
    pub root: Option<PathBuf>,
}

fn is_yaml(p: &Path) -> bool {
    p.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("yml") || e.eq_ignore_ascii_case("yaml"))
}

/// The *.yml / *.yaml files below `dir`, sorted by path (symbolic links to folders are
/// not followed).
fn scan_dir(root: &Path, dir: &Path, out: &mut Vec<Source>) -> Result<()> {
    let rd = fs::read_dir(dir).map_err(|e| IoError::io(dir, e))?;
    let mut entries = rd
        .map(|e| e.map(|e| e.path()).map_err(|e| IoError::io(dir, e)))
        .collect::<std::result::Result<Vec<PathBuf>, _>>()?;
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

/// The YAML files of the inputs (files, or folders scanned recursively), each once.
pub(crate) fn sources(inputs: &[PathBuf]) -> Result<Vec<Source>> {
    let mut out: Vec<Source> = Vec::new();
    for input in inputs {
        if input.is_dir() {
            let before = out.len();
            scan_dir(input, input, &mut out)?;
            if out.len() == before {
                return Err(PipelineError::Data {
                    path: input.display().to_string(),
                    reason: "no *.yml or *.yaml files".into(),
                });
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
pub fn default_name(path: &Path) -> String {
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
pub(crate) fn folder_category(s: &Source) -> Option<String> {
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

/// A surface layer named by the map: the layer material, the thickness range and, for a
/// layer material without built-in data, its constant index.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct LayerSpec {
    pub name: String,
    pub min_nm: f64,
    pub max_nm: f64,
    pub index: Option<(f64, f64)>,
}

/// Name, category, reference and surface layer given by the map for one file.
#[derive(Debug, Clone, Default)]
pub(crate) struct Mapped {
    pub name: Option<String>,
    pub category: Option<String>,
    pub reference: Option<String>,
    /// `None`: the map says nothing (the default applies); `Some(None)`: `none`, no layer.
    pub layer: Option<Option<LayerSpec>>,
}

/// The map's optional surface columns (`layer`, `layer_min_nm`, `layer_max_nm`, and
/// `layer_n`, `layer_k` for a constant index).
struct LayerCols {
    layer: usize,
    min: Option<usize>,
    max: Option<usize>,
    n: Option<usize>,
    k: Option<usize>,
}

/// The surface layer of map row `r`: an empty `layer` cell → the default (`None`);
/// `none` → no layer; else a layer material with `0 <= layer_min_nm <= layer_max_nm`,
/// whose index is `layer_n`, `layer_k` when given (both), else the built-in data of a
/// known layer material ([`polarid_io::surfaces::LAYER_SOURCES`]).
fn map_layer(t: &CsvTable, r: usize, c: &LayerCols) -> Result<Option<Option<LayerSpec>>> {
    let name = t.name(r, c.layer)?;
    let others = [c.min, c.max, c.n, c.k];
    if name.is_empty() || name.eq_ignore_ascii_case("none") {
        for cc in others.into_iter().flatten() {
            if !t.text(r, cc).is_empty() {
                return Err(t
                    .err(r, cc, "a layer value without a `layer` material")
                    .into());
            }
        }
        return Ok((!name.is_empty()).then_some(None));
    }
    let need = |col: Option<usize>, what: &str| -> Result<f64> {
        match col {
            Some(cc) => Ok(t.f64(r, cc)?),
            None => Err(t
                .err(r, c.layer, format!("a layer needs the column `{what}`"))
                .into()),
        }
    };
    let min_nm = need(c.min, "layer_min_nm")?;
    let max_nm = need(c.max, "layer_max_nm")?;
    if min_nm < 0.0 {
        // ok: need() succeeded, so the column exists.
        return Err(t
            .err(
                r,
                c.min.unwrap_or(c.layer),
                "layer thickness must be >= 0 nm",
            )
            .into());
    }
    if max_nm < min_nm {
        return Err(t
            .err(
                r,
                c.max.unwrap_or(c.layer),
                format!("layer_max_nm must be >= layer_min_nm ({min_nm})"),
            )
            .into());
    }
    let n = t.opt_f64(r, c.n)?;
    let k = t.opt_f64(r, c.k)?;
    let index = match (n, k) {
        (Some(n), Some(k)) if n > 0.0 && k >= 0.0 => Some((n, k)),
        (Some(_), Some(_)) => {
            return Err(t
                .err(
                    r,
                    c.n.unwrap_or(c.layer),
                    "layer index needs layer_n > 0 and layer_k >= 0",
                )
                .into());
        }
        (None, None) => None,
        _ => {
            return Err(t
                .err(
                    r,
                    c.layer,
                    "layer_n and layer_k go together (give both or neither)",
                )
                .into());
        }
    };
    if index.is_none() && polarid_io::surfaces::layer_source(&name).is_none() {
        let known: Vec<&str> = polarid_io::surfaces::LAYER_SOURCES
            .iter()
            .map(|l| l.name)
            .collect();
        return Err(t
            .err(
                r,
                c.layer,
                format!(
                    "unknown layer material{} (built-in ones: {}); give its index with \
                     layer_n, layer_k",
                    polarid_io::suggest::did_you_mean(&name, known.iter().copied()),
                    known.join(", ")
                ),
            )
            .into());
    }
    Ok(Some(Some(LayerSpec {
        name,
        min_nm,
        max_nm,
        index,
    })))
}

/// Read the `--names` map and assign its rows to the sources (index → entry).
pub(crate) fn read_names(map: &Path, srcs: &[Source]) -> Result<BTreeMap<usize, Mapped>> {
    let t = CsvTable::read(map)?;
    let c_file = t.require("file")?;
    let c_name = t.require("name")?;
    let c_cat = t.col("category");
    let c_ref = t.col("reference");
    let layer_cols = t.col("layer").map(|layer| LayerCols {
        layer,
        min: t.col("layer_min_nm"),
        max: t.col("layer_max_nm"),
        n: t.col("layer_n"),
        k: t.col("layer_k"),
    });
    if layer_cols.is_none() {
        for c in ["layer_min_nm", "layer_max_nm", "layer_n", "layer_k"] {
            if t.col(c).is_some() {
                return Err(IoError::CsvStructure {
                    path: t.path.clone(),
                    reason: format!("column `{c}` without a `layer` column"),
                }
                .into());
            }
        }
    }
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
                layer: match &layer_cols {
                    Some(c) => map_layer(&t, r, c)?,
                    None => None,
                },
            },
        );
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
