"""The structural Bouc-Wen model with the structural family's effects built in.

A restoring force F driven by an imposed displacement x (quasi-static cyclic tests of
columns, walls and connections). With every effect's gain at zero it is exactly the
seed's eq. 1-2 (`BoucWen` with D = 1, A = 1); the effects follow the forms OpenSees
uses, so a fitted model exports exactly where OpenSees has the material:

- degradation (Baber-Wen, and its ductility-driven form): nu = 1 +
  strength_degradation*e + peak_strength_degradation*p, eta = 1 +
  stiffness_degradation*e + peak_stiffness_degradation*p, with e the dissipated
  hysteretic energy and p = max|x| the largest displacement so far (RC members lose
  stiffness and strength with the largest excursion as well as with the energy,
  from the cracking that precedes yield; Park-Ang's damage index combines the two);
  zdot = Phi/eta * xdot where
  Phi = A - nu*(beta*sign(xdot*z) + gamma)*|z|^n (OpenSees `BoucWen`'s deltaNu,
  deltaEta; it has no peak-driven terms);
- pinching (Baber-Noori, Foliente's BWBN): zdot *= h(z) with
  h = 1 - zeta1*exp(-((z*sign(xdot) - q*zu)/zeta2)^2), zeta1 = pinch*(1 - exp(-pinch_rate*e)),
  zeta2 = pinch_width*zu*(pinch_lambda + zeta1), zu = (1/(beta + gamma))^(1/n)
  (OpenSees `BWBN` with zetas = pinch, q = pinch_shift, p = pinch_rate, Shi = pinch_width*zu);
  and, for a slip that widens with the largest excursion (bolt holes ovalising, crack
  openings, dowel embedment), Sivaselvan and Reinhorn's (2000) slip-lock: a slip s
  in series with the element, whose compliance is a Gaussian in the force F_e the
  element carries, ds = a/(sqrt(2 pi)*sigma)*exp(-(F_e/sigma)^2/2)*dF_e, so that
  s = a*(Phi(F_e/sigma) - 1/2) crosses from -a/2 to a/2 as the force crosses zero,
  a = slip_length*(max|x| - zu)+ (the excursion past the yield displacement zu:
  the slip opens once the test passes yield, as bolt holes ovalise and cracks stay
  open; where a grows, s grows with it on the side the force is, per sample), over
  a force window
  sigma = slip_window*F_y,
  F_y = (1 - alpha)*k*zu; the element sees x - s and moves at xdot/(1 + c*K_t), c
  that compliance and K_t the element's tangent stiffness (no OpenSees material has
  it);
- asymmetry (push and pull differ): the shape term (beta*sign(xdot*z) + gamma)*|z|^n is
  multiplied by 1 + yield_skew*sign(z) (the two sides yield at different levels,
  zu*(1 + yield_skew*sign(z))^(-1/n), with the same loop shape) and
  F += alpha*k*stiffness_skew*|x| (the post-yield stiffness differs by side);
- drift: F += offset + trend*s + curvature*(s^2 - 1/3) + wander*(5 s^3 - 3 s)/2
  (Legendre terms), s the time in [-1, 1]
  (load-cell offsets and slow drift that do not follow the mechanics).

The pinching's zu is capped at what the record's z can reach (`reach`: its max|x|,
and the z whose hysteretic force is its max|F|), where OpenSees has no cap: such a
model exports to BWBN inexactly.
The energy e is made dimensionless by `energy_scale` (max|F| * max|x| of the record,
set by `around`): a degradation rate of 0.1 then loses 10 % per unit of that energy,
about a quarter of one elastic-perfectly-plastic cycle at the peak amplitude.
The peak p is in the input's unit (a peak rate of 0.01 per mm raises nu by 0.1 once
the test has reached 10 mm; `slip_from_yield=False` grows the slip with max|x| from
zero too, the form of earlier builds); the largest |x| is kept exactly, per sample
(`sample_update`), so the
model runs under `RK4` with one step per sample (substeps allowed) unless both peak
rates and the slip length are held at zero: `model.held_at_zero(
["peak_strength_degradation", "peak_stiffness_degradation", "slip_length"])` runs
under diffrax and coarse RK4 steps as before.
State: (z, e, p, s): s the slip-lock's slip (zero while slip_length is).
"""

