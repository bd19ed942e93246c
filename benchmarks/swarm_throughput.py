"""Swarm evaluation throughput: jaxhyst's MPSO against NumPy, PySwarms and evosax.

Every method minimises the same objective -- the RMSE between the paper's piezo model
(`PiezoBoucWen.paper_table4(3)`) simulated with classical RK4 under the paper's input
u1 = 2 - 2 cos(0.2 pi t) and that model's own output -- over the same 5-dimensional unit
box (`ParameterSpace.default(..., gauge=True)`), with the same number of particles and
the same number of samples (stride 1). The figure of merit is

    particle-steps/s = evaluations * (N - 1) / seconds

where `evaluations` counts every particle evaluation actually performed (MPSO and evosax
evaluate the initial swarm once more than they iterate, so `evaluations = particles *
(iterations + 1)`; PySwarms evaluates once per iteration) and `N - 1` is the number of
RK4 steps of one simulation. `s/iter` is seconds per swarm evaluation (one iteration).

Device modes (XLA's CPU backend; the script never imports JAX in the parent process):

- phase "forced": `XLA_FLAGS=--xla_force_host_platform_device_count=<cpu count>` is set
  before JAX is imported, so every core is a separate JAX device. jaxhyst runs with
  `sharding=None` (all particles on device 0) and `sharding="auto"` (particles split
  across all devices). With the flag set, XLA no longer spreads one device's work over
  the cores: `sharding=None` then uses ONE core (see the cpu% column).
- phase "native": no flag, one CPU device. XLA:CPU does multithread within that device
  (cpu% ~ 200 % on 2 cores), so this is also an "all cores" mode. The JAX baselines
  (evosax) run here, where they get every core; NumPy and PySwarms are single-threaded
  whatever the phase.

Timing follows the house style: a first call (compilation included) is timed apart from
the steady state, JAX results are blocked on (`run_swarm` returns host values,
evosax states are `block_until_ready`-ed), and min / median of `--repeats` repeats are
reported; compile time is what `jax.monitoring` reports for tracing + lowering +
compiling. NumPy and PySwarms are much slower, so they run `--baseline-iterations`
iterations (per-particle-step normalisation makes the numbers comparable).

Run `python benchmarks/swarm_throughput.py` (or `--quick`); `--json PATH` saves results.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

import _common as common


DURATION = 10.0  # seconds: one period of the paper's u1


# --------------------------------------------------------------------------- options


WIDE_VECTORS = "--xla_cpu_prefer_vector_width=512"


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[50, 100, 300, 500])
    parser.add_argument(
        "--samples",
        type=int,
        default=10000,
        help="RK4 steps per simulation, N - 1 (u1 sampled at samples/10 s; 10000 -> "
        "1 kHz, N = 10001 samples as in the paper)",
    )
    parser.add_argument("--iterations", type=int, default=5)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument(
        "--dtype",
        nargs="+",
        default=["float64", "float32"],
        choices=["float64", "float32"],
    )
    parser.add_argument(
        "--baseline-iterations",
        type=int,
        default=2,
        help="iterations for the NumPy MPSO and PySwarms baselines",
    )
    common.add_subset(parser, "--methods", ["jaxhyst", "numpy", "pyswarms", "evosax"])
    common.add_subset(
        parser,
        "--phases",
        ["forced", "native", "wide"],
        help="wide = forced plus XLA_FLAGS=--xla_cpu_prefer_vector_width=512 (AVX-512 "
        "CPUs: XLA then vectorises 16 float32 / 8 float64 lanes); jaxhyst and evosax "
        "run in it",
    )
    parser.add_argument(
        "--llvm-interleave",
        type=int,
        default=0,
        metavar="K",
        help="wide phase only: also pass --xla_backend_extra_options="
        "-force-vector-interleave=K to LLVM (two independent vector chains per loop "
        "iteration; K = 2 sped up one RK4 step per sample 1.2-1.5x and slowed the "
        "31-sample objective here); 0 = LLVM's choice",
    )
    parser.add_argument(
        "--host-devices",
        type=int,
        default=os.cpu_count() or 1,
        help="device count forced in the 'forced' phase (default: os.cpu_count())",
    )
    parser.add_argument(
        "--quick",
        action="store_true",
        help="smoke-test settings: sizes 100, 2000 samples, 2 iterations, 2 repeats, "
        "1 baseline iteration",
    )
    parser.add_argument(
        "--wait-idle",
        type=float,
        default=0.0,
        metavar="SECONDS",
        help="before each measurement wait up to SECONDS for the machine to be idle "
        "(other processes < 0.15 cores): for shared machines",
    )
    common.add_json(parser)
    parser.add_argument(
        "--from-json", metavar="PATH", help="print the table of a saved --json result"
    )
    parser.add_argument(
        "--phase", choices=["forced", "native", "wide"], help=argparse.SUPPRESS
    )
    parser.add_argument("--phase-out", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.quick:
        args.sizes, args.samples, args.iterations = [100], 2000, 2
        args.repeats, args.baseline_iterations = 2, 1
    return args


# --------------------------------------------------------------------------- the problem


class Bench:
    """The shared objective in both worlds: a jaxhyst `Problem` and NumPy arrays."""

    def __init__(self, samples, dtype_name):
        import jax.numpy as jnp
        import numpy as np

        import jaxhyst as jh
        from jaxhyst._identification._problem import swarm_problem as _swarm_problem

        self.dtype_name = dtype_name
        self.np_dtype = np.dtype(dtype_name)
        model = jh.PiezoBoucWen.paper_table4(3)
        path64 = jh.sample(jh.paper_u1(), samples / DURATION)
        y64 = jh.simulate(model, path64, jh.RK4())
        record = jh.Recording(
            np.asarray(path64.times), np.asarray(path64.values), np.asarray(y64)
        )
        space = jh.ParameterSpace.default(model, record, gauge=True)
        dtype = jnp.dtype(dtype_name)
        # float32 runs: the input path (and so the simulation) and the swarm in float32.
        path = jh.InputPath(path64.t0, path64.dt, path64.values.astype(dtype))
        measured = y64.astype(dtype)
        self.problem = jh.identification.Problem(space, path, measured, jh.RK4())
        # The objective `identify`'s swarm runs: RK4 steps spanning several samples,
        # every sample still simulated (dense output) and compared.
        self.samples_per_step = jh.identification.swarm_samples_per_step(
            np.asarray(path.values)
        )
        self.swarm_problem = _swarm_problem(self.problem, self.samples_per_step)
        self.num_samples = path.num_samples
        self.dimension = space.dimension
        self.lower = jnp.zeros(space.dimension, dtype)
        self.upper = jnp.ones(space.dimension, dtype)
        # NumPy copies (the gauge fixes A1; the free names are k1, k2, beta1, gamma1, n).
        self.names = space.names
        self.np_lower = np.asarray(space.lower, self.np_dtype)
        self.np_upper = np.asarray(space.upper, self.np_dtype)
        self.np_floor = np.asarray(space.floor, self.np_dtype)
        self.np_A1 = self.np_dtype.type(float(space.template.A1))
        self.np_u = np.asarray(path.values)
        self.np_y = np.asarray(measured)
        self.np_dt = self.np_dtype.type(float(path.dt))
        self.plain_data = (
            jnp.asarray(self.np_lower),
            jnp.asarray(self.np_upper),
            jnp.asarray(self.np_floor),
            jnp.asarray(self.np_A1),
            path.values,
            measured,
            path.dt,
        )


def jaxhyst_objective(z, problem):
    return problem.rmse(z)


def plain_jax_loss(z, data):
    """A hand-written JAX objective (what a user would write without jaxhyst): RK4 over
    the piecewise-linear input in a `lax.scan`, then the RMSE."""
    import jax
    import jax.numpy as jnp

    lower, upper, floor, a1, u, y, dt = data
    z = z.astype(u.dtype)  # evosax hands out its own dtype (float64 under x64)
    k1, k2, beta1, gamma1, n = jnp.maximum(lower + z * (upper - lower), floor)
    rates = jnp.diff(u) / dt

    def field(h, rate, s):
        return (a1 - (beta1 * s * jnp.sign(h) + gamma1) * jnp.abs(h) ** n) * rate

    def step(h, rate):
        s = jnp.sign(rate)
        f1 = field(h, rate, s)
        f2 = field(h + dt / 2 * f1, rate, s)
        f3 = field(h + dt / 2 * f2, rate, s)
        f4 = field(h + dt * f3, rate, s)
        h = h + dt / 6 * (f1 + 2 * f2 + 2 * f3 + f4)
        return h, h

    h0 = jnp.zeros((), u.dtype)
    _, hs = jax.lax.scan(step, h0, rates)
    predicted = k1 * u + k2 * jnp.concatenate([h0[None], hs])
    return jnp.sqrt(jnp.mean((predicted - y) ** 2))


def numpy_rmse(bench, positions):
    """The objective for a (particles, d) array, vectorised over particles with NumPy;
    RK4 loop over time in Python. Non-finite -> +inf."""
    import numpy as np

    z = np.asarray(positions, bench.np_dtype)
    values = np.maximum(
        bench.np_lower + z * (bench.np_upper - bench.np_lower), bench.np_floor
    )
    params = dict(zip(bench.names, values.T))
    k1, k2, beta1, gamma1, n = (params[k] for k in ("k1", "k2", "beta1", "gamma1", "n"))
    a1, dt, u, y = bench.np_A1, bench.np_dt, bench.np_u, bench.np_y
    rates = np.diff(u) / dt
    half, sixth = dt / 2, dt / 6
    h = np.zeros(z.shape[0], bench.np_dtype)
    hs = np.empty((u.shape[0], z.shape[0]), bench.np_dtype)
    hs[0] = h
    with np.errstate(all="ignore"):
        for i in range(rates.shape[0]):
            rate = rates[i]
            b = beta1 * np.sign(rate)

            def field(h, rate=rate, b=b):
                return (a1 - (b * np.sign(h) + gamma1) * np.abs(h) ** n) * rate

            f1 = field(h)
            f2 = field(h + half * f1)
            f3 = field(h + half * f2)
            f4 = field(h + dt * f3)
            h = h + sixth * (f1 + 2 * f2 + 2 * f3 + f4)
            hs[i + 1] = h
        predicted = k1 * u[:, None] + k2 * hs
        rmse = np.sqrt(np.mean((predicted - y[:, None]) ** 2, axis=0))
    return np.where(np.isfinite(rmse), rmse, np.inf)


def check_objectives(bench):
    """The three implementations must agree on a few random points."""
    import jax
    import jax.numpy as jnp
    import numpy as np

    z = np.random.default_rng(0).uniform(size=(31, bench.dimension))
    z = np.vstack([z, np.full(bench.dimension, 0.5)]).astype(bench.np_dtype)
    ref = np.asarray(
        jax.jit(jax.vmap(jaxhyst_objective, (0, None)))(jnp.asarray(z), bench.problem)
    )
    plain = np.asarray(
        jax.jit(jax.vmap(plain_jax_loss, (0, None)))(jnp.asarray(z), bench.plain_data)
    )
    npv = numpy_rmse(bench, z)
    ok = np.isfinite(ref)
    scale = np.max(np.abs(bench.np_y))
    dev = {
        "numpy": float(np.max(np.abs(npv[ok] - ref[ok])) / scale),
        "plain_jax": float(np.max(np.abs(plain[ok] - ref[ok])) / scale),
    }
    common.log(
        f"  objective check ({bench.dtype_name}, {int(ok.sum())}/{len(ok)} finite): "
        f"max |diff| / max|y| numpy {dev['numpy']:.1e}, plain JAX {dev['plain_jax']:.1e}"
    )
    return dev


# ------------------------------------------------------------------------ measurements


class CompileClock:
    """Seconds JAX spends tracing, lowering and compiling (jax.monitoring events)."""

    def __init__(self):
        import jax

        self.seconds = 0.0
        jax.monitoring.register_event_duration_secs_listener(self)

    def __call__(self, event, duration, **kwargs):
        if event.startswith("/jax/core/compile/"):
            self.seconds += duration


def machine_busy_seconds():
    """CPU seconds all processes on the machine have been busy (Linux /proc/stat;
    None elsewhere)."""
    try:
        with open("/proc/stat") as f:
            fields = [int(v) for v in f.readline().split()[1:]]
    except (OSError, ValueError):
        return None
    idle = fields[3] + (fields[4] if len(fields) > 4 else 0)  # idle + iowait
    return (sum(fields[:8]) - idle) / os.sysconf("SC_CLK_TCK")


def wait_idle(max_seconds, threshold=0.15, window=2.0):
    """Wait (up to `max_seconds`) until other processes use less than `threshold`
    cores over `window` seconds; returns the seconds waited."""
    start = time.perf_counter()
    while time.perf_counter() - start < max_seconds:
        before = machine_busy_seconds()
        if before is None:
            break
        time.sleep(window)
        if (machine_busy_seconds() - before) / window < threshold:
            break
    return time.perf_counter() - start


def timed(fn):
    """Run fn(); return (result, wall seconds, (cpu seconds of this process, busy cpu
    seconds of the whole machine or None)). The difference of the two is what other
    processes took meanwhile: the machine is shared, and that shows it."""
    busy = machine_busy_seconds()
    wall, cpu = time.perf_counter(), time.process_time()
    result = fn()
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    after = machine_busy_seconds()
    return result, wall, (cpu, None if busy is None else after - busy)


def timed_repeats(run, repeats, clock):
    """`run(0)` (compilation included), then `run(1)` ... `run(repeats)` timed;
    returns (the last result, first call s, compile s, walls, cpus)."""
    before = clock.seconds
    result, first, _ = timed(lambda: run(0))
    compile_s = clock.seconds - before
    walls, cpus = [], []
    for rep in range(repeats):
        result, wall, cpu = timed(lambda rep=rep: run(rep + 1))
        walls.append(wall)
        cpus.append(cpu)
    return result, first, compile_s, walls, cpus


def summarise(
    method,
    devices,
    bench,
    size,
    iterations,
    evaluations,
    first,
    compile_s,
    walls,
    cpus,
    note="",
    samples_per_step=1,
):
    steps = bench.num_samples - 1
    rk4_steps = -(-steps // samples_per_step)
    best, median = min(walls), statistics.median(walls)
    return {
        "method": method,
        "samples_per_step": samples_per_step,
        "dtype": bench.dtype_name,
        "size": size,
        "devices": devices,
        "samples": bench.num_samples,
        "iterations": iterations,
        "evaluations": evaluations,
        "first_call_s": first,
        "compile_s": compile_s,
        "wall_min_s": best,
        "wall_median_s": median,
        "cpu_util": statistics.median(c / w for (c, _), w in zip(cpus, walls)),
        # CPU used by OTHER processes during the timed repeats, in cores (0.1 = 10 %
        # of one core); clearly above zero means the numbers are contaminated.
        "other_util": (
            None
            if any(b is None for _, b in cpus)
            else statistics.median(
                max(0.0, b - c) / w for (c, b), w in zip(cpus, walls)
            )
        ),
        "particle_steps_per_s": evaluations * steps / best,
        "particle_rk4_steps_per_s": evaluations * rk4_steps / best,
        "particle_steps_per_s_median": evaluations * steps / median,
        "s_per_iteration": best / (evaluations / size),
        "note": note,
    }


def bench_jaxhyst(bench, size, args, sharding, devices, clock, as_fitted=False):
    import jax

    import jaxhyst as jh

    swarm = jh.MPSO(num_particles=size, num_iterations=args.iterations)
    problem = bench.swarm_problem if as_fitted else bench.problem
    k = bench.samples_per_step if as_fitted else 1

    def run(seed):
        return jh.identification.run_swarm(
            jaxhyst_objective,
            bench.lower,
            bench.upper,
            swarm,
            jax.random.key(seed),
            args=problem,
            chunk_size=args.iterations
            + 1,  # one chunk: the initial evaluation + G moves
            sharding=sharding,
        )

    result, first, compile_s, walls, cpus = timed_repeats(run, args.repeats, clock)
    return summarise(
        f"jaxhyst MPSO, RK4 step {k} sample{'s' if k > 1 else ''}",
        devices,
        bench,
        size,
        args.iterations,
        result.evaluations,
        first,
        compile_s,
        walls,
        cpus,
        note="the objective identify's swarm runs" if as_fitted else "",
        samples_per_step=k,
    )


def bench_evosax(bench, size, args, objective, data, label, clock):
    import jax
    import jax.numpy as jnp
    import jax.random as jr
    from evosax.algorithms import PSO

    dtype = jnp.dtype(bench.dtype_name)
    es = PSO(population_size=size, solution=jnp.zeros(bench.dimension, dtype))
    params = es.default_params.replace(
        inertia_coeff=0.9, cognitive_coeff=1.3, social_coeff=1.7
    )
    evaluate = jax.jit(jax.vmap(objective, in_axes=(0, None)))

    def run(seed):
        key = jr.key(seed)
        key, k_pop, k_init = jr.split(key, 3)
        population = jr.uniform(k_pop, (size, bench.dimension), dtype)
        fitness = evaluate(population, data)
        state = es.init(k_init, population, fitness, params)
        for _ in range(args.iterations):
            key, k_ask, k_tell = jr.split(key, 3)
            population, state = es.ask(k_ask, state, params)
            fitness = evaluate(population, data)
            state, _ = es.tell(k_tell, population, fitness, state, params)
        return jax.block_until_ready(state)

    _, first, compile_s, walls, cpus = timed_repeats(run, args.repeats, clock)
    return summarise(
        label,
        "1 (native)",
        bench,
        size,
        args.iterations,
        size * (args.iterations + 1),
        first,
        compile_s,
        walls,
        cpus,
        note="no bounds/clamping (evosax PSO)",
    )


def numpy_mpso(bench, size, iterations, seed, counter):
    """The paper's MPSO (eq. 9-14, same bounds/clamping/absorbing walls as jaxhyst),
    vectorised over particles with NumPy."""
    import numpy as np

    rng = np.random.default_rng(seed)
    d, dt = bench.dimension, bench.np_dtype
    c1, c2, w_max, w_min, vlim = 1.3, 1.7, 0.9, 0.1, 0.2

    def evaluate(x):
        counter[0] += x.shape[0]
        return numpy_rmse(bench, x)

    x = rng.uniform(size=(size, d)).astype(dt)
    v = rng.uniform(-vlim, vlim, size=(size, d)).astype(dt)
    fitness = evaluate(x)
    pbest, pbest_fitness = x.copy(), fitness.copy()
    gbest = pbest[np.argmin(pbest_fitness)]
    for k in range(iterations):
        w = w_max - (k / iterations) * (w_max - w_min)
        r1, r2 = rng.uniform(size=(2, size, d)).astype(dt)
        v = w * v + c1 * r1 * (pbest - x) + c2 * r2 * (gbest - x)
        v = np.clip(v, -vlim, vlim)
        moved = x + v
        x = np.clip(moved, 0, 1)
        v = np.where(moved == x, v, 0)
        fitness = evaluate(x)
        improved = fitness < pbest_fitness
        pbest[improved], pbest_fitness[improved] = x[improved], fitness[improved]
        gbest = pbest[np.argmin(pbest_fitness)]
    return float(pbest_fitness.min())


def pyswarms_run(bench, size, iterations, seed, counter):
    import numpy as np
    import pyswarms as ps

    np.random.seed(seed)
    d = bench.dimension
    optimizer = ps.single.GlobalBestPSO(
        n_particles=size,
        dimensions=d,
        options={"c1": 1.3, "c2": 1.7, "w": 0.9},
        bounds=(np.zeros(d), np.ones(d)),
        velocity_clamp=(-0.2, 0.2),
    )

    def objective(x):
        counter[0] += x.shape[0]
        return numpy_rmse(bench, x)

    cost, _ = optimizer.optimize(objective, iters=iterations, verbose=False)
    return float(cost)


def bench_numpy(bench, size, args, runner, label, note):
    walls, cpus, evaluations = [], [], 0
    # One run is enough as a warm-up for NumPy; the repeats are timed.
    counter = [0]
    _, first, _ = timed(
        lambda: runner(bench, size, args.baseline_iterations, 0, counter)
    )
    for rep in range(max(1, min(args.repeats, 2))):
        counter = [0]
        _, wall, cpu = timed(
            lambda rep=rep, counter=counter: runner(
                bench, size, args.baseline_iterations, rep + 1, counter
            )
        )
        evaluations = counter[0]
        walls.append(wall)
        cpus.append(cpu)
    return summarise(
        label,
        "1 core",
        bench,
        size,
        args.baseline_iterations,
        evaluations,
        first,
        0.0,
        walls,
        cpus,
        note=note,
    )


# ------------------------------------------------------------------------------ phases


def run_phase(args):
    if args.phase in ("forced", "wide"):
        flag = f"--xla_force_host_platform_device_count={args.host_devices}"
        if args.phase == "wide":
            flag += " " + WIDE_VECTORS
            if args.llvm_interleave:
                flag += (
                    " --xla_backend_extra_options=-force-vector-interleave="
                    f"{args.llvm_interleave}"
                )
        os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "") + " " + flag).strip()
    load_before = os.getloadavg()
    import jax

    jax.config.update("jax_enable_x64", True)  # float64 runs need it
    devices = jax.devices()
    common.log(
        f"[phase {args.phase}] devices: {devices}  XLA_FLAGS="
        f"{os.environ.get('XLA_FLAGS', '')!r}"
    )
    clock = CompileClock()
    rows, checks = [], {}
    skipped = []
    has_pyswarms = common.package_version("pyswarms") is not None
    has_evosax = common.package_version("evosax") is not None
    if args.phase == "native":
        if "pyswarms" in args.methods and not has_pyswarms:
            skipped.append(("PySwarms GlobalBestPSO", "pyswarms is not installed"))
        if "evosax" in args.methods and not has_evosax:
            skipped.append(("evosax PSO", "evosax is not installed"))
    for dtype_name in args.dtype:
        bench = Bench(args.samples, dtype_name)
        if args.phase == "native":
            checks[dtype_name] = check_objectives(bench)
        for size in args.sizes:
            n = len(devices)
            todo = []  # (function, arguments)
            if "jaxhyst" in args.methods:
                for as_fitted in (False, True):
                    if args.phase in ("forced", "wide"):
                        mode = args.phase
                        todo.append(
                            (
                                bench_jaxhyst,
                                (None, f"1 of {n} ({mode})", clock, as_fitted),
                            )
                        )
                        todo.append(
                            (
                                bench_jaxhyst,
                                ("auto", f"{n} ({mode}, sharded)", clock, as_fitted),
                            )
                        )
                    else:
                        todo.append(
                            (bench_jaxhyst, (None, "1 (native)", clock, as_fitted))
                        )
            if args.phase in ("native", "wide"):
                wide = " [wide]" if args.phase == "wide" else ""
                if "evosax" in args.methods and has_evosax:
                    label = "evosax PSO + jaxhyst objective" + wide
                    todo.append(
                        (bench_evosax, (jaxhyst_objective, bench.problem, label, clock))
                    )
                    label = "evosax PSO + plain JAX objective" + wide
                    todo.append(
                        (bench_evosax, (plain_jax_loss, bench.plain_data, label, clock))
                    )
            if args.phase == "native":
                if "numpy" in args.methods:
                    todo.append(
                        (
                            bench_numpy,
                            (numpy_mpso, "NumPy MPSO", "vectorised over particles"),
                        )
                    )
                if (
                    "pyswarms" in args.methods
                    and has_pyswarms
                    and dtype_name == "float64"
                ):
                    todo.append(
                        (
                            bench_numpy,
                            (pyswarms_run, "PySwarms GlobalBestPSO", "NumPy objective"),
                        )
                    )
            for function, extra in todo:
                waited = wait_idle(args.wait_idle) if args.wait_idle > 0 else 0.0
                row = function(bench, size, args, *extra)
                row["waited_for_idle_s"] = waited
                rows.append(row)
                common.log(
                    f"  {row['method']:34s} {row['dtype']} size {row['size']:4d} "
                    f"{row['devices']:20s} {row['particle_steps_per_s'] / 1e6:8.2f} "
                    f"M/s  first {row['first_call_s']:.2f} s  compile "
                    f"{row['compile_s']:.2f} s  cpu {100 * row['cpu_util']:.0f}%  "
                    f"others {100 * (row['other_util'] or 0):.0f}%"
                )
    return {
        "phase": args.phase,
        "devices": [str(d) for d in devices],
        "xla_flags": os.environ.get("XLA_FLAGS", ""),
        "rows": rows,
        "objective_checks": checks,
        "skipped": skipped,
        "load_average": [load_before[0], os.getloadavg()[0]],
    }


def child_command(args, phase, out):
    cmd = [sys.executable, os.path.abspath(__file__), "--phase", phase]
    cmd += ["--phase-out", out, "--sizes", *map(str, args.sizes)]
    cmd += ["--samples", str(args.samples), "--iterations", str(args.iterations)]
    cmd += ["--repeats", str(args.repeats), "--dtype", *args.dtype]
    cmd += ["--baseline-iterations", str(args.baseline_iterations)]
    cmd += ["--methods", *args.methods, "--host-devices", str(args.host_devices)]
    cmd += ["--wait-idle", str(args.wait_idle)]
    cmd += ["--llvm-interleave", str(args.llvm_interleave)]
    return cmd


# ------------------------------------------------------------------------------ report


def _is_jaxhyst(row):
    return row["method"].startswith("jaxhyst MPSO")


def add_ratios(rows):
    """`jaxhyst_speedup` = the best jaxhyst rate / this row's rate, at the same dtype
    and size and under the same XLA vector-width setting (a "wide" baseline is compared
    with wide jaxhyst rows only, a default one with default rows only), in particle-
    samples per second (the N samples of one evaluation). Two references: jaxhyst
    with an RK4 step per sample (the same integration work as the baselines), and
    jaxhyst with the objective `identify`'s swarm runs (coarser RK4 steps, every
    sample still compared)."""

    def is_wide(r):
        return "wide" in r["devices"] or "[wide]" in r["method"]

    for row in rows:
        for key, coarse in (("jaxhyst_speedup", False), ("as_fitted_speedup", True)):
            candidates = [
                r
                for r in rows
                if _is_jaxhyst(r)
                and (r.get("samples_per_step", 1) > 1) == coarse
                and r["dtype"] == row["dtype"]
                and r["size"] == row["size"]
                and is_wide(r) == is_wide(row)
            ]
            ref = max(candidates, key=lambda r: r["particle_steps_per_s"], default=None)
            row[key] = (
                ref["particle_steps_per_s"] / row["particle_steps_per_s"]
                if ref
                else None
            )


def print_table(result):
    common.print_machine(result["machine"])
    s = result["settings"]
    print(
        f"problem: PiezoBoucWen.paper_table4(3), u1, N = {s['num_samples']} samples, "
        f"d = 5; jaxhyst/evosax iterations "
        f"{s['iterations']}, NumPy/PySwarms iterations {s['baseline_iterations']}, "
        f"repeats {s['repeats']}"
    )
    for phase in result["phases"]:
        print(
            f"phase {phase['phase']}: devices {phase['devices']}, XLA_FLAGS="
            f"{phase['xla_flags']!r}, 1-min load average before/after "
            f"{phase['load_average'][0]:.2f}/{phase['load_average'][1]:.2f}"
        )
    header = (
        f"{'method':34s} {'dtype':7s} {'size':>4s} {'devices':20s} "
        f"{'M p-samples/s':>13s} {'(median)':>9s} {'M RK4/s':>8s} {'s/iter':>8s} "
        f"{'first s':>8s} {'compile s':>9s} {'cpu%':>5s} {'other%':>6s} "
        f"{'x (k=1)':>8s} {'x (fit)':>8s}"
    )
    print()
    print(header)
    print("-" * len(header))
    rows = sorted(
        result["rows"],
        key=lambda r: (r["dtype"], r["size"], 0 if _is_jaxhyst(r) else 1),
    )
    last = None
    for r in rows:
        if last is not None and (r["dtype"], r["size"]) != last:
            print()
        last = (r["dtype"], r["size"])
        other = "" if r["other_util"] is None else f"{100 * r['other_util']:.0f}"
        rk4 = r.get("particle_rk4_steps_per_s", r["particle_steps_per_s"])
        ratios = " ".join(
            "" if r.get(key) is None else f"{r[key]:8.2f}"
            for key in ("jaxhyst_speedup", "as_fitted_speedup")
        )
        print(
            f"{r['method']:34s} {r['dtype']:7s} {r['size']:4d} {r['devices']:20s} "
            f"{r['particle_steps_per_s'] / 1e6:13.2f} "
            f"{r['particle_steps_per_s_median'] / 1e6:9.2f} {rk4 / 1e6:8.2f} "
            f"{r['s_per_iteration']:8.4f} {r['first_call_s']:8.2f} "
            f"{r['compile_s']:9.2f} {100 * r['cpu_util']:5.0f} {other:>6s} {ratios}"
        )
    for phase in result["phases"]:
        for name, reason in phase.get("skipped", []):
            print(f"{name:34s} skipped: {reason}")
    print()
    print(
        "M p-samples/s: million particle-samples per second, evaluations * (N-1) / "
        "min wall (median in brackets): every evaluation simulates and compares all N "
        "samples; M RK4/s: million particle-RK4-steps per second (equal to p-samples/s "
        "for one RK4 step per sample; 1/k of it for the rows with an RK4 step of k "
        "samples, the objective identify's swarm runs); s/iter: min wall per swarm "
        "evaluation; first s: "
        "first call incl. compile; cpu%: this process's CPU time / wall; other%: CPU "
        "time of OTHER processes on the machine / wall during the timed repeats (the "
        "machine is shared; rows with other% well above 0 are slowed by them); "
        "x (k=1): best jaxhyst rate with one RK4 step per sample (any device mode) / "
        "this rate; x (fit): the same for jaxhyst's swarm objective; same dtype, size "
        "and vector width."
    )


def main(argv=None):
    args = parse_args(argv)
    if args.phase is not None:
        out = run_phase(args)
        with open(args.phase_out, "w") as f:
            json.dump(out, f)
        return 0
    if args.from_json:
        with open(args.from_json) as f:
            result = json.load(f)
        add_ratios(result["rows"])
        print_table(result)
        return 0
    phases = []
    with tempfile.TemporaryDirectory() as tmp:
        for phase in args.phases:
            out = os.path.join(tmp, f"{phase}.json")
            env = dict(os.environ)
            if phase == "native":
                env.pop("XLA_FLAGS", None)
            # cwd: PySwarms writes a report.log into the working directory.
            subprocess.run(
                child_command(args, phase, out), check=True, env=env, cwd=tmp
            )
            with open(out) as f:
                phases.append(json.load(f))
    rows = [row for phase in phases for row in phase["rows"]]
    add_ratios(rows)
    num_samples = rows[0]["samples"] if rows else args.samples + 1
    result = {
        # The parent never imports JAX: the devices are in each phase's entry.
        "machine": common.machine_info("evosax", "flax", "pyswarms", devices=False),
        "settings": {
            "sizes": args.sizes,
            "num_samples": num_samples,
            "iterations": args.iterations,
            "baseline_iterations": args.baseline_iterations,
            "repeats": args.repeats,
            "dtypes": args.dtype,
            "host_devices": args.host_devices,
            "command": " ".join([os.path.basename(sys.executable), *sys.argv]),
        },
        "phases": [{k: v for k, v in p.items() if k != "rows"} for p in phases],
        "rows": rows,
    }
    print_table(result)
    if args.json:
        common.write_json(result, args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
