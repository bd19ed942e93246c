"""Export a fitted structural model to the matching OpenSees uniaxial material.

OpenSees (SRC/material/uniaxial/BoucWenMaterial.cpp and BWBN.cpp) integrates, per
strain increment dx with implicit Euler (Newton on the end-of-step z),

- `BoucWen`: Phi = (Ao - deltaA*e) - |z|^n*(gamma + beta*sign(dx*z))*(1 + deltaNu*e),
  dz = Phi/(1 + deltaEta*e)*dx;
- `BWBN`: Phi = Ao - |z|^n*(gamma + beta*sign(dx*z)), dz = Phi*h*dx with
  h = 1 - zeta1*exp(-((z*sign(dx) - q*zu)/zeta2)^2), zeta1 = zetas*(1 - exp(-p*e)),
  zeta2 = (Shi + deltaShi*e)*(lamda + zeta1), zu = (1/(beta + gamma))^(1/n);

both with F = alpha*ko*x + (1 - alpha)*ko*z and e += (1 - alpha)*ko*dx*z: the same
equations as `StructuralBoucWen`, whose energy is divided by `energy_scale`. Hence
(OpenSees name = jaxhyst value):

- both: alpha = alpha, ko = k, n = n, gamma = gamma, beta = beta, Ao = A;
- `BoucWen` (no pinching): deltaA = 0, deltaNu = strength_degradation/energy_scale,
  deltaEta = stiffness_degradation/energy_scale;
- `BWBN` (pinching): q = pinch_shift, zetas = pinch, p = pinch_rate/energy_scale,
  Shi = pinch_width*zu, deltaShi = 0, lamda = pinch_lambda; it has no nu, eta, so
  degradation is dropped when both are on;
- neither has peak-driven degradation (peak_strength_degradation,
  peak_stiffness_degradation), the series slip (slip_length, with its slip_window),
  asymmetry (yield_skew, stiffness_skew) or drift (offset, trend, curvature,
  wander).
"""

import ctypes
import importlib.util
import math
import os
import sys
from typing import Any

import equinox as eqx
import numpy as np
from jaxtyping import ArrayLike, Float

from ._models.bouc_wen import BoucWen
from ._models.structural import StructuralBoucWen
from ._smoothing import ExactSign


_INSTALL_HINT = (
    "install it with `pip install 'jaxhyst[opensees]'`. On Linux the openseespylinux "
    "wheel also needs libblas.so.3: jaxhyst loads the copy bundled in the wheel's "
    "lib/ folder, or install the system one (`apt-get install libblas3 liblapack3`)."
)
# The Newton iteration of OpenSees stops when |dz| < tol: relative to zu.
_RELATIVE_TOL = 1e-10
_MAX_ITER = 100
_DRIFT = ("offset", "trend", "curvature", "wander")
_PEAK_DEGRADATION = ("peak_strength_degradation", "peak_stiffness_degradation")
_BOUC_WEN_NAMES = (
    "alpha",
    "ko",
    "n",
    "gamma",
    "beta",
    "Ao",
    "deltaA",
    "deltaNu",
    "deltaEta",
    "tol",
    "maxNumIter",
)
_BWBN_NAMES = (
    "alpha",
    "ko",
    "n",
    "gamma",
    "beta",
    "Ao",
    "q",
    "zetas",
    "p",
    "Shi",
    "deltaShi",
    "lamda",
    "tol",
    "maxNumIter",
)


