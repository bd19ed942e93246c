"""The diagnosis: fit the family's base model, score every catalogue effect on the
residual, refit the strongest, keep an effect only if it earns its parameters on
held-out data, and repeat; then check the choices backwards, revisit them, refit
on everything, and say what the catalogue does not explain.

Each stage is a function of the typed `_Context` (what does not change) and the
`_State` (what the stages build up).
"""

import collections
import dataclasses
import functools
import math
import time
import traceback
import warnings
from collections.abc import Callable, Collection, Sequence
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, PRNGKeyArray

from .._identification._identify import Fit, identify
from .._inputs import InputPath
from .._memory_maps import release_if_near_map_limit
from .._metrics import error_metrics
from .._models.base import AbstractHysteresisModel
from .._params import ParameterSpace
from .._placement import moved_to, running_on, serial_device
from .._recording import Recording
from .._simulate import RK4
from .._status import RESULTS, has_status
from .._swarm import MPSO
from .._threads import side_by_side
from ._ambiguity import cannot_tell_rivals, confined, standing_in, unresolved
from ._effects.base import AbstractEffect, RefitScales, quantity
from ._families import AbstractFamily, PiezoFamily
from ._locate import effective_samples
from ._policy import AdoptionPolicy
from ._progress import Progress
from ._records import BATCH, DiagnosisRecords
from ._refit import DegenerateRefit, RefitSettings, fitted_names, idle_gains, refit
from ._remainder import remainder
from ._residual_probes import ResidualProbe, bin_prediction
from ._results import (
    RESOLVED_SIGMA,
    Advice,
    Ambiguity,
    Diagnosis,
    DiagnosisStep,
    Finding,
    NotShown,
    RecordingErrors,
    Rival,
    Score,
    Unexplained,
    Validation,
)
from ._score import (
    NoiseModel,
    chi2,
    moving_columns,
    predict,
    project_off,
    score_statistic,
)
from ._uncertainty import errors_and_correlations
from ._unexplained import unexplained_structure


class _Context(eqx.Module):
    """What every stage reads and none changes."""

    # The joined record (one recording's samples, or several one after another).
    recording: Recording
    records: DiagnosisRecords
    family: AbstractFamily
    policy: AdoptionPolicy
    key: PRNGKeyArray
    inputs: InputPath
    measured: Array
    y: np.ndarray
    fit_mask: np.ndarray
    hold_mask: np.ndarray
    weights: Array
    solver: RK4
    sample_rate: float
    duration: float
    progress: Progress
    # Catalogue effects the record cannot show (never scored), with the reason.
    hidden: dict[str, str]


class _Trial(eqx.Module):
    """A candidate refitted: its score, the model, its output, its validation,
    and the null refit it was judged against (the model it extends refitted from
    the candidate's values, when that fitted the held-out data better)."""

    score: Score
    model: AbstractHysteresisModel
    predicted: np.ndarray
    validation: Validation
    null: tuple[AbstractHysteresisModel, np.ndarray] | None = None
    # Dependents refitted and adopted together with the effect (see
    # `AbstractEffect.needs`), or the effect it was paired with (`joint`).
    dependents: tuple[str, ...] = ()
    # True when two independent candidates that failed alone were refitted as a
    # pair (`_jointly`), False for an effect and what it `needs`.
    joint: bool = False
    # The parameters the refit fitted (the others held where `start` had them).
    free: tuple[str, ...] = ()


class _Failed(eqx.Module):
    """A candidate whose refit produced no model to validate, and why."""

    reason: str


class _State(eqx.Module):
    """What the stages build up."""

    current: AbstractHysteresisModel
    predicted: np.ndarray
    free: tuple[str, ...]
    findings: tuple[Finding, ...] = ()
    ambiguities: tuple[Ambiguity, ...] = ()
    rounds: tuple[list[Score], ...] = ()
    # The models moved to, in order (the report's RMSE chain).
    steps: tuple[DiagnosisStep, ...] = ()
    # Each effect's latest trial that passed held-out validation, with where the
    # mismatch was then: the rivals every finding is tested against.
    passed_trials: dict[str, tuple[_Trial, dict[str, Any]]] = eqx.field(
        default_factory=dict
    )
    # Effects significant in some round but never refitted (not among the
    # strongest), with their latest score: rivals too, refitted in a finding's
    # place from the score test's step.
    untried: dict[str, Score] = eqx.field(default_factory=dict)
    # Each effect's latest refit that failed held-out validation: one more place a
    # rival's refit may start from (`AdoptionPolicy.whole_catalogue_rivals`).
    failed_trials: dict[str, _Trial] = eqx.field(default_factory=dict)
    # Pairs of fitted models the record cannot tell apart (for the advice).
    contrasts: tuple["_Contrast", ...] = ()
    noise: NoiseModel | None = None
    effective_heldout: float = 0.0
    # How far each parameter must move to change the output by its RMS (the
    # latest round's sensitivities).
    natural: dict[str, float] = eqx.field(default_factory=dict)

    @property
    def adopted(self) -> tuple[str, ...]:
        return tuple(f.effect for f in self.findings)

    def latest_score(self, effect: str) -> Score | None:
        """`effect`'s score in the latest round that scored it (its Gauss-Newton
        step: where a rival's refit starts when the effect was never refitted)."""
        for scores in reversed(self.rounds):
            for score in scores:
                if score.effect == effect:
                    return score
        return None

    @property
    def passed(self) -> frozenset[str]:
        """Effects that have passed held-out validation in some round."""
        return frozenset(self.passed_trials)

    @property
    def noise_model(self) -> NoiseModel:
        """The latest round's noise model (every stage after the first score test)."""
        if self.noise is None:
            raise RuntimeError(
                "diagnose: internal error, a stage ran before the first score test "
                "estimated the noise; please report it."
            )
        return self.noise


class _Contrast(eqx.Module):
    """Two fitted models the record cannot tell apart: `kept` (with `separates[0]`)
    and `other` (with the rest of `separates`, or without the effect when
    `separates` names one)."""

    separates: tuple[str, ...]
    kept: AbstractHysteresisModel
    other: AbstractHysteresisModel


def _mse(residual: np.ndarray, mask) -> float:
    return float(np.mean(residual[mask] ** 2))


def _finite(x: np.ndarray) -> bool:
    return bool(np.all(np.isfinite(x)))


def _refit(
    ctx: _Context,
    state: _State,
    model,
    free,
    *,
    max_steps: int,
    key: PRNGKeyArray | None = None,
    weights: Array | None = None,
    natural: dict[str, float] | None = None,
):
    """A refit on this recording with the current natural scales."""
    scales = RefitScales(
        ctx.sample_rate, ctx.duration, state.natural if natural is None else natural
    )
    settings = RefitSettings(
        max_steps, ctx.policy.refit_swarm, ctx.records.stride(ctx.family, model)
    )
    return refit(
        ctx.family,
        model,
        list(free),
        ctx.inputs,
        ctx.measured,
        ctx.weights if weights is None else weights,
        ctx.solver,
        scales,
        settings,
        key=key,
    )


def _candidate_bug(effect: str, error: Exception) -> str:
    """Why a candidate's refit failed with an error of jaxhyst's own (a bug, not a
    property of the record): warned with its traceback, so that it can be reported,
    while the diagnosis goes on without that candidate."""
    warnings.warn(
        f"diagnose: refitting {effect} failed with an error in jaxhyst; the "
        "diagnosis goes on without it. Please report this traceback:\n"
        + "".join(traceback.format_exception(error)),
        RuntimeWarning,
        stacklevel=2,
    )
    return (
        f"the refit failed with an error in jaxhyst ({type(error).__name__}: "
        f"{error}); please report it"
    )


def _refit_or_none(ctx: _Context, state: _State, model, free, **options):
    """`_refit`, or None where it is numerically degenerate (`DegenerateRefit`):
    the caller keeps what it had, as after a refit that diverged."""
    try:
        return _refit(ctx, state, model, free, **options)
    except DegenerateRefit:
        return None


def _predict(ctx: _Context, model) -> np.ndarray:
    return ctx.records.predict(model, ctx.solver)


def _predict_each(ctx: _Context, models: list) -> list[np.ndarray]:
    """`_predict` of each of `models`. Where more than `BATCH` of them share a
    structure once their zero gains are held (`held_at_zero`: the terms of the
    effects that are off are not computed), those run held and batched
    (`DiagnosisRecords.predict_each`): on the piezo family's 45 000-sample records,
    11 ms per model against 78 ms one by one as they are, which repays the held
    batch's own compilation (1.1 s) within a group. Fewer run one by one through
    the one program all predictions share."""
    held = [model.held_at_zero(idle_gains(ctx.family, model, ())) for model in models]
    structures = [jax.tree.structure(model) for model in held]
    sizes = collections.Counter(structures)
    batched = [i for i, one in enumerate(structures) if sizes[one] > BATCH]
    predicted = dict(
        zip(batched, ctx.records.predict_each([held[i] for i in batched], ctx.solver))
    )
    return [
        predicted[i] if i in predicted else _predict(ctx, model)
        for i, model in enumerate(models)
    ]


def _step(ctx: _Context, label: str, predicted: np.ndarray, model) -> DiagnosisStep:
    residual = ctx.y - predicted
    return DiagnosisStep(
        label,
        math.sqrt(_mse(residual, slice(None))),
        math.sqrt(_mse(residual, ctx.hold_mask)),
        model,
    )


def _with_step(ctx: _Context, state: _State, label: str, **changes: Any) -> _State:
    """`state` with `changes`, and a row for the model it moves to in the chain."""
    state = dataclasses.replace(state, **changes)
    return dataclasses.replace(
        state,
        steps=state.steps + (_step(ctx, label, state.predicted, state.current),),
    )


def _heldout_comparison(
    ctx: _Context, state: _State, kept: np.ndarray, other: np.ndarray
) -> tuple[float, float, float]:
    """The held-out MSEs of two fits' outputs and the standard error of their
    difference (for noise as the noise model describes it)."""
    kept_mse = _mse(ctx.y - kept, ctx.hold_mask)
    other_mse = _mse(ctx.y - other, ctx.hold_mask)
    change = float(np.sqrt(np.mean((other - kept)[ctx.hold_mask] ** 2)))
    bound = math.sqrt(min(kept_mse, other_mse)) if ctx.policy.noise_bound else None
    resolution = state.noise_model.resolution(
        change, state.effective_heldout, bound=bound
    )
    return kept_mse, other_mse, resolution / RESOLVED_SIGMA


