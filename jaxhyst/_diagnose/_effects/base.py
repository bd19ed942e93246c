"""What the diagnosis engine needs to know about one effect of a catalogue.

An effect is a piece of physics a base model can leave out, written as a set of
parameters of the family's extended model: with its gains at zero the extended model
is the base model exactly. Everything the engine decides per effect lives on the
effect object (one final class per effect, one file each): how it is switched on and
off, where its parameters may go, which output directions the score test projects
on, where a refit starts, the words of its evidence, its parameters' units and
their physical reading.

The helpers at the end turn figures into words: every claim an evidence sentence
makes is decided by the figure it quotes and a threshold named here (or in
`_locate`), so a sentence cannot say "concentrated" next to 0.92x.
"""

import abc
import math
from typing import Any, ClassVar, NamedTuple, TypeVar

import equinox as eqx
import numpy as np

from ..._models.base import AbstractHysteresisModel
from .._locate import CARRIES, CONCENTRATED, MIN_FRACTION


class RefitScales(eqx.Module):
    """The record's scales that bounds and starting points are expressed in."""

    sample_rate: float
    duration: float
    # How far each parameter must move to change the output by its RMS (from the
    # output's sensitivities at the current model).
    natural: dict[str, float]


class AbstractEffect(eqx.Module):
    """One catalogue entry: a stable `name`, the extended model's `parameters` that
    switch it on, what it means in an engineer's words, and its engine hooks.

    The defaults suit an effect whose parameters enter smoothly and vanish at zero:
    override a hook only where the physics needs it (a resonance that is switched
    on structurally, a time shift whose linearisation is poor).
    """

    name: ClassVar[str]
    parameters: ClassVar[tuple[str, ...]]
    meaning: ClassVar[str]
    # The effect's functional forms: each a stable name (the findings' `form`,
    # listed in the docs) with the parameters that are its own, in the order of
    # `parameters`; every parameter belongs to one form. A form is on in a model
    # when one of its gains is not zero; a form with no gain (a resonance switched
    # on by the model's structure) is on with the effect.
    forms: ClassVar[dict[str, tuple[str, ...]]]
    # Parameters searched on a log scale in refits (positive time constants, rates).
    log_scaled: ClassVar[tuple[str, ...]] = ()
    # Parameters that only shape the effect (inert while its gains are zero).
    shape_parameters: ClassVar[tuple[str, ...]] = ()
    # Parameters that add a fixed function of time to the output (the output's
    # sensitivity to them depends on no parameter): refits solve them in closed
    # form instead of searching them (`ActiveProblem`). Declare only what the
    # model makes exactly so; a test checks it for every family.
    additive: ClassVar[tuple[str, ...]] = ()
    # Additive parameters that are a spline's coefficients, in order: refits that
    # solve them all hold their second differences small (`SMOOTHNESS`), so that
    # the spline bridges held-out samples smoothly instead of swinging there.
    smooth: ClassVar[tuple[str, ...]] = ()
    # Whether a form of this effect other than the catalogue's would change the
    # loop (a function of the input's level, direction and history), so that a
    # model-free correction of the loop stands for it when an effect adopted after
    # this one is judged (`AdoptionPolicy.form_correction`). False for an effect
    # that is a slow function of time whatever its form (a drift, an offset).
    form_in_loops: ClassVar[bool] = True

    @property
    def gains(self) -> tuple[str, ...]:
        """The parameters whose zero switches the effect off."""
        return tuple(p for p in self.parameters if p not in self.shape_parameters)

    def forms_on(self, model: AbstractHysteresisModel) -> tuple[str, ...]:
        """The names of the forms on in `model` (none while the effect is off)."""
        if not self.is_on(model):
            return ()
        on = []
        for name, own in self.forms.items():
            gains = [p for p in own if p in self.gains]
            if not gains or any(float(getattr(model, p)) != 0.0 for p in gains):
                on.append(name)
        return tuple(on)

    def form(
        self,
        model: AbstractHysteresisModel,
        errors: dict[str, float] | None = None,
        correlations: dict[str, dict[str, float]] | None = None,
    ) -> str:
        """The forms on in `model`, joined by "+" (a finding's `form`). With the
        parameters' standard `errors` (and `correlations`), only those whose gains
        the record determines (`jointly_determined`), unless it determines none of
        them apart: a degradation driven by energy with a peak-excursion gain of
        0.0002 +- 0.0017 is named `energy`."""
        on = self.forms_on(model)
        if errors is None:
            return "+".join(on)
        values = self.values(model)
        named = []
        for name in on:
            gains = tuple(p for p in self.forms[name] if p in self.gains)
            if not gains or jointly_determined(
                gains, values, errors, correlations or {}
            ):
                named.append(name)
        return "+".join(named or on)

    def alone(
        self, model: AbstractHysteresisModel, form: str
    ) -> tuple[AbstractHysteresisModel, tuple[str, ...]]:
        """`model` with this effect in its form `form` alone (the other forms'
        gains at zero), and the parameters the other forms own (a refit of the
        form alone holds them)."""
        others = tuple(
            p for name, own in self.forms.items() if name != form for p in own
        )
        return model.replace(**{p: 0.0 for p in others if p in self.gains}), others

    def is_on(self, model: AbstractHysteresisModel) -> bool:
        return any(float(getattr(model, p)) != 0.0 for p in self.gains)

    def switch_off(self, model: AbstractHysteresisModel) -> AbstractHysteresisModel:
        """`model` with this effect's gains at zero (the shape parameters are inert
        then, and kept)."""
        return model.replace(**{p: 0.0 for p in self.gains})

    def values(self, model: AbstractHysteresisModel) -> dict[str, float]:
        """This effect's parameter values in `model`, by name."""
        return {p: float(getattr(model, p)) for p in self.parameters}

    def take_from(
        self, model: AbstractHysteresisModel, source: AbstractHysteresisModel
    ) -> AbstractHysteresisModel:
        """`model` with this effect's parameters taken from `source`."""
        return model.replace(**self.values(source))

    def fitted_dof(self, model: AbstractHysteresisModel) -> int:
        """How many parameters a refit that reached `model` fitted, for the
        information criterion: each of the effect's parameters except those held at
        their model's floor or ceiling (`parameter_floors`, `parameter_ceilings`),
        which fitted nothing (the degrees of freedom of bounded least squares); at
        least one."""
        limits = [type(model).parameter_floors, type(model).parameter_ceilings]
        return max(
            sum(
                not any(
                    p in limit and float(getattr(model, p)) == limit[p]
                    for limit in limits
                )
                for p in self.parameters
            ),
            1,
        )

    def undetermined(
        self,
        values: dict[str, float],
        errors: dict[str, float],
        correlations: dict[str, dict[str, float]],
    ) -> tuple[str, ...]:
        """The defining parameters the record leaves undetermined, empty when the
        record determines the effect. By default the gains define it, together:
        the gains with a finite standard error must be away from zero by more than
        one standard error jointly (`jointly_determined`, the Wald statistic of
        their `errors` and `correlations`), so that a delay and a lead network
        that trade off against each other, each undetermined alone, still
        determine a time shift between them. All the gains when they do not."""
        if jointly_determined(self.gains, values, errors, correlations):
            return ()
        return self.gains

    def sensitivity_parameters(self, model: AbstractHysteresisModel) -> tuple[str, ...]:
        """The parameters whose output sensitivities the engine computes at
        `model` (all of them for a smooth effect)."""
        return self.parameters

    def directions(
        self,
        columns: dict[str, np.ndarray],
        predicted: np.ndarray,
        dt: float,
    ) -> np.ndarray:
        """The output directions the score test projects the residual on: by
        default the output's sensitivities to the effect's parameters at zero."""
        return np.stack([columns[p] for p in self.parameters], axis=1)

    def bounds(
        self, name: str, value: float, scales: RefitScales
    ) -> tuple[float, float] | None:
        """Refit bounds for one of this effect's parameters, or None for the
        engine's rule (the current value +- its natural scale)."""
        return None

    def starting_points(
        self,
        current: AbstractHysteresisModel,
        step: dict[str, float],
        scales: RefitScales,
    ) -> list[AbstractHysteresisModel]:
        """Models a refit may start from: the score test's Gauss-Newton `step` at
        several lengths (the linearisation rarely has the right size)."""
        return [
            current.replace(
                **{p: float(getattr(current, p)) + scale * v for p, v in step.items()}
            )
            for scale in (0.25, 0.5, 1.0, 2.0, 4.0)
        ]

    # The effect this one is seen through (None: itself): a lag of the field shows
    # only once the force follows the field. When that effect's refit alone fails
    # validation, the engine also refits the two together (the dependent's score
    # test has no direction while the effect it needs is off).
    needs: ClassVar[str | None] = None

    def always_refit(self) -> bool:
        """Refit whenever significant, even outside the strongest few: for effects
        the linearised score understates."""
        return False

    def score_screens(self) -> bool:
        """Whether the score test screens this effect. False: it is refitted in
        every round in which it has a direction (the effect it `needs` is in the
        model), significant or not, and held-out validation alone decides; for
        effects whose linearised score can vanish where the effect is large."""
        return True

    @abc.abstractmethod
    def evidence(self, where: dict[str, Any], model: AbstractHysteresisModel) -> str:
        """The location figures (`where`, from the family's `locate`) and fitted
        values (`model`) that bear on this effect, in words: a figure is called
        support only when it passes its threshold, and a sentence with no such
        figure says so."""

    @abc.abstractmethod
    def units(self, *, time: str, input: str, output: str) -> dict[str, str]:
        """Each parameter's unit, from the recording's time, input and output unit
        strings ("1": dimensionless; an empty unit string reads as "time units",
        "input units" or "output units")."""

    @abc.abstractmethod
    def reading(
        self, values: dict[str, float], errors: dict[str, float], units: dict[str, str]
    ) -> str:
        """The fitted `values` with their standard `errors` (NaN or missing: not
        determined by the record) in an engineer's words, in the `units` that
        `units` gives."""


