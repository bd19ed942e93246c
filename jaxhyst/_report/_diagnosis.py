"""The diagnosis report: its content built once as blocks (`diagnosis_blocks`),
rendered as Markdown (`diagnosis_markdown`) and as self-contained HTML
(`diagnosis_html`), and the writers."""

import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from .._diagnose._results import Diagnosis
from .._identification._identify import Fit
from .._recording import Recording
from ._blocks import Block, Bullets, Heading, Image, Item, Paragraph, Table
from ._common import (
    advice_text,
    base_label,
    bracket,
    change,
    display_unit,
    final_label,
    final_parameters_text,
    fitted_share,
    labels,
    log10_p,
    named_form,
    number,
    parameters_text,
    relative_link,
    rivals_text,
    rmse_change,
    validation_lines,
)
from ._figures import CAPTIONS
from ._html import to_html
from ._markdown import to_markdown
from ._output import write_html, write_report


def metrics_rows(
    rows: Mapping[str, Mapping[str, float]],
    unit: str,
    scale: float = 1.0,
    *,
    reference: str | None = None,
    change_label: str = "change, last vs first row",
) -> Table:
    """The table of `metrics_table`, as a report block."""
    u = bracket(unit)
    body = [
        [
            label,
            number(scale * m["mad"]),
            number(m["mrd"]),
            number(scale * m["mae"]),
            number(m["nrmsd"]),
            number(scale * m["rmse"]),
        ]
        for label, m in rows.items()
    ]
    if reference is not None and reference not in rows:
        raise ValueError(
            f"metrics_table: reference {reference!r} is not a row label; pass one of "
            f"{', '.join(map(repr, rows))}, or None for the first row."
        )
    if len(rows) >= 2:
        first = rows[reference] if reference is not None else list(rows.values())[0]
        last = list(rows.values())[-1]
        keys = ("mad", "mrd", "mae", "nrmsd", "rmse")
        body.append([change_label, *(change(first[k], last[k]) for k in keys)])
    header = ["model", f"MAD{u}", "MRD [%]", f"MAE{u}", "NRMSD", f"RMSE{u}"]
    return Table(header, body, "lrrrrr")


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
    table = metrics_rows(
        rows, unit, scale, reference=reference, change_label=change_label
    )
    return to_markdown([table]).rstrip("\n")


def _remainder(diagnosis: Diagnosis, scale: float, unit: str) -> list[Block]:
    """The "What is left" section: `Diagnosis.remainder`'s sentence and numbers."""
    left = diagnosis.remainder
    s = f" {unit}" if unit else ""
    effective = (
        f"{number(left.effective_samples)} effective independent samples of "
        f"{left.samples} ({number(100 * left.effective_fraction, 3)} %)"
    )
    items = [
        f"worst span: {left.span_text()}, max |residual| "
        f"{number(scale * left.span_max)}{s}",
        f"verdict: {left.verdict}; {effective}",
    ]
    if left.heldout_rms is not None:
        items.append(
            f"RMS on the held-out samples {number(scale * left.heldout_rms)}{s}"
        )
    return [Paragraph(left.text(scale, unit)), Bullets(items)]


