"""The Levenberg-Marquardt polish through optimistix's own loop, against the loop it
replaced: `optx.least_squares` restarted every 10 steps (each restart throws away
the damping and trust region), both with the same minimum-gain rule, from the same
swarm results, in one process.

    python benchmarks/polish_loop.py [--seeds 5] [--json OUT]

Reports per start: seconds (second run, compiled) and final RMSE of each, and the
medians of the ratios (persistent / restarted).
"""

import argparse
import time

import _common as common
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

import jaxhyst as jh
from jaxhyst._identification._polish import stop_gain
from jaxhyst._identification._problem import problem_rmse


jax.config.update("jax_enable_x64", True)


@eqx.filter_jit
def _least_squares(problem, solver, z, steps):
    solution = optx.least_squares(
        lambda z, p: p.residuals(z), solver, z, problem, max_steps=steps, throw=False
    )
    return solution.value, solution.result == optx.RESULTS.successful


def restarted_polish(problem, z0, *, max_steps=100, chunk=10):
    """The previous polish: `optx.least_squares` for `chunk` steps at a time,
    restarted from the last point, stopping when it converges or a chunk gains
    less than the minimum gain."""
    solver = optx.LevenbergMarquardt(1e-8, 1e-10)
    enough = stop_gain(None, problem)
    z, best_z = z0, z0
    best = float(problem_rmse(problem, z0))
    taken, converged = 0, False
    while taken < max_steps and not converged:
        z, ok = _least_squares(problem, solver, z, chunk)
        taken += chunk
        loss = float(problem_rmse(problem, z))
        if not np.isfinite(loss):
            break
        converged = bool(ok) or loss > best * (1 - enough)
        if loss < best:
            best_z, best = z, loss
    return best_z, best, taken


def _record(seed: int):
    truth = jh.PiezoBoucWen.paper_table4(3)
    path = jh.sample(jh.paper_u1(), 200.0)
    y = np.asarray(jh.simulate(truth, path))
    sigma = 0.002 * np.max(np.abs(y))
    noisy = y + sigma * np.random.default_rng(seed).standard_normal(y.size)
    return jh.Recording(np.asarray(path.times), np.asarray(path.values), noisy), sigma


def _timed(function, *args):
    function(*args)  # compile
    start = time.perf_counter()
    out = function(*args)
    return out, time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5)
    common.add_json(parser)
    args = parser.parse_args()
    template = jh.PiezoBoucWen(1.0, 1.0, 1.0, 1.0, 1.0, 1.5)
    rows = []
    for seed in range(args.seeds):
        recording, sigma = _record(seed)
        swarm_only = jh.identify(
            template,
            recording,
            key=jax.random.key(seed),
            swarm=jh.MPSO(num_particles=16, num_iterations=10),
            polish=None,
            analyse=False,
            throw=False,
        )
        space = jh.ParameterSpace.default(template, recording)
        problem = jh.identification.Problem(
            space, recording.input_path(), jnp.asarray(recording.y), jh.RK4()
        )
        z0 = space.from_model(swarm_only.model)
        (_, old_rmse, old_steps), old_s = _timed(restarted_polish, problem, z0)
        new, new_s = _timed(jh.LevenbergMarquardtPolish().run, problem, z0)
        new_rmse = float(new.loss_history.min())
        rows.append(
            {
                "seed": seed,
                "noise_sigma": sigma,
                "start_rmse": float(swarm_only.metrics["rmse"]),
                "restarted": {"seconds": old_s, "rmse": old_rmse, "steps": old_steps},
                "persistent": {
                    "seconds": new_s,
                    "rmse": new_rmse,
                    "steps": new.steps,
                    "status": jh.status_name(new.result),
                },
            }
        )
        print(
            f"seed {seed}: start RMSE {rows[-1]['start_rmse']:.4g}; restarted "
            f"{old_s:.2f} s, RMSE {old_rmse:.6g} ({old_steps} steps); persistent "
            f"{new_s:.2f} s, RMSE {new_rmse:.6g} ({new.steps} steps, "
            f"{jh.status_name(new.result)}); noise {sigma:.4g}",
            flush=True,
        )
    time_ratio = float(
        np.median(
            [r["persistent"]["seconds"] / r["restarted"]["seconds"] for r in rows]
        )
    )
    loss_ratio = float(
        np.median([r["persistent"]["rmse"] / r["restarted"]["rmse"] for r in rows])
    )
    print(
        f"median persistent/restarted: time {time_ratio:.3f}, final RMSE "
        f"{loss_ratio:.6f}"
    )
    common.write_results(
        args.json, rows=rows, median_time_ratio=time_ratio, median_rmse_ratio=loss_ratio
    )


if __name__ == "__main__":
    main()
