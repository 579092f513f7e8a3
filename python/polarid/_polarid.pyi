"""Type stubs of the Rust extension module ``polarid._polarid``.

Numeric arguments accept a float, a nested sequence or a numpy array of any real dtype;
element-wise functions broadcast their arguments with numpy's rules and return a
``float`` when all arguments are scalars (or 0-d arrays), else a float64 array. Image
functions put S0, S1, S2 (or the per-angle images) on the first axis.
"""

import os
from collections.abc import Mapping, Sequence
from typing import Any, Literal, TypedDict, overload

import numpy as np
from numpy.typing import ArrayLike, DTypeLike, NDArray

__all__ = [
    "FIT_STATUS",
    "__version__",
    "aolp",
    "beta_map",
    "classify",
    "classify_table",
    "demosaic",
    "dofp_dolp_aolp",
    "dolp",
    "dolp_aolp",
    "dolp_model",
    "dolp_model_grad",
    "fit_mixed",
    "fit_nk",
    "fit_table",
    "load_manifest",
    "map_manifest",
    "measure",
    "pbrdf",
    "read_image",
    "simulate",
    "stokes",
    "stokes_color",
]

__version__: str
#: Status words of a fit, indexed by ``fit_nk(...)["status_code"]`` (and equal to its
#: ``status_names``).
FIT_STATUS: list[str]

_F = float | NDArray[np.float64]
_Path = str | os.PathLike[str]

# --- forward model (eq. 9) ---------------------------------------------------------
@overload
def dolp_model(n: float, k: float, beta_deg: float) -> float: ...
@overload
def dolp_model(n: ArrayLike, k: ArrayLike, beta_deg: ArrayLike) -> _F: ...
@overload
def dolp_model_grad(n: float, k: float, beta_deg: float) -> tuple[float, float, float]: ...
@overload
def dolp_model_grad(n: ArrayLike, k: ArrayLike, beta_deg: ArrayLike) -> tuple[_F, _F, _F]: ...

# --- Stokes images -------------------------------------------------------------------
@overload
def stokes(
    frames: ArrayLike,
    angles_deg: Sequence[float] | NDArray[Any],
    *,
    dark_level: float = 0.0,
    saturation: float | None = None,
    min_s0: float = 0.0,
    return_mask: Literal[False] = False,
) -> NDArray[np.float32]: ...
@overload
def stokes(
    frames: ArrayLike,
    angles_deg: Sequence[float] | NDArray[Any],
    *,
    dark_level: float = 0.0,
    saturation: float | None = None,
    min_s0: float = 0.0,
    return_mask: Literal[True],
) -> tuple[NDArray[np.float32], NDArray[np.uint8]]: ...
@overload
def demosaic(
    raw: ArrayLike,
    pattern: Sequence[float] = (90, 45, 135, 0),
    method: Literal["bilinear", "superpixel"] = "bilinear",
    output: Literal["stokes", "angles"] = "stokes",
    *,
    dark_level: float = 0.0,
    saturation: float | None = None,
    min_s0: float = 0.0,
    round: bool | None = None,
    return_mask: Literal[False] = False,
    dtype: DTypeLike | None = None,
    out: NDArray[Any] | None = None,
) -> NDArray[Any]: ...
@overload
def demosaic(
    raw: ArrayLike,
    pattern: Sequence[float] = (90, 45, 135, 0),
    method: Literal["bilinear", "superpixel"] = "bilinear",
    output: Literal["stokes"] = "stokes",
    *,
    dark_level: float = 0.0,
    saturation: float | None = None,
    min_s0: float = 0.0,
    round: bool | None = None,
    return_mask: Literal[True],
    out: NDArray[np.float32] | None = None,
) -> tuple[NDArray[np.float32], NDArray[np.uint8]]: ...
@overload
def dofp_dolp_aolp(
    raw: ArrayLike,
    pattern: Sequence[float] = (90, 45, 135, 0),
    method: Literal["bilinear", "superpixel"] = "bilinear",
    *,
    dark_level: float = 0.0,
    saturation: float | None = None,
    min_s0: float = 0.0,
    round: bool | None = None,
    return_stokes: Literal[False] = False,
    return_mask: Literal[False] = False,
    out: tuple[NDArray[np.float32], NDArray[np.float32]] | None = None,
) -> tuple[NDArray[np.float32], NDArray[np.float32]]: ...
@overload
def dofp_dolp_aolp(
    raw: ArrayLike,
    pattern: Sequence[float] = (90, 45, 135, 0),
    method: Literal["bilinear", "superpixel"] = "bilinear",
    *,
    dark_level: float = 0.0,
    saturation: float | None = None,
    min_s0: float = 0.0,
    round: bool | None = None,
    return_stokes: bool = False,
    return_mask: bool = False,
    out: tuple[NDArray[np.float32], NDArray[np.float32]] | None = None,
) -> tuple[NDArray[Any], ...]: ...
class ColorBand(TypedDict, total=False):
    """One band of ``stokes_color``: its wavelength, the asked images (float32, (H, W)
    for bilinear, (H/4, W/4) for superpixel), the mask with ``return_mask`` and the
    pixel counts (valid, saturated, dark, invalid)."""

    wavelength_nm: float
    s0: NDArray[np.float32]
    s1: NDArray[np.float32]
    s2: NDArray[np.float32]
    dolp: NDArray[np.float32]
    aolp: NDArray[np.float32]
    mask: NDArray[np.uint8]
    counts: dict[str, int]

