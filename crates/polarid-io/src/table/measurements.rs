//! Measurements CSV — written by `measure`, read by `fit`.
//!
//! `target,class,theta_i_deg,theta_r_deg,phi_deg,beta_deg,dolp,dolp_se,s0,pixels,rejected`
//! (extra columns written by polarid: `exposure`, `saturated`), then the optional
//! columns [`OPTIONAL_COLUMNS`] (`wavelength_nm`, the spectral band of the row; `beta_sd_deg`, `aolp_deg`, `aolp_poi_deg` of calibrated
//! captures, `angle_sd_deg` when the manifest gives it), each written only when some row
//! has a value for it, so a far-field file keeps exactly the columns above. Then the
//! text column `reference` ([`REFERENCE_COLUMN`]) when some region is an in-scene
//! reference of known material ([`Reference`]): its rows carry the material's name or
//! its index `n+ki`, the other rows are empty.
//!
//! Partial failure: a row that was measured but must not be fitted (a dark region, a
//! region without a usable pixel in that capture) carries a [`RowStatus`] other than
//! `ok` and a reason, in the optional columns `status` and `reason` (written only when
//! some row is not `ok`). `fit` skips such rows. Their values may be `nan` (no pixel,
//! no DoLP) and are not range-checked.

use std::io::Write;
use std::path::Path;

use polarid_core::geometry;

use super::{CsvTable, fmt_f64, fmt_opt, write_rows};
use crate::error::Result;

/// Column order of the measurements CSV.
pub const COLUMNS: [&str; 13] = [
    "target",
    "class",
    "theta_i_deg",
    "theta_r_deg",
    "phi_deg",
    "beta_deg",
    "dolp",
    "dolp_se",
    "s0",
    "pixels",
    "rejected",
    "exposure",
    "saturated",
];

/// The optional columns, in output order: written after [`COLUMNS`], each one only when
/// some row has a value.
pub const OPTIONAL_COLUMNS: [&str; 5] = [
    "wavelength_nm",
    "beta_sd_deg",
    "aolp_deg",
    "aolp_poi_deg",
    "angle_sd_deg",
];

/// The optional text column of in-scene reference regions ([`Reference`]), written after
/// [`OPTIONAL_COLUMNS`] when some row has one.
pub const REFERENCE_COLUMN: &str = "reference";

/// The status columns, written last and only when some row is not
/// [`RowStatus::Ok`].
pub const STATUS_COLUMNS: [&str; 2] = ["status", "reason"];

/// Whether a measurement row may be fitted (the optional `status` column; an empty cell
/// or no column is `ok`).
#[non_exhaustive]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum RowStatus {
    /// Measured and usable.
    #[default]
    Ok,
    /// The region's signal is below the capture's dark threshold (docs/FORMATS.md,
    /// "Dark regions"): its DoLP is biased by quantization, clipping and noise and is
    /// not fitted.
    Dark,
    /// Every pixel of the region is rejected, most of them saturated.
    Saturated,
    /// Every pixel of the region is rejected, most of them invalid (non-finite data).
    Invalid,
}

impl RowStatus {
    /// Every status, in documentation order.
    pub const ALL: [RowStatus; 4] = [
        RowStatus::Ok,
        RowStatus::Dark,
        RowStatus::Saturated,
        RowStatus::Invalid,
    ];

    /// The word of the `status` column: `ok`, `dark`, `saturated`, `invalid`.
    pub fn as_str(self) -> &'static str {
        match self {
            RowStatus::Ok => "ok",
            RowStatus::Dark => "dark",
            RowStatus::Saturated => "saturated",
            RowStatus::Invalid => "invalid",
        }
    }

    /// The status of a word of [`RowStatus::as_str`] (exact); `None` otherwise.
    pub fn parse(word: &str) -> Option<RowStatus> {
        RowStatus::ALL.into_iter().find(|s| s.as_str() == word)
    }

    /// True for [`RowStatus::Ok`]: the row may be fitted.
    pub fn is_ok(self) -> bool {
        self == RowStatus::Ok
    }
}

