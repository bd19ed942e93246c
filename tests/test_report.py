"""Reports of fits and diagnoses (`jaxhyst._report`): figures, Markdown, HTML, JSON.

The diagnosis here is built by hand (one made-up finding) so that every section of
the report is exercised without running the diagnosis itself."""

import base64
import json
import math
import re
from html.parser import HTMLParser
from pathlib import Path

import jax
import numpy as np
import pytest

import jaxhyst as jh
from jaxhyst._diagnose._remainder import remainder
from jaxhyst._diagnose._results import Advice, Ambiguity, DiagnosisStep, Rival
from jaxhyst._models.extended import ExtendedPiezo
from jaxhyst._report import (
    DIAGNOSIS_FIGURES,
    FIT_FIGURES,
    diagnosis_html,
    diagnosis_markdown,
    diagnosis_summary,
    fit_summary,
    metrics_table,
    rmse_change,
    write_compensation_report,
    write_diagnosis_figures,
    write_diagnosis_html,
    write_diagnosis_report,
    write_fit_figures,
)
from jaxhyst._serialise import jsonable, write_json
from jaxhyst.families import PiezoFamily


PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
TRUTH = jh.PiezoBoucWen(k1=0.3, k2=1.0, A1=0.5, beta1=0.6, gamma1=0.2, n=1.5)
AMBIGUITY = "cannot tell asymmetry from input_bias on this recording"


@pytest.fixture(scope="module")
def recording():
    path = jh.sample(jh.paper_u1(), 50.0)
    clean = np.asarray(jh.simulate(TRUTH, path))
    noise = 2e-3 * np.random.default_rng(0).standard_normal(clean.size)
    tilt = 0.01 * np.asarray(path.values) * np.sign(np.gradient(path.values))
    return jh.Recording(
        np.asarray(path.times),
        np.asarray(path.values),
        clean + tilt + noise,
        name="made-up",
        input_unit="V",
        output_unit="m",
    )


@pytest.fixture(scope="module")
def diagnosis(recording):
    y = np.asarray(recording.y)
    inputs = recording.input_path()
    base_predicted = np.asarray(jh.simulate(TRUTH, inputs))
    final_predicted = y - 2e-3 * np.random.default_rng(1).standard_normal(y.size)
    final_model = ExtendedPiezo.around(TRUTH, inputs).replace(eps=0.01, quad=0.0)
    baseline = jh.error_metrics(y, base_predicted)
    final = jh.error_metrics(y, final_predicted)
    validation = jh.diagnosis.Validation(
        heldout_rmse_before=0.01,
        heldout_rmse_after=0.002,
        fit_rmse_before=0.01,
        fit_rmse_after=0.002,
        heldout_margin_mse=1e-7,
        heldout_resolution_mse=1e-8,
        effective_samples_heldout=150.0,
        bic_change=-300.0,
        score_statistic=420.0,
        score_dof=2,
        log10_p=-90.0,
        accepted=True,
    )
    finding = jh.Finding(
        effect="asymmetry",
        evidence="the branches differ: made-up evidence",
        where="mismatch on the ascending branch (1.4x the overall RMS)",
        score=420.0,
        parameters={"eps": 0.01, "quad": 0.0},
        before=baseline,
        after=final,
        validation=validation,
        rivals=(Rival("rate_dependence", 0.0021, 1.5),),
        final_parameters={"eps": 0.012, "quad": 0.0},
        standard_errors={"eps": 0.001, "quad": float("nan")},
        units={"eps": "1/(V·s)", "quad": "µm"},
        meaning="made-up meaning",
        reading="made-up reading of eps",
    )
    directions = np.zeros((y.size, 1))
    rounds = [
        [
            jh.diagnosis.Score(
                "asymmetry",
                420.0,
                2,
                -90.0,
                1e-4,
                True,
                {},
                directions,
                1e-5,
                validation,
            ),
            jh.diagnosis.Score(
                "drift",
                3.0,
                3,
                -0.5,
                1e-7,
                False,
                {},
                directions,
                1e-5,
                rejection="not significant",
            ),
        ]
    ]
    heldout = ~PiezoFamily().holdout(recording, 0.3)
    return jh.Diagnosis(
        recording=recording.name,
        samples=recording.num_samples,
        family="piezo",
        base_name="piezo",
        base_model=TRUTH,
        final_model=final_model,
        baseline=baseline,
        final=final,
        findings=[finding],
        unexplained=[],
        rounds=rounds,
        ambiguities=[
            Ambiguity(
                AMBIGUITY + "; both explain the mismatch equally.", ("asymmetry",)
            )
        ],
        advice=[Advice(("asymmetry", "rate_dependence"), "a made-up test", 6.5, 0.8)],
        steps=[
            DiagnosisStep("piezo fitted", baseline["rmse"], 0.01),
            DiagnosisStep(
                "asymmetry added (refit on the fitted samples)", final["rmse"], 0.002
            ),
        ],
        noise_sigma=2e-3,
        noise={"sigma": 2e-3, "lag1_autocorrelation": 0.01, "effective_samples": 500.0},
        location={"overall_rms": 0.01, "holding": {"mean": float("nan")}},
        base_predicted=base_predicted,
        final_predicted=final_predicted,
        heldout=heldout,
        holdout_description=PiezoFamily.holdout_description,
        holdout_fraction=0.3,
        final_parameters={"k1": 1.0, "eps": 0.01},
        exports={},
        seconds=1.5,
        remainder=remainder(recording, y - final_predicted, heldout=heldout),
    )


