"""The standard Bouc-Wen model (eq. 1-2) and the piezo models derived from it
(eq. 7-8, the corrected eq. 16-17, and the stage dynamics of eq. 3-4)."""

from typing import TYPE_CHECKING, ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from .._inputs import InputPath
from .._recording import Recording
from .._simulate import RK4
from .._smoothing import AbstractSmoothing, ExactSign
from .base import (
    AbstractDrive,
    AbstractHysteresisModel,
    BoucWenShape,
    DataScales,
    Drive,
    SearchBox,
    StageDynamics,
    as_parameter,
    hysteretic_rate,
    read_input,
    smoothing_field,
)


if TYPE_CHECKING:
    from .extended import ExtendedPiezo
    from .structural import StructuralBoucWen


def _piezo_box(
    model: AbstractHysteresisModel, scales: DataScales, gauge: bool
) -> SearchBox:
    """The search box of the piezo hysteresis (eq. 7-8's k1, k2, A1, beta1, gamma1, n),
    shared by every piezo model. With `gauge`, A1 is fixed at 1/max|u| (h is then
    dimensionless) instead of searched."""
    su, sy = scales.input_peak, scales.output_peak
    bounds = {
        "k1": (-3 * sy / su, 3 * sy / su),
        "k2": (-5 * sy, 5 * sy),
        "A1": (-3 / su, 3 / su),
        # |beta1|, |gamma1| * max|u| up to 50: the loop may saturate within 2 % of
        # the input range (the paper's Table 4 sets reach ~37).
        "beta1": (-50 / su, 50 / su),
        "gamma1": (-50 / su, 50 / su),
        "n": (1.0, 3.0),
    }
    if gauge:
        del bounds["A1"]
        model = model.replace(A1=1.0 / su)
    return SearchBox(model, bounds)


def structural_solver(recording: Recording) -> RK4:
    """The solver of the structural models (`BoucWen`, `StructuralBoucWen`): the
    structural diagnosis family's (`StructuralFamily.solver`), which `diagnose`
    fits them with."""
    from .._diagnose._families import StructuralFamily  # the family imports models

    return StructuralFamily().solver(recording)


def shift_reason(model: "CorrectedPiezoBoucWen | ExtendedPiezo") -> str | None:
    """Why a model with a time shift phi lags the drive (None at phi = 0)."""
    phi = float(model.phi)
    if not phi:
        return None
    return (
        f"{type(model).__name__} with phi = {phi:g} s reads the drive "
        "shifted in time (V(t) = u(t + phi)), not at the present sample"
    )


def _piezo_shape(
    model: "PiezoBoucWen | CorrectedPiezoBoucWen | PiezoStage",
) -> BoucWenShape:
    """The piezo models' shape: (A1, beta1, gamma1, n), no D."""
    return BoucWenShape(
        model.A1,
        model.beta1,
        model.gamma1,
        model.n,
        names=("A1", "beta1", "gamma1", "n"),
    )


