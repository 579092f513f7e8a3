//! Grayscale frames (PNG, TIFF) in, float32 TIFF and 8/16-bit PNG/TIFF out.
//!
//! Readers accept single-page grayscale images: PNG of 8 or 16 bits, TIFF of 8 or 16
//! bit unsigned integers or 32-bit (also 64-bit) IEEE floats. The file type is found from
//! its first bytes, not its name. Everything else — colour, alpha, palettes, several
//! pages, other bit depths, truncated or corrupt files — is an [`IoError::Image`] naming
//! the file and saying what is wrong. Pixel values are returned as `f32` (exact for 8-
//! and 16-bit integers), row-major, with the sample type and the largest value the
//! file says its samples can take ([`Frame::recorded_max`]) so that callers know the
//! default saturation level ([`Frame::level_max`]).
//!
//! **Bit depth.** A 12-bit sensor's data is stored in 16-bit samples. The file can say
//! so: a PNG's `sBIT` chunk (significant bits, e.g. 12: largest value 4095) or a TIFF's
//! `MaxSampleValue` tag (281, e.g. 4095). Without either, the PNG and TIFF
//! specifications make every stored bit significant (16-bit samples: 65535), and
//! nothing in the file tells a 12-bit camera's data from a 16-bit one's.
//! [`write_gray16_bits`] records the bit depth when writing.
//!
//! Reading is bounded ([`crate::limits`]): the file must be a regular file no larger
//! than the memory budget, and before any pixel is decoded the frame's cost —
//! `pixels × (stored bytes per sample + 4 × frames in flight + the command's bytes per
//! pixel)` — must fit in the budget, and a compressed frame must not expand more than
//! [`MAX_EXPANSION`](crate::limits::MAX_EXPANSION) times (decompression bombs).
//!
//! Writers are atomic ([`crate::atomic::write_atomic`]): the image is encoded in memory
//! and renamed into place only when complete. Inside a [`crate::atomic::StagedDir`]
//! pass the staged path.

use std::borrow::Cow;
use std::io::Cursor;
use std::path::{Path, PathBuf};

use crate::atomic::write_atomic;
use crate::error::{IoError, Result};
use crate::limits;
use tiff::encoder::TiffValue;
use tiff::encoder::colortype::{self as tiff_color, ColorType};

/// The sample type of a frame as stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SampleKind {
    /// 8-bit unsigned integers.
    U8,
    /// 16-bit unsigned integers.
    U16,
    /// 32-bit IEEE floats (64-bit float TIFFs are read as this too).
    F32,
}

impl SampleKind {
    /// Bits per sample as stored (64-bit float TIFFs report 32).
    pub fn bit_depth(self) -> u8 {
        match self {
            SampleKind::U8 => 8,
            SampleKind::U16 => 16,
            SampleKind::F32 => 32,
        }
    }

    /// Largest representable value: 255, 65535, or `+inf` for floats.
    pub fn type_max(self) -> f32 {
        match self {
            SampleKind::U8 => 255.0,
            SampleKind::U16 => 65535.0,
            SampleKind::F32 => f32::INFINITY,
        }
    }

    /// True for the integer types.
    pub fn is_integer(self) -> bool {
        !matches!(self, SampleKind::F32)
    }
}

/// One grayscale frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// The file it was read from.
    pub path: PathBuf,
    /// Width (columns).
    pub width: usize,
    /// Height (rows).
    pub height: usize,
    /// Sample type as stored.
    pub kind: SampleKind,
    /// Pixel values, row-major, `width × height`.
    pub data: Vec<f32>,
    /// The largest value the file says its samples can take when it is below the
    /// type's maximum: `2^bits − 1` from a PNG's `sBIT` chunk, or a TIFF's
    /// `MaxSampleValue` tag (module docs); `None` when the file records no bit depth
    /// (or the full one).
    pub recorded_max: Option<f32>,
}

