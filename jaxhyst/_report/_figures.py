"""The report's figures: each drawn by the `plot_*` functions (`jaxhyst._plots`) and
saved with `save_figure`, into one folder checked before anything is written."""

import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from jaxtyping import ArrayLike

from .._diagnose._results import Diagnosis
from .._files import Refusal, output_folder
from .._identification._identify import Fit
from .._plots import (
    new_figure,
    plot_error_trend,
    plot_loop,
    plot_loop_opening,
    plot_residual_scatter,
    plot_residual_time,
    plot_spectrum,
    plot_time_history,
    require_matplotlib,
    save_figure,
)
from .._recording import Recording
from ._common import bracket, final_label, labels, number, rmse_change


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
"""Captions by figure name, used by the diagnosis report."""


def loop_figure(
    u: ArrayLike,
    curves: Mapping[str, ArrayLike],
    *,
    xlabel: str,
    ylabel: str,
    title: str,
    scale: float = 1.0,
):
    """The loop above its opening (`plot_loop` over `plot_loop_opening`, sharing
    the input axis): the paper-style loop figure. Returns the figure."""
    figure, (top, bottom) = new_figure(2, height=7.5, sharex=True)
    plot_loop(u, curves, xlabel="", ylabel=ylabel, title=title, scale=scale, ax=top)
    plot_loop_opening(
        u,
        curves,
        xlabel=xlabel,
        ylabel=f"{ylabel}\nminus straight line",
        scale=scale,
        ax=bottom,
    )
    return figure


def _folder(
    directory: str | os.PathLike,
    names: Mapping[str, str],
    overwrite: bool,
    owner: str,
) -> dict[str, Path]:
    """{name: directory/file}, after checking none exists unless `overwrite`;
    creates the folder."""
    require_matplotlib()
    paths = output_folder(
        directory,
        names.values(),
        overwrite=overwrite,
        refusal=Refusal(owner),
        create=True,
    )
    return dict(zip(names, paths, strict=True))