class BoucWen(AbstractHysteresisModel[Drive]):
    """Standard Bouc-Wen (eq. 1-2):

    Phi  = alpha*k*u + (1 - alpha)*D*k*h
    hdot = (A*udot - beta*|udot|*|h|^(n-1)*h - gamma*udot*|h|^n) / D
    """

    k: Float[Array, ""] = eqx.field(converter=as_parameter)
    alpha: Float[Array, ""] = eqx.field(converter=as_parameter)
    D: Float[Array, ""] = eqx.field(converter=as_parameter)
    A: Float[Array, ""] = eqx.field(converter=as_parameter)
    beta: Float[Array, ""] = eqx.field(converter=as_parameter)
    gamma: Float[Array, ""] = eqx.field(converter=as_parameter)
    n: Float[Array, ""] = eqx.field(converter=as_parameter)
    smoothing: AbstractSmoothing = smoothing_field()

    state_size: ClassVar[int] = 1
    has_opensees_material: ClassVar[bool] = True

    def vector_field(self, t, state, drive):
        hdot = hysteretic_rate(
            self.smoothing,
            state[0],
            drive.udot,
            self.A,
            self.beta,
            self.gamma,
            self.n,
        )
        return jnp.stack([hdot / self.D])

    def output(self, t, state, drive):
        return (
            self.alpha * self.k * drive.u
            + (1 - self.alpha) * self.D * self.k * (state[0])
        )

    def default_bounds(self, scales: DataScales, *, gauge: bool = True) -> SearchBox:
        """k in [1e-3, 10]*max|y|/max|u| (log scale), alpha in [0, 1], A in [-3, 3],
        beta and gamma in +-10/max|u|, n in [1, 3]; D is fixed at 1 (whatever
        `gauge`: it only rescales h)."""
        su, sy = scales.input_peak, scales.output_peak
        bounds = {
            "k": (1e-3 * sy / su, 10 * sy / su),
            "alpha": (0.0, 1.0),
            "A": (-3.0, 3.0),
            "beta": (-10 / su, 10 / su),
            "gamma": (-10 / su, 10 / su),
            "n": (1.0, 3.0),
        }
        return SearchBox(self.replace(D=1.0), bounds, ("k",))

    def bouc_wen_shape(self) -> BoucWenShape:
        return BoucWenShape(
            self.A,
            self.beta,
            self.gamma,
            self.n,
            self.D,
            names=("A", "beta", "gamma", "n", "D"),
        )

    def default_solver(self, recording: Recording) -> RK4:
        """The structural family's substeps (`structural_solver`)."""
        return structural_solver(recording)

    def opensees_model(self) -> "StructuralBoucWen":
        """`StructuralBoucWen.from_bouc_wen(self)` (needs D > 0 and A > 0)."""
        from .structural import StructuralBoucWen  # it builds on this module

        return StructuralBoucWen.from_bouc_wen(self)

    def gauge_fixed(self) -> "BoucWen":
        """The same force for every displacement history written with D = 1 and
        A = 1: w = (D/A)*h obeys wdot = udot - beta'*|udot|*|w|^(n-1)*w -
        gamma'*udot*|w|^n with (beta', gamma') = (beta, gamma)*A^(n-1)/D^n, and
        (1 - alpha)*D*k*h = (1 - alpha)*k*A*w. Needs D > 0 and A > 0."""
        D, A, n = self.D, self.A, self.n
        if not (float(D) > 0 and float(A) > 0):
            raise ValueError(
                "BoucWen.gauge_fixed: needs D > 0 and A > 0 (got "
                f"D={float(D):.4g}, A={float(A):.4g}); refit the model with "
                "ParameterSpace.default, which fixes D = 1."
            )
        scale = A ** (n - 1) / D**n
        hysteretic = (1 - self.alpha) * self.k * A
        elastic = self.alpha * self.k
        k = elastic + hysteretic
        return self.replace(
            k=k,
            alpha=elastic / k,
            D=1.0,
            A=1.0,
            beta=self.beta * scale,
            gamma=self.gamma * scale,
        )


