"""Reports of fits and diagnoses: paper-style figures, a Markdown report, JSON and
console summaries.

Shared by the `jaxhyst fit` / `diagnose` / `demo` commands and usable from notebooks:

- `write_fit_figures(fit, recording, directory)`: the measured-vs-model loop, time
  histories and absolute-error trend of one fit (the paper's Figures 8-10 layout).
- `write_diagnosis_figures(diagnosis, recording, directory)`: the same before/after
  the diagnosis (measured vs base vs final model), plus the residual analysis:
  against time, against the input split by branch, against the rate |du/dt|, and
  its spectrum.
- `write_diagnosis_report(diagnosis, recording, path, figures)`: a Markdown report
  with a before/after table in the paper's Table 5/6 format (MAD, MRD, MAE, NRMSD),
  the findings with their evidence, location and validation, the ambiguities, and
  relative links to the figures, and what is left (`Diagnosis.remainder`).

A diagnosis report quotes one base RMSE and one improvement: `rmse_change(diagnosis)`
(the base model's RMSE on all samples -> the final model's, in percent).

Figures need matplotlib (`pip install 'jaxhyst[plot]'`); like everything that writes
files here, they refuse to replace existing files unless `overwrite=True`.
"""

import json
import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import equinox as eqx
import numpy as np

from ._diagnose._results import RESOLVED_SIGMA, Advice, Diagnosis, Finding
from ._identification._identify import Fit
from ._plots import (
    plot_error_trend,
    plot_loop,
    plot_residual_scatter,
    plot_residual_time,
    plot_spectrum,
    plot_time_history,
)
from ._recording import Recording
from ._status import status_message, status_name


FIT_FIGURES: dict[str, str] = {
    "fit_loop": "fit_loop.png",
    "fit_time_history": "fit_time_history.png",
    "fit_error_trend": "fit_error_trend.png",
}
"""Figure name -> file name written by `write_fit_figures`."""

DIAGNOSIS_FIGURES: dict[str, str] = {
    "loop": "loop_before_after.png",
    "time_history": "time_history_before_after.png",
    "error_trend": "error_trend_before_after.png",
    "residual_time": "residual_time.png",
    "residual_input": "residual_input.png",
    "residual_rate": "residual_rate.png",
    "residual_spectrum": "residual_spectrum.png",
}
"""Figure name -> file name written by `write_diagnosis_figures`."""

CAPTIONS: dict[str, str] = {
    "fit_loop": "Hysteresis loop, measured vs the fitted model (lower panel: both "
    "minus the straight line through the measurement, which shows the loop opening).",
    "fit_time_history": "Time histories: the input (top), measured and model output "
    "(bottom).",
    "fit_error_trend": "Absolute error |y - yhat| of the fitted model over time.",
    "loop": "Hysteresis loops before/after the diagnosis: measured vs the base "
    "model vs the final model with the adopted physics.",
    "time_history": "Time histories before/after: measured vs base vs final model.",
    "error_trend": "Absolute error trends before (base model) and after (final model).",
    "residual_time": "Residual y - yhat against time under the input, before and "
    "after (faint: raw; bold: moving average).",
    "residual_input": "Residual against the input, split into the ascending and "
    "descending branches (faint: samples; bold: binned means). Branches that "
    "disagree point to asymmetry or an input bias.",
    "residual_rate": "Residual against the input rate |du/dt| (binned means per "
    "branch). A trend with the rate points to rate dependence or stage dynamics.",
    "residual_spectrum": "Amplitude spectral density of the residual before and "
    "after. White noise is a flat floor; missing physics shows as excess at the "
    "excitation's harmonics or at a resonance.",
}
"""Captions by figure name, used by `write_diagnosis_report`."""


# ------------------------------------------------------------------------ helpers


def display_unit(unit: str) -> tuple[float, str]:
    """(scale, unit) to show a quantity stored in `unit`: metres as micrometres."""
    if unit == "m":
        return 1e6, "µm"
    if unit == "um":
        return 1.0, "µm"
    return 1.0, unit


def _bracket(unit: str) -> str:
    return f" [{unit}]" if unit else ""


