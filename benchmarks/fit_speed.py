"""End-to-end identification speed: a fresh Python process, from its start to a
finished `jh.identify` on a paper-like recording, against the paper's MPSO schedule.

The recording: the paper's model (`PiezoBoucWen.paper_table4(3)`) driven by u1 = 2 -
2 cos(0.2 pi t), sampled at 1 kHz for one period (N = 10001), plus Gaussian noise of
standard deviation 0.1 % of max|y| (fixed seed).

1. "jaxhyst identify": `jh.identify(template, recording, key=...)` with its defaults
   (MPSO 100 particles x up to 200 iterations with stall stopping on a decimated copy,
   Levenberg-Marquardt polish on all samples, identifiability analysis), run in a
   child process started with `subprocess.run([sys.executable, __file__, "--child",
   "fit"])`. The wall time is measured by the parent from just before it starts the
   child to the moment the child's `identify` returns, so it includes interpreter
   start, imports, loading the recording (an NPZ file written beforehand by another
   child, as a user would have a recording on disk), tracing/compilation and the fit.
   The template passed to `identify` is a neutral `PiezoBoucWen(1, 1, 1, 1, 1, 1.5)`.
2. "paper MPSO (extrapolated)": `MPSO.paper_case(3)` (300 particles, G = 5000) at full
   resolution (`swarm_stride=1`), `polish=None`, no stall stopping. It is far too slow
   to run in full here, so a fresh child runs `--paper-iterations` of its iterations
   (the initial evaluation is the first pass of the first 20-pass chunk, so with
   iterations + 1 a multiple of 20 no pass is computed beyond the count), twice: the first call gives the compile time, the second the steady
   seconds per iteration, from which the full schedule (G iterations plus the initial
   evaluation) is EXTRAPOLATED.
3. "jaxhyst fit (CLI)": the command line on the same NPZ recording, `jaxhyst fit
   RECORDING --json OUT` (its defaults, as 1.), each run a fresh process whose wall time
   the parent measures from start to exit, with the persistent compilation cache
   (`JAXHYST_CACHE_DIR`) in a fresh temporary folder: first with the folder EMPTY (a
   cold start: everything compiled, then written to the cache), then again with the
   same folder WARM (the compiled programs loaded from it). `--cli-repeats` pairs
   (default 3), each with its own new folder; the table gives the medians, the RMSE
   of the fit relative to the noise sigma, and whether the warm fits equal the cold
   ones. (The child of 1. never enables the cache: a library import does not.)

No child sets XLA_FLAGS (one CPU device; XLA multithreads within it) unless
`--host-devices K` is given. The children cache Python bytecode (in a temporary
folder, filled by the first child before any timing), as a user's Python does;
`--no-bytecode-cache` makes each compile every module from source, as on machines
that set PYTHONDONTWRITEBYTECODE (about 0.5 s more per process here).

Run `python benchmarks/fit_speed.py`; `--json PATH` saves the results.
"""

import time


T0_PERF = time.perf_counter()  # as early as possible: imports count in the child

import argparse  # noqa: E402
import json  # noqa: E402
import os  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402

import _common as common  # noqa: E402


RESULT_PREFIX = "FIT_SPEED_RESULT "


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    parser.add_argument("--seed", type=int, default=0, help="noise and swarm seed")
    parser.add_argument(
        "--noise", type=float, default=1e-3, help="noise sigma / max|y| (0.1 %%)"
    )
    parser.add_argument("--rate", type=float, default=1000.0, help="sample rate, Hz")
    parser.add_argument(
        "--paper-iterations",
        type=int,
        default=59,
        help="iterations of MPSO.paper_case(3) actually run (then extrapolated); "
        "iterations + 1 should be a multiple of identify's 20-pass chunk",
    )
    parser.add_argument("--paper-case", type=int, default=3, choices=[1, 2, 3, 4])
    parser.add_argument(
        "--skip-paper", action="store_true", help="only the end-to-end fit"
    )
    parser.add_argument(
        "--host-devices",
        type=int,
        default=None,
        help="set XLA_FLAGS=--xla_force_host_platform_device_count=K in the children",
    )
    parser.add_argument(
        "--cli-repeats",
        type=int,
        default=3,
        help="cold/warm pairs of fresh-process 'jaxhyst fit' runs (0: skip them)",
    )
    common.add_baseline(parser)
    common.add_bytecode(parser)
    common.add_json(parser)
    parser.add_argument(
        "--child", choices=["make", "fit", "paper"], help=argparse.SUPPRESS
    )
    parser.add_argument("--recording", help=argparse.SUPPRESS)
    return parser.parse_args(argv)


