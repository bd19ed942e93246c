"""The recordings a diagnosis reads, as its stages see them.

Every sample-wise stage (hold-out masks, score test, noise model, location, what
is left) reads one flat vector: the recordings' samples one after another, the
`joined` record. The simulation does not run on the joined record: each recording
is simulated from its own initial state (a stacked input path, vmapped over
recordings, shorter ones padded and the padding dropped), so no state carries
over from the end of one test to the start of the next.

Recordings at different sample rates are read the same way: each is simulated at
its own sample interval (the stacked path's `dt` is one per record, and the vmapped
RK4 steps each record by its own), none resampled. The joined vector then runs at
the finest recording's step (`Recording.join(..., mixed_rates=True)`), so where a
stage needs one rate it reads that one: the refit bounds' fastest time scale, the
score test's derivative directions (a direction mis-scaled on part of the vector
costs the test power, not validity: the refits and held-out checks simulate every
record at its own rate). The refits' stride is the smallest any recording asks
for, and the slowest time scale is the recordings' total duration.
"""

from collections.abc import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._identification._identifiability import output_jacobian
from .._identification._problem import RecordSimulation, stack_inputs
from .._inputs import InputPath
from .._models.base import AbstractHysteresisModel
from .._recording import _UNIFORM_RTOL, Recording, RecordingError
from .._simulate import AbstractSimulationSolver, simulate
from ._families import AbstractFamily
from ._score import jacobian, predict


class StackedSimulation(eqx.Module):
    """A model's output at every sample of several input paths stacked on a leading
    axis (`(records, n)`, padding included): `StackedSimulation(inputs, solver)(model)`."""

    inputs: InputPath
    solver: AbstractSimulationSolver

    def __call__(self, model: AbstractHysteresisModel) -> Float[Array, "r n"]:
        return jax.vmap(lambda path: simulate(model, path, self.solver, throw=False))(
            self.inputs
        )


@eqx.filter_jit
def _simulated(simulation, model):
    return simulation(model)


# How many models of one structure `predict_each` simulates in one program: one
# sequential simulation leaves the 2-core CPU's vector units mostly idle, and 8
# side by side took 11-16 ms per model on a 45 000-sample piezo record against
# 48-85 ms one at a time (16 were no faster per model).
BATCH = 8


@eqx.filter_jit
def _simulated_batch(simulation, models):
    return eqx.filter_vmap(simulation)(models)


