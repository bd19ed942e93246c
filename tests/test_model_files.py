"""Model files: jh.save_model / jh.load_model, and `jaxhyst evaluate`."""

import importlib
import inspect
import io
import json
import sys
from typing import Any

import equinox as eqx
import numpy as np
import pytest

import jaxhyst as jh
from jaxhyst._cli import main
from jaxhyst._model_files import MODEL_CLASSES, checksum


QUICK = ["--particles", "8", "--iterations", "10"]
METRIC_KEYS = {"rmse", "mad", "mrd", "mae", "nrmsd"}
_PAPER = jh.PiezoBoucWen.paper_table4(3)
# Every StructuralBoucWen field (typed Any: its converters take floats).
_STRUCTURAL: dict[str, Any] = {
    "k": 2.0,
    "alpha": 0.1,
    "A": 1.0,
    "beta": 0.6,
    "gamma": 0.3,
    "n": 1.5,
    "strength_degradation": 0.1,
    "stiffness_degradation": 0.05,
    "pinch": 0.2,
    "pinch_shift": 0.15,
    "yield_skew": 0.05,
    "stiffness_skew": 0.02,
    "offset": 0.01,
    "trend": -0.02,
    "curvature": 0.003,
    "wander": 1 / 3,
    "pinch_lambda": 0.4,
    "energy_scale": 3.0,
    "displacement_scale": 2.0,
    "force_scale": 2.5,
    "time_center": 1.5,
    "time_scale": 1.5,
    "slip_from_yield": False,
    "smoothing": jh.AlgebraicSign(1e-3),
}


def _every_model() -> dict[str, jh.AbstractHysteresisModel]:
    """One instance of every model class, with non-trivial values of every field
    and a non-default smoothing rule."""
    paper = jh.PiezoBoucWen.paper_table4(3, smoothing=jh.AlgebraicSign(1e-2))
    return {
        "BoucWen": jh.BoucWen(
            k=1.3,
            alpha=0.4,
            D=1.2,
            A=0.9,
            beta=0.55,
            gamma=0.35,
            n=1.7,
            smoothing=jh.TanhSign(1e-3),
        ),
        "PiezoBoucWen": paper,
        "CorrectedPiezoBoucWen": jh.CorrectedPiezoBoucWen.from_piezo(
            paper.replace(k1=2.9e-5 + 1e-12), phi=0.05, eps=1e-6
        ),
        "PiezoStage": jh.PiezoStage.from_piezo(
            paper, natural_frequency=50.0, damping_ratio=0.1
        ),
        "HystereticOscillator": jh.HystereticOscillator(
            2.0, 10.0, 5e4, 5e4, 800.0, -1100.0, 1.3, smoothing=jh.TanhSign(1e-4)
        ),
        "StructuralBoucWen": jh.StructuralBoucWen(**_STRUCTURAL),
        "ExtendedPiezo": jh.ExtendedPiezo(
            **_PAPER.parameters(),
            eps=1e-6,
            quad=1e-7,
            skew=0.3,
            phi=0.01,
            input_lead=-0.5,
            rate_gain=0.1,
            viscous=1e-7,
            creep_fast=2e-7,
            creep_slow=-1e-7,
            offset=1e-7,
            trend=3e-8,
            natural_frequency=60.0,
            damping_ratio=0.3,
            input_center=2.0,
            input_scale=2.0,
            rate_scale=1.3,
            time_center=1.5,
            time_scale=1.5,
            creep_times=(0.02, 0.2, 2.0, 20.0),
            dynamic=True,
            smoothing=jh.TanhSign(1e-3),
        ),
        "BoucWenDamper": jh.BoucWenDamper(
            25.0, 40.0, 0.3, 900.0, -12.0, 1.0, 150.0, 110.0, 1.6
        ),
        "SpencerDamper": jh.SpencerDamper.spencer_1997(
            smoothing=jh.AlgebraicSign(1e-2)
        ).replace(x0=14.3 + 1e-9),
        "ExtendedDamper": jh.ExtendedDamper.around(
            jh.BoucWenDamper(25.0, 40.0, 0.3, 900.0, -12.0, 1.0, 150.0, 110.0, 1.6),
            jh.InputPath(
                0.0, 1e-3, np.sin(np.arange(50) / 8.0), channels=np.ones((1, 50))
            ),
            300.0,
        ).replace(
            field_alpha=0.8,
            field_damping=0.3,
            field_knee=0.4,
            command_lag=0.01,
            rolloff=0.05,
            offset3=2.0,
            offset17=-1.5,
            skew=0.1,
            damping_skew=-0.05,
        ),
    }