impl Frame {
    /// Largest value of the stored type ([`SampleKind::type_max`]).
    pub fn type_max(&self) -> f32 {
        self.kind.type_max()
    }

    /// Largest value the samples can take: [`Frame::recorded_max`] when the file
    /// records a bit depth, else the type's maximum (the default saturation level).
    pub fn level_max(&self) -> f32 {
        self.recorded_max.unwrap_or_else(|| self.type_max())
    }

    /// Largest sample value of the frame (NaN samples ignored; `-inf` for none).
    pub fn data_max(&self) -> f32 {
        self.data.iter().copied().fold(f32::NEG_INFINITY, f32::max)
    }

    /// Bits per sample as stored.
    pub fn bit_depth(&self) -> u8 {
        self.kind.bit_depth()
    }
}

fn image_err(path: &Path, reason: impl Into<String>) -> IoError {
    IoError::Image {
        path: path.to_path_buf(),
        reason: reason.into(),
    }
}

/// Largest frame the readers accept, in pixels (2^28, e.g. 16384 x 16384): a decoded
/// frame of this size holds 1 GiB of `f32`. A header announcing more is refused before
/// anything is allocated, so a corrupt or hostile file cannot exhaust memory.
pub const MAX_PIXELS: u64 = 1 << 28;

/// Read a grayscale PNG or TIFF frame (a regular file within the memory budget, see
/// the module documentation).
pub fn read_frame(path: &Path) -> Result<Frame> {
    read_frame_in_flight(path, 1)
}

/// [`read_frame`] for one of `in_flight` frames that will be held in memory together.
fn read_frame_in_flight(path: &Path, in_flight: u64) -> Result<Frame> {
    let bytes = limits::read_capped(path, limits::memory_limit(), "image")?;
    let lim = Limits {
        max_pixels: MAX_PIXELS,
        in_flight,
    };
    decode(path, &bytes, lim)
}

/// Decode a grayscale PNG or TIFF frame held in memory; `path` labels errors and is
/// recorded in the frame. Same rules as [`read_frame`], with a caller-chosen limit on the
/// number of pixels (fuzzing uses a small one to keep each run fast).
pub fn decode_frame_limited(path: &Path, bytes: &[u8], max_pixels: u64) -> Result<Frame> {
    decode(
        path,
        bytes,
        Limits {
            max_pixels,
            in_flight: 1,
        },
    )
}

/// What a decode may use.
#[derive(Debug, Clone, Copy)]
struct Limits {
    /// Largest frame, in pixels.
    max_pixels: u64,
    /// Frames of this size held in memory together (the frames of one capture).
    in_flight: u64,
}

impl Limits {
    /// Error unless a `w × h` frame of `stored` bytes per sample, decoded from a file of
    /// `file_len` bytes, fits the memory budget and is no decompression bomb.
    fn check(self, path: &Path, w: u32, h: u32, stored: u64, file_len: u64) -> Result<()> {
        let px = u64::from(w) * u64::from(h);
        let decoded = px.saturating_mul(stored);
        if decoded > limits::EXPANSION_FLOOR && decoded / file_len.max(1) > limits::MAX_EXPANSION {
            return Err(image_err(
                path,
                format!(
                    "would decode {w}x{h} pixels ({}) from a {}-byte file, an expansion of \
                     {}:1, more than the {}:1 of any real image: refused as a decompression \
                     bomb",
                    limits::human(decoded),
                    file_len,
                    decoded / file_len.max(1),
                    limits::MAX_EXPANSION
                ),
            ));
        }
        let per_pixel = stored + 4 * self.in_flight + limits::work_per_pixel();
        let frames = if self.in_flight > 1 {
            format!(" ({} frames of it)", self.in_flight)
        } else {
            String::new()
        };
        limits::check_budget(
            path,
            &format!("decoding and processing this {w}x{h} frame{frames}"),
            px.saturating_mul(per_pixel).saturating_add(file_len),
        )
    }
}

