"""A fitted model on a recording: the solver it is simulated with, and its output.

`jaxhyst fit`, `evaluate` and `compensate` simulate a kind of model with one
solver, so that a saved model is evaluated (and inverted) as it was fitted.
"""

import numpy as np

from ._models.base import AbstractHysteresisModel
from ._recording import Recording
from ._simulate import RK4, simulate


def default_solver(model: AbstractHysteresisModel, recording: Recording) -> RK4:
    """The solver `jaxhyst fit` / `diagnose` simulate this kind of model with
    (`model.default_solver(recording)`): RK4 with 4 substeps for `PiezoStage` (its
    stage is stiff on the sample scale), the structural family's substeps for
    `BoucWen` and `StructuralBoucWen`, the model's own `recommended_substeps` for
    the MR damper models (their internal dashpot and sharp loops are stiff at kHz
    sample rates) and the damper family's substeps for `ExtendedDamper` (what
    `diagnose` fitted it with), else one RK4 step per sample."""
    return model.default_solver(recording)


def predict(
    model: AbstractHysteresisModel,
    recording: Recording,
    solver: RK4 | None = None,
) -> np.ndarray:
    """The model's output under the recording's input, from rest (`solver`:
    `default_solver` unless given). Not checked: a diverged model gives non-finite
    values."""
    if solver is None:
        solver = default_solver(model, recording)
    return np.asarray(simulate(model, recording.input_path(), solver, throw=False))