def _loops(diagnosis: Diagnosis, recording: Recording) -> list[Block]:
    """The "The loops, without a model" section: `Diagnosis.loops`' verdicts, its
    numbers per amplitude level, and whether the named effects agree."""
    loops = diagnosis.loops
    if loops is None:
        return []
    f_scale, f_unit = display_unit(recording.output_unit)
    x_scale, x_unit = display_unit(recording.input_unit)
    stiffness_unit = f"{f_unit}/{x_unit}" if f_unit and x_unit else ""
    asked = {"degradation": "Do they degrade?", "pinching": "Do they pinch?"}
    out: list[Block] = [
        Heading("The loops, without a model"),
        Paragraph(
            "Read from the record alone, whatever the model (`jh.diagnosis."
            f"loop_indicators`: {loops.reversals} reversals, {len(loops.cycles)} "
            f"cycles, {len(loops.levels)} amplitude levels):"
        ),
        Bullets(
            [
                f"**{asked[name]} {v.answer}**: {v.reason}."
                for name, v in loops.verdicts.items()
            ]
        ),
    ]
    if loops.levels:
        rows = [
            [
                str(index),
                number(x_scale * level.amplitude),
                str(level.cycles),
                number(f_scale * level.peak_force),
                number(f_scale / x_scale * level.stiffness),
                number(level.second_strength_ratio, 3),
                number(level.zero_force_ratio, 2),
                number(level.energy_ratio, 2),
                number(level.unloading_ratio, 2),
            ]
            for index, level in enumerate(loops.levels, start=1)
        ]
        out += [
            Table(
                [
                    "level",
                    f"amplitude{bracket(x_unit)}",
                    "cycles",
                    f"peak force{bracket(f_unit)}",
                    f"secant stiffness{bracket(stiffness_unit)}",
                    "2nd / 1st cycle force",
                    "force at zero / peak",
                    "energy / rectangle",
                    "unloading / secant",
                ],
                rows,
                "rrrrrrrrr",
            ),
            Paragraph(
                "Per level (consecutive cycles reaching about the same "
                "displacements), its first cycle's half peak-to-peak displacement, "
                "force and secant stiffness; the second cycle's force at the first "
                "cycle's displacement over the first's (both directions); the "
                "loop's height at zero displacement over its peak-to-peak force "
                "and its energy over that of the rectangle through its peaks "
                "(both 1 for an elastic-perfectly-plastic loop), and its unloading "
                "stiffness from the peaks over its secant (about 1 for a nearly "
                "elastic loop), medians over the level's cycles."
            ),
        ]
    words = {True: "agree", False: "disagree", None: "the loops cannot tell"}
    agreement = diagnosis.loop_agreement
    if agreement:
        out += [
            Paragraph("Beside the findings:"),
            Bullets([f"**{words[a.agree]}**: {a.statement}." for a in agreement]),
        ]
    return out


def _candidates(diagnosis: Diagnosis, scale: float, unit: str) -> Table:
    header = [
        "round",
        "effect",
        "statistic",
        "dof",
        "log10 p",
        "significant",
        f"held-out RMSE after{bracket(unit)}",
        "adopted",
    ]
    rows = []
    adopted = list(diagnosis.effects)
    for index, round_ in enumerate(diagnosis.candidates, start=1):
        for c in round_:
            v = c.get("validation")
            after = number(scale * v["heldout_rmse_after"]) if v else "-"
            if index <= len(adopted) and adopted[index - 1] == c["effect"]:
                taken = "yes"
            elif v and v.get("accepted"):
                taken = "passed; another did better"
            elif v:
                taken = "rejected"
            else:
                taken = "not refitted" if c["significant"] else "-"
            rows.append(
                [
                    str(index),
                    c["effect"],
                    number(c["statistic"], 4),
                    str(c["dof"]),
                    log10_p(c["log10_p"]),
                    "yes" if c["significant"] else "no",
                    after,
                    taken,
                ]
            )
    return Table(header, rows, "rlrrrlrl")


