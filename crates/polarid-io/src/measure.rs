//! The measure pipeline shared by `polarid measure`, `polarid stokes` and the Python
//! bindings: capture files → Stokes images → region statistics → [`Measurement`] rows.
//!
//! - Rotating-polarizer frames: [`polarid_core::stokes::StokesSolver::compute`] with the capture's
//!   [`rules_for`] (dark level, saturation; default the type's maximum).
//! - DoFP mosaics: demosaiced by [`dofp_stokes`]; [`measure_manifest`] uses the bilinear
//!   reconstruction at full resolution (so that region rectangles are in raw pixel
//!   coordinates), not rounded, whose standard errors use the bilinear variance
//!   inflation ([`polarid_core::region::Sampling::BilinearDofp`]).
//! - Stokes captures (float TIFF) are used as they are: `dark_level` and `saturation` do
//!   not apply; pixels with `S0 <= 0` or non-finite values are rejected.
//!
//! For every region and capture a row holds the DoLP of the region's mean Stokes vector,
//! its standard error from the pixel scatter (`polarid_core::region`; an SE of 0, from
//! noiseless data, is left empty), the mean S0 divided by the capture's exposure, the
//! pixels used, rejected and saturated, and `beta` from the geometry (paper eq. 5).
//!
//! **Calibrated captures** (a `source` under a `[camera]`): every pixel of a region gets
//! its own `β`, `θi`, `θr`, `φ` and plane-of-incidence angle from
//! [`ViewGeometry::fill`] (the region's plane, the capture's source), and the row comes
//! from [`region_stats_local`]: the DoLP of the mean Stokes vector taken in each pixel's
//! plane-of-incidence frame, the S0-weighted mean geometry (`theta_i_deg`,
//! `theta_r_deg`, `phi_deg`, `beta_deg`) with `beta_sd_deg`, `aolp_deg` (image frame)
//! and `aolp_poi_deg` (from the plane of incidence; 90 for a single interface), and a
//! standard error from the scatter with the trend in β removed (docs/GEOMETRY.md).
//!
//! **HDR brackets** (a capture's `brackets`, [`hdr_images`]): the exposures are merged
//! per pixel before the Stokes solve: each pixel takes its values from the longest
//! exposure in which none of its raw values is saturated (for a DoFP mosaic: none of
//! the raw pixels of its 3×3 neighbourhood, which the bilinear demosaic uses), dark
//! subtracted and scaled by the exposure ratio to the longest exposure's DN. A pixel
//! saturated in every bracket is saturated. One bracket for all the polarizer angles of
//! a pixel keeps an error in the exposure ratios out of its DoLP.
//!
//! **Colour captures** (a `dofp` with `color`, docs/BANDS.md): a manifest with colour
//! captures is measured per band ([`measure_capture_bands`]): each colour mosaic is
//! reconstructed once into per-band Stokes images at full resolution
//! ([`crate::bands::capture_band_images`]) and every band gives one row per region with
//! `wavelength_nm`; the rules above (dark level, saturation, dark threshold, HDR
//! brackets, calibrated geometry) apply to each band.
//!
//! **Partial failure.** A region that is dark in a capture (its mean dark-subtracted S0
//! below the capture's dark threshold, [`dark_threshold_dn`]), or that has no usable
//! pixel there (all saturated, dark or invalid), gives a row with a [`RowStatus`] other
//! than `ok` and a reason instead of an error; `fit` skips such rows. With `strict`
//! ([`measure_manifest_with`]) the first such row is an error naming the region's
//! `rect`, as before.
//!
//! Nothing here prints: progress goes through a callback and saturation warnings are
//! returned as text ([`saturation_warnings`]) for the caller to show.

use polarid_core::CoreError;
use polarid_core::geometry::{self, GeometryMaps, PinholeCamera, Source, ViewGeometry};
use polarid_core::region::{Rect, RegionGeometry, RegionStats, region_stats, region_stats_local};

use crate::error::{IoError, Result};
use crate::manifest::{Capture, CaptureSource, Manifest, Region, SourceSpec};
use crate::table::measurements::{Measurement, RowStatus};