# ------------------------------------------------------------------------------ child


def make_recording(jh, np, args):
    model = jh.PiezoBoucWen.paper_table4(3)
    path = jh.sample(jh.paper_u1(), args.rate)
    clean = np.asarray(jh.simulate(model, path, jh.RK4()))
    sigma = args.noise * float(np.max(np.abs(clean)))
    noisy = clean + sigma * np.random.default_rng(args.seed).standard_normal(
        clean.shape
    )
    t = np.arange(path.num_samples) / args.rate
    recording = jh.Recording(t, np.asarray(path.values), noisy, name="paper-u1-1kHz")
    return model, recording, clean, sigma


def child_fit(args):
    import jax

    jax.config.update("jax_enable_x64", True)
    import numpy as np

    import jaxhyst as jh

    t_imported = time.perf_counter()
    recording = jh.Recording.load(args.recording)
    with np.load(args.recording + ".truth.npz") as truth:
        clean, sigma = truth["clean"], float(truth["sigma"])
    t_data = time.perf_counter()
    # A neutral template: identify uses only its class (and smoothing), never its
    # values, so nothing of the truth reaches the fit.
    template = jh.PiezoBoucWen(1.0, 1.0, 1.0, 1.0, 1.0, 1.5)
    fit = jh.identify(template, recording, key=jax.random.key(args.seed))
    done_epoch = time.time()
    t_done = time.perf_counter()
    predicted = np.asarray(fit.predicted)
    rmse = float(fit.metrics["rmse"])
    return {
        "done_epoch": done_epoch,
        "child_total_s": t_done - T0_PERF,
        "import_s": t_imported - T0_PERF,
        "data_s": t_data - t_imported,
        "identify_s": t_done - t_data,
        "timing": {k: float(v) for k, v in fit.timing.items()},
        "swarm_compile_s": float(fit.swarm.compile_seconds) if fit.swarm else None,
        "swarm_iterations": fit.swarm.iterations_run if fit.swarm else None,
        "swarm_evaluations": fit.swarm.evaluations if fit.swarm else None,
        "swarm_stop": fit.swarm.stop_reason if fit.swarm else None,
        "polish_steps": fit.polish.steps if fit.polish else None,
        "num_samples": int(recording.num_samples),
        "sigma": sigma,
        "rmse": rmse,
        "rmse_over_sigma": rmse / sigma,
        "rmse_vs_clean_over_sigma": float(
            np.sqrt(np.mean((predicted - clean) ** 2)) / sigma
        ),
        "parameters": {k: float(v) for k, v in fit.model.parameters().items()},
        "devices": [str(d) for d in jax.devices()],
    }


def child_make(args):
    """Write the recording (and, beside it, the clean truth) for the fit child."""
    import jax

    jax.config.update("jax_enable_x64", True)
    import numpy as np

    import jaxhyst as jh

    _, recording, clean, sigma = make_recording(jh, np, args)
    recording.save(args.recording)
    np.savez(args.recording + ".truth.npz", clean=clean, sigma=sigma)
    return {}


def child_paper(args):
    import jax

    jax.config.update("jax_enable_x64", True)
    import numpy as np

    import jaxhyst as jh

    template, recording, _, sigma = make_recording(jh, np, args)
    full = jh.MPSO.paper_case(args.paper_case)
    swarm = jh.MPSO.paper_case(args.paper_case, num_iterations=args.paper_iterations)

    def run(seed):
        return jh.identify(
            template,
            recording,
            key=jax.random.key(seed),
            swarm=swarm,
            swarm_stride=1,
            polish=None,
            stall_iterations=None,
            analyse=False,
        )

    first = run(args.seed).swarm
    steady_fits = [run(args.seed + 1 + i) for i in range(2)]
    steady = [fit.swarm for fit in steady_fits if fit.swarm is not None]
    assert first is not None and len(steady) == len(steady_fits)
    walls = [s.wall_seconds for s in steady]
    evaluations_per_iteration = swarm.num_particles
    passes = steady[0].evaluations / evaluations_per_iteration  # G + 1
    s_per_iteration = min(walls) / passes
    compile_s = float(first.compile_seconds)
    return {
        "case": args.paper_case,
        "num_particles": full.num_particles,
        "full_iterations": full.num_iterations,
        "iterations_run": steady[0].iterations_run,
        "num_samples": int(recording.num_samples),
        "first_swarm_s": float(first.wall_seconds),
        "compile_s": compile_s,
        "steady_swarm_s": walls,
        "s_per_iteration": s_per_iteration,
        "particle_steps_per_s": evaluations_per_iteration
        * (recording.num_samples - 1)
        / s_per_iteration,
        "extrapolated_full_s": compile_s + (full.num_iterations + 1) * s_per_iteration,
        "rmse_after_run_over_sigma": float(steady_fits[0].metrics["rmse"]) / sigma,
        "devices": [str(d) for d in jax.devices()],
    }