impl std::fmt::Display for RowStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// One row: a target's DoLP in one capture.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Measurement {
    /// Target (region) name.
    pub target: String,
    /// Known class, if any.
    pub class: Option<String>,
    /// Source zenith angle, degrees.
    pub theta_i_deg: Option<f64>,
    /// Camera zenith angle, degrees.
    pub theta_r_deg: Option<f64>,
    /// `phi_r - phi_i`, degrees (default 180).
    pub phi_deg: f64,
    /// Half the source–camera angle, degrees (eq. 5).
    pub beta_deg: f64,
    /// DoLP of the region's mean Stokes vector.
    pub dolp: f64,
    /// Standard error of `dolp`.
    pub dolp_se: Option<f64>,
    /// Mean S0 (divided by the exposure).
    pub s0: Option<f64>,
    /// Pixels used.
    pub pixels: Option<u64>,
    /// Pixels rejected (saturated, dark, invalid).
    pub rejected: Option<u64>,
    /// Relative exposure of the capture (S0 was divided by it).
    pub exposure: Option<f64>,
    /// Pixels rejected because they were saturated (part of `rejected`).
    pub saturated: Option<u64>,
    /// S0-weighted standard deviation of β over the region's pixels, degrees
    /// (calibrated geometry; `None`/0: one β).
    pub beta_sd_deg: Option<f64>,
    /// AoLP of the region's mean Stokes vector in the image, degrees, `[0, 180)`.
    pub aolp_deg: Option<f64>,
    /// AoLP of the region's mean Stokes vector in the pixels' plane-of-incidence frames,
    /// measured from the plane of incidence, degrees, `[0, 180)` (90 for a single
    /// interface).
    pub aolp_poi_deg: Option<f64>,
    /// Standard uncertainty of the directions of the source and of the camera, degrees
    /// (the manifest's `angle_sd_deg`; `None`: `fit`'s default applies, docs/ERRORS.md).
    pub angle_sd_deg: Option<f64>,
    /// Whether the row may be fitted ([`RowStatus::Ok`] unless the region was dark or
    /// had no usable pixel in this capture).
    pub status: RowStatus,
    /// Why the status is not `ok` (empty for `ok`).
    pub reason: String,
    /// Centre wavelength of the row's spectral band, nm (`None`: single-band data).
    /// `fit` fits each (target, band) separately.
    pub wavelength_nm: Option<f64>,
    /// The region is an in-scene reference of this known material (the manifest's
    /// `reference`, or `reference_n` and `reference_k`; the optional column
    /// `reference`): `classify` calibrates the polarimeter with it (docs/CLASSIFY.md).
    pub reference: Option<Reference>,
}

/// The known material of an in-scene reference region: a material of the built-in
/// library by name, or an index `N = n + ik`. In the `reference` column a name is
/// written as it is and an index as `n+ki` (e.g. `1.5168+0i`).
#[derive(Debug, Clone, PartialEq)]
pub enum Reference {
    /// A material name (of the built-in library, or of the library `classify` uses).
    Material(String),
    /// A known index, the same at every band.
    Index {
        /// Real part, > 0.
        n: f64,
        /// Imaginary part, >= 0.
        k: f64,
    },
}

impl Reference {
    /// The text of the `reference` column: the name, or `n+ki`.
    pub fn text(&self) -> String {
        match self {
            Reference::Material(name) => name.clone(),
            Reference::Index { n, k } => format!("{}+{}i", fmt_f64(*n), fmt_f64(*k)),
        }
    }

    /// The reference of a `reference` cell: `n+ki` with finite `n > 0`, `k >= 0` is an
    /// index, anything else a material name; `None` for an empty cell.
    pub fn parse(text: &str) -> Option<Reference> {
        let t = text.trim();
        if t.is_empty() {
            return None;
        }
        if let Some(body) = t.strip_suffix('i') {
            for (i, _) in body.match_indices('+').filter(|(i, _)| *i > 0) {
                let (a, b) = (&body[..i], &body[i + 1..]);
                if let (Ok(n), Ok(k)) = (a.parse::<f64>(), b.parse::<f64>())
                    && n.is_finite()
                    && n > 0.0
                    && k.is_finite()
                    && k >= 0.0
                {
                    return Some(Reference::Index { n, k });
                }
            }
        }
        Some(Reference::Material(t.to_string()))
    }
}