class PiezoBoucWen(AbstractHysteresisModel[Drive]):
    """The paper's six-parameter quasi-static piezo model (eq. 7-8):

        y    = k1*u + k2*h
        hdot = A1*udot - beta1*|udot|*|h|^(n-1)*h - gamma1*udot*|h|^n

    (k2, A1, beta1, gamma1) carry a scaling symmetry h -> c*h, so one direction of the
    six parameters is not identifiable from y alone; fix a gauge (e.g. A1) when fitting.
    """

    k1: Float[Array, ""] = eqx.field(converter=as_parameter)
    k2: Float[Array, ""] = eqx.field(converter=as_parameter)
    A1: Float[Array, ""] = eqx.field(converter=as_parameter)
    beta1: Float[Array, ""] = eqx.field(converter=as_parameter)
    gamma1: Float[Array, ""] = eqx.field(converter=as_parameter)
    n: Float[Array, ""] = eqx.field(converter=as_parameter)
    smoothing: AbstractSmoothing = smoothing_field()

    state_size: ClassVar[int] = 1

    @classmethod
    def paper_table4(
        cls, case: int = 3, *, smoothing: AbstractSmoothing | None = None
    ) -> "PiezoBoucWen":
        """The parameters the paper identified (Table 4, cases 1-4; y in metres, u in
        volts). Case 3 is the paper's reference model."""
        table = {
            1: (26.4355e-6, 2.2610, -15.4396e-6, 9.6240, -6.6160, 1.0),
            2: (28.3432e-6, 0.4260, -14.5375e-6, 5.3900, -5.3954, 1.0),
            3: (29.3383e-6, 0.2412, -15.3490e-6, 9.2620, -6.4164, 1.0),
            4: (29.3384e-6, 0.2410, -15.5320e-6, 9.2623, -6.0162, 2.0),
        }
        if case not in table:
            raise ValueError(f"paper_table4(case={case!r}): case must be 1, 2, 3 or 4.")
        return cls(
            *table[case], smoothing=ExactSign() if smoothing is None else smoothing
        )

    def vector_field(self, t, state, drive):
        hdot = hysteretic_rate(
            self.smoothing,
            state[0],
            drive.udot,
            self.A1,
            self.beta1,
            self.gamma1,
            self.n,
        )
        return jnp.stack([hdot])

    def output(self, t, state, drive):
        return self.k1 * drive.u + self.k2 * state[0]

    def default_bounds(self, scales: DataScales, *, gauge: bool = True) -> SearchBox:
        """Bounds scaled to max|u| and max|y|. With `gauge=True` (default) A1 is
        fixed at 1/max|u|, which makes h dimensionless and removes the h -> c*h
        symmetry (any fit with A1 != 0 maps onto it exactly); then k1, k2 are
        O(max|y|/max|u|) and O(max|y|), beta1, gamma1 O(1/max|u|), n in [1, 3].
        `gauge=False` searches all six (the redundant direction is then reported,
        not removed)."""
        return _piezo_box(self, scales, gauge)

    def bouc_wen_shape(self) -> BoucWenShape:
        return _piezo_shape(self)

    def c_export_parameters(self) -> dict[str, float]:
        """The six parameters and eps = 0."""
        return _c_parameters(self, 0.0)


def _c_parameters(
    model: "PiezoBoucWen | CorrectedPiezoBoucWen", eps: float
) -> dict[str, float]:
    """`export_c`'s constants: the piezo law's six parameters, then eps."""
    values = {n: float(getattr(model, n)) for n in PiezoBoucWen.parameter_names}
    values["eps"] = eps
    return values


class ShiftedDrive(AbstractDrive):
    """The input and its rate, plus the time-shifted input V(t) = u(t + phi) and its
    rate, which the corrected model's hysteresis operator sees."""

    u: Float[Array, ""]
    udot: Float[Array, ""]
    v: Float[Array, ""]
    vdot: Float[Array, ""]


