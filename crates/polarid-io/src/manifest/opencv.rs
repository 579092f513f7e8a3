//! OpenCV camera calibration files, for the manifest's `[camera]` table:
//! `opencv = "calib.yml"` (or `opencv = { file = "calib.yml", camera_matrix = "M1",
//! distortion = "D1" }`) takes the camera matrix and the distortion coefficients from
//! the file that OpenCV's `cv::calibrateCamera` results are saved to with
//! `cv::FileStorage` (C++ or Python `cv2.FileStorage`).
//!
//! The three formats `FileStorage` writes are read, recognised from the content:
//!
//! - YAML (`%YAML:1.0`, `.yml`/`.yaml`): a matrix is a mapping tagged
//!   `!!opencv-matrix` with `rows`, `cols`, `dt` and `data` (a flow sequence, possibly
//!   over several lines);
//! - JSON (`.json`): a matrix is an object `{"type_id": "opencv-matrix", "rows": 3,
//!   "cols": 3, "dt": "d", "data": [...]}`;
//! - XML (`.xml`): `<camera_matrix type_id="opencv-matrix"><rows>3</rows>...
//!   <data>...</data></camera_matrix>` under `<opencv_storage>`.
//!
//! Only the entries needed are interpreted: the camera matrix (`camera_matrix`,
//! `cameraMatrix`, `K`, `mtx`, ... — the names of OpenCV's calibration samples and
//! tutorials, or the name given in the manifest), the distortion coefficients
//! (`distortion_coefficients`, `distCoeffs`, `dist_coeffs`, `D`, ...), and, when present,
//! `image_width`, `image_height` (the size of the calibration images, checked against
//! the frames) and `fisheye_model`. Other entries (board size, reprojection errors,
//! extrinsics, image points, comments) are skipped. A matrix may also be written as a
//! plain sequence of numbers (`[fx, 0, cx, 0, fy, cy, 0, 0, 1]` or three rows of three).
//!
//! The pinhole model is OpenCV's (`u = fx·x'' + cx`, `v = fy·y'' + cy`, with the
//! distortion `k1, k2, p1, p2, k3` of `cv::projectPoints`; docs/CONVENTIONS.md):
//! the camera matrix must be `[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]` (no skew), and
//! only the first five distortion coefficients are modelled: the rational (`k4, k5,
//! k6`), thin-prism (`s1..s4`) and tilt (`τx, τy`) terms of 8, 12 or 14 coefficients
//! must be zero. A fisheye calibration (`cv::fisheye`, `fisheye_model: 1`) is refused.
//!
//! Errors are [`IoError::Manifest`] naming the calibration file, the line, the field
//! (`camera_matrix.data[2]`, `distortion_coefficients.rows`, ...) and the value.

use std::path::{Path, PathBuf};

use toml::de::DeValue;

use super::{Capture, Parser, Table, Val};
use crate::error::{IoError, Result};

/// Entry names of the camera matrix tried in order when the manifest names none.
pub const CAMERA_MATRIX_KEYS: &[&str] = &[
    "camera_matrix",
    "cameraMatrix",
    "Camera_Matrix",
    "CameraMatrix",
    "camera_matrix_left",
    "K",
    "mtx",
    "intrinsic",
    "intrinsics",
    "M",
    "M1",
];

/// Entry names of the distortion coefficients tried in order when the manifest names
/// none.
pub const DISTORTION_KEYS: &[&str] = &[
    "distortion_coefficients",
    "Distortion_Coefficients",
    "distCoeffs",
    "DistCoeffs",
    "dist_coeffs",
    "distortion",
    "dist",
    "D",
    "D1",
];

/// The intrinsics read from an OpenCV calibration file.
#[derive(Debug, Clone, PartialEq)]
pub struct OpenCvCalibration {
    /// The calibration file.
    pub path: PathBuf,
    /// `fx`, `fy` (pixels).
    pub focal_px: [f64; 2],
    /// `cx`, `cy` (pixels; the centre of pixel (column c, row r) at (c, r), as OpenCV).
    pub principal_point_px: [f64; 2],
    /// `k1, k2, p1, p2, k3` (zeros for the coefficients the file does not give).
    pub distortion: [f64; 5],
    /// `image_width`, `image_height` of the calibration images, when the file has them.
    pub image_size: Option<[usize; 2]>,
    /// The entry the camera matrix was read from.
    pub camera_matrix_key: String,
    /// The entry the distortion coefficients were read from.
    pub distortion_key: String,
}

/// Which entries hold the camera matrix and the distortion coefficients (`None`: try
/// [`CAMERA_MATRIX_KEYS`], [`DISTORTION_KEYS`]).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct OpenCvKeys {
    /// The camera matrix's entry.
    pub camera_matrix: Option<String>,
    /// The distortion coefficients' entry.
    pub distortion: Option<String>,
}

/// Read an OpenCV calibration file (YAML, JSON or XML as `cv::FileStorage` writes it).
///
/// Errors: the file cannot be read ([`IoError::Io`]), or [`IoError::Manifest`] naming
/// the file, line, field and value (see the module documentation).
pub fn read_opencv_calibration(path: &Path, keys: &OpenCvKeys) -> Result<OpenCvCalibration> {
    let bytes = crate::limits::read_capped(path, crate::limits::text_cap(), "text")?;
    if bytes.starts_with(&[0x1f, 0x8b]) {
        return Err(err(
            path,
            0,
            "-",
            "gzip data",
            "a compressed FileStorage file (.gz): decompress it first (gunzip)",
        ));
    }
    let text = String::from_utf8(bytes).map_err(|e| {
        err(
            path,
            0,
            "-",
            format!("byte {}", e.utf8_error().valid_up_to()),
            "not UTF-8 text",
        )
    })?;
    parse_opencv_calibration(path, crate::limits::strip_bom(text).as_str(), keys)
}

/// [`read_opencv_calibration`] of `text` (`path` labels errors).
pub fn parse_opencv_calibration(
    path: &Path,
    text: &str,
    keys: &OpenCvKeys,
) -> Result<OpenCvCalibration> {
    let doc = Doc::parse(path, text)?;
    let (ck, km) = doc.find(
        keys.camera_matrix.as_deref(),
        CAMERA_MATRIX_KEYS,
        "camera matrix",
    )?;
    let (dk, dm) = doc.find(keys.distortion.as_deref(), DISTORTION_KEYS, "distortion")?;
    if let Some(f) = doc.get("fisheye_model")
        && let Node::Scalar(s) = &f.node
        && s.trim().parse::<f64>().is_ok_and(|x| x != 0.0)
    {
        return Err(err(
            path,
            f.line,
            "fisheye_model",
            s,
            "a fisheye calibration (cv::fisheye) uses another distortion model; \
             calibrate with cv::calibrateCamera (the pinhole model with k1, k2, p1, p2, k3)",
        ));
    }
    let [fx, fy, cx, cy] = camera_matrix(path, ck, &doc.matrix(ck, km)?)?;
    let distortion = distortion(path, dk, &doc.matrix(dk, dm)?)?;
    let image_size = match (doc.get("image_width"), doc.get("image_height")) {
        (Some(w), Some(h)) => Some([doc.size(w, "image_width")?, doc.size(h, "image_height")?]),
        _ => None,
    };
    Ok(OpenCvCalibration {
        path: path.to_path_buf(),
        focal_px: [fx, fy],
        principal_point_px: [cx, cy],
        distortion,
        image_size,
        camera_matrix_key: ck.to_string(),
        distortion_key: dk.to_string(),
    })
}