pub use crate::stokes_images::{
    DARK_FRACTION, Demosaic, FEW_BITS_MAX, StokesImages, capture_images, dark_threshold_dn,
    dofp_stokes, frames_stokes, hdr_images, read_stokes, rules_for, saturation_notes,
};

/// Fraction of a region's pixels above which [`saturation_warnings`] reports saturation
/// (1 %).
pub const SATURATED_WARN: f64 = 0.01;

/// The capture's scattering angle `beta` in degrees (paper eq. 5) from its
/// `theta_i_deg`, `theta_r_deg` and `phi_deg`.
pub fn beta_deg(c: &Capture) -> f64 {
    geometry::beta(
        c.theta_i_deg.to_radians(),
        c.theta_r_deg.to_radians(),
        c.phi_deg.to_radians(),
    )
    .to_degrees()
}

/// One row per region of `m` (in region order) for capture `c`: far-field or, for a
/// capture with a `source` (calibrated geometry), per-pixel geometry (module docs). In
/// a manifest with colour captures, one row per region per band of `c`
/// ([`measure_capture_bands`]).
///
/// Errors: those of [`capture_images`] and [`measure_images`].
pub fn measure_capture(m: &Manifest, c: &Capture) -> Result<Vec<Measurement>> {
    if has_colour(m) {
        return measure_capture_bands(m, c, false);
    }
    let img = capture_images(m, c)?;
    measure_images(m, c, &img)
}

/// One row per region of `m` (in region order) from `img`, the Stokes images of capture
/// `c` (as [`capture_images`] makes them); a dark region or one without a usable pixel
/// gives a row with its [`RowStatus`] and reason (module docs).
///
/// Errors: [`IoError::Manifest`] naming the region's `rect` (line, value) when it leaves
/// the frame, or (calibrated geometry) has a pixel whose ray misses its plane; the
/// reason names the capture, its first file and the frame size. A source below the
/// plane's horizon at some pixel of a region names the capture's `source` field and the
/// target.
pub fn measure_images(m: &Manifest, c: &Capture, img: &StokesImages) -> Result<Vec<Measurement>> {
    measure_images_with(m, c, img, false)
}

/// [`measure_images`]; with `strict`, a row that is not `ok` is an error instead (an
/// [`IoError::Manifest`] naming the region's `rect`, the capture and the reason).
pub fn measure_images_with(
    m: &Manifest,
    c: &Capture,
    img: &StokesImages,
    strict: bool,
) -> Result<Vec<Measurement>> {
    let first_file = first_file(c);
    let rect_err = |r: &Region, reason: String| {
        r.rect_error(
            &m.path,
            format!(
                "in capture {} (line {}, {first_file}, {}x{} pixels): {reason}",
                c.index, c.line, img.width, img.height
            ),
        )
    };
    let rows = region_rows(m, c, img, &rect_err)?;
    if strict && let Some((r, row)) = m.regions.iter().zip(&rows).find(|(_, x)| !x.status.is_ok()) {
        return Err(rect_err(r, format!("{}: {}", row.status, row.reason)));
    }
    Ok(rows)
}

/// The first file of capture `c` as shown in errors (empty when it has none).
fn first_file(c: &Capture) -> String {
    c.source
        .files()
        .first()
        .map(|p| p.display().to_string())
        .unwrap_or_default()
}

/// Pixel counts of `rect` (inside the image): valid, saturated, dark, invalid.
fn rect_counts(img: &StokesImages, rect: Rect) -> [u64; 4] {
    let mut cnt = [0u64; 4];
    for y in rect.y..rect.y + rect.height {
        let o = y * img.width;
        for m in img
            .mask
            .get(o + rect.x..o + rect.x + rect.width)
            .unwrap_or(&[])
        {
            cnt[(m & 3) as usize] += 1;
        }
    }
    cnt
}

/// The label of a capture in reasons: `capture 8 "L08"` or `capture 8`.
fn capture_label(c: &Capture) -> String {
    match &c.name {
        Some(n) => format!("capture {} {n:?}", c.index),
        None => format!("capture {}", c.index),
    }
}