# ------------------------------------------------------------------- base fit


def _base_fit(
    ctx: _Context,
    base: AbstractHysteresisModel | None,
    swarms: tuple[MPSO, ...],
    progress: bool,
) -> tuple[_State, AbstractHysteresisModel]:
    """The base model fitted on the fit mask (unless given), and the extended model
    around it with every effect off. `swarms[0]` searches; a windowed start also
    tries the others."""
    swarm = swarms[0]
    if base is None:
        records = ctx.records
        several = records.several
        weights = (
            [jnp.asarray(m, ctx.measured.dtype) for m in records.split(ctx.fit_mask)]
            if several
            else ctx.weights
        )

        def fit_base(space: ParameterSpace | None, **options: Any) -> Fit:
            """The base model on every recording's fitted samples."""
            return identify(
                ctx.family.base_template(),
                list(records.recordings) if several else ctx.recording,
                key=ctx.key,
                space=space,
                solver=ctx.solver,
                weights=weights,
                analyse=False,
                progress=progress,
                stable_only=ctx.family.stable_fits,
                throw=False,
                **options,
            )

        start = None
        window = ctx.family.base_swarm_window(ctx.recording)
        swarm_space = ctx.family.base_swarm_space(ctx.recording)
        if window is not None and not several:
            start = _windowed_start(ctx, window, swarms, progress)
        elif swarm_space is not None:
            searched = fit_base(swarm_space, swarm=swarm, polish=None)
            start = ctx.family.base_gauge(searched.model)
        fit = fit_base(
            ctx.family.base_space(ctx.recording),
            swarm=None if start is not None else swarm,
            start=start,
        )
        # A base fit that ran out of polish steps is refined by every later
        # refit; one whose output is not finite leaves nothing to diagnose.
        if has_status(fit.result, RESULTS.nonfinite):
            raise ValueError(
                f"diagnose: the {ctx.family.base_name} base model's fit to "
                f"{ctx.recording.name!r} diverged (non-finite output); check the "
                "recording's columns and units, or pass base=<a fitted model>."
            )
        base = fit.model
    current = ctx.family.extend(base, ctx.recording)
    predicted = _predict(ctx, current)
    state = _State(current, predicted, ctx.family.base_free)
    state = dataclasses.replace(
        state, steps=(_step(ctx, f"{ctx.family.base_name} fitted", predicted, current),)
    )
    return state, base


def _windowed_start(
    ctx: _Context, window: int, swarms: tuple[MPSO, ...], progress: bool
) -> AbstractHysteresisModel:
    """The base swarm and polish on the first `window` samples at the full rate:
    `swarms[0]` from two keys, each further swarm from one (a swarm of a
    sharp-looped model can settle in a wrong basin: on a clean synthetic damper
    record one key's fit stayed at 9.4 noise sigmas, the other's reached 1.00), and
    a polish from each of the family's `base_starts`; the fit with the lowest
    fitted-sample error there. The base fit then polishes it on every fitted
    sample."""
    first = ctx.recording.segment(None, float(ctx.recording.t[window - 1]))
    weights = ctx.weights[: first.num_samples]
    space = ctx.family.base_space(ctx.recording)

    def window_fit(attempt: tuple[MPSO | None, Any, Any, bool]) -> tuple[Any, float]:
        swarm, key, start, shown = attempt
        fit = identify(
            ctx.family.base_template(),
            first,
            key=key,
            space=space,
            swarm=swarm,
            start=start,
            solver=ctx.solver,
            swarm_stride=1,
            weights=weights,
            analyse=False,
            progress=shown,
            stable_only=ctx.family.stable_fits,
            throw=False,
        )
        residual = (jnp.asarray(first.y) - jnp.asarray(fit.predicted)) * weights
        return fit.model, float(jnp.sum(residual**2))

    attempts = [(swarms[0], ctx.key, None)]
    attempts += [(swarms[0], jax.random.fold_in(ctx.key, 1), None)]
    attempts += [
        (other, jax.random.fold_in(ctx.key, 1 + number), None)
        for number, other in enumerate(swarms[1:], 1)
    ]
    attempts += [
        (None, ctx.key, start) for start in ctx.family.base_starts(ctx.recording, first)
    ]
    best, best_mse = None, math.inf
    # They run side by side: only the first shows its swarm's progress bar.
    shown = [
        (swarm, key, start, progress and i == 0)
        for i, (swarm, key, start) in enumerate(attempts)
    ]
    with side_by_side(window_fit, shown) as fits:
        for model, mse in fits:
            if math.isfinite(mse) and mse < best_mse:
                best, best_mse = model, mse
    if best is None:
        raise ValueError(
            f"diagnose: the {ctx.family.base_name} base model's fit to the start of "
            f"{ctx.recording.name!r} diverged (non-finite output); check the "
            "recording's columns and units, or pass base=<a fitted model>."
        )
    return best


# ------------------------------------------------------------------ score test


def _score_round(
    ctx: _Context, state: _State
) -> tuple[_State, list[Score], dict[str, float], dict[str, np.ndarray]]:
    """Score every effect not yet adopted: the residual's projection on the
    effect's directions after removing what the free parameters absorb, against an
    AR(2) noise model read from what no candidate explains. Also returns every
    parameter's natural scale and output sensitivities at the current model."""
    family, current = ctx.family, state.current
    remaining = _unscored(ctx, state)
    sensitive = set()
    for effect in family.catalogue:
        sensitive |= set(effect.sensitivity_parameters(current))
    owned = {p for e in family.catalogue for p in e.parameters}
    names = [
        n for n in fitted_names(family, current) if n not in owned or n in sensitive
    ]
    jac = ctx.records.jacobian(current, names, ctx.solver)
    column = {name: jac[:, i] for i, name in enumerate(names)}
    residual = ctx.y - state.predicted
    w = ctx.fit_mask.astype(float)
    base_cols = np.stack([column[p] for p in state.free], axis=1)
    dt = ctx.records.step
    projected = {}
    for effect in remaining:
        cols = effect.directions(column, state.predicted, dt)
        projected[effect.name] = (cols, project_off(base_cols, cols, w))
    # The noise's colour, read from what no candidate explains.
    everything = np.concatenate([p for _, p in projected.values()], axis=1)
    coef, *_ = np.linalg.lstsq(everything, residual * w, rcond=None)
    noise = NoiseModel.estimate(
        (residual * w - everything @ coef)[ctx.fit_mask],
        across_strides=ctx.policy.noise_across_strides,
    )
    scores = []
    for effect in remaining:
        cols, perp = projected[effect.name]
        params = effect.parameters
        norms = np.linalg.norm(perp, axis=0)
        usable = norms > 1e-9 * (np.linalg.norm(cols, axis=0) + 1e-300)
        if not usable.any():
            continue
        perp = perp[:, usable]
        stat = score_statistic(perp, residual * w, noise.ar, noise.innovation_var)
        dof = perp.shape[1]
        threshold = float(chi2().isf(ctx.policy.significance, dof))
        step, *_ = np.linalg.lstsq(perp, residual * w, rcond=None)
        scores.append(
            Score(
                effect.name,
                stat,
                dof,
                float(chi2().logsf(stat, dof) / np.log(10)),
                float(np.sum((perp @ step) ** 2) / max(1, w.sum())),
                bool(stat > threshold),
                dict(zip([p for p, ok in zip(params, usable) if ok], step.tolist())),
                perp,
            )
        )
    scores.sort(key=lambda c: -c.statistic / c.dof)
    rms_y = float(np.sqrt(np.mean(ctx.y**2)))
    natural = {}
    for p, col in column.items():
        norm = float(np.sqrt(np.mean(col**2)))
        natural[p] = rms_y / norm if norm > 0 else 1.0
    state = dataclasses.replace(
        state,
        noise=noise,
        effective_heldout=noise.effective_ratio * float(ctx.hold_mask.sum()),
    )
    return state, scores, natural, column


# ---------------------------------------------------------------------- refits


def _best_start(
    ctx: _Context, effect: AbstractEffect, current, step, scales, *, on: bool = False
):
    """The starting point with the lowest error on the fitted samples (`on`: among
    those with the effect switched on)."""
    best, best_mse = current, float("inf")
    starts = [
        trial
        for trial in effect.starting_points(current, step, scales)
        if not on or effect.is_on(trial)
    ]
    for trial, pred in zip(starts, _predict_each(ctx, starts)):
        if not _finite(pred):
            continue
        mse = float(np.mean((ctx.y - pred)[ctx.fit_mask] ** 2))
        if mse < best_mse:
            best, best_mse = trial, mse
    return best, best_mse


def _validate(
    ctx: _Context,
    state: _State,
    score: Score,
    effect: AbstractEffect,
    new_pred,
    *,
    parameters: int,
) -> Validation:
    """Held-out and fitted errors before and after, and the adoption rule: the
    held-out MSE drop must beat its own noise (its resolution) and the minimum
    gain, and the information criterion on the fitted samples must fall, charged
    for the `parameters` the candidate fitted (`AbstractEffect.fitted_dof`)."""
    noise = state.noise_model
    residual, new_res = ctx.y - state.predicted, ctx.y - new_pred
    before_hold, after_hold = (
        _mse(residual, ctx.hold_mask),
        _mse(new_res, ctx.hold_mask),
    )
    before_fit, after_fit = _mse(residual, ctx.fit_mask), _mse(new_res, ctx.fit_mask)
    n_eff_fit = noise.effective_ratio * ctx.fit_mask.sum()
    change = float(np.sqrt(np.mean((new_pred - state.predicted)[ctx.hold_mask] ** 2)))
    bound = math.sqrt(min(before_hold, after_hold)) if ctx.policy.noise_bound else None
    resolution = noise.resolution(change, state.effective_heldout, bound=bound)
    margin = max(ctx.policy.min_heldout_gain * before_hold, resolution)
    bic_change = n_eff_fit * math.log(after_fit / before_fit) + parameters * math.log(
        n_eff_fit
    )
    return Validation(
        math.sqrt(before_hold),
        math.sqrt(after_hold),
        math.sqrt(before_fit),
        math.sqrt(after_fit),
        margin,
        resolution,
        state.effective_heldout,
        bic_change,
        score.statistic,
        score.dof,
        score.log10_p,
        bool(before_hold - after_hold > margin and bic_change < 0),
    )