def stokes_color(
    raw: ArrayLike,
    color: str = "RGGB",
    pattern: Sequence[float] = (90, 45, 135, 0),
    method: Literal["bilinear", "superpixel"] = "bilinear",
    *,
    bands: Mapping[str, float] | None = None,
    dark_level: float = 0.0,
    saturation: float | None = None,
    min_s0: float = 0.0,
    quantities: Sequence[Literal["s0", "s1", "s2", "dolp", "aolp"]] | None = None,
    return_mask: bool = False,
) -> dict[str, ColorBand]:
    """Per-band images of a colour polarization mosaic, keyed by band letter (R, G, B
    for RGGB), as ``polarid stokes --dofp RAW --color RGGB``."""

def dolp(s: ArrayLike) -> NDArray[np.float32] | NDArray[np.float64]: ...
def aolp(s: ArrayLike) -> NDArray[np.float32] | NDArray[np.float64]: ...
def dolp_aolp(
    s: ArrayLike,
) -> tuple[NDArray[np.float32] | NDArray[np.float64], NDArray[np.float32] | NDArray[np.float64]]: ...

# --- pBRDF (eq. 3) ---------------------------------------------------------------------
def pbrdf(
    n: ArrayLike,
    k: ArrayLike,
    sigma: ArrayLike,
    theta_i: ArrayLike,
    theta_r: ArrayLike,
    phi: ArrayLike,
) -> dict[str, Any]:
    """keys: local, global (arrays (..., 3, 3)), beta, facet_tilt (degrees), dolp."""

# --- fit (eq. 16) ----------------------------------------------------------------------
def fit_mixed(
    theta_i_deg: Sequence[float],
    theta_r_deg: Sequence[float],
    dolp: Sequence[float],
    s0: Sequence[float],
    *,
    phi_deg: float = 180.0,
    dolp_se: Sequence[float] | None = None,
    estimate_theta_r: bool = False,
    shadowing: Literal["none", "smith"] = "none",
    s0_rel_sd: float = 0.02,
) -> dict[str, Any]:
    """Specular + Lambertian diffuse fit of one target with BIC model selection.

    Returns ``selected``, ``delta_bic``, ``delta_aic`` and the ``specular`` and ``mixed``
    fits (dicts: n, k, sigma, rho_d, theta_r_deg, standard errors, status, reason).
    """