def test_diagnosis_figures_are_written_and_never_overwritten(
    diagnosis, recording, tmp_path
):
    figures = write_diagnosis_figures(diagnosis, recording, tmp_path / "figs")
    assert set(figures) == set(DIAGNOSIS_FIGURES)
    for name, path in figures.items():
        assert path == tmp_path / "figs" / DIAGNOSIS_FIGURES[name]
        assert path.read_bytes().startswith(PNG_SIGNATURE)
    mine = figures["residual_input"]
    mine.write_bytes(b"mine")
    with pytest.raises(FileExistsError, match="overwrite=True"):
        write_diagnosis_figures(diagnosis, recording, tmp_path / "figs")
    assert mine.read_bytes() == b"mine"
    write_diagnosis_figures(diagnosis, recording, tmp_path / "figs", overwrite=True)
    assert mine.read_bytes().startswith(PNG_SIGNATURE)


def test_diagnosis_figures_need_the_diagnosed_recording(diagnosis, tmp_path):
    other = jh.Recording(np.arange(10.0), np.sin(np.arange(10.0)), np.zeros(10))
    with pytest.raises(ValueError, match="pass the recording it diagnosed"):
        write_diagnosis_figures(diagnosis, other, tmp_path)
    assert not list(tmp_path.iterdir())


def test_report_has_the_table_findings_ambiguities_and_links(
    diagnosis, recording, tmp_path
):
    figures = write_diagnosis_figures(diagnosis, recording, tmp_path / "figures")
    (tmp_path / "out").mkdir()
    data = write_json(diagnosis.to_dict(), tmp_path / "out" / "d.json", overwrite=False)
    report = tmp_path / "report" / "report.md"
    report.parent.mkdir()
    path = write_diagnosis_report(
        diagnosis, recording, report, figures, files={"diagnosis JSON": data}
    )
    assert path == report
    text = report.read_text(encoding="utf-8")
    # The paper's Table 5/6 format, in micrometres (the recording is in metres).
    assert "| model | MAD [µm] | MRD [%] | MAE [µm] | NRMSD | RMSE [µm] |" in text
    rows = [line for line in text.splitlines() if line.startswith("| base piezo")]
    assert len(rows) == 1
    mad = float(rows[0].split("|")[2])
    assert mad == pytest.approx(1e6 * diagnosis.baseline["mad"], rel=1e-3)
    assert "| final piezo+asymmetry |" in text
    assert "| change, final vs base |" in text
    # The finding, with its evidence, location and validation; the ambiguity.
    assert "### 1. asymmetry" in text
    assert "made-up evidence" in text
    assert "on the ascending branch" in text
    assert "held-out RMSE 1e+04 -> 2000 µm" in text
    assert "accepted" in text and "eps = 0.01 -> 0.012 ± 0.001 1/(V·s)" in text
    assert "quad = 0 -> 0 (not determined) µm" in text
    assert "**Reading (final model):** made-up reading of eps." in text
    assert "**Meaning:** made-up meaning." in text
    assert AMBIGUITY in text
    # The RMSE chain (one row per model moved to) and the advice.
    assert f"| piezo fitted | {1e6 * diagnosis.baseline['rmse']:.4g} | 1e+04 |" in text
    assert "## Tests that would decide" in text and "a made-up test" in text
    # Every figure is linked relative to the report, and the link resolves.
    links = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", text)
    assert len(links) == len(DIAGNOSIS_FIGURES)
    for link in links:
        assert not Path(link).is_absolute()
        assert (report.parent / link).resolve().is_file()
    assert "](../out/d.json)" in text
    with pytest.raises(FileExistsError, match="overwrite=True"):
        write_diagnosis_report(diagnosis, recording, report, figures)


