//! Fits CSV — written by `fit`, read by `train` and `classify`.
//!
//! `target,class,n,k,n_se,k_se,nk_corr,rms_residual,measurements,status`
//! (extra columns written by polarid: `reason`, `model`, `sigma`, `rho_d`, `theta_r_deg`,
//! then the error model's `n_se_noise`, `k_se_noise`, `nk_corr_noise`, `gof_p`,
//! `aolp_p`; docs/ERRORS.md). `n_se`, `k_se`, `nk_corr` are the total (noise plus
//! systematic) uncertainty; the `_noise` columns the noise's part alone; the `_sample`
//! columns (`n_se_sample`, `k_se_sample`, `nk_corr_sample`, after `aolp_p`) the noise
//! plus the surface layer's variation from plate to plate, what a model's prototype is
//! compared with on its own bench (docs/ERRORS.md "Same bench"; optional on input).
//!
//! Multi-band fits (a colour camera) carry `wavelength_nm`, one row per target per band;
//! the column is written after `class` only when some row has a wavelength, so
//! single-band files keep exactly the columns above.
//!
//! Multi-band fits with the error model's surface layer also carry the fit's layer shifts
//! [`FILM_COLUMNS`] (`film1_dn`, `film1_dk`, … `film3_dk`, after `aolp_p`; written only
//! when some row has them, optional on input): the `(n, k)` shift of a layer of one
//! standard thickness of each index of `polarid_core::systematic::FILM_INDICES`, which
//! multi-band classification correlates across a target's bands (docs/BANDS.md).

use std::io::Write;
use std::path::Path;

use super::{BandedRow, CsvTable, fmt_f64, fmt_opt, write_banded};
use crate::error::Result;
use polarid_core::FitStatus;
use polarid_core::systematic::FilmShifts;

/// Column order of the fits CSV.
pub const COLUMNS: [&str; 23] = [
    "target",
    "class",
    "n",
    "k",
    "n_se",
    "k_se",
    "nk_corr",
    "rms_residual",
    "measurements",
    "status",
    "reason",
    "model",
    "sigma",
    "rho_d",
    "theta_r_deg",
    "n_se_noise",
    "k_se_noise",
    "nk_corr_noise",
    "gof_p",
    "aolp_p",
    "n_se_sample",
    "k_se_sample",
    "nk_corr_sample",
];

/// The layer-shift columns, in order: `[δn, δk]` of the layers of index 1.5, 2.8 and
/// 2.8 + 0.3i (`FILM_INDICES`), written after [`COLUMNS`] when some row has them.
pub const FILM_COLUMNS: [&str; 6] = [
    "film1_dn", "film1_dk", "film2_dn", "film2_dk", "film3_dn", "film3_dk",
];

/// One fitted target.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FitRow {
    /// Target name.
    pub target: String,
    /// Known class, if any.
    pub class: Option<String>,
    /// Centre wavelength of the band the target was fitted in, nm (`None`: single-band).
    pub wavelength_nm: Option<f64>,
    /// Real part of the index.
    pub n: f64,
    /// Imaginary part of the index.
    pub k: f64,
    /// Standard error of `n` (NaN when unknown).
    pub n_se: f64,
    /// Standard error of `k` (NaN when unknown).
    pub k_se: f64,
    /// Correlation of the `n` and `k` estimates (NaN when unknown).
    pub nk_corr: f64,
    /// Root-mean-square DoLP residual.
    pub rms_residual: f64,
    /// Number of measurements used.
    pub measurements: u64,
    /// [`FitStatus::Ok`], or why the estimate should not be trusted.
    pub status: FitStatus,
    /// Human-readable reason for a status other than `ok` (may be empty).
    pub reason: String,
    /// Reflectance model used (`specular` or `mixed`).
    pub model: String,
    /// Fitted roughness σ (mixed model only).
    pub sigma: Option<f64>,
    /// Fitted diffuse albedo ρd (mixed model only).
    pub rho_d: Option<f64>,
    /// Fitted camera zenith angle, degrees (when estimated).
    pub theta_r_deg: Option<f64>,
    /// Standard error of `n` from the noise alone (`n_se` is noise plus systematic).
    pub n_se_noise: Option<f64>,
    /// Standard error of `k` from the noise alone.
    pub k_se_noise: Option<f64>,
    /// Correlation of `n` and `k` from the noise alone.
    pub nk_corr_noise: Option<f64>,
    /// p-value of the χ² goodness of fit against the total (noise + systematic) DoLP
    /// covariance (weighted fits).
    pub gof_p: Option<f64>,
    /// p-value of the AoLP test (rows with `aolp_poi_deg`).
    pub aolp_p: Option<f64>,
    /// Standard error of `n` from the noise and the surface layer's variation between
    /// plates of one material (the sample covariance; docs/ERRORS.md "Same bench").
    pub n_se_sample: Option<f64>,
    /// Standard error of `k` of the sample covariance (one-sided upper deviation when
    /// formed in `(n, k²)`, as `k_se`).
    pub k_se_sample: Option<f64>,
    /// Correlation of the sample covariance.
    pub nk_corr_sample: Option<f64>,
    /// The fit's `(n, k)` shifts by a surface layer of one standard thickness of each
    /// `FILM_INDICES` index ([`FILM_COLUMNS`]; multi-band fits with a layer allowance).
    pub film: Option<FilmShifts>,
}