/// `fx, fy, cx, cy` of the camera matrix `k` (entry `ck`), which must be
/// `[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]` with `fx, fy > 0`.
fn camera_matrix(path: &Path, ck: &str, k: &Matrix) -> Result<[f64; 4]> {
    if k.rows * k.cols != 9 || (k.rows != 3 && k.rows != 1 && k.cols != 1) {
        return Err(err(
            path,
            k.line,
            &format!("{ck}.rows"),
            format!("{}x{}", k.rows, k.cols),
            "the camera matrix must be 3x3",
        ));
    }
    let v = &k.values;
    let at = |i: usize| v.get(i).copied().unwrap_or(f64::NAN);
    let (fx, skew, cx, fy, cy) = (at(0), at(1), at(2), at(4), at(5));
    for (i, name) in [(0usize, "fx"), (4, "fy")] {
        if at(i).is_nan() || at(i) <= 0.0 {
            return Err(err(
                path,
                k.lines[i],
                &format!("{ck}.data[{}]", i + 1),
                fmt(at(i)),
                format!("the focal length {name} must be > 0 pixels"),
            ));
        }
    }
    if skew.abs() > 1e-9 * fx.max(fy) {
        return Err(err(
            path,
            k.lines[1],
            &format!("{ck}.data[2]"),
            fmt(skew),
            "the camera matrix has a skew term; polarid's pinhole model has none (as \
             cv::calibrateCamera, which always gives 0)",
        ));
    }
    for (i, want) in [(3usize, 0.0), (6, 0.0), (7, 0.0), (8, 1.0)] {
        if (at(i) - want).abs() > 1e-9 {
            return Err(err(
                path,
                k.lines[i],
                &format!("{ck}.data[{}]", i + 1),
                fmt(at(i)),
                format!(
                    "not a camera matrix [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]: element {} must \
                     be {want}",
                    i + 1
                ),
            ));
        }
    }
    Ok([fx, fy, cx, cy])
}

/// `k1, k2, p1, p2, k3` of the distortion coefficients `d` (entry `dk`): 4, 5, 8, 12 or
/// 14 of them, those after `k3` zero.
fn distortion(path: &Path, dk: &str, d: &Matrix) -> Result<[f64; 5]> {
    if d.rows != 1 && d.cols != 1 {
        return Err(err(
            path,
            d.line,
            &format!("{dk}.rows"),
            format!("{}x{}", d.rows, d.cols),
            "the distortion coefficients must be one row or one column",
        ));
    }
    let n = d.values.len();
    if ![4usize, 5, 8, 12, 14].contains(&n) {
        return Err(err(
            path,
            d.line,
            &format!("{dk}.data"),
            format!("{n} coefficients"),
            "expected 4, 5, 8, 12 or 14 distortion coefficients (k1, k2, p1, p2[, k3, ...])",
        ));
    }
    if let Some(i) = (5..n).find(|&i| d.values[i] != 0.0) {
        return Err(err(
            path,
            d.lines[i],
            &format!("{dk}.data[{}]", i + 1),
            fmt(d.values[i]),
            "only k1, k2, p1, p2, k3 are modelled: the rational (k4, k5, k6), thin-prism and \
             tilt coefficients must be 0 (calibrate without CALIB_RATIONAL_MODEL, \
             CALIB_THIN_PRISM_MODEL and CALIB_TILTED_MODEL)",
        ));
    }
    let mut distortion = [0.0; 5];
    for (o, x) in distortion.iter_mut().zip(&d.values) {
        *o = *x;
    }
    Ok(distortion)
}

impl Parser<'_> {
    /// The `[camera]` table's `opencv` key, if any: the calibration file read, and the
    /// key's value (for the spans of later errors). With `opencv`, `focal_px`,
    /// `principal_point_px` and `distortion` may not be given.
    pub(super) fn opencv_camera<'t, 'i>(
        &self,
        t: &'t Table<'i>,
    ) -> Result<Option<(OpenCvCalibration, &'t Val<'i>)>> {
        let Some(v) = self.get(t, "opencv") else {
            return Ok(None);
        };
        let (file_v, field, keys) = match v.get_ref() {
            DeValue::String(_) => (v, "camera.opencv", OpenCvKeys::default()),
            DeValue::Table(ot) => {
                self.warn_unknown(
                    ot,
                    &["file", "camera_matrix", "distortion"],
                    "camera.opencv.",
                );
                let fv = self
                    .get(ot, "file")
                    .ok_or_else(|| self.err(&v.span(), "camera.opencv.file", "missing `file`"))?;
                let key = |k: &str| -> Result<Option<String>> {
                    self.get(ot, k)
                        .map(|x| self.string(x, &format!("camera.opencv.{k}")))
                        .transpose()
                };
                let keys = OpenCvKeys {
                    camera_matrix: key("camera_matrix")?,
                    distortion: key("distortion")?,
                };
                (fv, "camera.opencv.file", keys)
            }
            other => {
                return Err(self.err(
                    &v.span(),
                    "camera.opencv",
                    format!(
                        "expected the calibration file's name, or a table {{ file = \"...\", \
                         camera_matrix = \"...\", distortion = \"...\" }}, found a {}",
                        other.type_str()
                    ),
                ));
            }
        };
        for k in ["focal_px", "principal_point_px", "distortion"] {
            if let Some(x) = self.get(t, k) {
                return Err(self.err(
                    &x.span(),
                    &format!("camera.{k}"),
                    "the intrinsics come from the `opencv` calibration file: give either \
                     `opencv` or focal_px, principal_point_px and distortion, not both",
                ));
            }
        }
        let path = self.file(file_v, field)?;
        let cal = read_opencv_calibration(&path, &keys)?;
        Ok(Some((cal, v)))
    }

    /// With an `opencv` calibration that records its images' size, the first file of
    /// the first capture must have that size (the intrinsics are in its pixels).
    pub(super) fn check_opencv_image_size(
        &self,
        calibration: Option<&OpenCvCalibration>,
        camera_line: usize,
        captures: &[Capture],
    ) -> Result<()> {
        let Some(cal) = calibration else {
            return Ok(());
        };
        let Some([cw, ch]) = cal.image_size else {
            return Ok(());
        };
        let Some(file) = captures
            .first()
            .and_then(|c| c.files().first().map(|p| p.to_path_buf()))
        else {
            return Ok(());
        };
        let [fw, fh] = crate::frames_dir::image_size(&file)?;
        if [fw, fh] == [cw, ch] {
            return Ok(());
        }
        let hint = if [fw, fh] == [2 * cw, 2 * ch] {
            format!(
                "; it looks like a calibration on 2x2 super-pixel images: for the raw mosaic \
                 give focal_px = [{}, {}] and principal_point_px = [{}, {}] (f x 2, c x 2 + 0.5) \
                 and the distortion as they are, instead of `opencv`",
                2.0 * cal.focal_px[0],
                2.0 * cal.focal_px[1],
                2.0 * cal.principal_point_px[0] + 0.5,
                2.0 * cal.principal_point_px[1] + 0.5
            )
        } else {
            String::new()
        };
        Err(IoError::Manifest {
            path: self.path.to_path_buf(),
            line: camera_line,
            field: "camera.opencv".into(),
            value: cal.path.display().to_string(),
            reason: format!(
                "the calibration images were {cw}x{ch} (image_width, image_height) but the \
                 frames are {fw}x{fh} ({}): the intrinsics must be in pixels of the files as \
                 stored (for a polarization camera, the raw mosaic){hint}",
                file.display()
            ),
        })
    }
}