def _branches(recording: Recording) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """|du/dt| and the ascending / descending masks (holds excluded), as `locate`."""
    udot = np.gradient(np.asarray(recording.u), recording.dt)
    speed = np.abs(udot)
    moving = speed > 1e-3 * (np.max(speed) + 1e-300)
    return speed, moving & (udot > 0), moving & (udot < 0)


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
    model in legends (default: its class). Refuses to replace an existing figure
    unless `overwrite` (before drawing any). Returns {name: path} (see
    `FIT_FIGURES`)."""
    paths = _folder(directory, FIT_FIGURES, overwrite, "write_fit_figures")
    scale, unit, _, _ = labels(recording)
    name = label or type(fit.model).__name__
    predicted = np.asarray(fit.predicted)
    y = np.asarray(recording.y)
    _loop_history_error(
        recording,
        {"measured": y, name: predicted},
        {name: np.abs(y - predicted)},
        (paths["fit_loop"], paths["fit_time_history"], paths["fit_error_trend"]),
        (
            f"measured vs {name}",
            "time histories",
            f"absolute error of {name} (RMSE on all samples "
            f"{number(scale * fit.metrics['rmse'])}{' ' + unit if unit else ''})",
        ),
        overwrite,
    )
    return paths


def _loop_history_error(
    recording: Recording,
    curves: dict[str, np.ndarray],
    errors: dict[str, np.ndarray],
    paths: tuple[Path, Path, Path],
    titles: tuple[str, str, str],
    overwrite: bool,
) -> None:
    """The three figures every report opens with: the loops, the time histories
    (of `curves`) and the absolute-error trends (`errors`), saved to `paths` with
    `titles` after the recording's name."""
    scale, unit, xlabel, ylabel = labels(recording)
    loop_path, history_path, trend_path = paths
    loop_title, history_title, trend_title = titles
    loop = loop_figure(
        recording.u,
        curves,
        xlabel=xlabel,
        ylabel=ylabel,
        title=f"{recording.name}: {loop_title}",
        scale=scale,
    )
    save_figure(loop, loop_path, overwrite=overwrite)
    history = plot_time_history(
        recording.t,
        recording.u,
        curves,
        ulabel=xlabel,
        ylabel=ylabel,
        title=f"{recording.name}: {history_title}",
        scale=scale,
    )
    save_figure(history, history_path, overwrite=overwrite)
    trend = plot_error_trend(
        recording.t,
        errors,
        ylabel=f"absolute error |y - yhat|{bracket(unit)}",
        title=f"{recording.name}: {trend_title}",
        scale=scale,
    )
    save_figure(trend, trend_path, overwrite=overwrite)


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
    diagnosed. Refuses to replace an existing figure unless `overwrite` (before
    drawing any). Returns {name: path} (see `DIAGNOSIS_FIGURES`)."""
    owner = "write_diagnosis_figures"
    y = np.asarray(recording.y)
    if y.shape != np.shape(diagnosis.base_predicted):
        raise ValueError(
            f"{owner}: the recording has {y.size} samples but the diagnosis "
            f"{np.size(diagnosis.base_predicted)}; pass the recording it diagnosed."
        )
    paths = _folder(directory, DIAGNOSIS_FIGURES, overwrite, owner)
    scale, unit, xlabel, ylabel = labels(recording)
    base = np.asarray(diagnosis.base_predicted)
    final = np.asarray(diagnosis.final_predicted)
    changed = bool(diagnosis.findings)
    before_name = f"base {diagnosis.base_name} model"
    after_name = f"final {final_label(diagnosis)}" if changed else "final (= base)"
    curves = {"measured": y, before_name: base}
    if changed:
        curves[after_name] = final
    change = rmse_change(diagnosis)
    rmse = f"RMSE {number(scale * change.base)}"
    errors = {f"{before_name} ({rmse})": np.abs(y - base)}
    if changed:
        rmse = f"RMSE {number(scale * change.final)}, {change.percent_text}"
        errors[f"{after_name} ({rmse})"] = np.abs(y - final)
    _loop_history_error(
        recording,
        curves,
        errors,
        (paths["loop"], paths["time_history"], paths["error_trend"]),
        (
            "loops before/after the diagnosis",
            "time histories before/after",
            "absolute error before/after (RMSE on all samples)",
        ),
        overwrite,
    )
    if changed:
        residuals = {
            f"before: {before_name}": y - base,
            f"after: {after_name}": y - final,
        }
    else:
        residuals = {f"{before_name} (no physics added: final = base)": y - base}
    rlabel = f"residual y - yhat{bracket(unit)}"
    over_time = plot_residual_time(
        recording.t,
        recording.u,
        residuals,
        ulabel=xlabel,
        ylabel=rlabel,
        tlabel=f"time t{bracket(recording.time_unit)}",
        tunit=recording.time_unit,
        title=f"{recording.name}: residual over time",
        scale=scale,
        window=0.25,
    )
    save_figure(over_time, paths["residual_time"], overwrite=overwrite)
    speed, ascending, descending = _branches(recording)
    groups = {"ascending": ascending, "descending": descending}
    against_input = plot_residual_scatter(
        recording.u,
        residuals,
        groups=groups,
        xlabel=xlabel,
        ylabel=rlabel,
        title=f"{recording.name}: residual against the input, by branch",
        scale=scale,
    )
    save_figure(against_input, paths["residual_input"], overwrite=overwrite)
    rate_unit = (
        f"{recording.input_unit}/{recording.time_unit}" if recording.input_unit else ""
    )
    against_rate = plot_residual_scatter(
        speed,
        residuals,
        groups=groups,
        xlabel=f"input rate |d{recording.input_name}/dt|{bracket(rate_unit)}",
        ylabel=rlabel,
        title=f"{recording.name}: residual against the input rate",
        scale=scale,
        logx=True,
    )
    save_figure(against_rate, paths["residual_rate"], overwrite=overwrite)
    spectrum = plot_spectrum(
        recording.sample_rate,
        residuals,
        ylabel=f"residual ASD{bracket(f'{unit}/√Hz' if unit else '')}",
        title=f"{recording.name}: residual spectrum",
        scale=scale,
    )
    save_figure(spectrum, paths["residual_spectrum"], overwrite=overwrite)
    return paths