def test_diagnosis_json_is_strict(diagnosis, tmp_path):
    path = write_json(diagnosis.to_dict(), tmp_path / "d.json", overwrite=False)

    def refuse(constant):
        raise AssertionError(f"non-standard JSON constant {constant}")

    data = json.loads(path.read_text(), parse_constant=refuse)
    assert data["location"]["holding"]["mean"] is None  # NaN -> null
    assert data["candidates"][0][1]["significant"] is False
    assert data["final"]["model"] == "piezo+asymmetry"
    assert data["findings"][0]["effect"] == "asymmetry"
    with pytest.raises(FileExistsError):
        write_json({}, path, overwrite=False)


def test_jsonable_converts_numpy_and_non_finite():
    value = {
        "a": np.float32(1.5),
        "b": np.arange(3),
        "c": (np.int64(2), math.inf),
        "d": np.bool_(True),
        1: jax.numpy.asarray(2.0),
    }
    assert jsonable(value) == {
        "a": 1.5,
        "b": [0, 1, 2],
        "c": [2, None],
        "d": True,
        "1": 2.0,
    }
    with pytest.raises(TypeError, match="cannot convert object"):
        jsonable(object())


def test_metrics_table_change_row():
    before = {"rmse": 2.0, "mad": 4.0, "mrd": 1.0, "mae": 1.0, "nrmsd": 0.02}
    after = {"rmse": 1.0, "mad": 3.0, "mrd": 0.75, "mae": 0.5, "nrmsd": 0.01}
    table = metrics_table({"plain": before, "corrected": after}, "µm")
    lines = table.splitlines()
    assert lines[0] == "| model | MAD [µm] | MRD [%] | MAE [µm] | NRMSD | RMSE [µm] |"
    assert lines[2] == "| plain | 4 | 1 | 1 | 0.02 | 2 |"
    assert lines[-1] == (
        "| change, last vs first row | -25.0 % | -25.0 % | -50.0 % | -50.0 % | -50.0 % |"
    )


def test_fit_figures_and_summary(recording, tmp_path):
    fit = jh.identify(
        jh.PiezoBoucWen(1.0, 1.0, 1.0, 1.0, 1.0, 1.5),
        recording,
        key=jax.random.key(0),
        swarm=None,
        polish=None,
        start=TRUTH,
        gauge=False,
    )
    figures = write_fit_figures(fit, recording, tmp_path / "new", label="piezo")
    assert {name: path.name for name, path in figures.items()} == FIT_FIGURES
    for path in figures.values():
        assert path.read_bytes().startswith(PNG_SIGNATURE)
    with pytest.raises(FileExistsError):
        write_fit_figures(fit, recording, tmp_path / "new")
    summary = fit_summary(fit, recording)
    assert "model: PiezoBoucWen" in summary
    assert "RMSE" in summary and "NRMSD" in summary and "µm" in summary
    assert "timing:" in summary


def test_diagnosis_summary(diagnosis, recording):
    summary = diagnosis_summary(diagnosis, recording)
    assert "1. asymmetry: made-up reading of eps" in summary
    assert "rivals: rate_dependence (held-out RMSE" in summary
    assert "lost by 1.5 standard errors" in summary and "cannot tell" in summary
    assert "advice: to tell asymmetry from rate_dependence: a made-up test" in summary
    assert "6.5 noise sigmas" in summary and "would separate them" in summary
    assert "evidence: the branches differ" in summary
    assert "final model: piezo+asymmetry" in summary
    assert AMBIGUITY in summary