def _package_model_classes() -> set[str]:
    """Every concrete model class defined in jaxhyst._models."""
    found = set()
    import pkgutil

    import jaxhyst._models

    modules = [m.name for m in pkgutil.iter_modules(jaxhyst._models.__path__)]
    for module in modules:
        mod = importlib.import_module(f"jaxhyst._models.{module}")
        for name, obj in vars(mod).items():
            if (
                inspect.isclass(obj)
                and issubclass(obj, jh.AbstractHysteresisModel)
                and obj.__module__ == mod.__name__
                and not inspect.isabstract(obj)
            ):
                found.add(name)
    return found


def test_every_model_class_is_covered():
    assert _package_model_classes() == set(MODEL_CLASSES) == set(_every_model())


@pytest.mark.parametrize("name", sorted(_every_model()))
def test_round_trip_is_exact(name, tmp_path):
    model = _every_model()[name]
    assert type(model).__name__ == name
    path = jh.sample(jh.paper_u1(periods=0.3), 500.0)
    if len(model.input_names) > 1:  # an MR damper: a command of 1.5 V beside x
        more = np.full((len(model.input_names) - 1, path.num_samples), 1.5)
        path = jh.InputPath(path.t0, path.dt, path.values, channels=more)
    y = np.asarray(jh.simulate(model, path, jh.RK4(), throw=False))
    recording = jh.Recording(
        np.asarray(path.times), np.asarray(path.values), y, name="r", input_unit="V"
    )
    file = jh.save_model(model, tmp_path / "model.json", recording=recording)
    loaded = jh.load_model(file)
    assert type(loaded.model) is type(model)
    assert eqx.tree_equal(loaded.model, model)
    assert loaded.model.smoothing == model.smoothing
    again = np.asarray(jh.simulate(loaded.model, path, jh.RK4(), throw=False))
    assert np.all(np.isfinite(y))
    np.testing.assert_array_equal(again, y)
    assert loaded.units == {"input": "V", "output": "", "time": "s"}
    u = np.asarray(path.values)
    assert loaded.recordings == (
        {
            "name": "r",
            "samples": y.size,
            "sample_rate_hz": 500.0,
            "input_range": [float(u.min()), float(u.max())],
            "inputs": ["u"],
            "output": "y",
        },
    )
    # A model of more inputs than the recording names has no columns to read.
    one_input = len(model.input_names) == 1
    assert loaded.columns == ((("u",), "y") if one_input else None)
    assert loaded.family is None and loaded.effects == ()
    assert loaded.jaxhyst_version == jh.__version__


def test_gains_held_by_a_refit_are_not_part_of_the_file(tmp_path):
    # `held_at_zero` is a way of computing: the file lists the model's fields only,
    # and the loaded model computes every term again.
    model = _every_model()["ExtendedDamper"].replace(offset4=0.0)
    held = model.held_at_zero(["offset4", "offset5", "field_lag"])
    file = jh.save_model(held, tmp_path / "held.json")
    assert "zero_gains" not in json.loads(file.read_text())["model"]["fields"]
    loaded = jh.load_model(file).model
    assert isinstance(loaded, jh.ExtendedDamper)
    assert loaded.zero_gains == frozenset()
    assert eqx.tree_equal(loaded, held.held_at_zero(()))


