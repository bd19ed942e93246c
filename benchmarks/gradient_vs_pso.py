"""Gradient polish against particle swarms: RMSE against wall time and against model
evaluations, and how often each method reaches the noise floor.

Data: the paper-like recording of `paper_cases.py` without the correction: the
paper's Table 4 Case 3 model (`PiezoBoucWen.paper_table4(3)`) under u1 = 2 - 2 cos(0.2
pi t) at 1 kHz (N = 10001), plus Gaussian noise of sigma = `--noise` * max|y|. Seed s
draws a new noise realisation and new optimiser randomness from `jax.random.key(s)`.
The fitted model class contains the truth, so the RMSE of the true parameters on
the recording is the floor. SUCCESS means a final RMSE <= `--tolerance` (default
1.001) x the true-parameter RMSE on that recording (1.05 x, reported beside it as the
"lax" criterion, still accepts fits 0.3 sigma from the truth).

Methods (all in the same search space, `ParameterSpace.default`: the gauge A1 =
1/max|u| fixed, bounds scaled to the data; the box is printed):

- "MPSO Case c": the paper's Table 3 swarm (swarm only, no early stop, every sample),
  with G SCALED to `--budget-seconds` of iteration time per run when the full G does
  not fit (measured seconds per iteration; the inertia weight schedule is compressed
  to G'); the table says G' of G.
- "swarm + LM": `jh.identify`'s default, MPSO 100 x up to 200 (stall stop after 40
  iterations, on every 5th sample) then optimistix Levenberg-Marquardt on all
  samples (`jh.LevenbergMarquardtPolish()`).
- "swarm + BFGS": the same swarm, then `jh.BFGSPolish()` (optimistix BFGS).
- "swarm + Adam": the same swarm, then `jh.AdamPolish()` (optax Adam, lr 1e-3, 500
  steps).
  The three share one swarm run per seed (same result, same clock), so they differ
  only in the polish. When the swarm alone already meets the criterion, their time
  to success is the swarm's.
- "multi-start LM": Levenberg-Marquardt from uniform random points of the unit box,
  one after the other, until one succeeds or `--starts` (default 8) are spent.

Clocks and counts. Times exclude JIT compilation: every polish is warmed up once on
the first recording before anything is timed, and the swarms' own measured compile
time is subtracted from their wall time (compile times are reported apart). Within a
run, a swarm's time is spread evenly over its iterations, a polish's over its
chunks of steps. Evaluations count full-recording simulations: a swarm particle whose RK4
steps span k samples counts 1/k; a Levenberg-Marquardt step 1 + d (residuals plus
d forward-mode Jacobian columns, d = 5 free parameters); a BFGS or Adam step 2
(value and reverse-mode gradient); plus one per RMSE check of the polish driver.
During the swarm phase of "swarm + ..." the RMSE is the swarm's, with its coarse
RK4 steps (drawn dotted); success is only ever judged on all samples.

    python benchmarks/gradient_vs_pso.py --quick
    python benchmarks/gradient_vs_pso.py --seeds 5 --json gvp.json --plots gvp

Outputs (`--json`, `--plots`) are never replaced without `--force`.
"""

import argparse
import statistics
import sys
import time
from pathlib import Path

import jax


jax.config.update("jax_enable_x64", True)

import _common as common  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
from paper_cases import (  # noqa: E402
    CASE_SIZES,
    UM,
    VELOCITY_LIMIT,
    paper_recording,
    plan_iterations,
    search_space,
    seconds_per_iteration,
)

import jaxhyst as jh  # noqa: E402


PLOT_NAME = "gradient_vs_pso.png"
SHORT_SWARM = jh.MPSO(num_particles=100, num_iterations=200)


