"""The command line's one table from names to objects: every `--model`, `--signal`
and `--preset` value, what it means (for `--help`) and what it builds. A name is
added here and nowhere else."""

import importlib
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any, NamedTuple

import jax
import numpy as np

from .._models.base import AbstractHysteresisModel
from .._models.bouc_wen import BoucWen, CorrectedPiezoBoucWen, PiezoBoucWen, PiezoStage
from .._models.damper import BoucWenDamper, SpencerDamper
from .._signals import AbstractSignal, Chirp, Multisine, Triangle, paper_u1, paper_u2


if TYPE_CHECKING:
    from .._diagnose._families import AbstractFamily


# ------------------------------------------------------------------ --seed


def prng_key(seed: int) -> jax.Array:
    """`jax.random.key(seed)`, the key every `--seed` means. With 64-bit JAX (as the
    command line runs) and its default threefry generator, the key is the seed's 64
    bits as two 32-bit words, made here on the host: `jax.random.key` compiles two
    small programs for it, 0.07 s of a command's cold start. Other generators and
    seeds outside int64 go through `jax.random.key` (and its errors)."""
    config = jax.config  # its flags are attributes made at run time: `Any` here
    x64: Any = config.jax_enable_x64  # pyright: ignore[reportAttributeAccessIssue]
    impl: Any = config.jax_default_prng_impl  # pyright: ignore[reportAttributeAccessIssue]
    if x64 and impl == "threefry2x32" and -(2**63) <= seed < 2**63:
        bits = int(seed) % 2**64  # two's complement, as JAX's seeding reads it
        words = np.array([bits >> 32, bits & 0xFFFFFFFF], dtype=np.uint32)
        return jax.random.wrap_key_data(jax.device_put(words), impl="threefry2x32")
    return jax.random.key(seed)


# --------------------------------------------------------- simulate --model


class ModelChoice(NamedTuple):
    description: str
    build: Callable[[], AbstractHysteresisModel]
    input_unit: str
    output_unit: str


def _paper() -> PiezoBoucWen:
    return PiezoBoucWen.paper_table4(3)


SIMULATE_MODELS: dict[str, ModelChoice] = {
    "piezo": ModelChoice(
        "PiezoBoucWen, the paper's Table 4 case 3 (eq. 7-8)", _paper, "V", "m"
    ),
    "corrected": ModelChoice(
        "CorrectedPiezoBoucWen, Table 4 case 3 with phi=0.05 s, eps=1e-6 (eq. 16-17)",
        lambda: CorrectedPiezoBoucWen.from_piezo(_paper(), phi=0.05, eps=1e-6),
        "V",
        "m",
    ),
    "bouc-wen": ModelChoice(
        "BoucWen (eq. 1-2), k=1, alpha=0.5, D=1, A=1, beta=0.6, gamma=0.4, n=1",
        lambda: BoucWen(k=1.0, alpha=0.5, D=1.0, A=1.0, beta=0.6, gamma=0.4, n=1.0),
        "",
        "",
    ),
    "stage": ModelChoice(
        "PiezoStage (eq. 3-4), Table 4 case 3 with a 50 Hz, 0.1-damped stage",
        lambda: PiezoStage.from_piezo(
            _paper(), natural_frequency=50.0, damping_ratio=0.1
        ),
        "V",
        "m",
    ),
}


# -------------------------------------------------------- simulate --signal


class SignalChoice(NamedTuple):
    description: str
    build: Callable[[float, int], AbstractSignal]  # (periods, seed) -> signal


def _multisine(periods: float, seed: int) -> AbstractSignal:
    return Multisine.random_phase(
        prng_key(seed),
        np.array([0.1, 0.3, 0.7, 1.3]),
        rms=0.6,
        duration=10.0 * periods,
        offset=2.0,
    )


SIGNALS: dict[str, SignalChoice] = {
    "u1": SignalChoice(
        "the paper's u1 = 2 - 2 cos(0.2 pi t), 0 to 4, 10 s per period",
        lambda periods, seed: paper_u1(periods=periods),
    ),
    "u2": SignalChoice(
        "the paper's u2 = 4 - 4 cos(0.2 pi t), 0 to 8, 10 s per period",
        lambda periods, seed: paper_u2(periods=periods),
    ),
    "multisine": SignalChoice(
        "random-phase multisine at 0.1, 0.3, 0.7, 1.3 Hz about 2, RMS 0.6", _multisine
    ),
    "chirp": SignalChoice(
        "raised linear chirp 0 to 4 sweeping 0.1 to 2 Hz",
        lambda periods, seed: Chirp(0.1, 2.0, 2.0, duration=10.0 * periods),
    ),
    "triangle": SignalChoice(
        "raised triangle wave 0 to 4 at 0.1 Hz",
        lambda periods, seed: Triangle(2.0, 0.1, duration=10.0 * periods),
    ),
}


