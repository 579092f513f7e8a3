//! Rows of `polarid model` (`docs/FORMATS.md`): the inputs of the forward model and
//! the columns it writes.
//!
//! Two kinds of input rows, told apart by the header:
//!
//! - **pBRDF rows** — columns `n,k,sigma,theta_i_deg,theta_r_deg,phi_deg` (chosen
//!   whenever `sigma`, `theta_i_deg`, `theta_r_deg` and `phi_deg` are all present).
//!   Output: those columns, then `beta_deg,facet_tilt_deg,m00,m01,m02,m10,m11,m12,m20,
//!   m21,m22,m01_psps,m02_psps,m10_psps,m11_psps,m12_psps,m20_psps,m21_psps,m22_psps,
//!   dolp` ([`PBRDF_COMPUTED`]). `m00_psps` is not written: `m00` is the same in both
//!   frames (as in `data/oracles/pbrdf_reference.csv`).
//! - **DoP rows** — columns `n,k,beta_deg`. Output: those columns, then `dop`.
//!
//! Validation (each error names the file, the line, the column and the value):
//! every value finite; `n > 0`; `k >= 0`; `sigma > 0`; `theta_i_deg`, `theta_r_deg`
//! in `[0, 90)` (eq. 3 divides by `cos θi cos θr`); `beta_deg` in `[0, 90]` (eq. 9 is
//! defined at grazing incidence, where `P = 0`; the DoP oracle has such rows);
//! `phi_deg` any finite value (azimuths are periodic).
//!
//! Input columns that are neither inputs nor outputs of the model (e.g. a label) are
//! copied, in input order, after the computed columns; input columns named like a
//! computed column are replaced by the computed values.

use std::io::Write;
use std::path::Path;

use super::{CsvTable, fmt_f64, write_rows};
use crate::error::{IoError, Result};

/// Input columns of pBRDF rows.
pub const PBRDF_INPUTS: [&str; 6] = ["n", "k", "sigma", "theta_i_deg", "theta_r_deg", "phi_deg"];

/// Columns computed for pBRDF rows, in output order.
pub const PBRDF_COMPUTED: [&str; 20] = [
    "beta_deg",
    "facet_tilt_deg",
    "m00",
    "m01",
    "m02",
    "m10",
    "m11",
    "m12",
    "m20",
    "m21",
    "m22",
    "m01_psps",
    "m02_psps",
    "m10_psps",
    "m11_psps",
    "m12_psps",
    "m20_psps",
    "m21_psps",
    "m22_psps",
    "dolp",
];

/// Input columns of DoP rows.
pub const DOP_INPUTS: [&str; 3] = ["n", "k", "beta_deg"];

/// Columns computed for DoP rows.
pub const DOP_COMPUTED: [&str; 1] = ["dop"];

/// One row asking for the degree of polarization of eq. (9).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DopRow {
    /// Line of the row in its file.
    pub line: u64,
    /// Real part of the index.
    pub n: f64,
    /// Imaginary part of the index (`>= 0`).
    pub k: f64,
    /// Local incidence angle, degrees, in `[0, 90]`.
    pub beta_deg: f64,
}

/// One row asking for the pBRDF of eq. (3).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PbrdfRow {
    /// Line of the row in its file.
    pub line: u64,
    /// Real part of the index.
    pub n: f64,
    /// Imaginary part of the index (`>= 0`).
    pub k: f64,
    /// Slope standard deviation `σ > 0`.
    pub sigma: f64,
    /// Source zenith, degrees, in `[0, 90)`.
    pub theta_i_deg: f64,
    /// Camera zenith, degrees, in `[0, 90)`.
    pub theta_r_deg: f64,
    /// `φr − φi`, degrees (180 = forward in-plane).
    pub phi_deg: f64,
}

/// The rows of a model input file, of one kind.
#[derive(Debug, Clone, PartialEq)]
pub enum ModelRows {
    /// `n,k,beta_deg` rows.
    Dop(Vec<DopRow>),
    /// `n,k,sigma,theta_i_deg,theta_r_deg,phi_deg` rows.
    Pbrdf(Vec<PbrdfRow>),
}

/// A model input file: its rows and the extra columns to copy to the output.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelInput {
    /// The rows.
    pub rows: ModelRows,
    /// Names of the extra (pass-through) columns.
    pub extra_headers: Vec<String>,
    /// Text of the extra columns, one vector per row.
    pub extra: Vec<Vec<String>>,
}