/// Read a fits CSV: needs `target`, `n`, `k`; the rest is optional (`status` defaults to
/// `ok`, standard errors to NaN: unknown).
///
/// `n_se`, `k_se` and `nk_corr` are unknown when their cell is empty; the literal `nan`
/// is refused in a usable (`ok`) row (naming the file, line, column and value) and
/// accepted only in a failed fit's row, whose `n` and `k` may be `nan` too.
pub fn read(path: &Path) -> Result<Vec<FitRow>> {
    let t = CsvTable::read(path)?;
    from_table(&t)
}

/// Parse fits from an already read table.
pub fn from_table(t: &CsvTable) -> Result<Vec<FitRow>> {
    let c_target = t.require("target")?;
    let c_n = t.require("n")?;
    let c_k = t.require("k")?;
    let c_class = t.col("class");
    let c_wl = t.col("wavelength_nm");
    let (c_nse, c_kse, c_corr, c_rms) = (
        t.col("n_se"),
        t.col("k_se"),
        t.col("nk_corr"),
        t.col("rms_residual"),
    );
    let (c_meas, c_status, c_reason, c_model) = (
        t.col("measurements"),
        t.col("status"),
        t.col("reason"),
        t.col("model"),
    );
    let (c_sigma, c_rho, c_tr) = (t.col("sigma"), t.col("rho_d"), t.col("theta_r_deg"));
    // Standard errors may legitimately be "nan" in our own output.
    let nan_ok = |r: usize, c: Option<usize>| -> Result<f64> {
        match c {
            Some(c) if t.text(r, c).eq_ignore_ascii_case("nan") => Ok(f64::NAN),
            _ => Ok(t.opt_f64(r, c)?.unwrap_or(f64::NAN)),
        }
    };
    // Optional numbers that may be "nan" (an empty cell: not known).
    let opt_nan = |r: usize, c: Option<usize>| -> Result<Option<f64>> {
        match c {
            Some(c) if t.text(r, c).eq_ignore_ascii_case("nan") => Ok(Some(f64::NAN)),
            _ => t.opt_f64(r, c),
        }
    };
    let c_film: Vec<Option<usize>> = FILM_COLUMNS.iter().map(|c| t.col(c)).collect();
    let mut out = Vec::with_capacity(t.rows.len());
    for r in 0..t.rows.len() {
        let target = t.name(r, c_target)?;
        if target.is_empty() {
            return Err(t.err(r, c_target, "empty target name"));
        }
        if let Some(c) = c_status.filter(|&c| t.text(r, c).is_empty()) {
            return Err(t.err(r, c, "empty fit status (write `ok` for a usable fit)"));
        }
        let status = match (c_status, t.opt_text(r, c_status)) {
            (Some(c), Some(word)) => FitStatus::parse(&word).ok_or_else(|| {
                let words: Vec<&str> = FitStatus::ALL.iter().map(|s| s.as_str()).collect();
                t.err(
                    r,
                    c,
                    format!("unknown fit status (expected one of {})", words.join(", ")),
                )
            })?,
            _ => FitStatus::Ok,
        };
        // n, k (and their errors) of a failed fit may be nan; of a usable fit they must
        // be numbers (errors: numbers or empty cells).
        let failed = !status.is_ok();
        let num = |c: usize| -> Result<f64> {
            if !status.is_ok() && t.text(r, c).eq_ignore_ascii_case("nan") {
                Ok(f64::NAN)
            } else {
                t.f64(r, c)
            }
        };
        let n = num(c_n)?;
        let k = num(c_k)?;
        if n <= 0.0 {
            return Err(t.err(r, c_n, "n must be > 0"));
        }
        if k < 0.0 {
            return Err(t.err(r, c_k, "k must be >= 0"));
        }
        let wavelength_nm = t.opt_f64(r, c_wl)?;
        if let (Some(w), Some(c)) = (wavelength_nm, c_wl)
            && !(w.is_finite() && w > 0.0)
        {
            return Err(t.err(r, c, "wavelength must be finite and > 0 nm"));
        }
        out.push(FitRow {
            target,
            class: t.opt_name(r, c_class)?,
            wavelength_nm,
            n,
            k,
            n_se: t.se(r, c_nse, failed)?,
            k_se: t.se(r, c_kse, failed)?,
            nk_corr: t.corr(r, c_corr, failed)?,
            rms_residual: nan_ok(r, c_rms)?,
            measurements: t.opt_u64(r, c_meas)?.unwrap_or(0),
            status,
            reason: t.opt_text(r, c_reason).unwrap_or_default(),
            model: t.opt_text(r, c_model).unwrap_or_else(|| "specular".into()),
            sigma: t.opt_f64(r, c_sigma)?,
            rho_d: t.opt_f64(r, c_rho)?,
            theta_r_deg: t.opt_f64(r, c_tr)?,
            n_se_noise: opt_nan(r, t.col("n_se_noise"))?,
            k_se_noise: opt_nan(r, t.col("k_se_noise"))?,
            nk_corr_noise: opt_nan(r, t.col("nk_corr_noise"))?,
            gof_p: opt_nan(r, t.col("gof_p"))?,
            aolp_p: opt_nan(r, t.col("aolp_p"))?,
            n_se_sample: opt_nan(r, t.col("n_se_sample"))?,
            k_se_sample: opt_nan(r, t.col("k_se_sample"))?,
            nk_corr_sample: opt_nan(r, t.col("nk_corr_sample"))?,
            film: film_cells(t, r, &c_film)?,
        });
    }
    Ok(out)
}