# --------------------------------------------------------------- fit --model


class FitChoice(NamedTuple):
    description: str
    # The template identified by swarm + polish; None: the corrected model, fitted
    # in the paper's stages by `identify_corrected`.
    template: Callable[[], AbstractHysteresisModel] | None


def _piezo_template() -> PiezoBoucWen:
    return PiezoBoucWen(1.0, 1.0, 1.0, 1.0, 1.0, 1.5)


FIT_MODELS: dict[str, FitChoice] = {
    "piezo": FitChoice("PiezoBoucWen (eq. 7-8)", _piezo_template),
    "corrected": FitChoice(
        "CorrectedPiezoBoucWen (eq. 16-17), fitted in the paper's two stages: piezo, "
        "then (phi, eps) by the swarm, then all eight jointly",
        None,
    ),
    "bouc-wen": FitChoice(
        "BoucWen (eq. 1-2)",
        lambda: BoucWen(k=1.0, alpha=0.5, D=1.0, A=1.0, beta=0.5, gamma=0.5, n=1.5),
    ),
    "stage": FitChoice(
        "PiezoStage (eq. 3-4, with mass and damping; RK4 with 4 substeps)",
        lambda: PiezoStage.from_piezo(
            _piezo_template(), natural_frequency=50.0, damping_ratio=0.5
        ),
    ),
    "mr-damper": FitChoice(
        "BoucWenDamper (an MR damper at a fixed field: dashpot, spring and Bouc-Wen "
        "element in parallel; reads the displacement)",
        lambda: _damper_template(),
    ),
    "spencer": FitChoice(
        "SpencerDamper (Spencer et al. 1997's modified Bouc-Wen MR damper; reads the "
        "displacement and the command: --input u --input v; stiff, so RK4 substeps "
        "follow the record and long records are slow: fit a window with "
        "--start/--end)",
        lambda: SpencerDamper.spencer_1997(),
    ),
}


def _damper_template() -> BoucWenDamper:
    # Spencer et al.'s values at 0 V (N, cm, s): only the RK4 substeps read them.
    s = SpencerDamper.spencer_1997()
    return BoucWenDamper(
        c0=s.c0a,
        k0=s.k0,
        x0=0.0,
        alpha=s.alpha_a,
        f0=0.0,
        A=s.A,
        beta=s.beta,
        gamma=s.gamma,
        n=s.n,
    )


# ------------------------------------------------------------- fit --preset


# The paper's MPSO settings of Table 3, by case number.
PRESETS: dict[str, int] = {f"case{case}": case for case in (1, 2, 3, 4)}


# ---------------------------------------------------------- diagnose --model


# Each `--model` value and its family class in `jaxhyst._diagnose._families`,
# imported when a diagnosis asks for it (the other commands do not import it).
DIAGNOSE_FAMILIES: dict[str, str] = {
    "piezo": "PiezoFamily",
    "bouc-wen": "StructuralFamily",
    "mr-damper": "DamperFamily",
}


def family(name: str) -> "AbstractFamily":
    """The diagnosis family of `diagnose --model NAME`."""
    if name not in DIAGNOSE_FAMILIES:
        known = (
            f"{name!r} is a model 'jaxhyst fit' can identify, but diagnose has no "
            "effect catalogue for it"
            if name in FIT_MODELS
            else f"unknown model {name!r}"
        )
        raise ValueError(
            f"--model {name}: {known}; use --model piezo (piezo actuators and stages), "
            "--model bouc-wen (structural cyclic tests: displacement -> force) or "
            "--model mr-damper (MR dampers: displacement and command -> force)."
        )
    families = importlib.import_module(".._diagnose._families", __package__)
    return getattr(families, DIAGNOSE_FAMILIES[name])()


def described(table: Mapping[str, ModelChoice | SignalChoice | FitChoice]) -> str:
    """ "name: description; ..." of a table, for `--help`."""
    return "; ".join(f"{name}: {choice.description}" for name, choice in table.items())
