"""Material maps of image archives on Dask: ``polarid map`` block by block.

``material_map`` turns a dask array of polarization captures into lazy dask arrays of
the per-pixel complex refractive index ``(n, k)``, its standard errors and the material
class. Each block of the map is computed by the very kernels of ``polarid map`` (and
``polarid.map_manifest``): the (binned) DoLP per capture with its signal flags
(saturated, dark, invalid), the eq. (9) fit of every pixel over the captures and the
nearest-prototype classification of the model, so that a map assembled from blocks
equals the map of the whole frame: bit for bit with one β per capture; with a β per
pixel the fits are grouped by their usable captures within a block, and the last bits of
a group's fits depend on its members (as with ``polarid map --tile``).
``python/tests/test_dask.py`` compares with the CLI on a ``dask.distributed.LocalCluster``
of 2 worker processes. It runs on any Dask scheduler
(threads, processes, distributed); the kernels release the GIL and use every core of a
worker.

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
from collections.abc import Sequence
from typing import Any

import numpy as np

from ._polarid import _map_block, _map_names

__all__ = ["material_map", "aligned_chunks", "PLANES"]

#: The float32 planes of a block's result, in order (class and reason are integer codes).
PLANES = ("n", "k", "n_se", "k_se", "rms_residual", "class", "reason")

#: Raw pixels around a DoFP block read by the bilinear interpolation (its 3×3
#: neighbourhood, rounded up to keep the 2×2 pattern's phase).
DOFP_HALO = 2


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


def _block(x, beta=None, *, block_id, nblocks, pattern, per_capture_beta, t, a, kw):
    """One map block: ``x`` (L, h, w) frames (L = T·A) or DoFP mosaics with their halo."""
    i, j = block_id[1], block_id[2]
    if pattern is not None:
        halo = (
            DOFP_HALO if i > 0 else 0,
            DOFP_HALO if i < nblocks[0] - 1 else 0,
            DOFP_HALO if j > 0 else 0,
            DOFP_HALO if j < nblocks[1] - 1 else 0,
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
    return _map_block(frames, kw["angles_deg"], b, kw["model_json"], label=kw["label"],
                      pattern=pattern, halo=halo, bin=kw["bin"], dark_level=kw["dark_level"],
                      saturation=kw["saturation"], min_s0=kw["min_s0"],
                      max_distance=kw["max_distance"], metric=kw["metric"], tile=kw["tile"])


def material_map(
    frames: Any,
    angles_deg: Sequence[float] | None,
    beta_deg: Any,
    model: Any,
    *,
    pattern: Sequence[float] | None = None,
    bin: int = 1,
    dark_level: float | Sequence[float] = 0.0,
    saturation: float | Sequence[float | None] | None = None,
    min_s0: float | None = None,
    max_distance: float | None = None,
    metric: str = "euclidean",
    tile: int = 65536,
    rechunk: bool = True,
) -> dict[str, Any]:
    """Per-pixel (n, k) and material maps of a stack of captures, as lazy dask arrays.

    The same computation as ``polarid map`` (and ``polarid.map_manifest``), block by
    block: for each capture the (``bin`` × ``bin`` binned) DoLP and the signal flags,
    then the fit of every unflagged pixel's DoLP values over the captures against eq.
    (9) and the nearest prototype of the model. The map equals the CLI's whatever the
    chunking (classes identical, n and k to 1e-6; ``python/tests/test_dask.py``).

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
        It is read once here and shipped to the workers with the tasks.
    pattern : sequence of 4 float, optional
        The DoFP polarizer pattern of the 2×2 cell, row by row (IMX250MZR:
        ``(90, 45, 135, 0)``); frames are then mosaics, demosaiced bilinearly as by
        ``polarid map`` (each block reads 2 raw pixels around it: ``dask.array.overlap``).
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
    max_distance : float, optional
        Leave pixels whose nearest prototype is farther unclassified (``rejected``).
    metric : {"euclidean", "mahalanobis"}
        Distance to the prototypes.
    tile : int, default 65536
        Pixels per fitting tile within a block.
    rechunk : bool, default True
        Chunks along rows and columns must have boundaries at multiples of ``bin`` (and
        of 2 for DoFP mosaics) so that no bin straddles two blocks. True: move the
        boundaries down to such multiples (``aligned_chunks``); False: raise
        ``ValueError`` when they are not.

    Returns
    -------
    dict
        ``n``, ``k``, ``n_se``, ``k_se``, ``rms_residual``: float32 dask arrays (H // bin,
        W // bin), NaN where not fitted; ``class``: uint8 (uint16 above 255 classes) class
        codes, 0 = not classified, code ``i`` is ``class_names[i]``; ``reason``: uint8
        codes, code ``i`` is ``reason_names[i]``; ``class_names`` (list, ``"unknown"``
        first), ``reason_names`` (list, ``"classified"`` first; ``no_geometry`` with
        per-pixel β only). The arrays share one task per block: compute them together
        (``dask.compute(*maps.values())``, ``dask.array.to_zarr``, ...).

    Raises
    ------
    ValueError
        Bad shapes, options (``bin must be in 1..=64, got 0``, as ``polarid map``), chunks
        not aligned with ``rechunk=False``; errors of a block (a bad pattern, too few
        angles) are raised at compute time with the same messages as ``polarid map``.
    FileNotFoundError
        A missing model file.
    """
    da = _dask_array()
    dofp = pattern is not None
    if not isinstance(frames, da.Array):
        frames = da.from_array(np.asarray(frames))
    want = 3 if dofp else 4
    if frames.ndim != want:
        layout = "(captures, rows, columns) with pattern" if dofp else "(captures, angles, rows, columns)"
        raise ValueError(f"frames must have shape {layout}, got shape {frames.shape}")
    if dofp and angles_deg is not None:
        raise ValueError("give angles_deg=None with a DoFP pattern (the pattern gives the angles)")
    if not dofp and angles_deg is None:
        raise ValueError("angles_deg is needed for (T, A, H, W) frames (or give a DoFP pattern)")
    t = int(frames.shape[0])
    a = 1 if dofp else int(frames.shape[1])
    height, width = int(frames.shape[-2]), int(frames.shape[-1])
    if not isinstance(bin, (int, np.integer)) or isinstance(bin, bool):
        raise TypeError(f"bin must be an int, got {bin!r}")
    bin = int(bin)

    # β: per capture (a small vector, shipped with every task) or per map pixel.
    if isinstance(beta_deg, da.Array) and beta_deg.ndim == 1:
        beta_deg = beta_deg.compute()
    per_pixel = (isinstance(beta_deg, da.Array) and beta_deg.ndim == 3) or np.ndim(beta_deg) == 3
    model_json, label = _model_json(model)
    class_names, reason_names = _map_names(
        model_json, label=label, per_pixel_beta=per_pixel, bin=bin, min_s0=min_s0,
        max_distance=max_distance, metric=metric, tile=tile)
    if bin > height or bin > width:
        raise ValueError(f"bin {bin} does not fit the {width}x{height} frames")
    oh, ow = height // bin, width // bin

    # Chunks: whole captures and angles; rows and columns at multiples of the bin.
    unit = math.lcm(bin, 2) if dofp else bin
    minimum = DOFP_HALO * 2 if dofp else 1
    lead = {0: -1} if dofp else {0: -1, 1: -1}
    frames = frames.rechunk(lead)
    new = [aligned_chunks(frames.chunks[ax], unit, minimum) for ax in (-2, -1)]
    if tuple(new) != (frames.chunks[-2], frames.chunks[-1]):
        if not rechunk:
            raise ValueError(
                f"the chunks of frames along rows {frames.chunks[-2]} and columns "
                f"{frames.chunks[-1]} must end at multiples of {unit} (bin={bin}"
                f"{', and 2 for the DoFP 2x2 cell' if dofp else ''}), except the last; "
                f"rechunk (e.g. to {new[0]} and {new[1]}) or pass rechunk=True")
        frames = frames.rechunk({frames.ndim - 2: new[0], frames.ndim - 1: new[1]})
    rows, cols = frames.chunks[-2], frames.chunks[-1]
    out_rows = tuple(c // bin for c in rows)
    out_cols = tuple(c // bin for c in cols)
    # Rows/columns beyond the last whole bin: dropped inside the last block.
    if sum(out_rows) != oh or sum(out_cols) != ow:  # pragma: no cover - by construction
        raise RuntimeError("internal error: block sizes do not add up to the map")

    if not dofp:
        frames = frames.reshape(t * a, height, width)
    x = frames
    if dofp and (len(rows) > 1 or len(cols) > 1):
        x = da.overlap.overlap(frames, depth={0: 0, 1: DOFP_HALO, 2: DOFP_HALO}, boundary="none")

    kw = dict(
        angles_deg=None if dofp else [float(v) for v in angles_deg],
        model_json=model_json, label=label, bin=bin,
        dark_level=[0.0 if v is None else v for v in _per_capture("dark_level", dark_level, t)],
        saturation=_per_capture("saturation", saturation, t),
        min_s0=min_s0, max_distance=max_distance, metric=metric, tile=int(tile),
    )
    common = dict(nblocks=(len(rows), len(cols)), pattern=None if pattern is None else [float(v) for v in pattern],
                  t=t, a=a, kw=kw)
    chunks = ((len(PLANES),), out_rows, out_cols)
    meta = np.empty((0, 0, 0), dtype=np.float32)
    if per_pixel:
        beta = beta_deg if isinstance(beta_deg, da.Array) else da.from_array(np.asarray(beta_deg, dtype=np.float64))
        if beta.shape != (t, oh, ow):
            raise ValueError(f"beta_deg must have shape ({t},) or ({t}, {oh}, {ow}) (one per map pixel at bin {bin}), got {beta.shape}")
        beta = beta.rechunk(((t,), out_rows, out_cols))
        stack = da.map_blocks(_block, x, beta, chunks=chunks, dtype=np.float32, meta=meta,
                              per_capture_beta=None, **common,
                              token="polarid-map")
    else:
        b = np.asarray(beta_deg, dtype=np.float64)
        if b.shape != (t,):
            raise ValueError(f"beta_deg must have shape ({t},) or ({t}, {oh}, {ow}) (one per map pixel at bin {bin}), got {b.shape}")
        stack = da.map_blocks(_block, x, chunks=chunks, dtype=np.float32, meta=meta,
                              per_capture_beta=b, **common, token="polarid-map")
    class_dtype = np.uint8 if len(class_names) <= 256 else np.uint16
    out: dict[str, Any] = {p: stack[i] for i, p in enumerate(PLANES[:5])}
    out["class"] = stack[5].astype(class_dtype)
    out["reason"] = stack[6].astype(np.uint8)
    out["class_names"] = class_names
    out["reason_names"] = reason_names
    return out