fn fmt(x: f64) -> String {
    format!("{x}")
}

fn err(
    path: &Path,
    line: usize,
    field: &str,
    value: impl Into<String>,
    reason: impl Into<String>,
) -> IoError {
    let mut value: String = value.into();
    if value.chars().count() > 60 {
        value = value.chars().take(57).collect::<String>() + "...";
    }
    IoError::Manifest {
        path: path.to_path_buf(),
        line,
        field: field.to_string(),
        value,
        reason: reason.into(),
    }
}

/// A value of the file: a scalar (as written, unquoted), a sequence or a mapping.
#[derive(Debug, Clone, PartialEq)]
enum Node {
    Scalar(String),
    Seq(Vec<Item>),
    Map(Vec<(String, Item)>),
    /// A YAML entry that could not be parsed (the message), reported when it is needed.
    Unreadable(String),
}

/// A node and the 1-based line where it starts.
#[derive(Debug, Clone, PartialEq)]
struct Item {
    node: Node,
    line: usize,
}

/// A matrix read from the file.
#[derive(Debug)]
struct Matrix {
    rows: usize,
    cols: usize,
    values: Vec<f64>,
    /// The line of each value.
    lines: Vec<usize>,
    /// The line of the entry.
    line: usize,
}

/// The top-level entries of the file.
struct Doc<'a> {
    path: &'a Path,
    entries: Vec<(String, Item)>,
}

impl<'a> Doc<'a> {
    fn parse(path: &'a Path, text: &str) -> Result<Self> {
        let first = text
            .lines()
            .map(str::trim)
            .find(|l| !l.is_empty() && !l.starts_with('#') && !l.starts_with("//"));
        let entries = match first {
            None => return Err(err(path, 0, "-", "", "the file is empty")),
            Some(l) if l.starts_with('{') => {
                let lines: Vec<(usize, String)> = text
                    .lines()
                    .enumerate()
                    .map(|(i, l)| (i + 1, strip_comment(l, true)))
                    .collect();
                let mut f = Flow::new(path, &lines);
                let root = f.value()?;
                f.end()?;
                match root.node {
                    Node::Map(m) => m,
                    _ => return Err(err(path, root.line, "-", "", "expected a JSON object")),
                }
            }
            Some(l) if l.starts_with('<') => xml_entries(path, text)?,
            Some(_) => yaml_entries(path, text)?,
        };
        Ok(Doc { path, entries })
    }

    fn get(&self, key: &str) -> Option<&Item> {
        self.entries.iter().find(|(k, _)| k == key).map(|(_, v)| v)
    }

    /// The entry `want`, or the first of `candidates` present.
    fn find<'k>(
        &'k self,
        want: Option<&'k str>,
        candidates: &[&'k str],
        what: &str,
    ) -> Result<(&'k str, &'k Item)> {
        let found = match want {
            Some(k) => self.get(k).map(|v| (k, v)),
            None => candidates.iter().find_map(|k| self.get(k).map(|v| (*k, v))),
        };
        found.ok_or_else(|| {
            let names: Vec<&str> = self.entries.iter().map(|(k, _)| k.as_str()).collect();
            let tried = match want {
                Some(k) => format!("no entry `{k}`"),
                None => format!("no {what} entry (tried {})", candidates.join(", ")),
            };
            err(
                self.path,
                0,
                what,
                format!("entries: {}", names.join(", ")),
                format!(
                    "{tried}; name it in the manifest: opencv = {{ file = \"...\", \
                     camera_matrix = \"NAME\", distortion = \"NAME\" }}"
                ),
            )
        })
    }

    /// A non-negative integer entry (an image size).
    fn size(&self, item: &Item, field: &str) -> Result<usize> {
        match &item.node {
            Node::Scalar(s) => s
                .trim()
                .parse::<usize>()
                .ok()
                .filter(|&x| x > 0)
                .ok_or_else(|| {
                    err(
                        self.path,
                        item.line,
                        field,
                        s,
                        "expected a positive integer",
                    )
                }),
            _ => Err(err(
                self.path,
                item.line,
                field,
                "",
                "expected a positive integer",
            )),
        }
    }

    fn number(&self, item: &Item, field: &str) -> Result<f64> {
        match &item.node {
            Node::Scalar(s) => match s.trim().parse::<f64>() {
                Ok(x) if x.is_finite() => Ok(x),
                _ => Err(err(
                    self.path,
                    item.line,
                    field,
                    s,
                    "expected a finite number",
                )),
            },
            _ => Err(err(self.path, item.line, field, "", "expected a number")),
        }
    }

    fn count(&self, m: &[(String, Item)], key: &str, pre: &str) -> Result<Option<usize>> {
        let Some((_, it)) = m.iter().find(|(k, _)| k == key) else {
            return Ok(None);
        };
        self.size(it, &format!("{pre}.{key}")).map(Some)
    }

    /// The numbers of `items` (fields `field[1]`, `field[2]`, ...) and their lines.
    fn scalars(&self, items: &[Item], field: &str) -> Result<(Vec<f64>, Vec<usize>)> {
        let mut vals = Vec::with_capacity(items.len());
        let mut lines = Vec::with_capacity(items.len());
        for (i, it) in items.iter().enumerate() {
            vals.push(self.number(it, &format!("{field}[{}]", i + 1))?);
            lines.push(it.line);
        }
        Ok((vals, lines))
    }

