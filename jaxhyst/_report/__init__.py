"""Reports of fits, diagnoses and compensations: paper-style figures, a Markdown
report with the same report as one self-contained HTML file next to it, and console
summaries.

Shared by the `jaxhyst fit` / `diagnose` / `demo` / `compensate` commands and usable
from notebooks (every writer is public as `jaxhyst.report.<name>`):

- `write_fit_figures(fit, recording, directory)`: the measured-vs-model loop, time
  histories and absolute-error trend of one fit (the paper's Figures 8-10 layout).
- `write_diagnosis_figures(diagnosis, recording, directory)`: the same before/after
  the diagnosis (measured vs base vs final model), plus the residual analysis:
  against time, against the input split by branch, against the rate |du/dt|, and
  its spectrum.
- `write_diagnosis_report(diagnosis, recording, path, figures)`: a Markdown report
  with a before/after table in the paper's Table 5/6 format (MAD, MRD, MAE, NRMSD),
  the findings with their evidence, location and validation, the ambiguities,
  relative links to the figures, and what is left (`Diagnosis.remainder`); and the
  same report as self-contained HTML next to it (figures embedded), the file to
  mail. `diagnosis_markdown` / `diagnosis_html` return the texts,
  `write_diagnosis_html` writes the HTML alone.
- `write_compensation_report(compensation, reference, path, model=...)`: the
  predicted tracking error of a feedforward drive, with its figures.
- `fit_summary`, `diagnosis_summary`: what the commands print.

The report is built once as a list of typed blocks (`_blocks.py`: heading,
paragraph, table, list, figure) and rendered to Markdown (`_markdown.py`) and to
HTML (`_html.py`), so the two say the same. A diagnosis report quotes one base RMSE
and one improvement: `rmse_change(diagnosis)` (the base model's RMSE on all
samples -> the final model's, in percent).

Figures need matplotlib (`pip install 'jaxhyst[plot]'`); they are drawn by the
`plot_*` functions of `jaxhyst._plots` (public in `jaxhyst.report`) and saved by
its `save_figure`. Like everything that writes files here, the writers refuse to
replace existing files unless `overwrite=True` (`jaxhyst._files`).
"""

from ._blocks import (
    Block as Block,
    Bullets as Bullets,
    Heading as Heading,
    Image as Image,
    Item as Item,
    Paragraph as Paragraph,
    Table as Table,
)
from ._common import (
    RmseChange as RmseChange,
    display_unit as display_unit,
    rmse_change as rmse_change,
)
from ._compensation import (
    COMPENSATION_FIGURES as COMPENSATION_FIGURES,
    write_compensation_report as write_compensation_report,
)
from ._console import (
    diagnosis_summary as diagnosis_summary,
    fit_summary as fit_summary,
)
from ._diagnosis import (
    diagnosis_blocks as diagnosis_blocks,
    diagnosis_html as diagnosis_html,
    diagnosis_markdown as diagnosis_markdown,
    metrics_table as metrics_table,
    write_diagnosis_html as write_diagnosis_html,
    write_diagnosis_report as write_diagnosis_report,
)
from ._figures import (
    CAPTIONS as CAPTIONS,
    DIAGNOSIS_FIGURES as DIAGNOSIS_FIGURES,
    FIT_FIGURES as FIT_FIGURES,
    loop_figure as loop_figure,
    write_diagnosis_figures as write_diagnosis_figures,
    write_fit_figures as write_fit_figures,
)
from ._html import to_html as to_html
from ._markdown import to_markdown as to_markdown
from ._output import html_path as html_path, write_report as write_report
