//! `polarid init`: a commented manifest skeleton from a folder of frames.
//!
//! The folder is recognised as one of these layouts (docs/CAPTURE.md):
//!
//! - **one folder per capture** (source position): `DIR/<capture>/` holding either
//!   rotating-polarizer frames named by their angle (`p000.png`, `pol045.tif`, `90.png`,
//!   `img_135deg.tif`: the number that differs between the files is the angle), or one
//!   raw frame of a polarization camera (DoFP), or `s0`, `s1`, `s2` Stokes images;
//! - **one flat folder**: rotating-polarizer frames named by capture and angle
//!   (`i35_p000.png`, `i35_p045.png`, …, `i40_p000.png`, …: grouped by the name without
//!   the angle), or one DoFP raw frame per capture (`lamp1.png`, `lamp2.png`, …).
//!
//! A number is taken for a polarizer angle when, across the files of a capture, it is
//! the only part of the name that changes, its values are distinct modulo 180°, there
//! are at least three, and the set looks like a polarizer's (it holds 0°, or is evenly
//! spaced over 180°); otherwise single frames are DoFP raws. Frames whose name starts
//! with `dark` (or in a folder `dark`/`darks`) are dark frames: their mean becomes
//! `dark_level`. The sensor's bit depth, and with it `saturation`, is read from the files
//! ([`polarid_io::frames_dir::SensorDepth`]).
//!
//! What the frames cannot say — the geometry (the camera's and each source's zenith, or
//! the camera and source positions of a calibrated bench), the regions, the exposures —
//! is written as a placeholder with a comment: numbers as `nan`, rectangles as
//! `[0, 0, 0, 0]`, so that `measure` refuses the manifest (naming the line and field)
//! until every placeholder is filled in.
//!
//! A folder that fits none of the layouts is refused ([`PipelineError::Data`], exit
//! status 2) with the reason: no PNG/TIFF frames, loose frames beside capture folders,
//! several frames without angles in their names, frames of different sizes or types.

use std::fmt::Write;
use std::path::{Component, Path, PathBuf};

use polarid_io::frames_dir::{FrameStats, SensorDepth, frame_stats, list_folder};

use crate::{PipelineError, Result, Warning};

/// What to initialise.
#[derive(Debug, Clone, PartialEq)]
pub struct InitConfig {
    /// The folder of frames.
    pub frames_dir: PathBuf,
    /// Where the manifest will be written (its folder anchors the relative paths).
    pub manifest_path: PathBuf,
    /// An OpenCV calibration file (`cv::FileStorage`): the skeleton is then a calibrated
    /// one (`[camera] opencv = ...`, a `source` per capture) instead of far-field angles.
    pub opencv: Option<PathBuf>,
}

/// How the frames of one capture were recorded.
#[derive(Debug, Clone, PartialEq)]
pub enum CaptureData {
    /// Rotating polarizer: `(angle_deg, file)` sorted by angle.
    Frames(Vec<(f64, PathBuf)>),
    /// One raw mosaic of a polarization camera.
    Dofp(PathBuf),
    /// Stokes images S0, S1, S2.
    Stokes([PathBuf; 3]),
}

/// One capture found.
#[derive(Debug, Clone, PartialEq)]
pub struct FoundCapture {
    /// Its label (folder name, or the common part of its file names).
    pub name: String,
    /// Its data.
    pub data: CaptureData,
}

/// The result of [`init`].
#[derive(Debug, Clone, PartialEq)]
pub struct InitOutput {
    /// The manifest skeleton (TOML with comments).
    pub text: String,
    /// The captures found, in manifest order.
    pub captures: Vec<FoundCapture>,
    /// Frame width and height (pixels).
    pub size: [usize; 2],
    /// The sensor depth read from the frames.
    pub depth: SensorDepth,
    /// `dark_level` from dark frames, if there were any (and how many).
    pub dark: Option<(f64, usize)>,
    /// Every file read (the output must not overwrite any of them).
    pub inputs: Vec<PathBuf>,
    /// What the caller should tell the user.
    pub warnings: Vec<Warning>,
}

fn data_err(dir: &Path, reason: impl Into<String>) -> PipelineError {
    PipelineError::Data {
        path: dir.display().to_string(),
        reason: reason.into(),
    }
}

/// The captures found in a folder and what else it holds.
struct Layout {
    /// The captures, in manifest order.
    captures: Vec<FoundCapture>,
    /// Dark frames (`dark*` files, or in a `dark`/`darks` folder).
    dark_files: Vec<PathBuf>,
}