    /// The matrix of entry `key`.
    fn matrix(&self, key: &str, item: &Item) -> Result<Matrix> {
        match &item.node {
            Node::Map(m) => self.opencv_matrix(key, item, m),
            Node::Seq(s) if s.iter().all(|x| matches!(x.node, Node::Seq(_))) && !s.is_empty() => {
                let mut values = Vec::new();
                let mut lines = Vec::new();
                let mut cols = None;
                for (r, row) in s.iter().enumerate() {
                    let Node::Seq(row_items) = &row.node else {
                        continue;
                    };
                    if *cols.get_or_insert(row_items.len()) != row_items.len() {
                        return Err(err(
                            self.path,
                            row.line,
                            &format!("{key}[{}]", r + 1),
                            format!("{} numbers", row_items.len()),
                            "every row must have the same length",
                        ));
                    }
                    let (v, l) = self.scalars(row_items, &format!("{key}[{}]", r + 1))?;
                    values.extend(v);
                    lines.extend(l);
                }
                Ok(Matrix {
                    rows: s.len(),
                    cols: cols.unwrap_or(0),
                    values,
                    lines,
                    line: item.line,
                })
            }
            Node::Seq(s) => {
                let (values, lines) = self.scalars(s, key)?;
                Ok(Matrix {
                    rows: 1,
                    cols: values.len(),
                    values,
                    lines,
                    line: item.line,
                })
            }
            Node::Scalar(s) => Err(err(
                self.path,
                item.line,
                key,
                s,
                "expected a matrix (an opencv-matrix or a sequence of numbers)",
            )),
            Node::Unreadable(why) => Err(err(
                self.path,
                item.line,
                key,
                "",
                format!("cannot be read: {why}"),
            )),
        }
    }

    /// An `opencv-matrix` mapping `m` (entry `key`): `rows` and `cols` (or `sizes`), `dt`
    /// and `data`.
    fn opencv_matrix(&self, key: &str, item: &Item, m: &[(String, Item)]) -> Result<Matrix> {
        let (rows, cols) = self.dimensions(key, item, m)?;
        if let Some((_, dt)) = m.iter().find(|(k, _)| k == "dt")
            && let Node::Scalar(s) = &dt.node
        {
            let digits: String = s.trim().chars().take_while(char::is_ascii_digit).collect();
            let channels = digits.parse::<usize>().unwrap_or(1);
            let rest = s.trim().get(digits.len()..).unwrap_or("");
            if channels != 1 || rest.len() != 1 || !"ucwsifdh".contains(rest) {
                return Err(err(
                    self.path,
                    dt.line,
                    &format!("{key}.dt"),
                    s,
                    "expected a single-channel numeric type (d, f, i, ...)",
                ));
            }
        }
        let Some((_, data)) = m.iter().find(|(k, _)| k == "data") else {
            return Err(err(
                self.path,
                item.line,
                &format!("{key}.data"),
                "",
                "an opencv-matrix needs `data`",
            ));
        };
        let field = format!("{key}.data");
        let (values, lines) = match &data.node {
            Node::Seq(s) => self.scalars(s, &field)?,
            Node::Scalar(s) if s.contains("$base64$") => {
                return Err(err(
                    self.path,
                    data.line,
                    &field,
                    s,
                    "base64-encoded data is not read: write the file without \
                     FileStorage::BASE64",
                ));
            }
            Node::Scalar(s) => {
                return Err(err(
                    self.path,
                    data.line,
                    &field,
                    s,
                    "expected a sequence of numbers",
                ));
            }
            Node::Map(_) | Node::Unreadable(_) => {
                return Err(err(
                    self.path,
                    data.line,
                    &field,
                    "",
                    "expected a sequence of numbers",
                ));
            }
        };
        if values.len() != rows * cols {
            return Err(err(
                self.path,
                data.line,
                &field,
                format!("{} numbers", values.len()),
                format!(
                    "rows x cols = {rows} x {cols} needs {} numbers",
                    rows * cols
                ),
            ));
        }
        Ok(Matrix {
            rows,
            cols,
            values,
            lines,
            line: item.line,
        })
    }

    /// The rows and columns of an `opencv-matrix` mapping (`rows` and `cols`, or the
    /// `sizes` of an `opencv-nd-matrix`).
    fn dimensions(&self, key: &str, item: &Item, m: &[(String, Item)]) -> Result<(usize, usize)> {
        let rows = self.count(m, "rows", key)?;
        let cols = self.count(m, "cols", key)?;
        let sizes = match m.iter().find(|(k, _)| k == "sizes") {
            Some((_, it)) => match &it.node {
                Node::Seq(s) => {
                    let mut out = Vec::new();
                    for (i, x) in s.iter().enumerate() {
                        out.push(self.size(x, &format!("{key}.sizes[{}]", i + 1))?);
                    }
                    Some(out)
                }
                _ => None,
            },
            None => None,
        };
        match (rows, cols, sizes.as_deref()) {
            (Some(r), Some(c), _) => Ok((r, c)),
            (None, None, Some([r, c])) => Ok((*r, *c)),
            (None, None, Some([n])) => Ok((*n, 1)),
            _ => Err(err(
                self.path,
                item.line,
                &format!("{key}.rows"),
                "",
                "an opencv-matrix needs `rows` and `cols`",
            )),
        }
    }
}

/// `line` without its comment: `#` (YAML, at the start or after a blank) or, for JSON,
/// `//`; quotes are respected.
fn strip_comment(line: &str, json: bool) -> String {
    let mut quote: Option<char> = None;
    let mut prev_blank = true;
    let mut escaped = false;
    let chars: Vec<char> = line.chars().collect();
    for (i, &c) in chars.iter().enumerate() {
        match quote {
            Some(q) => {
                if escaped {
                    escaped = false;
                } else if c == '\\' && q == '"' {
                    escaped = true;
                } else if c == q {
                    quote = None;
                }
            }
            None => {
                if c == '"' || c == '\'' {
                    quote = Some(c);
                } else if (!json && c == '#' && prev_blank)
                    || (json && c == '/' && chars.get(i + 1) == Some(&'/'))
                {
                    return chars[..i].iter().collect();
                }
            }
        }
        prev_blank = c == ' ' || c == '\t';
    }
    line.to_string()
}

/// A line of a YAML block: its 1-based number, indentation and content (no comment).
#[derive(Debug, Clone)]
struct Line {
    no: usize,
    indent: usize,
    text: String,
}

/// The top-level mapping of a FileStorage YAML file. Each top-level entry is parsed on
/// its own, so that an entry this reader does not need cannot stop it unless it breaks
/// the structure of lines.
fn yaml_entries(path: &Path, text: &str) -> Result<Vec<(String, Item)>> {
    let mut lines = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let t = raw.trim_start();
        if t.starts_with('%') || t == "---" || t.starts_with("--- ") || t == "..." {
            continue;
        }
        let s = strip_comment(raw, false);
        let content = s.trim_end();
        if content.trim().is_empty() {
            continue;
        }
        let indent = content.len() - content.trim_start().len();
        lines.push(Line {
            no: i + 1,
            indent,
            text: content.trim_start().to_string(),
        });
    }
    let mut out = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        let l = &lines[i];
        let mut j = i + 1;
        while j < lines.len()
            && (lines[j].indent > 0 || lines[j].text == "-" || lines[j].text.starts_with("- "))
        {
            j += 1;
        }
        let Some((key, rest)) = split_key(&l.text) else {
            return Err(err(
                path,
                l.no,
                "-",
                &l.text,
                "expected `name: value` at the top level of a FileStorage YAML file",
            ));
        };
        // An entry this reader cannot parse is an error only if it is needed.
        let item = yaml_value(path, &rest, l.no, &lines[i + 1..j]).unwrap_or_else(|e| Item {
            node: Node::Unreadable(e.to_string()),
            line: l.no,
        });
        out.push((key, item));
        i = j;
    }
    Ok(out)
}