def test_file_format_is_documented_json(tmp_path):
    file = jh.save_model(
        _PAPER, tmp_path / "m.json", family="piezo", effects=("creep", "drift")
    )
    data = json.loads(file.read_text())
    assert data["format"] == "jaxhyst-model" and data["format_version"] == 1
    assert data["model"]["class"] == "PiezoBoucWen"
    assert data["model"]["parameters"]["k1"] == float(_PAPER.k1)
    assert data["model"]["smoothing"] == {"rule": "ExactSign"}
    assert data["family"] == "piezo" and data["effects"] == ["creep", "drift"]
    assert data["units"] == {"input": "", "output": "", "time": ""}
    assert data["recordings"] == []
    assert data["checksum"] == checksum(data)
    loaded = jh.load_model(file)
    assert loaded.family == "piezo" and loaded.effects == ("creep", "drift")


def test_refuses_to_overwrite(tmp_path):
    file = jh.save_model(_PAPER, tmp_path / "m.json")
    before = file.read_text()
    with pytest.raises(FileExistsError, match="m.json.*overwrite=True"):
        jh.save_model(_PAPER.replace(k1=1.0), file)
    assert file.read_text() == before
    jh.save_model(_PAPER.replace(k1=1.0), file, overwrite=True)
    assert jh.load_model(file).model.parameters()["k1"] == 1.0


def test_refuses_what_it_cannot_save(tmp_path):
    with pytest.raises(ValueError, match="k1 = nan is not finite"):
        jh.save_model(_PAPER.replace(k1=float("nan")), tmp_path / "m.json")
    with pytest.raises(TypeError, match="effects"):
        jh.save_model(_PAPER, tmp_path / "m.json", effects="creep")
    assert not (tmp_path / "m.json").exists()


def _edit(file, change):
    data = json.loads(file.read_text())
    change(data)
    file.write_text(json.dumps(data, indent=2))


def test_tampered_file_is_refused_unless_not_verified(tmp_path):
    file = jh.save_model(_PAPER, tmp_path / "m.json")
    text = file.read_text()
    old = repr(float(_PAPER.k2))  # 0.2412
    assert text.count(old) == 1
    file.write_text(text.replace(old, old.replace("0.24", "0.25")))
    with pytest.raises(ValueError, match="changed after it was written") as error:
        jh.load_model(file)
    assert "verify=False" in str(error.value)
    assert jh.load_model(file, verify=False).model.parameters()["k2"] == 0.2512


def test_other_format_version_names_both(tmp_path):
    file = jh.save_model(_PAPER, tmp_path / "m.json")
    _edit(file, lambda d: d.update(format_version=2))
    with pytest.raises(ValueError, match="format version 2.*format version 1"):
        jh.load_model(file, verify=False)


def test_structural_files_of_another_peak_origin_are_refused_by_name(tmp_path):
    # Files written before the slip alone read the excursion past yield lack
    # `slip_from_yield` (the latest of them carry `peak_from_yield`, for which
    # their peak-driven degradation counted from yield too): read with today's
    # meaning, their peak rates would mean something else, so they are refused,
    # naming the fields.
    file = jh.save_model(jh.StructuralBoucWen(**_STRUCTURAL), tmp_path / "m.json")

    def older(data):
        fields = data["model"]["fields"]
        fields["peak_from_yield"] = fields.pop("slip_from_yield")
        data["checksum"] = checksum(data)

    _edit(file, older)
    with pytest.raises(
        ValueError,
        match=r"missing field\(s\) \['slip_from_yield'\].*unknown field\(s\) "
        r"\['peak_from_yield'\]",
    ):
        jh.load_model(file)


