"""The program store: traced programs kept on disk so that a later call (in this
process or another) runs them without tracing; what it refuses to store; what it
does with a damaged file. Fresh processes check the cross-process case."""

import json
import os
import re
import subprocess
import sys
import textwrap
import threading
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxhyst import _program_store, _xla_options
from jaxhyst._program_store import (
    enable_program_store,
    prefetching,
    preparing,
    program_store,
    stored_jit,
)
from jaxhyst._xla_options import ELEMENTAL_EMITTERS


class _Scaled(eqx.Module):
    weights: jax.Array
    power: int = eqx.field(static=True)


traces = {"count": 0}


def _body(model: _Scaled, x, offset: float):
    traces["count"] += 1
    return {"y": jnp.sum(model.weights * x**model.power) + offset, "n": model.power}


_stored = stored_jit(_body)


@pytest.fixture
def store(tmp_path, monkeypatch):
    """The store on in `tmp_path`, with this module's names accepted in keys (its
    source is not part of the key: the tests change nothing in it); off after."""
    monkeypatch.setattr(
        _program_store,
        "_PINNED_PACKAGES",
        (*_program_store._PINNED_PACKAGES, __name__.split(".")[0]),
    )
    monkeypatch.setattr(_stored, "_memo", {})
    before = program_store()
    enable_program_store(tmp_path / "programs")
    jax.clear_caches()  # so that the trace counts below see every trace
    traces["count"] = 0
    yield tmp_path / "programs"
    enable_program_store(before)


def _files(folder: Path, kind: str = "program") -> list[Path]:
    return sorted(folder.glob(f"*.{kind}")) if folder.exists() else []


def _stored_compiles(compiled: list) -> int:
    """How many of the compiled programs are stored ones (their `jax.jit` is named
    `stored_program_<key digest>`)."""
    return sum(1 for name in compiled if str(name).startswith("jit(stored_program_"))


def _model(power=2):
    return _Scaled(jnp.array([1.0, 2.0, 3.0]), power)


def test_the_store_is_off_until_turned_on(tmp_path):
    assert program_store() is None  # a library import changes nothing
    traces["count"] = 0
    out = _stored(_model(), jnp.ones(3), 0.5)
    assert out["y"] == 6.5 and out["n"] == 2
    assert traces["count"] == 1


def test_a_stored_program_gives_the_traced_result_and_is_not_traced_again(store):
    x = jnp.linspace(0.0, 1.0, 3)
    out = _stored(_model(), x, 0.5)
    assert traces["count"] == 1  # traced once, to export it
    assert len(_files(store)) == 1
    assert out["n"] == 2 and isinstance(out["n"], int)  # static outputs come back
    expected = _stored._traced(_model(), x, 0.5)  # plain filter_jit (the export's)
    np.testing.assert_array_equal(out["y"], expected["y"])
    # New array values, same structure: the stored program, no new trace or file.
    _stored.__dict__["_memo"] = {}  # as a new process would: read it from disk
    jax.clear_caches()
    again = _stored(_Scaled(jnp.array([3.0, 2.0, 1.0]), 2), x + 1.0, 0.5)
    assert traces["count"] == 1
    assert len(_files(store)) == 1
    np.testing.assert_allclose(
        again["y"], np.sum(np.array([3.0, 2.0, 1.0]) * (np.asarray(x) + 1) ** 2) + 0.5
    )


def test_what_tracing_depends_on_is_part_of_the_key(store):
    x = jnp.ones(3)
    _stored(_model(2), x, 0.5)
    _stored(_model(3), x, 0.5)  # a static field
    _stored(_model(2), x, 0.25)  # a Python number (static under filter_jit)
    _stored(_Scaled(jnp.ones(4), 2), jnp.ones(4), 0.5)  # a shape
    _stored(_model(2), jnp.ones(3, dtype=jnp.float32), 0.5)  # a dtype
    assert traces["count"] == 5
    assert len(_files(store)) == 5
    y = _stored(_model(3), x, 0.25)["y"]
    assert float(y) == 6.25


