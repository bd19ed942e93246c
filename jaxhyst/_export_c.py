"""C99 export of a quasi-static piezo model and its compensator, for the real-time
controllers stages run on.

`export_c(model, directory)` writes `<prefix>.h` and `<prefix>.c`: self-contained
C99 (only `<math.h>`), with the model's parameters as constants and

- `<prefix>_init(state, u0)`: the model at rest at drive `u0`;
- `<prefix>_step(state, u_next, dt)`: advance one sample with the drive ramping
  linearly to `u_next` (RK4 with the exported number of substeps and the model's
  sign rule, as `simulate` with `RK4(substeps)` and linear input); returns the
  output at the new sample;
- `<prefix>_compensate_step(state, y_ref, dt, lo, hi, &at_limit)`: the compensator
  of `compensate`: the drive in [lo, hi] nearest the present one whose step meets
  `y_ref` (the same bracket search and bisection), applied to the state;
  `at_limit` is set when `y_ref` is out of reach.

Exported: `PiezoBoucWen` and `CorrectedPiezoBoucWen` with phi = 0, with
`ExactSign`, `TanhSign` or `AlgebraicSign` smoothing.
"""

from pathlib import Path

from ._compensate import _EXPANSIONS
from ._files import Refusal, output_folder
from ._models.base import AbstractHysteresisModel
from ._smoothing import AlgebraicSign, ExactSign, TanhSign


def _sign_code(model: AbstractHysteresisModel) -> str:
    smoothing = model.smoothing
    if isinstance(smoothing, ExactSign):
        return "return (x > 0.0) - (x < 0.0);"
    if isinstance(smoothing, TanhSign):
        return f"return tanh(x / {float(smoothing.width)!r});"
    if isinstance(smoothing, AlgebraicSign):
        width = float(smoothing.width)
        return f"return x / sqrt(x * x + {width * width!r});"
    raise ValueError(
        f"export_c: no C form of the sign rule {type(smoothing).__name__}; use "
        "ExactSign, TanhSign or AlgebraicSign."
    )


_HEADER = """/* {prefix}.h: {model} exported by jaxhyst {version}. C99, needs <math.h>. */
#ifndef {guard}
#define {guard}

typedef struct {{
    double h; /* the hysteretic state */
    double u; /* the drive at the last sample */
}} {prefix}_state;

/* The model at rest at drive u0 (h = 0). */
void {prefix}_init({prefix}_state *state, double u0);

/* Output at the present sample. */
double {prefix}_output(const {prefix}_state *state);

/* Advance one sample of dt seconds, the drive ramping linearly to u_next; returns
   the output at the new sample. */
double {prefix}_step({prefix}_state *state, double u_next, double dt);

/* The drive in [lo, hi] nearest the present one whose step meets y_ref (brackets
   doubling from the present drive on the side where the output moves toward
   y_ref, then bisection, at most {iterations} halvings), applied to the state;
   *at_limit is 1 when y_ref is out of reach (the drive is then the one tried that came nearest, the nearer limit
   for a monotone model), else 0. */
double {prefix}_compensate_step({prefix}_state *state, double y_ref, double dt,
                                double lo, double hi, int *at_limit);

#endif
"""