def diagnosis_blocks(
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
) -> list[Block]:
    """The content of the diagnosis report, as blocks (links relative to `path`)."""
    scale, unit, _, _ = labels(recording)
    s = f" {unit}" if unit else ""
    path = Path(path)
    final_name = final_label(diagnosis)
    out: list[Block] = [Heading(title or f"jaxhyst diagnosis of {recording.name!r}", 1)]
    if intro:
        out.append(Paragraph(intro))
    out += [
        Paragraph(
            f"Recording `{recording.name}`: {recording.num_samples} samples at "
            f"{recording.sample_rate:g} Hz over {recording.duration:g} s "
            f"(input{bracket(recording.input_unit)}, output{bracket(unit)}). The "
            f"diagnosis took {diagnosis.seconds:.1f} s."
        ),
        Heading("Summary"),
    ]
    rmse = rmse_change(diagnosis)
    if diagnosis.findings:
        names = ", ".join(f"**{f.effect}**" for f in diagnosis.findings)
        summary = (
            f"The {base_label(diagnosis)} leaves physics out of this "
            f"recording. Adopted, in order: {names}. With them the RMSE on all "
            f"samples falls from {number(scale * rmse.base)} (base model) to "
            f"{number(scale * rmse.final)}{s} (final model), "
            f"{rmse.percent_text}."
        )
    else:
        summary = (
            "No missing physics found: no catalogue effect both passes the score "
            "test and lowers the error on the held-out data by more than its noise. "
            f"The base {diagnosis.base_name} model's RMSE on all samples is "
            f"{number(scale * rmse.base)}{s}."
        )
    held = float(np.mean(diagnosis.heldout))
    out += [
        Paragraph(summary),
        Paragraph(
            f"The base model was fitted on {fitted_share(diagnosis)}; the other "
            f"{100 * held:.0f} %, {diagnosis.holdout_description}, is held out to "
            "judge every candidate. The residual left at the end has RMS "
            f"{number(scale * diagnosis.noise_sigma)}{s}, lag-1 autocorrelation "
            f"{number(diagnosis.noise.get('lag1_autocorrelation'), 3)}."
        ),
        Heading("Error measures (Table 5/6 format)"),
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
        f"base model is the diagnosis's, fitted on {fitted_share(diagnosis)}"
    )
    if diagnosis.findings:
        notes += "; the change row compares the final model with it"
    if fit is not None:
        notes += (
            "; the plain fit is a separate fit on every sample (the figures of the "
            "plain model), not the diagnosis's base"
        )
    out += [
        metrics_rows(
            rows,
            unit,
            scale,
            reference=base_row,
            change_label="change, final vs base",
        ),
        Paragraph(notes + "."),
        Heading("Findings"),
    ]
    if not diagnosis.findings:
        out.append(Paragraph("None."))
    for index, finding in enumerate(diagnosis.findings, start=1):
        items: list[str | Item] = [
            f"**Evidence:** {finding.evidence}",
            f"**Where:** {finding.where}.",
            f"**Meaning:** {finding.meaning}.",
            f"**Reading (final model):** {finding.reading}.",
            "**Parameters (at adoption -> final, ± standard error):** "
            f"{final_parameters_text(finding)}.",
        ]
        if finding.moved is not None:
            items.append(f"**Moved:** {finding.moved}")
        items += [
            f"**RMSE when adopted:** {number(scale * finding.before['rmse'])} -> "
            f"{number(scale * finding.after['rmse'])}{s} (all samples).",
            f"**Rivals:** {rivals_text(finding, scale, s)}",
            Item(
                "**Validation:**",
                validation_lines(finding.validation.to_dict(), scale, unit),
            ),
        ]
        out += [Heading(f"{index}. {named_form(finding)}", 3), Bullets(items)]
    out += _loops(diagnosis, recording)
    out += [
        Heading("RMSE chain"),
        Paragraph(
            "Every model the diagnosis moved to, in order (internal refits are rows "
            "of their own):"
        ),
        Table(
            [
                "step",
                f"RMSE, all samples{bracket(unit)}",
                f"RMSE, held out{bracket(unit)}",
            ],
            [
                [
                    step.label,
                    number(scale * step.rmse),
                    number(scale * step.heldout_rmse),
                ]
                for step in diagnosis.steps
            ],
            "lrr",
        ),
        Heading("What the catalogue does not explain"),
    ]
    if diagnosis.unexplained:
        out.append(
            Bullets(
                [
                    f"{item.description} (RMS {number(scale * item.rms)}{s}); it "
                    f"resembles {item.resembles}; {item.where}."
                    for item in diagnosis.unexplained
                ]
            )
        )
    else:
        out.append(
            Paragraph(
                "Nothing: no structure a model-free probe could learn on the fitted "
                "samples predicts the held-out residual beyond its noise."
            )
        )
    if diagnosis.cannot_show:
        out += [
            Heading("What this record cannot show"),
            Bullets([f"{n.effect}: {n.reason}" for n in diagnosis.cannot_show]),
        ]
    out.append(Heading("Ambiguities"))
    if diagnosis.ambiguities:
        out.append(Bullets([a.statement for a in diagnosis.ambiguities]))
    else:
        out.append(
            Paragraph(
                "None: every finding beat each of its rivals (the other effects that "
                "passed held-out validation, or were significant but not refitted) "
                "by more than this record resolves."
            )
        )
    if diagnosis.advice:
        out += [
            Heading("Tests that would decide"),
            Bullets([advice_text(a) for a in diagnosis.advice]),
        ]
    final_parameters = diagnosis.to_dict()["final"]["parameters"]
    out += [
        Heading("Final model"),
        Paragraph(f"`{final_name}`: {parameters_text(final_parameters)}."),
        Heading("What is left"),
        *_remainder(diagnosis, scale, unit),
    ]
    if diagnosis.candidates:
        out += [
            Heading("Candidates scored"),
            _candidates(diagnosis, scale, unit),
        ]
    if figures:
        out.append(Heading("Figures"))
        for index, (name, target) in enumerate(figures.items(), start=first_figure):
            out.append(
                Image(
                    Path(target),
                    relative_link(target, path),
                    f"Figure {index}: {name}",
                    f"**Figure {index}.** {CAPTIONS.get(name, name)}",
                )
            )
    if files:
        out += [
            Heading("Files"),
            Bullets(
                [
                    f"[{label}]({relative_link(target, path)})"
                    for label, target in files.items()
                ]
            ),
        ]
    return out


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
    """The Markdown text of `write_diagnosis_report` (links are relative to
    `path`)."""
    return to_markdown(
        diagnosis_blocks(
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
    )


def diagnosis_html(
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
    """The self-contained HTML text of `write_diagnosis_html`: the content of
    `diagnosis_markdown`, with the `figures` (which must exist) embedded; the
    `files` are linked relative to `path`."""
    blocks = diagnosis_blocks(
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
    return to_html(blocks, owner="diagnosis_html")


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
    html: bool = True,
) -> Path:
    """Write a Markdown report of `diagnosis` to `path` and, with `html` (the
    default), the same report as one self-contained HTML file next to it (`path`
    with `.html`, e.g. report.md -> report.html, the figures embedded: the file to
    mail).

    The report: summary, a before/after table in the paper's Table 5/6 format
    (MAD/MRD/MAE/NRMSD, plus RMSE), each finding with its evidence, where the
    mismatch lives and how it was validated, the ambiguities, the final parameters,
    every scored candidate, and the `figures` ({name: path}, e.g. from
    `write_diagnosis_figures`, numbered from `first_figure`, captioned by name from
    `CAPTIONS`) linked relative to the report.

    Optional: `fit`, a plain fit on the whole record, adds its row to the table;
    `files` ({label: path}) adds links (e.g. the JSON outputs); `title` replaces the
    heading; `intro` is a paragraph under it. Refuses to replace an existing file
    (either) unless `overwrite`, before writing anything. Returns the Markdown
    report's path."""
    blocks = diagnosis_blocks(
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
    owner = "write_diagnosis_report"
    return write_report(blocks, path, overwrite=overwrite, owner=owner, html=html)[0]


def write_diagnosis_html(
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
    """Write the diagnosis report (the content of `write_diagnosis_report`) as one
    self-contained HTML file to `path` (e.g. report.html): the `figures` (which
    must exist) embedded as PNG data, a little inline CSS, no other files needed
    to show it. Refuses to replace an existing file unless `overwrite`. Returns the
    path."""
    blocks = diagnosis_blocks(
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
    return write_html(blocks, path, overwrite=overwrite, owner="write_diagnosis_html")
