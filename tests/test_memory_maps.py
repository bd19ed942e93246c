"""The guard against Linux's per-process memory-map limit (`_memory_maps`)."""

import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxhyst as jh
from jaxhyst import _memory_maps


def _linux_counts():
    counts = _memory_maps.memory_maps()
    if counts is None:
        pytest.skip("this system does not report its memory maps (/proc)")
    return counts


def _compile_fresh_programs(count: int) -> None:
    # New functions on new shapes: each call compiles a program of its own.
    for size in range(3, 3 + count):
        jax.jit(lambda x, c=size: jnp.sin(x) * c + jnp.cumsum(x))(jnp.ones(size))


def test_the_maps_are_counted_against_the_kernel_s_limit():
    used, limit = _linux_counts()
    assert 0 < used < limit
    _compile_fresh_programs(5)
    assert _memory_maps.memory_maps()[0] > used  # pyright: ignore[reportOptionalSubscript]


def test_near_the_limit_the_caches_are_cleared_with_a_warning(monkeypatch):
    _linux_counts()
    _compile_fresh_programs(20)
    before = _memory_maps.memory_maps()[0]  # pyright: ignore[reportOptionalSubscript]
    monkeypatch.setattr(_memory_maps, "RELEASE_AT", 0.0)
    with pytest.warns(RuntimeWarning, match=r"vm\.max_map_count") as record:
        assert _memory_maps.release_if_near_map_limit("diagnose")
    assert "diagnose: this process held" in str(record[0].message)
    # The compiled programs were freed, and jitted code still runs (recompiled).
    assert _memory_maps.memory_maps()[0] < before  # pyright: ignore[reportOptionalSubscript]
    np.testing.assert_allclose(jax.jit(jnp.cos)(jnp.zeros(2)), [1.0, 1.0])


def test_far_from_the_limit_nothing_is_cleared(monkeypatch):
    _linux_counts()
    monkeypatch.setattr(_memory_maps, "RELEASE_AT", 1.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert not _memory_maps.release_if_near_map_limit("identify")


def test_a_system_without_proc_is_left_alone(monkeypatch):
    monkeypatch.setattr(_memory_maps, "_LIMIT", "/nonexistent/max_map_count")
    monkeypatch.setattr(_memory_maps, "RELEASE_AT", 0.0)
    assert _memory_maps.memory_maps() is None
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert not _memory_maps.release_if_near_map_limit("identify")


def test_identify_checks_the_limit_before_it_compiles(monkeypatch):
    _linux_counts()
    monkeypatch.setattr(_memory_maps, "RELEASE_AT", 0.0)
    t = np.linspace(0.0, 1.0, 101)
    u = np.sin(2 * np.pi * t)
    recording = jh.Recording(t, u, u, name="sine")
    model = jh.BoucWen(1.0, 0.5, 1.0, 1.0, 1.0, 1.0, 1.5)
    with pytest.warns(RuntimeWarning, match=r"^identify: this process held"):
        jh.identify(
            model,
            recording,
            key=jax.random.key(0),
            swarm=None,
            polish=None,
            start=model,
            analyse=False,
        )