def test_what_the_key_cannot_pin_down_runs_unstored(store):
    x = jnp.ones(3)

    class Local(eqx.Module):  # defined at run time: no name pins its code
        w: jax.Array

    def body(m, x):
        return jnp.sum(m.w * x)

    local = stored_jit(body)
    assert float(local(Local(jnp.ones(3)), x)) == 3.0
    scale = jnp.array(2.0)
    closure = stored_jit(lambda x: jnp.sum(x * scale))
    assert float(closure(x)) == 6.0
    assert _files(store) == []


def test_programs_that_call_back_into_python_run_unstored(store, monkeypatch):
    def checked(x):
        return eqx.error_if(x, x < 0, "negative input")

    monkeypatch.setattr(sys.modules[__name__], "_checked", checked, raising=False)
    stored = stored_jit(checked)
    np.testing.assert_array_equal(stored(jnp.ones(2)), jnp.ones(2))
    assert _files(store) == []
    with pytest.raises(Exception, match="negative input"):
        stored(-jnp.ones(2))


def test_calls_inside_jit_vmap_and_grad_are_traced_as_usual(store):
    def total(x):
        return _stored(_model(), x, 0.0)["y"]

    x = jnp.array([0.5, 1.0, 1.5])
    assert float(jax.jit(total)(x)) == pytest.approx(1 * 0.25 + 2 * 1 + 3 * 2.25)
    np.testing.assert_allclose(jax.grad(total)(x), 2 * np.array([1.0, 2.0, 3.0]) * x)
    assert jax.vmap(total)(jnp.stack([x, x])).shape == (2,)
    assert _files(store) == []