@pytest.fixture(scope="module")
def plain_fit(recording):
    """A plain fit on all samples whose RMSE differs from the diagnosis's base (as
    the demo's does): the truth with k1 off by 5 %, not polished."""
    return jh.identify(
        jh.PiezoBoucWen(1.0, 1.0, 1.0, 1.0, 1.0, 1.5),
        recording,
        key=jax.random.key(0),
        swarm=None,
        polish=None,
        start=TRUTH.replace(k1=0.315),
        gauge=False,
        analyse=False,
    )


def _percents(text: str) -> list[str]:
    return re.findall(r"[+-]\d+(?:\.\d+)? %", text)


def test_one_base_rmse_and_one_improvement_per_report(
    diagnosis, recording, plain_fit, tmp_path
):
    """The summary sentence, the table's change row and the console quote the same
    base RMSE and the same percentage, even with a plain fit of another RMSE in
    the table (the demo's layout)."""
    assert plain_fit.metrics["rmse"] != pytest.approx(diagnosis.baseline["rmse"])
    change = rmse_change(diagnosis)
    assert change.base == diagnosis.baseline["rmse"]
    assert change.percent == pytest.approx(
        100 * (diagnosis.final["rmse"] / diagnosis.baseline["rmse"] - 1)
    )
    text = diagnosis_markdown(
        diagnosis, recording, tmp_path / "report.md", {}, fit=plain_fit
    )
    console = diagnosis_summary(diagnosis, recording)
    base = f"{1e6 * change.base:.4g}"

    # Every RMSE change quoted in prose, and the table's RMSE change.
    prose = [
        line
        for line in (*text.splitlines(), *console.splitlines())
        if "RMSE" in line and not line.startswith("|") and "held-out" not in line
    ]
    quoted = [p for line in prose for p in _percents(line)]
    rows = [line.split("|") for line in text.splitlines() if line.startswith("|")]
    change_row = [cells for cells in rows if cells[1].strip().startswith("change")]
    assert len(change_row) == 1
    quoted.append(change_row[0][-2].strip())  # the RMSE column
    assert len(quoted) >= 3, quoted
    assert set(quoted) == {change.percent_text}, quoted

    # Every base RMSE: the summary sentence, the base row, the console.
    (sentence,) = (line for line in text.splitlines() if "falls from" in line)
    from_base = re.search(r"falls from (\S+) \(base model\)", sentence)
    assert from_base is not None, sentence
    base_rows = [cells for cells in rows if cells[1].strip().startswith("base")]
    assert len(base_rows) == 1, [cells[1] for cells in rows]
    (console_base,) = (
        line for line in console.splitlines() if line.startswith("base model")
    )
    console_rmse = re.search(r"RMSE on all samples (\S+)", console_base)
    assert console_rmse is not None, console_base
    found = {from_base.group(1), base_rows[0][-2].strip(), console_rmse.group(1)}
    assert found == {base}, found
    # The plain fit keeps its row, labelled as another model.
    assert "| plain PiezoBoucWen fit on all samples (not the base) |" in text


def test_report_and_summary_say_what_is_left(diagnosis, recording, tmp_path):
    left = diagnosis.remainder
    text = diagnosis_markdown(diagnosis, recording, tmp_path / "report.md", {})
    section = text.split("## What is left", 1)[1]
    assert left.text(1e6, "µm") in section
    assert f"verdict: {left.verdict}" in section
    assert "what is left: " + left.text(1e6, "µm") in diagnosis_summary(
        diagnosis, recording
    )
    assert diagnosis.to_dict()["remainder"]["verdict"] == left.verdict


# ------------------------------------------------------------ plots, HTML, refusals


