"""jaxhyst: Bouc-Wen hysteresis models in JAX — simulate, identify, diagnose."""

import importlib.metadata

from ._inputs import (
    AbstractInterpolation as AbstractInterpolation,
    CubicInterpolation as CubicInterpolation,
    InputPath as InputPath,
    LinearInterpolation as LinearInterpolation,
)
from ._smoothing import (
    AbstractSmoothing as AbstractSmoothing,
    AlgebraicSign as AlgebraicSign,
    ExactSign as ExactSign,
    TanhSign as TanhSign,
)

# [recording-exports]
# [signals-exports]
# [swarm-exports]
# [core-exports]


__version__ = importlib.metadata.version("jaxhyst")
