"""The paper's two-stage fit of the corrected (asymmetric) piezo model, plus a joint
polish: one function for the command line, the benchmarks and the notebooks."""

from collections.abc import Sequence

import jax
from jaxtyping import PRNGKeyArray

from .._models.bouc_wen import CorrectedPiezoBoucWen, PiezoBoucWen
from .._params import ParameterSpace
from .._recording import Recording
from .._swarm import MPSO
from ._identify import Fit, identify, joint_scales


CORRECTED_STAGES = (
    "piezo: all six by swarm + polish",
    "corrected: phi, eps by swarm + polish, the rest fixed",
    "corrected: all eight jointly, polished from stage 2",
)


def identify_corrected(
    recording: Recording | Sequence[Recording],
    *,
    key: PRNGKeyArray,
    swarm: MPSO = MPSO(num_particles=100, num_iterations=200),
    progress: bool = False,
) -> tuple[Fit, tuple[Fit, Fit, Fit]]:
    """The paper's stages (`CORRECTED_STAGES`): the plain piezo model (eq. 7-8) by
    swarm and polish; then (phi, eps) in the corrected model's default bounds by the
    swarm, the rest fixed at stage 1 (seeded with phi = eps = 0); then all eight
    polished jointly from there. Returns the final fit and the three stages' fits
    (statuses kept, `throw=False`: inspect `fit.result`)."""
    records = [recording] if isinstance(recording, Recording) else list(recording)
    first = identify(
        PiezoBoucWen(1.0, 1.0, 1.0, 1.0, 1.0, 1.5),
        records,
        key=jax.random.fold_in(key, 0),
        swarm=swarm,
        analyse=False,
        progress=progress,
        throw=False,
    )
    template = CorrectedPiezoBoucWen.from_piezo(first.model)
    box = template.default_bounds(joint_scales(records))
    space = ParameterSpace(template, {n: box.bounds[n] for n in ("phi", "eps")})
    second = identify(
        template,
        records,
        key=jax.random.fold_in(key, 1),
        space=space,
        swarm=swarm,
        start=template,  # phi = eps = 0, stage 1's fit, unless the swarm beats it
        analyse=False,
        progress=progress,
        throw=False,
    )
    joint = identify(
        template,
        records,
        key=jax.random.fold_in(key, 2),
        swarm=None,
        start=second.model,
        throw=False,
    )
    return joint, (first, second, joint)
