"""Where one-trajectory work runs (`polish_device`, `diagnose(device=...)`)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import piezo_model

import jaxhyst as jh
from jaxhyst._placement import moved_to, serial_device


CPU = jax.devices("cpu")[0]
TEMPLATE = jh.PiezoBoucWen(1.0, 1.0, 1.0, 1.0, 1.0, 1.5)


def _recording(rate=50.0):
    path = jh.sample(jh.paper_u1(), rate)
    y = np.asarray(jh.simulate(piezo_model(), path))
    noise = 1e-3 * np.max(np.abs(y)) * np.random.default_rng(0).standard_normal(y.size)
    return jh.Recording(np.asarray(path.times), np.asarray(path.values), y + noise)


def test_serial_device_choice_and_errors():
    # With a CPU default device there is nothing to move; with an accelerator the
    # host CPU takes the one-trajectory work. An explicit device is kept.
    on_cpu = jax.devices()[0].platform == "cpu"
    assert serial_device(None) is (None if on_cpu else CPU)
    assert serial_device(CPU) is CPU
    with pytest.raises(TypeError, match="polish_device must be a jax.Device"):
        serial_device("cpu", "polish_device")  # type: ignore[arg-type]


def test_moved_to_copies_arrays_uncommitted_and_keeps_the_rest():
    committed = jax.device_put(jnp.arange(4.0), CPU)
    key = jax.random.key(7)
    tree = {"x": committed, "key": key, "name": "u1", "scale": 2.0, "none": None}
    moved = moved_to(tree, CPU)
    assert committed.committed and not moved["x"].committed
    np.testing.assert_array_equal(moved["x"], committed)
    assert jax.random.uniform(moved["key"]) == jax.random.uniform(key)
    assert (moved["name"], moved["scale"], moved["none"]) == ("u1", 2.0, None)
    assert moved_to(tree, None) is tree


def test_identify_on_an_explicit_polish_device_gives_the_same_fit():
    recording = _recording()
    start = piezo_model(beta1=0.7)
    options = dict(key=jax.random.key(0), swarm=None, start=start)
    here = jh.identify(TEMPLATE, recording, **options)
    moved = jh.identify(TEMPLATE, recording, polish_device=CPU, **options)
    assert moved.metrics == here.metrics
    np.testing.assert_array_equal(moved.predicted, here.predicted)
    with pytest.raises(TypeError, match="polish_device"):
        jh.identify(TEMPLATE, recording, polish_device="cpu", **options)  # type: ignore[arg-type]


def test_diagnose_rejects_a_device_that_is_not_one():
    recording = _recording(rate=50.0)
    with pytest.raises(TypeError, match="device must be a jax.Device"):
        jh.diagnose(recording, key=jax.random.key(0), device="gpu")  # type: ignore[arg-type]