def test_other_jaxhyst_version_loads(tmp_path):
    file = jh.save_model(_PAPER, tmp_path / "m.json")

    def older(data):
        data["jaxhyst_version"] = "0.0.1"
        data["checksum"] = checksum(data)

    _edit(file, older)
    loaded = jh.load_model(file)
    assert loaded.jaxhyst_version == "0.0.1"
    assert eqx.tree_equal(loaded.model, _PAPER)


@pytest.mark.parametrize(
    "change, expected",
    [
        (lambda m: m.update({"class": "os.system"}), "unknown model class 'os.system'"),
        (
            lambda m: m["parameters"].pop("gamma1"),
            r"missing parameter\(s\) \['gamma1'\]",
        ),
        (
            lambda m: m["parameters"].update(zeta=1.0),
            r"unknown parameter\(s\) \['zeta'\]",
        ),
        (lambda m: m["parameters"].update(n="2"), "must be numbers"),
        (lambda m: m.update(smoothing={"rule": "Eval"}), "unknown smoothing"),
        (lambda m: m.update(smoothing={"rule": "TanhSign"}), r"missing TanhSign"),
        (lambda m: m.update(smoothing={"rule": "TanhSign", "width": -1}), "positive"),
        (lambda m: m["fields"].update(dynamic=True), r"unknown field\(s\)"),
    ],
)
def test_bad_model_blocks_are_refused(change, expected, tmp_path):
    file = jh.save_model(_PAPER, tmp_path / "m.json")

    def edit(data):
        change(data["model"])
        data["checksum"] = checksum(data)  # valid checksum: content checks still run

    _edit(file, edit)
    with pytest.raises(ValueError, match=expected):
        jh.load_model(file)


def test_unknown_class_lists_the_known_ones(tmp_path):
    file = jh.save_model(_PAPER, tmp_path / "m.json")
    _edit(file, lambda d: d["model"].update({"class": "Foo"}))
    with pytest.raises(ValueError, match="Foo") as error:
        jh.load_model(file, verify=False)
    for name in MODEL_CLASSES:
        assert name in str(error.value)


def test_a_damper_file_with_the_retired_legendre_offset_says_to_refit(tmp_path):
    # Files written before the offset became a spline name its Legendre terms:
    # loading one says what they were and what to do, not only that names differ.
    file = jh.save_model(_every_model()["ExtendedDamper"], tmp_path / "m.json")

    def edit(data):
        parameters = data["model"]["parameters"]
        for k in range(1, 27):
            parameters.pop(f"offset{k}")
        parameters.update(trend=1.0, curvature=0.0, wander=0.0, legendre4=0.0)

    _edit(file, edit)
    with pytest.raises(
        ValueError,
        match=r"earlier jaxhyst.*'trend'.*Legendre terms.*offset1 \.\.\. offset26"
        r".*refit",
    ):
        jh.load_model(file, verify=False)


def test_extended_fields_check_their_kind(tmp_path):
    model = _every_model()["ExtendedPiezo"]
    file = jh.save_model(model, tmp_path / "m.json")
    _edit(file, lambda d: d["model"]["fields"].update(dynamic=1.0))
    with pytest.raises(ValueError, match="dynamic = 1.0 must be true or false"):
        jh.load_model(file, verify=False)
    file = jh.save_model(model, tmp_path / "m.json", overwrite=True)
    _edit(file, lambda d: d["model"]["fields"].pop("creep_times"))
    with pytest.raises(ValueError, match=r"missing field\(s\) \['creep_times'\]"):
        jh.load_model(file, verify=False)


def test_not_a_model_file(tmp_path):
    file = tmp_path / "x.json"
    file.write_text('{"a": 1}')
    with pytest.raises(ValueError, match="not a jaxhyst model file"):
        jh.load_model(file)
    file.write_text('{"model": "PiezoBoucWen", "parameters": {}}')
    with pytest.raises(ValueError, match="no 'model_file' block"):
        jh.load_model(file)
    file.write_text("{")
    with pytest.raises(ValueError, match="not a JSON file"):
        jh.load_model(file)


