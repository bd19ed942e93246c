"""The parts `jaxhyst.identify` is made of, for fits it does not cover.

`identify` runs a particle swarm (`jaxhyst.MPSO`) over a `SearchBox` (`search`,
`starting_points`, `run_swarm` with its `SwarmState` and `SwarmResult`), then
polishes the best particles (`refine`, one `PolishStage` at a time, each giving a
`PolishResult`), on a `Problem` that holds one or several records
(`stack_problems`, `joint_scales`, `RecordSimulation`, `swarm_samples_per_step`),
and scores the fit on each record (`RecordingMetrics`). The identifiability of a
fit's parameters (`identifiability`, `identifiability_of`, `Identifiability`,
`covariance`, `output_jacobian`) and the corrected piezo model's staged fit
(`identify_corrected`, `CORRECTED_STAGES`) are here too.
"""

from ._identification._corrected import (
    CORRECTED_STAGES as CORRECTED_STAGES,
    identify_corrected as identify_corrected,
)
from ._identification._identifiability import (
    Identifiability as Identifiability,
    covariance as covariance,
    identifiability as identifiability,
    identifiability_of as identifiability_of,
    output_jacobian as output_jacobian,
)
from ._identification._identify import (
    PolishStage as PolishStage,
    RecordingMetrics as RecordingMetrics,
    joint_scales as joint_scales,
    refine as refine,
    search as search,
    starting_points as starting_points,
)
from ._identification._polish import PolishResult as PolishResult
from ._identification._problem import (
    Problem as Problem,
    RecordSimulation as RecordSimulation,
    stack_problems as stack_problems,
    swarm_samples_per_step as swarm_samples_per_step,
)
from ._models.base import SearchBox as SearchBox
from ._swarm import (
    SwarmResult as SwarmResult,
    SwarmState as SwarmState,
    run_swarm as run_swarm,
)


__all__ = [
    "CORRECTED_STAGES",
    "Identifiability",
    "PolishResult",
    "PolishStage",
    "Problem",
    "RecordSimulation",
    "RecordingMetrics",
    "SearchBox",
    "SwarmResult",
    "SwarmState",
    "covariance",
    "identifiability",
    "identifiability_of",
    "identify_corrected",
    "joint_scales",
    "output_jacobian",
    "refine",
    "run_swarm",
    "search",
    "stack_problems",
    "starting_points",
    "swarm_samples_per_step",
]