class OpenSeesMaterial(eqx.Module):
    """An OpenSees uniaxial material equivalent to a jaxhyst model.

    `command` is the Tcl line, `openseespy_args()` the arguments of
    `openseespy.opensees.uniaxialMaterial`. `exact` says whether OpenSees integrates
    the same equations (its implicit Euler converges to the ODE as the strain
    increments shrink); `dropped` names the effects it cannot represent, and `note`
    says why.
    """

    material: str
    tag: int
    names: tuple[str, ...]
    values: tuple[float | int, ...]
    command: str
    exact: bool
    dropped: tuple[str, ...]
    units: str
    note: str

    def parameters(self) -> dict[str, float | int]:
        """The material's arguments after the tag, by their OpenSees names."""
        return dict(zip(self.names, self.values, strict=True))

    def openseespy_args(self) -> tuple[Any, ...]:
        """`(material, tag, *values)`: call `ops.uniaxialMaterial(*args)`."""
        return (self.material, self.tag, *self.values)

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready summary."""
        return {
            "material": self.material,
            "tag": self.tag,
            "command": self.command,
            "parameters": self.parameters(),
            "exact": self.exact,
            "dropped": list(self.dropped),
            "units": self.units,
            "note": self.note,
        }


def _format(value: float | int) -> str:
    return str(value) if isinstance(value, int) else repr(float(value))


def _units(material: str, force_unit: str | None, displacement_unit: str | None, n):
    force = force_unit or "force"
    length = displacement_unit or "displacement"
    energy = f"1/({force}*{length})"
    parts = [
        f"ko in {force}/{length}",
        f"gamma and beta in 1/{length}^n (n = {n:.6g})",
    ]
    if material == "BoucWen":
        parts.append(f"deltaA, deltaNu and deltaEta in {energy} (per unit energy)")
        parts.append("alpha, n and Ao dimensionless")
    else:
        parts.append(f"p in {energy} (per unit energy)")
        parts.append(f"Shi in {length}, deltaShi in {length}/({force}*{length})")
        parts.append("alpha, n, Ao, q, zetas and lamda dimensionless")
    parts.append(f"tol in {length}")
    sentence = "; ".join(parts) + "."
    if force_unit is None or displacement_unit is None:
        sentence += (
            " These are the units of the record the model was fitted to; name them "
            "with force_unit= and displacement_unit=."
        )
    return sentence


def opensees_material(
    model: StructuralBoucWen | BoucWen,
    *,
    tag: int = 1,
    force_unit: str | None = None,
    displacement_unit: str | None = None,
) -> OpenSeesMaterial:
    """The OpenSees uniaxial material that reproduces `model` (a `StructuralBoucWen`,
    or a `BoucWen` with D > 0 and A > 0, converted by
    `StructuralBoucWen.from_bouc_wen`): the model's `opensees_model()`, whose
    `opensees_parameters()` the material is built from.

    Without pinching it is `BoucWen` (deltaNu, deltaEta = strength_degradation,
    stiffness_degradation divided by energy_scale; deltaA = 0); with pinching it is
    `BWBN` (zetas = pinch, q = pinch_shift, p = pinch_rate/energy_scale, Shi =
    pinch_width*zu, deltaShi = 0, lamda = pinch_lambda), which has no degradation: with
    both on, degradation is dropped. Asymmetry and drift are dropped when on, and a
    smoothed sign (OpenSees uses the exact one) makes the export inexact. Parameters
    count as on when non-zero. tol = 1e-10*zu, maxNumIter = 100.

    Checked against OpenSees (openseespy 3.7) in tests/test_opensees.py: driven by
    `opensees_force` with 200 strain increments per sample of a 300-sample cyclic
    history of growing amplitude, the force agrees with `simulate(model, path,
    RK4(substeps=20))` within 1e-3 of max|F| (measured 1.5e-4, the implicit Euler's
    first-order error, shrinking as 1/substeps) for plain, degrading and pinching
    models. OpenSees materials start at x = 0, z = 0: start the history at 0.
    """
    model = model.opensees_model()
    if isinstance(tag, bool) or not isinstance(tag, int | np.integer):
        raise TypeError(f"opensees_material(tag={tag!r}): tag must be an integer >= 1.")
    if tag < 1:
        raise ValueError(
            f"opensees_material(tag={tag}): OpenSees tags must be >= 1; pass tag=1 "
            "or the next free tag of your OpenSees model."
        )
    for option, unit in (
        ("force_unit", force_unit),
        ("displacement_unit", displacement_unit),
    ):
        if unit is not None and not isinstance(unit, str):
            raise TypeError(
                f"opensees_material({option}={unit!r}): a unit is a string such as "
                "'kN' or 'mm', or None."
            )

    p = model.opensees_parameters()
    energy_scale, pinch_lambda = p["energy_scale"], p["pinch_lambda"]
    k, alpha, n, gamma, beta, A = (
        p[x] for x in ("k", "alpha", "n", "gamma", "beta", "A")
    )
    total = beta + gamma
    zu = (1.0 / total) ** (1.0 / n) if total > 0 and n > 0 else math.nan

    degrading = p["strength_degradation"] != 0 or p["stiffness_degradation"] != 0
    pinching = p["pinch"] != 0
    dropped: list[str] = []
    reasons: list[str] = []
    if pinching and degrading:
        dropped.append("degradation")
        reasons.append(
            "degradation (strength_degradation="
            f"{p['strength_degradation']:.4g}, stiffness_degradation="
            f"{p['stiffness_degradation']:.4g}): BWBN, the only OpenSees material "
            "with this pinching, has no strength or stiffness degradation"
        )

    def drop_group(what: str, names: tuple[str, ...], why: str) -> None:
        on = {name: p[name] for name in names if p.get(name, 0.0) != 0}
        if on:
            dropped.append(what)
            listed = ", ".join(f"{name}={value:.4g}" for name, value in on.items())
            reasons.append(f"{what} ({listed}): {why}")

    drop_group(
        "peak-driven degradation",
        _PEAK_DEGRADATION,
        "OpenSees's Bouc-Wen materials degrade with the dissipated energy only, not "
        "with the largest displacement reached",
    )
    drop_group(
        "series slip",
        ("slip_length",),
        "no OpenSees Bouc-Wen material has a slip in series whose length grows "
        f"with the largest displacement (its force window: slip_window="
        f"{p['slip_window']:.4g} F_y)",
    )
    if p["yield_skew"] != 0 or p["stiffness_skew"] != 0:
        dropped.append("asymmetry")
        reasons.append(
            f"asymmetry (yield_skew={p['yield_skew']:.4g}, stiffness_skew="
            f"{p['stiffness_skew']:.4g}): OpenSees Bouc-Wen materials are symmetric "
            "(one saturation level, one post-yield stiffness)"
        )
    drop_group(
        "drift",
        _DRIFT,
        "a load-cell offset and slow drift of the test, not a property of the member",
    )
    if not isinstance(model.smoothing, ExactSign):
        dropped.append("smoothing")
        reasons.append(
            f"smoothing ({type(model.smoothing).__name__}): OpenSees uses the exact "
            "sign, so the exported loops have sharp reversals"
        )

    cap = float(model.reach())
    if pinching and math.isfinite(zu) and zu > cap:
        dropped.append("pinching position")
        reasons.append(
            f"the pinching's position: jaxhyst places it at zu capped at {cap:.4g} "
            f"(the z the record's max|x| and max|F| reach; the loop does not "
            f"saturate within the test, zu = {zu:.4g}); BWBN uses zu itself"
        )
    tol = _RELATIVE_TOL * (zu if math.isfinite(zu) else 1.0)
    if pinching:
        if not math.isfinite(zu):
            raise ValueError(
                "opensees_material: BWBN's pinching is placed at zu = "
                "(1/(beta + gamma))^(1/n), which needs beta + gamma > 0 and n > 0 "
                f"(got beta={beta:.4g}, gamma={gamma:.4g}, n={n:.4g}); refit with "
                "those bounds or switch pinching off (pinch=0)."
            )
        material, names = "BWBN", _BWBN_NAMES
        values: tuple[float | int, ...] = (
            alpha,
            k,
            n,
            gamma,
            beta,
            A,
            p["pinch_shift"],
            p["pinch"],
            p["pinch_rate"] / energy_scale,
            p["pinch_width"] * zu,
            0.0,
            pinch_lambda,
            tol,
            _MAX_ITER,
        )
    else:
        material, names = "BoucWen", _BOUC_WEN_NAMES
        values = (
            alpha,
            k,
            n,
            gamma,
            beta,
            A,
            0.0,
            p["strength_degradation"] / energy_scale,
            p["stiffness_degradation"] / energy_scale,
            tol,
            _MAX_ITER,
        )
    bad = [name for name, v in zip(names, values) if not math.isfinite(v)]
    if bad:
        raise ValueError(
            f"opensees_material: the {material} parameters {', '.join(bad)} are not "
            "finite; check the model's parameters and energy_scale (> 0)."
        )

    if reasons:
        note = (
            f"OpenSees {material} cannot represent " + "; ".join(reasons) + ". The "
            "material reproduces the model without these."
        )
    else:
        note = (
            f"Exact: OpenSees {material} integrates the same equations (implicit "
            "Euler per strain increment; use small increments)."
        )
    note += " OpenSees starts the material at x = 0 with z = 0."
    command = " ".join(
        ["uniaxialMaterial", material, str(int(tag))] + [_format(v) for v in values]
    )
    return OpenSeesMaterial(
        material=material,
        tag=int(tag),
        names=names,
        values=values,
        command=command,
        exact=not dropped,
        dropped=tuple(dropped),
        units=_units(material, force_unit, displacement_unit, n),
        note=note,
    )


def _preload_bundled_blas() -> bool:
    """Load libblas.so.3 from the openseespylinux wheel's lib/ folder, where the
    wheel's liblapack finds it only on LD_LIBRARY_PATH. True if it was loaded."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        spec = importlib.util.find_spec("openseespylinux")
    except (ImportError, ValueError):
        return False
    if spec is None or not spec.submodule_search_locations:
        return False
    for folder in spec.submodule_search_locations:
        path = os.path.join(folder, "lib", "libblas.so.3")
        if os.path.exists(path):
            try:
                ctypes.CDLL(path)
            except OSError:
                return False
            return True
    return False