# ----------------------------------------------------------------------------- parent


def environment(args, **variables):
    """A child's environment: bytecode cached in `args.pycache` (None: inherited),
    XLA_FLAGS only from --host-devices."""
    env = common.child_environment(args.pycache, **variables)
    if args.host_devices:
        env["XLA_FLAGS"] = f"--xla_force_host_platform_device_count={args.host_devices}"
    return env


def run_child(args, kind):
    cmd = [sys.executable, os.path.abspath(__file__), "--child", kind]
    cmd += ["--seed", str(args.seed), "--noise", str(args.noise)]
    cmd += ["--rate", str(args.rate), "--paper-case", str(args.paper_case)]
    cmd += ["--paper-iterations", str(args.paper_iterations)]
    if args.recording:
        cmd += ["--recording", args.recording]
    env = environment(args)
    start_epoch = time.time()
    start = time.perf_counter()
    proc = subprocess.run(cmd, env=env, stdout=subprocess.PIPE, text=True)
    process_s = time.perf_counter() - start
    if proc.returncode != 0:
        raise SystemExit(f"child {kind!r} failed with exit status {proc.returncode}")
    line = [ln for ln in proc.stdout.splitlines() if ln.startswith(RESULT_PREFIX)][-1]
    result = json.loads(line[len(RESULT_PREFIX) :])
    result["process_s"] = process_s
    if "done_epoch" in result:
        result["start_to_done_s"] = result["done_epoch"] - start_epoch
    return result


def run_cli_fit(args, cache_dir, out, tree=None):
    """One fresh `jaxhyst fit` process with JAXHYST_CACHE_DIR=cache_dir (jaxhyst
    from `tree` when given)."""
    cmd = [
        *common.launcher(args.baseline),
        "fit",
        args.recording,
        "--json",
        out,
        "--force",
    ]
    cmd += ["--seed", str(args.seed)]
    env = common.from_tree(environment(args, JAXHYST_CACHE_DIR=cache_dir), tree)
    start = time.perf_counter()
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
    wall_s = time.perf_counter() - start
    if proc.returncode != 0:
        raise SystemExit(
            f"'jaxhyst fit' failed with exit status {proc.returncode}:\n"
            + proc.stderr[-2000:]
        )
    with open(out) as f:
        data = json.load(f)
    entries, size = common.cache_size(cache_dir)
    return {
        "wall_s": wall_s,
        "identify_total_s": float(data["timing"]["total_s"]),
        "rmse": float(data["metrics"]["rmse"]),
        "parameters": data["parameters"],
        "cache_entries": entries,
        "cache_bytes": size,
        "warnings": [ln for ln in proc.stderr.splitlines() if "arning" in ln],
    }


def median(values):
    values = sorted(values)
    mid = len(values) // 2
    return values[mid] if len(values) % 2 else 0.5 * (values[mid - 1] + values[mid])


def cli_cold_warm(args, folder, sigma):
    """`--cli-repeats` pairs: a fresh cache folder, a cold run, then a warm run."""
    runs = cli_runs(args, folder, {"this tree": None})["this tree"]
    return summarise(args, runs, sigma)


def cli_runs(args, folder, trees):
    """`--cli-repeats` rounds; in each, every tree of `trees` (label -> checkout,
    None for this one) runs a cold then a warm fit in its own fresh cache folder,
    one tree after the other, so slow and quiet minutes fall on all. Returns each
    tree's runs by cache state."""
    runs = {label: {"empty": [], "warm": []} for label in trees}
    for i in range(args.cli_repeats):
        for t, (label, tree) in enumerate(trees.items()):
            cache_dir = os.path.join(folder, f"jax-cache-{i}-{t}")
            os.mkdir(cache_dir)
            for state in ("empty", "warm"):
                common.log(
                    f"cli: {label}: jaxhyst fit, {state} cache, "
                    f"round {i + 1}/{args.cli_repeats}"
                )
                out = os.path.join(folder, f"fit-{i}-{t}-{state}.json")
                runs[label][state].append(run_cli_fit(args, cache_dir, out, tree))
    return runs