ModelT = TypeVar("ModelT", bound=AbstractHysteresisModel)


def model_as(model: AbstractHysteresisModel, cls: type[ModelT], effect: str) -> ModelT:
    """`model` as its family's extended model class, or a TypeError naming the
    mismatch (an effect of one family asked about another family's model)."""
    if not isinstance(model, cls):
        raise TypeError(
            f"the {effect!r} effect acts on {cls.__name__} models, got "
            f"{type(model).__name__}; pass a model of the same family."
        )
    return model


# ----------------------------------------------------------------- figures to words

# Two means (the branches', push's and pull's) differ when they are at least this
# share of the overall residual RMS apart: a mean offset of a quarter of the RMS is
# visible on a plot of the residual, a smaller one is not worth naming.
MEAN_GAP = 0.25
# One category's residual RMS is "larger" than another's at this ratio (fast vs
# slow rates, the last vs the first third of a test): 2.25x the power.
CONTRAST = 1.5
# What carries a finding that no location figure supports.
SCORE_AND_GAIN = "the score test and the held-out gain"


class Figure(NamedTuple):
    """One figure in words, and whether it supports the effect (words may be empty
    for a figure that is only worth quoting when it supports)."""

    supports: bool
    words: str


def concentration(where: dict[str, Any], key: str, place: str, why: str = "") -> Figure:
    """Whether `where[key]`'s residual RMS stands out (`CONCENTRATED` times the
    overall or more, on more than `MIN_FRACTION` of the samples), in words; `why`
    follows a supporting figure."""
    entry = where[key]
    relative = float(entry["relative"])
    if not (math.isfinite(relative) and entry["fraction"] > MIN_FRACTION):
        return Figure(False, f"too few samples {place} to tell")
    # Decided on the figure as quoted, so the words never contradict it.
    quoted = round(relative, 2)
    if quoted >= CONCENTRATED:
        tail = f", {why}" if why else ""
        return Figure(
            True,
            f"the residual is concentrated {place} ({quoted:.2f}x the overall RMS)"
            + tail,
        )
    return Figure(
        False,
        f"the residual is not concentrated {place} ({quoted:.2f}x the overall RMS)",
    )