/// Read a model input CSV (see the module documentation).
pub fn read(path: &Path) -> Result<ModelInput> {
    let t = CsvTable::read(path)?;
    from_table(&t)
}

/// Parse model rows from an already read table.
pub fn from_table(t: &CsvTable) -> Result<ModelInput> {
    let has = |c: &str| t.col(c).is_some();
    let pbrdf = ["sigma", "theta_i_deg", "theta_r_deg", "phi_deg"]
        .iter()
        .all(|c| has(c));
    if !pbrdf && !has("beta_deg") {
        return Err(IoError::CsvStructure {
            path: t.path.clone(),
            reason: format!(
                "model rows need columns `n,k,beta_deg` or `n,k,sigma,theta_i_deg,theta_r_deg,phi_deg` (columns are: {})",
                t.headers.join(",")
            ),
        });
    }
    let (inputs, computed): (&[&str], &[&str]) = if pbrdf {
        (&PBRDF_INPUTS, &PBRDF_COMPUTED)
    } else {
        (&DOP_INPUTS, &DOP_COMPUTED)
    };
    let idx: Vec<usize> = inputs.iter().map(|c| t.require(c)).collect::<Result<_>>()?;
    let extra_cols: Vec<usize> = (0..t.headers.len())
        .filter(|&i| {
            let h = t.headers[i].as_str();
            !inputs.contains(&h) && !computed.contains(&h) && !h.is_empty()
        })
        .collect();
    let extra_headers = extra_cols.iter().map(|&i| t.headers[i].clone()).collect();
    let mut extra = Vec::with_capacity(t.rows.len());
    let mut dop_rows = Vec::new();
    let mut pbrdf_rows = Vec::new();
    for r in 0..t.rows.len() {
        let line = t.rows[r].0; // ok: r < rows.len()
        let mut v = [0.0f64; 6];
        for (slot, &c) in v.iter_mut().zip(idx.iter()) {
            *slot = t.f64(r, c)?;
        }
        // `CsvTable::f64` has rejected NaN and infinities. Indexing below is ok: `v` has
        // six slots and `idx` one per input column (2 or 6).
        let (n, k) = (v[0], v[1]);
        if n <= 0.0 {
            return Err(t.err(r, idx[0], "the real index n must be > 0"));
        }
        if k < 0.0 {
            return Err(t.err(r, idx[1], "the extinction coefficient k must be >= 0"));
        }
        if pbrdf {
            if v[2] <= 0.0 {
                return Err(t.err(r, idx[2], "sigma must be > 0"));
            }
            for j in [3, 4] {
                if !(0.0..90.0).contains(&v[j]) {
                    return Err(t.err(r, idx[j], "angle outside [0, 90) degrees"));
                }
            }
            pbrdf_rows.push(PbrdfRow {
                line,
                n,
                k,
                sigma: v[2],
                theta_i_deg: v[3],
                theta_r_deg: v[4],
                phi_deg: v[5],
            });
        } else {
            if !(0.0..=90.0).contains(&v[2]) {
                return Err(t.err(r, idx[2], "angle outside [0, 90] degrees"));
            }
            dop_rows.push(DopRow {
                line,
                n,
                k,
                beta_deg: v[2],
            });
        }
        extra.push(
            extra_cols
                .iter()
                .map(|&c| t.text(r, c).to_string())
                .collect(),
        );
    }
    Ok(ModelInput {
        rows: if pbrdf {
            ModelRows::Pbrdf(pbrdf_rows)
        } else {
            ModelRows::Dop(dop_rows)
        },
        extra_headers,
        extra,
    })
}

/// The computed values of one pBRDF row (angles in degrees, matrices in sr⁻¹).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PbrdfOut {
    /// `β`, degrees.
    pub beta_deg: f64,
    /// Facet tilt `θ`, degrees.
    pub facet_tilt_deg: f64,
    /// Local-frame 3×3 Mueller matrix.
    pub local: [[f64; 3]; 3],
    /// Global (psps) 3×3 Mueller matrix.
    pub global: [[f64; 3]; 3],
    /// DoLP for unpolarized input.
    pub dolp: f64,
}