def summarise(args, runs, sigma):
    summary = {}
    for state, results in runs.items():
        summary[state] = {
            "median_wall_s": median([r["wall_s"] for r in results]),
            "median_identify_total_s": median([r["identify_total_s"] for r in results]),
            "median_rmse_over_sigma": median([r["rmse"] for r in results]) / sigma,
            "cache_entries_after": [r["cache_entries"] for r in results],
            "cache_bytes_after": [r["cache_bytes"] for r in results],
        }
    return {
        "command": " ".join(
            [
                *common.launcher(args.baseline),
                "fit",
                "RECORDING",
                "--json",
                "OUT",
                "--force",
            ]
        ),
        "repeats": args.cli_repeats,
        "runs": runs,
        "summary": summary,
        "speedup": summary["empty"]["median_wall_s"] / summary["warm"]["median_wall_s"],
        "warm_fit_equals_cold": all(
            w["parameters"] == c["parameters"] and w["rmse"] == c["rmse"]
            for c, w in zip(runs["empty"], runs["warm"])
        ),
    }


def cli_against_baseline(args, folder, sigma):
    """This tree's and `--baseline`'s CLI fits, interleaved round by round; this
    tree's median wall times as ratios of the baseline's."""
    common.warm_bytecode(common.from_tree(environment(args), args.baseline))
    trees = {"this tree": None, "baseline": args.baseline}
    runs = cli_runs(args, folder, trees)
    results = {label: summarise(args, runs[label], sigma) for label in trees}
    return {
        "baseline_tree": os.path.abspath(args.baseline),
        **results,
        "ratio": {
            state: results["this tree"]["summary"][state]["median_wall_s"]
            / results["baseline"]["summary"][state]["median_wall_s"]
            for state in ("empty", "warm")
        },
        "same_fit_as_baseline": all(
            a["rmse"] == b["rmse"]
            for a, b in zip(runs["this tree"]["warm"], runs["baseline"]["warm"])
        ),
    }


def print_cli(cli):
    """The table of one tree's cold and warm CLI fits."""
    print(
        f"jaxhyst fit (CLI), fresh process start -> exit, median of "
        f"{cli['repeats']}, JAXHYST_CACHE_DIR a new temporary folder per pair:"
    )
    print(
        f"  {'cache':<8}{'wall (s)':>10}{'identify (s)':>14}{'RMSE/sigma':>12}"
        f"{'entries':>9}{'MB':>7}"
    )
    for state, row in cli["summary"].items():
        print(
            f"  {state:<8}{row['median_wall_s']:>10.2f}"
            f"{row['median_identify_total_s']:>14.2f}"
            f"{row['median_rmse_over_sigma']:>12.4f}"
            f"{row['cache_entries_after'][0]:>9d}"
            f"{row['cache_bytes_after'][0] / 1e6:>7.2f}"
        )
    print(
        f"  warm start is {cli['speedup']:.2f}x faster; warm fits identical to "
        f"the cold ones: {'yes' if cli['warm_fit_equals_cold'] else 'NO'}"
    )
    warned = [w for state in cli["runs"].values() for r in state for w in r["warnings"]]
    if warned:
        print(f"  warnings on stderr: {warned[0]!r} ({len(warned)} in all)")


def print_against_baseline(cli):
    """This tree's and the baseline's CLI fits, and their ratios."""
    print(
        f"jaxhyst fit (CLI, python -m jaxhyst), fresh process start -> exit, median "
        f"of {cli['this tree']['repeats']} interleaved rounds, a new cache folder per "
        f"round and tree; baseline: {cli['baseline_tree']}"
    )
    print(f"  {'cache':<8}{'baseline (s)':>14}{'this tree (s)':>15}{'ratio':>8}")
    for state in ("empty", "warm"):
        base = cli["baseline"]["summary"][state]["median_wall_s"]
        this = cli["this tree"]["summary"][state]["median_wall_s"]
        print(f"  {state:<8}{base:>14.2f}{this:>15.2f}{cli['ratio'][state]:>8.2f}")
    print(
        "  same final RMSE as the baseline: "
        + ("yes" if cli["same_fit_as_baseline"] else "NO")
        + "; warm fits identical to the cold ones: "
        + ", ".join(
            f"{label} {'yes' if cli[label]['warm_fit_equals_cold'] else 'NO'}"
            for label in ("this tree", "baseline")
        )
    )