/// Recognise the layout of `dir` (module documentation); a warning for the entries that
/// are not frames.
fn find_captures(dir: &Path, warnings: &mut Vec<Warning>) -> Result<Layout> {
    let top = list_folder(dir)?;
    let is_dark_dir = |p: &Path| {
        p.file_name()
            .map(|n| n.to_string_lossy().to_lowercase())
            .is_some_and(|n| n == "dark" || n == "darks")
    };
    let is_dark_file = |p: &Path| {
        p.file_stem()
            .map(|n| n.to_string_lossy().to_lowercase())
            .is_some_and(|n| n.starts_with("dark"))
    };
    let (mut dark_files, loose): (Vec<PathBuf>, Vec<PathBuf>) =
        top.images.iter().cloned().partition(|p| is_dark_file(p));
    let mut ignored: Vec<PathBuf> = top.others.clone();
    let mut capture_dirs = Vec::new();
    for d in &top.dirs {
        let sub = list_folder(d)?;
        if is_dark_dir(d) {
            dark_files.extend(sub.images);
            continue;
        }
        if sub.images.is_empty() {
            if !sub.dirs.is_empty() {
                return Err(data_err(
                    d,
                    "holds folders but no frames: polarid init reads one folder per capture \
                     (with its frames in it), not deeper levels",
                ));
            }
            ignored.push(d.clone());
            continue;
        }
        ignored.extend(sub.others);
        capture_dirs.push((d.clone(), sub.images));
    }
    let mut captures = if !capture_dirs.is_empty() {
        if let Some(f) = loose.first() {
            return Err(data_err(
                dir,
                format!(
                    "holds both capture folders ({}) and loose frames ({}): put every \
                     capture in its own folder, or all frames in this one",
                    capture_dirs
                        .iter()
                        .take(3)
                        .map(|(d, _)| file_name(d))
                        .collect::<Vec<_>>()
                        .join(", "),
                    file_name(f)
                ),
            ));
        }
        let one = |(d, images): &(PathBuf, Vec<PathBuf>)| {
            let (name, data) = (file_name(d), one_capture(d, images)?);
            Ok(FoundCapture { name, data })
        };
        capture_dirs.iter().map(one).collect::<Result<_>>()?
    } else if loose.is_empty() {
        return Err(data_err(
            dir,
            "holds no PNG or TIFF frames (nor folders of them); polarid init needs the \
             folder of frames as the camera wrote them",
        ));
    } else {
        flat_captures(dir, &loose, warnings)?
    };
    captures.sort_by(|a, b| natural_cmp(&a.name, &b.name));
    if !ignored.is_empty() {
        warnings.push(Warning(format!(
            "left out {} entr{} that are not frames: {}",
            ignored.len(),
            if ignored.len() == 1 { "y" } else { "ies" },
            ignored
                .iter()
                .take(5)
                .map(|p| file_name(p))
                .collect::<Vec<_>>()
                .join(", ")
                + if ignored.len() > 5 { ", ..." } else { "" }
        )));
    }
    Ok(Layout {
        captures,
        dark_files,
    })
}

/// Read every frame of `captures` (sizes, types, values): their statistics, in order.
/// Errors: frames of different sizes or types, DoFP raws of an odd size.
fn read_frames(dir: &Path, captures: &[FoundCapture]) -> Result<Vec<FrameStats>> {
    let files = captures.iter().flat_map(|c| capture_files(&c.data));
    let stats = files
        .map(|f| frame_stats(&f))
        .collect::<polarid_io::Result<Vec<_>>>()?;
    let first = stats
        .first()
        .ok_or_else(|| data_err(dir, "no frames found"))?;
    for s in &stats {
        if [s.width, s.height] != [first.width, first.height] {
            return Err(data_err(
                dir,
                format!(
                    "frames of different sizes: {} is {}x{}, {} is {}x{} (one camera, one \
                     frame size)",
                    first.path.display(),
                    first.width,
                    first.height,
                    s.path.display(),
                    s.width,
                    s.height
                ),
            ));
        }
        if s.kind != first.kind {
            return Err(data_err(
                dir,
                format!(
                    "frames of different types: {} has {} bits, {} has {}",
                    first.path.display(),
                    first.kind.bit_depth(),
                    s.path.display(),
                    s.kind.bit_depth()
                ),
            ));
        }
    }
    if has_dofp(captures) && (first.width % 2 != 0 || first.height % 2 != 0) {
        return Err(data_err(
            dir,
            format!(
                "single frames of {}x{} pixels cannot be polarization-camera (DoFP) raws: a \
                 2x2 mosaic needs an even width and height",
                first.width, first.height
            ),
        ));
    }
    Ok(stats)
}