def refit_choice(
    family: AbstractFamily,
    policy: AdoptionPolicy,
    scores: list[Score],
    passed: Collection[str],
    structure_left: Callable[[], bool],
) -> tuple[list[Score], bool]:
    """The round's candidates to refit: the `refits_per_round` strongest
    significant ones, significant ones whose effect always asks for a refit, runners-up
    that passed before (`refit_runners_up`), and those the score cannot screen;
    when none is significant and `structure_left()` (asked only then), the
    strongest ones anyway (`refit_on_structure`; the second value says so)."""
    significant = [c for c in scores if c.significant]
    chosen = significant[: policy.refits_per_round] + [
        c
        for c in significant[policy.refits_per_round :]
        if family.effect(c.effect).always_refit()
    ]
    if policy.refit_runners_up:
        chosen += [c for c in scores if not c.significant and c.effect in passed]
    taken = {c.effect for c in chosen}
    chosen += [
        c
        for c in scores
        if c.effect not in taken and not family.effect(c.effect).score_screens()
    ]
    anyway = policy.refit_on_structure and not significant and structure_left()
    if anyway:
        taken = {c.effect for c in chosen}
        chosen += [c for c in scores if c.effect not in taken][
            : policy.refits_per_round
        ]
    return chosen, anyway


def _refit_candidates(
    ctx: _Context, state: _State, scores: list[Score]
) -> tuple[list[Score], list[_Trial]]:
    """Refit the strongest significant candidates (plus those whose effect asks
    for it, and those the score cannot screen) from their best starting points;
    validate each on held-out data. Returns the round's scores with what became of
    each, and the trials."""
    family, policy = ctx.family, ctx.policy
    chosen, anyway = refit_choice(
        family,
        policy,
        scores,
        state.passed,
        lambda: _structure_left(ctx, state),
    )
    if anyway:
        ctx.progress.say(
            "the score test flags nothing, but structure is left on the held-out "
            "samples: refitting the strongest candidates anyway"
        )
    if chosen:
        ctx.progress.say(
            "refitting " + ", ".join(c.effect for c in chosen) + " and validating "
            "each on the held-out samples"
        )
    scales = RefitScales(ctx.sample_rate, ctx.duration, state.natural)
    starts = {}
    updated = {c.effect: c for c in scores}

    def best_start(c: Score):
        return _best_start(ctx, family.effect(c.effect), state.current, c.step, scales)

    with side_by_side(best_start, chosen) as found:
        for c, (start, start_mse) in zip(chosen, found):
            starts[c.effect] = start
            updated[c.effect] = dataclasses.replace(c, start_mse=start_mse)
    for c in scores:
        if c.effect not in starts:
            reason = (
                "not significant"
                if not c.significant
                else f"significant, but not among the {policy.refits_per_round} "
                "strongest this round"
            )
            updated[c.effect] = dataclasses.replace(updated[c.effect], rejection=reason)

    def attempt(numbered: tuple[int, Score]) -> _Trial | _Failed:
        # The key counts the trials made before this one: `number` of them when
        # none of those failed.
        number, c = numbered
        effect = family.effect(c.effect)
        key = jax.random.fold_in(ctx.key, 1000 * len(state.findings) + number)
        trial = _trial(ctx, state, updated[c.effect], (effect,), starts[c.effect], key)
        if isinstance(trial, _Trial) and not trial.validation.accepted:
            trial = _with_dependents(ctx, state, trial, effect, scales, key)
        return trial

    trials = []
    numbered = list(enumerate(chosen))
    with side_by_side(attempt, numbered) as attempted:
        outcomes = list(attempted)
    for (number, c), trial in zip(numbered, outcomes):
        if number != len(trials):  # an earlier one failed: its key was not this
            trial = attempt((len(trials), c))
        if isinstance(trial, _Failed):
            updated[c.effect] = dataclasses.replace(
                updated[c.effect], rejection=trial.reason
            )
            continue
        updated[c.effect] = trial.score
        trials.append(trial)
    return [updated[c.effect] for c in scores], trials


def _structure_left(ctx: _Context, state: _State) -> bool:
    """Whether the model-free probes find structure in the current residual that
    they predict on the held-out samples (`unexplained_structure`)."""
    residual = ctx.y - state.predicted
    found = unexplained_structure(
        ctx.recording, ctx.family, residual, ctx.fit_mask, ctx.policy, seed=0
    )
    return bool(found)


def _trial(
    ctx: _Context,
    state: _State,
    score: Score,
    effects: tuple[AbstractEffect, ...],
    start: AbstractHysteresisModel,
    key: PRNGKeyArray,
) -> _Trial | _Failed:
    """`effects` (the scored one, then any dependents) refitted together from
    `start` and validated on the held-out samples (against the null refit when the
    policy asks); `_Failed` if the refit diverged or was numerically degenerate
    (`DegenerateRefit`): that candidate is rejected, the diagnosis goes on."""
    effect, dependents = effects[0], effects[1:]
    names = list(state.free) + [p for e in effects for p in e.parameters]
    try:
        refitted = _refit(
            ctx, state, start, names, max_steps=ctx.policy.candidate_steps, key=key
        )
    except DegenerateRefit as error:
        return _Failed(f"the refit was numerically degenerate: {error}")
    except Exception as error:  # a bug in one candidate's refit: the others go on
        return _Failed(_candidate_bug(effect.name, error))
    new_pred = _predict(ctx, refitted)
    if not _finite(new_pred):
        return _Failed("the refitted model diverged")
    parameters = sum(e.fitted_dof(refitted) for e in effects)
    validation = _validate(ctx, state, score, effect, new_pred, parameters=parameters)
    rejection = None if validation.accepted else _why_rejected(validation)
    null = None
    if ctx.policy.null_refit and validation.accepted:
        try:
            validation, rejection, null = _against_null(
                ctx, state, score, effects, refitted, new_pred, parameters=parameters
            )
        except DegenerateRefit:
            pass  # no null refit to judge against: the validation above stands
    together = tuple(e.name for e in dependents)
    score = dataclasses.replace(
        score, validation=validation, rejection=rejection, together=together
    )
    return _Trial(
        score, refitted, new_pred, validation, null, together, free=tuple(names)
    )


def _with_dependents(
    ctx: _Context,
    state: _State,
    alone: _Trial,
    effect: AbstractEffect,
    scales: RefitScales,
    key: PRNGKeyArray,
) -> _Trial:
    """An effect that failed validation alone, refitted together with each effect
    seen only through it (`AbstractEffect.needs`; e.g. a lag of the field, which a
    field dependence fitted without its lag cannot show): the first pair that passes,
    else the effect alone with what each pair reached added to its rejection."""
    notes = []
    dependents = [e for e in _unscored(ctx, state) if e.needs == effect.name]
    for dependent in dependents:
        # From the effect's own refit with the dependent switched on: at zero (a
        # lag of none) its derivative may not move it.
        together = _refit_with(
            ctx,
            state,
            alone,
            (effect, dependent),
            {},
            scales,
            jax.random.fold_in(key, 1 + ctx.family.effect_names.index(dependent.name)),
        )
        if isinstance(together, _Failed):
            notes.append(f"refitted together with {dependent.name}, {together.reason}")
            continue
        if together.validation.accepted:
            return together
        v = together.validation
        notes.append(
            f"refitted together with {dependent.name}, the held-out RMSE went "
            f"from {v.heldout_rmse_before:.3g} to {v.heldout_rmse_after:.3g}: "
            + (together.score.rejection or "")
        )
    if not notes:
        return alone
    rejection = "; ".join([alone.score.rejection or "", *notes])
    return dataclasses.replace(
        alone, score=dataclasses.replace(alone.score, rejection=rejection)
    )


def _jointly(ctx: _Context, state: _State, trials: list[_Trial]) -> _Trial | None:
    """When no candidate passed alone: the one that lowered the held-out error most,
    refitted together with each other refitted candidate in turn (best held-out
    error first); the first pair that passes validation, else None.

    Two effects present at once bias the model each is added to alone (the base
    parameters stand in for the other one), so each may fall short of the
    adoption margin while the pair clears it. The pair is validated as one
    candidate with both effects' parameters counted; the backward check then
    tests each alone."""
    family = ctx.family
    alone = sorted(
        (t for t in trials if not t.dependents),
        key=lambda t: t.validation.heldout_rmse_after,
    )
    if len(alone) < 2:
        return None
    first = alone[0]
    if not first.validation.heldout_rmse_after < first.validation.heldout_rmse_before:
        return None
    effect = family.effect(first.score.effect)
    scales = RefitScales(ctx.sample_rate, ctx.duration, state.natural)
    for other in alone[1:]:
        partner = family.effect(other.score.effect)
        ctx.progress.say(
            f"neither {effect.name} nor {partner.name} passed alone; refitting them "
            "together"
        )
        pair = _refit_with(
            ctx,
            state,
            first,
            (effect, partner),
            other.score.step,
            scales,
            jax.random.fold_in(
                ctx.key,
                7919
                + 100 * len(state.findings)
                + family.effect_names.index(partner.name),
            ),
        )
        if isinstance(pair, _Trial) and pair.validation.accepted:
            return dataclasses.replace(pair, joint=True)
    return None


def _refit_with(
    ctx: _Context,
    state: _State,
    alone: _Trial,
    effects: tuple[AbstractEffect, AbstractEffect],
    step: dict[str, float],
    scales: RefitScales,
    key: PRNGKeyArray,
) -> _Trial | _Failed:
    """`alone`'s effect (`effects[0]`) refitted together with `effects[1]`, from
    `alone`'s refit with the second switched on at its best starting point (from
    its score-test `step`); validated as one candidate."""
    start, _ = _best_start(ctx, effects[1], alone.model, step, scales, on=True)
    return _trial(
        ctx,
        state,
        dataclasses.replace(alone.score, validation=None, rejection=None),
        effects,
        start,
        key,
    )


