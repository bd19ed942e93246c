import os
import subprocess
import sys
import textwrap
import threading

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest
from helpers import lowered_while

from jaxhyst._status import RESULTS, status_name
from jaxhyst._swarm import MPSO, SwarmState, run_swarm


# Objectives are module-level so that tests share compilations.
def sphere(x, args):
    return jnp.sum((x - 0.3) ** 2)


def shifted_sphere(x, centre):
    return jnp.sum((x - centre) ** 2)


def rosenbrock(x, args):
    return jnp.sum(100.0 * (x[1:] - x[:-1] ** 2) ** 2 + (1.0 - x[:-1]) ** 2)


def half_nan(x, args):
    # Optimum at x = 0.5 lies in the region x[0] > 0, where the objective is NaN
    # (or +inf / -inf on parts of it): the swarm must settle on x[0] <= 0.
    value = jnp.sum((x - 0.5) ** 2)
    bad = jnp.where(x[1] > 0.5, jnp.inf, jnp.where(x[1] < -0.5, -jnp.inf, jnp.nan))
    return jnp.where(x[0] > 0, bad, value)


def constant(x, args):
    return jnp.asarray(1.0)


def always_inf(x, args):
    return jnp.inf + jnp.sum(x)


def always_nan(x, args):
    return jnp.nan + jnp.sum(x)


UNIT = (-jnp.ones(3), jnp.ones(3))
SMALL = MPSO(num_particles=16, num_iterations=60)


# ---------------------------------------------------------------- settings


def test_defaults_and_paper_cases():
    swarm = MPSO()
    assert swarm.num_particles == 64 and swarm.num_iterations == 500
    assert float(swarm.velocity_limit) == 0.2
    expected = {1: (50, 500), 2: (100, 1500), 3: (300, 5000), 4: (500, 10000)}
    for case, (size, iterations) in expected.items():
        swarm = MPSO.paper_case(case)
        assert (swarm.num_particles, swarm.num_iterations) == (size, iterations)
        assert float(swarm.c1) == 1.3 and float(swarm.c2) == 1.7
        assert float(swarm.w_max) == 0.9 and float(swarm.w_min) == 0.1
        assert float(swarm.velocity_limit) == 1.0
    assert float(MPSO.paper_case(3, velocity_limit=0.2).velocity_limit) == 0.2
    with pytest.raises(ValueError, match="Table 3"):
        MPSO.paper_case(5)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(num_particles=1), "num_particles"),
        (dict(num_particles=10.0), "num_particles"),
        (dict(num_iterations=0), "num_iterations"),
        (dict(c1=-1.0), "c1"),
        (dict(c2=float("nan")), "c2"),
        (dict(w_min=0.95), "w_min <= w_max"),
        (dict(velocity_limit=0.0), "velocity_limit"),
        (dict(velocity_limit=np.ones((2, 2))), "velocity_limit"),
    ],
)
def test_check_init(kwargs, match):
    with pytest.raises(ValueError, match=match):
        MPSO(**kwargs)


def test_input_validation():
    key = jr.key(0)
    with pytest.raises(ValueError, match="lower < upper"):
        SMALL.init(sphere, jnp.zeros(2), jnp.array([1.0, 0.0]), key)
    with pytest.raises(ValueError, match="same non-zero length"):
        SMALL.init(sphere, jnp.zeros(2), jnp.ones(3), key)
    with pytest.raises(ValueError, match="3 entries"):
        MPSO(velocity_limit=jnp.ones(3)).init(sphere, jnp.zeros(2), jnp.ones(2), key)
    with pytest.raises(ValueError, match="scalar"):
        SMALL.init(lambda x, args: x, jnp.zeros(2), jnp.ones(2), key)


# ---------------------------------------------------------------- one step


