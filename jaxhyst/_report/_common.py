"""What every part of the reports shares: display units, number formats, the one
RMSE change a diagnosis report quotes, and the sentences the Markdown/HTML report
and the console summary both say."""

import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import equinox as eqx
import numpy as np

from .._diagnose._results import RESOLVED_SIGMA, Advice, Diagnosis, Finding
from .._recording import Recording


def display_unit(unit: str) -> tuple[float, str]:
    """(scale, unit) to show a quantity stored in `unit`: metres as micrometres."""
    if unit == "m":
        return 1e6, "µm"
    if unit == "um":
        return 1.0, "µm"
    return 1.0, unit


def bracket(unit: str) -> str:
    """ " [unit]", or nothing without a unit."""
    return f" [{unit}]" if unit else ""


def labels(recording: Recording) -> tuple[float, str, str, str]:
    """(scale, unit, input label, output label) of `recording`'s figures."""
    scale, unit = display_unit(recording.output_unit)
    xlabel = f"input {recording.input_name}{bracket(recording.input_unit)}"
    ylabel = f"output {recording.output_name}{bracket(unit)}"
    return scale, unit, xlabel, ylabel


def number(value: float | None, digits: int = 4) -> str:
    """`value` to `digits` significant digits; "n/a" for None or non-finite."""
    if value is None or not math.isfinite(value):
        return "n/a"
    return f"{value:.{digits}g}"


def log10_p(value: float | None) -> str:
    """log10 of a p-value; one that underflows double precision shows as < -300."""
    if value is not None and value == -math.inf:
        return "< -300"
    return number(value, 3)


def change(first: float, last: float) -> str:
    """The change from `first` to `last` in percent, as every table and summary
    here shows it."""
    if not first or not (math.isfinite(first) and math.isfinite(last)):
        return "n/a"
    return f"{100 * (last / first - 1):+.1f} %"


class RmseChange(eqx.Module):
    """The one improvement a diagnosis report quotes: the base model's RMSE on all
    samples (the base model is fitted on the samples not held out) and the final
    model's, and the change between them in percent."""

    base: float
    final: float

    @property
    def percent(self) -> float:
        """100 * (final / base - 1); NaN when the base RMSE is zero."""
        return 100 * (self.final / self.base - 1) if self.base else math.nan

    @property
    def percent_text(self) -> str:
        """`percent` as shown, e.g. "-77.7 %"."""
        return change(self.base, self.final)


def rmse_change(diagnosis: Diagnosis) -> RmseChange:
    """The base -> final RMSE on all samples of `diagnosis`, quoted by every
    report (summary, table, console)."""
    return RmseChange(diagnosis.baseline["rmse"], diagnosis.final["rmse"])


def final_label(diagnosis: Diagnosis) -> str:
    """The final model's name, e.g. "piezo+asymmetry"."""
    return "+".join((diagnosis.base_name, *diagnosis.effects))


def base_label(diagnosis: Diagnosis) -> str:
    """The base model as the summary names it."""
    return {
        "piezo": "quasi-static piezo model (eq. 7-8)",
        "mr-damper": "MR damper model of fixed field (BoucWenDamper)",
    }.get(diagnosis.base_name, f"{diagnosis.base_name} model (eq. 1-2)")


def fitted_share(diagnosis: Diagnosis) -> str:
    """The base model's fitting samples, e.g. "70 % of the samples"."""
    return f"{100 * (1 - float(np.mean(diagnosis.heldout))):.0f} % of the samples"


def relative_link(target: str | os.PathLike, report: str | os.PathLike) -> str:
    """`target` relative to the folder of `report`, with forward slashes."""
    link = os.path.relpath(Path(target).resolve(), Path(report).resolve().parent)
    return Path(link).as_posix()


# ---------------------------------------------------------------------- sentences


def parameters_text(parameters: Mapping[str, float]) -> str:
    return ", ".join(f"{k} = {number(v, 6)}" for k, v in parameters.items())


def validation_lines(v: Mapping[str, Any], scale: float, unit: str) -> list[str]:
    """A finding's validation, one line per check."""
    s = f" {unit}" if unit else ""
    verdict = "accepted" if v.get("accepted") else "rejected"
    replaced = (
        [f"replaced {v['replaced']}, adopted first, once later effects were in"]
        if v.get("replaced")
        else []
    )
    return replaced + [
        f"held-out RMSE {number(scale * v['heldout_rmse_before'])} -> "
        f"{number(scale * v['heldout_rmse_after'])}{s} (needed a drop in MSE of "
        f"more than {number(scale**2 * v['heldout_margin_mse'], 3)}"
        f"{f' {unit}²' if unit else ''}, about "
        f"{number(v['effective_samples_heldout'], 3)} effective held-out samples)",
        f"fitted-part RMSE {number(scale * v['fit_rmse_before'])} -> "
        f"{number(scale * v['fit_rmse_after'])}{s}; BIC change "
        f"{number(v['bic_change'], 4)} (negative: the parameters pay for themselves)",
        f"score test {number(v['score_statistic'], 4)} on {v['score_dof']} dof, "
        f"log10 p {log10_p(v['log10_p'])}; {verdict}",
    ]


def final_parameters_text(finding: Finding) -> str:
    """A finding's parameters at adoption -> final, with standard errors."""
    parts = []
    for name, final in finding.final_parameters.items():
        error = finding.standard_errors.get(name, float("nan"))
        unit = finding.units.get(name, "")
        unit = "" if unit in ("", "1") else f" {unit}"
        spread = f" ± {error:.2g}" if np.isfinite(error) else " (not determined)"
        parts.append(
            f"{name} = {finding.parameters[name]:.4g} -> {final:.4g}{spread}{unit}"
        )
    return "; ".join(parts)


def named_form(finding: Finding) -> str:
    """A finding's effect with its form, as in "pinching (form: series_slip)"."""
    return (
        f"{finding.effect} (form: {finding.form})" if finding.form else finding.effect
    )


def rivals_text(finding: Finding, scale: float, s: str) -> str:
    """A finding's rivals and whether the record tells it from them."""
    if not finding.rivals:
        return (
            "none (no other effect passed held-out validation or was significant "
            "without being refitted)."
        )
    parts = [
        f"{r.effect} (held-out RMSE {number(scale * r.heldout_rmse)}{s}, "
        + (
            f"lost by {r.margin_sigma:.1f} standard errors)"
            if r.margin_sigma >= 0
            else f"better by {-r.margin_sigma:.1f} standard errors)"
        )
        for r in finding.rivals
    ]
    verdict = (
        "every rival lost beyond the resolution"
        if finding.decided
        else "the record cannot tell it from those within the resolution"
    )
    return "; ".join(parts) + f"; {verdict}."


def advice_text(advice: Advice) -> str:
    """The test that would separate rival effects, and whether it would."""
    names = " from ".join(advice.separates)
    what = (
        f"to tell {names}"
        if len(advice.separates) > 1
        else f"to tell whether {names} is present"
    )
    verdict = (
        "would separate them"
        if advice.difference_sigma >= RESOLVED_SIGMA
        else "would still not separate them clearly; none of the tests tried does"
    )
    return (
        f"{what}: {advice.input}. The fitted rival models differ there by "
        f"{advice.difference_sigma:.1f} noise sigmas (RMS), against "
        f"{advice.difference_sigma_here:.1f} on this record: it {verdict}."
    )