def _against_null(
    ctx: _Context,
    state: _State,
    score: Score,
    effects: tuple[AbstractEffect, ...],
    refitted: AbstractHysteresisModel,
    predicted: np.ndarray,
    *,
    parameters: int,
) -> tuple[Validation, str | None, tuple[AbstractHysteresisModel, np.ndarray] | None]:
    """The candidate validated against the model it extends, refitted from the
    candidate's refitted values with its effects switched off (when that null fits
    the held-out data better than the current model)."""
    effect = effects[0]
    switched_off = refitted
    for each in effects:
        switched_off = each.switch_off(switched_off)
    null = _refit(
        ctx,
        state,
        switched_off,
        state.free,
        max_steps=ctx.policy.candidate_steps,
    )
    null_pred = _predict(ctx, null)
    current_hold = _mse(ctx.y - state.predicted, ctx.hold_mask)
    extra = {"parameters": parameters}
    if not _finite(null_pred) or _mse(ctx.y - null_pred, ctx.hold_mask) >= current_hold:
        return _validate(ctx, state, score, effect, predicted, **extra), None, None
    versus = dataclasses.replace(state, current=null, predicted=null_pred)
    validation = _validate(ctx, versus, score, effect, predicted, **extra)
    if validation.accepted:
        return validation, None, (null, null_pred)
    return (
        validation,
        "its held-out gain came from refitting the parameters already in the model "
        "(the refit found a better basin for them), not from the effect: "
        + _why_rejected(validation),
        (null, null_pred),
    )


def _why_rejected(v: Validation) -> str:
    gain = v.heldout_rmse_before**2 - v.heldout_rmse_after**2
    if gain <= v.heldout_margin_mse:
        return (
            f"held-out MSE fell by {gain:.3g}, not more than the {v.heldout_margin_mse:.3g} "
            "adoption needs (its resolution or the minimum gain)"
        )
    return f"the information criterion rose by {v.bic_change:.3g}"


# -------------------------------------------------------------------- adoption


def _adopt(ctx: _Context, state: _State, trials: list[_Trial]) -> _State:
    """Adopt the accepted trial with the lowest held-out error, then converge the
    model with it before looking further: an under-fitted winner leaves structure
    that would pass for a further effect. (The other accepted trials are its
    rivals, compared once the selection is complete.)"""
    family, policy = ctx.family, ctx.policy
    winner = min(
        (t for t in trials if t.validation.accepted),
        key=lambda t: t.validation.heldout_rmse_after,
    )
    name = winner.score.effect
    where_now = family.locate(ctx.recording, ctx.y - state.predicted)
    effect = family.effect(name)
    finding = Finding(
        effect=name,
        evidence=_evidence(effect, winner.validation, where_now, winner.model),
        where=family.describe(where_now),
        score=float(winner.score.statistic),
        parameters=effect.values(winner.model),
        before=error_metrics(ctx.y, state.predicted),
        after=error_metrics(ctx.y, winner.predicted),
        validation=winner.validation,
    )
    findings = (finding,)
    for dependent_name in winner.dependents:
        dependent = family.effect(dependent_name)
        v = winner.validation
        why = (
            f"neither it nor {name} passed held-out validation alone (each biases the "
            "model the other is added to)"
            if winner.joint
            else f"it shows only through {name} (its score test has no direction "
            f"while {name} is off) and {name} alone did not pass held-out validation"
        )
        findings += (
            Finding(
                effect=dependent_name,
                evidence=f"{dependent.meaning}. {why[0].upper()}{why[1:]}, so the two "
                "were refitted together: adding "
                f"both lowered the held-out RMSE from {v.heldout_rmse_before:.3g} to "
                f"{v.heldout_rmse_after:.3g}. The backward check tests each alone.",
                where=family.describe(where_now),
                score=math.nan,
                parameters=dependent.values(winner.model),
                before=error_metrics(ctx.y, state.predicted),
                after=error_metrics(ctx.y, winner.predicted),
                validation=v,
            ),
        )
    added = [p for f in findings for p in family.effect(f.effect).parameters]
    free = state.free + tuple(p for p in added if p not in state.free)
    label = " and ".join((name, *winner.dependents))
    state = _with_step(
        ctx,
        state,
        f"{label} added (refit on the fitted samples)",
        current=winner.model,
        predicted=winner.predicted,
        free=free,
        findings=state.findings + findings,
    )
    ctx.progress.say(f"adopted {label}; converging the model with it")
    current = _refit_or_none(
        ctx, state, winner.model, free, max_steps=policy.converge_steps
    )
    if current is None:
        return state
    predicted = _predict(ctx, current)
    if not _finite(predicted) or _mse(ctx.y - predicted, ctx.fit_mask) > _mse(
        ctx.y - winner.predicted, ctx.fit_mask
    ):
        return state
    return _with_step(
        ctx,
        state,
        f"refit converged with {label}",
        current=current,
        predicted=predicted,
    )


def _near_misses(
    ctx: _Context, state: _State, column: dict[str, np.ndarray], trials: list[_Trial]
) -> list[Ambiguity]:
    """When nothing was adopted: rejected candidates that an adopted effect may be
    standing in for. Signatures are compared beyond what the base model's own
    parameters explain (both sides are largely functions of the input otherwise)."""
    family = ctx.family
    w = ctx.fit_mask.astype(float)
    base_only = np.stack([column[p] for p in family.base_free], axis=1)

    def signature(effect: AbstractEffect) -> np.ndarray:
        names = [p for p in effect.parameters if p in column]
        if not names:
            return np.zeros((ctx.y.size, 0))
        return moving_columns(np.stack([column[p] for p in names], axis=1))

    adopted = {
        name: project_off(base_only, signature(family.effect(name)), w)
        for name in state.adopted
    }
    raw = {}
    for trial in trials:
        effect = family.effect(trial.score.effect)
        raw[effect.name] = project_off(
            base_only,
            effect.directions(column, state.predicted, ctx.records.step),
            w,
        )
    rejected = [(t.score.effect, t.validation) for t in trials]
    return standing_in(
        rejected,
        raw,
        adopted,
        overlap=ctx.policy.overlap,
        min_gain=ctx.policy.min_heldout_gain,
    )


def _better_base(ctx: _Context, state: _State, trials: list[_Trial]):
    """The null refit (no effect added) that fits the fitted samples best, if it
    beats the current model there."""
    nulls = [t.null for t in trials if t.null is not None]
    if not nulls:
        return None
    best = min(nulls, key=lambda n: _mse(ctx.y - n[1], ctx.fit_mask))
    if _mse(ctx.y - best[1], ctx.fit_mask) < _mse(
        ctx.y - state.predicted, ctx.fit_mask
    ):
        return best
    return None


def _forward(ctx: _Context, state: _State) -> _State:
    """Forward selection: score, refit, adopt; until nothing is accepted."""
    for number in range(1, ctx.policy.max_effects + 1):
        if not _unscored(ctx, state):
            break
        ctx.progress.say(f"round {number}: scoring {_remaining(ctx, state)}")
        # The base fit checked through `identify`; each round compiles refits.
        release_if_near_map_limit("diagnose")
        state, scores, natural, column = _score_round(ctx, state)
        if any(c.significant for c in scores):
            # Refits (this round's and any later stage's) use these scales.
            state = dataclasses.replace(state, natural=natural)
        scores, trials = _refit_candidates(ctx, state, scores)
        accepted = [t for t in trials if t.validation.accepted]
        # Where the mismatch is now, kept with each trial that passed.
        where = (
            ctx.family.locate(ctx.recording, ctx.y - state.predicted)
            if accepted
            else {}
        )
        passed = {t.score.effect: (t, where) for t in accepted}
        tried = {t.score.effect for t in trials}
        untried = {
            name: score
            for name, score in {
                **state.untried,
                **{c.effect: c for c in scores if c.significant},
            }.items()
            if name not in tried and name not in state.passed_trials
        }
        failed = {t.score.effect: t for t in trials if not t.validation.accepted}
        state = dataclasses.replace(
            state,
            rounds=state.rounds + (scores,),
            passed_trials={**state.passed_trials, **passed},
            untried=untried,
            failed_trials={
                **{n: t for n, t in state.failed_trials.items() if n not in passed},
                **failed,
            },
        )
        if not passed:
            pair = _jointly(ctx, state, trials) if ctx.policy.pair_refits else None
            if pair is not None:
                state = _adopt(ctx, state, [pair])
                continue
            better = _better_base(ctx, state, trials)
            if better is not None:
                # No effect, but a better basin for the model's own parameters:
                # take it and score again from there.
                state = _with_step(
                    ctx,
                    state,
                    "base parameters refitted (a better basin, no effect added)",
                    current=better[0],
                    predicted=better[1],
                )
                continue
            near = _near_misses(ctx, state, column, trials) if trials else []
            rejected = [(t.score.effect, t.validation) for t in trials]
            near += unresolved(rejected, min_gain=ctx.policy.min_heldout_gain)
            near += confined(
                rejected,
                min_gain=ctx.policy.min_heldout_gain,
                already=frozenset(e for a in near for e in a.undecided),
            )
            by_effect = {t.score.effect: t for t in trials}
            contrasts = tuple(
                _Contrast(a.undecided, state.current, by_effect[a.undecided[0]].model)
                for a in near
            )
            return dataclasses.replace(
                state,
                ambiguities=state.ambiguities + tuple(near),
                contrasts=state.contrasts + contrasts,
            )
        state = _adopt(ctx, state, trials)
    return state


def _unscored(ctx: _Context, state: _State) -> list[AbstractEffect]:
    """The catalogue effects not adopted yet that the record can show."""
    return [
        e
        for e in ctx.family.catalogue
        if e.name not in state.adopted and e.name not in ctx.hidden
    ]


def _remaining(ctx: _Context, state: _State) -> str:
    names = [e.name for e in _unscored(ctx, state)]
    return ", ".join(names) if names else "nothing left"


# ------------------------------------------------------- backward check, swaps


