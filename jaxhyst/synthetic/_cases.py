"""Concealed piezo cases: a recording that hides catalogue effects under sensor
noise, and the truth behind it."""

from collections.abc import Mapping

import equinox as eqx
import jax
import numpy as np
from jaxtyping import PRNGKeyArray

from .._diagnose._families import EFFECT_NAMES
from .._inputs import InputPath
from .._models.bouc_wen import PiezoBoucWen
from .._recording import Recording
from .._simulate import RK4
from ._checks import (
    _check_positive,
    _validate_effects,
    _validate_noise,
    _validate_sizes,
)
from ._excitation import AbstractExcitation, rich_excitation
from ._noise import _sensor_noise
from ._random import _loguniform, _rng
from ._size_search import _rms
from ._sizing import _SIZERS, _Context, _run, _truth_solver
from ._truth import ConcealedTruth, base_truth


_DEFAULT_SIZES = (3.0, 10.0)  # noise sigmas, when size_sigmas is None


class ConcealedCase(eqx.Module):
    """A synthetic recording and the truth behind it.

    - `recording`: the noisy record (u in V, y in um);
    - `effects`: the concealed effects, in catalogue order (empty: a clean record);
    - `sigma`: the noise's marginal standard deviation (um);
    - `sizes`: per effect, the RMS of (y with that effect alone - y without it) in
      units of `sigma`;
    - `truth_description`: the base parameters, each effect's form and coefficients,
      and the noise;
    - `truth`: the `ConcealedTruth` that made the noise-free output, `base` the piezo
      model under it (what a perfect diagnosis recovers), `noiseless` that output,
      `noise` the noise kind, `solver` the integrator used.
    """

    recording: Recording
    effects: tuple[str, ...]
    sigma: float
    sizes: dict[str, float]
    truth_description: str
    truth: ConcealedTruth
    base: PiezoBoucWen
    noiseless: np.ndarray
    noise: str
    solver: RK4


def _validate_arguments(effects, key, noise, size_sigmas, owner: str):
    """Check everything before any work: (effects, noise, sizes or None)."""
    effects = _validate_effects(effects, EFFECT_NAMES, owner)
    _rng(key, owner)
    noise = _validate_noise(noise, owner)
    return effects, noise, _validate_sizes(size_sigmas, effects, owner)


def _concealed_case(
    path: InputPath,
    effects: tuple[str, ...],
    key: PRNGKeyArray,
    noise: str,
    size_sigmas,
    name: str,
    owner: str,
    *,
    input_line: str | None = None,
    note_shortfall: bool = False,
) -> ConcealedCase:
    """The case for `effects` on `path`. `input_line`, if given, describes the input
    as the first line of the truth description; with `note_shortfall` an effect that
    stayed below 95 % of its requested size says so in its line."""
    effects, noise, sizes_wanted = _validate_arguments(
        effects, key, noise, size_sigmas, owner
    )
    k_base, k_effects, k_sizes, k_noise = jax.random.split(key, 4)

    def effect_rng(root, effect: str) -> np.random.Generator:
        return _rng(jax.random.fold_in(root, EFFECT_NAMES.index(effect)), owner)

    if sizes_wanted is None:
        sizes_wanted = {
            e: float(effect_rng(k_sizes, e).uniform(*_DEFAULT_SIZES)) for e in effects
        }

    base = base_truth(k_base)
    rate = 1.0 / float(path.dt)
    solver = _truth_solver(rate)
    quiet = ConcealedTruth(base)
    y_base = _run(quiet, path, solver)
    noise_rng = _rng(k_noise, owner)
    sigma = _loguniform(noise_rng, 5e-4, 2e-3) * float(np.ptp(y_base))

    def measure(field: str, component) -> float:
        model = eqx.tree_at(lambda m: getattr(m, field), quiet, component)
        return _rms(_run(model, path, solver) - y_base)

    ctx = _Context(path, np.asarray(path.values), float(path.t1 - path.t0), measure)
    components, sizes, lines = {}, {}, []
    for effect in effects:
        target = sizes_wanted[effect] * sigma
        field, component, reached, what = _SIZERS[effect](
            effect_rng(k_effects, effect), ctx, target
        )
        components[field] = component
        sizes[effect] = reached / sigma
        line = f"{effect}: {what}; size {sizes[effect]:.3g} sigma"
        if note_shortfall and reached < 0.95 * target:
            line += (
                f" (requested {sizes_wanted[effect]:.3g} sigma: this input does not "
                "show more of it)"
            )
        lines.append(line)

    truth = ConcealedTruth(base, **components)
    y_true = _run(truth, path, solver) if effects else y_base
    e, what_noise = _sensor_noise(noise_rng, noise, sigma, y_true.shape[0])
    t = np.asarray(path.times)
    recording = Recording(
        t,
        np.asarray(path.values),
        y_true + e,
        name=name,
        input_name="u",
        output_name="y",
        input_unit="V",
        output_unit="um",
    )
    p = {k: float(v) for k, v in base.parameters().items()}
    head = (
        f"base: PiezoBoucWen(k1={p['k1']:.5g}, k2={p['k2']:.5g}, A1={p['A1']:.5g}, "
        f"beta1={p['beta1']:.5g}, gamma1={p['gamma1']:.5g}, n={p['n']:.4g}) "
        "[u in V, y in um]"
    )
    tail = (
        f"noise: {what_noise}, sigma {sigma:.4g} um "
        f"({sigma / np.ptp(y_base):.3%} of the output range)"
    )
    body = lines or ["no effects (clean recording)"]
    first = [] if input_line is None else [input_line]
    return ConcealedCase(
        recording=recording,
        effects=effects,
        sigma=sigma,
        sizes=sizes,
        truth_description="\n".join([*first, head, *body, tail]),
        truth=truth,
        base=base,
        noiseless=y_true,
        noise=noise,
        solver=solver,
    )


