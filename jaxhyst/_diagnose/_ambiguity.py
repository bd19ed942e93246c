"""Statements of what the recording cannot tell apart."""

import numpy as np

from ._results import RESOLVED_SIGMA, Ambiguity, Rival, Validation
from ._score import max_canonical_correlation, moving_columns


def standing_in(
    rejected: list[tuple[str, Validation]],
    signatures: dict[str, np.ndarray],
    adopted: dict[str, np.ndarray],
    *,
    overlap: float = 0.9,
    min_gain: float = 0.05,
) -> list[Ambiguity]:
    """Ambiguities for rejected candidates (effect, validation) that beat the
    held-out noise and the information criterion, and failed only the minimum-gain
    floor, while their signature (`signatures[effect]`: output sensitivities,
    columns) overlaps an adopted effect's (`adopted[effect]`): the adopted effect may
    be standing in for them (e.g. a slow creep mode and a thermal drift on a record
    whose input mean is steady)."""
    messages = []
    for effect, v in rejected:
        gain = v.heldout_rmse_before**2 - v.heldout_rmse_after**2
        if v.accepted or gain <= v.heldout_resolution_mse or v.bic_change >= 0:
            continue
        raw = moving_columns(signatures[effect])
        for name, cols in adopted.items():
            if raw.shape[1] == 0 or cols.shape[1] == 0:
                continue
            correlation = max_canonical_correlation(raw, cols)
            if correlation > overlap:
                percent = 100 * gain / v.heldout_rmse_before**2
                statement = (
                    f"{effect} may also be present: adding it lowered the held-out "
                    f"error by {percent:.1f} % (more than its noise, and the "
                    f"information criterion agrees), short of the {min_gain:.0%} "
                    f"adoption needs; its signature overlaps that of {name} (canonical "
                    f"correlation {correlation:.2f}), which may be standing in for "
                    "part of it. Vary the excitation (levels, rates, amplitudes) to "
                    "separate them."
                )
                messages.append(Ambiguity(statement, (effect,)))
                break
    return messages


def unresolved(
    rejected: list[tuple[str, Validation]], *, min_gain: float = 0.05
) -> list[Ambiguity]:
    """Statements for rejected candidates whose held-out gain was worth having (at
    least `min_gain` of the held-out MSE) but within what this record's held-out
    data can resolve: the data cannot tell, which is not the same as no effect."""
    messages = []
    for effect, v in rejected:
        before = v.heldout_rmse_before**2
        gain = before - v.heldout_rmse_after**2
        if v.accepted or gain < min_gain * before or gain > v.heldout_resolution_mse:
            continue
        statement = (
            f"cannot tell whether {effect} is present: adding it lowered the held-out "
            f"error by {gain / before:.0%}, but this record's held-out data resolve "
            f"only MSE changes above {v.heldout_resolution_mse:.3g} (the residual is "
            f"smooth and strongly correlated: about {v.effective_samples_heldout:.0f} "
            "effective held-out samples; sampling the same cycles more densely "
            "adds none). Record more cycles to decide."
        )
        messages.append(Ambiguity(statement, (effect,)))
    return messages


def confined(
    rejected: list[tuple[str, Validation]],
    *,
    min_gain: float = 0.05,
    already: frozenset[str] = frozenset(),
) -> list[Ambiguity]:
    """Statements for rejected candidates that lowered the error on the fitted
    samples by at least `min_gain` of its MSE, with the information criterion in
    favour, but not on the held-out samples: their evidence lies where the held-out
    data do not reach (a one-off event such as a switch-on transient), so the
    record cannot confirm them (nor refute them: a held-out loss beyond its
    resolution rules a candidate out). Effects in `already` are skipped."""
    messages = []
    for effect, v in rejected:
        if v.accepted or effect in already or v.bic_change >= 0:
            continue
        before = v.fit_rmse_before**2
        gain = before - v.fit_rmse_after**2
        held = v.heldout_rmse_before**2 - v.heldout_rmse_after**2
        if gain < min_gain * before or held > v.heldout_margin_mse:
            continue
        if held < -v.heldout_resolution_mse:  # the held-out data speak against it
            continue
        statement = (
            f"cannot tell whether {effect} is present: adding it lowered the error on "
            f"the fitted samples by {gain / before:.0%} (the information criterion "
            f"agrees) but the held-out error by only "
            f"{held / v.heldout_rmse_before**2:.1%}: what it explains does not carry "
            "over to the held-out data, so it is either confined to a one-off part of "
            "the fitted samples (a switch-on transient cannot be checked on data it "
            "was not fitted to) or fitted noise. Repeat the event, or see the advice "
            "for a test that would show it."
        )
        messages.append(Ambiguity(statement, (effect,)))
    return messages


def cannot_tell_rivals(
    kept: str, rivals: list[Rival], kept_rmse: float, *, kept_because: str
) -> Ambiguity:
    """The record cannot tell `kept` from `rivals` (each refitted in its place,
    within the held-out comparison's resolution); `kept_because` says why the fit
    keeps `kept`."""
    figures = "; ".join(
        f"{r.effect} {r.heldout_rmse:.3g} ({_margin_words(r.margin_sigma)})"
        for r in rivals
    )
    names = ", ".join(r.effect for r in rivals)
    return Ambiguity(
        f"cannot tell {kept} from {names} on this recording: refitted in its place, "
        f"none lost by more than the {RESOLVED_SIGMA:.0f} standard errors this "
        f"comparison needs (held-out RMSE {kept} {kept_rmse:.3g}; {figures}). {kept} "
        f"is kept for the fit ({kept_because}), but the "
        "record does not show that it is the explanation; see the advice for a test "
        "that would.",
        (kept, *(r.effect for r in rivals)),
    )


def _margin_words(margin: float) -> str:
    if margin >= 0:
        return f"lost by {margin:.1f} standard errors"
    return f"better by {-margin:.1f} standard errors"