/// The layer shifts of row `r`: all six cells numbers (finite), or all empty (`None`);
/// a partial set is an error naming the first missing column.
fn film_cells(t: &CsvTable, r: usize, cols: &[Option<usize>]) -> Result<Option<FilmShifts>> {
    let mut v = [0.0; 6];
    let mut given = 0;
    for (i, &c) in cols.iter().enumerate() {
        if let Some(x) = t.opt_f64(r, c)? {
            if let (false, Some(c)) = (x.is_finite(), c) {
                return Err(t.err(r, c, "a layer shift must be a finite number"));
            }
            v[i] = x;
            given += 1;
        }
    }
    if given == 0 {
        return Ok(None);
    }
    if given < cols.len() {
        let any = cols.iter().flatten().copied().next().unwrap_or(0);
        let (i, c) = cols
            .iter()
            .enumerate()
            .find(|(_, c)| c.is_none_or(|c| t.text(r, c).is_empty()))
            .map_or((0, None), |(i, c)| (i, *c));
        return Err(t.err(
            r,
            c.unwrap_or(any),
            format!(
                "the layer shifts come in six ({}): `{}` is missing or empty",
                FILM_COLUMNS.join(", "),
                FILM_COLUMNS[i]
            ),
        ));
    }
    Ok(Some(FilmShifts([[v[0], v[1]], [v[2], v[3]], [v[4], v[5]]])))
}

/// A standard error or correlation as written: an unknown one (NaN) is an empty cell
/// in a usable (`ok`) row — the reader refuses the literal `nan` there — and `nan` in a
/// failed fit's row, like its `n` and `k`.
fn fmt_se(f: &FitRow, x: f64) -> String {
    if x.is_nan() && f.status.is_ok() {
        String::new()
    } else {
        fmt_f64(x)
    }
}