impl std::fmt::Display for Reference {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Reference::Material(name) => f.write_str(name),
            Reference::Index { n, k } => write!(f, "N = {n} + {k}i"),
        }
    }
}

/// Read a measurements CSV. Needs `target`, `dolp` and either `beta_deg` or
/// `theta_i_deg` and `theta_r_deg` (`phi_deg` defaults to 180; `beta_deg` then follows
/// from eq. 5, also out of the plane of incidence). Angles must be finite and in
/// `[0, 90)`, `dolp` in `[0, 1]`, `dolp_se` positive; the optional `beta_sd_deg` in
/// `[0, 90)`, `aolp_deg` and `aolp_poi_deg` in `[0, 180)`, `angle_sd_deg` in `[0, 90)`.
pub fn read(path: &Path) -> Result<Vec<Measurement>> {
    let t = CsvTable::read(path)?;
    from_table(&t)
}

/// Parse measurements from an already read table.
pub fn from_table(t: &CsvTable) -> Result<Vec<Measurement>> {
    let c_target = t.require("target")?;
    let c_dolp = t.require("dolp")?;
    let c_beta = t.col("beta_deg");
    let c_ti = t.col("theta_i_deg");
    let c_tr = t.col("theta_r_deg");
    if c_beta.is_none() && (c_ti.is_none() || c_tr.is_none()) {
        // Report the first missing one.
        t.require(if c_ti.is_none() {
            "theta_i_deg"
        } else {
            "theta_r_deg"
        })
        .map_err(|_| crate::error::IoError::CsvStructure {
            path: t.path.clone(),
            reason: "needs column `beta_deg`, or columns `theta_i_deg` and `theta_r_deg`".into(),
        })?;
    }
    let c_status = t.col("status");
    let c_reason = t.col("reason");
    let c_ref = t.col(REFERENCE_COLUMN);
    let mut out = Vec::with_capacity(t.rows.len());
    // One reference per target: every row of a target says the same.
    let mut refs: Vec<(String, Option<Reference>, u64)> = Vec::new();
    for r in 0..t.rows.len() {
        let target = t.name(r, c_target)?;
        if target.is_empty() {
            return Err(t.err(r, c_target, "empty target name"));
        }
        let reference = c_ref.and_then(|c| Reference::parse(t.text(r, c)));
        if let Some(c) = c_ref {
            match refs.iter().find(|x| x.0 == target) {
                Some((_, first, line)) if *first != reference => {
                    return Err(t.err(
                        r,
                        c,
                        format!(
                            "target {target:?} has another reference on line {line} ({}): \
                             a region is one material in every row",
                            first.as_ref().map_or("none".into(), Reference::text)
                        ),
                    ));
                }
                Some(_) => {}
                None => refs.push((target.clone(), reference.clone(), t.rows[r].0)),
            }
        }
        let status = match c_status.map(|c| (c, t.text(r, c))) {
            None | Some((_, "")) => RowStatus::Ok,
            Some((c, w)) => RowStatus::parse(w).ok_or_else(|| {
                t.err(
                    r,
                    c,
                    "unknown status (expected ok, dark, saturated or invalid)",
                )
            })?,
        };
        out.push(if status.is_ok() {
            measured_row(t, r, c_dolp, target, reference)?
        } else {
            Measurement {
                reference,
                ..skipped_row(t, r, target, status, c_reason)?
            }
        });
    }
    Ok(out)
}