class CorrectedPiezoBoucWen(AbstractHysteresisModel[ShiftedDrive]):
    """The paper's corrected (asymmetric) piezo model (eq. 16-17):

        y         = k1*u(t) + k2*h
        hdot      = (A1 - (beta1*sign(Vdot)*sign(h) + gamma1)*|h|^n)*Vdot + Delta_Phi
        V(t)      = u(t + phi)              (input bias: a time shift in seconds)
        Delta_Phi = eps*u(t)*sign(udot(t))  (asymmetry)

    V is read from the interpolated sampled input (held at its end values outside
    the record). With phi = eps = 0 this is exactly `PiezoBoucWen`.
    """

    k1: Float[Array, ""] = eqx.field(converter=as_parameter)
    k2: Float[Array, ""] = eqx.field(converter=as_parameter)
    A1: Float[Array, ""] = eqx.field(converter=as_parameter)
    beta1: Float[Array, ""] = eqx.field(converter=as_parameter)
    gamma1: Float[Array, ""] = eqx.field(converter=as_parameter)
    n: Float[Array, ""] = eqx.field(converter=as_parameter)
    phi: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    eps: Float[Array, ""] = eqx.field(converter=as_parameter, default=0.0)
    smoothing: AbstractSmoothing = smoothing_field()

    state_size: ClassVar[int] = 1

    @classmethod
    def from_piezo(
        cls,
        base: AbstractHysteresisModel,
        *,
        phi: Float[ArrayLike, ""] = 0.0,
        eps: Float[ArrayLike, ""] = 0.0,
    ) -> "CorrectedPiezoBoucWen":
        """The corrected model around a fitted plain model (the paper's two stages):
        `base` must be a `PiezoBoucWen`."""
        if not isinstance(base, PiezoBoucWen):
            raise TypeError(
                "CorrectedPiezoBoucWen.from_piezo: base must be a PiezoBoucWen, got "
                f"{type(base).__name__}."
            )
        return cls(**base.parameters(), phi=phi, eps=eps, smoothing=base.smoothing)

    def drive(self, path: InputPath, t, interval=None, frac=None) -> ShiftedDrive:
        u, udot = read_input(path, t, interval, frac)
        if interval is None or frac is None:
            v, vdot = path.evaluate(t + self.phi)
        else:
            v, vdot = path.on_interval_shifted(interval, frac, self.phi)
        return ShiftedDrive(u, udot, v, vdot)

    def vector_field(self, t, state, drive: ShiftedDrive):
        s = self.smoothing
        hdot = hysteretic_rate(
            s, state[0], drive.vdot, self.A1, self.beta1, self.gamma1, self.n
        )
        return jnp.stack([hdot + self.eps * drive.u * s.sign(drive.udot)])

    def output(self, t, state, drive):
        return self.k1 * drive.u + self.k2 * state[0]

    def default_bounds(self, scales: DataScales, *, gauge: bool = True) -> SearchBox:
        """`PiezoBoucWen`'s box plus phi in +-5 % of the duration and eps in
        +-2/(max|u|*duration)."""
        box = _piezo_box(self, scales, gauge)
        su, duration = scales.input_peak, scales.duration
        bounds = dict(box.bounds)
        bounds["phi"] = (-0.05 * duration, 0.05 * duration)
        bounds["eps"] = (-2.0 / (su * duration), 2.0 / (su * duration))
        return SearchBox(box.template, bounds, box.log_scale)

    def bouc_wen_shape(self) -> BoucWenShape:
        return _piezo_shape(self)

    def lag_reason(self) -> str | None:
        """The time shift's, where phi != 0."""
        return shift_reason(self)

    def time_shift(self) -> float:
        return float(self.phi)

    def quasi_static(self) -> "CorrectedPiezoBoucWen":
        """The model with phi = 0."""
        return self.replace(phi=0.0)

    def c_export_parameters(self) -> dict[str, float]:
        """The six parameters and eps; refused unless phi = 0 (the per-sample C step
        reads only the present drive)."""
        if float(self.phi) != 0.0:
            raise ValueError(
                f"export_c: phi = {float(self.phi):g} s shifts the drive in time; "
                "the per-sample C step reads only the present drive. Export the "
                "model with phi = 0."
            )
        return _c_parameters(self, float(self.eps))