# ------------------------------------------------------------- command line


def _recording(tmp_path_factory, name, signal, truth):
    path = jh.sample(signal, 250.0)
    y = np.asarray(jh.simulate(truth, path))
    y = y + 1e-3 * np.max(np.abs(y)) * np.random.default_rng(0).standard_normal(y.size)
    recording = jh.Recording(
        np.asarray(path.times),
        np.asarray(path.values),
        y,
        name=name,
        input_unit="V",
        output_unit="um",
    )
    file = tmp_path_factory.mktemp(name) / f"{name}.csv"
    recording.save(file)
    return file


_TRUTH = jh.PiezoBoucWen(k1=0.3, k2=1.0, A1=0.5, beta1=0.6, gamma1=0.2, n=1.5)


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    """Two tests of one system: u1 (fitted), and a triangle wave (not fitted)."""
    return (
        _recording(tmp_path_factory, "short", jh.paper_u1(periods=0.8), _TRUTH),
        _recording(
            tmp_path_factory,
            "other",
            jh.Triangle(2.0, 0.2, duration=6.0),
            _TRUTH,
        ),
    )


def _run(argv):
    with pytest.MonkeyPatch.context() as patch:
        stdout = io.StringIO()
        patch.setattr(sys, "stdout", stdout)
        status = main(argv)
    return status, stdout.getvalue()


@pytest.fixture(scope="module")
def fit_json(recordings, tmp_path_factory):
    out = tmp_path_factory.mktemp("fit") / "fit.json"
    status, _ = _run(["fit", str(recordings[0]), "--json", str(out), *QUICK])
    assert status == 0
    return out


def _one_error_line(capsys) -> str:
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("jaxhyst: error: "), err
    return lines[0]


def test_fit_json_loads_directly(fit_json):
    data = json.loads(fit_json.read_text())
    loaded = jh.load_model(fit_json)
    assert isinstance(loaded.model, jh.PiezoBoucWen)
    assert eqx.tree_equal(loaded.model, jh.PiezoBoucWen(**data["parameters"]))
    assert loaded.units == {"input": "V", "output": "um", "time": "s"}
    assert loaded.recordings[0]["name"] == "short"
    assert loaded.recordings[0]["samples"] == 2001
    # The visible parameters are checked against the embedded model.
    data["parameters"]["k1"] += 1e-9
    edited = fit_json.with_name("edited.json")
    edited.write_text(json.dumps(data))
    with pytest.raises(ValueError, match=r"changed after it was written.*\['k1'\]"):
        jh.load_model(edited)
    assert eqx.tree_equal(jh.load_model(edited, verify=False).model, loaded.model)


def test_evaluate_two_recordings_writes_the_contract(fit_json, recordings, tmp_path):
    out = tmp_path / "evaluation.json"
    argv = ["evaluate", str(fit_json), *map(str, recordings), "--json", str(out)]
    status, stdout = _run(argv)
    assert status == 0
    data = json.loads(out.read_text())
    model = jh.load_model(fit_json).model
    assert [r["recording"] for r in data["recordings"]] == list(map(str, recordings))
    for entry, file in zip(data["recordings"], recordings):
        assert set(entry["metrics"]) == METRIC_KEYS
        recording = jh.Recording.load(file)
        y = jh.simulate(model, recording.input_path(), jh.RK4(), throw=False)
        assert entry["metrics"] == jh.error_metrics(recording.y, y)
    # The fitted recording is matched well; the other one is a real test.
    assert data["recordings"][0]["metrics"]["nrmsd"] < 0.02
    for word in ("PiezoBoucWen", "RMSE [µm]", "NRMSD", str(recordings[1])):
        assert word in stdout
    assert f"wrote {out}" in stdout
    # Refused without --force, before any computation; replaced with it.
    status, _ = _run(argv)
    assert status == 2
    assert _run([*argv, "--force"])[0] == 0