/// The status of a region of capture `c` with pixel counts `cnt` (valid, saturated,
/// dark, invalid) and, when it has valid pixels, mean S0 `s0_dn` (DN, before the
/// exposure): `ok`, `dark` (mean S0 below `img.dark_signal_dn`), or for a region without
/// a usable pixel the most common reason of its rejections.
#[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN-safe on purpose
fn row_status(c: &Capture, img: &StokesImages, cnt: [u64; 4], s0_dn: f64) -> (RowStatus, String) {
    let [_, sat, dark, invalid] = cnt;
    let area: u64 = cnt.iter().sum();
    let cap = capture_label(c);
    if cnt[0] == 0 {
        let status = if sat >= dark && sat >= invalid {
            RowStatus::Saturated
        } else if dark >= invalid {
            RowStatus::Dark
        } else {
            RowStatus::Invalid
        };
        return (
            status,
            format!("{cap}: has no usable pixel ({sat} saturated, {dark} dark, {invalid} invalid)"),
        );
    }
    // `!(x >= t)`: a NaN mean is dark too.
    if img.dark_signal_dn > 0.0 && !(s0_dn >= img.dark_signal_dn) {
        return (
            RowStatus::Dark,
            format!(
                "{cap}: mean S0 {s0_dn:.3} DN is below the dark threshold {:.3} DN \
                 ({dark} of {area} pixels at or below the dark level); the DoLP of so \
                 low a signal is biased",
                img.dark_signal_dn
            ),
        );
    }
    (RowStatus::Ok, String::new())
}

/// The row of region `r` in capture `c` with its statistics `st` (`None`: no usable
/// pixel, the counts `cnt` only), status and reason; the capture's angles in the far
/// field (a calibrated capture's caller sets its per-region angles).
fn region_row(
    r: &Region,
    c: &Capture,
    st: Option<&RegionStats>,
    cnt: [u64; 4],
    status: (RowStatus, String),
    beta_deg: f64,
) -> Measurement {
    let far = c.illumination.is_none();
    Measurement {
        target: r.name.clone(),
        class: r.class.clone(),
        theta_i_deg: far.then_some(c.theta_i_deg),
        theta_r_deg: far.then_some(c.theta_r_deg),
        phi_deg: if far { c.phi_deg } else { f64::NAN },
        beta_deg,
        dolp: st.map_or(f64::NAN, |s| s.dolp),
        // Noiseless data have no scatter; an SE of 0 is left empty (the CSV contract
        // requires dolp_se > 0 when present).
        dolp_se: st
            .and_then(|s| s.dolp_se)
            .filter(|se| se.is_finite() && *se > 0.0),
        s0: st.map(|s| s.s0() / c.exposure),
        pixels: Some(st.map_or(0, |s| s.pixels)),
        rejected: Some(st.map_or(cnt[1] + cnt[2] + cnt[3], |s| s.rejected)),
        exposure: Some(c.exposure),
        saturated: Some(st.map_or(cnt[1], |s| s.saturated)),
        beta_sd_deg: None,
        aolp_deg: None,
        aolp_poi_deg: None,
        angle_sd_deg: c.angle_sd_deg,
        status: status.0,
        reason: status.1,
        wavelength_nm: c.wavelength_nm,
        reference: r.reference.clone(),
    }
}

/// The source of a capture as written in the manifest (`{ position = [..] }`, ...).
fn source_text(s: &SourceSpec) -> String {
    match s {
        SourceSpec::Position(p) => format!("{{ position = {p:?} }}"),
        SourceSpec::Direction(d) => format!("{{ direction = {d:?} }}"),
        SourceSpec::Sun { time, .. } => format!("{{ sun = {time:?} }}"),
    }
}