/// Whether some captures are DoFP raws.
fn has_dofp(captures: &[FoundCapture]) -> bool {
    captures
        .iter()
        .any(|c| matches!(c.data, CaptureData::Dofp(_)))
}

/// The sensor depth of the raw frames (of every frame when all are Stokes images); a
/// warning when raw frames reach the saturation level.
fn sensor_depth(
    stats: &[FrameStats],
    captures: &[FoundCapture],
    warnings: &mut Vec<Warning>,
) -> SensorDepth {
    let raw_stats: Vec<FrameStats> = stats
        .iter()
        .zip(captures.iter().flat_map(|c| {
            let stokes = matches!(c.data, CaptureData::Stokes(_));
            std::iter::repeat_n(stokes, capture_files(&c.data).len())
        }))
        .filter(|(_, stokes)| !stokes)
        .map(|(s, _)| s.clone())
        .collect();
    let depth = SensorDepth::infer(if raw_stats.is_empty() {
        stats
    } else {
        &raw_stats
    });
    let saturated: Vec<_> = raw_stats
        .iter()
        .filter(|s| depth.saturation.is_some_and(|sat| f64::from(s.max) >= sat) && s.at_max > 0)
        .map(|s| (s.path.clone(), s.at_max))
        .collect();
    if !saturated.is_empty() {
        let total: usize = saturated.iter().map(|s| s.1).sum();
        warnings.push(Warning(format!(
            "{} frame(s) have pixels at the saturation level {} ({} pixels in all, e.g. {}): \
             saturated pixels are left out by measure; shorten the exposure or use HDR brackets \
             if they fall on the targets",
            saturated.len(),
            depth.saturation.unwrap_or(0.0),
            total,
            saturated[0].0.display()
        )));
    }
    depth
}

/// `dark_level` (the mean of the dark frames, to 0.1 DN) and how many there were;
/// `None` without dark frames (a warning when the sensor depth is known). Errors: a dark
/// frame whose size is not `first`'s.
fn dark_level(
    dir: &Path,
    dark_files: &[PathBuf],
    first: &FrameStats,
    depth: &SensorDepth,
    warnings: &mut Vec<Warning>,
) -> Result<Option<(f64, usize)>> {
    if dark_files.is_empty() {
        if depth.saturation.is_some() {
            warnings.push(Warning(
                "no dark frames (dark*.png, or a dark/ folder): dark_level is 0; set it to your \
                 camera's black level (docs/CAPTURE.md, \"Dark frames\")"
                    .into(),
            ));
        }
        return Ok(None);
    }
    let mut sum = 0.0;
    for f in dark_files {
        let s = frame_stats(f)?;
        if [s.width, s.height] != [first.width, first.height] {
            return Err(data_err(
                dir,
                format!(
                    "dark frame {} is {}x{}, the frames {}x{}",
                    f.display(),
                    s.width,
                    s.height,
                    first.width,
                    first.height
                ),
            ));
        }
        sum += s.mean;
    }
    let level = (sum / dark_files.len() as f64 * 10.0).round() / 10.0;
    Ok(Some((level, dark_files.len())))
}

/// Recognise the layout of `cfg.frames_dir` and write the manifest skeleton.
///
/// Errors: [`PipelineError::Data`] for a folder that fits no layout (module
/// documentation), [`PipelineError::Io`] for a missing folder or an unreadable frame.
pub fn init(cfg: &InitConfig) -> Result<InitOutput> {
    let dir = cfg.frames_dir.as_path();
    if !dir.is_dir() {
        return Err(data_err(
            dir,
            if dir.exists() {
                "is not a folder (give the folder that holds the frames)"
            } else {
                "no such folder"
            },
        ));
    }
    let mut warnings = Vec::new();
    let Layout {
        captures,
        dark_files,
    } = find_captures(dir, &mut warnings)?;
    let stats = read_frames(dir, &captures)?;
    let depth = sensor_depth(&stats, &captures, &mut warnings);
    let first = &stats[0];
    let dark = dark_level(dir, &dark_files, first, &depth, &mut warnings)?;
    let mut inputs: Vec<PathBuf> = captures
        .iter()
        .flat_map(|c| capture_files(&c.data))
        .collect();
    inputs.extend(dark_files);
    let size = [first.width, first.height];
    let manifest_dir = parent_dir(&cfg.manifest_path);
    let text = render(&Render {
        dir,
        captures: &captures,
        size,
        depth: &depth,
        dark,
        opencv: cfg.opencv.as_deref(),
        quad: has_dofp(&captures),
        rel: &|p: &Path| toml_str(&relative_path(p, &manifest_dir)),
    });
    Ok(InitOutput {
        text,
        captures,
        size,
        depth,
        dark,
        inputs,
        warnings,
    })
}

