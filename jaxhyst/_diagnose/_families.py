"""A family: a base model, its catalogue of effects, and how its records are read.

The engine (`diagnose`) knows nothing about piezo stages or structural tests; it
asks the family for the base fit, the extended model with every effect off, the
hold-out split, the solver, and where a residual lives.
"""

import abc
import math
from typing import Any, ClassVar

import equinox as eqx
import numpy as np

from .._models.base import AbstractHysteresisModel
from .._models.bouc_wen import BoucWen, PiezoBoucWen
from .._models.damper import BoucWenDamper
from .._models.damper_extended import ExtendedDamper
from .._models.extended import ExtendedPiezo
from .._models.structural import StructuralBoucWen
from .._opensees import opensees_json
from .._params import ParameterSpace
from .._recording import Recording
from .._simulate import RK4
from .._swarm import MPSO
from ._effects.asymmetry import Asymmetry
from ._effects.base import AbstractEffect, model_as
from ._effects.creep import Creep
from ._effects.damper_asymmetry import DamperAsymmetry
from ._effects.damper_offset import DamperOffset
from ._effects.degradation import Degradation
from ._effects.drift import Drift
from ._effects.driver_lag import DriverLag
from ._effects.dynamics import Dynamics
from ._effects.field_dependence import FieldDependence
from ._effects.input_bias import InputBias
from ._effects.pinching import Pinching
from ._effects.push_pull import PushPullAsymmetry
from ._effects.rate_dependence import RateDependence
from ._effects.rolloff import Rolloff
from ._locate import describe, describe_cycles, locate, locate_cycles
from ._locate_damper import describe_damper, locate_damper
from ._loop_indicators import LoopIndicators, loop_indicators
from ._policy import AdoptionPolicy
from ._probes import Probe, cyclic_probes, piezo_probes
from ._probes_damper import damper_probes
from ._residual_probes import (
    ResidualProbe,
    command_history_probe,
    excursion_probe,
    loop_probe,
    velocity_command_probe,
)


