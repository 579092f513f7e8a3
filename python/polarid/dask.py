"""Material maps of image archives on Dask: ``polarid map`` block by block.

``material_map`` turns a dask array of polarization captures into lazy dask arrays of
the per-pixel complex refractive index ``(n, k)``, its standard errors and the material
class. Each block of the map is computed by the very kernels of ``polarid map`` (and
``polarid.map_manifest``) with the same options and defaults: the (binned) DoLP per
capture with its signal flags (saturated, dark, invalid), the eq. (9) fit of every pixel
over the captures, and the answer of the set rule (the model's materials consistent with
the pixel's estimate at ``confidence``, noise plus the systematic error model: one
material, ``ambiguous`` or unknown) or of the paper's nearest prototype
(``rule="nearest"``).

Weighted fits (``weights="auto"`` with a β per pixel, or ``weights="noise"``) use the
map's noise model (read noise ``r`` and gain ``g`` of the camera, one pair for the whole
map), which ``polarid map`` estimates from the residuals of a sample of the whole image.
That is a global step: unless ``noise=`` gives the model, ``material_map`` computes it
when called, in two passes over the blocks on the current scheduler (each block's DoLP
and noise terms; first the usable pixels per row, then the pixels of the CLI's sample,
every ``m``-th usable pixel in row-major order), and fits the gathered sample (at most
20 000 pixels) on the client: the same sample, the same fits, the same estimate as
``polarid map``. The maps are then lazy, every block weighted by that model
(``maps["noise"]`` reports it; pass it as ``noise=`` to map more captures of the same
camera without the two passes).

A map assembled from blocks equals the map of the whole frame: bit for bit with one β
per capture; with a β per pixel the fits are grouped by their usable captures within a
block, and the last bits of a group's fits depend on its members (as with ``polarid map
--tile``). ``python/tests/test_dask.py`` compares with the CLI on a
``dask.distributed.LocalCluster`` of 2 worker processes. It runs on any Dask scheduler
(threads, processes, distributed); the kernels release the GIL and use every core of a
worker.

Colour polarization mosaics (a 2×2 polarizer block under each colour of a Bayer
pattern, ``color="RGGB"``) are mapped per band as ``polarid map`` maps a colour
manifest: every band fitted per pixel (``maps["bands"][450]["n"]`` ...), every pixel
classified on all its bands against a multi-band model or library, with the same
calibrated geometry (a β per pixel) and noise weights (one noise model per band) as
single-band maps (each block reads 4 raw pixels around it).

Dask is an optional dependency: ``pip install "./python[dask]"`` (dask[array]; add
``distributed`` for clusters).

Example
-------
>>> import dask.array as da, polarid.dask
>>> frames = da.from_zarr("survey.zarr", component="frames")   # (T, A, H, W)
>>> maps = polarid.dask.material_map(frames, [0, 45, 90, 135], beta_deg, "model.json",
...                                  bin=2, saturation=4095)
>>> maps["class_names"][maps["class"][0, 0].compute()]

See ``python/examples/dask_map.py`` for a directory of captures (or a zarr store) to
maps on disk with a progress bar.
"""

from __future__ import annotations

import json
import math
import os
import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ._polarid import (
    _MAP_DEFAULTS,
    _NOISE_SAMPLE,
    _estimate_noise,
    _map_block,
    _map_names,
    _noise_block,
)

__all__ = ["material_map", "aligned_chunks", "PLANES"]

#: The float32 planes of a block's result, in order (class and reason are integer codes).
PLANES = ("n", "k", "n_se", "k_se", "rms_residual", "class", "reason")

#: Raw pixels around a DoFP block read by the bilinear interpolation (its 3×3
#: neighbourhood, rounded up to keep the 2×2 pattern's phase).
DOFP_HALO = 2

#: The defaults of ``polarid map``'s systematic error model (``polarid fit``'s), read from
#: the Rust pipeline.
DEFAULT_ERRORS = {
    key: _MAP_DEFAULTS[key] for key in ("angle_sd_deg", "dolp_floor", "extinction_ratio", "retardance_deg")
}