def fit_nk(
    dolp: ArrayLike,
    beta_deg: ArrayLike,
    dolp_se: ArrayLike | None = None,
    *,
    n_range: tuple[float, float] = (0.01, 10.0),
    k_range: tuple[float, float] = (0.0, 15.0),
    status_strings: bool = False,
) -> dict[str, Any]:
    """1-D dolp: floats/ints/str per key; (..., T): arrays (see the docstring), the
    status as ``status_code`` (uint8) + ``status_names`` (= FIT_STATUS), the reason as
    ``reason_code`` + ``reasons``; ``status`` (str array) only with ``status_strings``.

    ``beta_deg``: shape (T,), one angle per measurement shared by every pixel; or an
    array broadcastable to ``dolp.shape``, a β per pixel and measurement (calibrated
    geometry)."""

# --- fit of a measurements table (polarid fit) ------------------------------------------
def fit_table(
    measurements: _Path,
    *,
    reflectance: Literal["auto", "specular", "mixed"] = "auto",
    n_range: tuple[float, float] = (0.01, 10.0),
    k_range: tuple[float, float] = (0.0, 15.0),
    depolarized_dolp: float = 0.02,
    estimate_theta_r: bool = False,
    shadowing: Literal["none", "smith"] = "none",
    s0_rel_sd: float = 0.02,
    sigma_range: tuple[float, float] = (0.02, 1.0),
    angle_sd_deg: float = 0.2,
    dolp_floor: float = 0.002,
    extinction_ratio: float = 100.0,
    retardance_deg: float = 0.0,
    mismatch_p: float = 0.001,
    film_sd_nm: float | None = None,
    strict: bool = False,
) -> dict[str, list[Any]]:
    """Fit every target of a measurements CSV exactly as ``polarid fit`` does.

    The specular fit's error model (docs/ERRORS.md), as ``polarid fit``'s options:
    ``angle_sd_deg`` (``--angle-sd-deg``, degrees in [0, 90), for rows without an
    ``angle_sd_deg`` column), ``dolp_floor`` (``--dolp-floor``, in [0, 1)),
    ``extinction_ratio`` (``--extinction-ratio``, > 1, ``math.inf`` for an ideal
    polarizer), ``retardance_deg`` (``--retardance-deg``, degrees in [0, 90]) and
    ``mismatch_p`` (``--mismatch-p``, in [0, 1); 0: never ``model_mismatch``). A bad
    value raises ``ValueError`` naming it.

    Returns the columns of the fits CSV, in its order, one list element per target:
    ``target``, ``class`` (str or None), ``n``, ``k``, ``n_se``, ``k_se``, ``nk_corr``,
    ``rms_residual`` (float), ``measurements`` (int), ``status`` (a word of
    ``FIT_STATUS``), ``reason``, ``model``, ``sigma``, ``rho_d``, ``theta_r_deg``
    (float or None; mixed fit only).
    """

# --- classification --------------------------------------------------------------------
def classify(
    n: ArrayLike,
    k: ArrayLike,
    library_or_model: _Path | Sequence[tuple[str, float, float] | tuple[str, float, float, str | None]] | None = None,
    *,
    n_se: ArrayLike | None = None,
    k_se: ArrayLike | None = None,
    nk_corr: ArrayLike | None = None,
    fit_status: ArrayLike | str | None = None,
    wavelength_nm: ArrayLike | None = None,
    film_shifts: ArrayLike | None = None,
    band_axis: int | None = None,
    rule: Literal["set", "nearest"] | None = None,
    confidence: float = 0.95,
    metric: Literal["euclidean", "mahalanobis"] | None = None,
    neighbours: int = 1,
    reject: float | None = None,
    max_distance: float | None = None,
    strings: bool = False,
) -> dict[str, Any]:
    """Scalar input, keys: predicted, distance, runner_up, runner_up_distance, margin,
    status, candidates, n_candidates, category, bands_used. Array input: distance,
    runner_up_distance, margin, n_candidates and integer codes with name tables:
    predicted_code / runner_up_code (class_names), status_code (status_names),
    candidates_code (candidates_names), category_code (category_names), bands_used_code
    (bands_used_names); with ``strings=True`` also predicted, runner_up, status,
    candidates, category, bands_used as str arrays.

    ``library_or_model``: single- or multi-band (``"builtin-rgb"``, a multi-band library
    CSV or model JSON), as ``polarid classify``. ``wavelength_nm`` (NaN: none) gives
    each estimate's wavelength (the built-in libraries are evaluated there);
    ``band_axis``: the axis holding the bands of one estimate (classified on all of
    them at once; removed from the results)."""