def _backward(ctx: _Context, state: _State) -> _State:
    """Drop any adopted effect that no longer earns its place once later ones are
    in (e.g. a rate dependence that was standing in for an input network)."""
    family = ctx.family
    if len(state.findings) >= 2:
        ctx.progress.say("backward check: does every effect still earn its place?")
    while len(state.findings) >= 2:
        hold_now = _mse(ctx.y - state.predicted, ctx.hold_mask)
        weakest = None

        def without(finding: Finding, state: _State = state):
            effect = family.effect(finding.effect)
            names = tuple(p for p in state.free if p not in effect.parameters)
            reduced = _refit_or_none(
                ctx, state, effect.switch_off(state.current), names, max_steps=20
            )
            if reduced is None:  # no reduced model to judge by: the effect stays
                return names, None, None
            return names, reduced, _predict(ctx, reduced)

        with side_by_side(without, state.findings) as refitted:
            reductions = list(zip(state.findings, refitted))
        for finding, (names, reduced, reduced_pred) in reductions:
            if reduced_pred is None or not _finite(reduced_pred):
                continue
            loss = _mse(ctx.y - reduced_pred, ctx.hold_mask) - hold_now
            change = float(
                np.sqrt(np.mean((reduced_pred - state.predicted)[ctx.hold_mask] ** 2))
            )
            needed = max(
                ctx.policy.min_heldout_gain * _mse(ctx.y - reduced_pred, ctx.hold_mask),
                state.noise_model.resolution(change, state.effective_heldout),
            )
            if loss < needed and (weakest is None or loss < weakest[1]):
                weakest = (finding, loss, reduced, reduced_pred, names)
        if weakest is None:
            break
        finding, _, current, predicted, free = weakest
        findings = tuple(f for f in state.findings if f is not finding)
        message = (
            f"{finding.effect} was adopted, then dropped: once "
            f"{', '.join(f.effect for f in findings)} had been added it no longer "
            "lowered the held-out error by more than its noise."
        )
        state = _with_step(
            ctx,
            state,
            f"{finding.effect} dropped (backward check)",
            current=current,
            predicted=predicted,
            free=free,
            findings=findings,
            ambiguities=state.ambiguities + (Ambiguity(message),),
        )
    return state


def _rivals(ctx: _Context, state: _State) -> _State:
    """Test every finding against its rivals: each effect that passed held-out
    validation in some round and is not adopted, refitted in the finding's place
    with the other findings kept, compared on the held-out samples in standard
    errors of the difference. A rival better beyond the resolution replaces the
    finding (greedy choices made while a later effect was unmodelled can be
    wrong); rivals within it leave the finding undecided, said as an ambiguity.
    Among effects the record cannot tell apart, the fit keeps the one with the
    lowest held-out error: a validated rival better within the resolution also
    replaces the finding (undecided), since the order of adoption says nothing
    about which explanation the complete model prefers. An effect so replaced is
    not brought back by a rival within the resolution."""
    family = ctx.family
    position, replacements = 0, 0
    # Effects a rival replaced within the resolution: not swapped back in.
    left_behind: set[str] = set()
    while position < len(state.findings):
        finding = state.findings[position]
        adopted_effect = family.effect(finding.effect)
        others = _rival_names(ctx, state, finding.effect)
        if others:
            ctx.progress.say(
                f"testing {finding.effect} against its rivals: {', '.join(others)}"
            )
        rivals: list[tuple[Rival, AbstractHysteresisModel]] = []
        replaced, closer = None, None
        swap_in = functools.partial(_swapped_in, ctx, state, position, adopted_effect)
        with side_by_side(swap_in, others) as swaps:
            for name, (names, swapped, swapped_pred) in zip(others, swaps):
                alternative = family.effect(name)
                trial, where_then = state.passed_trials.get(name, (None, None))
                if swapped is None or swapped_pred is None or not _finite(swapped_pred):
                    continue
                kept_mse, rival_mse, se = _heldout_comparison(
                    ctx, state, state.predicted, swapped_pred
                )
                margin = (rival_mse - kept_mse) / se if se > 0 else 0.0
                if (
                    margin < 0
                    and trial is not None
                    and where_then is not None
                    and replacements < len(family.catalogue)
                ):
                    swap = _Swap(
                        trial,
                        where_then,
                        alternative,
                        swapped,
                        swapped_pred,
                        names,
                        kept_mse,
                        rival_mse,
                        resolved=margin < -RESOLVED_SIGMA,
                    )
                    if swap.resolved:
                        replaced = swap
                        break
                    if name not in left_behind and (
                        closer is None or rival_mse < closer.rival_mse
                    ):
                        closer = swap
                rivals.append((Rival(name, math.sqrt(rival_mse), margin), swapped))
        if replaced is None and closer is not None:
            replaced = closer
            left_behind.add(finding.effect)
        if replaced is not None:
            state = _replace_finding(ctx, state, position, replaced)
            replacements += 1
            continue  # test the replacement against its own rivals
        close = [(r, m) for r, m in rivals if not r.resolved]
        findings = list(state.findings)
        findings[position] = dataclasses.replace(
            finding, rivals=tuple(r for r, _ in rivals)
        )
        state = dataclasses.replace(state, findings=tuple(findings))
        if close:
            kept_rmse = math.sqrt(_mse(ctx.y - state.predicted, ctx.hold_mask))
            state = dataclasses.replace(
                state,
                ambiguities=state.ambiguities
                + (
                    cannot_tell_rivals(
                        finding.effect,
                        [r for r, _ in close],
                        kept_rmse,
                        kept_because=_kept_because(
                            close, left_behind, state.passed_trials
                        ),
                    ),
                ),
                contrasts=state.contrasts
                + tuple(
                    _Contrast((finding.effect, r.effect), state.current, m)
                    for r, m in close
                ),
            )
        position += 1
    return state


def _forms_apart(ctx: _Context, state: _State) -> _State:
    """Each finding whose effect has several forms on, refitted in each of them
    alone (`AdoptionPolicy.forms_apart`) and compared with its forms together on
    the held-out samples, in standard errors of the difference. A form alone within
    the resolution of the forms together, or better, takes their place; of several,
    the one with the lowest held-out error, and the forms within the resolution of
    it are said: the record cannot tell them apart."""
    if not ctx.policy.forms_apart:
        return state
    for finding in state.findings:
        effect = ctx.family.effect(finding.effect)
        on = effect.forms_on(state.current)
        if len(on) < 2 or any(
            not set(effect.forms[form]) & set(effect.gains) for form in on
        ):
            continue
        ctx.progress.say(f"refitting {finding.effect} in each of its forms alone")
        alone = functools.partial(_in_form_alone, ctx, state, effect)
        with side_by_side(alone, on) as refits:
            fitted = [each for each in refits if each is not None]
        simpler = []
        for each in fitted:
            kept_mse, form_mse, se = _heldout_comparison(
                ctx, state, state.predicted, each.predicted
            )
            if form_mse - kept_mse < RESOLVED_SIGMA * se:
                simpler.append(each)
        if not simpler:
            continue
        best = min(simpler, key=lambda r: r.heldout_mse)
        close = []
        for each in fitted:
            if each is best:
                continue
            best_mse, other_mse, se = _heldout_comparison(
                ctx, state, best.predicted, each.predicted
            )
            if other_mse - best_mse < RESOLVED_SIGMA * se:
                close.append(each)
        statements = ()
        if close:
            figures = "; ".join(
                f"{r.form} {math.sqrt(r.heldout_mse):.3g}" for r in (best, *close)
            )
            statements = (
                Ambiguity(
                    f"cannot tell the forms of {finding.effect} apart on this "
                    f"recording: {best.form} alone and "
                    f"{', '.join(r.form for r in close)} alone each fit the "
                    f"held-out samples within the {RESOLVED_SIGMA:.0f} standard "
                    f"errors this comparison needs (held-out RMSE {figures}). The "
                    f"fit keeps {best.form}, with the lowest held-out error; the "
                    f"record shows {finding.effect}, not which of these forms it "
                    "takes.",
                    concerns=(finding.effect,),
                ),
            )
        ctx.progress.say(f"{finding.effect}: its {best.form} form alone kept")
        state = _with_step(
            ctx,
            state,
            f"{finding.effect} in its {best.form} form alone",
            current=best.model,
            predicted=best.predicted,
            free=best.free,
            ambiguities=state.ambiguities + statements,
        )
    return state


# An effect adopted after others stays a finding when it fits the held-out samples
# better than a form correction of them by more than this many standard errors of
# the difference: the held-out data favour it over the correction beyond their
# noise. (At the resolution, 3, true second effects on short records were lost
# beside their partners: a pinching beside a degradation on the structural suite's
# 1000-point record, 1.90 against 2.08 held out, about 3 standard errors.)
FORM_CORRECTION_SIGMA = 1.0


def _form_corrections(ctx: _Context, state: _State) -> _State:
    """Each finding adopted after others, last first, against a form correction of
    the earlier ones (`AdoptionPolicy.form_correction`): the model without it
    (refitted, the other findings kept) plus the best of the family's model-free
    loop corrections (`form_probes`: the residual's bin means, learnt on the
    fitted samples). A finding that does not fit the held-out samples better by
    `FORM_CORRECTION_SIGMA` standard errors is not named: what it took up may be a
    form of the earlier findings that the catalogue does not have."""
    if not ctx.policy.form_correction or len(state.findings) < 2:
        return state
    probes = ctx.family.form_probes(ctx.recording)
    for index in range(len(state.findings) - 1, 0, -1):
        earlier = [
            f.effect
            for f in state.findings[:index]
            if ctx.family.effect(f.effect).form_in_loops
        ]
        if earlier:
            state = _against_form_correction(ctx, state, index, earlier, probes)
    return state


