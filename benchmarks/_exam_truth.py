"""The exam's truth (`exam.py`): simulators of its records, written apart from
jaxhyst's model classes, with effect forms that are in neither the diagnosis
catalogue (`jaxhyst/_diagnose/_effects`, `jaxhyst/_models`) nor `jaxhyst.synthetic`,
nor among the forms planned for the engine (Baber-Noori or series-slip pinching;
degradation driven by dissipated energy or peak excursion; creep as relaxation modes
or a logarithmic law; input bias as a pure delay or a first-order network; drift as
polynomials or a slow spline).

Only the base parameter ranges are shared with jaxhyst.synthetic (`base_truth`,
`structural_base_truth`; the damper's are drawn in `exam.py` in the damper suite's
ranges). The hysteresis is integrated here with fixed-step RK4 (JAX `lax.scan`,
float64) on the input linear between samples; linear filters with SciPy's `lsim`;
history kernels by FFT convolution of the input's increments. Every effect is off
at zero. `size` sets one effect's coefficient so that the change it makes alone
(against the base, or against the field dependence for a driver lag), less what a
refit of the base takes up to first order (`visible`: the change less its
least-squares projection on the base's output sensitivities), has the requested
RMS; the raw change stays within `RAW_CAP` sigmas and the bounds below.

Piezo (u in V, y in um; base y = k1*u + k2*h, hdot = (A1 - (beta1*sgn(Vdot*h) +
gamma1)*|h|^n)*Vdot with V = u, h(0) = 0):

- asymmetry
  - `output_square`: a gauge nonlinearity even in the measured displacement,
    y += a*(q^2 - q0^2 - s*y/Y), q = (y - c)/Y, q0 = -c/Y, Y half the base output's
    range, c a level 15-85 % up the range, s the base record's least-squares slope
    of q^2 - q0^2 on y/Y (the part a gain would take up).
  - `wang_wen`: Wang & Wen's asymmetric Bouc-Wen term,
    hdot = (A1 - (beta1*sgn(Vdot*h) + gamma1 + phi*sgn(Vdot))*|h|^n)*Vdot,
    |phi| <= 0.8*beta1 (the two branches saturate at different levels).
- input_bias (the hysteresis sees V, the linear part k1*u the drive itself, the
  catalogue's meaning of the effect)
  - `rlc`: a second-order (RLC) drive network,
    V'' = w_d^2*(u - V) - 2*zeta_d*w_d*V', zeta_d in [0.3, 0.7],
    w_d >= 2 pi max(4 f_drive, 2 Hz).
  - `play`: a backlash (play operator) of half-width r on the drive,
    V = min(max(V_prev, u - r), u + r), r <= 10 % of the drive's range.
- rate_dependence
  - `power_dashpot`: a fractional-power (nonlinear viscous) damping of the stage,
    y += c*sgn(udot)*|udot/R|^p, p in [0.3, 0.7], R the RMS drive rate.
  - `springpot`: a Scott-Blair springpot (fractional derivative of order a),
    y += c*D^a u = c*sum_j du_j*K(t - t_j), K(tau) = (tau/1 s)^-a/Gamma(1 - a),
    a in [0.3, 0.7]. (A velocity-dependent Bouc-Wen amplitude,
    A1*(1 + a*tanh(|Vdot|/R)), was tried: a single sine shows at most 1-2 sigmas
    of it that a base refit cannot take up, even at a = 3.)
- creep (Boltzmann superposition on the drive history, y += c*sum_j du_j*K(t - t_j),
  the increment of each sample interval at its midpoint)
  - `power_law`: K(tau) = (1 + tau/tau_0)^alpha - 1, alpha in [0.1, 0.4], onset
    tau_0 in [0.05, 0.3] s (Kuhnen, Jung-Gweon fractional creep).
  - `stretched`: K(tau) = 1 - exp(-(tau/tau_c)^b), b in [0.3, 0.6], tau_c 0.5-5 s
    (Kohlrausch-Williams-Watts).
- dynamics (y_s the quasi-static output, q the stage's; a mode too stiff to show
  is softened, down to max(15 Hz, 5 f_drive), participations at most 1)
  - `two_mode`: two stage modes, y = y_s + p*(q1 - y_s) + rho*p*(q2 - y_s),
    q_i'' = w_i^2*(y_s - q_i) - 2*z_i*w_i*q_i', f1 40-150 Hz, z1 0.03-0.15,
    f2/f1 in [2.2, 3.5], z2 0.05-0.2, rho 0.3-0.8.
  - `reid_damping`: one mode (40-150 Hz) with hysteretic (Reid, structural)
    damping, q'' = w^2*(y_s - q) - eta*w^2*|q - y_s|*sgn(q' - y_s'),
    eta in [0.1, 0.5] (sgn(v) smoothed as v/sqrt(v^2 + e^2), e = 1e-3 w range(y_s)),
    y = y_s + p*(q - y_s).
- drift (independent of the drive)
  - `hvac`: a thermal cycle of 1.2-3 periods per record,
    d = D*(sin(2 pi t/P + phi0) - sin(phi0)).
  - `step`: a smoothed zero shift, d = D*(S((t - t0)/w) - S(-t0/w)), S the
    logistic function, t0 30-70 % and w 3-10 % of the record.

Structural (x in mm, F in kN, pseudo time t = sample index; base F = alpha*k*x +
(1 - alpha)*k*z, zdot = (1 - (beta*sgn(xdot*z) + gamma)*|z|^n)*xdot, zu = x_y):

- degradation
  - `cycles`: strength lost per cycle: the yield level falls to zu/(1 + d*N(t)),
    N the number of completed excursions that passed x_y,
    zdot = (1 - (beta*sgn + gamma)*zu^n*|z/(lambda*zu)|^n)*xdot, lambda = 1/(1 + d*N),
    lambda >= 0.3 at the end.
  - `travel`: stiffness lost with the cumulative travel T(t) = sum|dx|/x_y,
    zdot = (...)*xdot/eta, eta = 1 + d*T/100 <= 4.
- pinching (m = min(1, (max|x|/x_y - 1)+/2) grows with the damage)
  - `crack_closure`: open cracks carry less force near the centre,
    F = alpha*k*x + (1 - alpha)*k*z*(1 - d*m*exp(-(x/(c*x_y))^2)), c in [0.5, 1.5],
    d <= 0.9.
  - `contact_gap`: a share s*m of the resistance is carried by contact (bearing,
    crack closure) that engages outside a gap g = g_r*(max|x| - x_y)+,
    F = alpha*k*x + (1 - s*m)*(1 - alpha)*k*z + s*m*F_y*sgn(x)*tanh((|x| - g)+/w),
    w = 0.3*x_y, F_y = (1 - alpha)*k*x_y, g_r in [0.3, 0.7], s <= 0.9.
- asymmetry
  - `gbw_direction`: the generalised Bouc-Wen's loading-direction term, shape
    (beta*sgn(xdot*z) + gamma + phi*sgn(xdot))*|z|^n, |phi| <= 0.8*(beta - gamma).
  - `side_sharpness`: the knee is sharper on one side, same strength,
    shape (beta*sgn + gamma)*zu^n*|z/zu|^(n*(1 + s*sgn(z))), |s| <= 0.6.
- drift (load cell)
  - `thermal_cycle`: F += D*(sin(2 pi t/P + phi0) - sin(phi0)), 1-3 periods.
  - `zero_shift`: F += D*(S((t - t0)/w) - S(-t0/w)), as the piezo `step`.

MR damper (x in cm, command v in V, F in N; base F = c0*xdot + k0*x + alpha*z + f0,
zdot = (1 - (beta*sgn(xdot*z) + gamma)*|z|^n)*xdot, ignoring the command):

- field_dependence (q = |w|/2.5 V, w the field's command; alpha -> alpha*(1 + G*g),
  c0 -> c0*(1 + rho*G*g), g(1) = 1, G <= 20, rho in [0.05, 0.3])
  - `langevin`: g = L(q/q_s)/L(1/q_s), L(x) = coth(x) - 1/x, q_s in [0.15, 0.5].
  - `hill`: g = q^h*(q_k^h + 1)/(q_k^h + q^h), h in [1.5, 2.5], q_k in [0.3, 0.7].
- driver_lag (w from v; always with field_dependence, sized on top of it)
  - `dead_time`: a second-order driver after a dead time,
    w'' = (v(t - T_d) - w)/T^2 - 2*zeta*w'/T, zeta in [0.35, 0.6], T <= 30 ms,
    T_d = 0.3-1 T.
  - `diffusive`: eddy-current diffusion, W(s) = 1/(1 + sqrt(s*T)), T <= 50 ms:
    the step response 1 - erfcx(sqrt(t/T)) (a slow t^-1/2 tail).
- rolloff
  - `series_spring`: the damper behind a compliant mount (a Maxwell element),
    F = k_s*(x - y) = c0*ydot + k0*y + alpha*z(y) + f0, k_s >= 0.3 alpha.
  - `leakage`: a bypass that carries the flow at low piston speed,
    alpha*z -> alpha*z*(1 - r*exp(-(xdot/v_b)^2)), r <= 0.9, v_b 10-40 % of the
    RMS speed.
- offset
  - `settle`: F += P*(1 - exp(-t/tau)), tau 0.2-0.6 of the record (in time, not
    in dissipated energy).
  - `zero_step`: F += D*(S((t - t0)/w) - S(-t0/w)), as the piezo `step`.
- asymmetry
  - `gas_spring`: a polytropic accumulator beyond its linear part,
    F += P*((1 - x/L)^-kappa - 1 - kappa*x/L), kappa in [1.0, 1.4], L 3-8 max|x|.
  - `one_sided_exponent`: the valving's force grows with another power of the
    speed in compression than in extension, c0*xdot -> c0*xdot*(|xdot|/v_r)^e on
    xdot > 0 only, |e| <= 0.5, v_r the RMS speed. (Wang & Wen's phi*sgn(xdot) term
    was tried too: it moves z's two saturation levels, which a base refit takes up
    nearly whole as f0 and alpha, and the dashpot hides the rest.)
"""