fn decode(path: &Path, bytes: &[u8], lim: Limits) -> Result<Frame> {
    if bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
        read_png(path, bytes, lim)
    } else if bytes.starts_with(b"II*\0")
        || bytes.starts_with(b"MM\0*")
        || bytes.starts_with(b"II+\0")
        || bytes.starts_with(b"MM\0+")
    {
        read_tiff(path, bytes, lim)
    } else if bytes.is_empty() {
        Err(image_err(path, "is empty (expected a PNG or TIFF image)"))
    } else {
        Err(image_err(path, "is not a PNG or TIFF image"))
    }
}

/// Error unless a `w x h` frame is within `max_pixels` and not empty.
fn check_dims(path: &Path, w: u32, h: u32, max_pixels: u64) -> Result<()> {
    if w == 0 || h == 0 {
        return Err(image_err(path, format!("has no pixels ({w}x{h})")));
    }
    let n = u64::from(w) * u64::from(h);
    if n > max_pixels {
        return Err(image_err(
            path,
            format!(
                "is {w}x{h} = {n} pixels, more than the {max_pixels} a frame may have \
                 (corrupt header?)"
            ),
        ));
    }
    Ok(())
}

fn read_png(path: &Path, bytes: &[u8], lim: Limits) -> Result<Frame> {
    let max_pixels = lim.max_pixels;
    let corrupt = |e: png::DecodingError| image_err(path, format!("truncated or corrupt PNG: {e}"));
    let mut dec = png::Decoder::new(Cursor::new(bytes));
    // The decoder's own limit (64 MiB by default) would refuse large 16-bit frames
    // with a confusing message; the size is checked against `max_pixels` instead.
    dec.set_limits(png::Limits {
        bytes: usize::try_from(max_pixels.saturating_mul(2)).unwrap_or(usize::MAX),
    });
    let mut reader = dec.read_info().map_err(corrupt)?;
    let info = reader.info();
    check_dims(path, info.width, info.height, max_pixels)?;
    let (w, h) = (info.width as usize, info.height as usize);
    let depth = info.bit_depth;
    // sBIT of a grayscale image: one byte, the significant bits (1..=bit depth).
    let sbit = info.sbit.as_deref().and_then(|b| b.first().copied());
    match info.color_type {
        png::ColorType::Grayscale => {}
        png::ColorType::GrayscaleAlpha => return Err(alpha_err(path)),
        other => return Err(colour_err(path, other)),
    }
    if info.is_animated() {
        return Err(image_err(
            path,
            "is an animated PNG with several frames; one image per file is needed",
        ));
    }
    let kind = match depth {
        png::BitDepth::Eight => SampleKind::U8,
        png::BitDepth::Sixteen => SampleKind::U16,
        other => {
            return Err(image_err(
                path,
                format!(
                    "has {} bits per sample; 8- or 16-bit grayscale is needed",
                    other as u8
                ),
            ));
        }
    };
    let stored = u64::from(kind.bit_depth() / 8);
    lim.check(path, info.width, info.height, stored, bytes.len() as u64)?;
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| image_err(path, "is too large to decode"))?;
    let mut buf = vec![0u8; size];
    let out = reader.next_frame(&mut buf).map_err(corrupt)?;
    // ok: the decoder never reports more than the buffer it was given.
    let buf = buf.get(..out.buffer_size()).unwrap_or(&buf);
    let data: Vec<f32> = match kind {
        SampleKind::U8 => buf.iter().map(|&v| v as f32).collect(),
        _ => buf
            .chunks_exact(2)
            .map(|c| u16::from_be_bytes([c[0], c[1]]) as f32) // ok: chunks of exactly 2
            .collect(),
    };
    let recorded_max = sbit.and_then(|b| recorded_max_of_bits(kind, b));
    decoded_frame(path, w, h, kind, data, recorded_max)
}