/// A row whose status is `ok` (`c_dolp`: the `dolp` column): its values checked.
fn measured_row(
    t: &CsvTable,
    r: usize,
    c_dolp: usize,
    target: String,
    reference: Option<Reference>,
) -> Result<Measurement> {
    let c_beta = t.col("beta_deg");
    let c_ti = t.col("theta_i_deg");
    let c_tr = t.col("theta_r_deg");
    let c_phi = t.col("phi_deg");
    let c_class = t.col("class");
    let c_se = t.col("dolp_se");
    let c_s0 = t.col("s0");
    let c_pix = t.col("pixels");
    let c_rej = t.col("rejected");
    let c_exp = t.col("exposure");
    let c_sat = t.col("saturated");
    let c_bsd = t.col("beta_sd_deg");
    let c_aolp = t.col("aolp_deg");
    let c_apoi = t.col("aolp_poi_deg");
    let c_asd = t.col("angle_sd_deg");
    let c_reason = t.col("reason");
    let c_wl = t.col("wavelength_nm");
    let status = RowStatus::Ok;
    let angle = |c: Option<usize>| -> Result<Option<f64>> {
        let v = t.opt_f64(r, c)?;
        if let (Some(v), Some(c)) = (v, c)
            && !(0.0..90.0).contains(&v)
        {
            return Err(t.err(r, c, "angle outside [0, 90) degrees"));
        }
        Ok(v)
    };
    let theta_i_deg = angle(c_ti)?;
    let theta_r_deg = angle(c_tr)?;
    let phi_deg = t.opt_f64(r, c_phi)?.unwrap_or(180.0);
    let beta_deg = match (t.opt_f64(r, c_beta)?, theta_i_deg, theta_r_deg) {
        (Some(b), _, _) => {
            let c = c_beta.unwrap_or(0);
            if !(0.0..90.0).contains(&b) {
                return Err(t.err(r, c, "angle outside [0, 90) degrees"));
            }
            b
        }
        (None, Some(ti), Some(tr)) => {
            geometry::beta(ti.to_radians(), tr.to_radians(), phi_deg.to_radians()).to_degrees()
        }
        (None, _, _) => {
            let c = c_beta.or(c_ti).unwrap_or(0);
            return Err(t.err(
                r,
                c,
                "missing value: need beta_deg, or theta_i_deg and theta_r_deg",
            ));
        }
    };
    let dolp = t.f64(r, c_dolp)?;
    if !(0.0..=1.0).contains(&dolp) {
        return Err(t.err(r, c_dolp, "DoLP outside [0, 1]"));
    }
    let dolp_se = t.opt_f64(r, c_se)?;
    if let (Some(se), Some(c)) = (dolp_se, c_se)
        && se <= 0.0
    {
        return Err(t.err(r, c, "standard error must be > 0"));
    }
    let in_range = |c: Option<usize>, hi: f64, what: &str| -> Result<Option<f64>> {
        let v = t.opt_f64(r, c)?;
        if let (Some(v), Some(c)) = (v, c)
            && !(0.0..hi).contains(&v)
        {
            return Err(t.err(r, c, format!("{what} outside [0, {hi}) degrees")));
        }
        Ok(v)
    };
    let beta_sd_deg = in_range(c_bsd, 90.0, "spread of beta")?;
    let aolp_deg = in_range(c_aolp, 180.0, "AoLP")?;
    let aolp_poi_deg = in_range(c_apoi, 180.0, "AoLP")?;
    let angle_sd_deg = in_range(c_asd, 90.0, "angle uncertainty")?;
    let wavelength_nm = t.opt_f64(r, c_wl)?;
    if let (Some(w), Some(c)) = (wavelength_nm, c_wl)
        && !(w.is_finite() && w > 0.0)
    {
        return Err(t.err(r, c, "wavelength must be finite and > 0 nm"));
    }
    Ok(Measurement {
        target,
        class: t.opt_name(r, c_class)?,
        theta_i_deg,
        theta_r_deg,
        phi_deg,
        beta_deg,
        dolp,
        dolp_se,
        s0: t.opt_f64(r, c_s0)?,
        pixels: t.opt_u64(r, c_pix)?,
        rejected: t.opt_u64(r, c_rej)?,
        exposure: t.opt_f64(r, c_exp)?,
        saturated: t.opt_u64(r, c_sat)?,
        beta_sd_deg,
        aolp_deg,
        aolp_poi_deg,
        angle_sd_deg,
        status,
        reason: t.opt_text(r, c_reason).unwrap_or_default(),
        wavelength_nm,
        reference,
    })
}