def test_plots_draw_on_the_axes_they_are_given(recording, tmp_path):
    """Two plots composed into one figure: each draws on the Axes it is given and
    returns it; a multi-panel plot takes a sequence of Axes."""
    from matplotlib.figure import Figure

    figure = Figure(figsize=(10.0, 6.0), layout="constrained")
    (loop, trend), (upper, lower) = figure.subplots(2, 2)
    y = np.asarray(recording.y)
    assert jh.report.plot_loop(recording.u, {"measured": y}, ax=loop) is loop
    errors = {"model": np.abs(y - np.mean(y))}
    assert jh.report.plot_error_trend(recording.t, errors, ax=trend) is trend
    drawn = jh.report.plot_time_history(
        recording.t, recording.u, {"measured": y}, axes=[upper, lower]
    )
    assert list(drawn) == [upper, lower]
    assert len(figure.axes) == 4
    for axis in (loop, trend, upper, lower):
        assert axis.get_lines()
    assert loop.get_lines()[0].get_xdata().shape == y.shape
    path = jh.report.save_figure(figure, tmp_path / "composed.png")
    assert path.read_bytes().startswith(PNG_SIGNATURE)
    # Saving refuses to replace a file and names the fix; an Axes saves its figure.
    with pytest.raises(FileExistsError, match="pass overwrite=True"):
        jh.report.save_figure(loop, path)
    assert jh.report.save_figure(loop, path, overwrite=True) == path


class _Page(HTMLParser):
    """The headings and table rows of an HTML page, checking that every element
    that opens closes, in order."""

    VOID = {"meta", "img", "br", "hr", "link"}

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.open: list[str] = []
        self.headings: list[tuple[int, str]] = []
        self.rows: list[list[str]] = []
        self.sources: list[str] = []
        self._text: list[str] | None = None
        self._row: list[str] | None = None

    def handle_starttag(self, tag, attrs):
        if tag not in self.VOID:
            self.open.append(tag)
        if tag in ("h1", "h2", "h3", "td", "th"):
            self._text = []
        if tag == "tr":
            self._row = []
        if tag == "img":
            self.sources.append(dict(attrs)["src"] or "")

    def handle_endtag(self, tag):
        assert self.open and self.open[-1] == tag, (self.open, tag)
        self.open.pop()
        if tag in ("h1", "h2", "h3"):
            assert self._text is not None
            self.headings.append((int(tag[1]), "".join(self._text)))
        if tag in ("td", "th"):
            assert self._row is not None and self._text is not None
            self._row.append("".join(self._text))
        if tag == "tr":
            assert self._row is not None
            self.rows.append(self._row)

    def handle_data(self, data):
        if self._text is not None:
            self._text.append(data)


def _plain(markdown: str) -> str:
    """Markdown inline text as its HTML shows it (no ** or backticks)."""
    text = re.sub(r"\[([^\]]+)\]\([^)]+\)", r"\1", markdown)
    return text.replace("**", "").replace("`", "")


def test_html_report_is_self_contained_with_the_markdown_content(
    diagnosis, recording, tmp_path
):
    figures = write_diagnosis_figures(diagnosis, recording, tmp_path / "figures")
    report = write_diagnosis_report(
        diagnosis,
        recording,
        tmp_path / "report.md",
        figures,
        files={"diagnosis JSON": tmp_path / "d.json"},
    )
    markdown = report.read_text(encoding="utf-8")
    text = (tmp_path / "report.html").read_text(encoding="utf-8")
    assert text.startswith("<!DOCTYPE html>")
    # Every figure embedded (the very bytes of its file); nothing loaded from a file.
    assert text.count('src="data:image/png;base64,') == len(figures)
    assert not re.findall(r'src="(?!data:image/png;base64,)', text)
    assert "<link" not in text and "<script" not in text
    page = _Page()
    page.feed(text)
    page.close()
    assert page.open == []
    for source, path in zip(page.sources, figures.values(), strict=True):
        data = base64.b64decode(source.removeprefix("data:image/png;base64,"))
        assert data == path.read_bytes()
    # The same headings and tables as the Markdown.
    headings = [
        (len(line) - len(line.lstrip("#")), _plain(line.lstrip("#").strip()))
        for line in markdown.splitlines()
        if line.startswith("#")
    ]
    assert page.headings == headings
    assert (3, "1. asymmetry") in headings and (2, "Figures") in headings
    rows = [
        [_plain(cell.strip()) for cell in line.strip("|").split("|")]
        for line in markdown.splitlines()
        if line.startswith("|") and not line.startswith("|---")
    ]
    assert page.rows == rows
    assert "made-up evidence" in text and AMBIGUITY in text
    assert '<a href="d.json">diagnosis JSON</a>' in text
    # The text functions give the files' texts.
    args = (diagnosis, recording, report, figures)
    files = {"diagnosis JSON": tmp_path / "d.json"}
    assert diagnosis_html(*args, files=files) == text
    assert diagnosis_markdown(*args, files=files) == markdown
    # The HTML alone, or no HTML.
    alone = tmp_path / "alone.html"
    write_diagnosis_html(diagnosis, recording, alone, figures, files=files)
    assert alone.read_text(encoding="utf-8") == text
    only = write_diagnosis_report(
        diagnosis, recording, tmp_path / "only.md", figures, html=False
    )
    assert only.exists() and not (tmp_path / "only.html").exists()