def test_bounds_and_velocity_clamp_every_iteration():
    # The optimum (2, -2, 0.5) lies outside the box in two dimensions, so particles
    # press against the walls all the time.
    lower, upper = jnp.array([-1.0, -1.0, -1.0]), jnp.array([1.0, 1.0, 1.0])
    vlim = jnp.array([0.05, 0.3, 0.1])
    centre = jnp.array([2.0, -2.0, 0.5])
    swarm = MPSO(num_particles=12, num_iterations=40, velocity_limit=vlim)
    step = eqx.filter_jit(swarm.step)
    key_init, key = jr.split(jr.key(1))
    state = swarm.init(shifted_sphere, lower, upper, key_init, centre)
    assert np.all(np.abs(np.asarray(state.velocities)) <= np.asarray(vlim))
    hit_wall = False
    for k in range(swarm.num_iterations):
        previous = state
        state = step(shifted_sphere, state, jr.fold_in(key, k), centre)
        x, v = np.asarray(state.positions), np.asarray(state.velocities)
        assert int(state.iteration) == k + 1
        assert np.all(x >= np.asarray(lower)) and np.all(x <= np.asarray(upper))
        assert np.all(np.abs(v) <= np.asarray(vlim))
        # Absorbing walls: no velocity component points out of the box at a wall.
        assert not np.any((x == np.asarray(upper)) & (v > 0))
        assert not np.any((x == np.asarray(lower)) & (v < 0))
        hit_wall |= bool(np.any((x == 1.0) & (v == 0)))
        # Eq. 11: personal bests never get worse, gbest is the best of them.
        assert np.all(state.pbest_fitness <= previous.pbest_fitness)
        assert float(state.gbest_fitness) == float(np.min(state.pbest_fitness))
        np.testing.assert_allclose(
            state.fitness,
            jax.vmap(shifted_sphere, (0, None))(state.positions, centre),
            rtol=1e-14,
        )
    assert hit_wall
    np.testing.assert_allclose(state.gbest[:2], [1.0, -1.0], atol=1e-6)


def test_inertia_weight_schedule_eq13():
    swarm = MPSO(num_particles=4, num_iterations=50, w_max=0.8, w_min=0.2)
    for k in [0, 1, 10, 25, 49, 50, 80]:
        expected = 0.8 - min(k / 50, 1.0) * (0.8 - 0.2)
        assert float(swarm.inertia_weight(k)) == pytest.approx(expected, abs=1e-15)

    # With c1 = c2 = 0 and loose limits the step is v <- w(k) v exactly.
    swarm = eqx.tree_at(lambda s: (s.c1, s.c2), swarm, (jnp.zeros(()), jnp.zeros(())))
    swarm = eqx.tree_at(lambda s: s.velocity_limit, swarm, jnp.asarray(1.0))
    state = swarm.init(sphere, -100 * jnp.ones(2), 100 * jnp.ones(2), jr.key(2))
    for k in [0, 7, 30, 49]:
        at_k = eqx.tree_at(lambda s: s.iteration, state, jnp.asarray(k, jnp.int32))
        new = swarm.step(sphere, at_k, jr.key(3))
        w = 0.8 - (k / 50) * 0.6
        np.testing.assert_allclose(new.velocities, w * state.velocities, rtol=1e-14)
        np.testing.assert_allclose(
            new.positions, state.positions + new.velocities, rtol=1e-14
        )


# ---------------------------------------------------------------- driver


def test_determinism_and_chunk_size_independence():
    key = jr.key(42)
    results = [run_swarm(rosenbrock, *UNIT, SMALL, key, chunk_size=c) for c in (100, 7)]
    for other in results[1:]:
        np.testing.assert_array_equal(other.history, results[0].history)
        np.testing.assert_array_equal(other.best_x, results[0].best_x)
        np.testing.assert_array_equal(other.state.pbest, results[0].state.pbest)
    first = results[0]
    assert first.iterations_run == SMALL.num_iterations
    assert first.stop_reason == "max_iterations"
    # A fixed schedule (no target, no stall rule) run to its end is a success.
    assert status_name(first.result) == "successful"
    assert bool(first.result == RESULTS.successful)
    assert first.history.shape == (SMALL.num_iterations + 1,)
    assert np.all(np.diff(first.history) <= 0)
    assert first.best_fitness == first.history[-1]
    assert first.evaluations == SMALL.num_particles * (SMALL.num_iterations + 1)
    assert first.wall_seconds >= first.compile_seconds >= 0
    different = run_swarm(rosenbrock, *UNIT, SMALL, jr.key(43))
    assert not np.array_equal(different.history, first.history)


def test_nonfinite_regions_never_win():
    swarm = MPSO(num_particles=24, num_iterations=120)
    lower, upper = -jnp.ones(2), jnp.ones(2)
    result = run_swarm(half_nan, lower, upper, swarm, jr.key(5))
    assert np.all(np.isfinite(result.history))
    assert float(result.best_x[0]) <= 0
    assert float(half_nan(result.best_x, None)) == result.best_fitness
    # The best feasible point is (0, 0.5).
    np.testing.assert_allclose(result.best_x, [0.0, 0.5], atol=1e-4)
    state = result.state
    assert not np.any(np.isnan(state.fitness)) and not np.any(
        np.isnan(state.pbest_fitness)
    )
    bad = np.asarray(state.positions[:, 0]) > 0
    assert np.all(np.isposinf(np.asarray(state.fitness)[bad]))
    # A personal best is a point where the objective was finite (a particle that
    # never found one keeps its start, with fitness +inf).
    found = np.isfinite(np.asarray(state.pbest_fitness))
    assert found.sum() >= 20
    assert np.all(np.asarray(state.pbest[found, 0]) <= 0)