/// `key: rest` (quoted or plain key; the `:` followed by a blank or the end).
fn split_key(text: &str) -> Option<(String, String)> {
    let t = text.trim();
    if let Some(q) = t.chars().next().filter(|c| *c == '"' || *c == '\'') {
        let end = t[1..].find(q)? + 1;
        let key = t[1..end].to_string();
        let rest = t[end + 1..].trim_start();
        let rest = rest.strip_prefix(':')?;
        return Some((key, rest.trim().to_string()));
    }
    let bytes = t.as_bytes();
    let pos = (0..bytes.len()).find(|&i| {
        bytes[i] == b':' && (i + 1 == bytes.len() || bytes[i + 1] == b' ' || bytes[i + 1] == b'\t')
    })?;
    let key = t[..pos].trim();
    if key.is_empty() || key.starts_with(['[', '{', '-']) {
        return None;
    }
    Some((key.to_string(), t[pos + 1..].trim().to_string()))
}

/// A YAML value: `rest` on its key's line `no`, `block` the lines under it.
fn yaml_value(path: &Path, rest: &str, no: usize, block: &[Line]) -> Result<Item> {
    let mut rest = rest.trim();
    if rest.starts_with('!') {
        rest = rest.find([' ', '\t']).map_or("", |p| rest[p..].trim());
    }
    if rest.is_empty() {
        if block.is_empty() {
            return Ok(Item {
                node: Node::Scalar(String::new()),
                line: no,
            });
        }
        return yaml_block(path, block);
    }
    if rest.starts_with('[') || rest.starts_with('{') {
        let mut lines = vec![(no, rest.to_string())];
        lines.extend(block.iter().map(|l| (l.no, l.text.clone())));
        let mut f = Flow::new(path, &lines);
        let v = f.value()?;
        f.end()?;
        return Ok(v);
    }
    if let Some(b) = block.first() {
        return Err(err(
            path,
            b.no,
            "-",
            &b.text,
            "unexpected indented line after a scalar value",
        ));
    }
    Ok(Item {
        node: Node::Scalar(unquote(rest)),
        line: no,
    })
}

/// A block mapping or sequence (the lines of one value).
fn yaml_block(path: &Path, lines: &[Line]) -> Result<Item> {
    let Some(first) = lines.first() else {
        return Ok(Item {
            node: Node::Scalar(String::new()),
            line: 0,
        });
    };
    let ind = first.indent;
    let is_seq = |l: &Line| l.indent == ind && (l.text == "-" || l.text.starts_with("- "));
    let mut i = 0;
    if is_seq(first) {
        let mut items = Vec::new();
        while i < lines.len() {
            let l = &lines[i];
            if !is_seq(l) {
                return Err(err(
                    path,
                    l.no,
                    "-",
                    &l.text,
                    "expected `- item` in a sequence",
                ));
            }
            let mut j = i + 1;
            while j < lines.len() && lines[j].indent > ind {
                j += 1;
            }
            let rest = l.text[1..].trim();
            let item = if split_key(rest).is_some() && !rest.starts_with(['[', '{', '"', '\'']) {
                // `- key: value` starts a mapping, indented past the dash.
                let mut sub = vec![Line {
                    no: l.no,
                    indent: ind + 2,
                    text: rest.to_string(),
                }];
                sub.extend(lines[i + 1..j].iter().cloned());
                yaml_block(path, &sub)?
            } else {
                yaml_value(path, rest, l.no, &lines[i + 1..j])?
            };
            items.push(item);
            i = j;
        }
        return Ok(Item {
            node: Node::Seq(items),
            line: first.no,
        });
    }
    let mut map = Vec::new();
    while i < lines.len() {
        let l = &lines[i];
        if l.indent != ind {
            return Err(err(path, l.no, "-", &l.text, "unexpected indentation"));
        }
        let Some((key, rest)) = split_key(&l.text) else {
            return Err(err(path, l.no, "-", &l.text, "expected `name: value`"));
        };
        let mut j = i + 1;
        while j < lines.len() && (lines[j].indent > ind || (rest.is_empty() && is_seq(&lines[j]))) {
            j += 1;
        }
        map.push((key, yaml_value(path, &rest, l.no, &lines[i + 1..j])?));
        i = j;
    }
    Ok(Item {
        node: Node::Map(map),
        line: first.no,
    })
}

/// A scalar without its quotes (`"..."` with the escapes `\"`, `\\`, `\n`, `\t`).
fn unquote(s: &str) -> String {
    let s = s.trim();
    if s.len() >= 2 && s.starts_with('\'') && s.ends_with('\'') {
        return s[1..s.len() - 1].replace("''", "'");
    }
    if s.len() >= 2 && s.starts_with('"') && s.ends_with('"') {
        let mut out = String::new();
        let mut it = s[1..s.len() - 1].chars();
        while let Some(c) = it.next() {
            if c == '\\' {
                match it.next() {
                    Some('n') => out.push('\n'),
                    Some('t') => out.push('\t'),
                    Some(o) => out.push(o),
                    None => {}
                }
            } else {
                out.push(c);
            }
        }
        return out;
    }
    s.to_string()
}

/// A parser of flow collections (`[...]`, `{...}`; JSON is one) over numbered lines.
struct Flow<'a> {
    path: &'a Path,
    chars: Vec<(char, usize)>,
    pos: usize,
}

impl<'a> Flow<'a> {
    fn new(path: &'a Path, lines: &[(usize, String)]) -> Self {
        let mut chars = Vec::new();
        for (no, l) in lines {
            chars.extend(l.chars().map(|c| (c, *no)));
            chars.push(('\n', *no));
        }
        Flow {
            path,
            chars,
            pos: 0,
        }
    }

    fn line(&self) -> usize {
        self.chars
            .get(self.pos)
            .or(self.chars.last())
            .map_or(0, |c| c.1)
    }

    fn peek(&self) -> Option<char> {
        self.chars.get(self.pos).map(|c| c.0)
    }

    fn blanks(&mut self) {
        while self.peek().is_some_and(char::is_whitespace) {
            self.pos += 1;
        }
    }

    fn fail(&self, reason: &str) -> IoError {
        let rest: String = self.chars[self.pos.min(self.chars.len())..]
            .iter()
            .take(30)
            .map(|c| c.0)
            .take_while(|c| *c != '\n')
            .collect();
        err(self.path, self.line(), "-", rest, reason)
    }

