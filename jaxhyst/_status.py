"""How a swarm, a polish or a whole fit ended: one enumeration, as optimistix's
`RESULTS`, shared by `SwarmResult`, `PolishResult` and `Fit`."""

import equinox as eqx
import numpy as np


class RESULTS(eqx.Enumeration):
    """The status of a swarm, a polish or a fit (`result` on each).

    - `successful`: the stopping rule was met (a converged polish, a swarm that
      stalled or reached its target, a fixed schedule run to its end).
    - `max_steps_reached`: the budget ran out before the stopping rule was met
      (the objective was still improving by more than the rule allows, or had not
      reached a swarm's `target`).
    - `nonfinite`: the objective was not finite where the result was taken.
    - `solver_failed`: the optimiser itself reported a failure.
    """

    successful = ""
    max_steps_reached = (
        "the iteration budget ran out before the stopping rule was met (still "
        "improving, or short of the target); raise max_steps (polish) or "
        "num_iterations (swarm), or pass throw=False to keep the best point found"
    )
    nonfinite = (
        "the objective is not finite (the model diverged or produced NaN); check the "
        "recording's units and the parameter bounds, or pass throw=False to inspect "
        "the result"
    )
    solver_failed = (
        "the optimiser reported a failure (e.g. a singular linear solve) before "
        "converging; try another polish (BFGSPolish) or pass throw=False to keep "
        "the best point found"
    )


def has_status(result: RESULTS, item: RESULTS) -> bool:
    """`result == item` for a concrete (not traced) result, read on the host: `==`
    on two members is a JAX operation, which compiles a program (0.03 s, once a
    process) when called outside `jit`."""
    return int(np.asarray(result._value)) == int(np.asarray(item._value))


def status_name(result: RESULTS) -> str:
    """The member's name ("successful", "max_steps_reached", ...), for JSON and
    reports. Needs a concrete (not traced) result."""
    for name, item in RESULTS._name_to_item.items():
        if has_status(result, item):
            return name
    raise ValueError(f"status_name: {result!r} is not a RESULTS member.")


def status_message(result: RESULTS) -> str:
    """The member's message (empty for `successful`)."""
    return RESULTS[result]


def raise_unless_successful(result: RESULTS, caller: str) -> None:
    """Raise `RuntimeError` naming `caller` and the status when `result` is not
    `successful` (the `throw=True` behaviour of a host-side result)."""
    name = status_name(result)
    if name != "successful":
        raise RuntimeError(f"{caller}: {name}: {status_message(result)}.")
