"""polarid: what a shiny surface is made of, from passive polarization images.

polarid recovers the complex refractive index ``N = n + ik`` of specular targets from
their degree of linear polarization (DoLP) measured with the light source at several
known positions, and classifies the material. The numerics are in Rust (the
``polarid._polarid`` extension); every function takes numpy arrays (or anything
``numpy.asarray`` accepts), computes in float64 and releases the GIL while it works.

Conventions (those of the ``polarid`` command-line program): angles in degrees,
``k >= 0``, ``S1 = I(0) - I(90)``, ``S2 = I(45) - I(135)``. Bad input raises
``ValueError`` with the same message as the CLI; missing files raise
``FileNotFoundError``.

Functions
---------
dolp_model(n, k, beta_deg)
    DoLP of specular reflection, paper eq. (9), with numpy broadcasting.
dolp_model_grad(n, k, beta_deg)
    ``(P, dP/dn, dP/dk)`` of eq. (9).
"""

from ._polarid import __version__, dolp_model, dolp_model_grad

__all__ = ["__version__", "dolp_model", "dolp_model_grad"]
