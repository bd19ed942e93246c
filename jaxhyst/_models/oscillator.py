"""The hysteretic oscillator of the Bouc-Wen nonlinear benchmark (Noel & Schoukens)."""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._smoothing import AbstractSmoothing, ExactSign
from .base import (
    AbstractHysteresisModel,
    BoucWenShape,
    DataScales,
    Drive,
    SearchBox,
    as_parameter,
    hysteretic_rate,
)


class HystereticOscillator(AbstractHysteresisModel[Drive]):
    """A force-driven single-degree-of-freedom oscillator with a Bouc-Wen restoring force:

        mass*ydd + damping*yd + stiffness*y + z = u
        zdot = alpha*yd - beta_gamma*|yd|*|z|^(nu-1)*z - beta_delta*yd*|z|^nu

    The benchmark's (beta, gamma, delta) enter only as the products beta*gamma and
    beta*delta, which are the identifiable parameters used here. State: (y, yd, z).
    """

    mass: Float[Array, ""] = eqx.field(converter=as_parameter)
    damping: Float[Array, ""] = eqx.field(converter=as_parameter)
    stiffness: Float[Array, ""] = eqx.field(converter=as_parameter)
    alpha: Float[Array, ""] = eqx.field(converter=as_parameter)
    beta_gamma: Float[Array, ""] = eqx.field(converter=as_parameter)
    beta_delta: Float[Array, ""] = eqx.field(converter=as_parameter)
    nu: Float[Array, ""] = eqx.field(converter=as_parameter)
    smoothing: AbstractSmoothing = eqx.field(default_factory=ExactSign, kw_only=True)

    state_size: ClassVar[int] = 3

    @classmethod
    def benchmark_truth(cls) -> "HystereticOscillator":
        """The parameters that generated the benchmark data (m_L = 2 kg, c_L = 10 N s/m,
        k_L = 5e4 N/m, alpha = 5e4 N/m, beta = 1e3 1/m, gamma = 0.8, delta = -1.1, nu = 1)."""
        return cls(2.0, 10.0, 5e4, 5e4, 1e3 * 0.8, 1e3 * -1.1, 1.0)

    def vector_field(self, t, state, drive):
        y, yd, z = state[0], state[1], state[2]
        zdot = hysteretic_rate(
            self.smoothing, z, yd, self.alpha, self.beta_gamma, self.beta_delta, self.nu
        )
        ydd = (drive.u - self.damping * yd - self.stiffness * y - z) / self.mass
        return jnp.stack([yd, ydd, zdot])

    def output(self, t, state, drive):
        return state[0]

    def default_bounds(
        self, scales: DataScales, *, gauge: bool = True, nu_free: bool = False
    ) -> SearchBox:
        """Bounds set by the data's scales, not by any known answer: with
        k0 = rms(u)/rms(y) (a stiffness; u is a force, y a displacement) and the
        Nyquist frequency f_N, stiffness and alpha in k0*[1e-2, 10], mass such that
        sqrt(k0/m) spans 1 Hz to f_N, damping/k0 from 1e-5 s to 1 s (all four on a
        log scale), and beta*gamma, beta*delta in +-5/rms(y). `nu` stays at the
        template's value unless `nu_free` (then in [1, 3]). The model has no gauge
        (`gauge` is ignored)."""
        su, sy = scales.input_rms, scales.output_rms
        k0 = su / sy
        nyquist = 0.5 * scales.sample_rate
        bounds = {
            "mass": (k0 / (2 * np.pi * nyquist) ** 2, k0 / (2 * np.pi * 1.0) ** 2),
            "damping": (1e-5 * k0, 1.0 * k0),
            "stiffness": (1e-2 * k0, 10 * k0),
            "alpha": (1e-2 * k0, 10 * k0),
            "beta_gamma": (-5 / sy, 5 / sy),
            "beta_delta": (-5 / sy, 5 / sy),
        }
        if nu_free:
            bounds["nu"] = (1.0, 3.0)
        return SearchBox(self, bounds, ("mass", "damping", "stiffness", "alpha"))

    def bouc_wen_shape(self) -> BoucWenShape:
        return BoucWenShape(
            self.alpha,
            self.beta_gamma,
            self.beta_delta,
            self.nu,
            names=("alpha", "beta_gamma", "beta_delta", "nu"),
        )