import functools
import math
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np
import scipy.signal
import scipy.special
from jax import lax


jax.config.update("jax_enable_x64", True)

PIEZO_FORMS: dict[str, tuple[str, ...]] = {
    "asymmetry": ("output_square", "wang_wen"),
    "input_bias": ("rlc", "play"),
    "rate_dependence": ("power_dashpot", "springpot"),
    "creep": ("power_law", "stretched"),
    "dynamics": ("two_mode", "reid_damping"),
    "drift": ("hvac", "step"),
}
STRUCTURAL_FORMS: dict[str, tuple[str, ...]] = {
    "degradation": ("cycles", "travel"),
    "pinching": ("crack_closure", "contact_gap"),
    "asymmetry": ("gbw_direction", "side_sharpness"),
    "drift": ("thermal_cycle", "zero_shift"),
}
DAMPER_FORMS: dict[str, tuple[str, ...]] = {
    "field_dependence": ("langevin", "hill"),
    "driver_lag": ("dead_time", "diffusive"),
    "rolloff": ("series_spring", "leakage"),
    "offset": ("settle", "zero_step"),
    "asymmetry": ("gas_spring", "one_sided_exponent"),
}
FORMS = {"piezo": PIEZO_FORMS, "structural": STRUCTURAL_FORMS, "damper": DAMPER_FORMS}

# A form that reaches less than this share of its target size gives way to the
# effect's other form (the one that comes closer is kept if neither reaches it).
REACHED = 0.9
# Sizes count the change a refit of the base cannot take up (to first order: the
# change less its least-squares projection on the base's output sensitivities); the
# raw change may be at most this many noise sigmas.
RAW_CAP = 60.0
_BATCH = 8  # simulations run side by side (one compilation per record length)


# ------------------------------------------------------------------------ helpers


def rms(x) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


def logistic(x):
    return 0.5 * (1.0 + np.tanh(0.5 * np.asarray(x)))


def loguniform(rng: np.random.Generator, low: float, high: float) -> float:
    return float(np.exp(rng.uniform(math.log(low), math.log(high))))


def pow2(need: float, most: int = 64) -> int:
    need = max(1, math.ceil(need))
    return min(2 ** math.ceil(math.log2(need)), most)


def noise(
    rng: np.random.Generator, kind: str, sigma: float, num: int, phi: tuple
) -> tuple[np.ndarray, str]:
    """White Gaussian or AR(1) noise of marginal standard deviation `sigma`."""
    white = rng.standard_normal(num)
    if kind == "white":
        return sigma * white, "white Gaussian"
    a = rng.uniform(*phi)
    drive = math.sqrt(1 - a * a) * white
    drive[0] = white[0]  # start in the stationary distribution
    ar = np.asarray(scipy.signal.lfilter([1.0], [1.0, -a], drive))
    return sigma * ar, f"AR(1) {a:.3g}"


def visible(change: np.ndarray, columns: np.ndarray) -> float:
    """RMS of `change` less its least-squares projection on `columns` (the base
    model's output sensitivities: what a refit of the base takes up to first
    order)."""
    scale = np.sqrt(np.mean(columns**2, axis=0))
    keep = scale > 0
    cols = columns[:, keep] / scale[keep]
    coef, *_ = np.linalg.lstsq(cols, change, rcond=None)
    return rms(change - cols @ coef)