from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from .._inputs import InputPath
from .._recording import Recording
from .._simulate import RK4
from .._smoothing import AbstractSmoothing, ExactSign
from .base import (
    AbstractGainHoldingModel,
    AbstractHysteresisModel,
    BoucWenShape,
    Drive,
    as_parameter,
    held_gains_field,
    legendre_drift,
)
from .bouc_wen import BoucWen, structural_solver


def _scalar(model: "StructuralBoucWen", name: str) -> float:
    value = np.asarray(getattr(model, name))
    if value.shape != ():
        raise ValueError(
            f"opensees_material: {name} has shape {value.shape}; export one model at "
            "a time (index a batched model first)."
        )
    if value.dtype == np.float32:
        return float(np.format_float_scientific(np.float32(value), unique=True))
    return float(value)


def _field(default: float):
    return eqx.field(converter=as_parameter, default=default)


def _normaliser(default: float):
    return eqx.field(converter=as_parameter, default=default, kw_only=True)


class StructuralBoucWen(AbstractGainHoldingModel[Drive]):
    """Bouc-Wen restoring force with degradation, pinching, asymmetry and drift (all
    off at zero): F = alpha*k*x + (1 - alpha)*k*z (+ effects), z the hysteretic
    displacement. See the module docstring for each effect's equations."""

    k: Float[Array, ""] = eqx.field(converter=as_parameter)
    alpha: Float[Array, ""] = eqx.field(converter=as_parameter)
    A: Float[Array, ""] = eqx.field(converter=as_parameter)
    beta: Float[Array, ""] = eqx.field(converter=as_parameter)
    gamma: Float[Array, ""] = eqx.field(converter=as_parameter)
    n: Float[Array, ""] = eqx.field(converter=as_parameter)
    strength_degradation: Float[Array, ""] = _field(0.0)
    stiffness_degradation: Float[Array, ""] = _field(0.0)
    peak_strength_degradation: Float[Array, ""] = _field(0.0)
    peak_stiffness_degradation: Float[Array, ""] = _field(0.0)
    pinch: Float[Array, ""] = _field(0.0)
    pinch_shift: Float[Array, ""] = _field(0.1)
    pinch_width: Float[Array, ""] = _field(0.3)
    pinch_rate: Float[Array, ""] = _field(5.0)
    slip_length: Float[Array, ""] = _field(0.0)
    slip_window: Float[Array, ""] = _field(0.1)
    yield_skew: Float[Array, ""] = _field(0.0)
    stiffness_skew: Float[Array, ""] = _field(0.0)
    offset: Float[Array, ""] = _field(0.0)
    trend: Float[Array, ""] = _field(0.0)
    curvature: Float[Array, ""] = _field(0.0)
    wander: Float[Array, ""] = _field(0.0)
    pinch_lambda: Float[Array, ""] = _normaliser(0.5)
    energy_scale: Float[Array, ""] = _normaliser(1.0)
    displacement_scale: Float[Array, ""] = _normaliser(1e30)
    force_scale: Float[Array, ""] = _normaliser(1e30)
    time_center: Float[Array, ""] = _normaliser(0.0)
    time_scale: Float[Array, ""] = _normaliser(1.0)
    # Whether the series slip grows with the excursion past yield, (max|x| - zu)+
    # (True), or with max|x| from zero (False: the form of earlier builds; their
    # model files lack this field and are refused by name rather than read with
    # another meaning).
    slip_from_yield: bool = eqx.field(default=True, static=True, kw_only=True)
    smoothing: AbstractSmoothing = eqx.field(default_factory=ExactSign, kw_only=True)
    # Gains held at zero (`held_at_zero`): with pinch held no pinching (two
    # exponentials and a power per stage) is computed; with it and both energy
    # degradation rates held, no energy either; with both peak rates held, no peak.
    zero_gains: frozenset[str] = held_gains_field()

    state_size: ClassVar[int] = 4
    has_opensees_material: ClassVar[bool] = True
    # Degradation only degrades: a member does not get stronger or stiffer as a test
    # goes on (a fitted strengthening would stand in for a stiffening the catalogue
    # has no name for, such as a static hardening under growing amplitudes).
    parameter_floors: ClassVar[dict[str, float]] = {
        "strength_degradation": 0.0,
        "stiffness_degradation": 0.0,
        "peak_strength_degradation": 0.0,
        "peak_stiffness_degradation": 0.0,
        # Neither pinching form can speed the hysteretic rate up or slip backwards.
        "pinch": 0.0,
        "slip_length": 0.0,
    }
    # The slip-lock removes at most the whole hysteretic rate near the slip
    # (Baber and Noori's zeta_1 < 1): a larger `pinch` would reverse it, a loop
    # that turns back on itself on reloading.
    parameter_ceilings: ClassVar[dict[str, float]] = {"pinch": 1.0}

    @classmethod
    def from_bouc_wen(cls, base: BoucWen, **normalisers) -> "StructuralBoucWen":
        """The same restoring force written with A = 1 and no D (the gauge this
        model is fitted in; `BoucWen.gauge_fixed`). Needs D > 0 and A > 0."""
        fixed = base.gauge_fixed()
        return cls(
            fixed.k,
            fixed.alpha,
            1.0,
            fixed.beta,
            fixed.gamma,
            fixed.n,
            smoothing=base.smoothing,
            **normalisers,
        )

    @classmethod
    def around(
        cls, base: AbstractHysteresisModel, inputs: InputPath, output_scale: float
    ) -> "StructuralBoucWen":
        """All effects off around a fitted base model, normalised to the record."""
        if isinstance(base, BoucWen):
            base = cls.from_bouc_wen(base)
        if not isinstance(base, StructuralBoucWen):
            raise TypeError(
                "StructuralBoucWen.around: base must be a BoucWen or StructuralBoucWen "
                f"model, got {type(base).__name__}."
            )
        x = inputs.values
        return cls(
            base.k,
            base.alpha,
            base.A,
            base.beta,
            base.gamma,
            base.n,
            pinch_lambda=base.pinch_lambda,
            energy_scale=jnp.maximum(output_scale * jnp.max(jnp.abs(x)), 1e-30),
            displacement_scale=jnp.maximum(jnp.max(jnp.abs(x)), 1e-30),
            force_scale=jnp.maximum(output_scale, 1e-30),
            time_center=(inputs.t0 + inputs.t1) / 2,
            time_scale=(inputs.t1 - inputs.t0) / 2,
            slip_from_yield=base.slip_from_yield,
            smoothing=base.smoothing,
        )

    def bouc_wen_shape(self) -> BoucWenShape:
        """(A, beta, gamma, n) of the undegraded, symmetric law (yield_skew = 0)."""
        return BoucWenShape(
            self.A, self.beta, self.gamma, self.n, names=("A", "beta", "gamma", "n")
        )

    def default_solver(self, recording: Recording) -> RK4:
        """The structural family's substeps (`structural_solver`)."""
        return structural_solver(recording)

    def opensees_model(self) -> "StructuralBoucWen":
        """The model itself (OpenSees's materials read its equations)."""
        return self

    def opensees_parameters(self) -> dict[str, float]:
        """The values OpenSees's Bouc-Wen materials are built from
        (`opensees_material`), by name: every parameter (`parameter_names`), then
        `energy_scale` and `pinch_lambda`, as Python floats (a float32 value as the
        shortest decimal that is it: 0.05, not 0.05000000074505806). Needs one
        model's concrete values."""
        return {
            name: _scalar(self, name)
            for name in (*self.parameter_names, "energy_scale", "pinch_lambda")
        }

    def saturation(self) -> Float[Array, ""]:
        """zu = (1/(beta + gamma))^(1/n): where the undegraded hysteretic
        displacement saturates (OpenSees BWBN's zu), capped at `reach()` (what the
        record's max|x| and max|F| allow): a loop that does not saturate within the
        test (beta + gamma <= 0, or zu beyond that reach) still pinches where its z
        goes. Capped by max|x| alone, a loop that never saturated placed its slip
        beyond every z it reached (chiu: zu capped at 330 mm, z within 41 mm)."""
        total = jnp.maximum(self.beta + self.gamma, 1e-30)
        return jnp.minimum(jnp.exp(-jnp.log(total) / self.n), self.reach())

    def excess(self, peak: Float[ArrayLike, ""]) -> Float[Array, ""]:
        """(peak - zu)+: how far the largest |x| so far has gone past the yield
        displacement zu (`saturation`), what the series slip's length grows with
        (zero until the test yields). With `slip_from_yield=False`, the peak
        itself."""
        origin = self.saturation() if self.slip_from_yield else 0.0
        return jnp.maximum(jnp.asarray(peak) - origin, 0.0)

    def reach(self) -> Float[Array, ""]:
        """The largest hysteretic displacement the record can show: the smaller of
        its max|x| (`displacement_scale`) and the z whose hysteretic force
        (1 - alpha)*k*z is its max|F| (`force_scale`; 1 - alpha taken as at least
        0.1). Both are set by `around`; unset, nothing is capped."""
        stiffness = jnp.abs(self.k) * jnp.maximum(1 - self.alpha, 0.1)
        return jnp.minimum(self.displacement_scale, self.force_scale / stiffness)

    def vector_field(self, t, state, drive):
        s = self.smoothing
        z, energy = state[0], state[1]
        x, xdot = drive.u, drive.udot
        # The largest |x| so far: the state holds it at the last sample
        # (`sample_update`), and |x| is largest at an end of a linear interval.
        peak = jnp.maximum(state[2], jnp.abs(x))
        # Each held gain drops a factor of exactly 1 (the rest in the same order).
        shape = self.beta * s.sign(xdot) * s.sign(z) + self.gamma
        if not self._holds("yield_skew"):
            shape = shape * (1 + self.yield_skew * s.sign(z))
        shape = shape * s.abs_pow(z, self.n)
        nu = self._degradation(
            "strength_degradation", "peak_strength_degradation", energy, peak
        )
        if nu is not None:
            shape = nu * shape
        zdot = self.A - shape
        if not self._holds("pinch"):
            zu = self.saturation()
            zeta1 = self.pinch * (1 - jnp.exp(-self.pinch_rate * energy))
            zeta2 = self.pinch_width * zu * (self.pinch_lambda + zeta1)
            zeta2 = jnp.where(jnp.abs(zeta2) > 1e-30, zeta2, 1e-30)
            distance = (z * s.sign(xdot) - self.pinch_shift * zu) / zeta2
            zdot = (1 - zeta1 * jnp.exp(-(distance**2))) * zdot
        eta = self._degradation(
            "stiffness_degradation", "peak_stiffness_degradation", energy, peak
        )
        if eta is not None:
            zdot = zdot / eta
        # zdot is now dz/dx_e, x_e = x - s the element's own displacement.
        zero = jnp.zeros_like(zdot)
        if self._holds("slip_length"):
            element_rate, slip_rate = xdot, zero
        else:
            element_rate = xdot / (1 + self._slip_compliance(x, state, zdot))
            slip_rate = xdot - element_rate
        zdot = zdot * element_rate
        # Nothing reads the dissipated energy, or the peak, where its gains are held.
        if self._holds("strength_degradation", "stiffness_degradation", "pinch"):
            edot = zero
        else:
            edot = (1 - self.alpha) * self.k * z * element_rate / self.energy_scale
        return jnp.stack([zdot, edot, zero, slip_rate])

    def _slip_compliance(self, x, state, dz_dxe):
        """c*K_t: the slip-lock's compliance at the element's force times the
        element's tangent stiffness (>= 0), so that x_e moves at xdot/(1 + c*K_t).
        The slip length is the one at the sample's start (from state[2]): its growth
        within the sample is added at its end (`sample_update`), which keeps
        s = a*(Phi(F_e/sigma) - 1/2) exactly."""
        s = self.smoothing
        element = x - state[3]
        tangent = (
            self.alpha * self.k * (1 + self._gain("stiffness_skew") * s.sign(element))
            + (1 - self.alpha) * self.k * dz_dxe
        )
        window = self._slip_window_force()
        force = self._element_force(element, state[0])
        compliance = (
            self.slip_length
            * self.excess(state[2])
            / (jnp.sqrt(2 * jnp.pi) * window)
            * jnp.exp(-0.5 * (force / window) ** 2)
        )
        return compliance * jnp.maximum(tangent, 0.0)

    def _slip_window_force(self):
        """sigma = slip_window*F_y, F_y = (1 - alpha)*k*zu: the force window."""
        window = self.slip_window * (1 - self.alpha) * self.k * self.saturation()
        return jnp.maximum(jnp.abs(window), 1e-30)

    def _element_force(self, element, z):
        """The force the element carries at its displacement `element` = x - s."""
        return (
            self.alpha
            * self.k
            * (element + self._gain("stiffness_skew") * self.smoothing.abs(element))
            + (1 - self.alpha) * self.k * z
        )

    def degradation_factors(
        self, energy: Float[ArrayLike, ""], peak: Float[ArrayLike, ""]
    ) -> tuple[Float[Array, ""], Float[Array, ""]]:
        """(nu, eta) after dissipating `energy` (in `energy_scale` units) with the
        largest |x| so far `peak`: the strength and stiffness factors the hysteretic
        law divides by (1 where the rates are zero)."""
        one = jnp.ones_like(jnp.asarray(energy))
        nu = self._degradation(
            "strength_degradation", "peak_strength_degradation", energy, peak
        )
        eta = self._degradation(
            "stiffness_degradation", "peak_stiffness_degradation", energy, peak
        )
        return (one if nu is None else nu, one if eta is None else eta)

    def _degradation(self, energy_rate: str, peak_rate: str, energy, peak):
        """nu or eta: 1 + energy_rate*e + peak_rate*peak (floored at 0.01), or None
        where both gains are held (the factor is exactly 1)."""
        if self._holds(energy_rate, peak_rate):
            return None
        factor = 1 + self._gain(energy_rate) * energy + self._gain(peak_rate) * peak
        return jnp.maximum(factor, 1e-2)

    def initial_state(self, drive):
        u = jnp.asarray(drive.u)
        zero = jnp.zeros_like(u)
        return jnp.stack([zero, zero, jnp.abs(u), zero])

    def sample_update(self, inputs):
        """With a peak-driven degradation or the slip-lock on: the peak state takes
        each sample's |x| where it is larger (exact; the ODE leaves it alone), and the
        slip grows with it (keeping s = a*(Phi(F_e/sigma) - 1/2) as a grows). None
        while those gains are held at zero, so fits without them keep coarse RK4
        steps."""
        if self._holds(
            "peak_strength_degradation", "peak_stiffness_degradation", "slip_length"
        ):
            return None
        values = inputs.values
        slips = not self._holds("slip_length")

        def update(start, end, interval):
            x = values[interval + 1]
            peak = jnp.maximum(start[2], jnp.abs(x))
            end = end.at[2].set(peak)
            if slips:
                # The slip is a*(Phi(F_e/sigma) - 1/2), a = slip_length*excess:
                # where the excess grew, the slip grows with it on the side the
                # force is.
                force = self._element_force(x - end[3], end[0])
                half = 0.5 * jax.scipy.special.erf(
                    force / (jnp.sqrt(2.0) * self._slip_window_force())
                )
                grown = self.excess(peak) - self.excess(start[2])
                end = end.at[3].add(self.slip_length * grown * half)
            return end

        return update

    def output(self, t, state, drive):
        s = (t - self.time_center) / self.time_scale
        return (
            self._element_force(drive.u - state[3], state[0])
            + self._gain("offset")
            + legendre_drift(
                s, *(self._gain(n) for n in ("trend", "curvature", "wander"))
            )
        )