class PiezoStage(AbstractHysteresisModel[Drive]):
    """The stage dynamics of eq. 3-4: a mass-spring-damper driven by the hysteretic
    force, written per unit stiffness so that it nests the quasi-static model:

        ydd / omega^2 + (2*zeta/omega)*yd + y = k1*u + k2*h,   h as in `PiezoBoucWen`

    with omega = 2*pi*natural_frequency = sqrt(ks/m), zeta = c/(2*sqrt(ks*m)),
    k1 = alpha*k/ks, k2 = (1-alpha)*k*D/ks and A1, beta1, gamma1 = A/D, beta/D,
    gamma/D. As natural_frequency -> infinity this becomes `PiezoBoucWen` ("m*ydd and
    c*yd neglected"). State: (y, yd, h); it starts at rest in static equilibrium.
    """

    k1: Float[Array, ""] = eqx.field(converter=as_parameter)
    k2: Float[Array, ""] = eqx.field(converter=as_parameter)
    A1: Float[Array, ""] = eqx.field(converter=as_parameter)
    beta1: Float[Array, ""] = eqx.field(converter=as_parameter)
    gamma1: Float[Array, ""] = eqx.field(converter=as_parameter)
    n: Float[Array, ""] = eqx.field(converter=as_parameter)
    natural_frequency: Float[Array, ""] = eqx.field(converter=as_parameter)
    damping_ratio: Float[Array, ""] = eqx.field(converter=as_parameter)
    smoothing: AbstractSmoothing = smoothing_field()

    state_size: ClassVar[int] = 3

    @classmethod
    def from_physical(
        cls,
        *,
        m: float,
        c: float,
        ks: float,
        k: float,
        alpha: float,
        D: float,
        A: float,
        beta: float,
        gamma: float,
        n: float,
        smoothing: AbstractSmoothing | None = None,
    ) -> "PiezoStage":
        """Build from eq. 3-4's physical constants (mass, damping, stiffnesses)."""
        omega = (ks / m) ** 0.5
        return cls(
            k1=alpha * k / ks,
            k2=(1 - alpha) * k * D / ks,
            A1=A / D,
            beta1=beta / D,
            gamma1=gamma / D,
            n=n,
            natural_frequency=omega / (2 * jnp.pi),
            damping_ratio=c / (2 * (ks * m) ** 0.5),
            smoothing=ExactSign() if smoothing is None else smoothing,
        )

    @classmethod
    def from_piezo(
        cls,
        base: PiezoBoucWen,
        *,
        natural_frequency: Float[ArrayLike, ""],
        damping_ratio: Float[ArrayLike, ""],
    ) -> "PiezoStage":
        return cls(
            **base.parameters(),
            natural_frequency=natural_frequency,
            damping_ratio=damping_ratio,
            smoothing=base.smoothing,
        )

    def vector_field(self, t, state, drive):
        y, yd, h = state[0], state[1], state[2]
        omega = 2 * jnp.pi * self.natural_frequency
        hdot = hysteretic_rate(
            self.smoothing, h, drive.udot, self.A1, self.beta1, self.gamma1, self.n
        )
        static = self.k1 * drive.u + self.k2 * h
        ydd = omega**2 * (static - y) - 2 * self.damping_ratio * omega * yd
        return jnp.stack([yd, ydd, hdot])

    def output(self, t, state, drive):
        return state[0]

    def initial_state(self, drive):
        y0 = self.k1 * drive.u
        return jnp.stack([y0, jnp.zeros_like(y0), jnp.zeros_like(y0)])

    def default_bounds(self, scales: DataScales, *, gauge: bool = True) -> SearchBox:
        """`PiezoBoucWen`'s box plus natural_frequency from 2/duration to a quarter
        of the sample rate and damping_ratio in [1e-3, 3], both on a log scale."""
        box = _piezo_box(self, scales, gauge)
        nyquist = 0.5 * scales.sample_rate
        bounds = dict(box.bounds)
        bounds["natural_frequency"] = (2.0 / scales.duration, 0.5 * nyquist)
        bounds["damping_ratio"] = (1e-3, 3.0)
        log = (*box.log_scale, "natural_frequency", "damping_ratio")
        return SearchBox(box.template, bounds, log)

    def bouc_wen_shape(self) -> BoucWenShape:
        return _piezo_shape(self)

    def default_solver(self, recording: Recording) -> RK4:
        """RK4 with 4 substeps: the stage is stiff on the sample scale."""
        return RK4(substeps=4)

    def lag_reason(self) -> str | None:
        return (
            "PiezoStage's output is the position of a mass-spring-damper, which does "
            "not respond to the present drive within one sample"
        )

    def stage_dynamics(self) -> StageDynamics:
        """The stage at natural_frequency and damping_ratio; no drift."""
        return StageDynamics(
            2 * np.pi * float(self.natural_frequency),
            float(self.damping_ratio),
            lambda t: np.zeros_like(t),
        )

    def quasi_static(self) -> PiezoBoucWen:
        """The `PiezoBoucWen` of the same hysteresis (the stage left out)."""
        values = {n: getattr(self, n) for n in PiezoBoucWen.parameter_names}
        return PiezoBoucWen(**values, smoothing=self.smoothing)