def classify_table(
    fits: _Path,
    library_or_model: _Path | Sequence[tuple[str, float, float] | tuple[str, float, float, str | None]] | None = None,
    *,
    wavelength_nm: float | None = None,
    rule: Literal["set", "nearest"] = "set",
    confidence: float = 0.95,
    metric: Literal["euclidean", "mahalanobis"] | None = None,
    neighbours: int = 1,
    reject: float | None = None,
    max_distance: float | None = None,
) -> dict[str, list[Any]]:
    """Classify every target of a fits CSV exactly as ``polarid classify`` does (a
    target's rows with ``wavelength_nm`` together, on all their bands;
    ``wavelength_nm``: ``--wavelength-nm``). Returns the columns of the classification
    CSV: target, class, predicted, distance, runner_up, runner_up_distance, status,
    candidates (list of str), bands_used (only when some target has wavelengths),
    margin, nearest, category, metric, rule, confidence, gate, votes, reason."""

# --- files -----------------------------------------------------------------------------
def load_manifest(path: _Path) -> dict[str, Any]:
    """The validated manifest as a dict. A capture with calibrated geometry (a
    ``source``) has ``beta_deg`` None and ``calibrated`` True: its β differs from pixel to
    pixel, see ``beta_map``."""
def beta_map(manifest_path: _Path, capture: int = 0) -> NDArray[np.float32]:
    """Per-pixel β (degrees, (H, W), NaN where a pixel has no geometry) of capture
    ``capture`` (0-based) of a manifest with calibrated geometry."""
def measure(manifest_path: _Path, *, strict: bool = False) -> dict[str, NDArray[Any]]: ...
def read_image(path: _Path) -> NDArray[np.float32]: ...

# --- simulation ------------------------------------------------------------------------
def simulate(
    plates: Sequence[tuple[float, float, float] | tuple[float, float, float, float] | dict[str, float]],
    theta_i_deg: ArrayLike,
    theta_r_deg: ArrayLike | None = None,
    phi_deg: ArrayLike | None = None,
    *,
    angles_deg: Sequence[float] = (0.0, 45.0, 90.0, 135.0),
    dofp: bool = False,
    pattern: Sequence[float] = (90.0, 45.0, 135.0, 0.0),
    tile: int = 16,
    gap: int = 4,
    bit_depth: int = 12,
    full_well_e: float = 10000.0,
    read_noise_e: float = 3.0,
    dark_level_dn: float = 0.0,
    shot_noise: bool = True,
    fill: float = 0.8,
    electrons_per_unit: float | None = None,
    seed: int = 0,
) -> dict[str, Any]: ...

# --- maps ------------------------------------------------------------------------------
class MapBand(TypedDict):
    """One band of a colour map (``map_manifest(...)["bands"][450]``): the band's
    per-pixel fit, as the CLI's ``n_450.tif`` ... (float32 (H, W), NaN where not
    fitted), and why each pixel's fit of the band is not used (uint8 reason codes)."""

    wavelength_nm: float
    captures: list[int]
    n: NDArray[np.float32]
    k: NDArray[np.float32]
    n_se: NDArray[np.float32]
    k_se: NDArray[np.float32]
    rms_residual: NDArray[np.float32]
    reason: NDArray[np.uint8]
    reason_counts: NDArray[np.int64]