/// The per-pixel geometry of region `r` (its plane, `camera`) lit by `source`: five
/// maps over its rectangle, `[β | θi | θr | φ | ψ]`, radians.
///
/// Errors: [`IoError::Manifest`] naming the region's `rect` (a pixel whose ray misses
/// the plane) or, for a source below the plane's horizon at some pixel, the capture's
/// `source` field and the target.
fn region_geometry(
    m: &Manifest,
    c: &Capture,
    spec: &SourceSpec,
    camera: PinholeCamera,
    source: &Source,
    r: &Region,
    rect_err: &dyn Fn(&Region, String) -> IoError,
) -> Result<Vec<f64>> {
    let plane_spec = m.planes.get(r.plane);
    let plane_name = plane_spec.map_or("", |p| p.name.as_str());
    let vg = plane_spec
        .ok_or(CoreError::InvalidRegion {
            x: r.rect.x,
            y: r.rect.y,
            width: r.rect.width,
            height: r.rect.height,
            reason: format!("has no plane (index {})", r.plane),
        })
        .and_then(|p| p.to_plane())
        .and_then(|p| ViewGeometry::new(camera, p))
        .map_err(|e| rect_err(r, format!("{e} (plane {plane_name:?})")))?;
    let area = r.rect.width * r.rect.height;
    let mut maps = vec![0.0f64; 5 * area];
    let (beta, rest) = maps.split_at_mut(area);
    let (theta_i, rest) = rest.split_at_mut(area);
    let (theta_r, rest) = rest.split_at_mut(area);
    let (phi, poi) = rest.split_at_mut(area);
    let filled = vg.fill(
        r.rect,
        source,
        GeometryMaps {
            beta,
            theta_i,
            theta_r,
            phi,
            poi_angle: Some(poi),
        },
    );
    match filled {
        Ok(()) => Ok(maps),
        Err(e @ CoreError::SourceBelowHorizon { .. }) => Err(c.field_error(
            &m.path,
            &format!("source.{}", spec.key()),
            source_text(spec),
            format!(
                "for target {:?} (region[{}], plane {plane_name:?}): {e}",
                r.name, r.index
            ),
        )),
        Err(e) => Err(rect_err(
            r,
            format!("{e} (plane {plane_name:?}, source {})", source_text(spec)),
        )),
    }
}

/// The β (eq. 5, degrees) of every pixel of a `width × height` image lit by capture `c`
/// of `m`, row-major, each pixel on the plane of the first region whose rectangle holds
/// it (else the first plane); NaN where a pixel has no geometry (its ray misses the
/// plane, or the source is below the plane's horizon there). `None` for a far-field
/// capture (one β: [`beta_deg`]). For drawing a capture's geometry (`polarid.beta_map`).
///
/// Errors: [`IoError::Manifest`] naming `capture[j].source` when the manifest has no
/// camera or the camera is behind a plane that holds pixels.
pub fn beta_map(
    m: &Manifest,
    c: &Capture,
    width: usize,
    height: usize,
) -> Result<Option<Vec<f32>>> {
    let Some(spec) = &c.illumination else {
        return Ok(None);
    };
    let err = |e: CoreError| c.field_error(&m.path, "source", source_text(spec), e.to_string());
    let (camera, source) = camera_and_source(m, c, spec)?;
    let mut plane = vec![0usize; width * height];
    for r in m.regions.iter().rev() {
        for y in r.rect.y..(r.rect.y + r.rect.height).min(height) {
            for x in r.rect.x..(r.rect.x + r.rect.width).min(width) {
                plane[y * width + x] = r.plane;
            }
        }
    }
    // The geometry of each plane that holds pixels.
    let views = m.planes.iter().enumerate().map(|(i, p)| {
        let used = plane.contains(&i);
        let view = || p.to_plane().and_then(|p| ViewGeometry::new(camera, p));
        used.then(view).transpose().map_err(err)
    });
    let views = views.collect::<Result<Vec<_>>>()?;
    let mut out = vec![f32::NAN; width * height];
    for (i, (px, &pi)) in out.iter_mut().zip(&plane).enumerate() {
        let (u, v) = ((i % width) as f64, (i / width) as f64);
        if let Some(Ok(g)) = views
            .get(pi)
            .and_then(Option::as_ref)
            .map(|g| g.pixel(u, v, &source))
        {
            *px = g.beta.to_degrees() as f32;
        }
    }
    Ok(Some(out))
}

/// The camera of `m` and the resolved source `spec` of capture `c`; an error names the
/// capture's `source`.
fn camera_and_source(
    m: &Manifest,
    c: &Capture,
    spec: &SourceSpec,
) -> Result<(PinholeCamera, Source)> {
    let err = |reason: &str| c.field_error(&m.path, "source", source_text(spec), reason);
    let camera = m
        .camera
        .as_ref()
        .ok_or_else(|| err("a source needs a [camera] table"))?
        .to_camera();
    let source = spec
        .to_source()
        .ok_or_else(|| err("the source could not be resolved"))?;
    Ok((camera, source))
}

