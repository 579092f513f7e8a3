//! Looking at a folder of frames before a manifest exists (`polarid init`): which files
//! are images, their size and sample type, and what their values say about the
//! sensor's bit depth.
//!
//! A 16-bit file does not always say how many bits the sensor has: a 12-bit camera
//! stores 0…4095 (or, shifted to the top, multiples of 16 up to 65520). [`FrameStats`]
//! records the evidence — the largest value the file records for its samples
//! ([`Frame::recorded_max`](crate::image::Frame::recorded_max): a PNG `sBIT` chunk or a
//! TIFF `MaxSampleValue` tag, read by [`read_frame`] and nowhere else), the largest
//! value, and the low bits that are zero in every pixel — and [`SensorDepth::infer`]
//! turns it into a bit depth and a saturation level, saying how it was found. A recorded
//! depth decides, with the same level `measure` uses (12 significant bits: 4095,
//! [`recorded_max_of_bits`](crate::image::recorded_max_of_bits)).

use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};

use crate::error::{IoError, Result};
use crate::image::{SampleKind, read_frame};

/// True when the file starts like a PNG or a TIFF (the types polarid reads).
pub fn is_image_file(path: &Path) -> bool {
    let mut head = [0u8; 8];
    let Ok(mut f) = File::open(path) else {
        return false;
    };
    let n = f.read(&mut head).unwrap_or(0);
    let head = &head[..n];
    head.starts_with(b"\x89PNG\r\n\x1a\n")
        || head.starts_with(b"II*\0")
        || head.starts_with(b"MM\0*")
        || head.starts_with(b"II+\0")
        || head.starts_with(b"MM\0+")
}

/// The entries of a folder, sorted by name: its sub-folders, its image files (PNG or
/// TIFF by content) and its other files.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct FolderListing {
    /// Sub-folders (hidden ones, starting with `.`, are left out).
    pub dirs: Vec<PathBuf>,
    /// PNG and TIFF files.
    pub images: Vec<PathBuf>,
    /// Every other file (not hidden).
    pub others: Vec<PathBuf>,
}

/// List `dir` (see [`FolderListing`]).
///
/// Errors: [`IoError::Io`] when the folder cannot be read (a missing folder, or a file
/// where a folder is needed, is bad input).
pub fn list_folder(dir: &Path) -> Result<FolderListing> {
    let rd = std::fs::read_dir(dir).map_err(|e| IoError::io(dir, e))?;
    let mut out = FolderListing::default();
    for entry in rd {
        let entry = entry.map_err(|e| IoError::io(dir, e))?;
        let path = entry.path();
        let hidden = entry.file_name().to_string_lossy().starts_with('.');
        if hidden {
            continue;
        }
        if path.is_dir() {
            out.dirs.push(path);
        } else if path.is_file() && is_image_file(&path) {
            out.images.push(path);
        } else {
            out.others.push(path);
        }
    }
    out.dirs.sort();
    out.images.sort();
    out.others.sort();
    Ok(out)
}

/// Width and height of a PNG or TIFF file, from its header only.
///
/// Errors: [`IoError::Image`] for a file that is not a readable PNG or TIFF.
pub fn image_size(path: &Path) -> Result<[usize; 2]> {
    let bad = |why: String| IoError::Image {
        path: path.to_path_buf(),
        reason: why,
    };
    let f = File::open(path).map_err(|e| IoError::io(path, e))?;
    let mut r = BufReader::new(f);
    let mut head = [0u8; 8];
    r.read_exact(&mut head)
        .map_err(|_| bad("is not a PNG or TIFF image".into()))?;
    let f = File::open(path).map_err(|e| IoError::io(path, e))?;
    if head.starts_with(b"\x89PNG\r\n\x1a\n") {
        let dec = png::Decoder::new(BufReader::new(f));
        let reader = dec
            .read_info()
            .map_err(|e| bad(format!("truncated or corrupt PNG: {e}")))?;
        let info = reader.info();
        Ok([info.width as usize, info.height as usize])
    } else if is_image_file(path) {
        let mut dec = tiff::decoder::Decoder::new(BufReader::new(f))
            .map_err(|e| bad(format!("truncated or corrupt TIFF: {e}")))?;
        let (w, h) = dec
            .dimensions()
            .map_err(|e| bad(format!("truncated or corrupt TIFF: {e}")))?;
        Ok([w as usize, h as usize])
    } else {
        Err(bad("is not a PNG or TIFF image".into()))
    }
}