fn read_tiff(path: &Path, bytes: &[u8], lim: Limits) -> Result<Frame> {
    let max_pixels = lim.max_pixels;
    use tiff::decoder::{Decoder, DecodingResult};
    let corrupt = |e: tiff::TiffError| match e {
        tiff::TiffError::UnsupportedError(u) => {
            image_err(path, format!("unsupported TIFF variant: {u}"))
        }
        other => image_err(path, format!("truncated or corrupt TIFF: {other}")),
    };
    // 8 bytes per pixel covers 64-bit float samples; the frame size itself is checked
    // against `max_pixels` before decoding.
    let budget = usize::try_from(max_pixels.saturating_mul(8)).unwrap_or(usize::MAX);
    let mut limits = tiff::decoder::Limits::default();
    limits.decoding_buffer_size = budget;
    limits.intermediate_buffer_size = budget;
    limits.ifd_value_size = budget.min(64 << 20);
    let mut dec = Decoder::new(Cursor::new(bytes))
        .map_err(corrupt)?
        .with_limits(limits);
    let (w, h) = dec.dimensions().map_err(corrupt)?;
    check_dims(path, w, h, max_pixels)?;
    let (w, h) = (w as usize, h as usize);
    match dec.colortype().map_err(corrupt)? {
        tiff::ColorType::Gray(b @ (8 | 16 | 32 | 64)) => {
            // ok: w, h were checked to fit in u32 by the decoder.
            lim.check(
                path,
                w as u32,
                h as u32,
                u64::from(b / 8),
                bytes.len() as u64,
            )?;
        }
        tiff::ColorType::Gray(b) => {
            return Err(image_err(
                path,
                format!(
                    "has {b} bits per sample; 8/16-bit integer or 32-bit float grayscale is needed"
                ),
            ));
        }
        tiff::ColorType::GrayA(_) => return Err(alpha_err(path)),
        other => return Err(colour_err(path, other)),
    }
    if dec.more_images() {
        let mut pages = 1usize;
        while dec.more_images() && pages < 10_000 {
            if dec.next_image().is_err() {
                break;
            }
            pages += 1;
        }
        return Err(image_err(
            path,
            format!("is a multi-page TIFF ({pages} pages); one image per file is needed"),
        ));
    }
    // MaxSampleValue (281): the largest value of the samples, when recorded.
    let max_sample: Option<u32> = dec
        .find_tag_unsigned(tiff::tags::Tag::MaxSampleValue)
        .ok()
        .flatten();
    let (kind, data) = match dec.read_image().map_err(corrupt)? {
        DecodingResult::U8(v) => (SampleKind::U8, v.into_iter().map(|x| x as f32).collect()),
        DecodingResult::U16(v) => (SampleKind::U16, v.into_iter().map(|x| x as f32).collect()),
        DecodingResult::F32(v) => (SampleKind::F32, v),
        DecodingResult::F64(v) => (SampleKind::F32, v.into_iter().map(|x| x as f32).collect()),
        _ => {
            return Err(image_err(
                path,
                "has a sample format other than unsigned 8/16-bit integers or floats",
            ));
        }
    };
    let recorded_max = max_sample
        .filter(|_| kind.is_integer())
        .map(|v| v as f32)
        .filter(|&v| v > 0.0 && v < kind.type_max());
    decoded_frame(path, w, h, kind, data, recorded_max)
}

/// The error for a frame with an alpha channel.
fn alpha_err(path: &Path) -> IoError {
    image_err(
        path,
        "is a grayscale image with an alpha channel; frames must be plain grayscale",
    )
}

/// The error for a colour frame (`color`: the decoder's colour type).
fn colour_err(path: &Path, color: impl std::fmt::Debug) -> IoError {
    image_err(
        path,
        format!("is a colour image ({color:?}); frames must be grayscale"),
    )
}