@pytest.mark.parametrize("objective", [always_inf, always_nan])
def test_all_nonfinite_gives_inf_and_status_nonfinite(objective):
    swarm = MPSO(num_particles=4, num_iterations=3)
    result = run_swarm(objective, *UNIT, swarm, jr.key(0), throw=False)
    assert result.best_fitness == np.inf
    assert np.all(np.isposinf(result.history))
    assert result.stop_reason == "max_iterations"
    assert status_name(result.result) == "nonfinite"
    # Non-finite wins over a stall that was met (the fitness never improved).
    stalled = run_swarm(
        objective, *UNIT, swarm, jr.key(0), stall_iterations=2, throw=False
    )
    assert stalled.stop_reason == "stall"
    assert status_name(stalled.result) == "nonfinite"
    with pytest.raises(RuntimeError, match="run_swarm: nonfinite: .*throw=False"):
        run_swarm(objective, *UNIT, swarm, jr.key(0))


@pytest.mark.parametrize("d", [2, 6])
def test_converges_on_sphere(d):
    swarm = MPSO(num_particles=32, num_iterations=300)
    result = run_swarm(sphere, -jnp.ones(d), jnp.ones(d), swarm, jr.key(d))
    assert result.best_fitness < 1e-10
    np.testing.assert_allclose(result.best_x, 0.3 * np.ones(d), atol=1e-5)


def test_converges_on_rosenbrock():
    swarm = MPSO(num_particles=48, num_iterations=1500, velocity_limit=0.5)
    result = run_swarm(rosenbrock, -2 * jnp.ones(3), 2 * jnp.ones(3), swarm, jr.key(0))
    assert result.best_fitness < 1e-4
    np.testing.assert_allclose(result.best_x, np.ones(3), atol=0.05)


def test_coefficients_do_not_retrace():
    traces = []

    def counted(x, args):
        traces.append(None)
        return jnp.sum((x - args) ** 2)

    centre = jnp.full(3, 0.1)
    base = MPSO(num_particles=8, num_iterations=20)
    run_swarm(counted, *UNIT, base, jr.key(0), args=centre, chunk_size=10)
    count = len(traces)
    assert count > 0
    variants = [
        MPSO(num_particles=8, num_iterations=20, c1=2.0, c2=0.5),
        MPSO(num_particles=8, num_iterations=20, w_max=0.7, w_min=0.3),
        MPSO(num_particles=8, num_iterations=20, velocity_limit=0.05),
    ]
    for swarm in variants:
        run_swarm(counted, *UNIT, swarm, jr.key(1), args=2 * centre, chunk_size=10)
    # throw=False: whether these early-stopping rules are met is beside the point.
    run_swarm(
        counted,
        *UNIT,
        base,
        jr.key(0),
        args=centre,
        chunk_size=10,
        target=0.5,
        throw=False,
    )
    run_swarm(
        counted,
        *UNIT,
        base,
        jr.key(0),
        args=centre,
        chunk_size=10,
        stall_iterations=3,
        throw=False,
    )
    assert len(traces) == count


def test_chunk_function_traces_once():
    # The jitted chunk function itself is traced once for differing coefficients.
    from jaxhyst import _swarm

    original = _swarm._run_chunk
    wrapped = eqx.filter_jit(
        eqx.debug.assert_max_traces(original.__wrapped__, max_traces=1)
    )
    _swarm._run_chunk = wrapped
    try:
        for c1 in (0.5, 1.0, 2.0):
            swarm = MPSO(num_particles=8, num_iterations=10, c1=c1, w_min=c1 / 10)
            run_swarm(sphere, *UNIT, swarm, jr.key(0), chunk_size=5)
    finally:
        _swarm._run_chunk = original


TARGET_SWARM = MPSO(num_particles=16, num_iterations=400)