/// What one frame's values say about the sensor.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameStats {
    /// The file.
    pub path: PathBuf,
    /// Width (columns).
    pub width: usize,
    /// Height (rows).
    pub height: usize,
    /// Sample type as stored.
    pub kind: SampleKind,
    /// The largest value the file records for its samples
    /// ([`Frame::recorded_max`](crate::image::Frame::recorded_max): PNG `sBIT`, TIFF
    /// `MaxSampleValue`), if it records one.
    pub recorded_max: Option<f32>,
    /// Largest value (NaN-free; `-inf` for an all-NaN float frame).
    pub max: f32,
    /// Smallest value.
    pub min: f32,
    /// Mean value.
    pub mean: f64,
    /// Pixels at the largest value.
    pub at_max: usize,
    /// For integer frames: how many low bits are zero in every pixel (0 … 16; 16 when
    /// every pixel is 0).
    pub zero_low_bits: u32,
    /// Mean of each pixel of the 2×2 super-pixel over the frame, row by row from the
    /// top-left (for telling a polarization mosaic).
    pub quad_means: [f64; 4],
}

/// Read a frame and its [`FrameStats`].
///
/// Errors: those of [`read_frame`] (not an image, colour, several pages, too large, ...).
pub fn frame_stats(path: &Path) -> Result<FrameStats> {
    let frame = read_frame(path)?;
    let (mut max, mut min, mut sum, mut or_bits) = (f32::NEG_INFINITY, f32::INFINITY, 0.0f64, 0u32);
    let mut quad = [0.0f64; 4];
    let mut quad_n = [0usize; 4];
    for (i, &v) in frame.data.iter().enumerate() {
        if !v.is_finite() {
            continue;
        }
        max = max.max(v);
        min = min.min(v);
        sum += f64::from(v);
        if frame.kind.is_integer() {
            or_bits |= v as u32;
        }
        let (y, x) = (i / frame.width.max(1), i % frame.width.max(1));
        let q = (y % 2) * 2 + (x % 2);
        quad[q] += f64::from(v);
        quad_n[q] += 1;
    }
    let at_max = frame.data.iter().filter(|&&v| v == max).count();
    let n = frame.data.len().max(1);
    for (q, c) in quad.iter_mut().zip(quad_n) {
        *q /= c.max(1) as f64;
    }
    Ok(FrameStats {
        path: path.to_path_buf(),
        width: frame.width,
        height: frame.height,
        kind: frame.kind,
        recorded_max: frame.recorded_max,
        max,
        min,
        mean: sum / n as f64,
        at_max,
        zero_low_bits: if or_bits == 0 {
            16
        } else {
            or_bits.trailing_zeros()
        },
        quad_means: quad,
    })
}

/// A sensor bit depth inferred from frames, and the saturation level it implies.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorDepth {
    /// Bits of the sensor's ADC (`None` for float frames).
    pub bits: Option<u8>,
    /// Bits of the stored sample type (8, 16, 32).
    pub stored_bits: u8,
    /// Low bits the values are shifted by (a 12-bit sensor stored in the top of 16 bits:
    /// 4).
    pub shift: u32,
    /// The saturation level, DN: `(2^bits − 1) · 2^shift` (`None` for float frames).
    pub saturation: Option<f64>,
    /// How it was found, one sentence.
    pub evidence: String,
}