def parse_args(argv=None):
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--seeds", type=int, default=None, help="seeds 0..N-1 (5)")
    parser.add_argument("--noise", type=float, default=1e-3, help="sigma / max|y|")
    parser.add_argument("--rate", type=float, default=1000.0, help="sample rate, Hz")
    parser.add_argument(
        "--tolerance",
        type=float,
        default=1.001,
        help="success: final RMSE <= TOL x true-parameter RMSE (default 1.001)",
    )
    parser.add_argument(
        "--lax-tolerance",
        type=float,
        default=1.05,
        help="a second, laxer criterion reported beside it (default 1.05)",
    )
    parser.add_argument(
        "--cases", type=int, nargs="*", default=None, choices=[1, 2, 3, 4]
    )
    scaling = parser.add_mutually_exclusive_group()
    scaling.add_argument(
        "--budget-seconds",
        type=float,
        default=None,
        help="iteration time per MPSO run; G scaled down to fit (default 30)",
    )
    scaling.add_argument("--scale", type=float, help="run round(SCALE * G)")
    scaling.add_argument("--full", action="store_true", help="the paper's full G")
    parser.add_argument("--max-iterations", type=int, help="cap on every MPSO's G'")
    parser.add_argument("--starts", type=int, default=None, help="multi-start LM (8)")
    parser.add_argument(
        "--quick",
        action="store_true",
        help="a smoke run: 2 seeds, MPSO Cases 1-2 capped at 60 iterations, 4 "
        "starts, Adam 200 steps",
    )
    common.add_json(parser)
    parser.add_argument("--plots", metavar="DIR", help="write the figure here")
    common.add_force(parser)
    args = parser.parse_args(argv)
    quick = args.quick
    if args.seeds is None:
        args.seeds = 2 if quick else 5
    if args.cases is None:
        args.cases = [1, 2] if quick else [1, 2, 3, 4]
    if args.starts is None:
        args.starts = 4 if quick else 8
    if quick and args.max_iterations is None and args.scale is None:
        args.max_iterations = 60
    if args.full or args.scale is not None:
        args.budget_seconds = None
    elif args.budget_seconds is None:
        args.budget_seconds = 30.0
    args.adam_steps = 200 if quick else 500
    args.swarm_stride = 1  # for plan_iterations' cost model: the paper's N
    if args.scale is not None and not args.scale > 0:
        parser.error("--scale must be positive")
    return args


# ------------------------------------------------------------------------ traces


class Trace:
    """(time, evaluations, RMSE, on all samples?) points of one run."""

    def __init__(self, samples):
        self.samples = samples  # of the recording: the unit of an evaluation
        self.time, self.evals, self.rmse, self.full = [], [], [], []

    def add(self, t, evaluations, rmse, full=True):
        value = float(rmse)
        self.time.append(float(t))
        self.evals.append(float(evaluations))
        self.rmse.append(value if np.isfinite(value) else np.inf)
        self.full.append(bool(full))

    @property
    def end(self):
        return (self.time[-1], self.evals[-1]) if self.time else (0.0, 0.0)

    def best_full(self):
        values = [r for r, f in zip(self.rmse, self.full) if f]
        return min(values) if values else np.inf

    def first_below(self, threshold):
        """(time, evaluations) of the first all-sample point <= threshold."""
        for t, e, r, f in zip(self.time, self.evals, self.rmse, self.full):
            if f and r <= threshold:
                return t, e
        return None

    def to_dict(self, truth_rmse):
        return {
            "time_s": self.time,
            "evaluations": self.evals,
            "rmse_over_truth": [r / truth_rmse for r in self.rmse],
            "all_samples": self.full,
        }


def add_swarm(trace, swarm, num_samples, *, full):
    """A swarm's history, its steady time spread evenly over its iterations."""
    t0, e0 = trace.end
    history = np.asarray(swarm.history)
    steady = max(0.0, swarm.wall_seconds - swarm.compile_seconds)
    per_eval = swarm.evaluations / history.size
    weight = (num_samples - 1) / (trace.samples - 1)
    for k, value in enumerate(history):
        fraction = (k + 1) / history.size
        trace.add(t0 + steady * fraction, e0 + per_eval * (k + 1) * weight, value, full)
    return steady


def add_polish(trace, result, step_cost, chunk):
    """A polish's RMSE history (one point per chunk of steps, on all samples)."""
    t0, e0 = trace.end
    history = np.asarray(result.loss_history)
    chunks = max(1, history.size - 1)
    for j, value in enumerate(history):
        steps = min(result.steps, chunk * j)
        trace.add(
            t0 + result.wall_seconds * j / chunks,
            e0 + step_cost * steps + j + 1,
            value,
        )


# ----------------------------------------------------------------------- methods


