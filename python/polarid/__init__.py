"""polarid: what a shiny surface is made of, from passive polarization images.

polarid recovers the complex refractive index ``N = n + ik`` of specular targets from
their degree of linear polarization (DoLP) measured with the light source at several
known positions, and classifies the material. The numerics are in Rust (the
``polarid._polarid`` extension); every function takes numpy arrays (or anything
``numpy.asarray`` accepts) and releases the GIL while it works.

Conventions (those of the ``polarid`` command-line program): angles in degrees,
``k >= 0``, ``S1 = I(0) - I(90)``, ``S2 = I(45) - I(135)``, Stokes images with S0, S1,
S2 on the first axis, AoLP in degrees in [0, 180). Bad input raises ``ValueError`` with
the same message as the CLI; missing files raise ``FileNotFoundError``.

Functions
---------
stokes(frames, angles_deg)
    Stokes images (3, H, W) from polarizer frames (N, H, W).
demosaic(raw, pattern, method, output)
    Stokes or per-angle images from a division-of-focal-plane mosaic.
dolp(s), aolp(s), dolp_aolp(s)
    DoLP and AoLP (degrees) of Stokes images.
dofp_dolp_aolp(raw, pattern, method)
    DoLP and AoLP straight from a DoFP mosaic (fused, no intermediate images).
stokes_color(raw, color="RGGB", pattern, method)
    Per-band S0, S1, S2, DoLP and AoLP of a colour polarization mosaic (IMX250MYR),
    as ``polarid stokes --dofp RAW --color RGGB``.
dolp_model(n, k, beta_deg), dolp_model_grad(n, k, beta_deg)
    DoLP of specular reflection, paper eq. (9) (and its gradient), with broadcasting.
pbrdf(n, k, sigma, theta_i, theta_r, phi)
    The Priest-Meier pBRDF, paper eq. (3): local and global Mueller matrices.
fit_nk(dolp, beta_deg, dolp_se=None)
    (n, k) with standard errors for one target or a stack of pixels (eq. 16).
fit_mixed(theta_i_deg, theta_r_deg, dolp, s0, ...)
    Depolarization-aware fit (specular + Lambertian diffuse) with model selection.
fit_table(measurements_csv, reflectance="auto", ...)
    Every target of a measurements CSV, as ``polarid fit``: a dict of its columns.
classify(n, k, library_or_model, wavelength_nm=None, band_axis=None)
    Material classification (paper section 6) of arrays of estimates, single- or
    multi-band (``"builtin-rgb"``, multi-band libraries and models).
classify_table(fits_csv, library_or_model, wavelength_nm=None)
    Every target of a fits CSV, as ``polarid classify``: a dict of its columns.
load_manifest(path), measure(manifest_path)
    Capture-set manifests and the per-region DoLP measurements of ``polarid measure``.
beta_map(manifest_path, capture=0)
    The per-pixel β (degrees) of a capture with calibrated geometry ([camera] and a
    ``source``), where ``load_manifest`` gives ``beta_deg`` None.
read_image(path)
    A grayscale PNG/TIFF (e.g. a raw mosaic, or an output of ``polarid stokes``) as a
    float32 array (H, W), with the readers and limits of the CLI.
simulate(plates, theta_i_deg, ...)
    Synthetic frames of plates of known (n, k, sigma).
map_manifest(manifest_path, model, bin=1, ...)
    Per-pixel (n, k) and material maps of a capture set: ``polarid map`` as arrays.

Submodule (optional dependency dask: ``pip install "./python[dask]"``)
---------------------------------------------------------------------
polarid.dask.material_map(frames, angles_deg, beta_deg, model, **options)
    The maps of ``polarid map`` as lazy dask arrays, block by block, on any Dask
    scheduler (``import polarid.dask``; not imported by ``import polarid``); colour
    mosaics per band with ``color="RGGB"``.

Large results hold no per-pixel strings: ``fit_nk`` and ``classify`` on arrays return
integer codes with their name tables (``status_code`` / ``status_names``,
``predicted_code`` / ``class_names``, ...); ``status_strings=True`` / ``strings=True``
add the str arrays.
"""

from . import _polarid
from ._polarid import *  # noqa: F403

#: The public names: the extension's (PyO3 keeps its ``__all__``), without the private
#: helpers of ``polarid.dask``.
__all__ = sorted(n for n in _polarid.__all__ if not n.startswith("_") or n == "__version__")
