"""Console summaries of a fit and of a diagnosis (what the commands print)."""

import math

from .._diagnose._results import Diagnosis
from .._identification._identify import Fit
from .._recording import Recording
from .._stability import stability_warning
from .._status import status_message, status_name
from ._common import (
    advice_text,
    final_label,
    fitted_share,
    labels,
    named_form,
    number,
    rivals_text,
    rmse_change,
)


def fit_summary(fit: Fit, recording: Recording) -> str:
    """A console summary of a fit: parameters, error measures, timing."""
    scale, unit, _, _ = labels(recording)
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
    warning = stability_warning(fit.model)
    if warning is not None:
        lines.append(f"stability: {warning}")
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
    scale, unit, _, _ = labels(recording)
    s = f" {unit}" if unit else ""
    change = rmse_change(diagnosis)
    lines = [
        f"recording: {recording.name}, {recording.num_samples} samples at "
        f"{recording.sample_rate:g} Hz; diagnosis took {diagnosis.seconds:.1f} s",
        f"base model: {diagnosis.base_name}, fitted on {fitted_share(diagnosis)}; "
        f"RMSE on all samples {number(scale * change.base)}{s}",
    ]
    if not diagnosis.findings:
        lines.append(
            "findings: none; the residual is consistent with noise (no effect "
            "passed the score test and the held-out check)"
        )
    else:
        lines.append(f"findings ({len(diagnosis.findings)}):")
        for index, finding in enumerate(diagnosis.findings, start=1):
            lines += [
                f"  {index}. {named_form(finding)}: {finding.reading}",
                f"     evidence: {finding.evidence}",
                f"     where: {finding.where}",
                f"     rivals: {rivals_text(finding, scale, s)}",
            ]
            if finding.moved is not None:
                lines.append(f"     {finding.moved}")
        lines.append(
            f"final model: {final_label(diagnosis)}, RMSE on all samples "
            f"{number(scale * change.final)}{s} ({change.percent_text} vs the base "
            "model)"
        )
    warning = stability_warning(diagnosis.final_model)
    if warning is not None:
        lines.append(f"final model stability: {warning}")
    for item in diagnosis.unexplained:
        lines.append(f"unexplained: {item.description}; it resembles {item.resembles}")
    for item in diagnosis.cannot_show:
        lines.append(f"not asked: {item.effect}: {item.reason}")
    if diagnosis.ambiguities:
        lines.append("ambiguities:")
        lines += [f"  - {a.statement}" for a in diagnosis.ambiguities]
    else:
        lines.append("ambiguities: none")
    lines += [f"advice: {advice_text(a)}" for a in diagnosis.advice]
    lines.append(f"what is left: {diagnosis.remainder.text(scale, unit)}")
    return "\n".join(lines)
