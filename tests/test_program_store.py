"""The command line's store of exported programs (`jaxhyst._cli._programs`): keys
that two processes agree on, outputs rebuilt as the plain program returns them, a
plain program wherever the store cannot be sure, and the same fit with or without
it."""

import json
import os
import subprocess
import sys

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
import pytest

import jaxhyst as jh
from jaxhyst._cli._programs import (
    _describe,
    _rebuild,
    _Store,
    _stored,
    _structure,
    _Unkeyable,
)


def _key(value) -> str:
    parts = []
    _describe(value, parts)
    return "|".join(parts)


def test_keys_describe_arrays_by_shape_and_dtype_and_the_rest_by_value():
    model = jh.PiezoBoucWen.paper_table4(3)
    same = jh.PiezoBoucWen.paper_table4(3)
    assert _key(model) == _key(same)
    # Parameter values are arrays: they do not change the program.
    assert _key(model) == _key(model.replace(k1=2.0))
    assert _key(jnp.zeros(3)) != _key(jnp.zeros(4))
    assert _key(jnp.zeros(3)) != _key(jnp.zeros(3, jnp.float32))
    # Python numbers and strings are static: their values make other programs.
    assert _key((1.0, "a")) != _key((2.0, "a"))
    assert _key(jh.RK4(substeps=2)) != _key(jh.RK4(substeps=3))
    # A set's description does not depend on its iteration order.
    names = ["beta", "gamma", "alpha", "n", "k1"]
    assert _key(frozenset(names)) == _key(frozenset(reversed(names)))


def test_closures_and_unknown_objects_cannot_be_keyed():
    scale = 2.0

    def local(x):
        return scale * x

    class Unknown:
        pass

    for value in (local, lambda x: x, Unknown()):
        with pytest.raises(_Unkeyable):
            _key(value)
    # A function importable by its name is keyed by it.
    assert "jaxhyst._simulate:simulate" in _key(jh.simulate)


def test_outputs_are_rebuilt_as_the_program_returned_them():
    state = (
        jh.RK4(substeps=2),
        {"z": jnp.arange(3.0), "n": 4},
        [optx.RESULTS.successful, None],
    )
    leaves = []
    recipe = _structure(state, leaves)
    rebuilt = _rebuild(recipe, iter(leaves))
    assert jax.tree.structure(rebuilt) == jax.tree.structure(state)
    assert rebuilt[0].substeps == 2
    np.testing.assert_array_equal(rebuilt[1]["z"], state[1]["z"])
    assert rebuilt[2][0] == optx.RESULTS.successful


@eqx.filter_jit
def _scaled_sum(model, x, power: int):
    return {"total": jnp.sum(x**power) * model.k1, "power": power}


@eqx.filter_jit
def _checked(x):
    return eqx.error_if(x, jnp.any(x < 0), "negative")


def test_a_stored_program_gives_the_plain_programs_result(tmp_path):
    model = jh.PiezoBoucWen.paper_table4(3)
    x = jnp.linspace(0.0, 1.0, 7)
    for _ in range(2):  # export, then load from disk in a fresh store
        store = _Store(tmp_path)
        run = _stored(store, "scaled_sum", _scaled_sum)
        out = run(model, x, 3)
        assert out["power"] == 3
        assert out["total"] == _scaled_sum(model, x, 3)["total"]
        assert len(list(tmp_path.glob("scaled_sum-*.jaxexport"))) == 1
    # Another static argument is another program.
    assert run(model, x, 2)["total"] == _scaled_sum(model, x, 2)["total"]
    assert len(list(tmp_path.glob("scaled_sum-*.jaxexport"))) == 2


def test_a_program_with_a_host_callback_runs_plain(tmp_path):
    # `eqx.error_if` calls back into the process: it cannot be exported; the plain
    # program runs (and raises) as without the store, and later processes skip
    # the export attempt.
    run = _stored(_Store(tmp_path), "checked", _checked)
    np.testing.assert_array_equal(run(jnp.ones(3)), jnp.ones(3))
    with pytest.raises(Exception, match="negative"):
        run(-jnp.ones(3))
    assert list(tmp_path.glob("checked-*.jaxexport")) == []
    assert len(list(tmp_path.glob("checked-*.refused"))) == 1


def test_a_damaged_entry_is_exported_again(tmp_path):
    model = jh.PiezoBoucWen.paper_table4(3)
    x = jnp.linspace(0.0, 1.0, 5)
    _stored(_Store(tmp_path), "scaled_sum", _scaled_sum)(model, x, 3)
    (entry,) = tmp_path.glob("scaled_sum-*.jaxexport")
    entry.write_bytes(entry.read_bytes()[:100])
    out = _stored(_Store(tmp_path), "scaled_sum", _scaled_sum)(model, x, 3)
    assert out["total"] == _scaled_sum(model, x, 3)["total"]
    assert entry.stat().st_size > 100