def contrast(where: dict[str, Any], larger: str, smaller: str, words: str) -> Figure:
    """Whether `where[larger]`'s residual RMS is `CONTRAST` times `where[smaller]`'s
    or more: `words` with the ratio filled in ({ratio}) if so, no words if not."""
    a, b = float(where[larger]["relative"]), float(where[smaller]["relative"])
    if not (math.isfinite(a) and math.isfinite(b) and b > 0):
        return Figure(False, "")
    ratio = round(a / b, 2)
    if ratio >= CONTRAST:
        return Figure(True, words.format(ratio=ratio))
    return Figure(False, "")


def share(part: float, overall: float) -> float:
    """`part` as a share of `overall` (NaN when there is no residual)."""
    return float(part) / overall if overall > 0 else float("nan")


def carries(part: float, overall: float, what: str, why: str = "") -> Figure:
    """Whether a part of the residual (`what`, an RMS `part`) carries `CARRIES` of
    its overall RMS or more, in words."""
    fraction = share(part, overall)
    if not math.isfinite(fraction):
        return Figure(False, f"there is no residual to split into {what}")
    quoted = round(fraction, 2)
    if quoted >= CARRIES:
        tail = f", {why}" if why else ""
        return Figure(True, f"{what} carries {quoted:.0%} of the residual RMS{tail}")
    return Figure(False, f"{what} carries only {quoted:.0%} of the residual RMS")


def conclude(figures: list[Figure], instead: str = SCORE_AND_GAIN) -> str:
    """The figures' words, and, when none supports the effect, what does."""
    words = [f.words for f in figures if f.words]
    if not any(f.supports for f in figures):
        words.append(f"no location figure singles it out; the evidence is {instead}")
    return "; ".join(words)


# ------------------------------------------------------------- units and readings