def _import_openseespy() -> Any:
    """`openseespy.opensees` (a compiled module: typed Any), or an ImportError that
    says how to install it."""
    try:
        import openseespy.opensees as ops

        return ops
    except ModuleNotFoundError:
        raise ImportError(f"openseespy is not installed; {_INSTALL_HINT}") from None
    # openseespy wraps every failure to load its binary in a RuntimeError.
    except (ImportError, OSError, RuntimeError) as error:
        first = error
    if _preload_bundled_blas():
        try:
            import openseespy.opensees as ops

            return ops
        except (ImportError, OSError, RuntimeError) as error:
            first = error
    raise ImportError(
        f"openseespy is installed but cannot load ({first}); {_INSTALL_HINT}"
    ) from first


def opensees_force(
    material: OpenSeesMaterial,
    displacement: Float[ArrayLike, " n"],
    substeps: int,
) -> np.ndarray:
    """The force OpenSees's material gives along `displacement`: each sample
    interval (and the step from x = 0 to the first sample) is split into `substeps`
    equal strain increments, and the stress is read at every sample. The material
    starts at x = 0, z = 0, so start the history at 0 to compare with `simulate`.

    This wipes openseespy's model (`ops.wipe()`) before and after. Needs openseespy
    (`pip install 'jaxhyst[opensees]'`).
    """
    if not isinstance(material, OpenSeesMaterial):
        raise TypeError(
            "opensees_force: material must be an OpenSeesMaterial (from "
            f"opensees_material), got {type(material).__name__}."
        )
    x = np.asarray(displacement, dtype=np.float64)
    if x.ndim != 1 or x.size < 1 or not np.all(np.isfinite(x)):
        raise ValueError(
            "opensees_force: displacement must be a non-empty 1-D array of finite "
            f"numbers, got shape {x.shape}."
        )
    if isinstance(substeps, bool) or not isinstance(substeps, int) or substeps < 1:
        raise ValueError(
            f"opensees_force(substeps={substeps!r}): substeps must be an integer >= 1."
        )
    ops = _import_openseespy()
    fractions = np.arange(1, substeps + 1) / substeps
    start = np.concatenate([[0.0], x[:-1]])
    path = start[:, None] + (x - start)[:, None] * fractions[None, :]
    force = np.empty_like(x)
    ops.wipe()
    try:
        ops.model("basic", "-ndm", 1, "-ndf", 1)
        ops.uniaxialMaterial(*material.openseespy_args())
        ops.testUniaxialMaterial(material.tag)
        set_strain, get_stress = ops.setStrain, ops.getStress
        for i, row in enumerate(path.tolist()):
            for strain in row:
                set_strain(strain)
            force[i] = get_stress()
    finally:
        ops.wipe()
    return force


def opensees_json(model, recording) -> dict[str, Any]:
    """The `opensees` keys of the `jaxhyst fit` / `diagnose` JSON: the Tcl command
    (None when the model cannot be exported, with the reason) and the material's
    summary, in the recording's units."""
    try:
        material = opensees_material(
            model,
            force_unit=recording.output_unit or None,
            displacement_unit=recording.input_unit or None,
        )
    except ValueError as error:  # a fit outside OpenSees's forms (A <= 0, D <= 0)
        return {"opensees": None, "opensees_note": str(error)}
    return {"opensees": material.command, "opensees_material": material.to_dict()}