def second_order(t, x, omega: float, zeta: float) -> np.ndarray:
    """x through omega^2/(s^2 + 2 zeta omega s + omega^2), from rest at x[0]."""
    system = scipy.signal.lti([omega**2], [1.0, 2 * zeta * omega, omega**2])
    _, out, _ = scipy.signal.lsim(system, x - x[0], t)
    return np.asarray(out) + x[0]


def history(u: np.ndarray, kernel: Callable, dt: float) -> np.ndarray:
    """sum_j du_j*kernel(t - t_j), the increments at their interval's midpoint."""
    du = np.diff(u)
    lags = (np.arange(du.size) + 0.5) * dt
    out = scipy.signal.fftconvolve(du, kernel(lags))[: du.size]
    return np.concatenate([[0.0], out])


class _Sizing:
    """What every family's record shares for sizing: the base's output sensitivities
    (`columns`), the noise sigma, and the raw change allowed (`RAW_CAP` sigmas)."""

    columns: np.ndarray
    y_base: np.ndarray
    y_base_for_sweep: np.ndarray
    sigma: float = 1.0

    def seen(self, change: np.ndarray) -> float:
        """The size that counts: the change less what a base refit takes up."""
        return visible(change, self.columns)

    def linear(self, unit: np.ndarray, target: float, most: float = math.inf):
        """(coefficient, size reached) of a change linear in its coefficient
        (`unit` at 1), the coefficient at most `most` and the raw change at most
        `RAW_CAP` sigmas."""
        seen, raw = self.seen(unit), rms(unit)
        if not seen > 0:
            return 0.0, 0.0
        c = min(target / seen, most, RAW_CAP * self.sigma / raw)
        return c, c * seen

    def sweep(self, build: Callable[[float], dict]):
        """A vectorised size measure for `size_search`: `build(g)` gives the output
        at coefficient g; NaN where the raw change passes `RAW_CAP` sigmas."""

        def measure(grid):
            ys = self.outputs([build(g) for g in grid])  # pyright: ignore[reportAttributeAccessIssue]
            sizes = []
            for y in ys:
                change = y - self.y_base_for_sweep
                ok = rms(change) <= RAW_CAP * self.sigma
                sizes.append(self.seen(change) if ok else np.nan)
            return np.asarray(sizes)

        return measure


def size_search(
    measure: Callable[[np.ndarray], np.ndarray],
    target: float,
    low: float,
    high: float,
) -> tuple[float, float]:
    """A coefficient in (0, high] whose RMS change (`measure`, vectorised over
    coefficients) is `target`: a log grid, then two refinements around the log-log
    interpolated crossing. Returns (coefficient, RMS reached); `high` with what it
    reaches when even that falls short."""
    grid = np.geomspace(low, high, _BATCH)
    values = np.asarray(measure(grid))
    for _ in range(3):
        good = np.isfinite(values) & (values > 0)
        p, r = grid[good], values[good]
        if p.size == 0:
            return float(high), 0.0
        if r.max() < target:
            best = int(np.argmax(r))
            return float(p[best]), float(r[best])
        above = np.flatnonzero(r >= target)
        i = int(above[0])
        if i == 0:
            lo, hi = p[0] / 10, p[0]
            rl, rh = np.nan, r[0]
        else:
            lo, hi, rl, rh = p[i - 1], p[i], r[i - 1], r[i]
        if abs(rh / target - 1) < 0.005:
            return float(hi), float(rh)
        if np.isfinite(rl) and rl > 0 and rh > rl:
            w = math.log(target / rl) / math.log(rh / rl)
            centre = math.exp(math.log(lo) + w * math.log(hi / lo))
        else:
            centre = math.sqrt(lo * hi)
        span = min(hi / lo, 4.0) ** 0.5
        grid = np.clip(np.geomspace(centre / span, centre * span, _BATCH), 0, high)
        grid = np.maximum(grid, 1e-300)
        values = np.asarray(measure(grid))
    good = np.isfinite(values) & (values > 0)
    p, r = grid[good], values[good]
    best = int(np.argmin(np.abs(np.log(r / target))))
    return float(p[best]), float(r[best])


def _chunks(arrays: dict, fn: Callable) -> list[np.ndarray]:
    """`fn` on the batch of `arrays` (leading axis) in chunks of `_BATCH`, padded
    with copies of the last member so that each shape compiles once."""
    count = len(next(iter(arrays.values())))
    out = []
    for start in range(0, count, _BATCH):
        part = {k: np.asarray(v[start : start + _BATCH]) for k, v in arrays.items()}
        n = len(next(iter(part.values())))
        if n < _BATCH:
            part = {
                k: np.concatenate([v, np.repeat(v[-1:], _BATCH - n, axis=0)])
                for k, v in part.items()
            }
        result = np.asarray(fn(**{k: jnp.asarray(v) for k, v in part.items()}))
        out.extend(result[:n])
    return out


def _rk4(field, y, s0, h, substeps: int):
    def sub(carry, _):
        y, s = carry
        k1 = field(y, s)
        k2 = field(y + 0.5 * h * k1, s + 0.5 * h)
        k3 = field(y + 0.5 * h * k2, s + 0.5 * h)
        k4 = field(y + h * k3, s + h)
        return (y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4), s + h), None

    (y, _), _ = lax.scan(sub, (y, s0), None, length=substeps)
    return y


# ------------------------------------------------------------------------- piezo


@functools.partial(jax.jit, static_argnames="substeps")
def _piezo_h(V, A1, beta1, gamma1, n, phi, *, dt, substeps):
    """h under V (batch, samples), the Bouc-Wen law with the Wang-Wen term."""

    def one(V, A1, beta1, gamma1, n, phi):
        rates = jnp.diff(V) / dt

        def interval(h, vdot):
            amp = A1
            sv = jnp.sign(vdot)

            def field(h, _):
                shape = beta1 * sv * jnp.sign(h) + gamma1 + phi * sv
                return (amp - shape * jnp.abs(h) ** n) * vdot

            h = _rk4(field, h, 0.0, dt / substeps, substeps)
            return h, h

        _, hs = lax.scan(interval, jnp.zeros((), V.dtype), rates)
        return jnp.concatenate([jnp.zeros(1, V.dtype), hs])

    return jax.vmap(one)(V, A1, beta1, gamma1, n, phi)


@functools.partial(jax.jit, static_argnames="substeps")
def _reid_mode(ys, omega, eta, eps, *, dt, substeps):
    """q'' = w^2 (y_s - q) - eta w^2 |q - y_s| sgn(q' - y_s'), y_s linear between
    samples; q from rest at y_s[0]."""
    rates = jnp.diff(ys) / dt

    def interval(state, inp):
        y0, yd = inp

        def field(st, s):
            q, qd = st[0], st[1]
            d = q - (y0 + yd * s)
            rel = qd - yd
            damp = eta * omega**2 * jnp.abs(d) * rel / jnp.sqrt(rel**2 + eps**2)
            return jnp.stack([qd, -(omega**2) * d - damp])

        state = _rk4(field, state, 0.0, dt / substeps, substeps)
        return state, state[0]

    start = jnp.stack([ys[0], jnp.zeros((), ys.dtype)])
    _, q = lax.scan(interval, start, (ys[:-1], rates))
    return jnp.concatenate([ys[:1], q])


