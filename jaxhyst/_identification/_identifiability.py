"""What a record can determine about a model: the output's sensitivities to its
parameters (`output_jacobian`, the one implementation), their singular values and
null directions, and the covariance of the fitted parameters (`covariance`)."""

from collections.abc import Callable, Sequence
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._inputs import InputPath
from .._models.base import AbstractHysteresisModel
from .._simulate import RK4, AbstractSimulationSolver
from ._problem import RecordSimulation


# Directions of the column-scaled Jacobian with a relative singular value below
# this are not determined by the record; parameters loading on them get NaN.
UNDETERMINED = 1e-7
# A parameter loads on a direction when its weight in it exceeds this; on an exact
# null direction (relative singular value below EXACT) any weight above 1e-6 does.
LOADING = 0.1
EXACT = 1e-10


@eqx.filter_jit
def _jacobian(model, names, outputs):
    values = jnp.stack([jnp.asarray(getattr(model, n), float) for n in names])

    def simulated(v):
        new = eqx.tree_at(
            lambda m: [getattr(m, n) for n in names],
            model,
            [v[i] for i in range(len(names))],
        )
        return outputs(new)

    # One forward pass carries the outputs and a tangent per parameter (`jacfwd`
    # and a separate call for the outputs traced and compiled the simulation twice).
    def push(direction):
        return jax.jvp(simulated, (values,), (direction,))

    basis = jnp.eye(values.shape[0], dtype=values.dtype)
    outputs_at, columns = jax.vmap(push, out_axes=(None, -1))(basis)
    return columns, outputs_at


def output_jacobian(
    model: AbstractHysteresisModel,
    names: Sequence[str],
    outputs: Callable[[AbstractHysteresisModel], Array],
) -> tuple[Float[np.ndarray, "n p"], Float[np.ndarray, " n"]]:
    """d outputs(model) / d parameter for the parameters `names` (columns, in that
    order; NaN/inf entries become 0), and outputs(model) itself. `outputs` is a
    module (e.g. `RecordSimulation`) or a bound method of one, so repeated calls with
    the same structure reuse one compilation."""
    jac, y = _jacobian(model, tuple(names), outputs)
    return np.nan_to_num(np.asarray(jac)).reshape(-1, len(names)), np.asarray(
        y
    ).reshape(-1)


def covariance(
    jacobian: Float[np.ndarray, "n p"], sigma2: float
) -> tuple[Float[np.ndarray, " p"], Float[np.ndarray, "p p"]]:
    """Standard errors and correlations of the parameters whose output sensitivities
    are the columns of `jacobian`, from sigma^2 (J^T J)^-1 (a pseudo-inverse over the
    determined directions). NaN for parameters that load on directions the record
    does not determine (relative singular value below `UNDETERMINED`)."""
    p = jacobian.shape[1]
    if p == 0:
        return np.zeros(0), np.zeros((0, 0))
    norms = np.linalg.norm(jacobian, axis=0)
    safe = np.where(norms > 0, norms, 1.0)
    _, singular, vt = np.linalg.svd(jacobian / safe, full_matrices=False)
    relative = singular / singular[0] if singular[0] > 0 else np.zeros_like(singular)
    good = relative > UNDETERMINED
    scaled = (vt[good].T / singular[good] ** 2) @ vt[good] * sigma2
    cov = scaled / np.outer(safe, safe)
    se = np.sqrt(np.abs(np.diag(cov)))
    weight = np.where((relative < EXACT)[:, None], 1e-6, LOADING)
    loads = np.any((np.abs(vt) > weight) & ~good[:, None], axis=0) | (norms == 0)
    se = np.where(loads, np.nan, se)
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(se, se)
    return se, corr