def _against_form_correction(
    ctx: _Context,
    state: _State,
    index: int,
    earlier: list[str],
    probes: tuple[ResidualProbe, ...],
) -> _State:
    """`state`, or without its finding at `index` where the model without it plus
    a form correction (`_form_corrections`) fits the held-out samples as well."""
    finding = state.findings[index]
    effect = ctx.family.effect(finding.effect)
    free = tuple(p for p in state.free if p not in effect.parameters)
    ctx.progress.say(
        f"{finding.effect} against a form correction of {', '.join(earlier)}"
    )
    refitted = _short_refit(
        ctx,
        state,
        effect.switch_off(state.current),
        free,
        f"the model without {finding.effect}",
    )
    if refitted is None:  # no model without it to judge by: the finding stays
        return state
    reduced, reduced_pred = refitted
    residual = ctx.y - reduced_pred
    corrections = [
        (probe, reduced_pred + bin_prediction(probe.labels, residual, ctx.fit_mask))
        for probe in probes
    ]
    probe, corrected = min(corrections, key=lambda c: _mse(ctx.y - c[1], ctx.hold_mask))
    kept_mse, corrected_mse, se = _heldout_comparison(
        ctx, state, state.predicted, corrected
    )
    margin = (corrected_mse - kept_mse) / se if se > 0 else math.inf
    ctx.progress.say(
        f"{finding.effect}: held-out RMSE {math.sqrt(kept_mse):.4g} with it, "
        f"{math.sqrt(corrected_mse):.4g} without it and corrected ({probe.what}): "
        f"{margin:.1f} standard errors"
    )
    if margin > FORM_CORRECTION_SIGMA:
        return state
    forms = " and ".join(earlier)
    ctx.progress.say(f"{finding.effect} not named: a form correction fits as well")
    statement = Ambiguity(
        f"{finding.effect} may be present, or the form of {forms} differs from "
        f"the catalogue's: the model without {finding.effect}, corrected by a "
        f"model-free function of {probe.what} learnt on the fitted samples, fits "
        f"the held-out samples as well as the model with it (held-out RMSE "
        f"{math.sqrt(corrected_mse):.3g} against {math.sqrt(kept_mse):.3g}: "
        f"{finding.effect} is ahead by {margin:.1f} standard errors of the "
        f"difference, not the {FORM_CORRECTION_SIGMA:.0f} it needs). "
        f"{finding.effect} is not named; what it took up is left to what is left "
        f"of the residual. A record on which {finding.effect} shows apart from "
        f"{forms} would tell (see the advice).",
        (finding.effect,),
    )
    return _with_step(
        ctx,
        state,
        f"{finding.effect} dropped (a form correction of {forms} fits as well)",
        current=reduced,
        predicted=reduced_pred,
        free=free,
        findings=tuple(f for f in state.findings if f is not finding),
        ambiguities=tuple(
            a for a in state.ambiguities if finding.effect not in a.concerns
        )
        + (statement,),
        contrasts=state.contrasts
        + (_Contrast((finding.effect,), state.current, reduced),),
    )


class _FormAlone(eqx.Module):
    """A finding refitted in one of its forms alone: the form, the model, its
    output and held-out MSE, and the refit's free parameters."""

    form: str
    model: AbstractHysteresisModel
    predicted: np.ndarray
    heldout_mse: float
    free: tuple[str, ...]


def _short_refit(
    ctx: _Context, state: _State, start, free: tuple[str, ...], what: str
) -> tuple[AbstractHysteresisModel, np.ndarray] | None:
    """A 20-step polish of `start` over `free` and its output; None where it is
    degenerate, not finite, or fails with an error of jaxhyst's own (warned with
    its traceback: `what` names the refit), so that the caller keeps what it had."""
    try:
        model = _refit_or_none(ctx, state, start, free, max_steps=20)
    except Exception as error:  # a bug in this refit: the caller keeps its model
        _candidate_bug(what, error)
        return None
    if model is None:
        return None
    predicted = _predict(ctx, model)
    return (model, predicted) if _finite(predicted) else None


def _in_form_alone(
    ctx: _Context, state: _State, effect: AbstractEffect, form: str
) -> _FormAlone | None:
    """The finding `effect` refitted in its form `form` alone (the other forms'
    parameters held, their gains at zero), polished from its values in the current
    model; None where that refit is degenerate or fails."""
    start, held = effect.alone(state.current, form)
    free = tuple(p for p in state.free if p not in held)
    refitted = _short_refit(
        ctx, state, start, free, f"{effect.name} in its form {form}"
    )
    if refitted is None:
        return None
    model, predicted = refitted
    return _FormAlone(
        form, model, predicted, _mse(ctx.y - predicted, ctx.hold_mask), free
    )


def _swapped_in(
    ctx: _Context,
    state: _State,
    position: int,
    adopted_effect: AbstractEffect,
    name: str,
) -> tuple[tuple[str, ...], AbstractHysteresisModel | None, np.ndarray | None]:
    """The rival `name` refitted in the place of the finding at `position` (with
    the other findings kept): the refit's free parameters, the model, its output
    (None for both where the refit is numerically degenerate)."""
    family = ctx.family
    alternative = family.effect(name)
    names = tuple(p for p in state.free if p not in adopted_effect.parameters) + tuple(
        p for p in alternative.parameters if p not in state.free
    )
    without = adopted_effect.switch_off(state.current)
    key = jax.random.fold_in(
        ctx.key, 7919 + 97 * position + family.effect_names.index(name)
    )
    if name in state.passed_trials:
        trial, _ = state.passed_trials[name]
        start = alternative.take_from(without, trial.model)
        if _fitted_already(family, trial, start, names):
            return names, trial.model, trial.predicted
    elif name in state.untried:
        scales = RefitScales(ctx.sample_rate, ctx.duration, state.natural)
        start, _ = _best_start(
            ctx, alternative, without, state.untried[name].step, scales
        )
    else:
        # A rival of the whole catalogue starts from the best of its starting
        # points and its failed refit (which had its swarm), and is polished only.
        start, key = _rival_start(ctx, state, alternative, without), None
    try:
        swapped = _refit_or_none(ctx, state, start, names, max_steps=20, key=key)
    except Exception as error:  # a bug in one rival's refit: the finding stays
        _candidate_bug(name, error)
        swapped = None
    if swapped is None:  # no rival model to compare: the finding stays
        return names, None, None
    return names, swapped, _predict(ctx, swapped)


def _rival_names(ctx: _Context, state: _State, effect: str) -> list[str]:
    """The effects the finding `effect` is tested against: each effect that passed
    held-out validation in some round or was significant but never refitted, and,
    with `AdoptionPolicy.whole_catalogue_rivals`, every other effect of the
    catalogue the record can show (scored in some round, its `needs` among the
    findings kept): an effect that failed validation while another was standing in
    for it is a rival too."""
    named = [
        n for n in (*state.passed_trials, *state.untried) if n not in state.adopted
    ]
    if not ctx.policy.whole_catalogue_rivals:
        return named
    kept = set(state.adopted) - {effect}
    return named + [
        e.name
        for e in _unscored(ctx, state)
        if e.name not in named
        and state.latest_score(e.name) is not None
        and (e.needs is None or e.needs in kept)
    ]


def _rival_start(
    ctx: _Context,
    state: _State,
    alternative: AbstractEffect,
    without: AbstractHysteresisModel,
) -> AbstractHysteresisModel:
    """Where the refit of a rival that neither passed validation nor waits untried
    starts, in the model `without` the finding: the best (on the fitted samples) of
    its starting points from its latest score's step, with the effect on, and of
    its failed refit's values, when it had one."""
    scales = RefitScales(ctx.sample_rate, ctx.duration, state.natural)
    score = state.latest_score(alternative.name)
    step = {} if score is None else score.step
    start, start_mse = _best_start(ctx, alternative, without, step, scales, on=True)
    failed = state.failed_trials.get(alternative.name)
    if failed is not None:
        earlier = alternative.take_from(without, failed.model)
        predicted = _predict(ctx, earlier)
        if _finite(predicted) and _mse(ctx.y - predicted, ctx.fit_mask) < start_mse:
            start = earlier
    return start


def _fitted_already(
    family: AbstractFamily, trial: _Trial, start, names: tuple[str, ...]
) -> bool:
    """Whether `trial` refitted the very model that a refit of `names` from `start`
    fits: the same free parameters, and every other value the same (a rival tried
    when the other findings were what they are now), but for the shape parameters
    of effects that are off in both (inert: a refit holds their gains at zero, so
    their terms are not even computed; e.g. the time constant of an input network
    adopted since, switched off again for the swap). Its refit is then the rival's
    swap, and is not done again."""
    if set(trial.free) != set(names) or type(trial.model) is not type(start):
        return False
    fitted = trial.model.parameters()
    swap = start.replace(**{p: fitted[p] for p in names})
    inert = [
        p
        for effect in family.catalogue
        if not effect.is_on(swap) and not effect.is_on(trial.model)
        for p in effect.shape_parameters
    ]
    swap = swap.replace(**{p: fitted[p] for p in inert})
    return bool(eqx.tree_equal(swap, trial.model))


class _Swap(eqx.Module):
    """A validated rival that fits the held-out data better than a finding: its
    trial, where the mismatch was then, the rival refitted in the finding's place
    (`swapped`, with its output) and the free parameters of that refit; the two
    held-out MSEs; whether the difference is beyond the resolution."""

    trial: _Trial
    where_then: dict[str, Any]
    alternative: AbstractEffect
    swapped: AbstractHysteresisModel
    swapped_pred: np.ndarray
    names: tuple[str, ...]
    kept_mse: float
    rival_mse: float
    resolved: bool


def _kept_because(
    close: list[tuple[Rival, Any]], left_behind: set[str], validated: Collection[str]
) -> str:
    """Why a finding stays in the fit although `close` rivals are within the
    resolution (`validated`: the effects that passed held-out validation alone)."""
    better = [r.effect for r, _ in close if r.margin_sigma < 0]
    if not better:
        return "its held-out error is the lowest of them"
    back = [name for name in better if name in left_behind]
    if back:
        return f"it replaced {', '.join(back)} first"
    if any(name not in validated for name in better):
        return "it was adopted first; the better rival was never validated alone"
    return "it was adopted first"