def slow_shape(t: np.ndarray, form: str, p: dict) -> np.ndarray:
    """The unit shape of a drift or offset form on the time axis `t` (from 0)."""
    t = t - t[0]
    if form in ("hvac", "thermal_cycle"):
        return np.sin(2 * np.pi * t / p["P"] + p["phase"]) - np.sin(p["phase"])
    if form == "settle":
        return -np.expm1(-t / p["tau"])
    return logistic((t - p["t0"]) / p["w"]) - logistic(-p["t0"] / p["w"])


def _kernel(form: str, p: dict) -> Callable[[np.ndarray], np.ndarray]:
    """The history kernel K(tau) of a creep or springpot form."""
    if form == "springpot":
        scale = 1 / scipy.special.gamma(1 - p["a"])
        return lambda s: scale * s ** -p["a"]
    if form == "power_law":
        return lambda s: (1 + s / p["tau"]) ** p["alpha"] - 1
    return lambda s: -np.expm1(-((s / p["tau"]) ** p["b"]))


def play(u: np.ndarray, r: float) -> np.ndarray:
    v = np.empty_like(u)
    last = u[0]
    for i, x in enumerate(u):
        last = min(max(last, x - r), x + r)
        v[i] = last
    return v


class Piezo(_Sizing):
    """One piezo record's base and drive; `outputs(specs)` simulates truths.

    A spec maps effect -> (form, parameters)."""

    def __init__(self, t, u, base: dict, drive_frequency: float):
        self.t, self.u = np.asarray(t, float), np.asarray(u, float)
        self.dt = float(self.t[1] - self.t[0])
        self.base = {k: float(v) for k, v in base.items()}
        self.frequency = drive_frequency
        self.duration = float(self.t[-1] - self.t[0])
        self.udot = np.gradient(self.u, self.dt)
        self.rate_rms = rms(np.diff(self.u) / self.dt)
        top = float(np.max(np.abs(np.diff(self.u)))) / self.dt
        sat = (base["beta1"] - base["gamma1"]) ** (-1 / base["n"])
        # RK4 steps moving V by at most 2 % of the saturation level of h.
        self.substeps = pow2(top * self.dt / (0.02 * sat), 16)
        self.h_base = self._simulate_h([{}])[0]
        self.y_base = self.outputs([{}])[0]
        self.columns = self.sensitivities()

    _SIMULATED = ("input_bias", "_base")

    def _hysteresis(self, specs) -> list[np.ndarray]:
        cached = getattr(self, "h_base", None)
        need = [
            i
            for i, s in enumerate(specs)
            if cached is None
            or any(k in s for k in self._SIMULATED)
            or s.get("asymmetry", (None,))[0] == "wang_wen"
        ]
        out: list = [cached] * len(specs)
        if need:
            for i, h in zip(need, self._simulate_h([specs[i] for i in need])):
                out[i] = h
        return out

    def _simulate_h(self, specs) -> list[np.ndarray]:
        b = self.base
        rows: dict[str, list] = {k: [] for k in ("V", "phi")}
        for spec in specs:
            form, p = spec.get("input_bias", (None, {}))
            if form == "rlc":
                V = second_order(self.t, self.u, p["omega"], p["zeta"])
            elif form == "play":
                V = play(self.u, p["r"])
            else:
                V = self.u
            form_a, pa = spec.get("asymmetry", (None, {}))
            rows["V"].append(V)
            rows["phi"].append(pa["phi"] if form_a == "wang_wen" else 0.0)
        count = len(specs)
        run = functools.partial(_piezo_h, dt=self.dt, substeps=self.substeps)
        params = {k: np.full(count, b[k]) for k in ("A1", "beta1", "gamma1", "n")} | {
            k: np.asarray(v) for k, v in rows.items()
        }
        for key in ("A1", "beta1", "gamma1", "n"):
            if any(key in s.get("_base", {}) for s in specs):
                params[key] = np.asarray(
                    [s.get("_base", {}).get(key, b[key]) for s in specs]
                )
        return _chunks(params, run)

    def outputs(self, specs: list[dict]) -> list[np.ndarray]:
        b = self.base
        out = []
        for spec, h in zip(specs, self._hysteresis(specs)):
            y = b["k1"] * self.u + b["k2"] * h
            form, p = spec.get("rate_dependence", (None, {}))
            if form == "power_dashpot":
                y = (
                    y
                    + p["c"]
                    * np.sign(self.udot)
                    * np.abs(self.udot / self.rate_rms) ** p["p"]
                )
            elif form == "springpot":
                y = y + p["c"] * history(self.u, _kernel(form, p), self.dt)
            form, p = spec.get("creep", (None, {}))
            if form is not None:
                y = y + p["c"] * history(self.u, _kernel(form, p), self.dt)
            form, p = spec.get("dynamics", (None, {}))
            if form == "two_mode":
                q1 = second_order(self.t, y, p["omega1"], p["zeta1"])
                q2 = second_order(self.t, y, p["omega2"], p["zeta2"])
                y = y + p["p"] * (q1 - y) + p["p"] * p["rho"] * (q2 - y)
            elif form == "reid_damping":
                sub = pow2(p["omega"] * self.dt / 0.1, 64)
                eps = 1e-3 * p["omega"] * float(np.ptp(y))
                q = np.asarray(
                    _reid_mode(
                        jnp.asarray(y),
                        p["omega"],
                        p["eta"],
                        eps,
                        dt=self.dt,
                        substeps=sub,
                    )
                )
                y = y + p["p"] * (q - y)
            form, p = spec.get("asymmetry", (None, {}))
            if form == "output_square":
                y = y + p["a"] * self.square(y, p)
            form, p = spec.get("drift", (None, {}))
            if form is not None:
                y = y + p["D"] * slow_shape(self.t, form, p)
            out.append(y)
        return out

    @staticmethod
    def square(y, p):
        q, q0 = (y - p["c"]) / p["Y"], -p["c"] / p["Y"]
        return q**2 - q0**2 - p["s"] * y / p["Y"]

    def sensitivities(self) -> np.ndarray:
        """Output sensitivities to k1, k2, A1, beta1, gamma1, n (columns)."""
        b = self.base
        specs, steps = [{}], []
        for key in ("A1", "beta1", "gamma1", "n"):
            step = 1e-6 * max(abs(b[key]), 1e-12)
            specs.append({"_base": {key: b[key] + step}})
            steps.append(step)
        hs = self._hysteresis(specs)
        cols = [self.u, hs[0]]
        cols += [b["k2"] * (h - hs[0]) / s for h, s in zip(hs[1:], steps)]
        return np.stack(cols, axis=1)

    # -------------------------------------------------------------- sizing

    def size(self, effect: str, form: str, rng, target: float):
        """(parameters, size reached, words) of `form` at `target` (sizes are
        visible changes, `_Sizing.seen`)."""
        y0 = self.y_base_for_sweep = self.y_base

        def sweep(make):
            return self.sweep(lambda g: {effect: (form, make(g))})

        def alone(p):
            return self.outputs([{effect: (form, p)}])[0] - y0

        sign = float(rng.choice([-1.0, 1.0]))
        if form == "output_square":
            Y = float(np.ptp(y0)) / 2
            c = float(np.min(y0)) + rng.uniform(0.15, 0.85) * float(np.ptp(y0))
            q, q0 = (y0 - c) / Y, -c / Y
            s = float(np.dot(q**2 - q0**2, y0 / Y) / np.dot(y0 / Y, y0 / Y))
            p = {"c": c, "Y": Y, "s": s, "a": sign}
            a, r = self.linear(self.square(y0, p), target)
            p["a"] = sign * a
            return p, r, f"y += {p['a']:.4g}*(q^2 - q0^2 - {s:.3g} y/Y), c {c:.3g} um"
        if form == "wang_wen":
            cap = 0.8 * self.base["beta1"]
            phi, r = size_search(
                sweep(lambda g: {"phi": sign * g}), target, cap / 1e3, cap
            )
            return (
                {"phi": sign * phi},
                r,
                f"phi {sign * phi:.4g} (beta1 {cap / 0.8:.4g})",
            )
        if form == "rlc":
            zeta = rng.uniform(0.3, 0.7)
            slowest = 2 * np.pi * max(4 * self.frequency, 2.0)
            time, r = size_search(
                sweep(lambda g: {"omega": 1 / g, "zeta": zeta}),
                target,
                1e-5,
                1 / slowest,
            )
            words = f"RLC network {1 / (2 * np.pi * time):.4g} Hz, zeta {zeta:.3g}"
            return {"omega": 1 / time, "zeta": zeta}, r, words
        if form == "play":
            cap = 0.1 * float(np.ptp(self.u))
            width, r = size_search(sweep(lambda g: {"r": g}), target, cap / 1e3, cap)
            return {"r": width}, r, f"play half-width {width:.4g} V"
        if form == "springpot":
            order = rng.uniform(0.3, 0.7)
            c, r = self.linear(alone({"a": order, "c": 1.0}), target)
            return (
                {"a": order, "c": c},
                r,
                f"springpot {c:.4g} um s^a/V, order {order:.3g}",
            )
        if form == "power_dashpot":
            power = rng.uniform(0.3, 0.7)
            unit = np.sign(self.udot) * np.abs(self.udot / self.rate_rms) ** power
            c, r = self.linear(unit, target)
            return {"c": c, "p": power}, r, f"{c:.4g} um*sgn(udot)|udot/R|^{power:.3g}"
        if form in ("power_law", "stretched"):
            if form == "power_law":
                alpha, onset = rng.uniform(0.1, 0.4), rng.uniform(0.05, 0.3)
                p = {"alpha": alpha, "tau": onset, "c": 1.0}
                words = f"K = (1 + tau/{onset:.3g} s)^{alpha:.3g} - 1"
            else:
                tau, b = loguniform(rng, 0.5, 5.0), rng.uniform(0.3, 0.6)
                p = {"tau": tau, "b": b, "c": 1.0}
                words = f"K = 1 - exp(-(tau/{tau:.3g} s)^{b:.3g})"
            # Creep continues the drive's motion (c > 0).
            c, r = self.linear(alone(p), target)
            p["c"] = c
            return p, r, f"{words}, c {c:.4g} um/V"
        if form == "two_mode":
            f1 = loguniform(rng, 40.0, 150.0)
            p = {
                "omega1": 2 * np.pi * f1,
                "zeta1": rng.uniform(0.03, 0.15),
                "omega2": 2 * np.pi * f1 * rng.uniform(2.2, 3.5),
                "zeta2": rng.uniform(0.05, 0.2),
                "rho": rng.uniform(0.3, 0.8),
                "p": 1.0,
            }
            return self._size_mode(alone, p, target, "omega1", "omega2")
        if form == "reid_damping":
            p = {
                "omega": 2 * np.pi * loguniform(rng, 40.0, 150.0),
                "eta": rng.uniform(0.1, 0.5),
                "p": 1.0,
            }
            return self._size_mode(alone, p, target, "omega")
        if form in ("hvac", "step"):
            T = self.duration
            if form == "hvac":
                p = {"P": T / rng.uniform(1.2, 3.0), "phase": rng.uniform(0, 2 * np.pi)}
                words = f"period {p['P']:.3g} s"
            else:
                p = {"t0": rng.uniform(0.3, 0.7) * T, "w": rng.uniform(0.03, 0.1) * T}
                words = f"step at {p['t0']:.3g} s over {p['w']:.3g} s"
            D, r = self.linear(slow_shape(self.t, form, p), target)
            p["D"] = sign * D
            return p, r, f"{words}, D {sign * D:.4g} um"
        raise ValueError(form)

    def _size_mode(self, alone, p, target, *omegas):
        """Participation p <= 1; a mode too stiff to show is softened (down to 5x
        the drive frequency and 15 Hz), as a stage with a lower mode would be."""
        floor = 2 * np.pi * max(15.0, 5 * self.frequency)
        while True:
            part, r = self.linear(alone(p), target, most=1.0)
            if r >= 0.999 * target or p[omegas[0]] <= floor * 1.0001:
                break
            factor = max(0.7, floor / p[omegas[0]])
            for key in omegas:
                p[key] *= factor
        p["p"] = part
        hz = "/".join(f"{p[k] / (2 * np.pi):.4g}" for k in omegas)
        return p, r, f"mode(s) {hz} Hz, participation {part:.4g}"


