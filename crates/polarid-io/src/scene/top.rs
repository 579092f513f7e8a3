//! The top-level keys of a scene: name, frame size (at most [`MAX_SIDE`] pixels a side),
//! camera zenith `theta_r_deg`, `phi_deg`, the source zeniths `theta_i_deg` (a list or
//! `{ start, stop, step }`, at most 10000 positions), wavelength, background, seed and
//! image format; then the tables (`camera`, `plates`) and the assembled [`Scene`].

use toml::Spanned;

use super::colour::MaterialSource;
use super::context::Ctx;
use super::plates::PlateContext;
use super::raw::RawScene;
use super::{CaptureKind, Geometry, ImageFormat, MAX_SIDE, Plate, Scene};
use crate::error::{IoError, Result};

impl Ctx<'_> {
    fn theta_i(&self, v: &Spanned<toml::Value>) -> Result<Vec<f64>> {
        let field = "theta_i_deg";
        let span = v.span();
        let as_num = |x: &toml::Value| match x {
            toml::Value::Integer(i) => Some(*i as f64),
            toml::Value::Float(f) if f.is_finite() => Some(*f),
            _ => None,
        };
        let list: Vec<f64> = match v.get_ref() {
            toml::Value::Array(a) => {
                if a.len() > 10_000 {
                    return Err(self.err(
                        &span,
                        field,
                        format!("{} source positions, more than 10000", a.len()),
                    ));
                }
                let mut out = Vec::with_capacity(a.len());
                for x in a {
                    out.push(as_num(x).ok_or_else(|| {
                        self.err(&span, field, "expected an array of finite numbers")
                    })?);
                }
                out
            }
            toml::Value::Table(t) => {
                for k in t.keys() {
                    if !["start", "stop", "step"].contains(&k.as_str()) {
                        return Err(self.err(
                            &span,
                            field,
                            format!("unknown key `{k}` (expected start, stop, step)"),
                        ));
                    }
                }
                let get = |k: &str| {
                    t.get(k).and_then(as_num).ok_or_else(|| {
                        self.err(&span, &format!("{field}.{k}"), "expected a finite number")
                    })
                };
                let (a, b, s) = (get("start")?, get("stop")?, get("step")?);
                if s.is_nan() || s <= 0.0 || b < a {
                    return Err(self.err(&span, field, "need step > 0 and stop >= start"));
                }
                // Count in f64 and bound it before converting: a tiny step gives a count
                // beyond usize (the conversion saturates, and `+ 1` would overflow).
                let count = ((b - a) / s + 1e-9).floor() + 1.0;
                if !(count <= 10_000.0) {
                    return Err(self.err(&span, field, "more than 10000 source positions"));
                }
                (0..count as usize).map(|i| a + s * i as f64).collect()
            }
            other => {
                return Err(self.err(
                    &span,
                    field,
                    format!(
                        "expected an array of angles or {{ start, stop, step }}, found a {}",
                        other.type_str()
                    ),
                ));
            }
        };
        if list.is_empty() {
            return Err(self.err(&span, field, "at least one source position is needed"));
        }
        if let Some(bad) = list.iter().find(|x| !(0.0..90.0).contains(*x)) {
            return Err(self.err(
                &span,
                field,
                format!("source zenith {bad} is outside [0, 90) degrees"),
            ));
        }
        Ok(list)
    }

    pub(super) fn scene(&self) -> Result<Scene> {
        let raw: RawScene = toml::from_str(self.text).map_err(|e| {
            let span = e.span().unwrap_or(0..0);
            let msg = e.message().trim().to_string();
            IoError::Manifest {
                path: self.path.to_path_buf(),
                line: self.line(span.start),
                field: self.key_at(span.start, &msg),
                value: self.snippet(&span),
                reason: format!("invalid scene: {msg}"),
            }
        })?;
        let name = match &raw.name {
            Some(v) => Some(self.name(v, "name")?),
            None => None,
        };
        let width = self.side(&raw.width, "width")?;
        let height = self.side(&raw.height, "height")?;
        let wavelength_nm = match &raw.wavelength_nm {
            Some(v) => Some(self.num_in(v, "wavelength_nm", |x| x > 0.0, "> 0")?),
            None => None,
        };
        let background = match &raw.background {
            Some(v) => self.num_in(v, "background", |x| x >= 0.0, ">= 0")?,
            None => 0.0,
        };
        let seed = match &raw.seed {
            Some(v) if *v.get_ref() < 0 => {
                return Err(self.err(&v.span(), "seed", "must be a non-negative integer"));
            }
            Some(v) => *v.get_ref() as u64,
            None => 0,
        };
        let format = match &raw.format {
            None => ImageFormat::Png,
            Some(v) => match v.get_ref().to_ascii_lowercase().as_str() {
                "png" => ImageFormat::Png,
                "tif" | "tiff" => ImageFormat::Tiff,
                _ => return Err(self.err(&v.span(), "format", "must be \"png\" or \"tiff\"")),
            },
        };
        let sensor = self.sensor(raw.sensor.as_ref())?;
        let exposure = self.exposure(raw.exposure.as_ref())?;
        let capture = self.capture(
            raw.capture.as_ref(),
            raw.bands.as_ref(),
            raw.sensor.as_ref().and_then(|s| s.band_response.as_ref()),
        )?;
        if let (Some(w), Some(_)) = (&raw.wavelength_nm, capture.bands()) {
            return Err(self.err(
                &w.span(),
                "wavelength_nm",
                "a colour capture's wavelengths come from `bands` (default R 650, G 550, \
                 B 450 nm)",
            ));
        }
        self.check_mosaic_period(&raw, [width, height], &capture)?;
        let materials = MaterialSource {
            spec: raw.library.as_ref(),
            loaded: std::cell::OnceCell::new(),
        };
        let cx = PlateContext {
            bands: capture.bands(),
            wavelength_nm,
            materials: &materials,
        };
        let (geometry, plates) = if raw.camera.is_some() {
            let (c, plates) = self.calibrated(&raw, width, height, &cx)?;
            (Geometry::Calibrated(Box::new(c)), plates)
        } else {
            self.far_field(&raw, width, height, &cx)?
        };
        Ok(Scene {
            path: self.path.to_path_buf(),
            text: self.text.to_string(),
            name,
            width,
            height,
            geometry,
            wavelength_nm,
            background,
            seed,
            format,
            sensor,
            exposure,
            capture,
            plates,
        })
    }

    /// The frame's `width` or `height` (pixels).
    fn side(&self, v: &Option<Spanned<i64>>, field: &str) -> Result<usize> {
        let v = v
            .as_ref()
            .ok_or_else(|| self.missing(None, field, "frame size (pixels)"))?;
        let x = *v.get_ref();
        if !(2..=MAX_SIDE as i64).contains(&x) {
            return Err(self.err(
                &v.span(),
                field,
                format!("must be an integer from 2 to {MAX_SIDE}"),
            ));
        }
        Ok(x as usize)
    }

    /// A mosaic capture's frame size must hold whole periods of its pattern.
    fn check_mosaic_period(
        &self,
        raw: &RawScene,
        [width, height]: [usize; 2],
        capture: &CaptureKind,
    ) -> Result<()> {
        let check = |bad: fn(usize) -> bool, reason: &str| -> Result<()> {
            for (v, field, x) in [
                (&raw.width, "width", width),
                (&raw.height, "height", height),
            ] {
                if bad(x) {
                    return Err(self.err(&v.as_ref().map_or(0..0, |v| v.span()), field, reason));
                }
            }
            Ok(())
        };
        if matches!(capture, CaptureKind::Dofp { .. }) {
            // What `measure` demosaics (bilinear): whole 2x2 cells, at least 4x4 pixels.
            check(
                |x| !x.is_multiple_of(2) || x < 4,
                "a DoFP mosaic ([capture] dofp) has a 2x2 period: width and height \
                 must be even and at least 4 (what `polarid measure` demosaics)",
            )?;
        }
        if capture.bands().is_some() {
            check(
                |x| !x.is_multiple_of(4),
                "a colour polarization mosaic ([capture] color) has a 4x4 period: \
                 width and height must be multiples of 4",
            )?;
        }
        Ok(())
    }

    /// The geometry and plates of a scene without `[camera]`: `theta_r_deg`, `phi_deg`
    /// and `theta_i_deg`.
    fn far_field(
        &self,
        raw: &RawScene,
        width: usize,
        height: usize,
        cx: &PlateContext<'_>,
    ) -> Result<(Geometry, Vec<Plate>)> {
        self.refuse(
            [
                ("plane", raw.plane.as_ref().map(|v| v.span())),
                ("site", raw.site.as_ref().map(|v| v.span())),
                ("source", raw.source.as_ref().map(|v| v.span())),
            ],
            &str::to_string,
            "[[plane]], [site] and [[source]] describe a calibrated scene: add a [camera] \
             table, or give theta_r_deg and theta_i_deg instead",
        )?;
        let theta_r_deg = match &raw.theta_r_deg {
            Some(v) => self.zenith(v, "theta_r_deg")?,
            None => return Err(self.missing(None, "theta_r_deg", "camera zenith angle")),
        };
        let phi_deg = match &raw.phi_deg {
            Some(v) => self.num(v, "phi_deg")?,
            None => 180.0,
        };
        let theta_i_deg = match &raw.theta_i_deg {
            Some(v) => self.theta_i(v)?,
            None => {
                return Err(self.missing(None, "theta_i_deg", "source zenith angles"));
            }
        };
        let plates = self.plates(&raw.plate, width, height, cx)?;
        let geometry = Geometry::FarField {
            theta_r_deg,
            phi_deg,
            theta_i_deg,
        };
        Ok((geometry, plates))
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use crate::scene::parse;
    use crate::scene::tests::{GOOD, parse_err};

    /// Fuzz finding (fuzz/fuzz_targets/scene.rs): a tiny `step` made the number of source
    /// positions overflow usize (a panic with overflow checks; without them the count
    /// wrapped to 0 and the error wrongly said no position was given).
    #[test]
    fn theta_i_range_with_a_tiny_step_is_refused() {
        for step in ["1e-300", "5e-324", "1e-15", "0.0001"] {
            let e = parse_err(&GOOD.replace("step = 5 }", &format!("step = {step} }}")));
            assert!(
                e.contains("line 6")
                    && e.contains("theta_i_deg")
                    && e.contains("more than 10000 source positions"),
                "{step}: {e}"
            );
        }
        // 10000 positions are accepted, 10001 are not (step 2^-7: exact arithmetic).
        let range = |stop: &str| {
            GOOD.replace(
                "{ start = 35, stop = 80, step = 5 }",
                &format!("{{ start = 0, stop = {stop}, step = 0.0078125 }}"),
            )
        };
        let s = parse(Path::new("s.toml"), &range("78.1171875")).unwrap();
        let crate::scene::Geometry::FarField { theta_i_deg, .. } = &s.geometry else {
            panic!("far field expected")
        };
        assert_eq!(theta_i_deg.len(), 10_000);
        assert_eq!(theta_i_deg[9_999], 78.1171875);
        let e = parse_err(&range("78.125"));
        assert!(e.contains("more than 10000 source positions"), "{e}");
    }
}
