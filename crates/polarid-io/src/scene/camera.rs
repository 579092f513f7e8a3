//! The `[sensor]`, `[exposure]` and `[capture]` tables, each optional with documented
//! defaults (auto exposure at 0.7 of full scale; frames at 0°, 45°, 90°, 135°).

use polarid_core::mosaic::Pattern;
use polarid_core::simulate::{Exposure, Sensor};
use polarid_core::stokes::StokesSolver;

use toml::Spanned;

use super::CaptureKind;
use super::context::Ctx;
use super::raw::{RawCapture, RawExposure, RawSensor};
use crate::error::Result;

impl Ctx<'_> {
    pub(super) fn sensor(&self, raw: Option<&RawSensor>) -> Result<Sensor> {
        let mut s = Sensor::default();
        let Some(r) = raw else { return Ok(s) };
        if let Some(v) = &r.bit_depth {
            let b = *v.get_ref();
            if !(1..=16).contains(&b) {
                return Err(self.err(
                    &v.span(),
                    "sensor.bit_depth",
                    "must be an integer from 1 to 16",
                ));
            }
            s.bit_depth = b as u32;
        }
        if let Some(v) = &r.full_well_e {
            s.full_well_e = self.num_in(
                v,
                "sensor.full_well_e",
                |x| (1.0..=1e9).contains(&x),
                "from 1 to 1e9 electrons",
            )?;
        }
        if let Some(v) = &r.read_noise_e {
            s.read_noise_e = self.num_in(
                v,
                "sensor.read_noise_e",
                |x| (0.0..=1e6).contains(&x),
                ">= 0 electrons",
            )?;
        }
        if let Some(v) = &r.dark_level_dn {
            let max = s.max_dn();
            s.dark_level_dn = self.num_in(
                v,
                "sensor.dark_level_dn",
                |x| x >= 0.0 && x < max,
                &format!("in [0, {max}) DN (below the ADC maximum)"),
            )?;
        }
        if let Some(v) = &r.shot_noise {
            s.shot_noise = *v.get_ref();
        }
        Ok(s)
    }

    pub(super) fn exposure(&self, raw: Option<&RawExposure>) -> Result<Exposure> {
        let Some(r) = raw else {
            return Ok(Exposure::Auto { fraction: 0.7 });
        };
        // Without `mode`, a `value` means a fixed exposure.
        let (mode, mode_span) = match &r.mode {
            Some(m) => (m.get_ref().as_str(), Some(m.span())),
            None if r.value.is_some() => ("fixed", None),
            None => ("auto", None),
        };
        match mode {
            "auto" => {
                if let Some(v) = &r.value {
                    return Err(self.err(
                        &v.span(),
                        "exposure.value",
                        "`value` is for mode = \"fixed\"; auto exposure takes `fraction`",
                    ));
                }
                let fraction = match &r.fraction {
                    Some(v) => {
                        self.num_in(v, "exposure.fraction", |x| x > 0.0 && x <= 1.0, "in (0, 1]")?
                    }
                    None => 0.7,
                };
                Ok(Exposure::Auto { fraction })
            }
            "fixed" => {
                if let Some(v) = &r.fraction {
                    return Err(self.err(
                        &v.span(),
                        "exposure.fraction",
                        "`fraction` is for mode = \"auto\"; a fixed exposure takes `value`",
                    ));
                }
                let v = r.value.as_ref().ok_or_else(|| {
                    self.missing(mode_span.as_ref(), "exposure.value", "fixed exposure value")
                })?;
                Ok(Exposure::Fixed(self.num_in(
                    v,
                    "exposure.value",
                    |x| x > 0.0 && x <= 1e12,
                    "> 0",
                )?))
            }
            _ => Err(self.err(
                &mode_span.unwrap_or(0..0),
                "exposure.mode",
                "must be \"auto\" or \"fixed\"",
            )),
        }
    }

    /// The `[capture]` table; `bands` (top level) and `response` (`[sensor]
    /// band_response`) belong to colour captures only.
    pub(super) fn capture(
        &self,
        raw: Option<&RawCapture>,
        bands: Option<&Spanned<toml::Value>>,
        response: Option<&Spanned<toml::Value>>,
    ) -> Result<CaptureKind> {
        let colour = raw.and_then(|r| r.color.as_ref());
        if colour.is_none() {
            for (v, field) in [(bands, "bands"), (response, "sensor.band_response")] {
                if let Some(v) = v {
                    return Err(self.err(
                        &v.span(),
                        field,
                        "is for colour captures: add color = \"RGGB\" (or another colour \
                         pattern) to [capture] with kind = \"dofp\"",
                    ));
                }
            }
        }
        let default_angles = vec![0.0, 45.0, 90.0, 135.0];
        let Some(r) = raw else {
            return Ok(CaptureKind::Frames {
                angles_deg: default_angles,
            });
        };
        let kind = r.kind.as_ref().map(|k| (k.get_ref().as_str(), k.span()));
        match kind {
            None | Some(("frames", _)) => {
                if let Some(c) = &r.color {
                    return Err(self.err(
                        &c.span(),
                        "capture.color",
                        "`color` is for kind = \"dofp\" (a colour polarization mosaic)",
                    ));
                }
                if let Some(p) = &r.pattern {
                    return Err(self.err(
                        &p.span(),
                        "capture.pattern",
                        "`pattern` is for kind = \"dofp\"",
                    ));
                }
                let angles_deg = match &r.angles_deg {
                    None => default_angles,
                    Some(v) => {
                        let a = v.get_ref().clone();
                        if let Err(e) = StokesSolver::from_degrees(&a) {
                            return Err(self.err(&v.span(), "capture.angles_deg", e.to_string()));
                        }
                        a
                    }
                };
                Ok(CaptureKind::Frames { angles_deg })
            }
            Some(("dofp", _)) => {
                if let Some(a) = &r.angles_deg {
                    return Err(self.err(
                        &a.span(),
                        "capture.angles_deg",
                        "`angles_deg` is for kind = \"frames\"; a DoFP capture takes `pattern`",
                    ));
                }
                let pattern = match &r.pattern {
                    None => Pattern::default(),
                    Some(v) => Pattern::new(v.get_ref())
                        .map_err(|e| self.err(&v.span(), "capture.pattern", e.to_string()))?,
                };
                if let Some(c) = &r.color {
                    let (pattern, bands) = self.colour_capture(pattern, c, bands, response)?;
                    return Ok(CaptureKind::ColourDofp { pattern, bands });
                }
                Ok(CaptureKind::Dofp { pattern })
            }
            Some((_, span)) => {
                Err(self.err(&span, "capture.kind", "must be \"frames\" or \"dofp\""))
            }
        }
    }
}