    fn end(&mut self) -> Result<()> {
        self.blanks();
        match self.peek() {
            None => Ok(()),
            Some(_) => Err(self.fail("unexpected text after the value")),
        }
    }

    fn value(&mut self) -> Result<Item> {
        self.blanks();
        let line = self.line();
        match self.peek() {
            Some('[') => Ok(Item {
                node: Node::Seq(self.entries(']', Self::value)?),
                line,
            }),
            Some('{') => Ok(Item {
                node: Node::Map(self.entries('}', Self::map_entry)?),
                line,
            }),
            Some(_) => Ok(Item {
                node: Node::Scalar(self.scalar(false)?),
                line,
            }),
            None => Err(self.fail("unexpected end of the file")),
        }
    }

    /// The entries of a flow collection after its opening bracket, each read by `entry`,
    /// separated by `,` and ending at `close`.
    fn entries<T>(
        &mut self,
        close: char,
        mut entry: impl FnMut(&mut Self) -> Result<T>,
    ) -> Result<Vec<T>> {
        self.pos += 1;
        let mut out = Vec::new();
        loop {
            self.blanks();
            if self.peek() == Some(close) {
                self.pos += 1;
                return Ok(out);
            }
            out.push(entry(self)?);
            self.blanks();
            match self.peek() {
                Some(',') => self.pos += 1,
                Some(c) if c == close => {}
                _ => return Err(self.fail(&format!("expected `,` or `{close}`"))),
            }
        }
    }

    /// `key: value` in a flow mapping.
    fn map_entry(&mut self) -> Result<(String, Item)> {
        let key = self.scalar(true)?;
        self.blanks();
        if self.peek() != Some(':') {
            return Err(self.fail("expected `:` after a key"));
        }
        self.pos += 1;
        let mut v = self.value()?;
        if let Node::Scalar(s) = &v.node
            && s.starts_with('!')
        {
            // A tag before a collection: `key: !!opencv-matrix { ... }`.
            self.blanks();
            if matches!(self.peek(), Some('[' | '{')) {
                v = self.value()?;
            }
        }
        Ok((key, v))
    }

    /// A quoted or plain scalar; a plain key ends at `:`, a plain value at `,`, `]`,
    /// `}` or the end of the line.
    fn scalar(&mut self, key: bool) -> Result<String> {
        self.blanks();
        if let Some(q) = self.peek().filter(|c| *c == '"' || *c == '\'') {
            self.pos += 1;
            let mut out = String::new();
            loop {
                match self.peek() {
                    None => return Err(self.fail("unterminated string")),
                    Some(c) if c == q => {
                        self.pos += 1;
                        return Ok(out);
                    }
                    Some('\\') if q == '"' => {
                        self.pos += 1;
                        match self.peek() {
                            Some('n') => out.push('\n'),
                            Some('t') => out.push('\t'),
                            Some(c) => out.push(c),
                            None => return Err(self.fail("unterminated string")),
                        }
                        self.pos += 1;
                    }
                    Some(c) => {
                        out.push(c);
                        self.pos += 1;
                    }
                }
            }
        }
        let mut out = String::new();
        while let Some(c) = self.peek() {
            if c == ',' || c == ']' || c == '}' || c == '\n' || (key && c == ':') {
                break;
            }
            out.push(c);
            self.pos += 1;
        }
        let out = out.trim().to_string();
        if out.is_empty() {
            return Err(self.fail("expected a value"));
        }
        Ok(out)
    }
}

/// The top-level elements of a FileStorage XML file that this reader needs
/// (`<opencv_storage><camera_matrix type_id="opencv-matrix"><rows>3</rows>...`).
fn xml_entries(path: &Path, text: &str) -> Result<Vec<(String, Item)>> {
    let line_of = |pos: usize| text[..pos.min(text.len())].matches('\n').count() + 1;
    let Some(start) = text.find("<opencv_storage>") else {
        return Err(err(
            path,
            1,
            "-",
            text.lines().next().unwrap_or(""),
            "not an OpenCV FileStorage XML file (no <opencv_storage>)",
        ));
    };
    let body_start = start + "<opencv_storage>".len();
    let body_end = text.rfind("</opencv_storage>").unwrap_or(text.len());
    let body = text.get(body_start..body_end).unwrap_or("");
    let mut out = Vec::new();
    let mut pos = 0;
    // Walk the top-level elements: `<name ...>content</name>` or `<name/>`.
    while let Some(off) = body[pos..].find('<') {
        let open = pos + off;
        let rest = &body[open + 1..];
        if rest.starts_with("!--") {
            pos = body[open..]
                .find("-->")
                .map_or(body.len(), |e| open + e + 3);
            continue;
        }
        let Some(gt) = rest.find('>') else {
            return Err(err(
                path,
                line_of(body_start + open),
                "-",
                "",
                "unclosed tag",
            ));
        };
        let tag = &rest[..gt];
        let name = tag
            .split_whitespace()
            .next()
            .unwrap_or("")
            .trim_end_matches('/');
        if name.is_empty() || name.starts_with('/') {
            pos = open + 1 + gt + 1;
            continue;
        }
        let content_start = open + 1 + gt + 1;
        if tag.ends_with('/') {
            out.push((
                name.to_string(),
                Item {
                    node: Node::Scalar(String::new()),
                    line: line_of(body_start + open),
                },
            ));
            pos = content_start;
            continue;
        }
        let close = format!("</{name}>");
        let Some(cl) = find_close(&body[content_start..], name) else {
            return Err(err(
                path,
                line_of(body_start + open),
                name,
                "",
                format!("no {close}"),
            ));
        };
        let content = &body[content_start..content_start + cl];
        let abs = body_start + content_start;
        let node = if content.trim_start().starts_with('<') {
            // A matrix: <rows>, <cols>, <dt>, <data> (or <sizes>).
            let mut map = Vec::new();
            for field in ["rows", "cols", "dt", "data", "sizes"] {
                let o = format!("<{field}>");
                if let Some(a) = content.find(&o) {
                    let from = a + o.len();
                    let to = content[from..]
                        .find(&format!("</{field}>"))
                        .map_or(content.len(), |e| from + e);
                    let inner = &content[from..to];
                    let item = if field == "data" || field == "sizes" {
                        let mut items = Vec::new();
                        let mut p = 0;
                        for tok in inner.split_whitespace() {
                            let at = inner[p..].find(tok).map_or(p, |q| p + q);
                            p = at + tok.len();
                            items.push(Item {
                                node: Node::Scalar(tok.to_string()),
                                line: line_of(abs + from + at),
                            });
                        }
                        Node::Seq(items)
                    } else {
                        Node::Scalar(unquote(inner))
                    };
                    map.push((
                        field.to_string(),
                        Item {
                            node: item,
                            line: line_of(abs + a),
                        },
                    ));
                }
            }
            Node::Map(map)
        } else {
            Node::Scalar(unquote(content))
        };
        out.push((
            name.to_string(),
            Item {
                node,
                line: line_of(body_start + open),
            },
        ));
        pos = content_start + cl + close.len();
    }
    Ok(out)
}

