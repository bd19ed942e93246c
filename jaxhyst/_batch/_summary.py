"""The batch's summary, rebuilt from the record folders every time: `summary.csv`
(one row per manifest row) and `index.html` (a sortable table linking every record's
report, and bar charts across records drawn in HTML and CSS, so they need no
plotting library)."""

import csv
import dataclasses
import html
import json
from collections import Counter
from pathlib import Path

from ._manifest import Manifest, Record
from ._store import ERROR, read_done, record_folder
from ._task import OUTCOME, RESULT


SUMMARY = "summary.csv"
INDEX = "index.html"


@dataclasses.dataclass(frozen=True)
class SummaryRow:
    """One record as the summary reports it.

    - `status`: `done`, `failed`, or `missing` (no folder: not run yet, or deleted).
    - `findings`: the diagnosis's effects in order (empty for a fit).
    - `finding_forms`: each finding's form (`Finding.form`; "" when the result
      names none).
    - `heldout_gains`: each finding's drop of the held-out mean squared error, as a
      fraction.
    - `undecided`: the effects the record cannot decide between.
    - `base_rmse`, `final_rmse`: the base model's and the final model's RMSE (a
      fit's RMSE is both); None when unknown.
    - `seconds`: the record's wall time on its worker; None when unknown.
    - `report`: the record's report, relative to the batch folder ("" if none).
    """

    record: Record
    status: str
    findings: tuple[str, ...] = ()
    error: str = ""
    finding_forms: tuple[str, ...] = ()
    heldout_gains: tuple[float, ...] = ()
    undecided: tuple[str, ...] = ()
    base_rmse: float | None = None
    final_rmse: float | None = None
    seconds: float | None = None
    report: str = ""


def _gain(finding: dict) -> float:
    validation = finding.get("validation", {})
    before = validation.get("heldout_rmse_before")
    after = validation.get("heldout_rmse_after")
    if not before or after is None:
        return float("nan")
    return 1.0 - (after / before) ** 2


def _number(value) -> float | None:
    return float(value) if isinstance(value, (int, float)) else None