def jsonable(value: Any) -> Any:
    """`value` with every NumPy/JAX scalar or array turned into Python numbers and
    lists, tuples into lists, and non-finite floats into None, so that
    `json.dumps(..., allow_nan=False)` accepts it (strict JSON has no NaN)."""
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        number = float(value)
        return number if math.isfinite(number) else None
    if isinstance(value, str) or value is None:
        return value
    if hasattr(value, "shape") and hasattr(value, "dtype"):  # NumPy or JAX array
        array = np.asarray(value)
        return jsonable(array.item() if array.ndim == 0 else array.tolist())
    raise TypeError(f"jsonable: cannot convert {type(value).__name__} to JSON.")


def write_json(data: Mapping[str, Any], path: str | os.PathLike, *, overwrite: bool):
    """Write `jsonable(data)` as indented strict JSON; refuses to replace an
    existing file unless `overwrite`. Returns the path."""
    path = Path(path)
    text = json.dumps(jsonable(data), indent=2, allow_nan=False)
    _refuse_existing(path, overwrite, "write_json")
    path.write_text(text + "\n", encoding="utf-8")
    return path


def _refuse_existing(path: Path, overwrite: bool, owner: str) -> None:
    if path.exists() and not overwrite:
        raise FileExistsError(
            f"{owner}: {str(path)!r} already exists; pass overwrite=True (--force on "
            "the command line) to replace it."
        )


def _directory(directory: str | os.PathLike, names, overwrite: bool, owner: str):
    folder = Path(directory)
    if folder.exists() and not folder.is_dir():
        raise FileExistsError(f"{owner}: {str(folder)!r} is a file, not a folder.")
    paths = {name: folder / file for name, file in names.items()}
    if not overwrite:
        existing = [repr(str(p)) for p in paths.values() if p.exists()]
        if existing:
            raise FileExistsError(
                f"{owner}: {', '.join(existing)} already exist(s); pass "
                "overwrite=True (--force on the command line) to replace them."
            )
    folder.mkdir(parents=True, exist_ok=True)
    return paths


def _labels(recording: Recording) -> tuple[float, str, str, str]:
    scale, unit = display_unit(recording.output_unit)
    xlabel = f"input {recording.input_name}{_bracket(recording.input_unit)}"
    ylabel = f"output {recording.output_name}{_bracket(unit)}"
    return scale, unit, xlabel, ylabel


def _branches(recording: Recording) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """|du/dt| and the ascending / descending masks (holds excluded), as `locate`."""
    udot = np.gradient(np.asarray(recording.u), recording.dt)
    speed = np.abs(udot)
    moving = speed > 1e-3 * (np.max(speed) + 1e-300)
    return speed, moving & (udot > 0), moving & (udot < 0)


def _final_label(diagnosis: Diagnosis) -> str:
    return "+".join((diagnosis.base_name, *diagnosis.effects))


def _base_label(diagnosis: Diagnosis) -> str:
    return {"piezo": "quasi-static piezo model (eq. 7-8)"}.get(
        diagnosis.base_name, f"{diagnosis.base_name} model (eq. 1-2)"
    )


def _change(first: float, last: float) -> str:
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
        return _change(self.base, self.final)


def rmse_change(diagnosis: Diagnosis) -> RmseChange:
    """The base -> final RMSE on all samples of `diagnosis`, quoted by every
    report (summary, table, console)."""
    return RmseChange(diagnosis.baseline["rmse"], diagnosis.final["rmse"])


def _fitted_share(diagnosis: Diagnosis) -> str:
    """The base model's fitting samples, e.g. "70 % of the samples"."""
    return f"{100 * (1 - float(np.mean(diagnosis.heldout))):.0f} % of the samples"


# ------------------------------------------------------------------------ figures