def test_report_writers_refuse_to_overwrite_and_name_the_fix(
    diagnosis, recording, tmp_path
):
    figures = write_diagnosis_figures(diagnosis, recording, tmp_path / "figures")
    (tmp_path / "report.html").write_text("mine")
    # Either file refuses the pair, before anything is written.
    with pytest.raises(FileExistsError, match="report.html.*pass overwrite=True"):
        write_diagnosis_report(diagnosis, recording, tmp_path / "report.md", figures)
    assert not (tmp_path / "report.md").exists()
    assert (tmp_path / "report.html").read_text() == "mine"
    with pytest.raises(FileExistsError, match="write_diagnosis_html: .*overwrite=True"):
        write_diagnosis_html(diagnosis, recording, tmp_path / "report.html", figures)
    write_diagnosis_report(
        diagnosis, recording, tmp_path / "report.md", figures, overwrite=True
    )
    assert (tmp_path / "report.html").read_text(encoding="utf-8") != "mine"
    # The HTML embeds its figures, so they must exist; the Markdown path is not .html.
    missing = {**figures, "loop": tmp_path / "nowhere.png"}
    with pytest.raises(FileNotFoundError, match="write the figures first"):
        write_diagnosis_report(diagnosis, recording, tmp_path / "new.md", missing)
    assert not (tmp_path / "new.md").exists()
    with pytest.raises(ValueError, match="pass the Markdown report's path"):
        write_diagnosis_report(diagnosis, recording, tmp_path / "r.html", figures)
    # The figure writers refuse before drawing any.
    (tmp_path / "fit").mkdir()
    (tmp_path / "fit" / FIT_FIGURES["fit_loop"]).write_bytes(b"mine")
    with pytest.raises(FileExistsError, match="write_fit_figures: .*overwrite=True"):
        write_fit_figures(object(), recording, tmp_path / "fit")  # type: ignore[arg-type]


def test_compensation_report(tmp_path):
    t = np.linspace(0.0, 4.0, 201)
    reference = jh.Recording(
        t, t, 0.1 * (1 - np.cos(np.pi * t / 2)), name="ref", output_unit="m"
    )
    model = jh.PiezoBoucWen(k1=0.3, k2=1.0, A1=0.5, beta1=0.6, gamma1=0.2, n=1.5)
    result = jh.compensate(model, reference.t, reference.y, limits=(0.0, 4.0))
    folder = tmp_path / "rep"
    written = write_compensation_report(
        result, reference, folder / "report.md", model=model, model_file="m.json"
    )
    names = ["report.md", "report.html", *jh.report.COMPENSATION_FIGURES.values()]
    assert [path.name for path in written] == names
    text = (folder / "report.md").read_text(encoding="utf-8")
    assert text.startswith("# Compensation\n\nModel `PiezoBoucWen` from `m.json`; ")
    assert "reference `ref` (201 samples at 50 Hz); drive limits 0 to 4." in text
    assert "| RMS | " in text and " µm | " in text
    assert "![drive and output](compensation_drive.png)" in text
    html = (folder / "report.html").read_text(encoding="utf-8")
    assert html.count('src="data:image/png;base64,') == 2
    (folder / "compensation_error.png").write_bytes(b"mine")
    with pytest.raises(FileExistsError, match="write_compensation_report: "):
        write_compensation_report(result, reference, folder / "other.md", model=model)
    assert not (folder / "other.md").exists()
    assert (folder / "compensation_error.png").read_bytes() == b"mine"
