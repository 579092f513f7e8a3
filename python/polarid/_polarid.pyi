"""Type stubs of the Rust extension module ``polarid._polarid``.

Every numeric argument accepts a float, a nested sequence or a numpy array of any real
dtype (converted to float64); arguments broadcast together with numpy's rules. A result
is a ``float`` when all arguments are scalars (or 0-d arrays), else a float64 array.
"""

from typing import overload

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["__version__", "dolp_model", "dolp_model_grad"]

__version__: str

_F = float | NDArray[np.float64]

@overload
def dolp_model(n: float, k: float, beta_deg: float) -> float: ...
@overload
def dolp_model(n: ArrayLike, k: ArrayLike, beta_deg: ArrayLike) -> _F: ...
@overload
def dolp_model_grad(n: float, k: float, beta_deg: float) -> tuple[float, float, float]: ...
@overload
def dolp_model_grad(n: ArrayLike, k: ArrayLike, beta_deg: ArrayLike) -> tuple[_F, _F, _F]: ...