# -------------------------------------------------------------------- structural


@functools.partial(jax.jit, static_argnames="substeps")
def _structural_z(x, lam, eta, beta, gamma, n, phi, s, *, substeps):
    """z under x (pseudo time, dt = 1) with the exam's terms, per batch member."""
    rates = jnp.diff(x)

    def one(lam, eta, beta, gamma, n, phi, s):
        zu = (1 / (beta + gamma)) ** (1 / n)

        def interval(z, inp):
            xd, level, soft = inp
            sx = jnp.sign(xd)

            def field(z, _):
                expo = n * (1 + s * jnp.sign(z))
                shape = (beta * sx * jnp.sign(z) + gamma + phi * sx) * zu**n
                ratio = jnp.abs(z) / (level * zu)
                return (1 - shape * ratio**expo) * xd / soft

            z = _rk4(field, z, 0.0, 1.0 / substeps, substeps)
            return z, z

        _, zs = lax.scan(interval, jnp.zeros((), x.dtype), (rates, lam[:-1], eta[:-1]))
        return jnp.concatenate([jnp.zeros(1, x.dtype), zs])

    return jax.vmap(one)(lam, eta, beta, gamma, n, phi, s)


class Structural(_Sizing):
    """One structural test's base and protocol; `outputs(specs)` simulates."""

    def __init__(self, x, base: dict):
        self.x = np.asarray(x, float)
        self.t = np.arange(self.x.size, dtype=float)
        self.duration = float(self.x.size - 1)
        self.base = {k: float(v) for k, v in base.items()}
        b = self.base
        self.x_y = (1 / (b["beta"] + b["gamma"])) ** (1 / b["n"])
        self.f_y = (1 - b["alpha"]) * b["k"] * self.x_y
        ax = np.abs(self.x)
        self.peak = np.maximum.accumulate(ax)
        self.travel = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(self.x)))])
        self.travel /= self.x_y
        # Completed excursions that passed x_y, counted at their turning point.
        d = np.diff(self.x)
        turn = np.flatnonzero(np.sign(d[1:]) * np.sign(d[:-1]) < 0) + 1
        counted = np.zeros(self.x.size)
        counted[turn[ax[turn] > self.x_y]] = 1
        self.cycles = np.cumsum(counted)
        self.damage = np.minimum(1.0, np.maximum(self.peak / self.x_y - 1, 0) / 2)
        largest = float(np.max(np.abs(d)))
        self.substeps = pow2(largest / (0.02 * self.x_y), 64)
        self.z_base = self._z([{}])[0]
        self.y_base = self._force({}, self.z_base)
        self.columns = self.sensitivities()

    def _z(self, specs) -> list[np.ndarray]:
        cached = getattr(self, "z_base", None)
        keys = ("degradation", "asymmetry", "_base")
        need = [
            i
            for i, s in enumerate(specs)
            if cached is None or any(k in s for k in keys)
        ]
        out: list = [cached] * len(specs)
        if need:
            for i, z in zip(need, self._simulate_z([specs[i] for i in need])):
                out[i] = z
        return out

    def _simulate_z(self, specs) -> list[np.ndarray]:
        b = self.base
        count = len(specs)
        lam = np.ones((count, self.x.size))
        eta = np.ones((count, self.x.size))
        phi, s = np.zeros(count), np.zeros(count)
        params = {k: np.full(count, b[k]) for k in ("beta", "gamma", "n")}
        for i, spec in enumerate(specs):
            form, p = spec.get("degradation", (None, {}))
            if form == "cycles":
                lam[i] = 1 / (1 + p["d"] * self.cycles)
            elif form == "travel":
                eta[i] = 1 + p["d"] * self.travel / 100
            form, p = spec.get("asymmetry", (None, {}))
            if form == "gbw_direction":
                phi[i] = p["phi"]
            elif form == "side_sharpness":
                s[i] = p["s"]
            for key, value in spec.get("_base", {}).items():
                params[key][i] = value
        run = functools.partial(
            _structural_z, jnp.asarray(self.x), substeps=self.substeps
        )
        return _chunks({"lam": lam, "eta": eta, **params, "phi": phi, "s": s}, run)

    def _force(self, spec, z) -> np.ndarray:
        b, x = self.base, self.x
        hyst = (1 - b["alpha"]) * b["k"] * z
        F = b["alpha"] * b["k"] * x
        form, p = spec.get("pinching", (None, {}))
        if form == "crack_closure":
            window = np.exp(-((x / (p["c"] * self.x_y)) ** 2))
            F = F + hyst * (1 - p["d"] * self.damage * window)
        elif form == "contact_gap":
            F = F + hyst + p["s"] * self.damage * (self.contact(p) - hyst)
        else:
            F = F + hyst
        form, p = spec.get("drift", (None, {}))
        if form is not None:
            F = F + p["D"] * slow_shape(self.t, form, p)
        return F

    def contact(self, p) -> np.ndarray:
        gap = p["g"] * np.maximum(self.peak - self.x_y, 0)
        open_ = np.maximum(np.abs(self.x) - gap, 0)
        return self.f_y * np.sign(self.x) * np.tanh(open_ / (0.3 * self.x_y))

    def outputs(self, specs: list[dict]) -> list[np.ndarray]:
        return [self._force(s, z) for s, z in zip(specs, self._z(specs))]

    def sensitivities(self) -> np.ndarray:
        """Output sensitivities to k, alpha (through x and z), beta, gamma, n."""
        b = self.base
        specs, steps = [{}], []
        for key in ("beta", "gamma", "n"):
            step = 1e-6 * abs(b[key]) if b[key] else 1e-9
            specs.append({"_base": {key: b[key] + step}})
            steps.append(step)
        zs = self._z(specs)
        scale = (1 - b["alpha"]) * b["k"]
        cols = [self.x, zs[0]]
        cols += [scale * (z - zs[0]) / s for z, s in zip(zs[1:], steps)]
        return np.stack(cols, axis=1)

    def size(self, effect: str, form: str, rng, target: float):
        y0 = self.y_base_for_sweep = self.y_base

        def sweep(make):
            return self.sweep(lambda g: {effect: (form, make(g))})

        def alone(p):
            return self._force({effect: (form, p)}, self.z_base) - y0

        sign = float(rng.choice([-1.0, 1.0]))
        if form == "cycles":
            # Capped where the last cycle keeps 30 % of the strength.
            cap = (1 / 0.3 - 1) / max(float(self.cycles[-1]), 1.0)
            d, r = size_search(sweep(lambda g: {"d": g}), target, cap / 1e3, cap)
            words = f"yield level / (1 + {d:.4g} N), N to {self.cycles[-1]:.0f}"
            return {"d": d}, r, words
        if form == "travel":
            cap = 3.0 / max(float(self.travel[-1]) / 100, 1e-9)  # stiffness / 4
            d, r = size_search(sweep(lambda g: {"d": g}), target, cap / 1e3, cap)
            words = f"stiffness / (1 + {d:.4g} T/100), T to {self.travel[-1]:.0f} x_y"
            return {"d": d}, r, words
        if form == "crack_closure":
            c = rng.uniform(0.5, 1.5)
            d, r = self.linear(alone({"c": c, "d": 1.0}), target, most=0.9)
            return {"c": c, "d": d}, r, f"depth {d:.4g}, window {c:.3g} x_y"
        if form == "contact_gap":
            g = rng.uniform(0.3, 0.7)
            s, r = self.linear(alone({"g": g, "s": 1.0}), target, most=0.9)
            words = f"contact share {s:.4g}, gap {g:.3g}(max|x| - x_y)"
            return {"g": g, "s": s}, r, words
        if form == "gbw_direction":
            cap = 0.8 * (self.base["beta"] - self.base["gamma"])
            if not cap > 0:
                return {"phi": 0.0}, 0.0, "no room (beta = gamma)"
            phi, r = size_search(
                sweep(lambda g: {"phi": sign * g}), target, cap / 1e3, cap
            )
            return {"phi": sign * phi}, r, f"phi {sign * phi:.4g}"
        if form == "side_sharpness":
            s, r = size_search(sweep(lambda g: {"s": sign * g}), target, 1e-3, 0.6)
            return {"s": sign * s}, r, f"exponent n*(1 + {sign * s:.3g} sgn z)"
        if form in ("thermal_cycle", "zero_shift"):
            T = self.duration
            if form == "thermal_cycle":
                p = {"P": T / rng.uniform(1.0, 3.0), "phase": rng.uniform(0, 2 * np.pi)}
                words = f"period {p['P']:.0f} samples"
            else:
                p = {"t0": rng.uniform(0.3, 0.7) * T, "w": rng.uniform(0.03, 0.1) * T}
                words = f"shift at sample {p['t0']:.0f} over {p['w']:.0f}"
            D, r = self.linear(slow_shape(self.t, form, p), target)
            p["D"] = sign * D
            return p, r, f"{words}, D {sign * D:.4g} kN"
        raise ValueError(form)