def main(argv=None):
    args = parse_args(argv)
    if args.child is not None:
        children = {"make": child_make, "fit": child_fit, "paper": child_paper}
        result = children[args.child](args)
        print(RESULT_PREFIX + json.dumps(result), flush=True)
        return 0

    # The parent never imports JAX: the devices are the children's, fit["devices"].
    machine = common.machine_info(devices=False)
    machine["load_average_before"] = os.getloadavg()
    machine["xla_flags"] = (
        f"--xla_force_host_platform_device_count={args.host_devices}"
        if args.host_devices
        else ""
    )
    common.log("fit: fresh process -> jh.identify ...")
    with tempfile.TemporaryDirectory() as folder:
        args.pycache = None if args.no_bytecode_cache else os.path.join(folder, "pyc")
        machine["bytecode_cached"] = args.pycache is not None
        args.recording = os.path.join(folder, "paper-u1.npz")
        run_child(args, "make")  # also caches the bytecode, before any timing
        fit = run_child(args, "fit")
        cli = None
        if args.cli_repeats > 0 and args.baseline:
            cli = cli_against_baseline(args, folder, fit["sigma"])
        elif args.cli_repeats > 0:
            cli = cli_cold_warm(args, folder, fit["sigma"])
        paper = None
        if not args.skip_paper:
            common.log(
                f"paper: MPSO.paper_case({args.paper_case}) for "
                f"{args.paper_iterations} iterations ..."
            )
            paper = run_child(args, "paper")
    machine["load_average_after"] = os.getloadavg()

    m = machine
    common.print_machine(m)
    print(
        f"load average before {m['load_average_before'][0]:.2f}, after "
        f"{m['load_average_after'][0]:.2f}"
    )
    print(f"devices: {fit['devices']}  XLA_FLAGS={m['xla_flags']!r}")
    print(
        "bytecode: "
        + (
            "cached, as a user's Python does"
            if m["bytecode_cached"]
            else "not cached (every module compiled from source in each process)"
        )
    )
    print(
        f"recording: PiezoBoucWen.paper_table4(3) under u1 at {args.rate:g} Hz, N = "
        f"{fit['num_samples']}, noise sigma = {args.noise:g} * max|y| = "
        f"{fit['sigma']:.4g}, seed {args.seed}"
    )
    print()
    t = fit["timing"]
    print("jaxhyst identify (defaults), fresh process:")
    print(
        f"  process start -> identify done  {fit['start_to_done_s']:7.2f} s   "
        f"(whole child process incl. exit {fit['process_s']:.2f} s)"
    )
    print(
        f"    imports {fit['import_s']:.2f} s, load recording {fit['data_s']:.2f} s, "
        f"identify {fit['identify_s']:.2f} s = swarm {t.get('swarm_s', 0):.2f} s "
        f"(compile {fit['swarm_compile_s']:.2f} s, {fit['swarm_iterations']} "
        f"iterations, stop: {fit['swarm_stop']}) + polish {t.get('polish_s', 0):.2f} "
        f"s ({fit['polish_steps']} steps) + identifiability "
        f"{t.get('identifiability_s', 0):.2f} s + rest"
    )
    print(
        f"  final RMSE / sigma = {fit['rmse_over_sigma']:.4f}   (RMSE vs the clean "
        f"truth / sigma = {fit['rmse_vs_clean_over_sigma']:.4f})"
    )
    if cli is not None and args.baseline:
        print()
        print_against_baseline(cli)
    elif cli is not None:
        print()
        print_cli(cli)
    if paper is not None:
        print()
        print(
            f"paper MPSO.paper_case({paper['case']}): {paper['num_particles']} "
            f"particles x {paper['full_iterations']} iterations at N = "
            f"{paper['num_samples']}, polish=None:"
        )
        print(
            f"  ran {paper['iterations_run']} iterations: first call "
            f"{paper['first_swarm_s']:.2f} s (compile {paper['compile_s']:.2f} s), "
            f"steady {', '.join(f'{w:.2f}' for w in paper['steady_swarm_s'])} s -> "
            f"{paper['s_per_iteration']:.4f} s/iteration "
            f"({paper['particle_steps_per_s'] / 1e6:.1f} M particle-steps/s)"
        )
        print(
            f"  EXTRAPOLATED full schedule: {paper['extrapolated_full_s']:.0f} s "
            f"({paper['extrapolated_full_s'] / 60:.1f} min) = compile + "
            f"{paper['full_iterations'] + 1} x s/iteration"
        )
        print(
            f"  jaxhyst identify end-to-end is "
            f"{paper['extrapolated_full_s'] / fit['start_to_done_s']:.0f}x faster "
            "than the extrapolated paper schedule"
        )
    if args.json:
        result = {
            "machine": machine,
            "settings": vars(args),
            "fit": fit,
            "cli": cli,
            "paper": paper,
            "command": " ".join([os.path.basename(sys.executable), *sys.argv]),
        }
        common.write_json(result, args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
