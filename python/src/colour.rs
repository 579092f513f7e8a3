//! Colour polarization mosaics (Sony IMX250MYR and kin) → per-band Stokes, DoLP and AoLP
//! (`polarid_core::mosaic::colour_polar`, the kernel of `polarid stokes --dofp RAW
//! --color RGGB`), on numpy arrays.

use std::collections::HashMap;

use numpy::PyArrayMethods;
use polarid_core::mosaic::{ColourMethod, ColourPattern, DofpOutputs, Pattern, colour_polar};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use polarid_io::manifest::colour::{band_table, pattern_wavelengths};

use crate::arrays::raw_array;
use crate::errors::{PyResultExt, value_error};
use crate::stokes::{mosaic_shape, new_array, pixel_rules};
use crate::{set_fields, with_raw};

/// Register this module's functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(stokes_color, m)?)?;
    Ok(())
}

/// The quantities `stokes_color` can return per band.
const QUANTITIES: [&str; 5] = ["s0", "s1", "s2", "dolp", "aolp"];

/// The wavelength of every band letter of `pattern`: `bands` (letter → nm) replaces the
/// nominal bands of colour sensors (R 650, G 550, B 450 nm), as the manifest's `bands`
/// and `polarid stokes --bands` do (`polarid_io::manifest::colour::band_table`).
pub(crate) fn wavelengths(
    pattern: &ColourPattern,
    bands: Option<HashMap<String, f64>>,
) -> PyResult<Vec<f64>> {
    let bands = bands.unwrap_or_default();
    let table = band_table(bands.iter().map(|(k, &nm)| (k.as_str(), nm)))
        .map_err(|e| value_error(format!("bands: {e}")))?;
    pattern_wavelengths(pattern, &table)
        .map_err(|e| value_error(format!("color {}: {e} in bands", pattern.color())))
}