def write_fit_figures(
    fit: Fit,
    recording: Recording,
    directory: str | os.PathLike,
    *,
    overwrite: bool = False,
    label: str | None = None,
) -> dict[str, Path]:
    """The paper-style figures of one fit in `directory` (created if missing):
    measured vs model loop, time histories, absolute-error trend. `label` names the
    model in legends (default: its class). Returns {name: path} (see
    `FIT_FIGURES`)."""
    paths = _directory(directory, FIT_FIGURES, overwrite, "write_fit_figures")
    scale, unit, xlabel, ylabel = _labels(recording)
    name = label or type(fit.model).__name__
    predicted = np.asarray(fit.predicted)
    y = np.asarray(recording.y)
    curves = {"measured": y, name: predicted}
    plot_loop(
        paths["fit_loop"],
        recording.u,
        curves,
        xlabel=xlabel,
        ylabel=ylabel,
        title=f"{recording.name}: measured vs {name}",
        scale=scale,
        detrend=True,
        overwrite=overwrite,
    )
    plot_time_history(
        paths["fit_time_history"],
        recording.t,
        recording.u,
        curves,
        ulabel=xlabel,
        ylabel=ylabel,
        title=f"{recording.name}: time histories",
        scale=scale,
        overwrite=overwrite,
    )
    plot_error_trend(
        paths["fit_error_trend"],
        recording.t,
        {name: np.abs(y - predicted)},
        ylabel=f"absolute error |y - yhat|{_bracket(unit)}",
        title=f"{recording.name}: absolute error of {name} (RMSE on all samples "
        f"{_number(scale * fit.metrics['rmse'])}{' ' + unit if unit else ''})",
        scale=scale,
        overwrite=overwrite,
    )
    return paths


def write_diagnosis_figures(
    diagnosis: Diagnosis,
    recording: Recording,
    directory: str | os.PathLike,
    *,
    overwrite: bool = False,
) -> dict[str, Path]:
    """The diagnosis figures in `directory` (created if missing): loops, time
    histories and absolute-error trends before/after (measured vs base vs final
    model), and the residual before/after against time, against the input split by
    branch, against the rate |du/dt|, and its spectrum. `recording` must be the one
    diagnosed. Returns {name: path} (see `DIAGNOSIS_FIGURES`)."""
    owner = "write_diagnosis_figures"
    y = np.asarray(recording.y)
    if y.shape != np.shape(diagnosis.base_predicted):
        raise ValueError(
            f"{owner}: the recording has {y.size} samples but the diagnosis "
            f"{np.size(diagnosis.base_predicted)}; pass the recording it diagnosed."
        )
    paths = _directory(directory, DIAGNOSIS_FIGURES, overwrite, owner)
    scale, unit, xlabel, ylabel = _labels(recording)
    base = np.asarray(diagnosis.base_predicted)
    final = np.asarray(diagnosis.final_predicted)
    final_name = _final_label(diagnosis)
    changed = bool(diagnosis.findings)
    before_name = f"base {diagnosis.base_name} model"
    after_name = f"final {final_name}" if changed else "final (= base)"
    curves = {"measured": y, before_name: base}
    if changed:
        curves[after_name] = final
    plot_loop(
        paths["loop"],
        recording.u,
        curves,
        xlabel=xlabel,
        ylabel=ylabel,
        title=f"{recording.name}: loops before/after the diagnosis",
        scale=scale,
        detrend=True,
        overwrite=overwrite,
    )
    plot_time_history(
        paths["time_history"],
        recording.t,
        recording.u,
        curves,
        ulabel=xlabel,
        ylabel=ylabel,
        title=f"{recording.name}: time histories before/after",
        scale=scale,
        overwrite=overwrite,
    )
    change = rmse_change(diagnosis)
    rmse = f"RMSE {_number(scale * change.base)}"
    errors = {f"{before_name} ({rmse})": np.abs(y - base)}
    if changed:
        rmse = f"RMSE {_number(scale * change.final)}, {change.percent_text}"
        errors[f"{after_name} ({rmse})"] = np.abs(y - final)
    plot_error_trend(
        paths["error_trend"],
        recording.t,
        errors,
        ylabel=f"absolute error |y - yhat|{_bracket(unit)}",
        title=f"{recording.name}: absolute error before/after (RMSE on all samples)",
        scale=scale,
        overwrite=overwrite,
    )
    if changed:
        residuals = {
            f"before: {before_name}": y - base,
            f"after: {after_name}": y - final,
        }
    else:
        residuals = {f"{before_name} (no physics added: final = base)": y - base}
    rlabel = f"residual y - yhat{_bracket(unit)}"
    plot_residual_time(
        paths["residual_time"],
        recording.t,
        recording.u,
        residuals,
        ulabel=xlabel,
        ylabel=rlabel,
        tlabel=f"time t{_bracket(recording.time_unit)}",
        tunit=recording.time_unit,
        title=f"{recording.name}: residual over time",
        scale=scale,
        window=0.25,
        overwrite=overwrite,
    )
    speed, ascending, descending = _branches(recording)
    groups = {"ascending": ascending, "descending": descending}
    plot_residual_scatter(
        paths["residual_input"],
        recording.u,
        residuals,
        groups=groups,
        xlabel=xlabel,
        ylabel=rlabel,
        title=f"{recording.name}: residual against the input, by branch",
        scale=scale,
        overwrite=overwrite,
    )
    rate_unit = (
        f"{recording.input_unit}/{recording.time_unit}" if recording.input_unit else ""
    )
    plot_residual_scatter(
        paths["residual_rate"],
        speed,
        residuals,
        groups=groups,
        xlabel=f"input rate |d{recording.input_name}/dt|{_bracket(rate_unit)}",
        ylabel=rlabel,
        title=f"{recording.name}: residual against the input rate",
        scale=scale,
        logx=True,
        overwrite=overwrite,
    )
    plot_spectrum(
        paths["residual_spectrum"],
        recording.sample_rate,
        residuals,
        ylabel=f"residual ASD{_bracket(f'{unit}/√Hz' if unit else '')}",
        title=f"{recording.name}: residual spectrum",
        scale=scale,
        overwrite=overwrite,
    )
    return paths


