"""Table 2 of the paper: which Bouc-Wen shape parameters give a BIBO-stable operator."""

from typing import Any

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Bool, Float

from ._models.base import AbstractHysteresisModel


class StabilityReport(eqx.Module):
    """Whether a parameter set lies in one of Table 2's BIBO-stable classes, and why
    (not). `bool(report)` is `report.stable`."""

    stable: bool
    reason: str

    def __bool__(self) -> bool:
        return self.stable


def is_bibo_stable(
    A: Float[ArrayLike, "..."],
    beta: Float[ArrayLike, "..."],
    gamma: Float[ArrayLike, "..."],
    n: Float[ArrayLike, "..."] = 1.0,
    D: Float[ArrayLike, "..."] = 1.0,
) -> Bool[Array, "..."]:
    """Table 2 as a traceable predicate (usable inside jit/vmap, e.g. as a swarm
    constraint). Requires D > 0 and n >= 1; A == 0 is not a hysteretic operator."""
    A, beta, gamma = jnp.asarray(A), jnp.asarray(beta), jnp.asarray(gamma)
    positive_a = ((beta + gamma > 0) & (beta - gamma >= 0)) | (
        (beta - gamma < 0) & (beta >= 0)
    )
    negative_a = ((beta - gamma > 0) & (beta + gamma >= 0)) | (
        (beta + gamma < 0) & (beta >= 0)
    )
    by_sign = jnp.where(A > 0, positive_a, jnp.where(A < 0, negative_a, False))
    return by_sign & (jnp.asarray(D) > 0) & (jnp.asarray(n) >= 1)


def bibo_stability(model: AbstractHysteresisModel) -> StabilityReport:
    """Check a model's Bouc-Wen shape (`model.bouc_wen_shape()`: A, beta, gamma, n
    and D) against Table 2 and explain the verdict in the model's own parameter
    names. Needs concrete (not traced) values; `is_bibo_stable(*shape)` is the
    traceable check."""
    if not isinstance(model, AbstractHysteresisModel):
        raise TypeError(
            f"bibo_stability: model must be a jaxhyst model, got {type(model).__name__}."
        )
    try:
        shape = model.bouc_wen_shape()
    except TypeError as error:
        raise TypeError(f"bibo_stability: {error}") from None
    a_name, b_name, g_name, n_name = shape.names[:4]
    A, beta, gamma, n, D = (float(v) for v in shape)
    values = f"{a_name}={A:g}, {b_name}={beta:g}, {g_name}={gamma:g}"
    if not D > 0:
        return StabilityReport(False, f"D={D:g} must be positive (Table 2 needs D > 0)")
    if not n >= 1:
        return StabilityReport(
            False, f"{n_name}={n:g} must be >= 1 (Table 2 needs n >= 1)"
        )
    if A == 0:
        return StabilityReport(False, f"{a_name}=0: the operator has no hysteresis")
    s, d = beta + gamma, beta - gamma
    if A > 0:
        if s > 0 and d >= 0:
            return StabilityReport(
                True, f"{values}: A > 0, beta+gamma > 0, beta-gamma >= 0"
            )
        if d < 0 and beta >= 0:
            return StabilityReport(True, f"{values}: A > 0, beta-gamma < 0, beta >= 0")
        return StabilityReport(
            False,
            f"{values}: with A > 0 Table 2 needs (beta+gamma > 0 and beta-gamma >= 0) "
            f"or (beta-gamma < 0 and beta >= 0); here beta+gamma={s:g}, "
            f"beta-gamma={d:g}",
        )
    if d > 0 and s >= 0:
        return StabilityReport(
            True, f"{values}: A < 0, beta-gamma > 0, beta+gamma >= 0"
        )
    if s < 0 and beta >= 0:
        return StabilityReport(True, f"{values}: A < 0, beta+gamma < 0, beta >= 0")
    return StabilityReport(
        False,
        f"{values}: with A < 0 Table 2 needs (beta-gamma > 0 and beta+gamma >= 0) "
        f"or (beta+gamma < 0 and beta >= 0); here beta+gamma={s:g}, beta-gamma={d:g}",
    )


def stability_json(model: AbstractHysteresisModel) -> dict[str, Any] | None:
    """`bibo_stability(model)` as JSON, `{"stable": bool, "reason": str}`, or None
    for a model that defines no Bouc-Wen shape (`bouc_wen_shape`)."""
    if type(model).bouc_wen_shape is AbstractHysteresisModel.bouc_wen_shape:
        return None
    report = bibo_stability(model)
    return {"stable": report.stable, "reason": report.reason}


def stability_warning(model: AbstractHysteresisModel) -> str | None:
    """A sentence for reports when `model` lies outside Table 2's BIBO-stable
    classes (None inside them, or without a Bouc-Wen shape)."""
    record = stability_json(model)
    if record is None or record["stable"]:
        return None
    return (
        "outside Table 2's BIBO-stable classes: a bounded input may drive its "
        f"hysteretic state without bound beyond the recorded range ({record['reason']})"
    )