/// The rows of capture `c`, region by region: in the far field the region's statistics
/// at the capture's β; with a `source` (calibrated geometry), [`region_stats_local`] over
/// every pixel's own geometry ([`region_geometry`]).
fn region_rows(
    m: &Manifest,
    c: &Capture,
    img: &StokesImages,
    rect_err: &dyn Fn(&Region, String) -> IoError,
) -> Result<Vec<Measurement>> {
    let lit = match &c.illumination {
        Some(spec) => Some((spec, camera_and_source(m, c, spec)?)),
        None => None,
    };
    let far_beta_deg = if lit.is_some() { f64::NAN } else { beta_deg(c) };
    let (s0, s1, s2, mask) = (&img.s0, &img.s1, &img.s2, &img.mask);
    let mut rows = Vec::with_capacity(m.regions.len());
    for r in &m.regions {
        r.rect
            .check(img.width, img.height)
            .map_err(|e| rect_err(r, e.to_string()))?;
        let maps = match &lit {
            Some((spec, (camera, source))) => {
                Some(region_geometry(m, c, spec, *camera, source, r, rect_err)?)
            }
            None => None,
        };
        let cnt = rect_counts(img, r.rect);
        let stats_err = |e: CoreError| rect_err(r, e.to_string());
        rows.push(match maps {
            _ if cnt[0] == 0 => {
                let status = row_status(c, img, cnt, f64::NAN);
                region_row(r, c, None, cnt, status, far_beta_deg)
            }
            None => {
                let st = region_stats(img.width, s0, s1, s2, mask, r.rect, img.sampling)
                    .map_err(stats_err)?;
                let status = row_status(c, img, cnt, st.s0());
                region_row(r, c, Some(&st), cnt, status, far_beta_deg)
            }
            Some(maps) => {
                let area = r.rect.width * r.rect.height;
                let geom = RegionGeometry {
                    beta: &maps[..area],
                    theta_i: &maps[area..2 * area],
                    theta_r: &maps[2 * area..3 * area],
                    phi: &maps[3 * area..4 * area],
                    poi_angle: &maps[4 * area..],
                };
                let (w, sampling) = (img.width, img.sampling);
                let st = region_stats_local(w, s0, s1, s2, mask, r.rect, sampling, &geom)
                    .map_err(stats_err)?;
                let finite_deg = |x: f64| x.is_finite().then(|| x.to_degrees());
                let status = row_status(c, img, cnt, st.stats.s0());
                Measurement {
                    theta_i_deg: Some(st.theta_i.to_degrees()),
                    theta_r_deg: Some(st.theta_r.to_degrees()),
                    phi_deg: st.phi.to_degrees(),
                    beta_sd_deg: Some(st.beta_sd.to_degrees()),
                    aolp_deg: finite_deg(st.aolp),
                    aolp_poi_deg: finite_deg(st.aolp_poi),
                    ..region_row(r, c, Some(&st.stats), cnt, status, st.beta.to_degrees())
                }
            }
        });
    }
    Ok(rows)
}

/// Measure every region of every capture of a loaded manifest: one row per target per
/// capture, targets of capture 1 in region order, then capture 2, ... (the rows of
/// `polarid measure`). A manifest with colour captures gives one row per target per
/// capture per band ([`measure_capture_bands`]). Dark regions and regions without a
/// usable pixel give rows with a status and a reason ([`measure_manifest_with`] with
/// `strict` false).
///
/// Captures are processed one after the other (each one in parallel inside), so memory
/// holds one capture at a time; `progress` is called with the number of captures done
/// after each one.
///
/// Errors: those of [`measure_capture`], for the first capture that fails.
pub fn measure_manifest(m: &Manifest, progress: &mut dyn FnMut(usize)) -> Result<Vec<Measurement>> {
    measure_manifest_with(m, false, progress)
}

/// [`measure_manifest`]; with `strict`, the first row that is not `ok` (a dark region,
/// one without a usable pixel) stops it with an error naming the region's `rect`.
pub fn measure_manifest_with(
    m: &Manifest,
    strict: bool,
    progress: &mut dyn FnMut(usize),
) -> Result<Vec<Measurement>> {
    measure_manifest_report(m, strict, progress).map(|(rows, _)| rows)
}