_SOURCE = """/* {prefix}.c: {model} exported by jaxhyst {version}.
   y = k1*u + k2*h,
   hdot = (A1 - (beta1*sgn(udot)*sgn(h) + gamma1)*|h|^n)*udot + eps*u*sgn(udot),
   RK4 with {substeps} substep(s) per sample, drive linear between samples. */
#include <math.h>
#include "{prefix}.h"

static const double K1 = {k1!r};
static const double K2 = {k2!r};
static const double A1 = {A1!r};
static const double BETA1 = {beta1!r};
static const double GAMMA1 = {gamma1!r};
static const double N = {n!r};
static const double EPS = {eps!r};
static const int SUBSTEPS = {substeps};
static const int ITERATIONS = {iterations};
static const int EXPANSIONS = {expansions};

static double sgn(double x) {{ {sign} }}

static double abs_pow(double x) {{
    double a = x * sgn(x);
    return a > 0.0 ? pow(a, N) : 0.0;
}}

static double rate(double h, double u, double udot) {{
    double su = sgn(udot);
    return (A1 - (BETA1 * su * sgn(h) + GAMMA1) * abs_pow(h)) * udot + EPS * u * su;
}}

void {prefix}_init({prefix}_state *state, double u0) {{
    state->h = 0.0;
    state->u = u0;
}}

double {prefix}_output(const {prefix}_state *state) {{
    return K1 * state->u + K2 * state->h;
}}

static double advance(double h, double u0, double u1, double dt) {{
    double udot = (u1 - u0) / dt;
    double step = dt / SUBSTEPS;
    for (int j = 0; j < SUBSTEPS; ++j) {{
        double f0 = (double)j / SUBSTEPS;
        double fh = (j + 0.5) / SUBSTEPS;
        double f1 = (j + 1.0) / SUBSTEPS;
        double k1 = rate(h, u0 + f0 * dt * udot, udot);
        double k2 = rate(h + 0.5 * step * k1, u0 + fh * dt * udot, udot);
        double k3 = rate(h + 0.5 * step * k2, u0 + fh * dt * udot, udot);
        double k4 = rate(h + step * k3, u0 + f1 * dt * udot, udot);
        h = h + step / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
    }}
    return h;
}}

double {prefix}_step({prefix}_state *state, double u_next, double dt) {{
    state->h = advance(state->h, state->u, u_next, dt);
    state->u = u_next;
    return {prefix}_output(state);
}}

static double trial(const {prefix}_state *state, double u, double dt) {{
    return K1 * u + K2 * advance(state->h, state->u, u, dt);
}}

double {prefix}_compensate_step({prefix}_state *state, double y_ref, double dt,
                                double lo, double hi, int *at_limit) {{
    double u_now = state->u, f_now = trial(state, u_now, dt), g0 = f_now - y_ref;
    double first = ldexp(hi - lo, -EXPANSIONS);
    double up = fmin(u_now + first, hi), down = fmax(u_now - first, lo);
    int rising = trial(state, up, dt) >= trial(state, down, dt);
    double direction = (rising == (g0 < 0.0)) ? 1.0 : -1.0;
    double end = direction > 0.0 ? hi : lo;
    double a = u_now, b = u_now, best = u_now, g_best = g0, u;
    int found = g0 == 0.0;
    for (int k = 0; !found && k <= EXPANSIONS && b != end; ++k) {{
        double next = u_now + direction * ldexp(hi - lo, k - EXPANSIONS);
        next = direction > 0.0 ? fmin(next, hi) : fmax(next, lo);
        double g = trial(state, next, dt) - y_ref;
        found = !(g * g0 > 0.0);
        if (fabs(g) < fabs(g_best)) {{
            best = next;
            g_best = g;
        }}
        a = b;
        b = next;
    }}
    for (int i = 0; i < ITERATIONS; ++i) {{
        double mid = 0.5 * (a + b);
        if (mid == a || mid == b) break;
        if ((trial(state, mid, dt) - y_ref) * g0 > 0.0) a = mid; else b = mid;
    }}
    u = found ? 0.5 * (a + b) : best;
    *at_limit = !found && fabs(g_best) > 1e-9 * fmax(fabs(y_ref), fabs(f_now));
    {prefix}_step(state, u, dt);
    return u;
}}
"""


def export_c(
    model: AbstractHysteresisModel,
    directory: str | Path,
    *,
    prefix: str = "jaxhyst_model",
    substeps: int = 1,
    iterations: int = 52,
    overwrite: bool = False,
) -> tuple[Path, Path]:
    """Write `<prefix>.h` and `<prefix>.c` into `directory` (created if missing);
    returns their paths. `substeps`: RK4 steps per sample, as `RK4(substeps)` in
    `simulate`; `iterations`: the compensator's bisection halvings, as in
    `compensate`. Existing files are refused unless `overwrite`. The constants are
    the model's `c_export_parameters()` (a model without a C export refuses)."""
    import jaxhyst

    values = model.c_export_parameters()
    sign = _sign_code(model)
    if not prefix.isidentifier():
        raise ValueError(
            f"export_c: prefix {prefix!r} must be a C identifier (letters, digits, "
            "underscores, not starting with a digit)."
        )
    for name, value in (("substeps", substeps), ("iterations", iterations)):
        if not isinstance(value, int) or isinstance(value, bool) or value < 1:
            raise ValueError(
                f"export_c: {name} must be an integer >= 1, got {value!r}."
            )
    header, source = output_folder(
        directory,
        (f"{prefix}.h", f"{prefix}.c"),
        overwrite=overwrite,
        refusal=Refusal(
            "export_c", "overwrite=True", otherwise="choose another directory or prefix"
        ),
        create=True,
    )
    common = {
        "prefix": prefix,
        "model": type(model).__name__,
        "version": jaxhyst.__version__,
        "iterations": iterations,
        "expansions": _EXPANSIONS,
    }
    header.write_text(_HEADER.format(guard=prefix.upper() + "_H", **common))
    source.write_text(_SOURCE.format(sign=sign, substeps=substeps, **values, **common))
    return header, source
