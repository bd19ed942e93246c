"""Error measures between a measured output `y` and a model output `yhat`.

The paper's measures one at a time (`mad`, `mae`, `mrd`, `nrmsd`, `rmse`, eq. 12
and 15) and the sum of squared errors a fit minimises (`sum_squared_error`), all
written with `jax.numpy` so they work inside `jax.jit` and `jax.grad`. For a
report's table of all of them at once use `jaxhyst.error_metrics`; for the error's
spectrum, `jaxhyst.error_spectrum`.
"""

from ._metrics import (
    mad as mad,
    mae as mae,
    mrd as mrd,
    nrmsd as nrmsd,
    rmse as rmse,
)
from ._simulate import sum_squared_error as sum_squared_error


__all__ = ["mad", "mae", "mrd", "nrmsd", "rmse", "sum_squared_error"]