/// The decoded frame, or an error unless `data` holds `w × h` samples.
fn decoded_frame(
    path: &Path,
    w: usize,
    h: usize,
    kind: SampleKind,
    data: Vec<f32>,
    recorded_max: Option<f32>,
) -> Result<Frame> {
    if data.len() != w * h || w == 0 || h == 0 {
        return Err(image_err(
            path,
            format!(
                "decoded {} samples for a {w}x{h} image (truncated or corrupt)",
                data.len()
            ),
        ));
    }
    Ok(Frame {
        path: path.to_path_buf(),
        width: w,
        height: h,
        kind,
        data,
        recorded_max,
    })
}

/// Read several frames of one capture and check that they have the same size and sample
/// type (the error names the first file that differs from the first frame, and both
/// sizes or types).
///
/// The memory budget is checked for all the frames together.
pub fn read_frames<P: AsRef<Path>>(paths: &[P]) -> Result<Vec<Frame>> {
    let mut out: Vec<Frame> = Vec::with_capacity(paths.len());
    for p in paths {
        let f = read_frame_in_flight(p.as_ref(), paths.len() as u64)?;
        if let Some(first) = out.first() {
            check_same_size(first, &f)?;
            check_same_kind(first, &f)?;
        }
        out.push(f);
    }
    Ok(out)
}

fn kind_name(k: SampleKind) -> &'static str {
    match k {
        SampleKind::U8 => "8-bit integer",
        SampleKind::U16 => "16-bit integer",
        SampleKind::F32 => "floating-point",
    }
}

/// Error unless `other` has the sample type of `first` (mixing types in one capture
/// would mix saturation levels and scales).
pub fn check_same_kind(first: &Frame, other: &Frame) -> Result<()> {
    if first.kind != other.kind {
        return Err(image_err(
            &other.path,
            format!(
                "has {} samples but {} has {} samples: the frames of one capture must have \
                 the same type",
                kind_name(other.kind),
                first.path.display(),
                kind_name(first.kind)
            ),
        ));
    }
    Ok(())
}

/// Error unless `frame` holds floating-point samples (Stokes images, which can be
/// negative, are float TIFFs).
pub fn check_float(frame: &Frame, what: &str) -> Result<()> {
    if frame.kind != SampleKind::F32 {
        return Err(image_err(
            &frame.path,
            format!(
                "has {} samples; {what} must be a 32-bit float TIFF",
                kind_name(frame.kind)
            ),
        ));
    }
    Ok(())
}

/// Error unless `other` has the size of `first`.
pub fn check_same_size(first: &Frame, other: &Frame) -> Result<()> {
    if (first.width, first.height) != (other.width, other.height) {
        return Err(image_err(
            &other.path,
            format!(
                "is {}x{} pixels but {} is {}x{}: the frames of one capture must have the same size",
                other.width,
                other.height,
                first.path.display(),
                first.width,
                first.height
            ),
        ));
    }
    Ok(())
}

fn check_buf(path: &Path, width: usize, height: usize, len: usize) -> Result<(u32, u32)> {
    if width == 0 || height == 0 || width * height != len {
        return Err(image_err(
            path,
            format!("cannot write {len} samples as a {width}x{height} image"),
        ));
    }
    let w = u32::try_from(width).map_err(|_| image_err(path, "image too wide"))?;
    let h = u32::try_from(height).map_err(|_| image_err(path, "image too tall"))?;
    Ok((w, h))
}