def test_evaluate_saved_model_file_and_window(recordings, tmp_path):
    file = jh.save_model(_TRUTH, tmp_path / "truth.json")
    out = tmp_path / "e.json"
    argv = ["evaluate", str(file), str(recordings[1]), "--json", str(out)]
    status, stdout = _run(argv)
    assert status == 0
    data = json.loads(out.read_text())
    assert data["recordings"][0]["metrics"]["nrmsd"] < 0.01  # the true model
    assert data["window"] == {"start": None, "end": None, "time_unit": "s"}
    # A window is simulated from rest at its start, as `fit` does.
    status, stdout = _run([*argv, "--start", "1", "--end", "3", "--force"])
    assert status == 0
    data = json.loads(out.read_text())
    assert data["recordings"][0]["samples"] == 501
    assert data["window"]["start"] == 1.0 and data["window"]["end"] == 3.0
    assert "window:" in stdout


@pytest.fixture(scope="module")
def diagnosis_json(recordings, tmp_path_factory):
    out = tmp_path_factory.mktemp("diagnose") / "diagnosis.json"
    status, _ = _run(["diagnose", str(recordings[0]), "--json", str(out), *QUICK])
    assert status == 0
    return out


def test_diagnose_json_loads_the_final_model(diagnosis_json, recordings, tmp_path):
    data = json.loads(diagnosis_json.read_text())
    loaded = jh.load_model(diagnosis_json)
    assert isinstance(loaded.model, jh.ExtendedPiezo)
    assert loaded.family == "piezo"
    assert loaded.columns == (("u",), "y")  # the columns evaluate reads
    assert list(loaded.effects) == [f["effect"] for f in data["findings"]]
    for name, value in data["final"]["parameters"].items():
        assert float(getattr(loaded.model, name)) == value
    out = tmp_path / "e.json"
    argv = ["evaluate", str(diagnosis_json), str(recordings[1]), "--json", str(out)]
    assert _run(argv)[0] == 0
    assert json.loads(out.read_text())["recordings"][0]["metrics"]["nrmsd"] < 0.05


def _bad_file(tmp_path, kind):
    if kind == "missing":
        return tmp_path / "nothing.json"
    file = jh.save_model(_TRUTH, tmp_path / "m.json")
    if kind == "tampered":
        file.write_text(file.read_text().replace('"k2": 1.0', '"k2": 1.5'))
    elif kind == "diverges":
        file.unlink()
        unstable = _TRUTH.replace(beta1=-50.0, gamma1=-50.0)
        jh.save_model(unstable, file)
    elif kind == "units":
        _edit(
            file,
            lambda d: d.update(
                units={"input": "V", "output": "m", "time": "s"}, checksum=None
            ),
        )
        _edit(file, lambda d: d.update(checksum=checksum(d)))
    return file


@pytest.mark.parametrize(
    "kind, expected",
    [
        ("missing", "does not exist"),
        ("tampered", "changed after it was written"),
        ("diverges", "not finite"),
        ("units", "output is in um, the model's in m"),
    ],
)
def test_evaluate_bad_inputs_are_one_line_errors(
    kind, expected, recordings, tmp_path, capsys
):
    file = _bad_file(tmp_path, kind)
    out = tmp_path / "e.json"
    assert main(["evaluate", str(file), str(recordings[0]), "--json", str(out)]) == 2
    assert expected in _one_error_line(capsys)
    assert not out.exists()


def test_evaluate_usage_errors(recordings, tmp_path, capsys):
    file = jh.save_model(_TRUTH, tmp_path / "m.json")
    assert main(["evaluate", str(file)]) == 2
    assert "RECORDING" in _one_error_line(capsys)
    assert main(["evaluate", str(file), str(tmp_path / "none.csv")]) == 2
    assert "does not exist" in _one_error_line(capsys)
    assert main(["evaluate", "--help"]) == 0
    assert "MODEL" in capsys.readouterr().out