def _replace_finding(
    ctx: _Context, state: _State, position: int, swap: _Swap
) -> _State:
    """`state` with the finding at `position` replaced by `swap.alternative`
    (refitted in its place as `swap.swapped`), converged. Statements made before
    on whether the alternative is present besides the replaced finding (and the
    advice that would test them) are superseded, and dropped."""
    finding = state.findings[position]
    alternative, swapped, swapped_pred = (
        swap.alternative,
        swap.swapped,
        swap.swapped_pred,
    )
    later = [f.effect for f in state.findings if f is not finding]
    how = (
        "beyond the resolution)."
        if swap.resolved
        else "within the resolution: the record cannot tell them apart, and the fit "
        "keeps the one with the lower held-out error)."
    )
    message = (
        f"{finding.effect} was adopted first, then replaced by {alternative.name}: "
        + (f"with {', '.join(later)} modelled, " if later else "")
        + f"{alternative.name} explains the held-out data better (RMSE "
        f"{math.sqrt(swap.rival_mse):.3g} vs {math.sqrt(swap.kept_mse):.3g}, " + how
    )
    ctx.progress.say(f"{finding.effect} replaced by {alternative.name}")
    replacement = Finding(
        effect=alternative.name,
        evidence=_evidence(
            alternative, swap.trial.validation, swap.where_then, swapped
        ),
        where=ctx.family.describe(swap.where_then),
        score=float(swap.trial.score.statistic),
        parameters=alternative.values(swapped),
        before=error_metrics(ctx.y, state.predicted),
        after=error_metrics(ctx.y, swapped_pred),
        validation=dataclasses.replace(swap.trial.validation, replaced=finding.effect),
    )
    findings = list(state.findings)
    findings[position] = replacement
    superseded = (alternative.name,)
    state = _with_step(
        ctx,
        state,
        f"{finding.effect} replaced by {alternative.name}",
        current=swapped,
        predicted=swapped_pred,
        free=swap.names,
        findings=tuple(findings),
        ambiguities=tuple(a for a in state.ambiguities if a.undecided != superseded)
        + (Ambiguity(message),),
        contrasts=tuple(c for c in state.contrasts if c.separates != superseded),
    )
    current = _refit_or_none(
        ctx, state, swapped, swap.names, max_steps=ctx.policy.converge_steps
    )
    if current is None:
        return state
    predicted = _predict(ctx, current)
    if not _finite(predicted) or _mse(ctx.y - predicted, ctx.fit_mask) > _mse(
        ctx.y - swapped_pred, ctx.fit_mask
    ):
        return state
    return _with_step(
        ctx,
        state,
        f"refit converged with {alternative.name}",
        current=current,
        predicted=predicted,
    )


def _final_refit(
    ctx: _Context, state: _State
) -> tuple[AbstractHysteresisModel, np.ndarray]:
    """With effects adopted, the model refitted on every sample."""
    if not state.findings:
        return state.current, state.predicted
    ctx.progress.say("final refit on every sample")
    # Unit weights rather than None: the same structure as the masked refits, so
    # this fit reuses their compiled Levenberg-Marquardt program.
    final_model = _refit_or_none(
        ctx,
        state,
        state.current,
        state.free,
        max_steps=ctx.policy.final_steps,
        weights=ctx.records.stacked(np.ones(ctx.y.shape, ctx.y.dtype)),
        natural={},
    )
    if final_model is None:
        return state.current, state.predicted
    final_pred = _predict(ctx, final_model)
    if _finite(final_pred) and _mse(ctx.y - final_pred, slice(None)) <= _mse(
        ctx.y - state.predicted, slice(None)
    ):
        return final_model, final_pred
    return state.current, state.predicted


def _refitted_on_every_sample(
    ctx: _Context, state: _State
) -> tuple[_State, AbstractHysteresisModel, np.ndarray]:
    """`_final_refit`, with its step recorded when it moved the model."""
    final_model, final_pred = _final_refit(ctx, state)
    if final_model is not state.current:
        state = _with_step(
            ctx,
            state,
            "final refit on every sample",
            current=final_model,
            predicted=final_pred,
        )
    return state, final_model, final_pred


# A parameter that moves by more than this share of its size between adoption and
# the final model (and by more than the resolution in standard errors) is flagged.
MOVE_SHARE = 0.25


def _described(
    ctx: _Context,
    state: _State,
    final_model: AbstractHysteresisModel,
    final_pred: np.ndarray,
) -> tuple[tuple[Finding, ...], dict[str, dict[str, float]]]:
    """Each finding with its values in the final model, their standard errors (from
    the final model's output sensitivities) and units, their physical reading, and
    a flag on a large move since adoption; and the free parameters' correlations
    (parameter -> parameter -> correlation)."""
    if not state.findings:
        return (), {}
    ctx.progress.say("standard errors of the final model's parameters")
    names = list(state.free)
    # The effects left off are held at zero: their terms cost nothing here.
    held = final_model.held_at_zero(idle_gains(ctx.family, final_model, names))
    jac = ctx.records.jacobian(held, names, ctx.solver)
    errors_array, corr = errors_and_correlations(jac, ctx.y - final_pred)
    errors = dict(zip(names, errors_array.tolist()))
    correlations = {
        p: dict(zip(names, row.tolist())) for p, row in zip(names, np.asarray(corr))
    }
    recording = ctx.recording
    described = []
    for index, finding in enumerate(state.findings):
        effect = ctx.family.effect(finding.effect)
        values = effect.values(final_model)
        se = {p: float(errors.get(p, math.nan)) for p in values}
        units = effect.units(
            time=recording.time_unit,
            input=recording.input_unit,
            output=recording.output_unit,
        )
        later = [f.effect for f in state.findings[index + 1 :]]
        described.append(
            dataclasses.replace(
                finding,
                final_parameters=values,
                standard_errors=se,
                units=units,
                form=effect.form(final_model, se, correlations),
                meaning=effect.meaning,
                reading=effect.reading(values, se, units),
                moved=_moved(finding.parameters, values, se, units, later),
            )
        )
    return tuple(described), correlations


def _undetermined(
    ctx: _Context,
    findings: tuple[Finding, ...],
    correlations: dict[str, dict[str, float]],
) -> dict[str, str]:
    """The findings whose defining parameters the record does not determine
    (`AbstractEffect.undetermined`, given the parameters' `correlations`), with
    why in words."""
    why = {}
    for finding in findings:
        effect = ctx.family.effect(finding.effect)
        values, errors = finding.final_parameters, finding.standard_errors
        names = effect.undetermined(values, errors, correlations)
        if names:
            why[finding.effect] = ", ".join(
                f"{p} = {quantity(values[p], errors.get(p), finding.units[p])}"
                for p in names
            )
    return why


def _without(ctx: _Context, state: _State, dropped: dict[str, str]) -> _State:
    """`state` without the findings in `dropped` (effect: why undetermined): an
    effect that lowers the error with parameters the record does not determine is
    not a finding; its terms leave the model, and what they took up is left to the
    remainder and the unexplained-structure probes."""
    family = ctx.family
    current, free = state.current, state.free
    statements = []
    for name, why in dropped.items():
        effect = family.effect(name)
        current = effect.switch_off(current)
        free = tuple(p for p in free if p not in effect.parameters)
        ctx.progress.say(f"{name} not named: the record does not determine it")
        statements.append(
            Ambiguity(
                f"{name} lowered the held-out error, but the record does not "
                f"determine its defining parameters ({why}): it is not named, and "
                "what it took up is left to what is left of the residual. A "
                "record that excites it more would tell.",
                (name,),
            )
        )
    findings = tuple(f for f in state.findings if f.effect not in dropped)
    # What was said of a dropped finding's forms is no longer about a finding.
    kept = tuple(a for a in state.ambiguities if not set(a.concerns) & set(dropped))
    if not findings:
        # Nothing named: the base fit, as on a record where nothing was found (the
        # base parameters moved with the dropped effects and would not come back
        # by a refit from there).
        current = state.steps[0].model
    return _with_step(
        ctx,
        state,
        " and ".join(dropped) + " dropped (not determined by the record)",
        current=current,
        predicted=_predict(ctx, current),
        free=free,
        findings=findings,
        ambiguities=kept + tuple(statements),
    )


def _moved(
    adopted: dict[str, float],
    final: dict[str, float],
    errors: dict[str, float],
    units: dict[str, str],
    later: list[str],
) -> str | None:
    """Words for the parameters that moved a lot between adoption and the final
    model (beyond `MOVE_SHARE` of their size and the resolution), and why they can."""
    parts = []
    for name, before in adopted.items():
        after, se = final[name], errors[name]
        change = abs(after - before)
        if change <= MOVE_SHARE * max(abs(before), abs(after)):
            continue
        if math.isfinite(se) and change <= RESOLVED_SIGMA * se:
            continue
        size = f", {change / se:.0f} standard errors" if math.isfinite(se) else ""
        unit = "" if units[name] == "1" else f" {units[name]}"
        parts.append(f"{name} {before:.3g} -> {after:.3g}{unit}{size}")
    if not parts:
        return None
    why = (
        f"{', '.join(later)} adopted after it took up part of what it first absorbed; "
        if later
        else ""
    ) + "the final refit fits every sample, the held-out ones too"
    return f"moved between adoption and the final model: {'; '.join(parts)} ({why})."


def _advice(ctx: _Context, state: _State) -> list[Advice]:
    """For each pair of fitted models the record cannot tell apart, the family's
    proposed test under which their outputs differ most, in noise sigmas."""
    if not state.contrasts:
        return []
    ctx.progress.say("simulating the rival models under tests that could separate them")
    # At several sample rates the joined record's time is not the tests' own:
    # each recording proposes its tests.
    probes = (
        [p for r in ctx.records.recordings for p in ctx.family.probes(r)]
        if ctx.records.mixed_rates
        else ctx.family.probes(ctx.recording)
    )
    sigma = state.noise_model.sd
    advice = []
    for contrast in state.contrasts:
        here = _rms(_predict(ctx, contrast.kept) - _predict(ctx, contrast.other))
        best = None
        for probe in probes:
            apart = predict(contrast.kept, probe.path, ctx.solver) - predict(
                contrast.other, probe.path, ctx.solver
            )
            if _finite(apart) and (best is None or _rms(apart) > best[1]):
                best = (probe, _rms(apart))
        if best is not None:
            advice.append(
                Advice(
                    contrast.separates,
                    best[0].description,
                    best[1] / sigma,
                    here / sigma,
                )
            )
    return advice


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x**2)))