# ------------------------------------------------------------------------- tables


def _number(value: float | None, digits: int = 4) -> str:
    if value is None or not math.isfinite(value):
        return "n/a"
    return f"{value:.{digits}g}"


def metrics_table(
    rows: Mapping[str, Mapping[str, float]],
    unit: str,
    scale: float = 1.0,
    *,
    reference: str | None = None,
    change_label: str = "change, last vs first row",
) -> str:
    """A Markdown table in the paper's Table 5/6 format: one row per model
    ({label: error_metrics}), columns MAD [unit], MRD [%], MAE [unit], NRMSD, RMSE
    [unit]; with two or more rows, a last row (`change_label`) gives the change of
    the last model relative to the row labelled `reference` (default: the first),
    in percent."""
    u = _bracket(unit)
    lines = [
        f"| model | MAD{u} | MRD [%] | MAE{u} | NRMSD | RMSE{u} |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for label, m in rows.items():
        lines.append(
            f"| {label} | {_number(scale * m['mad'])} | {_number(m['mrd'])} | "
            f"{_number(scale * m['mae'])} | {_number(m['nrmsd'])} | "
            f"{_number(scale * m['rmse'])} |"
        )
    if reference is not None and reference not in rows:
        raise ValueError(
            f"metrics_table: reference {reference!r} is not a row label; pass one of "
            f"{', '.join(map(repr, rows))}, or None for the first row."
        )
    if len(rows) >= 2:
        first = rows[reference] if reference is not None else list(rows.values())[0]
        last = list(rows.values())[-1]
        keys = ("mad", "mrd", "mae", "nrmsd", "rmse")
        changes = " | ".join(_change(first[k], last[k]) for k in keys)
        lines.append(f"| {change_label} | {changes} |")
    return "\n".join(lines)


def _log10_p(value: float | None) -> str:
    """log10 of a p-value; one that underflows double precision shows as < -300."""
    if value is not None and value == -math.inf:
        return "< -300"
    return _number(value, 3)


def _parameters_text(parameters: Mapping[str, float]) -> str:
    return ", ".join(f"{k} = {_number(v, 6)}" for k, v in parameters.items())


def _validation_lines(v: Mapping[str, Any], scale: float, unit: str) -> list[str]:
    s = f" {unit}" if unit else ""
    verdict = "accepted" if v.get("accepted") else "rejected"
    replaced = (
        [f"replaced {v['replaced']}, adopted first, once later effects were in"]
        if v.get("replaced")
        else []
    )
    return replaced + [
        f"held-out RMSE {_number(scale * v['heldout_rmse_before'])} -> "
        f"{_number(scale * v['heldout_rmse_after'])}{s} (needed a drop in MSE of "
        f"more than {_number(scale**2 * v['heldout_margin_mse'], 3)}"
        f"{f' {unit}²' if unit else ''}, about "
        f"{_number(v['effective_samples_heldout'], 3)} effective held-out samples)",
        f"fitted-part RMSE {_number(scale * v['fit_rmse_before'])} -> "
        f"{_number(scale * v['fit_rmse_after'])}{s}; BIC change "
        f"{_number(v['bic_change'], 4)} (negative: the parameters pay for themselves)",
        f"score test {_number(v['score_statistic'], 4)} on {v['score_dof']} dof, "
        f"log10 p {_log10_p(v['log10_p'])}; {verdict}",
    ]


def _remainder_lines(diagnosis: Diagnosis, scale: float, unit: str) -> list[str]:
    """The "What is left" section: `Diagnosis.remainder`'s sentence and numbers."""
    left = diagnosis.remainder
    s = f" {unit}" if unit else ""
    effective = (
        f"{_number(left.effective_samples)} effective independent samples of "
        f"{left.samples} ({_number(100 * left.effective_fraction, 3)} %)"
    )
    lines = [
        left.text(scale, unit),
        "",
        f"- worst span: {left.span_text()}, max |residual| "
        f"{_number(scale * left.span_max)}{s}",
        f"- verdict: {left.verdict}; {effective}",
    ]
    if left.heldout_rms is not None:
        lines.append(
            f"- RMS on the held-out samples {_number(scale * left.heldout_rms)}{s}"
        )
    return lines


def _final_parameters_text(finding: Finding) -> str:
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


def _rivals_text(finding: Finding, scale: float, s: str) -> str:
    if not finding.rivals:
        return (
            "none (no other effect passed held-out validation or was significant "
            "without being refitted)."
        )
    parts = [
        f"{r.effect} (held-out RMSE {_number(scale * r.heldout_rmse)}{s}, "
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


def _advice_text(advice: Advice) -> str:
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


def _relative_link(target: Path, report: Path) -> str:
    link = os.path.relpath(Path(target).resolve(), Path(report).resolve().parent)
    return Path(link).as_posix()


# ------------------------------------------------------------------------- report


def diagnosis_markdown(
    diagnosis: Diagnosis,
    recording: Recording,
    path: str | os.PathLike,
    figures: Mapping[str, str | os.PathLike],
    *,
    fit: Fit | None = None,
    files: Mapping[str, str | os.PathLike] | None = None,
    first_figure: int = 1,
    title: str | None = None,
    intro: str = "",
) -> str:
    """The text of `write_diagnosis_report` (links are relative to `path`)."""
    scale, unit, _, _ = _labels(recording)
    s = f" {unit}" if unit else ""
    path = Path(path)
    final_name = _final_label(diagnosis)
    out: list[str] = [f"# {title or f'jaxhyst diagnosis of {recording.name!r}'}", ""]
    if intro:
        out += [intro, ""]
    out += [
        f"Recording `{recording.name}`: {recording.num_samples} samples at "
        f"{recording.sample_rate:g} Hz over {recording.duration:g} s "
        f"(input{_bracket(recording.input_unit)}, output{_bracket(unit)}). The "
        f"diagnosis took {diagnosis.seconds:.1f} s.",
        "",
        "## Summary",
        "",
    ]
    change = rmse_change(diagnosis)
    if diagnosis.findings:
        names = ", ".join(f"**{f.effect}**" for f in diagnosis.findings)
        out.append(
            f"The {_base_label(diagnosis)} leaves physics out of this "
            f"recording. Adopted, in order: {names}. With them the RMSE on all "
            f"samples falls from {_number(scale * change.base)} (base model) to "
            f"{_number(scale * change.final)}{s} (final model), "
            f"{change.percent_text}."
        )
    else:
        out.append(
            "No missing physics found: no catalogue effect both passes the score "
            "test and lowers the error on the held-out data by more than its noise. "
            f"The base {diagnosis.base_name} model's RMSE on all samples is "
            f"{_number(scale * change.base)}{s}."
        )
    held = float(np.mean(diagnosis.heldout))
    out += [
        "",
        f"The base model was fitted on {_fitted_share(diagnosis)}; the other "
        f"{100 * held:.0f} %, {diagnosis.holdout_description}, is held out to judge "
        "every candidate. The residual left at the end has RMS "
        f"{_number(scale * diagnosis.noise_sigma)}{s}, lag-1 autocorrelation "
        f"{_number(diagnosis.noise.get('lag1_autocorrelation'), 3)}.",
        "",
        "## Error measures (Table 5/6 format)",
        "",
    ]
    rows: dict[str, Mapping[str, float]] = {}
    if fit is not None:
        plain = f"plain {type(fit.model).__name__} fit on all samples (not the base)"
        rows[plain] = fit.metrics
    base_row = f"base {diagnosis.base_name} model (diagnosis)"
    rows[base_row] = diagnosis.baseline
    if diagnosis.findings:
        rows[f"final {final_name}"] = diagnosis.final
    notes = (
        "MAD: maximum absolute deviation; MRD: MAD / max |y| in percent; MAE: mean "
        "absolute error; NRMSD: RMSE / max |y| (eq. 15); all over every sample. The "
        f"base model is the diagnosis's, fitted on {_fitted_share(diagnosis)}"
    )
    if diagnosis.findings:
        notes += "; the change row compares the final model with it"
    if fit is not None:
        notes += (
            "; the plain fit is a separate fit on every sample (the figures of the "
            "plain model), not the diagnosis's base"
        )
    out += [
        metrics_table(
            rows,
            unit,
            scale,
            reference=base_row,
            change_label="change, final vs base",
        ),
        "",
        notes + ".",
        "",
        "## Findings",
        "",
    ]
    if not diagnosis.findings:
        out += ["None.", ""]
    for number, finding in enumerate(diagnosis.findings, start=1):
        out += [
            f"### {number}. {finding.effect}",
            "",
            f"- **Evidence:** {finding.evidence}",
            f"- **Where:** {finding.where}.",
            f"- **Meaning:** {finding.meaning}.",
            f"- **Reading (final model):** {finding.reading}.",
            f"- **Parameters (at adoption -> final, ± standard error):** "
            f"{_final_parameters_text(finding)}.",
        ]
        if finding.moved is not None:
            out.append(f"- **Moved:** {finding.moved}")
        out += [
            f"- **RMSE when adopted:** {_number(scale * finding.before['rmse'])} -> "
            f"{_number(scale * finding.after['rmse'])}{s} (all samples).",
            f"- **Rivals:** {_rivals_text(finding, scale, s)}",
            "- **Validation:**",
        ]
        out += [
            f"  - {line}"
            for line in _validation_lines(finding.validation.to_dict(), scale, unit)
        ]
        out.append("")
    out += ["## RMSE chain", ""]
    out += [
        "Every model the diagnosis moved to, in order (internal refits are rows of "
        "their own):",
        "",
        f"| step | RMSE, all samples{_bracket(unit)} | RMSE, held out{_bracket(unit)} |",
        "|---|---:|---:|",
    ]
    out += [
        f"| {step.label} | {_number(scale * step.rmse)} | "
        f"{_number(scale * step.heldout_rmse)} |"
        for step in diagnosis.steps
    ]
    out.append("")
    out += ["## What the catalogue does not explain", ""]
    if diagnosis.unexplained:
        for item in diagnosis.unexplained:
            out += [
                f"- {item.description} (RMS {_number(scale * item.rms)}{s}); it "
                f"resembles {item.resembles}; {item.where}.",
            ]
    else:
        out.append(
            "Nothing: no structure a model-free probe could learn on the fitted "
            "samples predicts the held-out residual beyond its noise."
        )
    out.append("")
    out += ["## Ambiguities", ""]
    if diagnosis.ambiguities:
        out += [f"- {a.statement}" for a in diagnosis.ambiguities]
    else:
        out.append(
            "None: every finding beat each of its rivals (the other effects that "
            "passed held-out validation, or were significant but not refitted) by "
            "more than this record resolves."
        )
    if diagnosis.advice:
        out += ["", "## Tests that would decide", ""]
        out += [f"- {_advice_text(a)}" for a in diagnosis.advice]
    out += ["", "## Final model", ""]
    final_parameters = diagnosis.to_dict()["final"]["parameters"]
    out += [f"`{final_name}`: {_parameters_text(final_parameters)}.", ""]
    out += ["## What is left", "", *_remainder_lines(diagnosis, scale, unit), ""]
    if diagnosis.candidates:
        out += [
            "## Candidates scored",
            "",
            "| round | effect | statistic | dof | log10 p | significant | "
            f"held-out RMSE after{_bracket(unit)} | adopted |",
            "|---:|---|---:|---:|---:|---|---:|---|",
        ]
        adopted = list(diagnosis.effects)
        for index, round_ in enumerate(diagnosis.candidates, start=1):
            for c in round_:
                v = c.get("validation")
                after = _number(scale * v["heldout_rmse_after"]) if v else "-"
                if index <= len(adopted) and adopted[index - 1] == c["effect"]:
                    taken = "yes"
                elif v and v.get("accepted"):
                    taken = "passed; another did better"
                elif v:
                    taken = "rejected"
                else:
                    taken = "not refitted" if c["significant"] else "-"
                out.append(
                    f"| {index} | {c['effect']} | {_number(c['statistic'], 4)} | "
                    f"{c['dof']} | {_log10_p(c['log10_p'])} | "
                    f"{'yes' if c['significant'] else 'no'} | {after} | {taken} |"
                )
        out.append("")
    if figures:
        out += ["## Figures", ""]
        for number, (name, target) in enumerate(figures.items(), start=first_figure):
            caption = CAPTIONS.get(name, name)
            link = _relative_link(Path(target), path)
            out += [
                f"**Figure {number}.** {caption}",
                "",
                f"![Figure {number}: {name}]({link})",
                "",
            ]
    if files:
        out += ["## Files", ""]
        out += [
            f"- [{label}]({_relative_link(Path(target), path)})"
            for label, target in files.items()
        ]
        out.append("")
    return "\n".join(out)


def write_diagnosis_report(
    diagnosis: Diagnosis,
    recording: Recording,
    path: str | os.PathLike,
    figures: Mapping[str, str | os.PathLike],
    *,
    overwrite: bool = False,
    fit: Fit | None = None,
    files: Mapping[str, str | os.PathLike] | None = None,
    first_figure: int = 1,
    title: str | None = None,
    intro: str = "",
) -> Path:
    """Write a Markdown report of `diagnosis` to `path`: summary, a before/after
    table in the paper's Table 5/6 format (MAD/MRD/MAE/NRMSD, plus RMSE), each
    finding with its evidence, where the mismatch lives and how it was validated,
    the ambiguities, the final parameters, every scored candidate, and the
    `figures` ({name: path}, e.g. from `write_diagnosis_figures`, numbered from
    `first_figure`, captioned by name from `CAPTIONS`) linked relative to the
    report.

    Optional: `fit`, a plain fit on the whole record, adds its row to the table;
    `files` ({label: path}) adds links (e.g. the JSON outputs). Refuses to replace
    an existing file unless `overwrite`. Returns the path."""
    path = Path(path)
    _refuse_existing(path, overwrite, "write_diagnosis_report")
    text = diagnosis_markdown(
        diagnosis,
        recording,
        path,
        figures,
        fit=fit,
        files=files,
        first_figure=first_figure,
        title=title,
        intro=intro,
    )
    path.write_text(text, encoding="utf-8")
    return path


# ----------------------------------------------------------------------- summaries


def fit_summary(fit: Fit, recording: Recording) -> str:
    """A console summary of a fit: parameters, error measures, timing."""
    scale, unit, _, _ = _labels(recording)
    s = f" {unit}" if unit else ""
    names = list(fit.model.parameter_names)
    errors = {}
    if fit.identifiability is not None:
        errors = fit.identifiability.standard_errors
    width = max(len(n) for n in names)
    lines = [f"model: {type(fit.model).__name__}"]
    status = status_name(fit.result)
    if status != "successful":
        lines.append(f"status: {status}: {status_message(fit.result)}")
    lines.append("parameters:")
    singular = False
    for name in names:
        value = float(getattr(fit.model, name))
        if name in errors and math.isfinite(errors[name]):
            note = f"  ± {errors[name]:.3g}"
        elif name in errors:
            note, singular = "  ± n/a", True
        else:
            note = "  (fixed)"
        lines.append(f"  {name:<{width}}  {value:>14.6g}{note}")
    if singular:
        lines.append(
            "  (± n/a: the parameter lies on a direction this record does not "
            "determine, so it has no standard error; see 'identifiability' in the "
            "JSON)"
        )
    elif errors:
        lines.append("  (± one standard error, from the Jacobian at the fit)")
    m = fit.metrics
    for each in fit.per_recording:
        r = each.metrics
        lines.append(
            f"  on {each.recording}: RMSE {scale * r['rmse']:.6g}{s}, "
            f"NRMSD {r['nrmsd']:.6g}"
        )
    if fit.per_recording:
        lines.insert(len(lines) - len(fit.per_recording), "metrics per recording:")
    lines += [
        "metrics on all samples" + (" together:" if fit.per_recording else ":"),
        f"  RMSE   {scale * m['rmse']:.6g}{s}",
        f"  MAD    {scale * m['mad']:.6g}{s}",
        f"  MRD    {m['mrd']:.6g} %",
        f"  MAE    {scale * m['mae']:.6g}{s}",
        f"  NRMSD  {m['nrmsd']:.6g}",
        "timing: "
        + ", ".join(f"{k.removesuffix('_s')} {v:.1f} s" for k, v in fit.timing.items()),
    ]
    return "\n".join(lines)


def diagnosis_summary(diagnosis: Diagnosis, recording: Recording) -> str:
    """A console summary of a diagnosis: the findings with their evidence, RMSE
    before/after, the ambiguities."""
    scale, unit, _, _ = _labels(recording)
    s = f" {unit}" if unit else ""
    change = rmse_change(diagnosis)
    lines = [
        f"recording: {recording.name}, {recording.num_samples} samples at "
        f"{recording.sample_rate:g} Hz; diagnosis took {diagnosis.seconds:.1f} s",
        f"base model: {diagnosis.base_name}, fitted on {_fitted_share(diagnosis)}; "
        f"RMSE on all samples {_number(scale * change.base)}{s}",
    ]
    if not diagnosis.findings:
        lines.append(
            "findings: none; the residual is consistent with noise (no effect "
            "passed the score test and the held-out check)"
        )
    else:
        lines.append(f"findings ({len(diagnosis.findings)}):")
        for number, finding in enumerate(diagnosis.findings, start=1):
            lines += [
                f"  {number}. {finding.effect}: {finding.reading}",
                f"     evidence: {finding.evidence}",
                f"     where: {finding.where}",
                f"     rivals: {_rivals_text(finding, scale, s)}",
            ]
            if finding.moved is not None:
                lines.append(f"     {finding.moved}")
        lines.append(
            f"final model: {_final_label(diagnosis)}, RMSE on all samples "
            f"{_number(scale * change.final)}{s} ({change.percent_text} vs the base "
            "model)"
        )
    for item in diagnosis.unexplained:
        lines.append(f"unexplained: {item.description}; it resembles {item.resembles}")
    if diagnosis.ambiguities:
        lines.append("ambiguities:")
        lines += [f"  - {a.statement}" for a in diagnosis.ambiguities]
    else:
        lines.append("ambiguities: none")
    lines += [f"advice: {_advice_text(a)}" for a in diagnosis.advice]
    lines.append(f"what is left: {diagnosis.remainder.text(scale, unit)}")
    return "\n".join(lines)