/// The offset of the `</name>` closing the element whose content `s` starts (elements of
/// the same name may nest).
fn find_close(s: &str, name: &str) -> Option<usize> {
    let open = format!("<{name}");
    let close = format!("</{name}>");
    let mut depth = 0usize;
    let mut pos = 0;
    loop {
        let c = s[pos..].find(&close)? + pos;
        let o = s[pos..].find(&open).map(|o| o + pos);
        match o {
            Some(o) if o < c => {
                depth += 1;
                pos = o + open.len();
            }
            _ => {
                if depth == 0 {
                    return Some(c);
                }
                depth -= 1;
                pos = c + close.len();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// As OpenCV 4's `samples/cpp/calibration.cpp` writes it (`cv::FileStorage`, YAML).
    const YAML: &str = "%YAML:1.0
---
calibration_time: \"Thu Dec  3 10:12:40 2026\"
nframes: 12
image_width: 480
image_height: 360
board_width: 9
board_height: 6
square_size: 2.5000000000000000e+01
# flags: +fix_aspect_ratio +zero_tangent_dist
flags: 14
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 6.5940000000000000e+02, 0., 2.3950000000000000e+02, 0.,
       6.5940000000000000e+02, 1.7950000000000000e+02, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 5
   cols: 1
   dt: d
   data: [ -8.0000000000000002e-02, 2.0000000000000000e-02, 0., 0.,
       0. ]
avg_reprojection_error: 2.1337563911233474e-01
per_view_reprojection_errors: !!opencv-matrix
   rows: 2
   cols: 1
   dt: f
   data: [ 2.03485832e-01, 2.22926438e-01 ]
image_points: !!opencv-nd-matrix
   sizes: [ 2, 2 ]
   dt: \"2f\"
   data: [ 1.0e+02, 2.0e+02, 1.1e+02, 2.0e+02, 1.0e+02, 2.1e+02, 1.1e+02,
       2.1e+02 ]
features:
   - { x:167, y:49, lbp:[ 1, 0, 0, 1 ] }
   - { x:298, y:130, lbp:[ 0, 0, 0, 1 ] }
";

    /// As `cv::FileStorage` writes JSON (`FORMAT_JSON`, or a `.json` name).
    const JSON: &str = "{
    \"image_width\": 480,
    \"image_height\": 360,
    \"camera_matrix\": {
        \"type_id\": \"opencv-matrix\",
        \"rows\": 3,
        \"cols\": 3,
        \"dt\": \"d\",
        \"data\": [ 6.5940000000000000e+02, 0.0, 2.3950000000000000e+02, 0.0,
            6.5940000000000000e+02, 1.7950000000000000e+02, 0.0, 0.0, 1.0 ]
    },
    // flags: +fix_aspect_ratio
    \"distortion_coefficients\": {
        \"type_id\": \"opencv-matrix\",
        \"rows\": 1,
        \"cols\": 5,
        \"dt\": \"d\",
        \"data\": [ -8.0000000000000002e-02, 2.0000000000000000e-02, 0.0, 0.0, 0.0 ]
    }
}
";

    const XML: &str = "<?xml version=\"1.0\"?>
<opencv_storage>
<image_width>480</image_width>
<image_height>360</image_height>
<camera_matrix type_id=\"opencv-matrix\">
  <rows>3</rows>
  <cols>3</cols>
  <dt>d</dt>
  <data>
    6.5940000000000000e+02 0. 2.3950000000000000e+02 0.
    6.5940000000000000e+02 1.7950000000000000e+02 0. 0. 1.</data></camera_matrix>
<distortion_coefficients type_id=\"opencv-matrix\">
  <rows>5</rows>
  <cols>1</cols>
  <dt>d</dt>
  <data>
    -8.0000000000000002e-02 2.0000000000000000e-02 0. 0. 0.</data></distortion_coefficients>