def _evidence(
    effect: AbstractEffect, v: Validation, where: dict[str, Any], model
) -> str:
    return (
        f"{effect.meaning}. Score test: statistic {v.score_statistic:.3g} on "
        f"{v.score_dof} dof (log10 p = {v.log10_p:.1f}); {effect.evidence(where, model)}. "
        f"Adding it lowered the held-out RMSE from {v.heldout_rmse_before:.3g} to "
        f"{v.heldout_rmse_after:.3g}."
    )


# --------------------------------------------------------------------- diagnose


def diagnose(
    recording: Recording | Sequence[Recording],
    *,
    key: PRNGKeyArray,
    family: AbstractFamily = PiezoFamily(),
    base: AbstractHysteresisModel | None = None,
    holdout_fraction: float = 0.3,
    policy: AdoptionPolicy | None = None,
    swarm: MPSO | None = None,
    progress: bool = False,
    device: jax.Device | None = None,
) -> Diagnosis:
    """Find the physics `family`'s base model leaves out of `recording` (one
    `Recording`, or a list of recordings of one specimen: one model for all of them).

    1. Hold-out: about `holdout_fraction` of the record is held out, as the family
       splits it (piezo: 30 short blocks interleaved through the record; structural:
       whole cycles, interleaved, one per amplitude level).
    2. Base fit: the family's base model on the fitted samples (or `base`).
    3. Forward selection, per round: every effect not yet adopted is scored by a
       Lagrange-multiplier test, the residual's projection on the effect's
       directions after removing what the free parameters absorb, with the residual
       and directions pre-whitened by an AR(2) noise model read from what no
       candidate explains (coloured noise does not pass for physics). The
       strongest significant candidates are refitted (best starting point, short
       swarm, Levenberg-Marquardt) and one is adopted only if it lowers the
       held-out error by more than its resolution and the policy's minimum gain and
       lowers an information criterion on the fitted samples. When none passes
       alone, the policy may refit the best with each other one as a pair.
    4. Backward check, then swaps: effects that no longer earn their place are
       dropped, runners-up that explain the held-out data better replace them.
       Each finding is refitted against every other effect of the catalogue in
       its place, and in each of its forms alone; an effect adopted after others
       must beat a model-free correction of the loop that stands for their forms
       differing from the catalogue's (`AdoptionPolicy.form_correction`).
    5. Final refit on every sample, and the residual that remains structured on
       held-out data but matches no effect is reported as `unexplained`.

    Several recordings (same units) are diagnosed as one: each is split by the
    family's rule (held-out data in every recording) and simulated from its own
    initial state, all of them share the model's parameters, and the
    sample-wise analysis reads their samples one after another (the `joined`
    record: the `Diagnosis`'s predictions, masks and locations are on it; times
    in it continue across the joins). Recordings at different sample rates are
    each simulated at their own (none resampled); the joined record then runs at
    the finest one's step, which is also the rate the refit bounds read, the
    refit stride is the smallest any recording asks for and the slowest time
    scale is their total duration (`DiagnosisRecords`). `Diagnosis.per_recording`
    has each recording's errors before and after. Each recording must start from
    rest, as separate tests do: a piece cut from the middle of a longer record
    starts with a hysteretic state the model does not know (on a synthetic piezo
    record cut in two, the second half simulated from rest missed by 38 noise
    sigmas).

    `policy` holds the adoption rules (`AdoptionPolicy`; None: the family's
    `default_policy()`). `swarm`: the base fit's swarm (None: the family's
    `base_swarm()`, and its `base_swarm_alternatives()` where the family starts
    from a window; unused when `base` is given). `device`: where the
    diagnosis runs; None: the host CPU when the default device is an accelerator
    (its refits and Jacobians integrate one trajectory at a time, which a CPU
    runs faster), else the default device.
    """
    recordings = (recording,) if isinstance(recording, Recording) else recording
    if not isinstance(recordings, Sequence) or isinstance(recordings, str):
        raise TypeError(
            "diagnose: recording must be a Recording or a list of Recordings, got "
            f"{type(recording).__name__}."
        )
    if not recordings:
        raise ValueError(
            "diagnose: the list of recordings is empty; pass at least one."
        )
    for index, each in enumerate(recordings):
        if not isinstance(each, Recording):
            raise TypeError(
                f"diagnose: recording[{index}] must be a Recording, got "
                f"{type(each).__name__}."
            )
    if not isinstance(family, AbstractFamily):
        raise TypeError(
            "diagnose: family must be a family object such as jh.families.PiezoFamily() or "
            f"jh.families.StructuralFamily(), got {type(family).__name__}."
        )
    if policy is None:
        policy = family.default_policy()
    swarms = (
        (family.base_swarm(), *family.base_swarm_alternatives())
        if swarm is None
        else (swarm,)
    )
    if not isinstance(policy, AdoptionPolicy):
        raise TypeError(
            f"diagnose: policy must be an AdoptionPolicy, got {type(policy).__name__}."
        )
    if not 0.05 <= holdout_fraction <= 0.5:
        raise ValueError(
            f"diagnose: holdout_fraction={holdout_fraction} must be in [0.05, 0.5]."
        )
    for each in recordings:
        family.check(each)
    records = DiagnosisRecords.of(tuple(recordings), "diagnose")
    device = serial_device(device)
    with running_on(device):
        return _diagnose(
            records,
            moved_to(key, device),
            family=family,
            base=moved_to(base, device),
            holdout_fraction=holdout_fraction,
            policy=policy,
            swarms=swarms,
            progress=progress,
        )


def _diagnose(
    records: DiagnosisRecords,
    key: PRNGKeyArray,
    *,
    family: AbstractFamily,
    base: AbstractHysteresisModel | None,
    holdout_fraction: float,
    policy: AdoptionPolicy,
    swarms: tuple[MPSO, ...],
    progress: bool,
) -> Diagnosis:
    start_time = time.perf_counter()
    recording = records.joined
    masks = [family.holdout(each, holdout_fraction) for each in records.recordings]
    for each, mask in zip(records.recordings, masks):
        if mask.all() or not mask.any():
            raise ValueError(
                f"diagnose: recording {each.name!r} is too short to hold part of it "
                "out (the family's split left nothing on one side); record more "
                "cycles."
            )
    fit_mask = np.concatenate(masks)
    measured = records.stacked(recording.y)
    ctx = _Context(
        recording,
        records,
        family,
        policy,
        key,
        records.inputs,
        measured,
        np.asarray(recording.y),
        fit_mask,
        ~fit_mask,
        records.stacked(fit_mask.astype(measured.dtype)),
        family.solver(recording),
        recording.sample_rate,
        records.duration,
        Progress(progress),
        family.cannot_show(recording),
    )
    for name, reason in ctx.hidden.items():
        ctx.progress.say(f"not scoring {name}: {reason}")
    ctx.progress.say(f"fitting the {family.base_name} base model")
    state, base = _base_fit(ctx, base, swarms, progress)
    base_predicted = state.predicted
    baseline = error_metrics(ctx.y, base_predicted)
    location = family.locate(recording, ctx.y - base_predicted)
    state = _forward(ctx, state)
    state = _backward(ctx, state)
    state = _rivals(ctx, state)
    state = _forms_apart(ctx, state)
    state = _form_corrections(ctx, state)
    advice = _advice(ctx, state)
    state, final_model, final_pred = _refitted_on_every_sample(ctx, state)
    findings, correlations = _described(ctx, state, final_model, final_pred)
    dropped = _undetermined(ctx, findings, correlations)
    if dropped:
        state = _without(ctx, state, dropped)
        state, final_model, final_pred = _refitted_on_every_sample(ctx, state)
        findings, _ = _described(ctx, state, final_model, final_pred)
    # The noise draws the unexplained probes are judged against, from the key.
    draws_seed = int(jax.random.randint(jax.random.fold_in(key, 977), (), 0, 2**31 - 1))
    undecided = tuple(
        dict.fromkeys(
            name
            for a in state.ambiguities
            for name in a.undecided
            if name not in state.adopted
        )
    )
    unexplained: list[Unexplained] = unexplained_structure(
        recording,
        family,
        ctx.y - final_pred,
        fit_mask,
        policy,
        seed=draws_seed,
        undecided=undecided,
    )
    final_residual = ctx.y - final_pred
    centred = final_residual - final_residual.mean()
    lag1 = float(
        np.dot(centred[:-1], centred[1:]) / max(np.dot(centred, centred), 1e-300)
    )
    noise = {
        "sigma": float(np.sqrt(np.mean(final_residual**2))),
        "lag1_autocorrelation": lag1,
        "effective_samples": effective_samples(final_residual),
    }
    names = [p for p in family.base_free + family.gauge]
    for finding in state.findings:
        names += list(family.effect(finding.effect).parameters)
    final_parameters = {
        n: float(getattr(final_model, n))
        for n in final_model.parameter_names
        if n in names
    }
    what_is_left = remainder(recording, ctx.y - final_pred, heldout=~fit_mask)
    per_recording = ()
    if records.several:
        per_recording = tuple(
            RecordingErrors(
                each.name,
                each.num_samples,
                error_metrics(y, before),
                error_metrics(y, after),
            )
            for each, y, before, after in zip(
                records.recordings,
                records.split(ctx.y),
                records.split(base_predicted),
                records.split(final_pred),
            )
        )
    return Diagnosis(
        recording=recording.name,
        samples=recording.num_samples,
        family=family.name,
        base_name=family.base_name,
        base_model=base,
        final_model=final_model,
        baseline=baseline,
        final=error_metrics(ctx.y, final_pred),
        findings=list(findings),
        unexplained=unexplained,
        rounds=list(state.rounds),
        ambiguities=list(state.ambiguities),
        advice=advice,
        steps=list(state.steps),
        noise_sigma=noise["sigma"],
        noise=noise,
        location=location,
        base_predicted=base_predicted,
        final_predicted=final_pred,
        heldout=~fit_mask,
        holdout_description=family.holdout_description,
        holdout_fraction=float(holdout_fraction),
        final_parameters=final_parameters,
        exports=family.exports(final_model, recording),
        seconds=time.perf_counter() - start_time,
        remainder=what_is_left,
        per_recording=per_recording,
        cannot_show=tuple(
            NotShown(name, reason) for name, reason in ctx.hidden.items()
        ),
        loops=None if records.several else family.loop_indicators(recording),
    )