class DiagnosisRecords(eqx.Module):
    """One recording, or several of one specimen, as a diagnosis reads them.

    `joined` holds every recording's samples in the order given (time continued
    across the joins), the vector every stage analyses; `inputs` is the input path
    the simulation runs on: the recording's own for one recording, the recordings'
    paths stacked on a leading axis for several (shorter ones padded); `valid` marks
    the stacked samples that are real.
    """

    recordings: tuple[Recording, ...]
    joined: Recording
    inputs: InputPath
    valid: np.ndarray | None

    @classmethod
    def of(cls, recordings: tuple[Recording, ...], owner: str) -> "DiagnosisRecords":
        """Check that `recordings` can be read as one specimen's tests and join
        them."""
        if len(recordings) == 1:
            only = recordings[0]
            return cls(recordings, only, only.input_path(), None)
        try:
            joined = Recording.join(recordings, mixed_rates=True)
        except RecordingError as error:
            raise ValueError(f"{owner}: {error}") from None
        length = max(r.num_samples for r in recordings)
        valid = (
            np.arange(length)[None, :]
            < np.array([r.num_samples for r in recordings])[:, None]
        )
        paths = [r.input_path() for r in recordings]
        return cls(recordings, joined, stack_inputs(paths), valid)

    @property
    def several(self) -> bool:
        return self.valid is not None

    @property
    def one_input(self) -> InputPath:
        """The first recording's input path (for checks that read one path)."""
        if self.valid is None:
            return self.inputs
        return jax.tree.map(lambda x: x[0], self.inputs)

    @property
    def mixed_rates(self) -> bool:
        """True when the recordings differ in sample rate (as `Recording.join`
        tells them apart)."""
        first = self.recordings[0].dt
        return any(abs(r.dt - first) > _UNIFORM_RTOL * first for r in self.recordings)

    @property
    def step(self) -> float:
        """The joined vector's sample interval: the recording's own for one rate,
        the finest recording's for several rates."""
        if not self.mixed_rates:
            return float(self.one_input.dt)
        return float(self.joined.dt)

    @property
    def duration(self) -> float:
        """The joined record's duration, or for several rates (whose joined time is
        compressed) the recordings' durations added up."""
        if not self.mixed_rates:
            return self.joined.duration
        return float(sum(r.duration for r in self.recordings))

    def stride(self, family: AbstractFamily, model: AbstractHysteresisModel) -> int:
        """The family's refit stride (`refit_stride`) for the joined record, or for
        several rates the smallest any recording asks for (one stride in samples
        steps every record; the slowest record's keeps its own resolution)."""
        if not self.mixed_rates:
            return family.refit_stride(model, self.joined)
        return min(family.refit_stride(model, r) for r in self.recordings)

    @property
    def samples_per_record(self) -> int:
        """The length of the simulated paths (the longest recording's)."""
        return int(self.inputs.values.shape[-1])

    def flat(self, stacked) -> np.ndarray:
        """Per-sample values on the simulated paths as the joined vector."""
        stacked = np.asarray(stacked)
        if self.valid is None:
            return stacked
        rows = stacked.reshape(self.valid.size, *stacked.shape[2:])
        return rows[self.valid.reshape(-1)]

    def stacked(self, joined) -> Array:
        """Per-sample values on the joined vector as the simulated paths hold them
        (zero on the padding)."""
        joined = jnp.asarray(joined)
        if self.valid is None:
            return joined
        out = jnp.zeros(self.valid.shape, joined.dtype)
        return out.at[np.nonzero(self.valid)].set(joined)

    def split(self, joined: np.ndarray) -> list[np.ndarray]:
        """The joined vector cut back into one array per recording."""
        ends = np.cumsum([r.num_samples for r in self.recordings])[:-1]
        return np.split(np.asarray(joined), ends)

    def predict(
        self, model: AbstractHysteresisModel, solver: AbstractSimulationSolver
    ) -> np.ndarray:
        """The model's output at every sample of the joined vector (NaN/inf where it
        diverges), each recording simulated from its own initial state."""
        if self.valid is None:
            return predict(model, self.inputs, solver)
        return self.flat(_simulated(StackedSimulation(self.inputs, solver), model))

    def predict_each(
        self,
        models: Sequence[AbstractHysteresisModel],
        solver: AbstractSimulationSolver,
    ) -> list[np.ndarray]:
        """`predict` of each of `models`, in order: those of one structure (the same
        class and static fields) simulated `BATCH` at a time in one program, a
        short batch padded with copies of its last model (a lone model runs as
        `predict`)."""
        simulation = (
            RecordSimulation(self.inputs, solver)
            if self.valid is None
            else StackedSimulation(self.inputs, solver)
        )
        groups: dict[object, list[int]] = {}
        for index, model in enumerate(models):
            groups.setdefault(jax.tree.structure(model), []).append(index)
        predicted: list[np.ndarray] = [np.empty(0)] * len(models)
        for indices in groups.values():
            for first in range(0, len(indices), BATCH):
                chunk = indices[first : first + BATCH]
                if len(chunk) == 1:  # a batch would cost more than it saves
                    predicted[chunk[0]] = self.predict(models[chunk[0]], solver)
                    continue
                rows = [models[i] for i in chunk]
                rows += [rows[-1]] * (BATCH - len(rows))
                stacked = jax.tree.map(lambda *leaves: jnp.stack(leaves), *rows)
                outputs = np.asarray(_simulated_batch(simulation, stacked))
                for row, index in enumerate(chunk):
                    predicted[index] = self.flat(outputs[row])
        return predicted

    def jacobian(
        self, model: AbstractHysteresisModel, names, solver: AbstractSimulationSolver
    ) -> np.ndarray:
        """d output / d parameter for `names` on the joined vector."""
        if self.valid is None:
            return jacobian(model, names, self.inputs, solver)
        jac, _ = output_jacobian(model, names, StackedSimulation(self.inputs, solver))
        return jac[self.valid.reshape(-1)]