</opencv_storage>
";

    fn parse(text: &str) -> Result<OpenCvCalibration> {
        parse_opencv_calibration(Path::new("calib.yml"), text, &OpenCvKeys::default())
    }

    fn bench(c: &OpenCvCalibration) {
        assert_eq!(c.focal_px, [659.4, 659.4]);
        assert_eq!(c.principal_point_px, [239.5, 179.5]);
        assert_eq!(c.distortion, [-0.08, 0.02, 0.0, 0.0, 0.0]);
        assert_eq!(c.image_size, Some([480, 360]));
        assert_eq!(c.camera_matrix_key, "camera_matrix");
        assert_eq!(c.distortion_key, "distortion_coefficients");
    }

    #[test]
    fn reads_the_three_filestorage_formats() {
        bench(&parse(YAML).unwrap());
        bench(&parse(JSON).unwrap());
        bench(&parse(XML).unwrap());
    }

    #[test]
    fn python_names_block_sequences_and_four_coefficients() {
        let text = "%YAML:1.0\n---\nK: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   \
                    data: [ 1000., 0., 320., 0., 1010., 240., 0., 0., 1. ]\nD: !!opencv-matrix\n   \
                    rows: 1\n   cols: 4\n   dt: d\n   data:\n   - 0.1\n   - -0.2\n   - 0.001\n   - 0.\n";
        let c = parse(text).unwrap();
        assert_eq!(c.focal_px, [1000.0, 1010.0]);
        assert_eq!(c.principal_point_px, [320.0, 240.0]);
        assert_eq!(c.distortion, [0.1, -0.2, 0.001, 0.0, 0.0]);
        assert_eq!(c.image_size, None);
        // Plain nested sequences (e.g. yaml.dump of numpy lists) and named keys.
        let text = "M1: [[800, 0, 100], [0, 800, 90], [0, 0, 1]]\nD1: [[0.01, 0, 0, 0, 0]]\n";
        let keys = OpenCvKeys {
            camera_matrix: Some("M1".into()),
            distortion: Some("D1".into()),
        };
        let c = parse_opencv_calibration(Path::new("stereo.yml"), text, &keys).unwrap();
        assert_eq!(c.focal_px, [800.0, 800.0]);
        assert_eq!(c.distortion[0], 0.01);
    }

    #[test]
    fn eight_coefficients_pass_when_the_rational_terms_are_zero() {
        let t = YAML.replace(
            "   rows: 5\n   cols: 1\n   dt: d\n   data: [ -8.0000000000000002e-02, 2.0000000000000000e-02, 0., 0.,\n       0. ]",
            "   rows: 8\n   cols: 1\n   dt: d\n   data: [ -0.08, 0.02, 0., 0., 0., 0., 0., 0. ]",
        );
        assert_eq!(parse(&t).unwrap().distortion, [-0.08, 0.02, 0.0, 0.0, 0.0]);
        let t = t.replace("0., 0., 0., 0., 0., 0. ]", "0., 0., 0., 0.5, 0., 0. ]");
        let e = parse(&t).unwrap_err().to_string();
        assert!(e.contains("distortion_coefficients.data[6]"), "{e}");
        assert!(e.contains("rational"), "{e}");
        assert!(e.contains("(value 0.5)"), "{e}");
    }

    #[test]
    fn errors_name_the_file_line_field_and_value() {
        // A wrong element count.
        let t = YAML.replace(
            "1.7950000000000000e+02, 0., 0., 1. ]",
            "1.7950000000000000e+02, 0., 0. ]",
        );
        let e = parse(&t).unwrap_err().to_string();
        assert!(
            e.starts_with("calib.yml: line 16, field `camera_matrix.data`"),
            "{e}"
        );
        assert!(e.contains("needs 9 numbers"), "{e}");
        // A non-number.
        let t = YAML.replace(
            "2.3950000000000000e+02, 0.,",
            "2.3950000000000000e+02, abc,",
        );
        let e = parse(&t).unwrap_err().to_string();
        assert!(e.contains("field `camera_matrix.data[4]`"), "{e}");
        assert!(e.contains("(value abc)"), "{e}");
        // Not a camera matrix.
        let t = JSON.replace("0.0, 0.0, 1.0 ]", "0.0, 0.0, 2.0 ]");
        let e = parse(&t).unwrap_err().to_string();
        assert!(e.contains("line 10, field `camera_matrix.data[9]`"), "{e}");
        assert!(e.contains("(value 2)"), "{e}");
        // A skewed camera matrix.
        let t = JSON.replace(
            "[ 6.5940000000000000e+02, 0.0,",
            "[ 6.5940000000000000e+02, 3.0,",
        );
        let e = parse(&t).unwrap_err().to_string();
        assert!(
            e.contains("camera_matrix.data[2]") && e.contains("skew"),
            "{e}"
        );
        // A negative focal length.
        let t = XML.replace(
            "6.5940000000000000e+02 0. 2.395",
            "-6.5940000000000000e+02 0. 2.395",
        );
        let e = parse(&t).unwrap_err().to_string();
        assert!(e.contains("line 10, field `camera_matrix.data[1]`"), "{e}");
        assert!(e.contains("fx must be > 0"), "{e}");
        // Missing entries name what the file has.
        let e = parse("%YAML:1.0\n---\nfoo: 1\nbar: [ 1, 2 ]\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("no camera matrix entry") && e.contains("entries: foo, bar"),
            "{e}"
        );
        // Multi-channel data and base64 data.
        let t = YAML.replace(
            "   dt: d\n   data: [ 6.594",
            "   dt: \"3d\"\n   data: [ 6.594",
        );
        let e = parse(&t).unwrap_err().to_string();
        assert!(e.contains("camera_matrix.dt") && e.contains("3d"), "{e}");
        // Fisheye.
        let e = parse(&format!("{YAML}fisheye_model: 1\n"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("fisheye_model"), "{e}");
        // A .Nan written by OpenCV.
        let t = YAML.replace("-8.0000000000000002e-02, 2.0", ".Nan, 2.0");
        let e = parse(&t).unwrap_err().to_string();
        assert!(
            e.contains("distortion_coefficients.data[1]") && e.contains(".Nan"),
            "{e}"
        );
        assert!(parse("").is_err());
        assert!(parse("{ \"camera_matrix\": [1, 2").is_err());
    }
    /// A calibrated manifest with `[camera] opencv = ...` and frames of `w x h`.
    fn manifest_with(
        dir: &Path,
        camera: &str,
        w: usize,
        h: usize,
    ) -> Result<super::super::Manifest> {
        for a in ["p000", "p045", "p090"] {
            crate::image::write_gray16(
                &dir.join(format!("{a}.png")),
                true,
                w,
                h,
                &vec![100u16; w * h],
            )
            .unwrap();
        }
        let text = format!(
            "{camera}\nposition = [-0.6128, 0.0, 0.5142]\nlook_at = [0.0, 0.0, 0.0]\nup = [0.0, 0.0, 1.0]\n\n\
             [[region]]\nname = \"a\"\nrect = [{}, {}, 8, 8]\n\n[[capture]]\n\
             source = {{ position = [0.4015, 0.0, 0.5734] }}\nframes = [\n  \
             {{ angle_deg = 0.0, file = \"p000.png\" }},\n  {{ angle_deg = 45.0, file = \"p045.png\" }},\n  \
             {{ angle_deg = 90.0, file = \"p090.png\" }},\n]\n",
            w / 2 - 4,
            h / 2 - 4
        );
        let path = dir.join("manifest.toml");
        std::fs::write(&path, text).unwrap();
        super::super::load(&path)
    }

    #[test]
    fn manifest_camera_reads_the_calibration_file() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("cal")).unwrap();
        std::fs::write(dir.path().join("cal/calib.yml"), YAML).unwrap();
        std::fs::write(dir.path().join("calib.json"), JSON).unwrap();
        let m =
            manifest_with(dir.path(), "[camera]\nopencv = \"cal/calib.yml\"", 480, 360).unwrap();
        let cam = m.camera.as_ref().unwrap();
        assert_eq!(cam.focal_px, [659.4, 659.4]);
        assert_eq!(cam.principal_point_px, [239.5, 179.5]);
        assert_eq!(cam.distortion, [-0.08, 0.02, 0.0, 0.0, 0.0]);
        assert_eq!(
            cam.opencv.as_ref().map(|c| c.image_size),
            Some(Some([480, 360]))
        );
        let t = "[camera]\nopencv = { file = \"calib.json\", camera_matrix = \"camera_matrix\" }";
        let m = manifest_with(dir.path(), t, 480, 360).unwrap();
        assert_eq!(m.camera.unwrap().focal_px, [659.4, 659.4]);
        // The calibration was made on images of another size.
        let e = manifest_with(dir.path(), "[camera]\nopencv = \"cal/calib.yml\"", 960, 720)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("field `camera.opencv`") && e.contains("480x360"),
            "{e}"
        );
        assert!(e.contains("super-pixel") && e.contains("1318.8"), "{e}");
        // Both the file and the intrinsics.
        let t = "[camera]\nopencv = \"cal/calib.yml\"\nfocal_px = 600.0";
        let e = manifest_with(dir.path(), t, 480, 360)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("line 3, field `camera.focal_px`") && e.contains("not both"),
            "{e}"
        );
        // A missing file names the manifest's field.
        let e = manifest_with(dir.path(), "[camera]\nopencv = \"nope.yml\"", 480, 360)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("field `camera.opencv`") && e.contains("not found"),
            "{e}"
        );
        // A bad calibration file names its own line and field.
        std::fs::write(
            dir.path().join("bad.yml"),
            YAML.replace("rows: 3", "rows: 2"),
        )
        .unwrap();
        let e = manifest_with(dir.path(), "[camera]\nopencv = \"bad.yml\"", 480, 360)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("bad.yml: line 16, field `camera_matrix.data`"),
            "{e}"
        );
    }
}