/// [`measure_manifest_with`], with the warnings of the captures' images
/// ([`StokesImages::warnings`]: a saturation level the data contradict, a colour
/// mosaic's partial period dropped), in capture order.
///
/// Every capture must have the size of the first one (the regions' rectangles are in
/// one frame's pixel coordinates): a capture of another size is an [`IoError::Image`]
/// naming its first file, both captures and both sizes.
pub fn measure_manifest_report(
    m: &Manifest,
    strict: bool,
    progress: &mut dyn FnMut(usize),
) -> Result<(Vec<Measurement>, Vec<String>)> {
    let mut rows = Vec::with_capacity(m.captures.len() * m.regions.len());
    let mut warnings = Vec::new();
    let colour = has_colour(m);
    let mut first: Option<(&Capture, usize, usize)> = None;
    for (i, c) in m.captures.iter().enumerate() {
        if colour {
            check_band_wavelength(m, c)?;
            let bands = crate::bands::capture_band_images(m, c)?;
            if let Some(b) = bands.first() {
                check_capture_size(&mut first, c, b.images.width, b.images.height)?;
                warnings.extend(b.images.warnings.iter().cloned());
            }
            rows.extend(band_rows(m, c, &bands, strict)?);
        } else {
            let img = capture_images(m, c)?;
            check_capture_size(&mut first, c, img.width, img.height)?;
            warnings.extend(img.warnings.iter().cloned());
            rows.extend(measure_images_with(m, c, &img, strict)?);
        }
        progress(i + 1);
    }
    Ok((rows, warnings))
}

/// Error unless capture `c`'s images (`width × height`) have the size of the first
/// capture's (recorded in `first` by the first call).
fn check_capture_size<'a>(
    first: &mut Option<(&'a Capture, usize, usize)>,
    c: &'a Capture,
    width: usize,
    height: usize,
) -> Result<()> {
    let file_of = |c: &Capture| {
        c.files()
            .first()
            .map(|p| p.to_path_buf())
            .unwrap_or_default()
    };
    match first {
        None => {
            *first = Some((c, width, height));
            Ok(())
        }
        Some((c0, w0, h0)) if (*w0, *h0) != (width, height) => Err(IoError::Image {
            path: file_of(c),
            reason: format!(
                "capture {} (line {}) is {width}x{height} pixels but capture {} (line {}, \
                 {}) is {w0}x{h0}: every capture of a manifest must have the same size \
                 (the regions' rectangles are in one frame's pixel coordinates)",
                c.index,
                c.line,
                c0.index,
                c0.line,
                file_of(c0).display()
            ),
        }),
        Some(_) => Ok(()),
    }
}

/// Whether some capture of `m` is a colour capture ([`CaptureSource::ColourDofp`]): its
/// measurements are then per band, every row with a `wavelength_nm`.
pub fn has_colour(m: &Manifest) -> bool {
    m.captures
        .iter()
        .any(|c| matches!(c.source, CaptureSource::ColourDofp { .. }))
}

/// The number of bands capture `c` is measured in: the distinct colours of a colour
/// capture's pattern, else 1.
pub fn band_count(c: &Capture) -> usize {
    match &c.source {
        CaptureSource::ColourDofp { pattern, .. } => pattern.bands().len(),
        _ => 1,
    }
}

/// The rows of capture `c` of a manifest with colour captures: for each band of the
/// capture in increasing wavelength ([`crate::bands::capture_band_images`], the mosaic
/// read and reconstructed once), one row per region in region order, with
/// `wavelength_nm` the band's wavelength; a single-band capture gives its rows with its
/// own `wavelength_nm` (or the manifest's). The dark level, saturation, dark threshold,
/// HDR brackets and calibrated geometry apply to every band as to a monochrome capture;
/// the reasons of rows that are not `ok` name the band (`capture 2 band 450 nm: ...`).
///
/// Errors: those of [`measure_images_with`] (with `strict`, naming the band too);
/// [`IoError::Manifest`] naming `capture[i].wavelength_nm` for a single-band capture
/// without a wavelength (its rows could not be fitted with the colour captures' bands).
pub fn measure_capture_bands(m: &Manifest, c: &Capture, strict: bool) -> Result<Vec<Measurement>> {
    check_band_wavelength(m, c)?;
    let bands = crate::bands::capture_band_images(m, c)?;
    band_rows(m, c, &bands, strict)
}