class AbstractFamily(eqx.Module):
    """A base model plus the catalogue of physics it can leave out.

    `catalogue` holds the effect objects in the order they are scored and
    reported; `name` is the family's stable identifier and `base_name` the base
    model's name in the `jaxhyst diagnose` JSON.
    """

    name: ClassVar[str]
    base_name: ClassVar[str]
    # The base parameters a refit moves (the gauge parameter stays fixed).
    base_free: ClassVar[tuple[str, ...]]
    gauge: ClassVar[tuple[str, ...]]
    # How `holdout` splits a record, in words (for reports).
    holdout_description: ClassVar[str]
    catalogue: eqx.AbstractVar[tuple[AbstractEffect, ...]]
    # Whether the base fit and every refit keep the model's Bouc-Wen shape inside
    # Table 2's BIBO-stable classes (`ParameterSpace(stable_shape=True)`: hard
    # floors on beta and gamma; `Problem.stable_only`: the swarm and the polish's
    # best skip the rest). Set it where a model outside them is not a material
    # this family's users can run: its hysteretic force grows without bound.
    stable_fits: ClassVar[bool] = False

    @property
    def effect_names(self) -> tuple[str, ...]:
        return tuple(e.name for e in self.catalogue)

    def effect(self, name: str) -> AbstractEffect:
        """The catalogue's effect called `name`."""
        for effect in self.catalogue:
            if effect.name == name:
                return effect
        raise ValueError(
            f"{type(self).__name__}: no effect {name!r}; the catalogue has "
            f"{list(self.effect_names)}."
        )

    def __check_init__(self):
        names = [e.name for e in self.catalogue]
        if len(set(names)) != len(names):
            raise ValueError(f"{type(self).__name__}: effect names repeat: {names}.")

    @abc.abstractmethod
    def check(self, recording: Recording) -> None:
        """Raise ValueError if `recording` is the wrong kind for this family."""

    @abc.abstractmethod
    def base_template(self) -> AbstractHysteresisModel:
        """The base model class `identify` fits (its values are unused)."""

    def default_policy(self) -> AdoptionPolicy:
        """The adoption rules `diagnose` uses unless given a policy."""
        return AdoptionPolicy()

    def cannot_show(self, recording: Recording) -> dict[str, str]:
        """The catalogue effects this recording cannot show, each with the reason
        (in words a user can act on). `diagnose` does not score them and says so
        (`Diagnosis.cannot_show`). None by default."""
        return {}

    def residual_probes(self, recording: Recording) -> tuple[ResidualProbe, ...]:
        """Bins of what this family's residual may be a function of, beside the
        input's level and direction and a slow function of time (which every
        family's unexplained-structure check reads). None by default."""
        return ()

    def form_probes(self, recording: Recording) -> tuple[ResidualProbe, ...]:
        """Bins of what a difference between a named effect's form and the
        catalogue's may be a function of: the model-free form corrections that an
        effect adopted after others must beat (`AdoptionPolicy.form_correction`).
        By default the input's level and direction and `residual_probes`."""
        return (loop_probe(recording), *self.residual_probes(recording))

    def base_swarm(self) -> MPSO:
        """The base fit's swarm `diagnose` uses unless given one."""
        return MPSO(num_particles=100, num_iterations=200)

    def base_swarm_alternatives(self) -> tuple[MPSO, ...]:
        """Further swarms a windowed base start (`base_swarm_window`) runs, one key
        each, beside `base_swarm`'s two, when `diagnose` is given no swarm; the
        start with the lowest error on the window is kept. None by default."""
        return ()

    def base_starts(
        self, recording: Recording, window: Recording
    ) -> tuple[AbstractHysteresisModel, ...]:
        """Base models, in `base_space(recording)`, that a windowed base start
        (`base_swarm_window`) also polishes on `window` (the record's first
        samples), beside its swarms' best: starts the physics suggests, for a base
        whose swarm can stop in a wrong basin. The lowest error on the window is
        kept. None by default."""
        return ()

    def base_swarm_window(self, recording: Recording) -> int | None:
        """None: the base fit's swarm reads the whole record, decimated as `identify`
        chooses. A number n: the swarm reads the record's first n samples at the
        full rate instead (then the polish fits every sample), for models whose
        dynamics a coarser step would bias."""
        return None

    def base_space(self, recording: Recording) -> ParameterSpace | None:
        """The base fit's parameter space; None: `ParameterSpace.default`."""
        return None

    def base_swarm_space(self, recording: Recording) -> ParameterSpace | None:
        """The space the base swarm searches when it is not `base_space` (a
        parametrisation whose good region is not a sliver of the box); its best
        model goes through `base_gauge` and the polish runs in `base_space` from it.
        None: the swarm searches `base_space`."""
        return None

    def base_gauge(self, model: AbstractHysteresisModel) -> AbstractHysteresisModel:
        """A model from `base_swarm_space` written in `base_space`'s gauge."""
        return model

    @abc.abstractmethod
    def extend(
        self, base: AbstractHysteresisModel, recording: Recording
    ) -> AbstractHysteresisModel:
        """The extended model with every effect off around a fitted base model."""

    @abc.abstractmethod
    def solver(self, recording: Recording) -> RK4:
        """The solver of every simulation the diagnosis runs."""

    @abc.abstractmethod
    def holdout(self, recording: Recording, fraction: float) -> np.ndarray:
        """The fit mask (True: fitted; False: held out, about `fraction`)."""

    @abc.abstractmethod
    def locate(self, recording: Recording, residual: np.ndarray) -> dict[str, Any]:
        """Where `residual` lives on this kind of record."""

    @abc.abstractmethod
    def describe(self, where: dict[str, Any]) -> str:
        """`locate`'s result as one sentence."""

    @abc.abstractmethod
    def probes(self, recording: Recording) -> list[Probe]:
        """Tests this family's users could run next to separate effects the
        record cannot tell apart (simulated, never assumed, to check the advice)."""

    def base_bounds(self, name: str, value: float) -> tuple[float, float] | None:
        """Refit bounds of a base parameter, or None for the engine's rule."""
        if name == "n":
            return (1.0, 4.0)
        return None

    @abc.abstractmethod
    def refit_stride(self, model: AbstractHysteresisModel, recording: Recording) -> int:
        """Every how many samples a refit compares (1: all)."""

    def exports(
        self, model: AbstractHysteresisModel, recording: Recording
    ) -> dict[str, Any]:
        """Extra keys of the diagnosis JSON that turn the final model into what this
        family's users run (none by default)."""
        return {}

    def loop_indicators(self, recording: Recording) -> LoopIndicators | None:
        """Model-free indicators of what this family's records show
        (`Diagnosis.loops`); None by default."""
        return None