/// Every file of a capture's data.
pub fn capture_files(d: &CaptureData) -> Vec<PathBuf> {
    match d {
        CaptureData::Frames(f) => f.iter().map(|(_, p)| p.clone()).collect(),
        CaptureData::Dofp(p) => vec![p.clone()],
        CaptureData::Stokes(s) => s.to_vec(),
    }
}

fn file_name(p: &Path) -> String {
    p.file_name().map_or_else(
        || p.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}

fn stem(p: &Path) -> String {
    p.file_stem()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned())
}

/// The numbers of a file stem: `(start, end, value)`; `22.5` is one number.
fn numbers(s: &str) -> Vec<(usize, usize, f64)> {
    let b = s.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        if b[i].is_ascii_digit() {
            let start = i;
            while i < b.len() && b[i].is_ascii_digit() {
                i += 1;
            }
            let mut text = s[start..i].to_string();
            if i + 1 < b.len() && b[i] == b'.' && b[i + 1].is_ascii_digit() {
                let f = i + 1;
                let mut j = f;
                while j < b.len() && b[j].is_ascii_digit() {
                    j += 1;
                }
                text = format!("{text}.{}", &s[f..j]);
                i = j;
            }
            if let Ok(v) = text.parse::<f64>() {
                out.push((start, i, v));
            }
        } else {
            i += 1;
        }
    }
    out
}

/// Files of one capture: the name without the angle, and `(angle_deg, file)`.
type AngleGroup = (String, Vec<(f64, PathBuf)>);

/// A number in a file name: `(start, end, value)`.
type NumberRun = (usize, usize, f64);

/// True when a set of angles (degrees, distinct) looks like a polarizer's: it holds 0°
/// (mod 180) or is evenly spaced over 180°.
fn polarizer_like(angles: &[f64]) -> bool {
    if angles.len() < 3 || angles.iter().any(|a| !(0.0..=360.0).contains(a)) {
        return false;
    }
    let mut m: Vec<f64> = angles.iter().map(|a| a.rem_euclid(180.0)).collect();
    m.sort_by(f64::total_cmp);
    if m.windows(2).any(|w| (w[1] - w[0]).abs() < 1e-9) {
        return false;
    }
    if m.first().is_some_and(|a| a.abs() < 1e-9) {
        return true;
    }
    let step = 180.0 / m.len() as f64;
    m.windows(2).all(|w| (w[1] - w[0] - step).abs() < 1e-6)
}

/// The polarizer angle of each file, when exactly one number of the names changes between
/// them and its values look like a polarizer's; with `flat`, files are grouped by the
/// rest of the name. Returns the groups `(key, [(angle, file)])`.
fn angle_groups(files: &[PathBuf]) -> Option<Vec<AngleGroup>> {
    let parsed: Vec<(String, Vec<NumberRun>)> = files
        .iter()
        .map(|f| {
            let s = stem(f);
            let n = numbers(&s);
            (s, n)
        })
        .collect();
    let max_runs = parsed.iter().map(|p| p.1.len()).max().unwrap_or(0);
    // From the last number of the names to the first: angles usually come last.
    for idx in (0..max_runs).rev() {
        let mut groups: Vec<AngleGroup> = Vec::new();
        let mut ok = true;
        for ((s, nums), f) in parsed.iter().zip(files) {
            // The idx-th number counted from the end, so names with a different count of
            // numbers before the angle still line up.
            let Some(&(a, b, v)) = nums
                .len()
                .checked_sub(max_runs - idx)
                .and_then(|k| nums.get(k))
            else {
                ok = false;
                break;
            };
            let ext = f
                .extension()
                .map_or(String::new(), |e| e.to_string_lossy().to_lowercase());
            let key = format!("{}{{}}{}.{ext}", &s[..a], &s[b..]);
            match groups.iter_mut().find(|g| g.0 == key) {
                Some(g) => g.1.push((v, f.clone())),
                None => groups.push((key, vec![(v, f.clone())])),
            }
        }
        if !ok || groups.is_empty() {
            continue;
        }
        let sets: Vec<Vec<f64>> = groups
            .iter()
            .map(|g| {
                let mut a: Vec<f64> = g.1.iter().map(|x| x.0).collect();
                a.sort_by(f64::total_cmp);
                a
            })
            .collect();
        if sets.iter().all(|s| polarizer_like(s)) && sets.iter().all(|s| s == &sets[0]) {
            for g in &mut groups {
                g.1.sort_by(|x, y| x.0.total_cmp(&y.0));
            }
            return Some(groups);
        }
    }
    None
}

