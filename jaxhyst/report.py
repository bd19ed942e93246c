"""Reports of fits, diagnoses and compensations, and the figures in them.

`write_fit_figures`, `write_diagnosis_figures` (the figure names in `FIT_FIGURES`
and `DIAGNOSIS_FIGURES`), `write_diagnosis_report` (Markdown, and the same report
as one self-contained HTML file next to it; `diagnosis_markdown`, `diagnosis_html`
return the texts and `write_diagnosis_html` writes the HTML alone) and
`write_compensation_report` (figures in `COMPENSATION_FIGURES`) are what the
`jaxhyst` commands write; `fit_summary` and `diagnosis_summary` what they print.
The `plot_*` functions draw one figure each on given matplotlib Axes and
`save_figure` saves it. Figures need matplotlib (`pip install 'jaxhyst[plot]'`),
imported when a figure is first drawn (`require_matplotlib` checks it is there);
the writers refuse to replace existing files unless `overwrite=True`.
"""

from ._plots import (
    plot_error_trend as plot_error_trend,
    plot_loop as plot_loop,
    plot_loop_opening as plot_loop_opening,
    plot_residual_scatter as plot_residual_scatter,
    plot_residual_time as plot_residual_time,
    plot_spectrum as plot_spectrum,
    plot_time_history as plot_time_history,
    require_matplotlib as require_matplotlib,
    save_figure as save_figure,
)
from ._report import (
    COMPENSATION_FIGURES as COMPENSATION_FIGURES,
    DIAGNOSIS_FIGURES as DIAGNOSIS_FIGURES,
    FIT_FIGURES as FIT_FIGURES,
    diagnosis_html as diagnosis_html,
    diagnosis_markdown as diagnosis_markdown,
    diagnosis_summary as diagnosis_summary,
    fit_summary as fit_summary,
    write_compensation_report as write_compensation_report,
    write_diagnosis_figures as write_diagnosis_figures,
    write_diagnosis_html as write_diagnosis_html,
    write_diagnosis_report as write_diagnosis_report,
    write_fit_figures as write_fit_figures,
)


__all__ = [
    "COMPENSATION_FIGURES",
    "DIAGNOSIS_FIGURES",
    "FIT_FIGURES",
    "diagnosis_html",
    "diagnosis_markdown",
    "diagnosis_summary",
    "fit_summary",
    "plot_error_trend",
    "plot_loop",
    "plot_loop_opening",
    "plot_residual_scatter",
    "plot_residual_time",
    "plot_spectrum",
    "plot_time_history",
    "require_matplotlib",
    "save_figure",
    "write_compensation_report",
    "write_diagnosis_figures",
    "write_diagnosis_html",
    "write_diagnosis_report",
    "write_fit_figures",
]
