"""Identification from periodic records (multisines), as in the Bouc-Wen benchmark.

`average_periods` folds a record of repeated periods into one averaged period
(`PeriodicAverage`, with the noise measured from the spread between periods);
`PeriodicSimulation` runs a model to periodic steady state (`SteadyOutput`), with
the input rebuilt between samples by `bandlimited_upsample`; `fit_periodic` is
`jaxhyst.identify` for such records (on a `periodic_problem`), with
`periodic_identifiability` at its result; `oscillator_space` is the search space
of the benchmark's oscillator.
"""

from ._identification._periodic import (
    PeriodicAverage as PeriodicAverage,
    PeriodicSimulation as PeriodicSimulation,
    SteadyOutput as SteadyOutput,
    average_periods as average_periods,
    bandlimited_upsample as bandlimited_upsample,
    fit_periodic as fit_periodic,
    oscillator_space as oscillator_space,
    periodic_identifiability as periodic_identifiability,
    periodic_problem as periodic_problem,
)


__all__ = [
    "PeriodicAverage",
    "PeriodicSimulation",
    "SteadyOutput",
    "average_periods",
    "bandlimited_upsample",
    "fit_periodic",
    "oscillator_space",
    "periodic_identifiability",
    "periodic_problem",
]