/// Write fits in the documented column order ([`COLUMNS`], with `wavelength_nm` after
/// `class` when some row has a wavelength).
pub fn write<W: Write + ?Sized>(w: &mut W, path: &Path, rows: &[FitRow]) -> Result<()> {
    let rows = rows.iter().map(|f| BandedRow {
        cells: vec![
            f.target.clone(),
            f.class.clone().unwrap_or_default(),
            fmt_f64(f.n),
            fmt_f64(f.k),
            fmt_se(f, f.n_se),
            fmt_se(f, f.k_se),
            fmt_se(f, f.nk_corr),
            fmt_f64(f.rms_residual),
            f.measurements.to_string(),
            f.status.as_str().to_string(),
            f.reason.clone(),
            f.model.clone(),
            fmt_opt(f.sigma),
            fmt_opt(f.rho_d),
            fmt_opt(f.theta_r_deg),
            fmt_opt(f.n_se_noise),
            fmt_opt(f.k_se_noise),
            fmt_opt(f.nk_corr_noise),
            fmt_opt(f.gof_p),
            fmt_opt(f.aolp_p),
            fmt_opt(f.n_se_sample),
            fmt_opt(f.k_se_sample),
            fmt_opt(f.nk_corr_sample),
        ],
        wavelength_nm: f.wavelength_nm,
        extra: f
            .film
            .as_ref()
            .map(|h| h.0.iter().flatten().map(|&x| fmt_f64(x)).collect()),
    });
    write_banded(w, path, &COLUMNS, &FILM_COLUMNS, rows.collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Vec<FitRow>> {
        from_table(&CsvTable::from_reader(Path::new("f.csv"), text.as_bytes())?)
    }

    #[test]
    fn literal_nan_errors_refused_in_usable_rows() {
        for (col, text) in [
            (
                "n_se",
                "target,n,k,n_se,k_se,nk_corr,status\nA,1.5,0,NaN,0.1,0.2,ok\n",
            ),
            (
                "k_se",
                "target,n,k,n_se,k_se,nk_corr,status\nA,1.5,0,0.1,nan,0.2,ok\n",
            ),
            (
                "nk_corr",
                "target,n,k,n_se,k_se,nk_corr\nA,1.5,0,0.1,0.1,NAN\n",
            ),
        ] {
            let e = parse(text).unwrap_err().to_string();
            assert!(
                e.contains("f.csv")
                    && e.contains("line 2")
                    && e.contains(&format!("`{col}`"))
                    && e.to_lowercase().contains("\"nan\"")
                    && e.contains("empty"),
                "{e}"
            );
        }
        // Empty cells: unknown.
        let rows = parse("target,n,k,n_se,k_se,nk_corr,status\nA,1.5,0,,,,ok\n").unwrap();
        assert!(rows[0].n_se.is_nan() && rows[0].k_se.is_nan() && rows[0].nk_corr.is_nan());
        // A failed fit's row may hold nan, as its n and k.
        let rows =
            parse("target,n,k,n_se,k_se,nk_corr,status\nA,nan,nan,nan,nan,nan,not_converged\n")
                .unwrap();
        assert!(rows[0].n.is_nan() && rows[0].n_se.is_nan());
    }

    #[test]
    fn layer_shifts_round_trip_and_come_in_six() {
        let h = FilmShifts([[-0.04, -0.13], [-0.076, -0.37], [-0.023, -0.41]]);
        let rows = vec![
            FitRow {
                target: "A".into(),
                wavelength_nm: Some(550.0),
                n: 0.46,
                k: 2.46,
                n_se: 0.1,
                k_se: 0.5,
                nk_corr: 0.3,
                film: Some(h),
                ..Default::default()
            },
            FitRow {
                target: "A".into(),
                wavelength_nm: Some(650.0),
                n: 0.16,
                k: 3.6,
                n_se: 0.1,
                k_se: 0.5,
                nk_corr: 0.3,
                ..Default::default()
            },
        ];
        let mut buf = Vec::new();
        write(&mut buf, Path::new("f.csv"), &rows).unwrap();
        let text = String::from_utf8(buf).unwrap();
        assert!(
            text.lines()
                .next()
                .unwrap()
                .ends_with("nk_corr_sample,film1_dn,film1_dk,film2_dn,film2_dk,film3_dn,film3_dk"),
            "{text}"
        );
        let back = parse(&text).unwrap();
        assert_eq!(back[0].film, Some(h));
        assert_eq!(back[1].film, None);
        // Old files (no columns) load; a partial set is refused naming the column.
        assert!(parse("target,n,k\nA,1.5,0\n").unwrap()[0].film.is_none());
        let e = parse("target,n,k,film1_dn,film1_dk\nA,1.5,0,0.1,0.2\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 2") && e.contains("film2_dn"), "{e}");
        // Without any layer shift the columns are not written.
        let mut buf = Vec::new();
        let plain = vec![FitRow {
            film: None,
            ..rows[1].clone()
        }];
        write(&mut buf, Path::new("f.csv"), &plain).unwrap();
        assert!(!String::from_utf8(buf).unwrap().contains("film1_dn"));
    }

    #[test]
    fn unknown_errors_written_as_empty_cells_and_read_back() {
        let rows = vec![
            FitRow {
                target: "A".into(),
                n: 1.5,
                k: 0.0,
                n_se: f64::NAN,
                k_se: 0.01,
                nk_corr: f64::NAN,
                status: FitStatus::Ok,
                ..Default::default()
            },
            FitRow {
                target: "B".into(),
                n: f64::NAN,
                k: f64::NAN,
                n_se: f64::NAN,
                k_se: f64::NAN,
                nk_corr: f64::NAN,
                status: FitStatus::InvalidInput,
                ..Default::default()
            },
        ];
        let mut buf = Vec::new();
        write(&mut buf, Path::new("f.csv"), &rows).unwrap();
        let text = String::from_utf8(buf).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert!(lines[1].starts_with("A,,1.5,0,,0.01,,"), "{}", lines[1]);
        assert!(
            lines[2].starts_with("B,,nan,nan,nan,nan,nan,"),
            "{}",
            lines[2]
        );
        let back = parse(&text).unwrap();
        assert!(back[0].n_se.is_nan() && back[0].nk_corr.is_nan() && back[0].k_se == 0.01);
        assert!(back[1].n_se.is_nan() && back[1].status == FitStatus::InvalidInput);
    }
}