def test_a_damaged_or_foreign_file_is_traced_again_and_replaced(store):
    x = jnp.ones(3)
    first = _stored(_model(), x, 0.5)["y"]
    (path,) = _files(store)
    good = path.read_bytes()
    for damaged in (good[: len(good) // 2], b"nonsense", good.replace(b"A[", b"B[", 1)):
        path.write_bytes(damaged)
        for executable in _files(store, "executable"):  # else loaded as it is
            executable.unlink()
        _stored.__dict__["_memo"] = {}
        jax.clear_caches()
        traces["count"] = 0
        assert _stored(_model(), x, 0.5)["y"] == first
        assert traces["count"] == 1
        assert path.read_bytes() != damaged
    # A valid file under another key's name is not used for this key.
    _stored(_model(3), x, 0.5)
    other = next(p for p in _files(store) if p != path)
    path.write_bytes(other.read_bytes())
    for executable in _files(store, "executable"):
        executable.unlink()
    _stored.__dict__["_memo"] = {}
    jax.clear_caches()
    traces["count"] = 0
    assert _stored(_model(), x, 0.5)["y"] == first
    assert traces["count"] == 1


_CHILD = textwrap.dedent(
    """
    import json, sys

    import jax
    jax.config.update("jax_enable_x64", True)

    import jaxhyst as jh
    from jaxhyst import enable_compilation_cache

    import threading

    traced, lowered = [], []
    jax.monitoring.register_event_duration_secs_listener(
        lambda event, duration, **kw: traced.append(
            [kw.get("fun_name"), threading.current_thread().name]
        )
        if event == "/jax/core/compile/jaxpr_trace_duration" else None
    )
    jax.monitoring.register_event_duration_secs_listener(
        lambda event, duration, **kw: lowered.append(kw.get("fun_name"))
        if event == "/jax/core/compile/jaxpr_to_mlir_module_duration" else None
    )
    enable_compilation_cache()
    model = jh.PiezoBoucWen.paper_table4(3)
    path = jh.sample(jh.paper_u1(), 100.0)
    y = jh.simulate(model, path, jh.RK4())
    import numpy as np
    recording = jh.Recording(np.arange(path.num_samples) / 100.0, np.asarray(path.values), np.asarray(y))
    key = jax.random.key(0)
    before_fit = len(lowered)
    fit = jh.identify(
        jh.PiezoBoucWen(1.0, 1.0, 1.0, 1.0, 1.0, 1.5),
        recording,
        key=key,
        swarm=jh.MPSO(num_particles=8, num_iterations=10),
    )
    print(json.dumps({
        "traced": traced,
        "lowered": lowered,
        "lowered_in_fit": lowered[before_fit:],
        "parameters": {k: float(v) for k, v in fit.model.parameters().items()},
    }))
    """
)


def _identify_in_child(cache: Path) -> dict:
    env = dict(os.environ, JAXHYST_CACHE_DIR=str(cache), JAX_PLATFORMS="cpu")
    done = subprocess.run(
        [sys.executable, "-c", _CHILD], env=env, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


def _stored_lowered(child: dict) -> list:
    return [
        name for name in child["lowered"] if str(name).startswith("jit(stored_program_")
    ]


def test_a_second_process_identifies_without_tracing_the_fit(tmp_path):
    cache = tmp_path / "cache"
    first = _identify_in_child(cache)
    stored = _files(cache / "programs")
    assert len(stored) >= 3  # the swarm, the polish, the identifiability at least
    # Each compiled here, so each executable kept beside its program.
    executables = _files(cache / "programs", "executable")
    assert [p.stem for p in executables] == [p.stem for p in stored]
    assert len(_stored_lowered(first)) == len(stored)
    # Traced under the export's jit ("stored_<name>"), which traces them inside it.
    heavy = {"stored__run_chunk", "stored__optimistix_loop", "stored__jacobian"}
    names = [name for name, _ in first["traced"]]
    assert heavy <= set(names), first["traced"]
    # Each once: the polish and the identifiability in the background thread that
    # prepares them during the swarm, and the calls after it reuse them.
    assert all(names.count(name) == 1 for name in heavy), first["traced"]
    threads = {name: thread for name, thread in first["traced"]}
    assert threads["stored__run_chunk"] == "MainThread"
    assert threads["stored__optimistix_loop"].startswith("jaxhyst-prepare")
    assert threads["stored__jacobian"].startswith("jaxhyst-prepare")
    second = _identify_in_child(cache)
    assert not heavy & {name for name, _ in second["traced"]}, second["traced"]
    # Not lowered either: the executables are loaded as they are. The polish and
    # the identifiability call jaxlib's LAPACK kernels, which loading sets up
    # (else this process would crash in the polish).
    assert _stored_lowered(second) == [], second["lowered"]
    # Nor any eager operation (a `jnp` call on host values, outside `jit`), each of
    # which lowers a small program in every process (the metrics are NumPy's).
    assert second["lowered_in_fit"] == [], second["lowered_in_fit"]
    assert _files(cache / "programs") == stored
    assert second["parameters"] == first["parameters"]


def test_stored_programs_are_not_written_to_jax_compilation_cache_too(tmp_path):
    # The store keeps their executables: a second copy in JAX's cache would be
    # compressed and written for nothing. Without its executables, a process
    # compiles the stored programs again and keeps them.
    cache = tmp_path / "cache"
    first = _identify_in_child(cache)
    in_jax_cache = [p.name for p in cache.glob("jit_stored_program_*")]
    assert in_jax_cache == [] and _files(cache / "programs", "executable")
    for path in _files(cache / "programs", "executable"):
        path.unlink()
    second = _identify_in_child(cache)
    assert len(_stored_lowered(second)) == len(_files(cache / "programs"))
    assert [p.stem for p in _files(cache / "programs", "executable")] == [
        p.stem for p in _files(cache / "programs")
    ]
    third = _identify_in_child(cache)
    assert _stored_lowered(third) == []
    assert first["parameters"] == second["parameters"] == third["parameters"]


def test_an_executable_read_back_from_jax_compilation_cache_is_not_kept(
    store, monkeypatch
):
    # XLA:CPU serializes an executable that JAX's compilation cache gave back
    # without its kernels: a process that loaded it would fail ("Function ... not
    # found"). So one that the cache served (an older jaxhyst wrote it there) is
    # not kept; the next process compiles it again.
    monkeypatch.setattr(_stored, "_memo", {})
    counts = iter([0, 1])
    monkeypatch.setattr(_program_store, "_compilation_cache_hits", lambda: next(counts))
    assert _stored(_model(), jnp.ones(3), 0.5)["y"] == 6.5
    assert _files(store) and _files(store, "executable") == []


def test_a_damaged_or_foreign_executable_is_compiled_again_and_replaced(store):
    x = jnp.ones(3)
    first = _stored(_model(), x, 0.5)["y"]
    (path,) = _files(store, "executable")
    good = path.read_bytes()
    _stored(_model(3), x, 0.5)
    other = next(p for p in _files(store, "executable") if p != path).read_bytes()
    for damaged in (good[: len(good) // 2], b"nonsense", other):
        path.write_bytes(damaged)
        _stored.__dict__["_memo"] = {}
        jax.clear_caches()
        traces["count"] = 0
        # Compiled from its program (not traced again), and written over.
        assert _result_and_compiles(lambda: _stored(_model(), x, 0.5)["y"]) == (
            first,
            1,
        )
        assert traces["count"] == 0
        assert path.read_bytes() != damaged
    # An executable compiled for another processor (or other XLA flags) is not
    # loaded: its key differs.
    _stored.__dict__["_memo"] = {}
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("XLA_FLAGS", "--xla_cpu_use_thunk_runtime=true")
        assert _result_and_compiles(lambda: _stored(_model(), x, 0.5)["y"]) == (
            first,
            1,
        )


def _result_and_compiles(call):
    """`call()`'s result, and how many stored programs it compiled."""
    compiled, listener = _compiled_programs()
    jax.monitoring.register_event_duration_secs_listener(listener)
    try:
        result = call()
    finally:
        jax.monitoring.unregister_event_duration_listener(listener)
    return result, _stored_compiles(compiled)


def test_committed_and_uncommitted_inputs_share_one_compiled_program(store):
    compiled = []

    def listener(event, duration, **kwargs):
        if event == "/jax/core/compile/backend_compile_duration":
            compiled.append(kwargs.get("fun_name"))

    jax.monitoring.register_event_duration_secs_listener(listener)
    try:
        x = jnp.ones(3)
        committed = jax.device_put(jnp.ones(3), jax.devices()[0])
        _stored(_model(), x, 0.5)
        _stored(_model(), committed, 0.5)
        _stored(_Scaled(jax.device_put(jnp.ones(3), jax.devices()[0]), 2), x, 0.5)
    finally:
        jax.monitoring.unregister_event_duration_listener(listener)
    assert _stored_compiles(compiled) == 1, compiled


def test_a_store_that_cannot_be_written_runs_the_program_all_the_same(store, tmp_path):
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    enable_program_store(blocker / "programs")  # cannot be created
    traces["count"] = 0
    out = _stored(_model(), jnp.ones(3), 0.5)
    assert float(out["y"]) == 6.5 and out["n"] == 2
    assert traces["count"] == 1


def _compiled_programs():
    compiled = []

    def listener(event, duration, **kwargs):
        if event == "/jax/core/compile/backend_compile_duration":
            compiled.append(kwargs.get("fun_name"))

    return compiled, listener


def test_prepare_compiles_without_running_and_a_later_call_reuses_it(store):
    compiled, listener = _compiled_programs()
    jax.monitoring.register_event_duration_secs_listener(listener)
    try:
        x = jnp.ones(3)
        assert _stored.prepare(_model(), x, 0.5) is None
        assert traces["count"] == 1 and len(_files(store)) == 1
        assert _stored_compiles(compiled) == 1
        out = _stored(_Scaled(jnp.array([3.0, 2.0, 1.0]), 2), 2 * x, 0.5)
    finally:
        jax.monitoring.unregister_event_duration_listener(listener)
    assert float(out["y"]) == 24.5 and out["n"] == 2
    assert traces["count"] == 1  # not traced again
    assert _stored_compiles(compiled) == 1  # nor compiled again


_gate = {"inside": threading.Event(), "release": threading.Event()}


def _slow(x):
    traces["count"] += 1
    _gate["inside"].set()
    _gate["release"].wait(timeout=30)
    return x * 2.0


def test_a_call_waits_for_the_thread_preparing_its_program(store, monkeypatch):
    monkeypatch.setitem(_gate, "inside", threading.Event())
    monkeypatch.setitem(_gate, "release", threading.Event())
    stored = stored_jit(_slow)
    x = jnp.ones(3)
    preparer = threading.Thread(target=stored.prepare, args=(x,))
    preparer.start()
    assert _gate["inside"].wait(timeout=30)  # the preparer is tracing
    results = []
    caller = threading.Thread(target=lambda: results.append(stored(x + 1.0)))
    caller.start()
    caller.join(timeout=0.5)
    assert caller.is_alive()  # waiting on the preparer, not tracing a second time
    _gate["release"].set()
    preparer.join(timeout=30)
    caller.join(timeout=30)
    np.testing.assert_array_equal(results[0], 2 * (x + 1.0))
    assert traces["count"] == 1
    assert len(_files(store)) == 1


def test_preparing_runs_in_the_background_and_raises_what_it_raised(store):
    ran = []
    with preparing(lambda: ran.append(threading.current_thread().name)):
        pass
    assert ran and ran[0].startswith("jaxhyst-prepare")

    def broken():
        raise KeyError("a bug in a preparation")

    with pytest.raises(KeyError, match="a bug in a preparation"):
        with preparing(broken):
            pass


def test_with_the_store_off_prepare_compiles_the_program_the_call_runs(monkeypatch):
    assert program_store() is None
    monkeypatch.setattr(  # this module's names pinned, as the `store` fixture does
        _program_store,
        "_PINNED_PACKAGES",
        (*_program_store._PINNED_PACKAGES, __name__.split(".")[0]),
    )
    compiled, listener = _compiled_programs()
    jax.monitoring.register_event_duration_secs_listener(listener)
    try:
        traces["count"] = 0
        x = jnp.ones(7)  # a shape no other test uses: nothing cached yet
        model = _Scaled(jnp.arange(7.0), 3)
        thread = threading.Thread(target=_stored.prepare, args=(model, x, 0.25))
        thread.start()
        thread.join()
        assert traces["count"] == 1 and compiled.count("jit(_body)") == 1
        out = _stored(model, 2 * x, 0.25)
    finally:
        jax.monitoring.unregister_event_duration_listener(listener)
    assert float(out["y"]) == pytest.approx(8 * 21 + 0.25)
    assert traces["count"] == 1 and compiled.count("jit(_body)") == 1


def test_preparing_does_nothing_when_jit_is_off():
    ran = []
    with jax.disable_jit():
        with preparing(lambda: ran.append(1)):
            pass
    assert ran == []


def test_identify_compiles_its_polish_during_the_swarm_with_the_store_off():
    """In-process, no cache: the polish's and the identifiability's programs are
    traced once each, in the preparing thread."""
    import jaxhyst as jh

    assert program_store() is None
    traced = []

    def listener(event, duration, **kwargs):
        if event == "/jax/core/compile/jaxpr_trace_duration":
            traced.append((kwargs.get("fun_name"), threading.current_thread().name))

    model = jh.PiezoBoucWen.paper_table4(3)
    path = jh.sample(jh.paper_u1(), 13.0)  # 131 samples: a length no other test uses
    y = np.asarray(jh.simulate(model, path, jh.RK4()))
    recording = jh.Recording(np.arange(path.num_samples) / 13.0, path.values, y)
    jax.monitoring.register_event_duration_secs_listener(listener)
    try:
        jh.identify(
            jh.PiezoBoucWen(1.0, 1.0, 1.0, 1.0, 1.0, 1.5),
            recording,
            key=jax.random.key(0),
            swarm=jh.MPSO(num_particles=8, num_iterations=10),
            throw=False,
        )
    finally:
        jax.monitoring.unregister_event_duration_listener(listener)
    for name in ("_optimistix_loop", "_jacobian"):
        threads = [thread for fun, thread in traced if fun == name]
        assert len(threads) == 1, traced
        assert threads[0].startswith("jaxhyst-prepare"), traced


def test_near_the_memory_map_limit_the_loaded_executables_are_let_go(
    store, monkeypatch
):
    from jaxhyst import _memory_maps

    if _memory_maps.memory_maps() is None:
        pytest.skip("this system does not report its memory maps (/proc)")
    x = jnp.ones(3)
    first = _stored(_model(), x, 0.5)["y"]
    assert _stored._memo  # the loaded executable, which jax.clear_caches keeps
    monkeypatch.setattr(_memory_maps, "RELEASE_AT", 0.0)
    with pytest.warns(RuntimeWarning, match=r"vm\.max_map_count"):
        assert _memory_maps.release_if_near_map_limit("diagnose")
    assert not _stored._memo
    traces["count"] = 0
    assert _stored(_model(), x, 0.5)["y"] == first  # loaded from the store again
    assert traces["count"] == 0


def _in_a_fresh_process():
    """Forget what this process loaded, as a new process starts."""
    _stored.__dict__["_memo"] = {}
    jax.clear_caches()
    traces["count"] = 0


def test_a_block_loads_ahead_what_the_last_block_begun_the_same_way_used(store):
    x = jnp.ones(3)
    with prefetching():
        first = [_stored(_model(p), x, 0.5)["y"] for p in (2, 3, 4)]
    (listed,) = (store / "prefetch").glob("*.list")
    _in_a_fresh_process()
    with prefetching():
        run = _program_store._prefetch
        assert run is not None
        again = [_stored(_model(2), x, 0.5)["y"]]
        assert run.thread is not None  # the first program started the thread
        run.thread.join()
        assert len(run.loaded) == 2  # the other two, loaded before being asked for
        again += [_stored(_model(p), x, 0.5)["y"] for p in (3, 4)]
        assert run.served == 2
    assert again == first
    assert traces["count"] == 0
    assert list((store / "prefetch").glob("*.list")) == [listed]
    # A block that begins with another program finds no list: nothing ahead.
    _in_a_fresh_process()
    with prefetching():
        run = _program_store._prefetch
        assert run is not None
        _stored(_model(3), x, 0.5)
        assert run.thread is None
        _stored(_model(2), x, 0.5)
    assert len(list((store / "prefetch").glob("*.list"))) == 2


def test_a_call_the_thread_has_not_reached_loads_its_own_and_the_thread_skips_it(
    store,
):
    x = jnp.ones(3)
    with prefetching():
        first = [_stored(_model(p), x, 0.5)["y"] for p in (2, 3, 4)]
    _in_a_fresh_process()
    with prefetching():
        run = _program_store._prefetch
        assert run is not None
        run.take(_stored._keyed((_model(4), x, 0.5), {}).digest)  # asked for first
        again = [_stored(_model(p), x, 0.5)["y"] for p in (2, 4, 3)]
        assert run.thread is not None
        run.thread.join()
        assert run.served <= 1  # only the third can have come from the thread
    assert again == [first[0], first[2], first[1]]


def test_a_damaged_list_or_executable_is_ignored_and_the_program_loaded_as_usual(
    store,
):
    x = jnp.ones(3)
    with prefetching():
        first = [_stored(_model(p), x, 0.5)["y"] for p in (2, 3)]
    (listed,) = (store / "prefetch").glob("*.list")
    listed.write_bytes(b"nonsense")
    _in_a_fresh_process()
    with prefetching():
        run = _program_store._prefetch
        assert run is not None
        assert [_stored(_model(p), x, 0.5)["y"] for p in (2, 3)] == first
        assert run.thread is None and run.served == 0
    # The list is written again; an executable damaged since is not served.
    executable = next(
        p
        for p in _files(store, "executable")
        if p.stem == _stored._keyed((_model(3), x, 0.5), {}).digest
    )
    executable.write_bytes(b"nonsense")
    _in_a_fresh_process()
    with prefetching():
        run = _program_store._prefetch
        assert run is not None
        y2, y3 = (_stored(_model(p), x, 0.5)["y"] for p in (2, 3))
        assert run.thread is not None and run.served == 0
    assert [y2, y3] == first
    assert traces["count"] == 0  # compiled from its program, not traced


def test_prefetching_is_off_without_the_store_and_not_nested(store):
    x = jnp.ones(3)
    enable_program_store(None)
    with prefetching():
        assert _program_store._prefetch is None
        _stored(_model(), x, 0.5)
    enable_program_store(store)
    with prefetching():
        outer = _program_store._prefetch
        with prefetching():
            assert _program_store._prefetch is outer
        _stored(_model(), x, 0.5)
    assert _program_store._prefetch is None
    assert not (store / "prefetch").exists()  # one program: nothing to load ahead


def test_the_command_line_runs_each_command_in_a_prefetching_block(
    store, tmp_path, monkeypatch
):
    from jaxhyst._cli import _main, _simulate

    blocks = []
    run = _simulate.run

    def watched(args):
        blocks.append(_program_store._prefetch)
        return run(args)

    monkeypatch.setattr(_simulate, "run", watched)
    assert _main.main(["simulate", "--out", str(tmp_path / "out")]) == 0
    assert len(blocks) == 1 and blocks[0] is not None
    assert _program_store._prefetch is None


def _watch_compiler_options(monkeypatch) -> list:
    """The `compiler_options` of every `jax.jit` made from now on (this test's)."""
    seen = []
    jit = jax.jit

    def watched(fun, *args, **kwargs):
        seen.append(kwargs.get("compiler_options"))
        return jit(fun, *args, **kwargs)

    monkeypatch.setattr(jax, "jit", watched)
    return seen


_ASKED = {**ELEMENTAL_EMITTERS, "xla_cpu_prefer_vector_width": 256}


@pytest.mark.parametrize("stored", [False, True])
def test_a_program_compiles_with_the_options_it_asks_for(stored, tmp_path, monkeypatch):
    monkeypatch.delenv("XLA_FLAGS", raising=False)
    own = stored_jit(_body, compiler_options=_ASKED)
    before = program_store()
    if stored:
        monkeypatch.setattr(
            _program_store,
            "_PINNED_PACKAGES",
            (*_program_store._PINNED_PACKAGES, __name__.split(".")[0]),
        )
        enable_program_store(tmp_path / "programs")
    seen = _watch_compiler_options(monkeypatch)
    try:
        out = own(_model(), jnp.ones(3), 0.5)
    finally:
        enable_program_store(before)
    assert out["y"] == 6.5
    assert _ASKED in seen
    if stored:  # the executable's key names them too
        (executable,) = _files(tmp_path / "programs", "executable")
        assert b"xla_cpu_use_fusion_emitters" in executable.read_bytes()


def test_the_polish_and_one_shot_programs_ask_for_the_elemental_emitters(
    monkeypatch,
):
    # Half the compile time of XLA:CPU's MLIR fusion emitters, and no slower to run
    # (benchmarks/HISTORY.md, session 34); the swarm's loop and the identifiability
    # Jacobian, whose code ran slower with them, ask for them only in a fit (the
    # options reach XLA: the test above).
    from jaxhyst._identification._identifiability import _jacobian
    from jaxhyst._identification._polish import _optimistix_loop
    from jaxhyst._identification._problem import model_at
    from jaxhyst._swarm import _run_chunk

    for program in (_optimistix_loop, model_at):
        assert program._compiler_options == ELEMENTAL_EMITTERS
    for program in (_run_chunk, _jacobian):
        assert "xla_cpu_use_fusion_emitters" not in program.usual._compiler_options
        assert ELEMENTAL_EMITTERS.items() <= program.one_shot._compiler_options.items()


_two_ways = stored_jit(_body, one_shot_options=_ASKED)


def _chosen(program) -> str:
    return "one-shot" if program._now() is program.one_shot else "usual"


def test_one_shot_options_apply_in_a_one_shot_block_outside_repeated_runs(
    monkeypatch,
):
    monkeypatch.delenv("XLA_FLAGS", raising=False)
    assert _chosen(_two_ways) == "usual"  # outside both: a benchmark's loop
    with _xla_options.one_shot():
        assert _chosen(_two_ways) == "one-shot"
        with _xla_options.repeated_runs():
            assert _chosen(_two_ways) == "usual"
    with _xla_options.repeated_runs(), _xla_options.one_shot():
        assert _chosen(_two_ways) == "usual"  # a diagnosis's fit
    assert _chosen(_two_ways) == "usual"
    assert _two_ways.one_shot._compiler_options == _ASKED
    assert _two_ways.usual._compiler_options == {}


def test_the_threads_of_a_block_run_in_its_mode():
    from jaxhyst._program_store import preparing
    from jaxhyst._threads import side_by_side

    seen = []
    with _xla_options.one_shot():
        with preparing(lambda: seen.append(_xla_options.in_one_shot())):
            pass
        with side_by_side(lambda _: _xla_options.in_one_shot(), range(4)) as each:
            seen.extend(each)
    # A thread started outside the block starts outside it.
    outside = []
    thread = threading.Thread(target=lambda: outside.append(_xla_options.in_one_shot()))
    with _xla_options.one_shot():
        thread.start()
        thread.join()
    assert seen == [True] * 5 and outside == [False]


def test_the_two_compilations_are_two_stored_programs(store, monkeypatch):
    monkeypatch.delenv("XLA_FLAGS", raising=False)
    monkeypatch.setattr(_two_ways.usual, "_memo", {})
    monkeypatch.setattr(_two_ways.one_shot, "_memo", {})
    seen = _watch_compiler_options(monkeypatch)
    usual = _two_ways(_model(), jnp.ones(3), 0.5)
    with _xla_options.one_shot():
        quick = _two_ways(_model(), jnp.ones(3), 0.5)
    assert usual["y"] == quick["y"] == 6.5
    assert {} in seen and _ASKED in seen
    # One key each: neither executable replaces the other.
    assert len(_files(store, "executable")) == 2


def test_xla_flags_deciding_the_one_shot_options_leave_one_program(monkeypatch):
    monkeypatch.setenv("XLA_FLAGS", "--xla_cpu_use_fusion_emitters=true")
    program = stored_jit(_body, one_shot_options=ELEMENTAL_EMITTERS)
    assert program.one_shot is program.usual


def test_inside_a_transformation_a_call_compiles_with_no_options_of_its_own():
    # XLA's options belong to the outermost jit: a nested one with options is an
    # error in JAX, so the stored function is traced into the caller's program.
    own = stored_jit(_body, compiler_options=_ASKED)
    outer = jax.jit(lambda x: own(_model(), x, 0.5)["y"])
    np.testing.assert_allclose(outer(jnp.ones(3)), 6.5)
    np.testing.assert_allclose(
        jax.vmap(lambda x: own(_model(), x, 0.5)["y"])(jnp.ones((2, 3))), [6.5, 6.5]
    )


def test_xla_flags_naming_an_optional_option_decide_it(monkeypatch):
    monkeypatch.setenv("XLA_FLAGS", "--xla_cpu_use_fusion_emitters=true")
    assert _xla_options.compiler_options(_ASKED) == {"xla_cpu_prefer_vector_width": 256}
    monkeypatch.setenv("XLA_FLAGS", "--xla_cpu_enable_fast_math=false")
    assert _xla_options.compiler_options(_ASKED) == _ASKED
    assert _xla_options.compiler_options(None) == {}


def test_an_optional_option_this_xla_does_not_know_is_left_out(monkeypatch):
    unknown = {"xla_cpu_no_such_option_in_any_xla": True}
    monkeypatch.setattr(_xla_options, "_OPTIONAL", frozenset(unknown))
    monkeypatch.delenv("XLA_FLAGS", raising=False)
    assert _xla_options.compiler_options(unknown) == unknown
    assert _xla_options.supported(unknown) == {}  # compiles without it
    # Not optional here: passed on as it is.
    assert _xla_options.supported(ELEMENTAL_EMITTERS) == ELEMENTAL_EMITTERS
    own = stored_jit(_body, compiler_options=unknown)
    assert own(_model(), jnp.ones(3), 0.5)["y"] == 6.5


def test_programs_calling_lapack_are_told_apart_from_their_serialized_module():
    # A loaded executable that calls LAPACK needs jaxlib's kernels set up first.
    from jax import export

    x = jnp.ones((4, 3))
    solving = export.export(jax.jit(lambda a: jnp.linalg.qr(a)[1]))(x)
    plain = export.export(jax.jit(lambda a: jnp.sin(a) @ a.T))(x)
    assert _program_store._uses_lapack(solving)
    assert not _program_store._uses_lapack(plain)
    # The same answer as reading the printed module.
    for exported in (solving, plain):
        printed = set(re.findall(r"custom_call @(\w+)", exported.mlir_module()))
        assert bool(printed & _program_store._LAPACK_TARGETS) == (
            _program_store._uses_lapack(exported)
        )