def test_early_stop_on_target():
    swarm = TARGET_SWARM
    runs = [
        run_swarm(sphere, *UNIT, swarm, jr.key(7), target=1e-8, chunk_size=c)
        for c in (10, 3)
    ]
    result = runs[0]
    assert result.stop_reason == "target"
    assert status_name(result.result) == "successful"
    assert result.best_fitness <= 1e-8 < result.history[-2]
    assert result.iterations_run < swarm.num_iterations
    assert len(result.history) == result.iterations_run + 1
    assert result.evaluations == swarm.num_particles * (result.iterations_run + 1)
    # Where the run stops does not depend on the chunk size.
    assert runs[1].iterations_run == result.iterations_run
    np.testing.assert_array_equal(runs[1].best_x, result.best_x)
    # A target met by the initial swarm stops before any iteration.
    early = run_swarm(sphere, *UNIT, swarm, jr.key(7), target=10.0)
    assert early.stop_reason == "target" and early.iterations_run == 0
    assert status_name(early.result) == "successful"


def test_early_stop_on_stall():
    swarm = TARGET_SWARM
    result = run_swarm(
        constant, *UNIT, swarm, jr.key(0), stall_iterations=25, chunk_size=10
    )
    assert result.stop_reason == "stall"
    assert status_name(result.result) == "successful"
    assert result.iterations_run == 25
    np.testing.assert_array_equal(result.history, np.ones(26))
    # A stall on the last iteration of the schedule is still a stall, a success.
    last = run_swarm(
        constant,
        *UNIT,
        MPSO(num_particles=16, num_iterations=25),
        jr.key(0),
        stall_iterations=25,
        chunk_size=10,
    )
    assert last.stop_reason == "stall" and last.iterations_run == 25
    assert status_name(last.result) == "successful"
    # On a converging problem a huge stall tolerance stops it early, too.
    loose = run_swarm(
        sphere,
        *UNIT,
        swarm,
        jr.key(0),
        stall_iterations=5,
        stall_tolerance=1e3,
        chunk_size=10,
    )
    assert loose.stop_reason == "stall" and loose.iterations_run == 5
    assert status_name(loose.result) == "successful"


@pytest.mark.parametrize(
    "rule",
    [
        dict(target=1e-30),
        dict(stall_iterations=1000),
        dict(target=1e-30, stall_iterations=1000),
    ],
    ids=["target", "stall", "both"],
)
def test_early_stopping_not_met_is_max_steps_reached(rule):
    # 10 iterations cannot reach 1e-30 on the sphere nor stall for 1000.
    swarm = MPSO(num_particles=16, num_iterations=10)
    result = run_swarm(sphere, *UNIT, swarm, jr.key(0), throw=False, **rule)
    assert result.stop_reason == "max_iterations"
    assert result.iterations_run == swarm.num_iterations
    assert np.isfinite(result.best_fitness)
    assert status_name(result.result) == "max_steps_reached"
    assert bool(result.result == RESULTS.max_steps_reached)
    with pytest.raises(
        RuntimeError, match="run_swarm: max_steps_reached: .*num_iterations"
    ) as info:
        run_swarm(sphere, *UNIT, swarm, jr.key(0), **rule)
    # The message ends with the fix.
    assert str(info.value).endswith("pass throw=False to keep the best point found.")


def test_throw_only_on_failure():
    # throw=True (the default) returns a successful result unchanged.
    swarm = MPSO(num_particles=16, num_iterations=10)
    thrown = run_swarm(sphere, *UNIT, swarm, jr.key(0), target=10.0)
    kept = run_swarm(sphere, *UNIT, swarm, jr.key(0), target=10.0, throw=False)
    assert status_name(thrown.result) == status_name(kept.result) == "successful"
    np.testing.assert_array_equal(thrown.history, kept.history)