/// A row whose status is not `ok`: its numbers are read as they are (`nan` or empty
/// allowed, no range checks), since `fit` does not use them.
fn skipped_row(
    t: &CsvTable,
    r: usize,
    target: String,
    status: RowStatus,
    c_reason: Option<usize>,
) -> Result<Measurement> {
    let num = |name: &str| -> Result<Option<f64>> {
        let Some(c) = t.col(name) else {
            return Ok(None);
        };
        let text = t.text(r, c);
        if text.is_empty() {
            return Ok(None);
        }
        text.parse::<f64>()
            .map(|v| Some(v).filter(|v| !v.is_nan()))
            .map_err(|_| t.err(r, c, "not a number"))
    };
    let nan = f64::NAN;
    Ok(Measurement {
        target,
        class: t.opt_text(r, t.col("class")),
        theta_i_deg: num("theta_i_deg")?,
        theta_r_deg: num("theta_r_deg")?,
        phi_deg: num("phi_deg")?.unwrap_or(180.0),
        beta_deg: num("beta_deg")?.unwrap_or(nan),
        dolp: num("dolp")?.unwrap_or(nan),
        dolp_se: num("dolp_se")?,
        s0: num("s0")?,
        pixels: t.opt_u64(r, t.col("pixels"))?,
        rejected: t.opt_u64(r, t.col("rejected"))?,
        exposure: num("exposure")?,
        saturated: t.opt_u64(r, t.col("saturated"))?,
        beta_sd_deg: num("beta_sd_deg")?,
        aolp_deg: num("aolp_deg")?,
        aolp_poi_deg: num("aolp_poi_deg")?,
        angle_sd_deg: num("angle_sd_deg")?,
        wavelength_nm: num("wavelength_nm")?,
        status,
        reason: t.opt_text(r, c_reason).unwrap_or_default(),
        reference: None,
    })
}