class PiezoFamily(AbstractFamily):
    """The quasi-static piezo model (eq. 7-8, `PiezoBoucWen`) and the physics a
    stage engineer's record can show beyond it: asymmetry, input bias, rate
    dependence, creep, stage dynamics, drift. Records: time, drive voltage,
    displacement."""

    catalogue: tuple[AbstractEffect, ...] = (
        Asymmetry(),
        InputBias(),
        RateDependence(),
        Creep(),
        Dynamics(),
        Drift(),
    )
    name: ClassVar[str] = "piezo"
    base_name: ClassVar[str] = "piezo"
    base_free: ClassVar[tuple[str, ...]] = ("k1", "k2", "beta1", "gamma1", "n")
    gauge: ClassVar[tuple[str, ...]] = ("A1",)
    holdout_description: ClassVar[str] = "in 30 short blocks spread over the record"

    def check(self, recording):
        if recording.has_pseudo_time:
            raise ValueError(
                f"diagnose: recording {recording.name!r} has a pseudo time (unit "
                f"{recording.time_unit!r}: a quasi-static record), but the piezo "
                "family's effects (rate dependence, creep, dynamics, drift) are "
                "functions of real time; use family=jh.families.StructuralFamily() (--model "
                "bouc-wen) for cyclic tests, or load the record with its time column."
            )
        recording.require_samples(200, what="the piezo diagnosis")

    def base_template(self):
        return PiezoBoucWen(1.0, 1.0, 1.0, 1.0, 1.0, 1.5)

    def extend(self, base, recording):
        return ExtendedPiezo.around(base, recording.input_path())

    def solver(self, recording):
        # One RK4 step per sample: the quasi-static part is slow on the sample scale
        # and the stage (when on) is propagated exactly per sample by the model.
        return RK4()

    def holdout(self, recording, fraction):
        return holdout_blocks(recording.num_samples, fraction)

    def locate(self, recording, residual):
        return locate(np.asarray(recording.t), np.asarray(recording.u), residual)

    def describe(self, where):
        return describe(where)

    def probes(self, recording):
        return piezo_probes(recording)

    def refit_stride(self, model, recording):
        # Quasi-static fits see turning points, not the sample rate: 250 Hz is
        # plenty. A resonance needs >= 4 samples per period at its starting frequency.
        piezo = model_as(model, ExtendedPiezo, "piezo family")
        slowest = 4 * float(piezo.natural_frequency) if piezo.dynamic else 250.0
        stride = max(1, int(recording.sample_rate // max(250.0, slowest)))
        return stride if recording.num_samples > 20 * stride else 1


def _peaks(recording: Recording) -> tuple[float, float]:
    """max|x| and max|F| of a structural record."""
    return float(np.max(np.abs(recording.u))), float(np.max(np.abs(recording.y)))


class StructuralFamily(AbstractFamily):
    """The Bouc-Wen restoring force under an imposed displacement (eq. 1-2,
    `BoucWen` with D = 1, A = 1; extended by `StructuralBoucWen`) and what cyclic
    tests of columns, walls and connections show beyond it: degradation,
    pinching, push/pull asymmetry, drift. Records: (pseudo) time, displacement,
    force; rate independent, so the time axis only orders the samples."""

    catalogue: tuple[AbstractEffect, ...] = (
        Degradation(),
        Pinching(),
        PushPullAsymmetry(),
        Drift(),
    )
    name: ClassVar[str] = "structural"
    base_name: ClassVar[str] = "bouc-wen"
    base_free: ClassVar[tuple[str, ...]] = ("k", "alpha", "beta", "gamma", "n")
    gauge: ClassVar[tuple[str, ...]] = ("A",)
    holdout_description: ClassVar[str] = (
        "in whole cycles interleaved through the test, one per amplitude level"
    )
    # A restoring force outside Table 2 (A = 1: beta < 0 or beta + gamma <= 0)
    # stiffens without bound as the displacement grows: unfit for a structural
    # material (OpenSees runs it, and it diverges beyond the tested range). On
    # chiu the refits reached beta + gamma = -0.03 with n = 1 (a loading branch
    # growing as exp(0.03 z)), fitting the pinched loops' stiffening before each
    # peak with an unbounded force instead of a slip-lock.
    stable_fits: ClassVar[bool] = True

    def check(self, recording):
        recording.require_samples(100, what="the structural diagnosis")
        reversals = recording.reversals()
        if reversals.size < 2:
            raise ValueError(
                f"diagnose: recording {recording.name!r} has {reversals.size} "
                "reversal(s) of its input; the structural family needs a cyclic "
                "test (at least two reversals: one full cycle). Check that the "
                "input column is the displacement."
            )

    def base_template(self):
        return BoucWen(1.0, 0.5, 1.0, 1.0, 1.0, 1.0, 1.5)

    def base_swarm(self):
        # beta and gamma scale as zu^-n: with n up to 3 the good region is a sliver
        # of their box (0.2 % on a synthetic earthquake-like test, where 100 x 200
        # stopped at 3.2 sigma and 300 x 400 reached the noise); these records are
        # short, so the larger swarm costs seconds.
        return MPSO(num_particles=300, num_iterations=400)

    def default_policy(self):
        # Cyclic tests have a few hundred to a few thousand samples: the score
        # test's AR noise model absorbs smooth misfit there (see AdoptionPolicy).
        # Degradation and pinching often come together and each biases the base
        # fit the other is added to: pairs are refitted when neither passes alone.
        # The pseudo time's sampling density is the data logger's choice: the
        # noise's effective count must not fall as it grows.
        return AdoptionPolicy(
            refit_runners_up=True,
            null_refit=True,
            noise_bound=True,
            pair_refits=True,
            noise_across_strides=True,
        )

    def base_space(self, recording):
        # D = 1 and A = 1 fix the gauge (z -> c z leaves the force unchanged
        # otherwise): z is then a displacement that saturates at zu. The polish
        # runs here, where no direction is redundant.
        sx = _peaks(recording)[0]
        return self._space(
            recording, beta=(-20 / sx, 1e3 / sx), gamma=(-20 / sx, 1e3 / sx)
        )

    def base_swarm_space(self, recording):
        # In base_space beta and gamma scale as zu^-n: for n near 2 the good region
        # is a sliver of their box (a 50 x 60 swarm stopped at 2.6-45 noise sigmas
        # on three of four synthetic earthquake-like tests). Here the swarm searches
        # the yield displacement D on a log scale with z dimensionless (saturating at
        # (beta + gamma)^(-1/n), beta and gamma of order one): the same four reached
        # the noise. D and (beta, gamma) trade off along one direction (z -> c z),
        # which a swarm does not mind and a polish does: it runs in base_space.
        sx = _peaks(recording)[0]
        return self._space(
            recording, D=(1e-2 * sx, 3 * sx), beta=(-1.0, 5.0), gamma=(-1.0, 5.0)
        )

    def _space(self, recording, **shape: tuple[float, float]) -> ParameterSpace:
        """A base space: k (log scale), alpha and n in their boxes, A = 1, D = 1
        unless searched, and the `shape` bounds (D, when given, on a log scale)."""
        sx, sy = _peaks(recording)
        bounds = {
            "k": (1e-2 * sy / sx, 1e3 * sy / sx),
            "alpha": (-0.2, 1.0),
            **shape,
            "n": (1.0, 3.0),
        }
        template = self.base_template().replace(D=1.0, A=1.0)
        log_scale = ["k", "D"] if "D" in shape else ["k"]
        return ParameterSpace(
            template, bounds, log_scale=log_scale, stable_shape=self.stable_fits
        )

    def base_gauge(self, model):
        return model_as(model, BoucWen, "structural family").gauge_fixed()

    def extend(self, base, recording):
        return StructuralBoucWen.around(
            base, recording.input_path(), float(np.max(np.abs(recording.y)))
        )

    def solver(self, recording):
        # RK4 steps of at most 1 % of the displacement range: a saturating Bouc-Wen
        # element is stiff in x where |z| nears zu.
        u = np.asarray(recording.u)
        largest = float(np.max(np.abs(np.diff(u))))
        substeps = math.ceil(largest / (0.01 * float(np.ptp(u))))
        return RK4(substeps=int(min(max(substeps, 1), 8)))

    def holdout(self, recording, fraction):
        return holdout_cycles(np.asarray(recording.u), recording.reversals(), fraction)

    def locate(self, recording, residual):
        return locate_cycles(np.asarray(recording.u), np.asarray(recording.y), residual)

    def describe(self, where):
        return describe_cycles(where)

    def form_probes(self, recording):
        # A test's loop changes shape as its excursions grow: the loop's shape
        # level by level, beside its level and direction alone.
        return (*super().form_probes(recording), excursion_probe(recording))

    def probes(self, recording):
        return cyclic_probes(recording)

    def exports(self, model, recording):
        # The matching OpenSees uniaxial material (BoucWen, or BWBN when pinched).
        return opensees_json(model, recording)

    def loop_indicators(self, recording):
        # Whether the loops degrade and pinch, read without a model.
        return loop_indicators(recording)

    def refit_stride(self, model, recording):
        # A quasi-static test's loss is set by its turning points and the path
        # between them: a few thousand samples are plenty.
        return max(1, math.ceil(recording.num_samples / 6000))


class DamperFamily(AbstractFamily):
    """The MR damper of fixed field (`BoucWenDamper`: a dashpot, a spring and
    Bouc-Wen hysteresis driven by the piston's velocity, ignoring the command;
    extended by `ExtendedDamper`) and what a controllable damper's record shows
    beyond it: field dependence, driver lag, roll-off, offset drift, asymmetry.
    Records: time, displacement, command (the first further input), force."""

    catalogue: tuple[AbstractEffect, ...] = (
        FieldDependence(),
        DriverLag(),
        Rolloff(),
        DamperOffset(),
        DamperAsymmetry(),
    )
    name: ClassVar[str] = "damper"
    base_name: ClassVar[str] = "mr-damper"
    base_free: ClassVar[tuple[str, ...]] = (
        "c0",
        "k0",
        "alpha",
        "f0",
        "beta",
        "gamma",
        "n",
    )
    # A fixes z's scale; x0 only shifts the force like f0 does.
    gauge: ClassVar[tuple[str, ...]] = ("A", "x0")
    holdout_description: ClassVar[str] = "in 30 short blocks spread over the record"
    # The smallest yield displacement the base may take, as a share of the largest
    # displacement between two samples: sharper loops turn within a fraction of a
    # sample at peak velocity, which the record does not resolve. It sets the RK4
    # substeps: the Bouc-Wen element relaxes at up to n*|xdot|/z_y, n <= `N_MAX`
    # (published MR damper fits have n = 1 or 2; Spencer et al. fix 2), and
    # `PER_STEP` of that per substep leaves RK4 (stable to 2.8) room for refits
    # that sharpen the loop and for the internal dashpot's relaxation.
    YIELD_SHARE: ClassVar[float] = 0.25
    PER_STEP: ClassVar[float] = 1.5
    N_MAX: ClassVar[float] = 2.0

    def check(self, recording):
        if recording.num_inputs < 2:
            raise ValueError(
                f"diagnose: recording {recording.name!r} carries one input "
                f"({recording.input_name!r}); the MR damper family reads the "
                "displacement and the command (voltage or current) beside it: load "
                "both, e.g. jaxhyst diagnose REC.csv --model mr-damper --input u "
                "--input v, Recording.load(path, input=['u', 'v']), or "
                "Recording(t, x, force, more_inputs={'command': v}); for a test at "
                "one fixed command, add it as a constant: "
                "rec.with_input('command', level)."
            )
        if recording.has_pseudo_time:
            raise ValueError(
                f"diagnose: recording {recording.name!r} has a pseudo time (unit "
                f"{recording.time_unit!r}), but a damper's force follows the "
                "velocity; load the record with its time column."
            )
        recording.require_samples(600, what="the MR damper diagnosis")

    def base_template(self):
        return BoucWenDamper(1.0, 1.0, 0.0, 1.0, 0.0, 1.0, 1.0, 1.0, 2.0)

    # A command whose spread is below this share of its level (or of 1 when it is
    # zero) is constant: a test at one coil current.
    CONSTANT_COMMAND: ClassVar[float] = 1e-6

    # The base swarm's window (samples at the full rate): a decimated record
    # integrates a damper's sharp loops with a stride-times larger RK4 step, which
    # moves the swarm's best basin (on a white-noise test the base then fitted at
    # 5 to 10 noise sigmas where its truth sat at 1). About as many RK4 steps as
    # `identify`'s own decimated swarm (<= 2000 steps of `solver`'s substeps).
    SWARM_WINDOW: ClassVar[int] = 2000

    def base_swarm_window(self, recording):
        return self.SWARM_WINDOW if recording.num_samples > self.SWARM_WINDOW else None

    def residual_probes(self, recording):
        # A random displacement does not repeat loops: the force's own variables.
        return (velocity_command_probe(recording), command_history_probe(recording))

    def base_swarm_alternatives(self):
        # Iterations over particles: on two synthetic white-noise tests with a
        # strong field dependence, the default 100 x 200 stopped in a viscous basin
        # (a tiny hysteresis, a large spring; 12.4 and 13.5 noise sigmas) from 4 of
        # 6 keys, where 64 x 500 reached the basin of the truth (4.2 and 7.1
        # sigmas) from 7 of 7. On Dyke's ransim_u, 64 x 500 alone fitted the base
        # at 579.6 N where 100 x 200 reached 470.9 N: both are tried, and the
        # window decides.
        return (MPSO(num_particles=64, num_iterations=500),)

    # Yield displacements of the Bingham starts, as shares of the displacement's
    # peak (MR dampers yield within a few per cent of their stroke).
    BINGHAM_YIELDS: ClassVar[tuple[float, ...]] = (0.01, 0.03, 0.1)

    def base_starts(self, recording, window):
        # Bingham's model (Stanway et al. 1987), F = c0*xdot + k0*x + Fy*sign(xdot)
        # + f0, is linear in its parameters: least squares gives the viscous
        # coefficient, the spring and the yield force directly, whatever basin a
        # swarm falls in. Each start is the Bouc-Wen damper with that yield force
        # reached over one of `BINGHAM_YIELDS` (n = 2, beta = gamma, as Spencer et
        # al.), in `base_space`'s gauge. On the damper suite's record 19 every
        # swarm start ended in a viscous basin (alpha*z_u 15 N against a 128 N
        # yield force; 2.67 noise sigmas left after the asymmetry was named).
        x = np.asarray(window.u)
        y = np.asarray(window.y)
        velocity = np.gradient(x, window.dt)
        columns = np.stack([velocity, x, np.sign(velocity), np.ones_like(x)], axis=1)
        (c0, k0, yield_force, f0), *_ = np.linalg.lstsq(columns, y, rcond=None)
        if not (np.isfinite(yield_force) and yield_force > 0 and c0 > 0):
            return ()
        space = self.base_space(recording)
        template = space.template
        floor = 1.0 / float(template.parameters()["A"])
        peak = float(np.max(np.abs(x - np.mean(x))))
        lower, upper = np.asarray(space.lower), np.asarray(space.upper)
        bound = dict(zip(space.names, zip(lower, upper)))
        starts = []
        for share in self.BINGHAM_YIELDS:
            yield_displacement = max(share * peak, 2.0 * floor)
            # z rises at slope A = 1/floor and saturates at z_u = (A/(beta +
            # gamma))^(1/n): z_u/A is the yield displacement.
            z_u = yield_displacement / floor
            each = 0.5 * (1.0 / floor) / z_u**2
            values = {
                "c0": c0,
                "k0": k0,
                "alpha": yield_force / z_u,
                "f0": f0,
                "beta": each,
                "gamma": each,
                "n": 2.0,
            }
            values = {
                name: float(np.clip(v, *bound[name])) if name in bound else float(v)
                for name, v in values.items()
            }
            starts.append(template.replace(**values))
        return tuple(starts)

    def cannot_show(self, recording):
        command = np.asarray(recording.more_inputs[0])
        spread = float(np.max(command) - np.min(command))
        if spread > self.CONSTANT_COMMAND * max(float(np.max(np.abs(command))), 1.0):
            return {}
        level = f"{float(command[0]):.4g} {recording.more_input_units[0] or ''}".strip()
        name = recording.input_names[1]
        return {
            "field_dependence": (
                f"the command ({name!r}) is constant ({level}): a record at one "
                "field cannot show how the force follows the field; the base "
                "model's force parameters are that field's. Record several "
                "command levels, or a varying command, to ask about it."
            ),
            "driver_lag": (
                f"the command ({name!r}) never changes, so no lag of the field "
                "behind it can show; record command steps to ask about it."
            ),
        }

    def _yield_floor(self, recording: Recording) -> float:
        """The smallest yield displacement the diagnosis resolves (see
        `YIELD_SHARE`)."""
        step = float(np.max(np.abs(np.diff(np.asarray(recording.u)))))
        return self.YIELD_SHARE * max(step, 1e-300)

    def base_space(self, recording):
        # A = 1/z_min fixes the gauge (z -> c z leaves the force unchanged
        # otherwise) so that beta + gamma <= A is a yield displacement of z_min or
        # more whatever n: beta and gamma up to A/2 each keep the loop within what
        # the record resolves and the solver integrates. With z_u from 1 to 5e5
        # (beta + gamma down to 2e-6*A), alpha (the yield force over z_u) spans
        # 1e-9..10 max|F|. c0 around rms(F)/rms(xdot), k0 of either sign up to
        # max|F|/max|x| (an accumulator's stiffness, which a plain fit may trade
        # against the hysteresis), f0 within +-max|F|.
        floor = self._yield_floor(recording)
        x, y = np.asarray(recording.u), np.asarray(recording.y)
        sx, sy = float(np.max(np.abs(x - np.mean(x)))), float(np.max(np.abs(y)))
        velocity = np.diff(x) / recording.dt
        viscous = float(
            np.sqrt(np.mean(y**2)) / max(np.sqrt(np.mean(velocity**2)), 1e-300)
        )
        template = self.base_template().replace(A=1.0 / floor, x0=0.0)
        bounds = {
            "c0": (1e-3 * viscous, 10.0 * viscous),
            "k0": (-sy / sx, sy / sx),
            "alpha": (1e-9 * sy, 10.0 * sy),
            "f0": (-sy, sy),
            "beta": (1e-6 / floor, 0.5 / floor),
            "gamma": (1e-6 / floor, 0.5 / floor),
            "n": (1.0, self.N_MAX),
        }
        return ParameterSpace(
            template, bounds, log_scale=["c0", "alpha", "beta", "gamma"]
        )

    def base_bounds(self, name, value):
        if name == "n":
            return (1.0, self.N_MAX)
        return None

    def extend(self, base, recording):
        rms = float(np.sqrt(np.mean(np.asarray(recording.y) ** 2)))
        return ExtendedDamper.around(base, recording.input_path(), rms)

    def solver(self, recording):
        # Substeps such that a loop at the yield floor is integrated at `PER_STEP`
        # per substep at the record's peak velocity: n*max|dx|/(z_min*substeps),
        # 6 substeps. (The floor scales with max|dx|, so they do not depend on the
        # record.)
        return RK4(substeps=math.ceil(self.N_MAX / (self.YIELD_SHARE * self.PER_STEP)))

    def holdout(self, recording, fraction):
        return holdout_blocks(recording.num_samples, fraction)

    def locate(self, recording, residual):
        window = (
            max(3, round(0.01 * recording.sample_rate))
            if recording.time_unit == "s"
            else 30
        )
        return locate_damper(
            np.asarray(recording.t),
            np.asarray(recording.u),
            np.asarray(recording.more_inputs[0]),
            residual,
            switch_window=window,
            time_unit=recording.time_unit,
        )

    def describe(self, where):
        return describe_damper(where)

    def probes(self, recording):
        return damper_probes(recording)

    def default_policy(self):
        # The base misfits a controllable damper's record grossly (it ignores the
        # command): the held-out resolution's noise level is bounded by the better
        # fit's held-out RMS, else the AR noise model (mostly misfit) would demand
        # far too large a gain. A candidate's gain is credited only beyond a refit
        # of the model it extends. (Candidate refits run no swarm: the extended
        # model's lagged field is propagated once per sample.) A white-noise test
        # misfits by many noise sigmas until the field and its lag are in: the
        # score test then loses power, and structure left on the held-out samples
        # has the strongest candidates refitted anyway.
        return AdoptionPolicy(
            null_refit=True, noise_bound=True, refit_on_structure=True
        )

    def refit_stride(self, model, recording):
        # No decimation: a stride s multiplies the RK4 step by s at the same
        # substeps, and a damper's sharp loops then integrate differently (on a
        # white-noise test a field-and-lag refit at stride 4 reached 1.95 sigma where
        # the same refit at full rate reached 1.17). The batched forward-mode
        # Jacobian makes full-rate refits affordable.
        return 1


def _peak_velocity(recording: Recording) -> float:
    return float(np.max(np.abs(np.diff(np.asarray(recording.u))))) / recording.dt


def _command_range(recording: Recording) -> tuple[float, float]:
    command = np.asarray(recording.more_inputs[0])
    return (float(np.min(command)), float(np.max(command)))


def _bandwidth(recording: Recording, share: float = 0.99) -> float:
    """The frequency below which `share` of the displacement's power lies."""
    x = np.asarray(recording.u) - np.mean(recording.u)
    power = np.abs(np.fft.rfft(x)) ** 2
    cumulative = np.cumsum(power)
    freqs = np.fft.rfftfreq(x.size, recording.dt)
    index = int(np.searchsorted(cumulative, share * cumulative[-1]))
    return max(float(freqs[min(index, freqs.size - 1)]), 1.0 / recording.duration)


def holdout_blocks(n: int, fraction: float, blocks: int = 30) -> np.ndarray:
    """Fit mask that holds out evenly spread blocks (about `fraction` of the samples),
    so that slow effects are judged by interpolation, not extrapolation. Many short
    blocks: every kind of excitation in the record (a sweep, a hold, a fast burst)
    then lands on both sides, so the held-out error measures the physics, not how the
    base model extrapolates to a segment it never saw."""
    held = max(1, round(fraction * blocks))
    chosen = np.round(np.linspace(1, blocks - 1, held)).astype(int)
    edges = np.linspace(0, n, blocks + 1).astype(int)
    mask = np.ones(n, bool)
    for b in chosen:
        mask[edges[b] : edges[b + 1]] = False
    return mask


def holdout_cycles(x: np.ndarray, reversals: np.ndarray, fraction: float) -> np.ndarray:
    """Fit mask that holds out whole cycles of a cyclic test, interleaved.

    A cycle is two consecutive excursions between reversals. Consecutive cycles
    whose peak |x| is within 15 % of each other form an amplitude level. In every
    level of two or more cycles one is held out (its second, so that a level of
    three is judged by interpolation): each such level is on both sides of the
    split. Levels of one cycle (growing or irregular histories) are held out in
    turn, every k-th (k ~ 1/fraction), never the first cycle or the one that
    reaches the largest amplitude: held-out cycles are judged by interpolation,
    not by extrapolation to a larger amplitude than the fit saw.
    """
    n = x.size
    edges = np.concatenate([[0], np.asarray(reversals, int), [n]])
    edges = np.unique(edges)
    cycles = [
        (edges[i], edges[min(i + 2, edges.size - 1)])
        for i in range(0, edges.size - 1, 2)
    ]
    amplitude = [float(np.max(np.abs(x[a:b]))) if b > a else 0.0 for a, b in cycles]
    levels: list[list[int]] = []
    for i, amp in enumerate(amplitude):
        if levels and abs(amp - amplitude[levels[-1][0]]) <= 0.15 * max(
            amplitude[levels[-1][0]], 1e-300
        ):
            levels[-1].append(i)
        else:
            levels.append([i])
    largest = int(np.argmax(amplitude))
    every = max(2, round(1 / fraction))
    held: list[int] = []
    singles = 0
    for level in levels:
        if len(level) >= 2:
            held.append(level[1])
        else:
            singles += 1
            if singles % every == 0:
                held.append(level[0])
    mask = np.ones(n, bool)
    for i in held:
        if i in (0, largest):
            continue
        a, b = cycles[i]
        mask[a:b] = False
    return mask


CATALOGUE: dict[str, AbstractEffect] = {e.name: e for e in PiezoFamily().catalogue}
"""The piezo family's effects by name (`PiezoFamily().catalogue`)."""
EFFECT_NAMES: tuple[str, ...] = tuple(CATALOGUE)
STRUCTURAL_EFFECT_NAMES: tuple[str, ...] = StructuralFamily().effect_names
DAMPER_EFFECT_NAMES: tuple[str, ...] = DamperFamily().effect_names