impl SensorDepth {
    /// Infer the sensor's depth from the statistics of all frames (of one sample type):
    /// a PNG `sBIT` chunk decides; else 8-bit files are 8 bits; else the low bits that
    /// are zero in every pixel give the shift and the largest value the bits (the
    /// smallest of 8, 10, 12, 14, 16 that holds it).
    pub fn infer(stats: &[FrameStats]) -> SensorDepth {
        let kind = stats.first().map_or(SampleKind::U16, |s| s.kind);
        let stored_bits = kind.bit_depth();
        let max = stats
            .iter()
            .map(|s| s.max)
            .fold(f32::NEG_INFINITY, f32::max);
        if !kind.is_integer() {
            return SensorDepth {
                bits: None,
                stored_bits,
                shift: 0,
                saturation: None,
                evidence: format!(
                    "float frames (largest value {max}): no saturation level can be read \
                     from them"
                ),
            };
        }
        if let Some(rec) = stats.iter().find_map(|s| s.recorded_max) {
            // The file's own record decides: the level `measure` takes by default.
            let bits = (f64::from(rec) + 1.0).log2();
            let whole = (bits.fract() == 0.0).then_some(bits as u8);
            let over = if max > rec {
                format!(
                    "; but values reach {max}, above it (data shifted to the top bits? give                      the saturation level in the manifest)"
                )
            } else {
                String::new()
            };
            return SensorDepth {
                bits: whole.or_else(|| {
                    [8u8, 10, 12, 14, 16]
                        .into_iter()
                        .find(|&b| f64::from(rec) < (1u64 << b) as f64)
                }),
                stored_bits,
                shift: 0,
                saturation: Some(f64::from(rec)),
                evidence: match whole {
                    Some(b) => format!(
                        "the file records {b} significant bits of {stored_bits} (largest value                          {rec}){over}"
                    ),
                    None => format!(
                        "the file records a largest sample value of {rec} (of {stored_bits}                          bits){over}"
                    ),
                },
            };
        }
        if stored_bits == 8 {
            return SensorDepth {
                bits: Some(8),
                stored_bits,
                shift: 0,
                saturation: Some(255.0),
                evidence: format!("8-bit files (largest value {max})"),
            };
        }
        let zero_low = stats.iter().map(|s| s.zero_low_bits).min().unwrap_or(0);
        // A shift only counts when the values span enough levels to show it.
        let shift = if (2..16).contains(&zero_low) && max >= 1024.0 {
            zero_low.min(8)
        } else {
            0
        };
        let top = (max as u64) >> shift;
        let bits = [8u8, 10, 12, 14, 16]
            .into_iter()
            .find(|&b| top < (1u64 << b))
            .unwrap_or(16);
        let bits = bits.min(stored_bits.saturating_sub(shift as u8).max(8));
        let sat = ((1u64 << bits) - 1) << shift;
        let at_max: usize = stats.iter().map(|s| s.at_max).sum();
        let evidence = if shift > 0 {
            format!(
                "{stored_bits}-bit files whose values are all multiples of {} (a {bits}-bit \
                 sensor stored in the top bits), largest value {max}",
                1u64 << shift
            )
        } else {
            format!(
                "{stored_bits}-bit files whose largest value is {max} ({at_max} pixels at \
                 it): taken as a {bits}-bit sensor"
            )
        };
        SensorDepth {
            bits: Some(bits),
            stored_bits,
            shift,
            saturation: Some(sat as f64),
            evidence,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stats(kind: SampleKind, max: f32, zero_low_bits: u32, sbit: Option<u8>) -> FrameStats {
        let recorded_max = sbit.and_then(|b| crate::image::recorded_max_of_bits(kind, b));
        FrameStats {
            path: PathBuf::from("f.png"),
            width: 4,
            height: 4,
            kind,
            recorded_max,
            max,
            min: 0.0,
            mean: max as f64 / 2.0,
            at_max: 1,
            zero_low_bits,
            quad_means: [0.0; 4],
        }
    }

    #[test]
    fn bit_depth_from_values_shift_and_sbit() {
        let d = SensorDepth::infer(&[stats(SampleKind::U8, 200.0, 0, None)]);
        assert_eq!((d.bits, d.saturation), (Some(8), Some(255.0)));
        let d = SensorDepth::infer(&[stats(SampleKind::U16, 4095.0, 0, None)]);
        assert_eq!((d.bits, d.saturation), (Some(12), Some(4095.0)));
        let d = SensorDepth::infer(&[stats(SampleKind::U16, 3000.0, 0, None)]);
        assert_eq!((d.bits, d.saturation), (Some(12), Some(4095.0)));
        let d = SensorDepth::infer(&[stats(SampleKind::U16, 900.0, 0, None)]);
        assert_eq!((d.bits, d.saturation), (Some(10), Some(1023.0)));
        // 12 bits in the top of 16: multiples of 16.
        let d = SensorDepth::infer(&[stats(SampleKind::U16, 65520.0, 4, None)]);
        assert_eq!(
            (d.bits, d.shift, d.saturation),
            (Some(12), 4, Some(65520.0))
        );
        // A recorded depth decides.
        let d = SensorDepth::infer(&[stats(SampleKind::U16, 1000.0, 0, Some(12))]);
        assert_eq!((d.bits, d.saturation), (Some(12), Some(4095.0)));
        assert!(
            d.evidence.contains("records 12 significant bits"),
            "{}",
            d.evidence
        );
        let d = SensorDepth::infer(&[stats(SampleKind::F32, 1.5, 0, None)]);
        assert_eq!(d.saturation, None);
    }
}