/// Write DoP results: `n,k,beta_deg,dop` then the extra columns.
pub fn write_dop<W: Write + ?Sized>(
    w: &mut W,
    path: &Path,
    input: &ModelInput,
    rows: &[DopRow],
    dop: &[f64],
) -> Result<()> {
    let mut headers: Vec<&str> = DOP_INPUTS
        .iter()
        .chain(DOP_COMPUTED.iter())
        .copied()
        .collect();
    headers.extend(input.extra_headers.iter().map(String::as_str));
    let out = rows.iter().zip(dop).enumerate().map(|(i, (r, p))| {
        let mut cells = vec![fmt_f64(r.n), fmt_f64(r.k), fmt_f64(r.beta_deg), fmt_f64(*p)];
        cells.extend(input.extra.get(i).into_iter().flatten().cloned());
        cells
    });
    write_rows(w, path, &headers, out)
}

/// Write pBRDF results: the input columns, [`PBRDF_COMPUTED`], then the extra columns.
pub fn write_pbrdf<W: Write + ?Sized>(
    w: &mut W,
    path: &Path,
    input: &ModelInput,
    rows: &[PbrdfRow],
    results: &[PbrdfOut],
) -> Result<()> {
    let mut headers: Vec<&str> = PBRDF_INPUTS
        .iter()
        .chain(PBRDF_COMPUTED.iter())
        .copied()
        .collect();
    headers.extend(input.extra_headers.iter().map(String::as_str));
    let out = rows.iter().zip(results).enumerate().map(|(i, (r, o))| {
        let mut cells = Vec::with_capacity(headers.len());
        for v in [
            r.n,
            r.k,
            r.sigma,
            r.theta_i_deg,
            r.theta_r_deg,
            r.phi_deg,
            o.beta_deg,
            o.facet_tilt_deg,
        ] {
            cells.push(fmt_f64(v));
        }
        cells.extend(o.local.iter().flatten().map(|v| fmt_f64(*v)));
        cells.extend(o.global.iter().flatten().skip(1).map(|v| fmt_f64(*v)));
        cells.push(fmt_f64(o.dolp));
        cells.extend(input.extra.get(i).into_iter().flatten().cloned());
        cells
    });
    write_rows(w, path, &headers, out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<ModelInput> {
        let t = CsvTable::from_reader(Path::new("rows.csv"), text.as_bytes())?;
        from_table(&t)
    }

    #[test]
    fn reads_both_kinds() {
        let m = parse("# c\nn,k,beta_deg,label\n1.5,0,56.3,glass\n").unwrap();
        match &m.rows {
            ModelRows::Dop(r) => assert_eq!((r[0].line, r[0].beta_deg), (3, 56.3)),
            other => panic!("{other:?}"),
        }
        assert_eq!(m.extra_headers, vec!["label".to_string()]);
        let m = parse("n,k,sigma,theta_i_deg,theta_r_deg,phi_deg,beta_deg\n1,2,0.1,10,20,180,15\n")
            .unwrap();
        assert!(matches!(m.rows, ModelRows::Pbrdf(ref r) if r[0].sigma == 0.1));
        assert!(m.extra_headers.is_empty());
    }

    #[test]
    fn errors_name_line_and_column() {
        let cases = [
            ("n,k,beta_deg\n1.5,0,10\n1.5,-0.1,10\n", "line 3", "`k`"),
            ("n,k,beta_deg\n1.5,0,nan\n", "line 2", "`beta_deg`"),
            ("n,k,beta_deg\n1.5,0,91\n", "line 2", "`beta_deg`"),
            ("n,k,beta_deg\n0,0,10\n", "line 2", "`n`"),
            (
                "n,k,sigma,theta_i_deg,theta_r_deg,phi_deg\n1,0,0,10,10,0\n",
                "line 2",
                "`sigma`",
            ),
            (
                "n,k,sigma,theta_i_deg,theta_r_deg,phi_deg\n1,0,0.1,90,10,0\n",
                "line 2",
                "`theta_i_deg`",
            ),
            (
                "n,k,sigma,theta_i_deg,theta_r_deg,phi_deg\n1,0,0.1,10,-1,0\n",
                "line 2",
                "`theta_r_deg`",
            ),
            (
                "n,k,sigma,theta_i_deg,theta_r_deg,phi_deg\n1,0,0.1,10,10,inf\n",
                "line 2",
                "`phi_deg`",
            ),
        ];
        for (text, line, col) in cases {
            let e = parse(text).unwrap_err().to_string();
            assert!(
                e.contains("rows.csv") && e.contains(line) && e.contains(col),
                "{text}: {e}"
            );
        }
        let e = parse("n,k\n1,2\n").unwrap_err().to_string();
        assert!(e.contains("beta_deg"), "{e}");
    }
}