# ------------------------------------------------------------------------ damper

FULL_SCALE = 2.5  # V, the command's range


@functools.partial(jax.jit, static_argnames=("substeps", "series"))
def _damper_z(x, av, cv, k0, f0, beta, gamma, n, ks, *, dt, substeps, series):
    """z (and the block's displacement y) per batch member; av, cv the field's
    alpha and c0 per sample."""
    rates = jnp.diff(x) / dt

    def one(av, cv, k0, f0, beta, gamma, n, ks):
        def interval(state, inp):
            x0, xd, a, c = inp

            def field(st, s):
                z, y = st[0], st[1]
                if series:
                    yd = (ks * (x0 + xd * s - y) - a * z - k0 * y - f0) / c
                else:
                    yd = xd
                sr = jnp.sign(yd)
                shape = beta * sr * jnp.sign(z) + gamma
                return jnp.stack([(1 - shape * jnp.abs(z) ** n) * yd, yd])

            state = _rk4(field, state, 0.0, dt / substeps, substeps)
            return state, state

        y0 = (ks * x[0] - f0) / (ks + k0) if series else x[0]
        start = jnp.stack([jnp.zeros((), x.dtype), y0])
        _, states = lax.scan(interval, start, (x[:-1], rates, av[:-1], cv[:-1]))
        return jnp.concatenate([start[None], states])

    return jax.vmap(one)(av, cv, k0, f0, beta, gamma, n, ks)