/// [`measure_capture_bands`] of colour capture `c` (one exposure) from its raw mosaic
/// `raw` in memory ([`crate::bands::colour_frame_images`]).
///
/// Errors: those of [`measure_capture_bands`].
pub fn measure_colour_frame(
    m: &Manifest,
    c: &Capture,
    raw: crate::image::Frame,
) -> Result<Vec<Measurement>> {
    band_rows(m, c, &crate::bands::colour_frame_images(c, raw)?, false)
}

/// Error unless capture `c` of a manifest with colour captures can be measured per band:
/// a single-band capture needs a wavelength.
fn check_band_wavelength(m: &Manifest, c: &Capture) -> Result<()> {
    if !matches!(c.source, CaptureSource::ColourDofp { .. }) && c.wavelength_nm.is_none() {
        return Err(c.field_error(
            &m.path,
            "wavelength_nm",
            "",
            "a manifest with colour captures measures every capture per band: give \
                     this single-band capture its wavelength_nm (or the top-level one)",
        ));
    }
    Ok(())
}

/// The rows of capture `c` from its per-band images `bands` ([`measure_capture_bands`]).
fn band_rows(
    m: &Manifest,
    c: &Capture,
    bands: &[crate::bands::BandImages],
    strict: bool,
) -> Result<Vec<Measurement>> {
    check_band_wavelength(m, c)?;
    let label = capture_label(c);
    let mut rows = Vec::with_capacity(bands.len() * m.regions.len());
    for b in bands {
        let band_rows = measure_images_with(m, c, &b.images, false)?;
        let band = b.wavelength_nm.map_or_else(String::new, |w| {
            format!(" band {} nm", crate::manifest::colour::wavelength_label(w))
        });
        for (r, mut row) in m.regions.iter().zip(band_rows) {
            row.wavelength_nm = b.wavelength_nm;
            if !row.status.is_ok() {
                row.reason = row.reason.replacen(&label, &format!("{label}{band}"), 1);
                if strict {
                    let file = first_file(c);
                    return Err(r.rect_error(
                        &m.path,
                        format!(
                            "in capture {} (line {}, {file},{band}, {}x{} pixels): {}: {}",
                            c.index,
                            c.line,
                            b.images.width,
                            b.images.height,
                            row.status,
                            row.reason
                        ),
                    ));
                }
            }
            rows.push(row);
        }
    }
    Ok(rows)
}

/// One message per row of `rows` (as [`measure_manifest`] returned them for `m`) where
/// more than [`SATURATED_WARN`] of the region's area is saturated, naming the target,
/// the capture (index and line) and the fraction.
pub fn saturation_warnings(m: &Manifest, rows: &[Measurement]) -> Vec<String> {
    let per_band = m.regions.len().max(1);
    // The capture of every row: `regions × bands` rows per capture.
    let colour = has_colour(m);
    let capture_of: Vec<usize> = m
        .captures
        .iter()
        .enumerate()
        .flat_map(|(i, c)| {
            let bands = if colour { band_count(c) } else { 1 };
            std::iter::repeat_n(i, per_band * bands)
        })
        .collect();
    let mut out = Vec::new();
    for (i, r) in rows.iter().enumerate() {
        let (Some(sat), Some(px), Some(rej)) = (r.saturated, r.pixels, r.rejected) else {
            continue;
        };
        let area = px + rej;
        if area > 0 && sat as f64 > SATURATED_WARN * area as f64 {
            let cap = capture_of.get(i).and_then(|&j| m.captures.get(j));
            let band = r.wavelength_nm.map_or_else(String::new, |w| {
                format!(", band {} nm", crate::manifest::colour::wavelength_label(w))
            });
            out.push(format!(
                "target {:?}, capture {} (line {}){band}: {sat} of {area} pixels ({:.1}%) \
                 saturated and left out",
                r.target,
                cap.map_or(0, |c| c.index),
                cap.map_or(0, |c| c.line),
                100.0 * sat as f64 / area as f64
            ));
        }
    }
    out
}