def _noisy_recording(folder) -> str:
    t = np.arange(1201) / 400.0
    u = np.sin(2 * np.pi * 1.0 * t) * (1 + 0.5 * np.sin(2 * np.pi * 0.3 * t))
    model = jh.PiezoBoucWen.paper_table4(3)
    y = np.asarray(jh.simulate(model, jh.InputPath.from_samples(t, u)))
    noisy = y + 1e-3 * np.max(np.abs(y)) * np.random.default_rng(0).standard_normal(
        t.size
    )
    recording = folder / "rec.csv"
    jh.Recording(t, u, noisy, name="rec").save(recording)
    return str(recording)


def _command_in_a_process(argv: list[str], out, cache, *, store: str = "1") -> dict:
    """`jaxhyst ARGV --json OUT` in a fresh process on the compilation cache `cache`
    (the program store on or off), and the JSON it wrote."""
    env = {
        **os.environ,
        "JAXHYST_CACHE_DIR": str(cache),
        "JAXHYST_PROGRAM_STORE": store,
    }
    subprocess.run(
        [sys.executable, "-m", "jaxhyst", *argv, "--json", str(out)],
        env=env,
        check=True,
        capture_output=True,
    )
    return json.loads(out.read_text())


def _fit_in_a_process(recording: str, out, cache, *, store: str = "1") -> dict:
    argv = ["fit", recording, "--seed", "0", "--particles", "12", "--iterations", "20"]
    return _command_in_a_process(argv, out, cache, store=store)


def test_the_command_line_fits_the_same_with_and_without_the_store(tmp_path):
    # Two processes: the store on (every program exported, then run as a later
    # process loads it; loading one from disk:
    # test_a_stored_program_gives_the_plain_programs_result)
    # and off; the fit is the same to the last bit.
    recording = _noisy_recording(tmp_path)
    results = [
        _fit_in_a_process(
            recording, tmp_path / f"fit{i}.json", tmp_path / "cache", store=store
        )
        for i, store in enumerate(("1", "0"))
    ]
    stored = list((tmp_path / "cache" / "programs").glob("*.jaxexport"))
    assert len(stored) >= 3
    for other in results[1:]:
        assert other["parameters"] == results[0]["parameters"]
        assert other["metrics"] == results[0]["metrics"]


def _compiled(cache) -> set[str]:
    """The compiled programs in a compilation cache folder."""
    return {p.name for p in cache.iterdir() if p.is_file()}


def test_a_second_fit_compiles_nothing(tmp_path):
    recording = _noisy_recording(tmp_path)
    cache = tmp_path / "cache"
    first = _fit_in_a_process(recording, tmp_path / "fit0.json", cache)
    after_first = _compiled(cache)
    assert after_first
    second = _fit_in_a_process(recording, tmp_path / "fit1.json", cache)
    assert _compiled(cache) == after_first
    assert second["parameters"] == first["parameters"]


@pytest.mark.slow
def test_a_second_diagnosis_compiles_nothing(tmp_path):
    # The first process runs the programs it exports as a later process loads them
    # (deserialized): the second one then finds each compiled program in the
    # compilation cache and adds none to it. Before, some of a diagnosis's stored
    # programs (9 of 35 on a real structural test) lowered to other modules once
    # loaded, and every second process compiled them again (a batch's workers after
    # its warm-up, a user's second run).
    case = jh.synthetic.structural_recording(("degradation",), key=jax.random.key(0))
    recording = tmp_path / "rec.csv"
    case.recording.save(recording)
    cache = tmp_path / "cache"
    argv = ["diagnose", str(recording), "--model", "bouc-wen"]
    argv += ["--input", case.recording.input_names[0]]
    argv += ["--output", case.recording.output_name]
    found = []
    for run in range(2):
        data = _command_in_a_process(argv, tmp_path / f"diagnosis{run}.json", cache)
        found.append([f["effect"] for f in data["findings"]])
        if run == 0:
            after_first = _compiled(cache)
    assert _compiled(cache) == after_first
    assert found[1] == found[0]


def test_jax_options_that_change_a_trace_change_the_key(tmp_path):
    store = _Store(tmp_path)
    args = (jh.PiezoBoucWen.paper_table4(3), jnp.zeros(3))
    before = store.key("p", args, {})
    with jax.default_matmul_precision("highest"):
        assert store.key("p", args, {}) != before
    assert store.key("p", args, {}) == before