class Damper(_Sizing):
    """One damper test's base, displacement and command; `outputs(specs)`."""

    def __init__(self, t, x, v, base: dict):
        self.t, self.x, self.v = (np.asarray(a, float) for a in (t, x, v))
        self.dt = float(self.t[1] - self.t[0])
        self.duration = float(self.t[-1] - self.t[0])
        self.base = {k: float(vv) for k, vv in base.items()}
        self.xdot = np.concatenate([np.diff(self.x) / self.dt, [0.0]])
        self.speed_rms = rms(np.diff(self.x) / self.dt)
        b = self.base
        z_y = (1 / (b["beta"] + b["gamma"])) ** (1 / b["n"])
        self.z_y = z_y
        velocity = float(np.max(np.abs(np.diff(self.x)))) / self.dt
        self.bw_rate = b["n"] * velocity / z_y
        self.substeps = pow2(self.bw_rate * self.dt, 64)
        self.states_base = self._simulate_states([{}])[0]
        self.z_base = self.states_base[:, 0]
        self.y_base = self.outputs([{}])[0]
        self.columns = self.sensitivities()

    def field(self, spec, w=None) -> np.ndarray:
        """g(w) of the spec's field form (0 without field dependence)."""
        form, p = spec.get("field_dependence", (None, {}))
        if form is None:
            return np.zeros_like(self.x)
        if w is None:
            w = self.command_seen(spec)
        q = np.abs(w) / FULL_SCALE
        if form == "langevin":

            def L(a):
                a = np.maximum(a, 1e-9)
                return np.where(a < 1e-3, a / 3, 1 / np.tanh(a) - 1 / a)

            return L(q / p["qs"]) / L(1 / p["qs"])
        h, k = p["h"], p["qk"]
        return q**h * (k**h + 1) / (k**h + q**h)

    def command_seen(self, spec) -> np.ndarray:
        form, p = spec.get("driver_lag", (None, {}))
        if form == "dead_time":
            delayed = np.interp(self.t - p["Td"], self.t, self.v)
            return second_order(self.t, delayed, 1 / p["T"], p["zeta"])
        if form == "diffusive":
            step = lambda s: 1 - scipy.special.erfcx(np.sqrt(s / p["T"]))
            return self.v[0] + history(self.v, step, self.dt)
        return self.v

    def _gains(self, spec):
        b = self.base
        g = self.field(spec)
        form, p = spec.get("field_dependence", (None, {}))
        G, rho = (p["G"], p["rho"]) if form is not None else (0.0, 0.0)
        return b["alpha"] * (1 + G * g), b["c0"] * (1 + rho * G * g)

    def _states(self, specs) -> list[np.ndarray]:
        cached = getattr(self, "states_base", None)

        def simulated(s) -> bool:
            return "_base" in s or s.get("rolloff", (None,))[0] == "series_spring"

        need = [i for i, s in enumerate(specs) if cached is None or simulated(s)]
        out: list = [cached] * len(specs)
        rigid = [
            i for i in need if specs[i].get("rolloff", (None,))[0] != "series_spring"
        ]
        series = [i for i in need if i not in rigid]
        for group in (rigid, series):
            if group:
                states = self._simulate_states([specs[i] for i in group])
                for i, st in zip(group, states):
                    out[i] = st
        return out

    def _simulate_states(self, specs) -> list[np.ndarray]:
        b = self.base
        count = len(specs)
        av, cv = np.empty((count, self.x.size)), np.empty((count, self.x.size))
        ks = np.ones(count)
        params = {k: np.full(count, b[k]) for k in ("k0", "f0", "beta", "gamma", "n")}
        series = False
        for i, spec in enumerate(specs):
            av[i], cv[i] = self._gains(spec)
            form, p = spec.get("rolloff", (None, {}))
            if form == "series_spring":
                ks[i], series = p["ks"], True
            for key, value in spec.get("_base", {}).items():
                params[key][i] = value
        if series and not all(
            s.get("rolloff", (None,))[0] == "series_spring" for s in specs
        ):
            raise ValueError("a batch mixes series-spring and rigid dampers")
        substeps = self.substeps
        if series:
            stiff = float(np.max(ks)) / float(np.min(cv))
            substeps = pow2(max(self.bw_rate, 2 * stiff) * self.dt, 64)
        run = functools.partial(
            _damper_z,
            jnp.asarray(self.x),
            dt=self.dt,
            substeps=substeps,
            series=series,
        )
        return _chunks({"av": av, "cv": cv, **params, "ks": ks}, run)

    def outputs(self, specs: list[dict]) -> list[np.ndarray]:
        b = self.base
        out = []
        for spec, states in zip(specs, self._states(specs)):
            z, y = states[:, 0], states[:, 1]
            av, cv = self._gains(spec)
            form, p = spec.get("rolloff", (None, {}))
            if form == "series_spring":
                F = p["ks"] * (self.x - y)
            else:
                hyst = av * z
                if form == "leakage":
                    hyst = hyst * (1 - p["r"] * np.exp(-((self.xdot / p["vb"]) ** 2)))
                viscous = cv * self.xdot
                form_a, pa = spec.get("asymmetry", (None, {}))
                if form_a == "one_sided_exponent":
                    ratio = np.maximum(np.abs(self.xdot), 1e-12) / self.speed_rms
                    bend = np.where(self.xdot > 0, ratio ** pa["e"], 1.0)
                    viscous = viscous * bend
                F = hyst + viscous + b["k0"] * self.x + b["f0"]
            form, p = spec.get("asymmetry", (None, {}))
            if form == "gas_spring":
                F = F + p["P"] * self.gas(p)
            form, p = spec.get("offset", (None, {}))
            if form is not None:
                F = F + p["D"] * slow_shape(self.t, form, p)
            out.append(F)
        return out

    def gas(self, p):
        s = self.x / p["L"]
        return (1 - s) ** -p["kappa"] - 1 - p["kappa"] * s

    def sensitivities(self) -> np.ndarray:
        """Output sensitivities to c0, k0, f0 (and x0), alpha, beta, gamma, n."""
        b = self.base
        specs, steps = [{}], []
        for key in ("beta", "gamma", "n"):
            step = 1e-6 * abs(b[key])
            specs.append({"_base": {key: b[key] + step}})
            steps.append(step)
        zs = [s[:, 0] for s in self._states(specs)]
        cols = [self.xdot, self.x, np.ones_like(self.x), zs[0]]
        cols += [b["alpha"] * (z - zs[0]) / s for z, s in zip(zs[1:], steps)]
        return np.stack(cols, axis=1)

    def size(self, effect: str, form: str, rng, target: float, reference: dict):
        """Sized on top of `reference` (the field dependence, for driver_lag)."""
        y0 = self.outputs([reference])[0] if reference else self.y_base
        self.y_base_for_sweep = y0

        def with_(p):
            return {**reference, effect: (form, p)}

        def sweep(make):
            return self.sweep(lambda g: with_(make(g)))

        def alone(p):
            return self.outputs([with_(p)])[0] - y0

        sign = float(rng.choice([-1.0, 1.0]))
        if form in ("langevin", "hill"):
            rho = rng.uniform(0.05, 0.3)
            if form == "langevin":
                p = {"qs": rng.uniform(0.15, 0.5)}
                words = f"Langevin q_s {p['qs']:.3g}"
            else:
                p = {"h": rng.uniform(1.5, 2.5), "qk": rng.uniform(0.3, 0.7)}
                words = f"Hill h {p['h']:.3g}, q_k {p['qk']:.3g}"
            p |= {"G": 1.0, "rho": rho}
            G, r = self.linear(alone(p), target, most=20.0)
            p["G"] = G
            return p, r, f"{words}: alpha x{1 + G:.3g}, c0 x{1 + rho * G:.3g} at 2.5 V"
        if form == "dead_time":
            zeta, ratio = rng.uniform(0.35, 0.6), rng.uniform(0.3, 1.0)
            T, r = size_search(
                sweep(lambda g: {"T": g, "zeta": zeta, "Td": ratio * g}),
                target,
                1e-5,
                0.03,
            )
            p = {"T": T, "zeta": zeta, "Td": ratio * T}
            words = (
                f"dead time {1e3 * ratio * T:.3g} ms, then {1 / (2 * np.pi * T):.3g} "
                f"Hz, zeta {zeta:.3g}"
            )
            return p, r, words
        if form == "diffusive":
            T, r = size_search(sweep(lambda g: {"T": g}), target, 1e-6, 0.05)
            return {"T": T}, r, f"1/(1 + sqrt(s {1e3 * T:.3g} ms))"
        if form == "series_spring":
            alpha = self.base["alpha"]
            C, r = size_search(
                sweep(lambda g: {"ks": 1 / g}),
                target,
                1 / (200 * alpha),
                1 / (0.3 * alpha),
            )
            words = f"mount k_s {1 / C:.4g} N/cm ({1 / (C * alpha):.3g} alpha)"
            return {"ks": 1 / C}, r, words
        if form == "leakage":
            vb = rng.uniform(0.1, 0.4) * self.speed_rms
            rr, r = self.linear(alone({"r": 1.0, "vb": vb}), target, most=0.9)
            return {"r": rr, "vb": vb}, r, f"bypass {rr:.3g} below {vb:.3g} cm/s"
        if form == "gas_spring":
            p = {
                "kappa": rng.uniform(1.0, 1.4),
                "L": rng.uniform(3.0, 8.0) * float(np.max(np.abs(self.x))),
                "P": 1.0,
            }
            P, r = self.linear(self.gas(p), target)
            p["P"] = P
            words = f"gas spring P {P:.4g} N, L {p['L']:.3g} cm, kappa {p['kappa']:.3g}"
            return p, r, words
        if form == "one_sided_exponent":
            e, r = size_search(sweep(lambda g: {"e": sign * g}), target, 1e-4, 0.5)
            words = (
                f"compression c0*xdot*(|xdot|/{self.speed_rms:.3g} cm/s)^{sign * e:.3g}"
            )
            return {"e": sign * e}, r, words
        if form in ("settle", "zero_step"):
            T = self.duration
            if form == "settle":
                p = {"tau": rng.uniform(0.2, 0.6) * T}
                words = f"settling over {p['tau']:.3g} s"
            else:
                p = {"t0": rng.uniform(0.3, 0.7) * T, "w": rng.uniform(0.03, 0.1) * T}
                words = f"step at {p['t0']:.3g} s over {p['w']:.3g} s"
            D, r = self.linear(slow_shape(self.t, form, p), target)
            p["D"] = sign * D
            return p, r, f"{words}, D {sign * D:.4g} N"
        raise ValueError(form)