/// Write measurements in the documented column order: [`COLUMNS`], then those of
/// [`OPTIONAL_COLUMNS`] that some row has a value for, then [`STATUS_COLUMNS`] when
/// some row is not `ok`.
pub fn write<W: Write + ?Sized>(w: &mut W, path: &Path, rows: &[Measurement]) -> Result<()> {
    let optional: [fn(&Measurement) -> Option<f64>; 5] = [
        |m| m.wavelength_nm,
        |m| m.beta_sd_deg,
        |m| m.aolp_deg,
        |m| m.aolp_poi_deg,
        |m| m.angle_sd_deg,
    ];
    let present: Vec<usize> = (0..optional.len())
        .filter(|&i| rows.iter().any(|m| optional[i](m).is_some()))
        .collect();
    let mut headers: Vec<&str> = COLUMNS.to_vec();
    headers.extend(present.iter().map(|&i| OPTIONAL_COLUMNS[i]));
    let with_ref = rows.iter().any(|m| m.reference.is_some());
    if with_ref {
        headers.push(REFERENCE_COLUMN);
    }
    let with_status = rows.iter().any(|m| !m.status.is_ok());
    if with_status {
        headers.extend(STATUS_COLUMNS);
    }
    write_rows(
        w,
        path,
        &headers,
        rows.iter().map(|m| {
            let mut cells = vec![
                m.target.clone(),
                m.class.clone().unwrap_or_default(),
                fmt_opt(m.theta_i_deg),
                fmt_opt(m.theta_r_deg),
                fmt_f64(m.phi_deg),
                fmt_f64(m.beta_deg),
                fmt_f64(m.dolp),
                fmt_opt(m.dolp_se),
                fmt_opt(m.s0),
                m.pixels.map(|v| v.to_string()).unwrap_or_default(),
                m.rejected.map(|v| v.to_string()).unwrap_or_default(),
                fmt_opt(m.exposure),
                m.saturated.map(|v| v.to_string()).unwrap_or_default(),
            ];
            cells.extend(present.iter().map(|&i| fmt_opt(optional[i](m))));
            if with_ref {
                cells.push(
                    m.reference
                        .as_ref()
                        .map(Reference::text)
                        .unwrap_or_default(),
                );
            }
            if with_status {
                cells.push(m.status.as_str().to_string());
                cells.push(m.reason.clone());
            }
            cells
        }),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header(rows: &[Measurement]) -> String {
        let mut buf = Vec::new();
        write(&mut buf, Path::new("m.csv"), rows).unwrap();
        String::from_utf8(buf)
            .unwrap()
            .lines()
            .next()
            .unwrap()
            .to_string()
    }

    #[test]
    fn optional_columns_only_when_some_row_has_them() {
        let far = Measurement {
            target: "A".into(),
            phi_deg: 180.0,
            beta_deg: 45.0,
            dolp: 0.5,
            ..Default::default()
        };
        assert_eq!(header(std::slice::from_ref(&far)), COLUMNS.join(","));
        let cal = Measurement {
            aolp_poi_deg: Some(90.0),
            beta_sd_deg: Some(1.5),
            ..far.clone()
        };
        assert_eq!(
            header(&[far.clone(), cal]),
            format!("{},beta_sd_deg,aolp_poi_deg", COLUMNS.join(","))
        );
        let text = "target,dolp,beta_deg,beta_sd_deg,aolp_poi_deg\nA,0.5,45,-1,90\n";
        let t = CsvTable::from_reader(Path::new("m.csv"), text.as_bytes()).unwrap();
        let e = from_table(&t).unwrap_err().to_string();
        assert!(e.contains("beta_sd_deg") && e.contains("\"-1\""), "{e}");
        let text = "target,dolp,beta_deg,aolp_poi_deg\nA,0.5,45,180\n";
        let t = CsvTable::from_reader(Path::new("m.csv"), text.as_bytes()).unwrap();
        assert!(from_table(&t).is_err());
        let with_sd = Measurement {
            angle_sd_deg: Some(0.1),
            ..far.clone()
        };
        assert_eq!(
            header(&[with_sd]),
            format!("{},angle_sd_deg", COLUMNS.join(","))
        );
        let text = "target,dolp,beta_deg,angle_sd_deg\nA,0.5,45,-0.1\n";
        let t = CsvTable::from_reader(Path::new("m.csv"), text.as_bytes()).unwrap();
        let e = from_table(&t).unwrap_err().to_string();
        assert!(e.contains("angle_sd_deg") && e.contains("\"-0.1\""), "{e}");
        let text = "target,dolp,beta_deg,angle_sd_deg\nA,0.5,45,0.25\n";
        let t = CsvTable::from_reader(Path::new("m.csv"), text.as_bytes()).unwrap();
        assert_eq!(from_table(&t).unwrap()[0].angle_sd_deg, Some(0.25));
        let banded = Measurement {
            wavelength_nm: Some(550.0),
            ..far.clone()
        };
        assert_eq!(
            header(&[far.clone(), banded]),
            format!("{},wavelength_nm", COLUMNS.join(","))
        );
        let text = "target,dolp,beta_deg,wavelength_nm\nA,0.5,45,-450\n";
        let t = CsvTable::from_reader(Path::new("m.csv"), text.as_bytes()).unwrap();
        let e = from_table(&t).unwrap_err().to_string();
        assert!(e.contains("wavelength_nm") && e.contains("\"-450\""), "{e}");
    }

    #[test]
    fn the_reference_column_round_trips_and_is_one_per_target() {
        let row = |t: &str, r: Option<Reference>| Measurement {
            target: t.into(),
            phi_deg: 180.0,
            beta_deg: 50.0,
            dolp: 0.5,
            reference: r,
            ..Default::default()
        };
        let rows = vec![
            row("slide", Some(Reference::Material("N-BK7".into()))),
            row("plate", None),
            row("glass", Some(Reference::Index { n: 1.5, k: 0.0 })),
        ];
        let mut buf = Vec::new();
        write(&mut buf, Path::new("m.csv"), &rows).unwrap();
        let text = String::from_utf8(buf).unwrap();
        assert!(
            text.lines().next().unwrap().ends_with(",reference"),
            "{text}"
        );
        assert!(text.contains("1.5+0i"), "{text}");
        let t = CsvTable::from_reader(Path::new("m.csv"), text.as_bytes()).unwrap();
        assert_eq!(from_table(&t).unwrap(), rows);
        // Without references the column is not written (old files keep their columns).
        assert!(!header(&[row("plate", None)]).contains("reference"));
        // A target whose rows disagree is refused, naming the column and the values.
        let text = "target,dolp,beta_deg,reference\nS,0.5,45,N-BK7\nS,0.6,50,N-SF11\n";
        let t = CsvTable::from_reader(Path::new("m.csv"), text.as_bytes()).unwrap();
        let e = from_table(&t).unwrap_err().to_string();
        assert!(
            e.contains("reference") && e.contains("N-SF11") && e.contains("N-BK7"),
            "{e}"
        );
    }
}