/// The TIFF bytes of a `w × h` image, with a `MaxSampleValue` tag when `max_sample` is
/// given.
fn tiff_bytes<C>(
    path: &Path,
    (w, h): (u32, u32),
    data: &[C::Inner],
    max_sample: Option<u16>,
) -> Result<Vec<u8>>
where
    C: ColorType,
    [C::Inner]: TiffValue,
{
    let mut cur = Cursor::new(Vec::new());
    let enc_err = |e: tiff::TiffError| image_err(path, format!("cannot encode TIFF: {e}"));
    let mut enc = tiff::encoder::TiffEncoder::new(&mut cur).map_err(enc_err)?;
    let mut img = enc.new_image::<C>(w, h).map_err(enc_err)?;
    if let Some(v) = max_sample {
        img.encoder()
            .write_tag(tiff::tags::Tag::MaxSampleValue, v)
            .map_err(enc_err)?;
    }
    img.write_data(data).map_err(enc_err)?;
    Ok(cur.into_inner())
}

fn write_bytes(path: &Path, force: bool, bytes: &[u8]) -> Result<()> {
    write_atomic(path, force, |w| {
        w.write_all(bytes).map_err(|e| IoError::io(path, e))
    })
}

/// Write a float32 grayscale TIFF (Stokes, DoLP, AoLP images).
pub fn write_tiff_f32(
    path: &Path,
    force: bool,
    width: usize,
    height: usize,
    data: &[f32],
) -> Result<()> {
    let size = check_buf(path, width, height, data.len())?;
    let bytes = tiff_bytes::<tiff_color::Gray32Float>(path, size, data, None)?;
    write_bytes(path, force, &bytes)
}

/// True when `path`'s extension asks for TIFF (`.tif`, `.tiff`), false for PNG
/// (`.png`); an error otherwise.
fn wants_tiff(path: &Path) -> Result<bool> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    match ext.as_deref() {
        Some("tif" | "tiff") => Ok(true),
        Some("png") => Ok(false),
        _ => Err(image_err(
            path,
            "unknown image type: the file name must end in .png, .tif or .tiff",
        )),
    }
}

/// The PNG bytes of a `w × h` image, with an `sBIT` chunk (grayscale: one byte) when
/// `sbit` is given.
fn png_bytes(
    path: &Path,
    (w, h): (u32, u32),
    color: png::ColorType,
    depth: png::BitDepth,
    data: &[u8],
    sbit: Option<u8>,
) -> Result<Vec<u8>> {
    let enc_err = |e: png::EncodingError| image_err(path, format!("cannot encode PNG: {e}"));
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, w, h);
        enc.set_color(color);
        enc.set_depth(depth);
        let mut wr = enc.write_header().map_err(enc_err)?;
        if let Some(b) = sbit {
            wr.write_chunk(png::chunk::sBIT, &[b]).map_err(enc_err)?;
        }
        wr.write_image_data(data).map_err(enc_err)?;
        wr.finish().map_err(enc_err)?;
    }
    Ok(out)
}

/// A grayscale sample type of the PNG/TIFF writers (8 or 16 bits): its TIFF colour
/// type, PNG bit depth and PNG (big-endian) bytes.
trait GraySample: Copy {
    type Tiff: ColorType<Inner = Self>;
    const PNG_DEPTH: png::BitDepth;
    fn png_data(data: &[Self]) -> Cow<'_, [u8]>;
}

impl GraySample for u8 {
    type Tiff = tiff_color::Gray8;
    const PNG_DEPTH: png::BitDepth = png::BitDepth::Eight;
    fn png_data(data: &[u8]) -> Cow<'_, [u8]> {
        data.into()
    }
}

impl GraySample for u16 {
    type Tiff = tiff_color::Gray16;
    const PNG_DEPTH: png::BitDepth = png::BitDepth::Sixteen;
    fn png_data(data: &[u16]) -> Cow<'_, [u8]> {
        data.iter().flat_map(|v| v.to_be_bytes()).collect()
    }
}