def run_mpso(case, g, rec, space, key, samples):
    particles, _ = CASE_SIZES[case]
    swarm = jh.MPSO.paper_case(
        3, num_particles=particles, num_iterations=g, velocity_limit=VELOCITY_LIMIT
    )
    fit = jh.identify(
        jh.PiezoBoucWen.paper_table4(3),
        rec,
        key=key,
        space=space,
        swarm=swarm,
        swarm_stride=1,
        polish=None,
        stall_iterations=None,
        analyse=False,
    )
    trace = Trace(samples)
    add_swarm(trace, fit.swarm, samples, full=True)
    return trace, {"compile_s": fit.swarm.compile_seconds, "iterations": g}


def short_swarm(rec, space, key):
    """`jh.identify`'s default swarm alone (shared by the three polishes)."""
    return jh.identify(
        jh.PiezoBoucWen.paper_table4(3),
        rec,
        key=key,
        space=space,
        swarm=SHORT_SWARM,
        polish=None,
        analyse=False,
    )


def run_polish_after(fit, polish, step_cost, chunk, rec, problem, samples):
    """The shared swarm's trace, then `polish` from its best."""
    trace = Trace(samples)
    # identify's default swarm RK4 step
    k = jh.identification.swarm_samples_per_step(rec.u)
    rk4_steps = -(-(rec.num_samples - 1) // k)
    add_swarm(trace, fit.swarm, rk4_steps + 1, full=k == 1)
    result = polish.run(problem, fit.swarm.best_x)
    add_polish(trace, result, step_cost, chunk)
    return trace, {
        "compile_s": fit.swarm.compile_seconds,
        "swarm_iterations": fit.swarm.iterations_run,
        "polish_steps": result.steps,
    }


def run_multistart(starts, threshold, problem, key, samples, d):
    trace = Trace(samples)
    points = jax.random.uniform(key, (starts, d))
    lm = jh.LevenbergMarquardtPolish()
    used = 0
    for z0 in points:
        used += 1
        result = lm.run(problem, z0)
        add_polish(trace, result, 1 + d, 10)
        if trace.best_full() <= threshold:
            break
    # best-so-far over the starts
    best = np.minimum.accumulate(np.asarray(trace.rmse))
    trace.rmse = best.tolist()
    return trace, {"starts_used": used}


# -------------------------------------------------------------------------- main


def record_run(runs, method, trace, extra, note, seed, data, args):
    """Score one run against both criteria and keep it under `method`."""
    truth = data["truth_rmse"]
    hit = trace.first_below(args.tolerance * truth)
    final = trace.best_full()
    runs.setdefault(method, []).append(
        {
            "seed": seed,
            "success": hit is not None,
            "success_lax": final <= args.lax_tolerance * truth,
            "time_to_success_s": hit[0] if hit else None,
            "evaluations_to_success": hit[1] if hit else None,
            "final_rmse_over_truth": final / truth,
            "total_time_s": trace.end[0],
            "total_evaluations": trace.end[1],
            "trace": trace.to_dict(truth),
            "note": note,
            **extra,
        }
    )
    common.log(
        f"  seed {seed} {method}: final RMSE / truth {final / truth:.5f}, "
        f"{'success' if hit else 'no success'}, {trace.end[0]:.1f} s"
    )


def median(values):
    return statistics.median(values) if values else None


def summarise(runs, tolerance):
    table = []
    for method, per_seed in runs.items():
        hits = [r for r in per_seed if r["success"]]
        table.append(
            {
                "method": method,
                "runs": len(per_seed),
                "successes": len(hits),
                "success_rate": len(hits) / len(per_seed),
                "successes_lax": sum(r["success_lax"] for r in per_seed),
                "median_time_to_success_s": median(
                    [r["time_to_success_s"] for r in hits]
                ),
                "median_evaluations_to_success": median(
                    [r["evaluations_to_success"] for r in hits]
                ),
                "median_final_rmse_over_truth": median(
                    [r["final_rmse_over_truth"] for r in per_seed]
                ),
                "median_total_time_s": median([r["total_time_s"] for r in per_seed]),
                "median_total_evaluations": median(
                    [r["total_evaluations"] for r in per_seed]
                ),
                "note": per_seed[0].get("note", ""),
            }
        )
    return table


def verdict(table, tolerance):
    """A plain sentence: which method wins on time, on evaluations, on reliability."""
    best_rate = max(row["success_rate"] for row in table)
    if best_rate == 0:
        return (
            f"No method reached {tolerance:g} x the true-parameter RMSE in these runs."
        )
    reliable = [row for row in table if row["success_rate"] == best_rate]
    fastest = min(reliable, key=lambda r: r["median_time_to_success_s"])
    fewest = min(reliable, key=lambda r: r["median_evaluations_to_success"])
    close = [
        r["method"]
        for r in reliable
        if r is not fastest
        and r["median_time_to_success_s"] <= 1.25 * fastest["median_time_to_success_s"]
    ]
    tie = (
        f"; {', '.join(close)} within 25 %, a tie at the timing precision of a "
        "shared machine"
        if close
        else ""
    )
    parts = [
        f"Among the most reliable methods (success in {best_rate:.0%} of seeds), "
        f"{fastest['method']} reaches {tolerance:g} x the true-parameter RMSE fastest "
        f"(median {fastest['median_time_to_success_s']:.3g} s{tie})"
    ]
    if fewest is fastest:
        parts.append(
            f" and with the fewest model evaluations "
            f"({fastest['median_evaluations_to_success']:.3g})."
        )
    else:
        parts.append(
            f"; {fewest['method']} needs the fewest model evaluations "
            f"({fewest['median_evaluations_to_success']:.3g})."
        )
    others = [r for r in table if r["success_rate"] < best_rate]
    if others:
        parts.append(
            " Less reliable here: "
            + ", ".join(f"{r['method']} ({r['successes']}/{r['runs']})" for r in others)
            + "."
        )
    mpso = [r for r in table if r["method"].startswith("MPSO")]
    slow = [r for r in mpso if r["successes"]]
    if slow and fastest not in mpso:
        ratio = (
            min(r["median_time_to_success_s"] for r in slow)
            / (fastest["median_time_to_success_s"])
        )
        parts.append(
            f" The quickest successful paper MPSO case needs {ratio:.3g} x the time "
            f"of {fastest['method']}."
        )
    return "".join(parts)


FLOOR = 1e-3  # the plots' floor of the excess error


def excess(tolerance):
    """Excess error sqrt(RMSE^2 - RMSE_true^2) / RMSE_true of a fit at `tolerance`."""
    return float(np.sqrt(max(tolerance**2 - 1, 0.0)))


def plot(folder, runs, truths, tolerance, lax):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(13, 5), constrained_layout=True)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for i, (method, per_seed) in enumerate(runs.items()):
        colour = colours[i % len(colours)]
        for j, run in enumerate(per_seed):
            trace = run["trace"]
            t = np.maximum(np.asarray(trace["time_s"]), 1e-4)
            e = np.maximum(np.asarray(trace["evaluations"]), 1.0)
            ratio = np.asarray(trace["rmse_over_truth"], dtype=float)
            full = np.asarray(trace["all_samples"])
            for flag in (False, True):  # best so far, within each kind of point
                ratio[full == flag] = np.minimum.accumulate(ratio[full == flag])
            r = np.sqrt(np.maximum(ratio**2 - 1, FLOOR**2))
            for axis, x in zip(axes, (t, e)):
                label = method if j == 0 else None
                if (~full).any():
                    axis.plot(x[~full], r[~full], ":", color=colour, lw=1)
                axis.plot(x[full], r[full], "-", color=colour, lw=1.2, label=label)
    xlabels = (
        "wall time [s] (compilation excluded)",
        "model evaluations (full-recording simulations)",
    )
    for axis, xlabel in zip(axes, xlabels):
        axis.axhline(
            excess(tolerance), color="k", ls="--", lw=1, label=f"success: {tolerance:g}"
        )
        axis.axhline(excess(lax), color="0.5", ls=":", lw=1, label=f"lax: {lax:g}")
        axis.set_xscale("log")
        axis.set_yscale("log")
        axis.set_xlabel(xlabel)
        axis.set_ylabel(
            "excess error sqrt(RMSE^2 - RMSE_true^2) / RMSE_true\n"
            f"(floored at {FLOOR:g}; x RMSE_true ~ noise sigma)"
        )
        axis.grid(alpha=0.3, which="both")
    axes[0].legend(fontsize="small")
    fig.suptitle(
        f"Paper-like u1 recording, {len(truths)} seed(s): best RMSE so far "
        "(dotted: a swarm with its coarse RK4 steps)"
    )
    path = folder / PLOT_NAME
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def main(argv=None):
    args = parse_args(argv)
    common.output_paths(
        args.json, args.plots, (PLOT_NAME,), force=args.force, folder_option="--plots"
    )
    started = time.perf_counter()
    info = common.machine_info("optax", "diffrax", load=True)
    template = jh.PiezoBoucWen.paper_table4(3)

    # The recordings and problems, one per seed.
    seeds = []
    for seed in range(args.seeds):
        k_noise, k_method = jax.random.split(jax.random.key(seed))
        data = paper_recording(
            jh.paper_u1(), key=k_noise, rate=args.rate, noise=args.noise, name="u1"
        )
        rec = data["recording"]
        space = search_space(template, rec)
        problem = jh.identification.Problem(
            space, rec.input_path(), jnp.asarray(rec.y), jh.RK4()
        )
        seeds.append((seed, k_method, data, rec, space, problem))
    d = seeds[0][4].dimension
    samples = seeds[0][3].num_samples

    # Warm-up: compile every polish once (not timed into any run).
    common.log("warm-up (compilation) ...")
    warm = {}
    problem0, z0 = seeds[0][5], jnp.full(d, 0.5)
    for name, polish in (
        ("LM", jh.LevenbergMarquardtPolish(max_steps=10)),
        ("BFGS", jh.BFGSPolish(max_steps=10)),
        ("Adam", jh.AdamPolish(max_steps=50)),
    ):
        start = time.perf_counter()
        polish.run(problem0, z0)
        warm[name] = time.perf_counter() - start

    # MPSO schedules: planned once (on seed 0's recording), used for every seed.
    plans = {}
    for case in args.cases:
        particles, full_g = CASE_SIZES[case]
        g, how, cost = plan_iterations(
            full_g,
            args,
            lambda p=particles: seconds_per_iteration(
                seeds[0][4], seeds[0][3], p, 1, jax.random.key(99)
            ),
        )
        plans[case] = {
            "G": full_g,
            "G_run": g,
            "scale": g / full_g,
            "how": how,
            "s_per_iteration": cost,
        }

    polishes = {
        "swarm + LM (identify default)": (jh.LevenbergMarquardtPolish(), 1 + d, 10),
        "swarm + BFGS": (jh.BFGSPolish(), 2, 10),
        f"swarm + Adam ({args.adam_steps} steps)": (
            jh.AdamPolish(max_steps=args.adam_steps),
            2,
            50,
        ),
    }
    runs = {}
    for seed, key, data, rec, space, problem in seeds:
        truth = data["truth_rmse"]
        threshold = args.tolerance * truth
        keys = jax.random.split(key, 8)

        def record(method, trace, extra, note="", _seed=seed, _data=data):
            record_run(runs, method, trace, extra, note, _seed, _data, args)

        for i, case in enumerate(args.cases):
            plan = plans[case]
            method = f"MPSO Case {case}"
            common.log(
                f"seed {seed}: {method} {CASE_SIZES[case][0]} x {plan['G_run']} ..."
            )
            trace, extra = run_mpso(case, plan["G_run"], rec, space, keys[i], samples)
            note = f"G' = {plan['G_run']} of {plan['G']}"
            if plan["G_run"] < plan["G"]:
                note += f" (SCALED x{plan['scale']:.3g}, {plan['how']})"
            record(method, trace, extra, note)
        common.log(f"seed {seed}: short swarm (identify's default) ...")
        swarm_fit = short_swarm(rec, space, keys[4])
        for method, (polish, cost, chunk) in polishes.items():
            common.log(f"seed {seed}: {method} ...")
            trace, extra = run_polish_after(
                swarm_fit, polish, cost, chunk, rec, problem, samples
            )
            record(method, trace, extra)
        common.log(f"seed {seed}: multi-start LM ...")
        trace, extra = run_multistart(
            args.starts, threshold, problem, keys[7], samples, d
        )
        record("multi-start LM", trace, extra, f"up to {args.starts} starts")

    table = summarise(runs, args.tolerance)
    sentence = verdict(table, args.tolerance)

    # ---------------------------------------------------------------- report
    common.print_machine(info)
    print(
        f"load average at start {info['load_average'][0]:.2f} (other work may share "
        "the cores)"
    )
    truths = [s[2]["truth_rmse"] for s in seeds]
    sigmas = [s[2]["sigma"] for s in seeds]
    print(
        f"data: PiezoBoucWen.paper_table4(3) under u1 at {args.rate:g} Hz, N = "
        f"{samples}, noise sigma {np.mean(sigmas) * UM:.4f} um; seeds "
        f"0..{args.seeds - 1}; true-parameter RMSE {min(truths) * UM:.4f}-"
        f"{max(truths) * UM:.4f} um"
    )
    clean, u = seeds[0][2]["clean"], np.asarray(seeds[0][3].u)
    hysteresis = float(np.ptp(clean - float(template.k1) * u))
    limit = excess(args.tolerance)
    print(
        f"success: final RMSE <= {args.tolerance:g} x the true-parameter RMSE of the "
        f"same recording (judged on all samples); a fit at that limit is off the "
        f"noise-free truth by about sqrt({args.tolerance:g}^2 - 1) = "
        f"{limit:.3g} sigma = {limit * np.mean(truths) * UM:.3g} um RMS, against a "
        f"hysteretic part of {hysteresis * UM:.3g} um peak to peak. "
        f"Column 'lax': final RMSE <= {args.lax_tolerance:g} x (off by up to "
        f"{excess(args.lax_tolerance):.3g} sigma)."
    )
    box = seeds[0][4]
    print(
        "search box (A1 fixed at 1/max|u|): "
        + ", ".join(
            f"{n} in [{lo:.4g}, {hi:.4g}]"
            for n, lo, hi in zip(box.names, box.lower, box.upper)
        )
    )
    print(
        "times exclude compilation; warm-up (compile) of the polishes: "
        + ", ".join(f"{k} {v:.2f} s" for k, v in warm.items())
    )
    scaled = [c for c, p in plans.items() if p["G_run"] < p["G"]]
    if scaled:
        print(
            "NOTE: SCALED MPSO: "
            + "; ".join(
                f"Case {c} ran G' = {plans[c]['G_run']} of G = {plans[c]['G']} "
                f"(x{plans[c]['scale']:.3g}, {plans[c]['how']})"
                for c in scaled
            )
            + ". The inertia weight schedule is compressed to G'."
        )
    print()
    print(
        f"  {'method':32s} {'success':>8s} {'lax':>5s} {'t to succ s':>11s} "
        f"{'evals to succ':>13s} "
        f"{'final/truth':>11s} {'total s':>8s} {'total evals':>11s}  note"
    )
    for row in table:
        print(
            f"  {row['method']:32s} {row['successes']:>3d}/{row['runs']:<4d} "
            f"{row['successes_lax']:>2d}/{row['runs']:<2d} "
            f"{_fmt(row['median_time_to_success_s'], '11.3g')} "
            f"{_fmt(row['median_evaluations_to_success'], '13.4g')} "
            f"{row['median_final_rmse_over_truth']:11.5f} "
            f"{row['median_total_time_s']:8.2f} {row['median_total_evaluations']:11.4g}"
            f"  {row['note']}"
        )
    print("  (medians over seeds; time and evaluations to success over the successes)")
    print()
    print(sentence)
    print(f"total wall time {time.perf_counter() - started:.1f} s")
    if args.plots:
        folder = Path(args.plots)
        folder.mkdir(parents=True, exist_ok=True)
        print(f"wrote {plot(folder, runs, truths, args.tolerance, args.lax_tolerance)}")
    if args.json:
        result = {
            "machine": info,
            "settings": vars(args),
            "success_criterion": f"final RMSE <= {args.tolerance} x true-parameter RMSE",
            "hysteresis_peak_to_peak_m": hysteresis,
            "mpso_plans": plans,
            "warmup_s": warm,
            "true_rmse": truths,
            "table": table,
            "verdict": sentence,
            "runs": runs,
        }
        common.write_json(result, args.json)
    return 0


def _fmt(value, spec):
    width = int("".join(c for c in spec.split(".")[0] if c.isdigit()) or 0)
    return f"{'-':>{width}s}" if value is None else format(value, spec)


if __name__ == "__main__":
    sys.exit(main())