def test_progress_bar(capsys):
    result = run_swarm(
        sphere,
        *UNIT,
        TARGET_SWARM,
        jr.key(0),
        target=1e-8,
        chunk_size=10,
        progress=True,
    )
    err = capsys.readouterr().err
    # The first chunk starts with the initial evaluation: one line per chunk.
    chunks = -(-(result.iterations_run + 1) // 10)
    assert err.count("\r") == chunks
    assert f"{result.iterations_run}/400" in err and "best" in err
    assert err.endswith("\n")


def test_state_is_a_module():
    state = SMALL.init(sphere, *UNIT, jr.key(0))
    assert isinstance(state, SwarmState)
    assert state.positions.shape == state.pbest.shape == (16, 3)
    assert state.fitness.shape == (16,) and int(state.iteration) == 0
    assert np.all(np.abs(np.asarray(state.velocities)) <= 0.2)
    np.testing.assert_array_equal(state.pbest, state.positions)


def test_explicit_single_device_mesh():
    # sharding="auto" with an explicit device list builds a one-device mesh.
    plain = run_swarm(rosenbrock, *UNIT, SMALL, jr.key(9), sharding=None)
    meshed = run_swarm(rosenbrock, *UNIT, SMALL, jr.key(9), devices=jax.devices()[:1])
    np.testing.assert_array_equal(plain.history, meshed.history)
    with pytest.raises(ValueError, match="devices"):
        run_swarm(rosenbrock, *UNIT, SMALL, jr.key(9), sharding=None, devices=[])


_SHARDED_SCRIPT = textwrap.dedent(
    """
    import jax, jax.numpy as jnp, jax.random as jr, numpy as np
    from jaxhyst._swarm import MPSO, run_swarm

    assert len(jax.devices()) == 2, jax.devices()

    def rosenbrock(x, args):
        return jnp.sum(100.0 * (x[1:] - x[:-1] ** 2) ** 2 + (1.0 - x[:-1]) ** 2)

    lower, upper = -2 * jnp.ones(4), 2 * jnp.ones(4)
    for n in (16, 15):  # 15: padded with one inert dummy particle
        swarm = MPSO(num_particles=n, num_iterations=60, velocity_limit=0.5)
        one = run_swarm(rosenbrock, lower, upper, swarm, jr.key(3), sharding=None)
        two = run_swarm(rosenbrock, lower, upper, swarm, jr.key(3), chunk_size=25)
        assert abs(one.best_fitness - two.best_fitness) <= 1e-12
        np.testing.assert_allclose(one.history, two.history, rtol=0, atol=1e-12)
        np.testing.assert_allclose(one.best_x, two.best_x, rtol=0, atol=1e-12)
        assert two.state.positions.shape == (n, 4)
        assert len(one.state.positions.sharding.device_set) == 1
        if n == 16:
            sharding = two.state.positions.sharding
            assert len(sharding.device_set) == 2, sharding
            assert sharding.spec[0] == "particles", sharding
            shards = two.state.positions.addressable_shards
            assert [s.data.shape for s in shards] == [(8, 4), (8, 4)]
    print("SHARDED-OK")
    """
)


def test_two_devices_match_single_device():
    env = dict(os.environ)
    env["XLA_FLAGS"] = "--xla_force_host_platform_device_count=2"
    env["JAX_ENABLE_X64"] = "1"
    env["JAX_PLATFORMS"] = "cpu"
    completed = subprocess.run(
        [sys.executable, "-c", _SHARDED_SCRIPT],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert completed.returncode == 0, completed.stderr[-4000:]
    assert "SHARDED-OK" in completed.stdout


def test_the_compile_timer_counts_only_its_own_thread():
    from jaxhyst._swarm import _CompileTimer

    def compile_elsewhere():
        jax.jit(lambda x: jnp.sin(x) * 3.0 + 1.25).lower(jnp.ones(11)).compile()

    with _CompileTimer() as timer:
        other = threading.Thread(target=compile_elsewhere)
        other.start()
        other.join()
    assert timer.seconds == 0.0
    with _CompileTimer() as timer:
        jax.jit(lambda x: jnp.cos(x) * 3.0 - 1.25).lower(jnp.ones(11)).compile()
    assert timer.seconds > 0.0


def test_has_status_reads_a_result_on_the_host_without_compiling():
    from jaxhyst._status import has_status

    members = list(RESULTS._name_to_item.values())
    table, lowered = lowered_while(
        lambda: [[has_status(a, b) for b in members] for a in members]
    )
    assert lowered == []
    assert table == [[bool(a == b) for b in members] for a in members]
    assert any(not x for row in table for x in row)


def test_a_run_is_init_then_steps_with_the_halves_of_its_key():
    # The first chunk draws the initial positions itself (no program of its own):
    # from the first half of the key, the iterations from the second.
    swarm = MPSO(num_particles=10, num_iterations=6)
    key = jr.key(5)
    result = run_swarm(sphere, *UNIT, swarm, key, chunk_size=4)
    with jax.threefry_partitionable(False):
        key_init, key_loop = jr.split(key)
        state = swarm.init(sphere, *UNIT, key_init)
        for k in range(swarm.num_iterations):
            state = swarm.step(sphere, state, jr.fold_in(key_loop, k))
    np.testing.assert_allclose(result.state.positions, state.positions, rtol=1e-12)
    np.testing.assert_allclose(result.state.pbest, state.pbest, rtol=1e-12)


def test_a_run_compiles_its_loop_and_nothing_else():
    lower, upper = jax.block_until_ready((jnp.zeros(3), jnp.ones(3)))
    swarm = MPSO(num_particles=9, num_iterations=3)
    key = jax.block_until_ready(jr.key(0))
    _, lowered = lowered_while(lambda: run_swarm(sphere, lower, upper, swarm, key))
    assert lowered == ["jit(_run_chunk)"], lowered