class Identifiability(eqx.Module):
    """What the data can and cannot determine, read off the output's Jacobian with
    respect to the *relative* change of every model parameter (d y / d log|theta|).

    - `singular_values`: of the column-scaled Jacobian, largest first, relative to the
      largest.
    - `unidentifiable`: one dict per direction whose relative singular value is below
      `threshold`: parameter name -> weight (a unit vector in relative changes). For
      the piezo model the scaling symmetry shows up as k2 : A1 : beta1 : gamma1 =
      -1 : 1 : (1-n) : (1-n).
    - `correlations`: parameter correlation matrix of the free (fitted) parameters.
    - `standard_errors`: of the free parameters, from sigma^2 (J^T J)^-1 with sigma the
      noise (default: the residual RMS); NaN for parameters on directions the record
      does not determine.
    """

    names: tuple[str, ...]
    singular_values: np.ndarray
    unidentifiable: list[dict[str, float]]
    free_names: tuple[str, ...]
    correlations: np.ndarray
    standard_errors: dict[str, float]
    threshold: float

    def to_dict(self) -> dict[str, Any]:
        return {
            "parameters": list(self.names),
            "relative_singular_values": [float(v) for v in self.singular_values],
            "threshold": self.threshold,
            "unidentifiable_directions": self.unidentifiable,
            "free_parameters": list(self.free_names),
            "standard_errors": self.standard_errors,
            "correlations": [[float(c) for c in row] for row in self.correlations],
        }


def identifiability(
    model: AbstractHysteresisModel,
    outputs: Callable[[AbstractHysteresisModel], Array] | InputPath,
    measured: Float[Array, "*records n"],
    *,
    free: Sequence[str] | None = None,
    solver: AbstractSimulationSolver = RK4(),
    weights: Float[Array, "*records n"] | None = None,
    noise_sigma: float | None = None,
    threshold: float = 1e-6,
) -> Identifiability:
    """Identifiability of `model` at its current parameters for the output map
    `outputs` (e.g. `Problem.simulated`; an `InputPath` means
    `RecordSimulation(outputs, solver)`) against `measured`; samples with zero `weights` are left out. Parameters equal to
    zero get an absolute (not relative) column. `noise_sigma` is the output noise
    for the standard errors (default: the residual RMS). Raise `threshold` to flag
    directions that are merely poorly determined."""
    names = tuple(model.parameter_names)
    if isinstance(outputs, InputPath):
        outputs = RecordSimulation(outputs, solver)
    jac, simulated = output_jacobian(model, names, outputs)
    return identifiability_of(
        model,
        jac,
        simulated - np.asarray(measured).reshape(-1),
        free=free,
        weights=weights,
        noise_sigma=noise_sigma,
        threshold=threshold,
    )


def identifiability_of(
    model: AbstractHysteresisModel,
    jacobian: Float[np.ndarray, "n p"],
    residual: Float[np.ndarray, " n"],
    *,
    free: Sequence[str] | None = None,
    weights: Float[Array, "*records n"] | None = None,
    noise_sigma: float | None = None,
    threshold: float = 1e-6,
) -> Identifiability:
    """`identifiability` from a Jacobian already computed (`output_jacobian` over all
    of `model.parameter_names`) and the residual (simulated - measured) at it."""
    names = tuple(model.parameter_names)
    free = names if free is None else tuple(free)
    jac = jacobian
    if weights is not None:
        keep = np.asarray(weights).reshape(-1) != 0
        jac, residual = jac[keep], residual[keep]
    values = np.array([float(getattr(model, n)) for n in names])
    # Signed scale: column j is d y / d log|theta_j| (an absolute column at zero).
    relative_jac = jac * np.where(values != 0, values, 1.0)
    norm = np.linalg.norm(relative_jac, axis=0)
    safe = np.where(norm > 0, norm, 1.0)
    _, sv, vt = np.linalg.svd(relative_jac / safe, full_matrices=False)
    relative = sv / sv[0] if sv[0] > 0 else sv
    null = []
    for s, v in zip(relative, vt):
        if s < threshold:
            v = v / safe  # back to relative changes
            v = v / v[np.argmax(np.abs(v))]
            null.append(
                {n: round(float(w), 6) for n, w in zip(names, v) if abs(w) > 1e-3}
            )
    if noise_sigma is None:
        dof = max(1, residual.size - len(free))
        sigma2 = float(np.sum(residual**2) / dof)
    else:
        sigma2 = float(noise_sigma) ** 2
    se, corr = covariance(jac[:, [names.index(n) for n in free]], sigma2)
    return Identifiability(
        names,
        relative,
        null,
        free,
        corr,
        {n: float(e) for n, e in zip(free, se)},
        threshold,
    )