# The unit of rates per dissipated energy (degradation, pinching): a cyclic test's
# energy is counted in the record's max|F| * max|x| (StructuralBoucWen's
# energy_scale).
ENERGY_UNIT = "1/(max|F|·max|x|)"


class Units(NamedTuple):
    """A recording's unit strings, never blank."""

    time: str
    input: str
    output: str


def named_units(time: str, input: str, output: str) -> Units:
    """The recording's unit strings, with "time units", "input units" and
    "output units" for empty ones."""
    return Units(time or "time units", input or "input units", output or "output units")


def _group(unit: str) -> str:
    return f"({unit})" if any(c in unit for c in " /·^") else unit


def per(numerator: str, denominator: str) -> str:
    """The unit `numerator` per `denominator` ("1" per ...: the inverse)."""
    return f"{_group(numerator)}/{_group(denominator)}"


def power(unit: str, exponent: str) -> str:
    """`unit` to the power `exponent` (a number or a parameter's name)."""
    return f"{_group(unit)}^{exponent}"


def times(*units: str) -> str:
    """The product of `units`."""
    return "·".join(_group(u) for u in units)


def not_determined(error: float | None) -> bool:
    """Whether a standard error leaves its parameter undetermined (NaN, inf,
    missing or not positive)."""
    return error is None or not math.isfinite(error) or error <= 0


def determined(value: float, error: float | None) -> bool:
    """Whether the record determines a parameter: its standard error is finite and
    below the value's size (the value is at least one standard error from 0)."""
    if error is None or not_determined(error):
        return False
    return abs(value) > error


def jointly_determined(
    names: tuple[str, ...],
    values: dict[str, float],
    errors: dict[str, float],
    correlations: dict[str, dict[str, float]],
) -> bool:
    """Whether the parameters `names` are away from zero by more than one standard
    error jointly: the Wald statistic of those with a finite error, from their
    `errors` and `correlations`, above chi-square's one-sigma point for as many
    degrees of freedom (for one parameter: |value| above its error, `determined`)."""
    from scipy.stats import chi2  # deferred: scipy.stats costs import time

    known = [p for p in names if not not_determined(errors.get(p))]
    if not known:
        return False
    se = np.array([errors[p] for p in known])
    rho = np.array(
        [
            [1.0 if p == q else correlations.get(p, {}).get(q, 0.0) for q in known]
            for p in known
        ]
    )
    rho = np.where(np.isfinite(rho), rho, 0.0)
    g = np.array([values[p] for p in known])
    wald = float(g @ np.linalg.pinv(rho * np.outer(se, se)) @ g)
    return wald > float(chi2.isf(ONE_SIGMA_TAIL, len(known)))


# The two-sided tail beyond one standard error of a normal variable.
ONE_SIGMA_TAIL = math.erfc(1 / math.sqrt(2))


def quantity(value: float, error: float | None, unit: str = "1") -> str:
    """A value with its standard error and unit, as in "0.133 ± 0.004 s": both
    rounded at the error's second significant digit when it starts with 1, else
    its first (with a shared power of ten outside 1e-3 to 1e6); an undetermined
    error reads "(not determined by this record)". Unit "1" or "" is left out."""
    suffix = "" if unit in ("", "1") else f" {unit}"
    if error is None or not_determined(error):
        return f"{value:.3g}{suffix} (not determined by this record)"
    exponent = math.floor(math.log10(error))
    place = exponent - 1 if round(error / 10**exponent, 1) < 2 else exponent
    largest = max(abs(value), error)
    if 1e-3 <= largest < 1e6:
        decimals = max(0, -place)
        v, e = round(value, -place) + 0.0, round(error, -place)
        return f"{v:.{decimals}f} ± {e:.{decimals}f}{suffix}"
    tens = math.floor(math.log10(largest))
    decimals = max(0, tens - place)
    v, e = value / 10**tens + 0.0, error / 10**tens
    return f"({v:.{decimals}f} ± {e:.{decimals}f})e{tens}{suffix}"


def fitted(
    values: dict[str, float],
    errors: dict[str, float],
    units: dict[str, str],
    name: str,
    scale: float = 1.0,
    unit: str | None = None,
) -> str:
    """Parameter `name`'s value (times `scale`) ± its error, in `unit` (default:
    its unit in `units`)."""
    error = errors.get(name)
    return quantity(
        scale * values[name],
        None if error is None else abs(scale) * error,
        units[name] if unit is None else unit,
    )


def time_scale(magnitude: float, unit: str) -> tuple[float, str]:
    """A factor and unit to quote a duration of `magnitude` in: milliseconds for
    durations under a second in seconds, else the unit as is."""
    if unit == "s" and abs(magnitude) < 1:
        return 1e3, "ms"
    return 1.0, unit
