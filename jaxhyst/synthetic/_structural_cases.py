"""Concealed structural cases: a quasi-static test that hides catalogue effects
under load-cell noise, and the truth behind it."""

from collections.abc import Mapping

import equinox as eqx
import jax
import numpy as np
from jaxtyping import PRNGKeyArray

from .._diagnose._families import STRUCTURAL_EFFECT_NAMES
from .._models.bouc_wen import BoucWen
from .._recording import Recording
from .._simulate import RK4
from ._checks import _validate_effects, _validate_noise, _validate_sizes
from ._noise import _load_cell_noise
from ._protocols import _check_points, _check_protocol, loading_protocol
from ._random import _loguniform, _rng
from ._size_search import _rms
from ._structural_sizing import _SIZERS, _Context, _run, _truth_solver
from ._structural_truth import StructuralTruth, structural_base_truth


_DEFAULT_SIZES = (4.0, 12.0)  # noise sigmas, when size_sigmas is None


class StructuralCase(eqx.Module):
    """A synthetic structural test and the truth behind it.

    - `recording`: the noisy record (u the displacement in mm, y the force in kN, t
      the pseudo time: the sample index, `time_unit` "sample");
    - `effects`: the concealed effects, in catalogue order (empty: a clean record);
    - `sigma`: the noise's marginal standard deviation (kN);
    - `sizes`: per effect, the RMS of (F with that effect alone - F without it) in
      units of `sigma`;
    - `forms`: per effect, the truth form used (see `STRUCTURAL_FORMS`);
    - `truth_description`: the base, the protocol, each effect's form and
      coefficients, and the noise;
    - `truth`: the `StructuralTruth` that made the noise-free force, `base` the
      Bouc-Wen model under it (what a perfect diagnosis recovers), `noiseless` that
      force, `noise` the noise kind, `protocol` the loading protocol, `solver` the
      integrator used.
    """

    recording: Recording
    effects: tuple[str, ...]
    sigma: float
    sizes: dict[str, float]
    forms: dict[str, str]
    truth_description: str
    truth: StructuralTruth
    base: BoucWen
    noiseless: np.ndarray
    noise: str
    protocol: str
    solver: RK4


def structural_recording(
    effects: tuple[str, ...],
    *,
    key: PRNGKeyArray,
    noise: str = "white",
    protocol: str = "cyclic",
    points: int = 2000,
    size_sigmas: float | Mapping[str, float] | None = None,
) -> StructuralCase:
    """A quasi-static test of a structural element (`structural_base_truth`: a
    Bouc-Wen restoring force, x in mm, F in kN) under an imposed-displacement
    `protocol` ("cyclic" or "earthquake", see `loading_protocol`) of `points`
    samples, that conceals `effects` (the structural catalogue's names,
    `jh.families.STRUCTURAL_EFFECT_NAMES`: degradation, pinching, asymmetry, drift;
    `()` gives a clean recording), plus load-cell noise.

    Each effect's form differs from the diagnosis catalogue's (`StructuralBoucWen`;
    see `StructuralTruth`), two forms per mechanical effect, drawn from the key.
    Its size is set so that the RMS of the change it makes, alone, is `size_sigmas`
    noise sigmas: one number for all, a mapping per effect, or None to draw each from
    [4, 12]. Where a form cannot reach the size within its realistic range (e.g. a
    Baber-Noori depth above 0.95) the other form is used; `sizes` reports what was
    reached (within 0.5 % of the request when reached) and `forms` which form.

    `noise` is "white" (Gaussian) or "coloured" (AR(1) with coefficient 0.6-0.9, at
    the same marginal sigma); sigma is 0.6-1.5 % of the base force's peak |F|. The
    recording's time is the pseudo time t = sample index (dt = 1).

    Everything random follows from `key`: the base, the protocol, each effect's form
    and size, and the noise. The same key with different effects gives the same
    base, displacement history and noise, so records differ only by the effects.
    """
    owner = "structural_recording"
    effects = _validate_effects(effects, STRUCTURAL_EFFECT_NAMES, owner)
    _rng(key, owner)
    noise = _validate_noise(noise, owner)
    protocol = _check_protocol(owner, protocol)
    _check_points(owner, points)
    sizes_wanted = _validate_sizes(size_sigmas, effects, owner)

    k_base, k_protocol, k_effects, k_sizes, k_noise = jax.random.split(key, 5)

    def effect_rng(root, effect: str) -> np.random.Generator:
        return _rng(
            jax.random.fold_in(root, STRUCTURAL_EFFECT_NAMES.index(effect)), owner
        )

    if sizes_wanted is None:
        sizes_wanted = {
            e: float(effect_rng(k_sizes, e).uniform(*_DEFAULT_SIZES)) for e in effects
        }

    base = structural_base_truth(k_base)
    quiet = StructuralTruth(base)
    x_y = float(quiet.yield_displacement)
    path, what_protocol = loading_protocol(
        k_protocol, yield_displacement=x_y, protocol=protocol, points=points
    )
    x = np.asarray(path.values)
    solver = _truth_solver(x, x_y)
    y_base, states = _run(quiet, path, solver)
    noise_rng = _rng(k_noise, owner)
    peak = float(np.max(np.abs(y_base)))
    sigma = _loguniform(noise_rng, 0.006, 0.015) * peak

    def measure(field: str, component) -> float:
        model = eqx.tree_at(lambda m: getattr(m, field), quiet, component)
        return _rms(_run(model, path, solver)[0] - y_base)

    ctx = _Context(
        x,
        x_y,
        float(base.k),
        float(base.alpha),
        float(states[-1, 2]),
        float(points - 1),
        measure,
    )
    components, sizes, forms, lines = {}, {}, {}, []
    for effect in effects:
        target = sizes_wanted[effect] * sigma
        field, component, reached, form, what = _SIZERS[effect](
            effect_rng(k_effects, effect), ctx, target
        )
        components[field] = component
        sizes[effect] = reached / sigma
        forms[effect] = form
        lines.append(f"{effect} [{form}]: {what}; size {sizes[effect]:.3g} sigma")

    truth = StructuralTruth(base, **components)
    y_true = _run(truth, path, solver)[0] if effects else y_base
    e, what_noise = _load_cell_noise(noise_rng, noise, sigma, y_true.shape[0])
    label = "+".join(effects) if effects else "clean"
    recording = Recording(
        np.arange(points, dtype=np.float64),
        x,
        y_true + e,
        name=f"structural-{label}-{protocol}-{noise}",
        input_name="displacement",
        output_name="force",
        input_unit="mm",
        output_unit="kN",
        time_unit="sample",
    )
    p = {k: float(v) for k, v in base.parameters().items()}
    head = (
        f"base: BoucWen(k={p['k']:.5g}, alpha={p['alpha']:.4g}, D=1, A=1, "
        f"beta={p['beta']:.5g}, gamma={p['gamma']:.5g}, n={p['n']:.4g}) [x in mm, F "
        f"in kN]; x_y {x_y:.4g} mm, F_y {float(quiet.yield_force):.4g} kN"
    )
    body = lines or ["no effects (clean recording)"]
    tail = (
        f"noise: {what_noise}, sigma {sigma:.4g} kN ({sigma / peak:.3%} of the peak "
        "force)"
    )
    return StructuralCase(
        recording=recording,
        effects=effects,
        sigma=sigma,
        sizes=sizes,
        forms=forms,
        truth_description="\n".join(
            [head, f"protocol: {what_protocol}, {points} points", *body, tail]
        ),
        truth=truth,
        base=base,
        noiseless=y_true,
        noise=noise,
        protocol=protocol,
        solver=solver,
    )
