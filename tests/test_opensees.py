"""Export to OpenSees uniaxial materials: the commands, and the real program's force
against `simulate` where openseespy loads."""

import json

import numpy as np
import pytest

import jaxhyst as jh
from jaxhyst._opensees import OpenSeesMaterial, opensees_force, opensees_material


# A column in SI units: yield displacement zu = 5 mm, so OpenSees's Newton (which
# starts at z = 0.01 and stops on an absolute |dz|) is exercised off the unit scale.
ZU = 0.005
N = 2.0
K = 2e7
ALPHA = 0.05
BETA, GAMMA = 0.6 / ZU**N, 0.4 / ZU**N
SAMPLES = 300
ENERGY_SCALE = K * 3 * ZU * 3 * ZU  # max|F| * max|x| of the history below, roughly
# OpenSees integrates each strain increment by implicit Euler: first order, so its
# error shrinks as 1/OPENSEES_SUBSTEPS (measured 1.5e-4 of max|F| at 200).
OPENSEES_SUBSTEPS = 200
RK4_SUBSTEPS = 20
TOLERANCE = 1e-3  # of max|F|


def _history() -> jh.Recording:
    """Three cycles of growing amplitude, up to 3*zu, starting at x = 0."""
    t = np.linspace(0.0, 1.0, SAMPLES)
    x = 3 * ZU * t * np.sin(2 * np.pi * 3 * t)
    return jh.Recording(t, x, np.zeros(SAMPLES))


def _structural(**effects) -> jh.StructuralBoucWen:
    return jh.StructuralBoucWen(
        K, ALPHA, 1.0, BETA, GAMMA, N, energy_scale=ENERGY_SCALE, **effects
    )


def _numbers(command: str) -> list[float]:
    return [float(v) for v in command.split()[3:]]


# --- commands -------------------------------------------------------------------


def test_plain_structural_model_exports_exactly_to_bouc_wen():
    material = opensees_material(_structural(), tag=7)
    assert isinstance(material, OpenSeesMaterial)
    assert material.material == "BoucWen"
    assert material.exact and material.dropped == ()
    assert material.command.startswith("uniaxialMaterial BoucWen 7 ")
    # alpha ko n gamma beta Ao deltaA deltaNu deltaEta tol maxNumIter
    values = _numbers(material.command)
    assert values[:9] == pytest.approx([ALPHA, K, N, GAMMA, BETA, 1.0, 0, 0, 0])
    assert values[9] == pytest.approx(1e-10 * ZU)
    assert values[10] == 100
    assert material.openseespy_args() == ("BoucWen", 7, *material.values)
    assert isinstance(material.openseespy_args()[-1], int)


def test_degradation_is_divided_by_the_energy_scale():
    model = _structural(strength_degradation=0.3, stiffness_degradation=0.2)
    material = opensees_material(model)
    assert material.material == "BoucWen" and material.exact
    parameters = material.parameters()
    assert parameters["deltaA"] == 0
    assert parameters["deltaNu"] == pytest.approx(0.3 / ENERGY_SCALE)
    assert parameters["deltaEta"] == pytest.approx(0.2 / ENERGY_SCALE)


def test_pinching_exports_to_bwbn_in_source_order():
    model = _structural(
        pinch=0.7, pinch_shift=0.15, pinch_width=0.25, pinch_rate=4.0, pinch_lambda=0.4
    )
    material = opensees_material(model, tag=3)
    assert material.material == "BWBN" and material.exact
    assert material.command.startswith("uniaxialMaterial BWBN 3 ")
    # alpha ko n gamma beta Ao q zetas p Shi deltaShi lamda tol maxNumIter
    expected = [ALPHA, K, N, GAMMA, BETA, 1.0, 0.15, 0.7, 4.0 / ENERGY_SCALE]
    expected += [0.25 * ZU, 0.0, 0.4, 1e-10 * ZU, 100]
    assert _numbers(material.command) == pytest.approx(expected)
    assert list(material.parameters()) == [
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
    ]


def test_command_values_round_trip_exactly():
    model = _structural(strength_degradation=0.123456789012345)
    material = opensees_material(model)
    assert _numbers(material.command) == list(material.values)


def test_pinching_with_degradation_drops_degradation():
    model = _structural(pinch=0.5, strength_degradation=0.2)
    material = opensees_material(model)
    assert material.material == "BWBN"
    assert not material.exact
    assert material.dropped == ("degradation",)
    assert "degradation" in material.note and "BWBN" in material.note


def test_asymmetry_drift_and_smoothing_are_dropped():
    model = _structural(yield_skew=0.1, stiffness_skew=0.2, offset=5.0, trend=1.0)
    material = opensees_material(model)
    assert material.material == "BoucWen"
    assert material.dropped == ("asymmetry", "drift")
    assert not material.exact
    assert "offset=5" in material.note and "yield_skew=0.1" in material.note
    if "wander" in jh.StructuralBoucWen.parameter_names:
        assert opensees_material(_structural(wander=0.2)).dropped == ("drift",)
    smooth = jh.StructuralBoucWen(
        K, ALPHA, 1.0, BETA, GAMMA, N, smoothing=jh.TanhSign(1e-4)
    )
    assert opensees_material(smooth).dropped == ("smoothing",)
    peak = opensees_material(
        _structural(strength_degradation=0.1, peak_stiffness_degradation=0.02)
    )
    assert peak.material == "BoucWen" and not peak.exact
    assert peak.dropped == ("peak-driven degradation",)
    assert "peak_stiffness_degradation=0.02" in peak.note
    assert "peak_strength_degradation" not in peak.note
    slip = opensees_material(_structural(pinch=0.5, slip_length=0.3))
    assert slip.material == "BWBN" and slip.dropped == ("series slip",)
    assert "slip_length=0.3" in slip.note and "slip_window=0.1" in slip.note
    # Its window is a shape parameter: inert, and not dropped, while the slip is off.
    assert opensees_material(_structural(slip_window=0.5)).exact