def read_row(out: Path, record: Record) -> SummaryRow:
    """The summary row of `record` from its folder under `out`."""
    folder = record_folder(out, record.name)
    if not folder.is_dir():
        return SummaryRow(record=record, status="missing")
    seconds = None
    try:
        outcome = json.loads((folder / OUTCOME).read_text(encoding="utf-8"))
        seconds = _number(outcome.get("seconds"))
    except (OSError, ValueError):
        pass
    report = ""
    for name in ("report.html",):
        if (folder / name).is_file():
            report = f"records/{record.name}/{name}"
    if read_done(folder) is None:
        try:
            error = (folder / ERROR).read_text(encoding="utf-8").strip()
        except OSError:
            error = "no 'done' file (an unfinished record); rerun the batch"
        return SummaryRow(record=record, status="failed", error=error, seconds=seconds)
    try:
        data = json.loads((folder / RESULT).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        data = {}
    if record.command == "diagnose":
        findings = data.get("findings", [])
        return SummaryRow(
            record=record,
            status="done",
            findings=tuple(str(f.get("effect", "")) for f in findings),
            finding_forms=tuple(str(f.get("form", "")) for f in findings),
            heldout_gains=tuple(_gain(f) for f in findings),
            undecided=tuple(str(u) for u in data.get("undecided", [])),
            base_rmse=_number(data.get("baseline", {}).get("rmse")),
            final_rmse=_number(data.get("final", {}).get("rmse")),
            seconds=seconds,
            report=report,
        )
    rmse = _number(data.get("metrics", {}).get("rmse"))
    return SummaryRow(
        record=record,
        status="done",
        base_rmse=rmse,
        final_rmse=rmse,
        seconds=seconds,
        report=report,
    )


def read_summary(out: Path, manifest: Manifest) -> list[SummaryRow]:
    return [read_row(out, record) for record in manifest.records]


def _text(value: float | None) -> str:
    return "" if value is None else f"{value:.6g}"


def columns(manifest: Manifest) -> list[str]:
    return [
        "recording",
        "status",
        "findings",
        "error",
        *manifest.label_columns,
        "name",
        "command",
        "finding_forms",
        "heldout_gains",
        "undecided",
        "base_rmse",
        "final_rmse",
        "seconds",
        "report",
    ]


def _cells(row: SummaryRow) -> list[str]:
    return [
        row.record.recording,
        row.status,
        "+".join(row.findings),
        row.error,
        *(value for _, value in row.record.labels),
        row.record.name,
        row.record.command,
        " ".join(
            f"{effect}:{form}"
            for effect, form in zip(row.findings, row.finding_forms)
            if form
        ),
        "+".join(f"{g:.3g}" for g in row.heldout_gains),
        "+".join(row.undecided),
        _text(row.base_rmse),
        _text(row.final_rmse),
        "" if row.seconds is None else f"{row.seconds:.1f}",
        row.report,
    ]


def write_summary_csv(out: Path, manifest: Manifest, rows: list[SummaryRow]) -> Path:
    path = out / SUMMARY
    partial = path.with_name(f".{SUMMARY}.partial")
    with open(partial, "w", newline="", encoding="utf-8") as file:
        writer = csv.writer(file)
        writer.writerow(columns(manifest))
        writer.writerows(_cells(row) for row in rows)
    partial.replace(path)
    return path


_STYLE = """
body{font-family:system-ui,sans-serif;margin:2em;max-width:80em}
table{border-collapse:collapse;font-size:90%}
th,td{border:1px solid #ccc;padding:2px 6px;text-align:left}
th{cursor:pointer;background:#eee}
tr.failed td{background:#fee}tr.missing td{color:#999}
.bar{background:#5470c6;height:1em;display:inline-block;vertical-align:middle}
.bar.base{background:#bbb}
td.n{text-align:right}
"""

_SORT = """
document.querySelectorAll('table.sortable th').forEach(function(th, i) {
  th.addEventListener('click', function() {
    var body = th.closest('table').tBodies[0];
    var rows = Array.from(body.rows);
    var up = th.dataset.up !== '1';
    th.dataset.up = up ? '1' : '0';
    rows.sort(function(a, b) {
      var x = a.cells[i].innerText, y = b.cells[i].innerText;
      var fx = parseFloat(x), fy = parseFloat(y);
      var c = (!isNaN(fx) && !isNaN(fy)) ? fx - fy : x.localeCompare(y);
      return up ? c : -c;
    });
    rows.forEach(function(r) { body.appendChild(r); });
  });
});
"""


def _bars(title: str, items: list[tuple[str, float]], unit: str = "") -> str:
    if not items:
        return ""
    top = max((v for _, v in items), default=0.0) or 1.0
    rows = "".join(
        f"<tr><td>{html.escape(k)}</td><td class='n'>{v:.3g}{unit}</td>"
        f"<td><span class='bar' style='width:{20 * v / top:.2f}em'></span></td></tr>"
        for k, v in items
    )
    return f"<h2>{html.escape(title)}</h2><table>{rows}</table>"


def _effects_by_group(manifest: Manifest, rows: list[SummaryRow]) -> str:
    group_column = manifest.label_columns[0] if manifest.label_columns else None
    groups: dict[str, Counter] = {}
    for row in rows:
        if row.status != "done" or row.record.command != "diagnose":
            continue
        group = dict(row.record.labels).get(group_column, "") if group_column else ""
        counter = groups.setdefault(group or "all", Counter())
        counter.update(row.findings or ("(none)",))
    out = []
    for group, counter in sorted(groups.items()):
        title = "Effects named" + (
            f" ({group_column} = {group})" if group_column else ""
        )
        out.append(_bars(title, sorted(counter.items(), key=lambda kv: -kv[1])))
    return "".join(out)


def _errors(rows: list[SummaryRow]) -> str:
    done = [r for r in rows if r.base_rmse and r.final_rmse is not None]
    if not done:
        return ""
    body = "".join(
        f"<tr><td>{html.escape(r.record.name)}</td>"
        f"<td class='n'>{r.final_rmse / r.base_rmse:.3g}</td>"  # type: ignore[operator]
        f"<td><span class='bar base' style='width:20em'></span><br>"
        f"<span class='bar' style='width:{20 * min(r.final_rmse / r.base_rmse, 1.5):.2f}em'>"  # type: ignore[operator]
        f"</span></td></tr>"
        for r in done
    )
    return (
        "<h2>Final against base RMSE</h2><p>grey: the base model's RMSE; blue: the "
        f"final model's, on the same scale.</p><table>{body}</table>"
    )


def write_index_html(out: Path, manifest: Manifest, rows: list[SummaryRow]) -> Path:
    names = columns(manifest)
    head = "".join(f"<th>{html.escape(c)}</th>" for c in names)
    body = []
    for row in rows:
        cells = _cells(row)
        tds = []
        for column, cell in zip(names, cells):
            text = html.escape(cell)
            if column == "name" and row.report:
                text = f'<a href="{html.escape(row.report)}">{text}</a>'
            elif column == "name" and row.status != "missing":
                text = f'<a href="records/{html.escape(row.record.name)}/">{text}</a>'
            tds.append(f"<td>{text}</td>")
        body.append(f"<tr class='{row.status}'>{''.join(tds)}</tr>")
    counts = Counter(row.status for row in rows)
    tally = ", ".join(f"{counts[s]} {s}" for s in ("done", "failed", "missing"))
    seconds = [
        (row.record.name, row.seconds) for row in rows if row.seconds is not None
    ]
    page = (
        "<!doctype html><meta charset='utf-8'><title>jaxhyst batch</title>"
        f"<style>{_STYLE}</style><h1>jaxhyst batch</h1>"
        f"<p>{len(rows)} records from {html.escape(str(manifest.path))}: {tally}. "
        "Click a column to sort; a record's name opens its report.</p>"
        f"<table class='sortable'><thead><tr>{head}</tr></thead>"
        f"<tbody>{''.join(body)}</tbody></table>"
        + _effects_by_group(manifest, rows)
        + _errors(rows)
        + _bars("Time per record", seconds, " s")
        + f"<script>{_SORT}</script>"
    )
    path = out / INDEX
    partial = path.with_name(f".{INDEX}.partial")
    partial.write_text(page, encoding="utf-8")
    partial.replace(path)
    return path


def write_summary(out: Path, manifest: Manifest) -> list[SummaryRow]:
    """Rebuild `OUT/summary.csv` and `OUT/index.html` from the record folders."""
    rows = read_summary(out, manifest)
    write_summary_csv(out, manifest, rows)
    write_index_html(out, manifest, rows)
    return rows