def map_manifest(
    manifest_path: _Path,
    model: _Path | None = None,
    *,
    library: str | None = None,
    bin: int = 1,
    min_s0: float | None = None,
    max_distance: float | None = None,
    metric: Literal["euclidean", "mahalanobis"] = "euclidean",
    tile: int = 65536,
    rule: Literal["set", "nearest"] = "set",
    confidence: float = 0.95,
    weights: Literal["auto", "noise", "none"] = "auto",
    angle_sd_deg: float = 0.2,
    dolp_floor: float = 0.002,
    extinction_ratio: float = 100.0,
    retardance_deg: float = 0.0,
) -> dict[str, Any]:
    """keys: n, k, n_se, k_se, rms_residual (float32 (H, W); single-band manifests),
    class, reason (uint8 codes), class_names, reason_names, class_counts, reason_counts,
    summary; with calibrated geometry ([camera], a source per capture) also beta_deg
    (float64 (T, H, W), every pixel's β per capture, NaN without geometry) and the
    reason no_geometry. A colour manifest (``model``: a multi-band model, or
    ``library="builtin-rgb"`` / a multi-band library CSV) gives ``bands`` instead of
    n ... rms_residual: ``{wavelength_nm: MapBand}``, and class/reason of the
    classification of every pixel on all its bands."""

# --- one block of a map (private: polarid.dask.material_map) ----------------------------
class _MapOptions(TypedDict):
    """The options of a map (``_map_names``, ``_map_block``): the prototypes (a model's
    text named by ``label``, or a library), ``polarid map``'s options and the set rule's
    error model (``angle_sd_deg``: one per capture)."""

    model_json: str | None
    library: str | None
    label: str
    max_distance: float | None
    metric: Literal["euclidean", "mahalanobis"]
    tile: int
    rule: Literal["set", "nearest"]
    confidence: float
    angle_sd_deg: Sequence[float]
    dolp_floor: float
    extinction_ratio: float
    retardance_deg: float
    bench: Literal["same", "other"]

def _map_names(
    options: _MapOptions,
    *,
    color: str | None = None,
    pattern: Sequence[float] | None = None,
    bands: Mapping[str, float] | None = None,
    bin: int = 1,
    min_s0: float | None = None,
) -> tuple[list[str], list[str], list[float]]: ...
class _BlockArgs(TypedDict):
    """One block's frames and the options of its DoLP stage (``_map_block``,
    ``_noise_block``)."""

    frames: ArrayLike
    angles_deg: Sequence[float] | None
    beta_deg: ArrayLike
    pattern: Sequence[float] | None
    color: str | None
    bands: Mapping[str, float] | None
    halo: tuple[int, int, int, int]
    bin: int
    dark_level: Sequence[float] | None
    saturation: Sequence[float | None] | None
    min_s0: float | None

def _map_block(
    block: _BlockArgs,
    options: _MapOptions,
    *,
    noise: list[tuple[float, float] | None] | None = None,
) -> NDArray[np.float32]: ...

_NOISE_SAMPLE: int
_MAP_DEFAULTS: dict[str, float | int]

def _noise_block(
    block: _BlockArgs,
    *,
    band: int = 0,
    row_offsets: Sequence[int] | None = None,
    stride: int = 1,
) -> list[int] | tuple[list[int], list[list[list[float]]]]: ...
def _estimate_noise(
    dolp: Sequence[Sequence[float]],
    read: Sequence[Sequence[float]],
    shot: Sequence[Sequence[float]],
    *,
    beta_deg: Sequence[float] | None = None,
    beta_rad: Sequence[Sequence[float]] | None = None,
) -> tuple[float, float, int, int, float] | None: ...