def concealed_recording(
    effects: tuple[str, ...],
    *,
    key: PRNGKeyArray,
    duration: float = 45.0,
    rate: float = 1000.0,
    noise: str = "white",
    size_sigmas: float | Mapping[str, float] | None = None,
) -> ConcealedCase:
    """A recording of a paper-like piezo stage (`base_truth`) under `rich_excitation`
    that conceals `effects` (the piezo catalogue's names, `jh.families.EFFECT_NAMES`:
    asymmetry, input_bias, rate_dependence, creep, dynamics, drift; `()` gives a clean
    recording), plus sensor noise.

    Each effect's form differs from the diagnosis catalogue's (see `ConcealedTruth`)
    and its size is set so that the RMS of the change it makes, alone, is
    `size_sigmas` noise sigmas: one number for all, a mapping per effect, or None to
    draw each from [3, 10]. `noise` is "white" (Gaussian) or "coloured" (AR(1) with
    coefficient 0.9-0.98, sometimes plus a little white noise, at the same marginal
    sigma); sigma is 0.05-0.2 % of the output range.

    `sizes` reports what was reached (within 0.5 % of the request). Where a variant
    cannot reach the request (a branch-dependent beta or a rate-dependent amplitude
    bounded by the hysteresis itself) the other variant of that effect is used; a
    stage mode is never shown with a participation above 1, so on a record with
    little fast content a dynamics effect can come out smaller than requested.

    Everything random follows from `key`: the excitation, the base model, each
    effect's variant and size, and the noise. The same key with different effects
    gives the same input, base and noise, so records differ only by the effects.
    """
    owner = "concealed_recording"
    _check_positive(owner, "duration", duration)
    _check_positive(owner, "rate", rate)
    effects, noise, _ = _validate_arguments(effects, key, noise, size_sigmas, owner)
    k_input, k_case = jax.random.split(key)
    path = rich_excitation(k_input, duration=duration, rate=rate)
    label = "+".join(effects) if effects else "clean"
    return _concealed_case(
        path, effects, k_case, noise, size_sigmas, f"concealed-{label}-{noise}", owner
    )


def practical_recording(
    effects: tuple[str, ...],
    *,
    key: PRNGKeyArray,
    excitation: AbstractExcitation,
    duration: float = 20.0,
    rate: float = 1000.0,
    noise: str = "white",
    size_sigmas: float | Mapping[str, float] | None = None,
) -> ConcealedCase:
    """A recording like the ones people have: the paper-like piezo stage of
    `concealed_recording` under a plain drive, `excitation` (a `SineExcitation` of one
    or two sines, a `SwitchOnSine`; a short `duration` for a short record), sampled
    at `rate` Hz for `duration` seconds, concealing `effects` under sensor noise.

    Effects, sizes and noise follow `concealed_recording` exactly (the same truth
    forms, sizing and noise kinds; `size_sigmas` None draws each size from [3, 10]
    noise sigmas). Everything random follows from `key`; the input is fixed by
    `excitation`, so the same key with different effects gives the same input, base
    and noise, and records differ only by the effects.

    A plain drive shows some effects little: `sizes` reports what was reached, and
    the truth description says when an effect stayed below 95 % of its requested size
    (a stage mode, never shown with a participation above 1, on a slow sine).
    On such records some effects also look alike (a delay of the drive, a rate
    dependence and creep on one sine), which is the point of these records.
    """
    owner = "practical_recording"
    if not isinstance(excitation, AbstractExcitation):
        raise TypeError(
            f"{owner}: excitation must be an excitation object, e.g. "
            "SineExcitation((1.0,)), SineExcitation((1.0, 5.0)) or SwitchOnSine(1.0), "
            f"got {type(excitation).__name__}."
        )
    _check_positive(owner, "duration", duration)
    _check_positive(owner, "rate", rate)
    effects, noise, _ = _validate_arguments(effects, key, noise, size_sigmas, owner)
    path = excitation.path(duration, rate)
    label = "+".join(effects) if effects else "clean"
    return _concealed_case(
        path,
        effects,
        key,
        noise,
        size_sigmas,
        f"practical-{label}-{noise}",
        owner,
        input_line=(
            f"input: {excitation.describe()}; {float(duration):g} s at {float(rate):g} Hz"
        ),
        note_shortfall=True,
    )