def test_bouc_wen_is_converted_to_the_structural_gauge():
    base = jh.BoucWen(K / 2, ALPHA, 2.0, 1.5, 3 * BETA, 3 * GAMMA, N)
    structural = jh.StructuralBoucWen.from_bouc_wen(base)
    material = opensees_material(base)
    assert material.material == "BoucWen" and material.exact
    assert material.parameters()["ko"] == pytest.approx(float(structural.k))
    assert material.parameters()["Ao"] == 1.0
    assert material.parameters()["beta"] == pytest.approx(float(structural.beta))


def test_units_and_json():
    material = opensees_material(
        _structural(pinch=0.5), force_unit="kN", displacement_unit="mm"
    )
    assert "ko in kN/mm" in material.units
    assert "Shi in mm" in material.units
    assert "p in 1/(kN*mm)" in material.units
    data = json.loads(json.dumps(material.to_dict()))
    assert data["material"] == "BWBN"
    assert data["command"] == material.command
    assert data["parameters"]["zetas"] == 0.5
    assert "force/displacement" in opensees_material(_structural()).units


def test_errors_name_the_argument():
    with pytest.raises(TypeError, match="StructuralBoucWen or BoucWen"):
        opensees_material(jh.PiezoBoucWen(0.3, 1.0, 0.5, 0.6, 0.2, 1.5))
    with pytest.raises(ValueError, match="tag=0"):
        opensees_material(_structural(), tag=0)
    with pytest.raises(TypeError, match="tag"):
        opensees_material(_structural(), tag=1.5)  # pyright: ignore[reportArgumentType]
    with pytest.raises(TypeError, match="force_unit"):
        opensees_material(_structural(), force_unit=1)  # pyright: ignore[reportArgumentType]
    with pytest.raises(ValueError, match="D > 0 and A > 0"):
        opensees_material(jh.BoucWen(K, ALPHA, 1.0, -1.0, BETA, GAMMA, N))
    with pytest.raises(ValueError, match="beta \\+ gamma > 0"):
        opensees_material(
            jh.StructuralBoucWen(K, ALPHA, 1.0, -BETA, GAMMA, N, pinch=0.5)
        )
    with pytest.raises(TypeError, match="OpenSeesMaterial"):
        opensees_force("BoucWen", np.zeros(3), 10)  # pyright: ignore[reportArgumentType]
    with pytest.raises(ValueError, match="substeps"):
        opensees_force(opensees_material(_structural()), np.zeros(3), 0)


# --- against the real OpenSees ----------------------------------------------------


@pytest.fixture(scope="module")
def opensees():
    try:
        opensees_force(opensees_material(_structural()), np.array([0.0, ZU]), 2)
    except (ImportError, OSError) as error:
        pytest.skip(f"openseespy cannot load here: {error}")


def _mismatch(model, substeps: int = OPENSEES_SUBSTEPS) -> float:
    recording = _history()
    expected = np.asarray(
        jh.simulate(model, recording.input_path(), jh.RK4(substeps=RK4_SUBSTEPS))
    )
    force = opensees_force(opensees_material(model), recording.u, substeps)
    return float(np.max(np.abs(force - expected)) / np.max(np.abs(expected)))


@pytest.mark.parametrize(
    "case",
    ["plain", "degradation", "pinching"],
)
def test_opensees_reproduces_the_model(opensees, case):
    model = {
        # A BoucWen with D, A != 1: the conversion is checked too.
        "plain": jh.BoucWen(K / 2, ALPHA, 2.0, 1.5, 3 * BETA, 3 * GAMMA, N),
        "degradation": _structural(strength_degradation=0.3, stiffness_degradation=0.2),
        "pinching": _structural(pinch=0.7, pinch_rate=5.0),
    }[case]
    assert _mismatch(model) < TOLERANCE


def test_opensees_converges_at_first_order(opensees):
    """Implicit Euler: 4x the increments, about 1/4 of the mismatch; a mapping error
    would not shrink."""
    model = _structural(pinch=0.7, strength_degradation=0.0, pinch_rate=5.0)
    coarse, fine = _mismatch(model, 50), _mismatch(model, 200)
    assert 3.0 < coarse / fine < 5.0


def test_a_wrong_parameter_is_detected(opensees):
    """The check discriminates: 10 % off in deltaNu is well above the tolerance."""
    model = _structural(strength_degradation=0.3)
    off = _structural(strength_degradation=0.33)
    recording = _history()
    expected = np.asarray(
        jh.simulate(model, recording.input_path(), jh.RK4(substeps=RK4_SUBSTEPS))
    )
    force = opensees_force(opensees_material(off), recording.u, OPENSEES_SUBSTEPS)
    assert np.max(np.abs(force - expected)) > 3 * TOLERANCE * np.max(np.abs(expected))