/// Write a grayscale image as PNG or TIFF (from the file name's extension); `bits`
/// (significant bits, largest value) records the bit depth: a PNG `sBIT` chunk, a TIFF
/// `MaxSampleValue` tag.
fn write_gray<S: GraySample>(
    path: &Path,
    force: bool,
    (width, height): (usize, usize),
    data: &[S],
    bits: Option<(u8, u16)>,
) -> Result<()>
where
    [S]: TiffValue,
{
    let size = check_buf(path, width, height, data.len())?;
    let bytes = if wants_tiff(path)? {
        tiff_bytes::<S::Tiff>(path, size, data, bits.map(|b| b.1))?
    } else {
        let color = png::ColorType::Grayscale;
        let sbit = bits.map(|b| b.0);
        png_bytes(path, size, color, S::PNG_DEPTH, &S::png_data(data), sbit)?
    };
    write_bytes(path, force, &bytes)
}

/// Write an 8-bit grayscale image as PNG or TIFF (from the file name's extension).
pub fn write_gray8(
    path: &Path,
    force: bool,
    width: usize,
    height: usize,
    data: &[u8],
) -> Result<()> {
    write_gray(path, force, (width, height), data, None)
}

/// Write a 16-bit grayscale image as PNG or TIFF (from the file name's extension).
pub fn write_gray16(
    path: &Path,
    force: bool,
    width: usize,
    height: usize,
    data: &[u16],
) -> Result<()> {
    write_gray(path, force, (width, height), data, None)
}

/// The largest value of samples of type `kind` whose file records `bits` significant
/// bits (a PNG `sBIT` chunk): `2^bits − 1` (12 bits: 4095), the values counted from 0
/// as [`write_gray16_bits`] writes them; `None` when `bits` is 0 or not below the type's
/// (every stored bit significant: the type's maximum applies). The one rule for a
/// recorded bit depth: [`Frame::recorded_max`] and `polarid init`'s saturation level
/// ([`crate::frames_dir::SensorDepth`]) both come from it.
pub fn recorded_max_of_bits(kind: SampleKind, bits: u8) -> Option<f32> {
    (bits > 0 && bits < kind.bit_depth() && kind.is_integer()).then(|| ((1u32 << bits) - 1) as f32)
}

/// Write 16-bit grayscale samples holding `bits`-bit data (1..=16, e.g. 12 for a
/// 12-bit sensor) as PNG or TIFF (from the file name's extension), recording the bit
/// depth: a PNG `sBIT` chunk, a TIFF `MaxSampleValue` tag of `2^bits − 1` (module
/// docs), which readers return as [`Frame::recorded_max`].
///
/// Errors: `bits` outside 1..=16, a sample above `2^bits − 1`, and those of
/// [`write_gray16`].
pub fn write_gray16_bits(
    path: &Path,
    force: bool,
    width: usize,
    height: usize,
    data: &[u16],
    bits: u8,
) -> Result<()> {
    check_buf(path, width, height, data.len())?;
    if !(1..=16).contains(&bits) {
        return Err(image_err(
            path,
            format!("cannot record {bits} significant bits in 16-bit samples"),
        ));
    }
    let max = ((1u32 << bits) - 1) as u16;
    if let Some(v) = data.iter().find(|&&v| v > max) {
        return Err(image_err(
            path,
            format!("sample {v} does not fit in {bits} bits (at most {max})"),
        ));
    }
    write_gray(path, force, (width, height), data, Some((bits, max)))
}

/// Write an 8-bit RGB PNG (views, colour maps); `data` is `width × height × 3`.
pub fn write_rgb8_png(
    path: &Path,
    force: bool,
    width: usize,
    height: usize,
    data: &[u8],
) -> Result<()> {
    if data.len() != width * height * 3 {
        return Err(image_err(
            path,
            format!(
                "cannot write {} bytes as a {width}x{height} RGB image",
                data.len()
            ),
        ));
    }
    let size = check_buf(path, width, height, width * height)?;
    let (color, depth) = (png::ColorType::Rgb, png::BitDepth::Eight);
    let bytes = png_bytes(path, size, color, depth, data, None)?;
    write_bytes(path, force, &bytes)
}
