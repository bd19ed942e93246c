"""The compensation report: the predicted tracking error of a feedforward drive,
and its figures, as Markdown and self-contained HTML."""

import os
from pathlib import Path

import numpy as np

from .._compensate import Compensation
from .._files import Refusal, output_folder
from .._models.base import AbstractHysteresisModel
from .._plots import (
    plot_error_trend,
    plot_time_history,
    require_matplotlib,
    save_figure,
)
from .._recording import Recording
from ._blocks import Block, Heading, Image, Paragraph, Table
from ._common import display_unit
from ._output import html_path, write_report


COMPENSATION_FIGURES: dict[str, str] = {
    "drive": "compensation_drive.png",
    "error": "compensation_error.png",
}
"""Figure name -> file name written next to the report by
`write_compensation_report`."""


def _blocks(
    compensation: Compensation,
    reference: Recording,
    figures: dict[str, Path],
    *,
    model: AbstractHysteresisModel,
    model_file: str | os.PathLike | None,
    reference_file: str | os.PathLike | None,
    scale: float,
    unit: str,
) -> list[Block]:
    tracking = compensation.tracking()
    s = f" {unit}" if unit else ""
    lo, hi = compensation.limits
    source = f" from `{model_file}`" if model_file is not None else ""
    named = reference_file if reference_file is not None else reference.name
    method = (
        "at every sample, the drive in the limits nearest the present one whose "
        "one-sample simulation meets the reference (bracket search and bisection)"
        if compensation.method == "per-sample inversion"
        else "the whole drive optimised through the simulator, from the inverse "
        "of the model's quasi-static part"
    )
    return [
        Heading("Compensation", 1),
        Paragraph(
            f"Model `{type(model).__name__}`{source}; reference `{named}` "
            f"({reference.num_samples} samples at {reference.sample_rate:g} Hz); "
            f"drive limits {lo:g} to {hi:g}."
        ),
        Paragraph(
            f"Method: {compensation.method} ({method}). The errors are the model's "
            "prediction: the stage tracks as well as the model describes it."
        ),
        Table(
            ["predicted tracking error", "value", "% of stroke"],
            [
                [
                    "RMS",
                    f"{scale * tracking['rms_error']:.4g}{s}",
                    f"{tracking['rms_error_percent_of_stroke']:.3g}",
                ],
                [
                    "maximum",
                    f"{scale * tracking['max_error']:.4g}{s}",
                    f"{tracking['max_error_percent_of_stroke']:.3g}",
                ],
            ],
            "lll",
        ),
        Paragraph(
            f"Samples out of reach inside the limits: {tracking['samples_at_limit']}."
            + _slew_sentence(compensation, tracking)
        ),
        Paragraph(
            "Where the predicted error lies in frequency (its RMS in octave bands, "
            "the bands holding at least 1 % of its mean square; the squares add up "
            "to the whole RMS):"
        ),
        _spectrum_table(compensation, scale=scale, unit=s),
        Image(figures["drive"], figures["drive"].name, "drive and output"),
        Image(figures["error"], figures["error"].name, "tracking error"),
    ]


def _slew_sentence(compensation: Compensation, tracking: dict) -> str:
    rate = f"{tracking['max_slew_rate']:.4g}"
    if compensation.slew_limit is None:
        return f" The drive's largest rate: {rate} per second."
    return (
        f" Samples the drive reaches faster than the slew limit "
        f"{compensation.slew_limit:g} per second: {tracking['samples_over_slew']} "
        f"(largest rate {rate} per second)."
    )


def _spectrum_table(compensation: Compensation, *, scale: float, unit: str) -> Table:
    spectrum = compensation.error_spectrum()
    rows = []
    for lo, hi, rms, percent, share in zip(
        spectrum.low,
        spectrum.high,
        spectrum.rms,
        spectrum.percent_of_stroke(),
        spectrum.shares(),
    ):
        if share >= 0.01:
            band = "mean (0 Hz)" if hi == 0 else f"{lo:.3g} to {hi:.3g} Hz"
            rows.append(
                [band, f"{scale * rms:.4g}{unit}", f"{percent:.3g}", f"{share:.0%}"]
            )
    return Table(["band", "RMS", "% of stroke", "share of mean square"], rows, "llll")


def write_compensation_report(
    compensation: Compensation,
    reference: Recording,
    path: str | os.PathLike,
    *,
    model: AbstractHysteresisModel,
    model_file: str | os.PathLike | None = None,
    reference_file: str | os.PathLike | None = None,
    output_unit: str | None = None,
    overwrite: bool = False,
    html: bool = True,
) -> list[Path]:
    """Write a Markdown report of `compensation` (from `jh.compensate(model, ...)`
    following `reference`) to `path`: the method, the predicted RMS and maximum
    tracking error (also in % of the reference's stroke), the samples out of reach,
    and two figures next to it (`COMPENSATION_FIGURES`: drive over reference and
    predicted output; the error over time). With `html` (the default), the same
    report as one self-contained HTML file next to it (`path` with `.html`).

    `model_file`, `reference_file`: the files to name (default: none, the
    reference's name). `output_unit`: the unit of the model's output (default: the
    reference's), shown in display units (metres as µm). Refuses to replace any
    existing output unless `overwrite`, before writing anything; creates the folder.
    Returns the paths written: the report(s), then the figures."""
    owner = "write_compensation_report"
    path = Path(path)
    reports = [path, html_path(path, owner)] if html else [path]
    require_matplotlib()
    refusal = Refusal(owner)
    # Every output, checked before anything is drawn or written.
    output_folder(
        path.parent,
        [p.name for p in reports] + list(COMPENSATION_FIGURES.values()),
        overwrite=overwrite,
        refusal=refusal,
        create=True,
    )
    figures = {name: path.parent / file for name, file in COMPENSATION_FIGURES.items()}
    scale, unit = display_unit(output_unit or reference.output_unit)
    t = np.asarray(compensation.times)
    history = plot_time_history(
        t,
        np.asarray(compensation.drive),
        {"reference": reference.y, "predicted": np.asarray(compensation.predicted)},
        ulabel="drive u",
        ylabel=f"output [{unit}]" if unit else "output",
        scale=scale,
        title="Compensation: drive (top), reference and predicted output",
    )
    save_figure(history, figures["drive"], overwrite=overwrite)
    trend = plot_error_trend(
        t,
        {"|predicted - reference|": np.abs(np.asarray(compensation.error))},
        ylabel=f"absolute error [{unit}]" if unit else "absolute error",
        scale=scale,
        title="Predicted tracking error",
    )
    save_figure(trend, figures["error"], overwrite=overwrite)
    blocks = _blocks(
        compensation,
        reference,
        figures,
        model=model,
        model_file=model_file,
        reference_file=reference_file,
        scale=scale,
        unit=unit,
    )
    written = write_report(blocks, path, overwrite=overwrite, owner=owner, html=html)
    return [*written, *figures.values()]