#: Pixels per fitting tile within a block (``polarid map --tile``'s default).
DEFAULT_TILE: int = _MAP_DEFAULTS["tile"]


def _dask_array():
    try:
        import dask.array as da
    except ImportError as e:  # pragma: no cover - depends on the environment
        raise ImportError(
            'polarid.dask needs dask: pip install "./python[dask]" (or pip install "dask[array]")'
        ) from e
    return da


def _model_json(model: Any) -> tuple[str, str]:
    """The model as JSON text and a label for errors: a path (str or os.PathLike) to a
    model of ``polarid train``, or the model itself as a dict (``json.load`` of such a
    file)."""
    if isinstance(model, (str, os.PathLike)):
        path = os.fspath(model)
        with open(path, encoding="utf-8") as f:  # FileNotFoundError names the path
            return f.read(), path
    if isinstance(model, dict):
        return json.dumps(model), "<model dict>"
    raise TypeError(
        f"model must be a path to a model JSON (polarid train) or its content as a dict, "
        f"got {type(model).__name__}"
    )


def aligned_chunks(chunks: Sequence[int], unit: int, minimum: int = 1) -> tuple[int, ...]:
    """Chunk sizes along one image axis whose boundaries are multiples of ``unit`` (the
    binning factor; for DoFP mosaics also a multiple of 2): every boundary of ``chunks``
    is moved down to a multiple of ``unit``; a last chunk smaller than ``max(unit,
    minimum)`` is merged into the previous one. The total is unchanged (the rows or
    columns of an incomplete last bin are dropped by the map, as by ``polarid map``)."""
    total = int(sum(chunks))
    bounds = []
    pos = 0
    for c in chunks[:-1]:
        pos += int(c)
        b = (pos // unit) * unit
        if b > (bounds[-1] if bounds else 0):
            bounds.append(b)
    while bounds and total - bounds[-1] < max(unit, minimum):
        bounds.pop()
    edges = [0, *bounds, total]
    return tuple(b - a for a, b in zip(edges[:-1], edges[1:]))


def _per_capture(name: str, value: Any, t: int) -> list:
    if value is None or np.isscalar(value):
        return [None if value is None else float(value)] * t
    v = list(value)
    if len(v) != t:
        raise ValueError(f"{name} gives {len(v)} value(s) for {t} capture(s); give one or one per capture")
    return [None if x is None else float(x) for x in v]


def _block_inputs(x, beta, block_id, nblocks, kw, per_capture_beta, t, a):
    """One block's frames, β and halo and the options of its DoLP stage (shared by the map
    and the noise passes), the first argument of ``_map_block`` and ``_noise_block``:
    ``x`` (L, h, w) frames (L = T·A) or DoFP mosaics with their halo (``kw["depth"]`` raw
    pixels on inner sides)."""
    i, j = block_id[1], block_id[2]
    depth = kw["depth"]
    if depth:
        halo = (
            depth if i > 0 else 0,
            depth if i < nblocks[0] - 1 else 0,
            depth if j > 0 else 0,
            depth if j < nblocks[1] - 1 else 0,
        )
        frames = x
    else:
        halo = (0, 0, 0, 0)
        frames = x.reshape(t, a, x.shape[-2], x.shape[-1])
    b = per_capture_beta if beta is None else beta
    # Blocks that crossed processes (distributed) can sit in unaligned buffers: the
    # kernels need C-contiguous, aligned arrays (np.require copies only when needed).
    frames = np.require(frames, requirements=("C", "A"))
    b = np.require(b, dtype=np.float64, requirements=("C", "A"))
    return dict(frames=frames, angles_deg=kw["angles_deg"], beta_deg=b, halo=halo,
                pattern=kw["pattern"], color=kw["color"], bands=kw["bands"], bin=kw["bin"],
                dark_level=kw["dark_level"], saturation=kw["saturation"], min_s0=kw["min_s0"])


def _block(x, beta=None, *, block_id, nblocks, per_capture_beta, t, a, kw):
    """One map block: float32 (6 B + 2, h/bin, w/bin), every band's n, k, n_se, k_se,
    rms_residual and reason, then the map's class and reason (``_map_block``)."""
    block = _block_inputs(x, beta, block_id, nblocks, kw, per_capture_beta, t, a)
    return _map_block(block, kw["options"], noise=kw["noise"])


def _count_block(x, beta=None, *, block_id, nblocks, per_capture_beta, t, a, kw):
    """Noise pass 1: the usable pixels of every map row of a block, (1, h/bin, 1)."""
    block = _block_inputs(x, beta, block_id, nblocks, kw, per_capture_beta, t, a)
    counts = _noise_block(block, band=kw["band"])
    return np.asarray(counts, dtype=np.int64).reshape(1, -1, 1)


def _sample_block(x, beta, offsets, stride, block_id, nblocks, per_capture_beta, t, a, kw):
    """Noise pass 2: the block's pixels of the map's noise sample, ``(index, images)``
    (``_noise_block``)."""
    block = _block_inputs(x, beta, block_id, nblocks, kw, per_capture_beta, t, a)
    return _noise_block(block, band=kw["band"], row_offsets=[int(v) for v in offsets],
                        stride=int(stride))


def _noise_arg(noise: Any) -> tuple[float, float]:
    """``noise=`` as ``(read_var_dn2, inv_gain)``: a mapping with those keys (as
    ``maps["noise"]``) or with ``read_noise_dn`` and ``gain_e_per_dn`` (as
    ``map_summary.json``'s ``noise``)."""
    if not isinstance(noise, Mapping):
        raise TypeError(f"noise must be a dict (maps['noise'] or map_summary.json's noise), got {type(noise).__name__}")
    if "read_var_dn2" in noise and "inv_gain" in noise:
        return float(noise["read_var_dn2"]), float(noise["inv_gain"])
    if "read_noise_dn" in noise and "gain_e_per_dn" in noise:
        g = noise["gain_e_per_dn"]
        return float(noise["read_noise_dn"]) ** 2, 0.0 if g is None else 1.0 / float(g)
    raise ValueError("noise needs the keys read_var_dn2 and inv_gain (or read_noise_dn and gain_e_per_dn)")


def _noise_dict(est) -> dict[str, Any]:
    r2, ig, pixels, outliers, chi2 = est
    return dict(read_var_dn2=r2, inv_gain=ig, read_noise_dn=math.sqrt(r2),
                gain_e_per_dn=(1.0 / ig) if ig > 0 else None, pixels=int(pixels),
                outliers=int(outliers), reduced_chi2=chi2)


def _estimate(da, x, beta, common, rows, cols, oh, ow, bin, per_capture_beta, scheduler):
    """The map's noise model, as ``polarid map`` estimates it (module documentation):
    ``(read_var_dn2, inv_gain, pixels, outliers, reduced_chi2)`` or None."""
    import dask

    nbr, nbc = len(rows), len(cols)
    out_rows = tuple(c // bin for c in rows)
    out_cols = tuple(c // bin for c in cols)
    args = (x,) if beta is None else (x, beta)
    counts = da.map_blocks(_count_block, *args, chunks=((1,), out_rows, (1,) * nbc), dtype=np.int64,
                           meta=np.empty((0, 0, 0), dtype=np.int64), per_capture_beta=per_capture_beta,
                           **common, token="polarid-noise-count")
    c = np.asarray(counts.compute(scheduler=scheduler))[0]  # (oh, nbc)
    total = int(c.sum())
    if total == 0:
        return None
    stride = -(-total // _NOISE_SAMPLE)
    row_tot = c.sum(axis=1)
    offsets = (np.cumsum(row_tot) - row_tot)[:, None] + np.cumsum(c, axis=1) - c
    xd = x.to_delayed()
    bd = None if beta is None else beta.to_delayed()
    tasks, where = [], []
    r0 = np.concatenate([[0], np.cumsum(out_rows)])
    c0 = np.concatenate([[0], np.cumsum(out_cols)])
    for i in range(nbr):
        for j in range(nbc):
            off = offsets[r0[i]:r0[i + 1], j]
            tasks.append(dask.delayed(_sample_block, pure=True)(
                xd[0, i, j], None if bd is None else bd[0, i, j], off, stride, (0, i, j),
                common["nblocks"], per_capture_beta, common["t"], common["a"], common["kw"]))
            where.append((r0[i], c0[j], out_cols[j]))
    parts = dask.compute(*tasks, scheduler=scheduler)
    # Each part: (index, images): the DoLP, read and shot terms (and β) per capture.
    gp = []
    for (idx, _), (ry, cx, bw) in zip(parts, where):
        idx = np.asarray(idx, dtype=np.int64)
        gp.append((ry + idx // bw) * ow + cx + idx % bw)
    order = np.argsort(np.concatenate(gp), kind="stable")
    t = common["t"]
    images = [np.concatenate([np.asarray(p[1][k], dtype=np.float32).reshape(t, -1) for p in parts],
                             axis=1)[:, order].tolist() for k in range(len(parts[0][1]))]
    if beta is None:
        return _estimate_noise(*images, beta_deg=[float(v) for v in per_capture_beta])
    return _estimate_noise(*images[:3], beta_rad=images[3])


def material_map(
    frames: Any,
    angles_deg: Sequence[float] | None,
    beta_deg: Any,
    model: Any = None,
    *,
    pattern: Sequence[float] | None = None,
    color: str | None = None,
    bands: Mapping[str, float] | None = None,
    library: str | None = None,
    bin: int = 1,
    dark_level: float | Sequence[float] = 0.0,
    saturation: float | Sequence[float | None] | None = None,
    min_s0: float | None = None,
    rule: str = "set",
    confidence: float = 0.95,
    weights: str = "auto",
    noise: Mapping[str, float] | None = None,
    angle_sd_deg: float | Sequence[float] = DEFAULT_ERRORS["angle_sd_deg"],
    dolp_floor: float = DEFAULT_ERRORS["dolp_floor"],
    extinction_ratio: float = DEFAULT_ERRORS["extinction_ratio"],
    retardance_deg: float = DEFAULT_ERRORS["retardance_deg"],
    max_distance: float | None = None,
    metric: str = "euclidean",
    tile: int = DEFAULT_TILE,
    bench: str = "same",
    rechunk: bool = True,
    scheduler: Any = None,
) -> dict[str, Any]:
    """Per-pixel (n, k) and material maps of a stack of captures, as lazy dask arrays.

    The same computation as ``polarid map`` (and ``polarid.map_manifest``) with the same
    options and defaults, block by block: for each capture the (``bin`` × ``bin``
    binned) DoLP and the signal flags, then the fit of every unflagged pixel's DoLP
    values over the captures against eq. (9) (weighted by the map's noise model with a
    β per pixel) and its answer (the set rule at 95 %, or the nearest prototype). The
    map equals the CLI's whatever the chunking (classes identical, n and k to 1e-6;
    ``python/tests/test_dask.py``).

    Parameters
    ----------
    frames : dask.array.Array or array_like
        Polarizer frames, shape (T, A, H, W): T captures (source positions) of A frames
        (one per polarizer angle); or, with ``pattern``, DoFP mosaics (T, H, W). Any
        chunking along rows and columns (the capture and angle axes are gathered into one
        chunk). uint8, uint16 and float32 frames are used as they are, other dtypes as
        float32. numpy arrays are wrapped with ``dask.array.from_array``.
    angles_deg : sequence of float or None
        The A polarizer angles, degrees (None for DoFP mosaics).
    beta_deg : array_like or dask.array.Array
        The local incidence angle β (eq. 5), degrees: shape (T,), one per capture (far
        field: every pixel shares it); or (T, H // bin, W // bin), one per map pixel and
        capture (calibrated geometry; NaN where a pixel has no geometry: reason
        ``no_geometry``). With per-pixel β the calibrated rules of ``polarid map`` apply:
        a capture in which a pixel is dark or saturated is left out of that pixel's fit
        (at least 3 must remain).
    model : str, os.PathLike or dict
        A model JSON written by ``polarid train`` (its path, or its content as a dict).
        It is read once here and shipped to the workers with the tasks. With ``color``:
        a multi-band model, or ``library`` instead.
    pattern : sequence of 4 float, optional
        The DoFP polarizer pattern of the 2×2 cell, row by row (IMX250MZR:
        ``(90, 45, 135, 0)``); frames are then mosaics, demosaiced bilinearly as by
        ``polarid map`` (each block reads 2 raw pixels around it: ``dask.array.overlap``).
    color : str, optional
        Colour polarization mosaics (T, H, W) (H, W multiples of 4): the colour of each
        2×2 polarizer block of the 4×4 period, block-row by block-row (``"RGGB"`` for the
        IMX250MYR; a manifest's ``dofp.color``), with ``pattern`` the polarizer block
        (default ``(90, 45, 135, 0)``). Mapped per band as ``polarid map`` maps a colour
        manifest (weighted fits use one noise model per band, estimated as ``polarid
        map`` does; ``noise=`` gives one model for every band).
    bands : dict, optional
        With ``color``: the wavelength (nm) of each colour letter (default R 650, G 550,
        B 450; a manifest's ``bands``).
    library : str, optional
        With ``color``, instead of ``model``: ``"builtin-rgb"`` or a multi-band library
        CSV (read by every worker: a path they can open).
    bin : int, default 1
        Sum ``bin`` × ``bin`` blocks of pixels before the DoLP (1 to 64). Incomplete
        blocks at the right and bottom edges are dropped.
    dark_level, saturation : float or sequence of one per capture
        DN subtracted from every raw value; raw values at or above ``saturation`` are
        saturated (default: the dtype's maximum, none for floats). As a manifest's
        ``dark_level`` / ``saturation``.
    min_s0 : float, optional
        Dark threshold on a block's mean dark-subtracted S0, DN (default: 1 % of the range
        from the dark level to saturation for integer frames, 0 for float frames).
    rule : {"set", "nearest"}, default "set"
        ``set`` (``polarid map``'s default): a pixel is the one material consistent with
        its estimate at ``confidence`` (noise plus the systematic error model),
        ``ambiguous`` (the last class name) when several are (or, against a built-in
        catalogue, when the one is transparent: its index, not its name), unknown (code 0, reason
        ``rejected``) when none is; ``nearest``: the paper's nearest prototype
        (``metric``, ``max_distance``).
    confidence : float, default 0.95
        Confidence of the consistent set, in (0, 1) (``--confidence``).
    weights : {"auto", "noise", "none"}, default "auto"
        Weight each pixel's fit by its DoLP standard errors from the map's noise model
        (``--weights``; ``auto``: with a β per pixel only, as ``polarid map`` with
        calibrated geometry). Unweighted fits scale each pixel's covariance by its own
        reduced χ² (the paper's fit).
    noise : dict, optional
        The noise model for weighted fits: ``maps["noise"]`` of an earlier map (keys
        ``read_var_dn2``, ``inv_gain``) or ``map_summary.json``'s ``noise``
        (``read_noise_dn``, ``gain_e_per_dn``). Default: estimated from this map's
        residuals when it is called (module documentation), as ``polarid map`` does.
    angle_sd_deg : float or sequence of one per capture, default 0.2
        Set rule: angle uncertainty of each capture, degrees (``--angle-sd-deg``; a
        manifest's per-capture ``angle_sd_deg`` wins in the CLI: pass them here).
    dolp_floor, extinction_ratio, retardance_deg : float
        Set rule: additive DoLP error (0.002), the polarizer's lowest extinction ratio
        (100; ``math.inf``: ideal), the largest retardance ahead of it (0°); as
        ``polarid map``.
    max_distance : float, optional
        Nearest rule: leave pixels whose nearest prototype is farther ``unknown``
        (``rejected``).
    metric : {"euclidean", "mahalanobis"}
        Nearest rule: distance to the prototypes.
    tile : int, default 65536
        Pixels per fitting tile within a block.
    bench : {"same", "other"}, default "same"
        Where the model was trained (``--bench``): ``same`` compares a pixel's noise
        covariance with the prototypes' sample covariance, ``other`` both sides' total
        covariances (as ``polarid map``).
    rechunk : bool, default True
        Chunks along rows and columns must have boundaries at multiples of ``bin`` (and
        of 2 for DoFP mosaics) so that no bin straddles two blocks. True: move the
        boundaries down to such multiples (``aligned_chunks``); False: raise
        ``ValueError`` when they are not.
    scheduler : optional
        The Dask scheduler of the noise-model passes (default: the current one, e.g. a
        ``distributed.Client``); the maps themselves are lazy.

    Returns
    -------
    dict
        ``n``, ``k``, ``n_se``, ``k_se``, ``rms_residual``: float32 dask arrays (H // bin,
        W // bin), NaN where not fitted; ``class``: uint8 (uint16 above 255 classes) class
        codes, 0 = ``unknown`` (no material; ``reason`` says why), code ``i`` is
        ``class_names[i]``; ``reason``: uint8
        codes, code ``i`` is ``reason_names[i]``; ``class_names`` (list, ``"unknown"``
        first, ``"ambiguous"`` last with the set rule), ``reason_names`` (list,
        ``"classified"`` first, as ``map_summary.json``'s ``reason_codes``); ``weights``
        (``"noise"`` or ``"none"``: what the fits used) and ``noise`` (the model used:
        ``read_var_dn2``, ``inv_gain``, ``read_noise_dn``, ``gain_e_per_dn`` and, when
        estimated, ``pixels``, ``outliers``, ``reduced_chi2``; None when unweighted). The
        arrays share one task per block: compute them together
        (``dask.compute(*maps.values())``, ``dask.array.to_zarr``, ...).

        With ``color``: ``bands`` instead of ``n`` ... ``rms_residual``: a dict keyed by
        each band's wavelength (float, increasing) of dicts ``n``, ``k``, ``n_se``,
        ``k_se``, ``rms_residual`` (float32) and ``reason`` (uint8: why the band's fit of
        a pixel is not used; 0 ``classified``), as ``map_manifest``'s ``bands``; ``class``
        and ``reason`` of the classification on all bands; ``noise`` the first band's
        model.

    Raises
    ------
    ValueError
        Bad shapes, options (``bin must be in 1..=64, got 0``, as ``polarid map``), chunks
        not aligned with ``rechunk=False``; errors of a block (a bad pattern, too few
        angles) are raised at compute time with the same messages as ``polarid map``.
    FileNotFoundError
        A missing model file.

    Warns
    -----
    UserWarning
        Weighted fits asked for but too few usable pixels to estimate the noise model:
        the fits are unweighted (as ``polarid map`` warns).
    """
    da = _dask_array()
    colour = color is not None
    if colour and pattern is None:
        pattern = (90.0, 45.0, 135.0, 0.0)
    if library is not None and not colour:
        raise ValueError("library= maps colour mosaics only (give color=); give model for mono frames")
    mosaic = pattern is not None
    if not isinstance(frames, da.Array):
        frames = da.from_array(np.asarray(frames))
    want = 3 if mosaic else 4
    if frames.ndim != want:
        layout = ("(captures, rows, columns) with color" if colour else
                  "(captures, rows, columns) with pattern" if mosaic else "(captures, angles, rows, columns)")
        raise ValueError(f"frames must have shape {layout}, got shape {frames.shape}")
    if mosaic and angles_deg is not None:
        raise ValueError("give angles_deg=None with color or a DoFP pattern (the pattern gives the angles)")
    if not mosaic and angles_deg is None:
        raise ValueError("angles_deg is needed for (T, A, H, W) frames (or give a DoFP pattern)")
    if colour and (model is None) == (library is None):
        raise ValueError("give model (a multi-band model JSON) or library (builtin-rgb or a "
                         "multi-band library CSV), not both or neither")
    t = int(frames.shape[0])
    a = 1 if mosaic else int(frames.shape[1])
    height, width = int(frames.shape[-2]), int(frames.shape[-1])
    if not isinstance(bin, (int, np.integer)) or isinstance(bin, bool):
        raise TypeError(f"bin must be an int, got {bin!r}")
    bin = int(bin)
    if weights not in ("auto", "noise", "none"):
        raise ValueError(f'weights must be "auto", "noise" or "none", got {weights!r}')
    if colour and (height % 4 or width % 4):
        raise ValueError(f"colour mosaics need whole 4x4 periods, got {width}x{height}")

    # β: per capture (a small vector, shipped with every task) or per map pixel.
    if isinstance(beta_deg, da.Array) and beta_deg.ndim == 1:
        beta_deg = beta_deg.compute()
    per_pixel = (isinstance(beta_deg, da.Array) and beta_deg.ndim == 3) or np.ndim(beta_deg) == 3
    # As polarid map's --weights auto: calibrated geometry, and a library's hypothesis
    # tests (the set rule) weigh the fits.
    tests_rows = library is not None and rule == "set"
    weighted = weights == "noise" or (weights == "auto" and (per_pixel or tests_rows))
    if noise is not None and weights == "none":
        raise ValueError('noise= gives a noise model for weighted fits; it cannot go with weights="none"')
    given_noise = None if noise is None else _noise_arg(noise)
    if given_noise is not None:
        weighted = True
    if model is not None:
        model_json, label = _model_json(model)
    else:
        model_json, label = None, f"library {library}"
    # The map's options (``_map_names``, ``_map_block``).
    options = dict(model_json=model_json, library=None if library is None else str(library),
                   label=label, max_distance=max_distance, metric=metric, tile=int(tile),
                   rule=rule, confidence=float(confidence),
                   angle_sd_deg=[float(v) for v in _per_capture("angle_sd_deg", angle_sd_deg, t)],
                   dolp_floor=float(dolp_floor), extinction_ratio=float(extinction_ratio),
                   retardance_deg=float(retardance_deg), bench=bench)
    kw = dict(
        angles_deg=None if mosaic else [float(v) for v in angles_deg],
        pattern=None if pattern is None else [float(v) for v in pattern],
        color=None if color is None else str(color),
        bands=None if bands is None else {str(k): float(v) for k, v in bands.items()},
        bin=bin, min_s0=min_s0, options=options, noise=None, band=0,
        depth=COLOUR_HALO if colour else DOFP_HALO if mosaic else 0,
    )
    class_names, reason_names, wavelengths = _map_names(
        options, color=kw["color"], pattern=kw["pattern"], bands=kw["bands"], bin=bin,
        min_s0=min_s0)
    nb = max(len(wavelengths), 1)
    if bin > height or bin > width:
        raise ValueError(f"bin {bin} does not fit the {width}x{height} frames")
    oh, ow = height // bin, width // bin
    kw.update(dark_level=[0.0 if v is None else v for v in _per_capture("dark_level", dark_level, t)],
              saturation=_per_capture("saturation", saturation, t))

    # Chunks: whole captures and angles; rows and columns at multiples of the bin (and of
    # the mosaic's period).
    period = 4 if colour else 2 if mosaic else 1
    unit = math.lcm(bin, period)
    minimum = 2 * kw["depth"] if mosaic else 1
    lead = {0: -1} if mosaic else {0: -1, 1: -1}
    frames = frames.rechunk(lead)
    new = [aligned_chunks(frames.chunks[ax], unit, minimum) for ax in (-2, -1)]
    if tuple(new) != (frames.chunks[-2], frames.chunks[-1]):
        if not rechunk:
            what = ", and 4 for the 4x4 colour period" if colour else ", and 2 for the DoFP 2x2 cell" if mosaic else ""
            raise ValueError(
                f"the chunks of frames along rows {frames.chunks[-2]} and columns "
                f"{frames.chunks[-1]} must end at multiples of {unit} (bin={bin}{what}), "
                f"except the last; rechunk (e.g. to {new[0]} and {new[1]}) or pass rechunk=True")
        frames = frames.rechunk({frames.ndim - 2: new[0], frames.ndim - 1: new[1]})
    rows, cols = frames.chunks[-2], frames.chunks[-1]
    out_rows = tuple(c // bin for c in rows)
    out_cols = tuple(c // bin for c in cols)
    # Rows/columns beyond the last whole bin: dropped inside the last block.
    if sum(out_rows) != oh or sum(out_cols) != ow:  # pragma: no cover - by construction
        raise RuntimeError("internal error: block sizes do not add up to the map")

    if not mosaic:
        frames = frames.reshape(t * a, height, width)
    x = frames
    if mosaic and (len(rows) > 1 or len(cols) > 1):
        d = kw["depth"]
        x = da.overlap.overlap(frames, depth={0: 0, 1: d, 2: d}, boundary="none")

    common = dict(nblocks=(len(rows), len(cols)), t=t, a=a, kw=kw)
    shape_msg = f"beta_deg must have shape ({t},) (one angle per capture) or ({t}, {oh}, {ow}) (one per map pixel at bin {bin})"
    if per_pixel:
        beta = beta_deg if isinstance(beta_deg, da.Array) else da.from_array(np.asarray(beta_deg, dtype=np.float64))
        if beta.shape != (t, oh, ow):
            raise ValueError(f"{shape_msg}, got {beta.shape}")
        beta = beta.rechunk(((t,), out_rows, out_cols))
        per_capture_beta = None
    else:
        beta = None
        per_capture_beta = np.asarray(beta_deg, dtype=np.float64)
        if per_capture_beta.shape != (t,):
            raise ValueError(f"{shape_msg}, got {per_capture_beta.shape}")

    # The map's noise model of every band: given, or estimated globally as polarid map
    # does.
    noise_info = None
    if given_noise is not None:
        kw["noise"] = [given_noise] * nb
        noise_info = dict(read_var_dn2=given_noise[0], inv_gain=given_noise[1],
                          read_noise_dn=math.sqrt(given_noise[0]),
                          gain_e_per_dn=(1.0 / given_noise[1]) if given_noise[1] > 0 else None)
    elif weighted:
        models = []
        for b in range(nb):
            band_common = dict(common, kw=dict(kw, band=b))
            est = _estimate(da, x, beta, band_common, rows, cols, oh, ow, bin, per_capture_beta, scheduler)
            if est is None:
                where = f"band {wavelengths[b]:g} nm: " if colour else ""
                warnings.warn(f"{where}too few usable pixels to estimate the noise model; the "
                              "per-pixel fits are unweighted", UserWarning, stacklevel=2)
                models.append(None)
            else:
                models.append((est[0], est[1]))
                if noise_info is None:
                    noise_info = _noise_dict(est)
        kw["noise"] = models

    planes = 6 * nb + 2
    meta = np.empty((0, 0, 0), dtype=np.float32)
    args = (x,) if beta is None else (x, beta)
    stack = da.map_blocks(_block, *args, chunks=((planes,), out_rows, out_cols), dtype=np.float32,
                          meta=meta, per_capture_beta=per_capture_beta, **common, token="polarid-map")
    class_dtype = np.uint8 if len(class_names) <= 256 else np.uint16
    out: dict[str, Any] = {}
    if colour:
        out["bands"] = {}
        for b, wl in enumerate(wavelengths):
            band = {p: stack[6 * b + i] for i, p in enumerate(PLANES[:5])}
            band["reason"] = stack[6 * b + 5].astype(np.uint8)
            out["bands"][float(wl)] = band
    else:
        out.update({p: stack[i] for i, p in enumerate(PLANES[:5])})
    out["class"] = stack[6 * nb].astype(class_dtype)
    out["reason"] = stack[6 * nb + 1].astype(np.uint8)
    out["class_names"] = class_names
    out["reason_names"] = reason_names
    out["weights"] = "noise" if any(m is not None for m in kw["noise"] or []) else "none"
    out["noise"] = noise_info
    return out


#: Raw pixels around a colour block read by the per-band bilinear interpolation (3,
#: rounded up to the 4×4 period).
COLOUR_HALO = 4