/// Per-band Stokes images, DoLP and AoLP of a colour polarization mosaic.
///
/// A colour polarization sensor (Sony IMX250MYR and kin) puts a 2×2 polarizer block
/// under each colour of a 2×2 colour pattern of blocks: a 4×4 period. Each band is
/// reconstructed from its own samples only, in one fused pass over the mosaic for all
/// bands, by the kernel of ``polarid stokes --dofp RAW --color RGGB`` (same float32
/// numbers as its ``s0_<nm>.tif`` … ``aolp_<nm>.tif``):
/// ``S0 = ((I0 + I90) + (I45 + I135)) / 2``, ``S1 = I0 - I90``, ``S2 = I45 - I135``
/// (dark-subtracted), ``DoLP = sqrt(S1² + S2²) / S0`` clamped to [0, 1] (paper eq. 9's
/// observable), ``AoLP = atan2(S2, S1) / 2`` in degrees in [0, 180).
///
/// Parameters
/// ----------
/// raw : array_like, shape (H, W)
///     The raw colour mosaic (uint8, uint16 or float32 are used without a copy when
///     C-contiguous; other real dtypes become float32); H and W non-zero multiples of 4.
/// color : str, default "RGGB"
///     The colour of each 2×2 polarizer block of the 4×4 period, block-row by block-row
///     (four ASCII letters, case-insensitive; IMX250MYR: ``"RGGB"``). The distinct
///     letters, in order of first appearance, are the bands.
/// pattern : sequence of 4 float, default (90, 45, 135, 0)
///     The polarizer angles of every 2×2 block, degrees, row by row (IMX250MYR:
///     ``90, 45, 135, 0``).
/// method : {"bilinear", "superpixel"}, default "bilinear"
///     ``bilinear``: every band at full resolution (H, W), each of its lattices
///     interpolated separably (exact on brightness ramps; a false DoLP within 3 pixels
///     of strong edges, documented in ``polarid_core::mosaic::colour``);
///     ``superpixel``: one value per 4×4 period, (H/4, W/4).
/// bands : dict of str to float, optional
///     Wavelength (nm) of each colour letter, e.g. ``{"R": 650, "G": 550, "B": 450}``
///     (the default: the nominal bands of colour sensors); a table given replaces the
///     default one, so it names every letter of ``color``; as ``--bands R=650,...`` and
///     the manifest's ``bands``.
/// dark_level : float, default 0
///     DN subtracted from every raw value.
/// saturation : float, optional
///     Raw values at or above it are saturated (default: the dtype's maximum, none for
///     floats); a band's pixel is rejected when a raw value it uses is.
/// min_s0 : float, default 0
///     Pixels whose dark-subtracted S0 is at or below it are rejected (dark).
/// quantities : sequence of str, default ("s0", "s1", "s2", "dolp", "aolp")
///     The images to compute per band (only those are written: e.g. ``("dolp",
///     "aolp")`` for the fastest DoLP/AoLP).
/// return_mask : bool, default False
///     Also return each band's pixel mask (uint8: 0 valid, 1 saturated, 2 dark, 3
///     invalid).
///
/// Returns
/// -------
/// dict
///     One entry per band letter in band order (``"R"``, ``"G"``, ``"B"`` for RGGB),
///     each a dict with ``wavelength_nm`` (float), the asked ``quantities`` (float32
///     numpy arrays, written in place by the kernel: no copy), ``mask`` with
///     ``return_mask``, and ``counts`` (dict: ``valid``, ``saturated``, ``dark``,
///     ``invalid`` pixel counts). DoLP and AoLP are NaN where the mask rejects the
///     pixel.
///
/// Raises
/// ------
/// ValueError
///     A bad colour pattern (``colour pattern "RGB" ...``), polarizer pattern, size
///     (not whole 4×4 periods), method, quantity, band wavelength or pixel rule.
///
/// Notes
/// -----
/// The GIL is released; strips of rows run in parallel.
#[pyfunction]
#[pyo3(signature = (raw, color = "RGGB", pattern = vec![90.0, 45.0, 135.0, 0.0], method = "bilinear", *, bands = None, dark_level = 0.0, saturation = None, min_s0 = 0.0, quantities = None, return_mask = false))]
#[allow(clippy::too_many_arguments)]
pub fn stokes_color<'py>(
    py: Python<'py>,
    raw: &Bound<'py, PyAny>,
    color: &str,
    pattern: Vec<f64>,
    method: &str,
    bands: Option<HashMap<String, f64>>,
    dark_level: f64,
    saturation: Option<f64>,
    min_s0: f64,
    quantities: Option<Vec<String>>,
    return_mask: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let cp = ColourPattern::new(Pattern::new(&pattern).py_err()?, color).py_err()?;
    let method = match crate::stokes::method_is_bilinear(method)? {
        true => ColourMethod::Bilinear,
        false => ColourMethod::Superpixel,
    };
    let nms = wavelengths(&cp, bands)?;
    let want: Vec<String> = quantities.unwrap_or_else(|| QUANTITIES.map(String::from).to_vec());
    let mut on = [false; 5];
    for q in &want {
        match QUANTITIES.iter().position(|x| x == q) {
            Some(i) => on[i] = true,
            None => {
                return Err(value_error(format!(
                    "quantities: unknown {q:?}, expected some of {QUANTITIES:?}"
                )));
            }
        }
    }
    let raw = raw_array("raw", raw)?;
    let (h, w) = mosaic_shape(&raw)?;
    let rules = pixel_rules(dark_level, saturation, raw.type_max(), min_s0)?;
    let (ow, oh) = method.output_size(w, h);
    let nb = cp.bands().len();
    // Caller-visible arrays, allocated by numpy and written in place by the kernel.
    let arrays: Vec<[Option<Bound<'py, numpy::PyArrayDyn<f32>>>; 5]> = (0..nb)
        .map(|_| std::array::from_fn(|i| on[i].then(|| new_array::<f32>(py, &[oh, ow]))))
        .collect();
    let masks: Vec<Option<Bound<'py, numpy::PyArrayDyn<u8>>>> = (0..nb)
        .map(|_| return_mask.then(|| new_array::<u8>(py, &[oh, ow])))
        .collect();
    let counts = {
        let mut guards: Vec<Vec<_>> = arrays
            .iter()
            .map(|a| a.iter().map(write).collect::<PyResult<_>>())
            .collect::<PyResult<_>>()?;
        let mut mguards: Vec<_> = masks.iter().map(write).collect::<PyResult<_>>()?;
        let mut outs: Vec<DofpOutputs<'_>> = Vec::with_capacity(nb);
        for (g, m) in guards.iter_mut().zip(mguards.iter_mut()) {
            let mut sl: Vec<Option<&mut [f32]>> = Vec::with_capacity(5);
            for x in g.iter_mut() {
                sl.push(x.as_mut().map(|x| x.as_slice_mut()).transpose()?);
            }
            let mask = m.as_mut().map(|m| m.as_slice_mut()).transpose()?;
            let mut it = sl.into_iter();
            let mut next = || it.next().flatten();
            outs.push(DofpOutputs {
                s0: next(),
                s1: next(),
                s2: next(),
                dolp: next(),
                aolp: next(),
                mask,
            });
        }
        with_raw!(&raw, |data| {
            py.detach(|| colour_polar(data, w, &cp, method, &rules, outs))
                .py_err()?
        })
    };
    let d = PyDict::new(py);
    for (b, ((letter, nm), (a, m))) in cp
        .bands()
        .iter()
        .zip(&nms)
        .zip(arrays.into_iter().zip(masks))
        .enumerate()
    {
        let e = PyDict::new(py);
        e.set_item("wavelength_nm", *nm)?;
        for (q, x) in QUANTITIES.iter().zip(a) {
            if let Some(x) = x {
                e.set_item(*q, x)?;
            }
        }
        if let Some(m) = m {
            e.set_item("mask", m)?;
        }
        let c = PyDict::new(py);
        let pc = &counts[b];
        set_fields!(c, pc, valid, saturated, dark, invalid);
        e.set_item("counts", c)?;
        d.set_item(letter.to_string(), e)?;
    }
    Ok(d)
}

/// A write guard on an optional output array.
fn write<'py, T: numpy::Element>(
    x: &Option<Bound<'py, numpy::PyArrayDyn<T>>>,
) -> PyResult<Option<numpy::PyReadwriteArrayDyn<'py, T>>> {
    x.as_ref()
        .map(|x| x.try_readwrite().map_err(PyErr::from))
        .transpose()
}