/// The data of a capture folder's frames.
fn one_capture(d: &Path, images: &[PathBuf]) -> Result<CaptureData> {
    if let [one] = images {
        return Ok(CaptureData::Dofp(one.clone()));
    }
    if images.len() == 2 {
        return Err(data_err(
            d,
            format!(
                "holds 2 frames ({}, {}): a rotating-polarizer capture needs at least 3 \
                 polarizer angles (p000.png, p045.png, p090.png, ...), a polarization camera one \
                 raw frame per capture folder",
                file_name(&images[0]),
                file_name(&images[1])
            ),
        ));
    }
    if images.len() == 3 {
        let find = |k: &str| {
            images
                .iter()
                .find(|p| stem(p).to_lowercase().ends_with(k))
                .cloned()
        };
        if let (Some(s0), Some(s1), Some(s2)) = (find("s0"), find("s1"), find("s2")) {
            return Ok(CaptureData::Stokes([s0, s1, s2]));
        }
    }
    match angle_groups(images) {
        Some(groups) if groups.len() == 1 => {
            let Some((_, frames)) = groups.into_iter().next() else {
                return Err(data_err(d, "no frames"));
            };
            Ok(CaptureData::Frames(frames))
        }
        Some(groups) => Err(data_err(
            d,
            format!(
                "holds {} sets of polarizer frames ({}): several exposures (HDR brackets) or \
                 several captures in one folder are not recognised; give each capture its own \
                 folder, and write HDR brackets into the manifest by hand (docs/FORMATS.md, \
                 \"HDR brackets\")",
                groups.len(),
                groups
                    .iter()
                    .take(3)
                    .map(|g| g.0.replace("{}", "*"))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        )),
        _ => Err(data_err(
            d,
            format!(
                "holds {} frames ({}) but their names give no polarizer angles: name \
                 rotating-polarizer frames by their angle (p000.png, p045.png, p090.png, \
                 p135.png; at least 3 distinct angles), or keep one polarization-camera raw \
                 frame per capture folder",
                images.len(),
                images
                    .iter()
                    .take(4)
                    .map(|p| file_name(p))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        )),
    }
}

/// The captures of a flat folder of frames.
fn flat_captures(
    dir: &Path,
    images: &[PathBuf],
    warnings: &mut Vec<Warning>,
) -> Result<Vec<FoundCapture>> {
    if images.len() >= 3
        && let Some(groups) = angle_groups(images)
    {
        return Ok(groups
            .into_iter()
            .enumerate()
            .map(|(i, (key, frames))| {
                let name = key
                    .rsplit_once('.')
                    .map_or(key.as_str(), |(k, _)| k)
                    .replace("{}", "")
                    .trim_matches(|c: char| !c.is_alphanumeric())
                    .to_string();
                let name = name
                    .strip_suffix("_pol")
                    .or_else(|| name.strip_suffix("_p"))
                    .or_else(|| name.strip_suffix("-p"))
                    .unwrap_or(&name)
                    .to_string();
                FoundCapture {
                    name: if name.is_empty() {
                        format!("c{:02}", i + 1)
                    } else {
                        name
                    },
                    data: CaptureData::Frames(frames),
                }
            })
            .collect());
    }
    if images.len() > 1 {
        warnings.push(Warning(format!(
            "the {} frames in {} carry no polarizer angles in their names: each is taken as \
             one capture of a polarization camera (a DoFP raw mosaic); if they are \
             rotating-polarizer frames, name them by angle (i35_p000.png, i35_p045.png, ...) \
             or put each capture in its own folder",
            images.len(),
            dir.display()
        )));
    }
    Ok(images
        .iter()
        .map(|p| FoundCapture {
            name: stem(p),
            data: CaptureData::Dofp(p.clone()),
        })
        .collect())
}

/// Compare names with their numbers as numbers (`c2` before `c10`).
fn natural_cmp(a: &str, b: &str) -> std::cmp::Ordering {
    fn key(s: &str) -> Vec<(String, u64)> {
        let mut out = Vec::new();
        let mut text = String::new();
        let mut num = String::new();
        for c in s.chars() {
            if c.is_ascii_digit() {
                num.push(c);
            } else {
                if !num.is_empty() {
                    out.push((std::mem::take(&mut text), num.parse().unwrap_or(u64::MAX)));
                    num.clear();
                }
                text.push(c);
            }
        }
        out.push((text, num.parse().unwrap_or(0)));
        out
    }
    key(a).cmp(&key(b)).then_with(|| a.cmp(b))
}

/// The folder of a file path (`.` for a bare name).
fn parent_dir(p: &Path) -> PathBuf {
    p.parent()
        .filter(|d| !d.as_os_str().is_empty())
        .map_or_else(|| PathBuf::from("."), Path::to_path_buf)
}

/// `target` relative to the folder `base` (both made absolute; `..` where needed), with
/// `/` separators; the absolute path when there is no common root.
fn relative_path(target: &Path, base: &Path) -> String {
    let abs = |p: &Path| {
        std::fs::canonicalize(p).unwrap_or_else(|_| {
            std::env::current_dir()
                .map(|d| d.join(p))
                .unwrap_or_else(|_| p.to_path_buf())
        })
    };
    let (t, b) = (abs(target), abs(base));
    let tc: Vec<Component> = t.components().collect();
    let bc: Vec<Component> = b.components().collect();
    let common = tc.iter().zip(&bc).take_while(|(x, y)| x == y).count();
    if common == 0 {
        return t.display().to_string();
    }
    let mut parts: Vec<String> = vec!["..".to_string(); bc.len() - common];
    parts.extend(
        tc[common..]
            .iter()
            .map(|c| c.as_os_str().to_string_lossy().into_owned()),
    );
    parts.join("/")
}

/// A TOML basic string.
fn toml_str(s: &str) -> String {
    let mut out = String::from("\"");
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            c if c.is_control() => out.push_str(&format!("\\u{:04X}", c as u32)),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

/// A number as TOML writes it (`45.0`, `22.5`).
fn num(x: f64) -> String {
    format!("{x:?}")
}

struct Render<'a> {
    dir: &'a Path,
    captures: &'a [FoundCapture],
    size: [usize; 2],
    depth: &'a SensorDepth,
    dark: Option<(f64, usize)>,
    opencv: Option<&'a Path>,
    /// Some DoFP captures (their pattern is explained).
    quad: bool,
    /// A path as the manifest writes it (a TOML string, relative to its folder).
    rel: &'a dyn Fn(&Path) -> String,
}

/// The manifest text.
fn render(r: &Render<'_>) -> String {
    let mut t = String::new();
    r.header(&mut t);
    r.sensor(&mut t);
    r.geometry(&mut t);
    r.targets(&mut t);
    r.captures(&mut t);
    t
}

impl Render<'_> {
    /// What was found and what to fill in.
    fn header(&self, t: &mut String) {
        let mut kinds: Vec<&str> = Vec::new();
        for c in self.captures {
            let s = match c.data {
                CaptureData::Frames(_) => "rotating-polarizer frame sets",
                CaptureData::Dofp(_) => "polarization-camera (DoFP) raw frames",
                CaptureData::Stokes(_) => "Stokes image sets",
            };
            if !kinds.contains(&s) {
                kinds.push(s);
            }
        }
        let _ = writeln!(
            t,
            "# Capture-set manifest written by `polarid init` from {}.\n\
             # Found: {} capture(s), {}; {}x{} pixels.\n\
             # Fill in every value marked FILL IN (numbers written `nan`, rectangles [0, 0, 0, 0]):\n\
             # `polarid measure` refuses the manifest, naming the line, until they are set.\n\
             # Every key: docs/FORMATS.md (\"Capture-set manifest\"); how to measure them: docs/CAPTURE.md.\n",
            self.dir.display(),
            self.captures.len(),
            kinds.join(" and "),
            self.size[0],
            self.size[1],
        );
    }

    /// Dark level, saturation, wavelength and angle uncertainty.
    fn sensor(&self, t: &mut String) {
        let _ = writeln!(
            t,
            "# --- Sensor ---------------------------------------------------------------"
        );
        match self.dark {
            Some((level, n)) => {
                let _ = writeln!(
                    t,
                    "dark_level = {}          # DN: the mean of {n} dark frame(s) (lens capped, same exposure and gain)",
                    num(level)
                );
            }
            None => {
                let _ = writeln!(
                    t,
                    "dark_level = 0.0          # DN subtracted from every raw value: your camera's black level.\n\
                 #                           Measure it: add dark frames (dark*.png, lens capped, same\n\
                 #                           exposure and gain) to the folder and run `polarid init` again."
                );
            }
        }
        match self.depth.saturation {
            Some(sat) => {
                let _ = writeln!(
                    t,
                    "saturation = {}       # DN: raw values at or above are rejected. From the files: {}.\n\
                 #                           Check it against your camera's bit depth ({} bits assumed).",
                    num(sat),
                    self.depth.evidence,
                    self.depth.bits.unwrap_or(0)
                );
            }
            None => {
                let _ = writeln!(
                    t,
                    "# saturation = 4095.0     # {}; set the raw level at which the sensor saturates.",
                    self.depth.evidence
                );
            }
        }
        let _ = writeln!(
            t,
            "# wavelength_nm = 650.0    # the light's wavelength (lamp x filter x sensor), nm: classify\n\
         #                           compares with the materials at this wavelength."
        );
        let _ = writeln!(
            t,
            "# angle_sd_deg = 0.2       # standard uncertainty of the source and camera directions, degrees\n\
         #                           (docs/ERRORS.md; docs/CAPTURE.md tells how to estimate it).\n"
        );
    }

    /// The camera: calibrated (`[camera]`, `[[plane]]`) or far-field angles.
    fn geometry(&self, t: &mut String) {
        let _ = writeln!(
            t,
            "# --- Geometry -------------------------------------------------------------"
        );
        if let Some(cal) = self.opencv {
            let _ = writeln!(
                t,
                "[camera]                    # a calibrated camera: every pixel gets its own angles\n\
             opencv = {}   # the camera matrix and distortion from OpenCV's calibrateCamera\n\
             position = [nan, nan, nan]  # FILL IN: the camera's centre of projection (entrance pupil, near the lens' front), scene frame\n\
             look_at = [nan, nan, nan]   # FILL IN: a point on the optical axis (e.g. the target in the image centre)\n\
             up = [0.0, 0.0, 1.0]        # the direction that points up in the image (scene frame)\n\
             # Lengths in any unit, the same everywhere (metres, millimetres). The scene frame is\n\
             # yours: e.g. origin on the target plane, z up from it. docs/CAPTURE.md shows how to\n\
             # measure the positions with a tape or a laser distance meter.\n\n\
             [[plane]]                   # the surface the targets lie on\n\
             name = \"target\"\n\
             point = [0.0, 0.0, 0.0]     # a point of the plane\n\
             normal = [0.0, 0.0, 1.0]    # pointing to the camera's side\n",
                (self.rel)(cal)
            );
        } else {
            let _ = writeln!(
                t,
                "theta_r_deg = nan          # FILL IN: camera zenith, degrees from the target's normal, in [0, 90)\n\
             phi_deg = 180.0            # phi_r - phi_i; 180 = source and camera in one plane with the normal\n\
             # Far-field angles: the lamp and the camera far from the targets (distance > ~20x the\n\
             # target's size), so every pixel sees them at the same angles. For a lamp or a lens\n\
             # close to the targets use a calibrated camera instead: `polarid init DIR --opencv\n\
             # calib.yml` writes [camera] and a source position per capture (docs/CAPTURE.md).\n"
            );
        }
    }

    /// One `[[region]]` to copy per target.
    fn targets(&self, t: &mut String) {
        let _ = writeln!(
            t,
            "# --- Targets --------------------------------------------------------------"
        );
        let _ = writeln!(
            t,
            "[[region]]                  # one table per target (copy it for each)\n\
         name = \"target1\"            # FILL IN: a unique name\n\
         rect = [0, 0, 0, 0]         # FILL IN: x (column), y (row), width, height in pixels of the files as\n\
         #                             stored ({}x{}{}), origin top-left. Find them on the S0 view of\n\
         #                             one capture:{}\n\
         # class = \"aluminum\"        # a reference plate of known material: its label for `polarid train`\n",
            self.size[0],
            self.size[1],
            if self.quad { ", the raw mosaic" } else { "" },
            view_command(self.captures.first(), self.rel)
        );
    }

    /// One `[[capture]]` per capture.
    fn captures(&self, t: &mut String) {
        let _ = writeln!(
            t,
            "# --- Captures (one per source position) ------------------------------------"
        );
        if self.quad {
            let _ = writeln!(
                t,
                "# DoFP raws: `pattern` lists the polarizer angles of the 2x2 super-pixel row by row from\n\
             # the top-left: [90, 45, 135, 0] for Sony IMX250MZR/IMX253MZR/IMX264MZR cameras (FLIR,\n\
             # Lucid, Basler, ...); check your camera's manual. A colour polarization camera\n\
             # (IMX250MYR): add color = \"RGGB\" to each dofp.\n"
            );
        }
        for (i, c) in self.captures.iter().enumerate() {
            let _ = writeln!(t, "[[capture]]");
            let _ = writeln!(t, "name = {}", toml_str(&c.name));
            if self.opencv.is_some() {
                let _ = writeln!(
                    t,
                    "source = {{ position = [nan, nan, nan] }}   # FILL IN: the lamp's position (the centre of its emitting part), scene frame"
                );
            } else {
                let _ = writeln!(
                    t,
                    "theta_i_deg = nan          # FILL IN: source zenith, degrees from the target's normal"
                );
            }
            let _ = writeln!(
                t,
                "exposure = 1.0             # relative exposure (time x gain); S0 is divided by it{}",
                if i == 0 {
                    ". Leave 1.0 when\n#                            every capture has the same exposure"
                } else {
                    ""
                }
            );
            match &c.data {
                CaptureData::Frames(f) => {
                    let _ = writeln!(t, "frames = [");
                    for (a, p) in f {
                        let _ = writeln!(
                            t,
                            "  {{ angle_deg = {}, file = {} }},",
                            num(*a),
                            (self.rel)(p)
                        );
                    }
                    let _ = writeln!(t, "]");
                }
                CaptureData::Dofp(p) => {
                    let _ = writeln!(
                        t,
                        "dofp = {{ file = {}, pattern = [90, 45, 135, 0] }}",
                        (self.rel)(p)
                    );
                }
                CaptureData::Stokes([s0, s1, s2]) => {
                    let _ = writeln!(
                        t,
                        "stokes = {{ s0 = {}, s1 = {}, s2 = {} }}",
                        (self.rel)(s0),
                        (self.rel)(s1),
                        (self.rel)(s2)
                    );
                }
            }
            let _ = writeln!(t);
        }
    }
}

/// The `polarid stokes` command that shows S0 and DoLP of a capture.
fn view_command(c: Option<&FoundCapture>, rel: &dyn Fn(&Path) -> String) -> String {
    let unq = |p: &Path| rel(p).trim_matches('"').to_string();
    match c.map(|c| &c.data) {
        Some(CaptureData::Frames(f)) => format!(
            "\n#                             polarid stokes --frames {} --angles {} -o view\n#                             (view/s0.tif, view/dolp.png)",
            f.iter().map(|(_, p)| unq(p)).collect::<Vec<_>>().join(" "),
            f.iter()
                .map(|(a, _)| format!("{a}"))
                .collect::<Vec<_>>()
                .join(",")
        ),
        Some(CaptureData::Dofp(p)) => format!(
            "\n#                             polarid stokes --dofp {} -o view   (view/s0.tif, view/dolp.png)",
            unq(p)
        ),
        _ => " any image viewer that shows pixel coordinates".to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_and_polarizer_sets() {
        assert_eq!(numbers("i35_p022.5"), vec![(1, 3, 35.0), (5, 10, 22.5)]);
        assert_eq!(numbers("img_135deg").last().map(|x| x.2), Some(135.0));
        assert!(polarizer_like(&[0.0, 45.0, 90.0, 135.0]));
        assert!(polarizer_like(&[0.0, 60.0, 120.0]));
        assert!(polarizer_like(&[30.0, 90.0, 150.0]));
        assert!(polarizer_like(&[0.0, 45.0, 90.0]));
        assert!(!polarizer_like(&[35.0, 40.0, 45.0, 50.0]));
        assert!(!polarizer_like(&[0.0, 90.0]));
        assert!(!polarizer_like(&[0.0, 180.0, 90.0]));
    }

    #[test]
    fn groups_by_name_without_the_angle() {
        let files: Vec<PathBuf> = [
            "i35_p000.png",
            "i35_p045.png",
            "i35_p090.png",
            "i35_p135.png",
            "i40_p000.png",
            "i40_p045.png",
            "i40_p090.png",
            "i40_p135.png",
        ]
        .iter()
        .map(PathBuf::from)
        .collect();
        let g = angle_groups(&files).unwrap();
        assert_eq!(g.len(), 2);
        assert_eq!(
            g[0].1.iter().map(|x| x.0).collect::<Vec<_>>(),
            vec![0.0, 45.0, 90.0, 135.0]
        );
        // Source zeniths are not polarizer angles: single DoFP frames.
        let files: Vec<PathBuf> = ["i35.png", "i40.png", "i45.png", "i50.png"]
            .iter()
            .map(PathBuf::from)
            .collect();
        assert!(angle_groups(&files).is_none());
        assert_eq!(natural_cmp("c2", "c10"), std::cmp::Ordering::Less);
        assert_eq!(
            relative_path(Path::new("/a/b/c.png"), Path::new("/a/d")),
            "../b/c.png"
        );
        assert_eq!(toml_str("a\"b\\c"), "\"a\\\"b\\\\c\"");
    }
}
