"""Evidence, units and readings of the catalogue effects: words built from numbers.

Every evidence sentence must claim a pattern only when the figure it quotes passes
its threshold, say so plainly when no figure supports the effect, and quote no
number that is not in (or directly derived from) the figures it was given.
"""

import copy
import math
import re

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest

import jaxhyst as jh
from jaxhyst._diagnose._effects import base as words
from jaxhyst._diagnose._effects.degradation import NEGLIGIBLE
from jaxhyst._diagnose._effects.dynamics import NEAR_RESONANCE
from jaxhyst._diagnose._families import CATALOGUE, StructuralFamily
from jaxhyst._diagnose._locate import (
    CONCENTRATED,
    describe,
    describe_cycles,
    locate,
    locate_cycles,
)


STRUCTURAL = {e.name: e for e in StructuralFamily().catalogue}
ALL_EFFECTS = [*CATALOGUE.values(), *STRUCTURAL.values()]
NO_SUPPORT = "no location figure singles it out"
RNG = np.random.default_rng(0)
NAN = re.compile(r"\bnan\b", re.IGNORECASE)

# ------------------------------------------------------------------ quoted numbers

_NUMBER = re.compile(r"(?<![\w.^|])-?\d+(?:\.\d+)?(?:e[+-]?\d+)?%?")


def _leaves(tree):
    if isinstance(tree, dict):
        for value in tree.values():
            yield from _leaves(value)
    elif isinstance(tree, int | float):
        yield float(tree)


def assert_quotes_only(text: str, *sources):
    """Every number in `text` is one of `sources` (numbers or `where` dicts, their
    absolute values included) as rounded where quoted (a % reads as a share)."""
    values = [v for s in sources for v in _leaves(s if isinstance(s, dict) else {0: s})]
    values += [abs(v) for v in values]
    for token in _NUMBER.findall(text):
        percent = token.endswith("%")
        digits = token.rstrip("%")
        mantissa = digits.split("e")[0]
        decimals = len(mantissa.split(".")[1]) if "." in mantissa else 0
        power = int(digits.split("e")[1]) if "e" in digits else 0
        quoted = float(digits) / (100 if percent else 1)
        tolerance = 0.5 * 10.0 ** (power - decimals) / (100 if percent else 1)
        assert any(
            math.isfinite(v) and abs(v - quoted) <= tolerance * (1 + 1e-9) + 1e-300
            for v in values
        ), f"{token!r} in {text!r} is none of the figures"


def test_the_number_check_can_fail():
    with pytest.raises(AssertionError):
        assert_quotes_only("residual 1.60x the overall RMS", {"relative": 0.92})
    assert_quotes_only("residual 0.92x and 15%", {"relative": 0.921, "s": 0.148})


# ------------------------------------------------------------------ piezo records

DT = 1e-3


def _piezo_record():
    """A 0.5 Hz sine with two 3 s holds: reversals, extremes, rates and holds. The
    sine's peaks fall between samples (a sample on a peak has zero central-difference
    rate, which `locate` would count as a hold)."""
    t = np.arange(0.0, 22.0, DT)
    u = np.zeros_like(t)
    moving = (t < 8) | ((t >= 11) & (t < 19))
    phase = np.where(t < 8, t, t - 3) + DT / 2
    u[moving] = 75 * np.sin(2 * np.pi * 0.5 * phase[moving])
    return t, u


T, U = _piezo_record()
UDOT = np.gradient(U, DT)
NOISE = RNG.standard_normal(T.size)


def _reversal_bumps():
    # The sine reverses at phase 0.5 + k s: t = 0.5 ... 7.5 and 11.5 ... 18.5.
    times = [*np.arange(0.5, 8, 1.0), *np.arange(11.5, 19, 1.0)]
    return sum(4 * np.exp(-(((T - tr) / 0.02) ** 2)) for tr in times)


def _hold_relaxation():
    holding = np.abs(UDOT) <= 1e-3 * np.max(np.abs(UDOT))
    starts = T[1:][np.diff(holding.astype(int)) == 1]
    tail = np.zeros_like(T)
    for start in starts:
        after = T >= start
        tail[after] += 3 * np.exp(-(T[after] - start) / 0.5)
    return tail


PIEZO_PATTERNS = {
    "noise": NOISE,
    "reversals": 0.2 * NOISE + _reversal_bumps(),
    "extremes": 0.2 * NOISE + 3 * (U / 75) ** 8,
    "branches": 0.3 * NOISE + np.sign(UDOT),
    "fast": 0.2 * NOISE + 3 * (np.abs(UDOT) / np.max(np.abs(UDOT))) ** 6,
    "hold": 0.2 * NOISE + _hold_relaxation(),
    "trend": 0.2 * NOISE + T / 10,
}
WHERE = {name: locate(T, U, r) for name, r in PIEZO_PATTERNS.items()}
BASE = jh.PiezoBoucWen(1.0, 0.3, -1.0, 0.002, -0.001, 1.5)
PIEZO = jh.ExtendedPiezo.around(BASE, jh.sample(jh.paper_u1(), 100.0))


def _piezo_derived(where):
    """The ratios of figures the piezo evidence may quote (branch gap, rate
    contrast, trend share)."""
    overall = where["overall_rms"]
    fast, slow = where["fast_rate"]["relative"], where["slow_rate"]["relative"]
    return [
        (where["ascending"]["mean"] - where["descending"]["mean"]) / overall,
        fast / slow,
        slow / fast,
        where["slow_trend_rms"] / overall,
    ]


def _claims(text: str) -> bool:
    return NO_SUPPORT not in text


@pytest.mark.parametrize(
    "effect, supported_by",
    [
        ("input_bias", {"reversals"}),
        ("asymmetry", {"extremes", "branches"}),
        ("rate_dependence", {"fast", "extremes", "reversals"}),
        ("creep", {"hold"}),
        ("drift", {"trend", "hold"}),
    ],
)
def test_piezo_evidence_claims_only_what_the_located_residual_shows(
    effect, supported_by
):
    for pattern, where in WHERE.items():
        text = CATALOGUE[effect].evidence(where, PIEZO)
        assert_quotes_only(text, where, *_piezo_derived(where))
        if pattern == "noise":
            assert not _claims(text), text
        if pattern in supported_by:
            assert _claims(text), (pattern, text)
        # A claim is always backed by a figure past its threshold.
        if "the residual is concentrated" in text:
            shown = re.findall(r"is concentrated [^(]*\((\d+\.\d+)x", text)
            assert shown and all(float(x) >= CONCENTRATED for x in shown)


def test_input_bias_does_not_call_092x_a_concentration():
    where = copy.deepcopy(WHERE["reversals"])
    assert "concentrated near reversals" in jh.effects.InputBias().evidence(
        where, PIEZO
    )
    where["near_reversals"]["relative"] = 0.92
    text = jh.effects.InputBias().evidence(where, PIEZO)
    assert "time shift" not in text and "is concentrated" not in text
    assert "not concentrated near reversals (0.92x the overall RMS)" in text
    assert NO_SUPPORT in text and "score test and the held-out gain" in text
    where["near_reversals"]["relative"] = 1.6
    text = jh.effects.InputBias().evidence(where, PIEZO)
    assert "concentrated near reversals (1.60x the overall RMS)" in text
    assert "time shift" in text and NO_SUPPORT not in text


@pytest.mark.parametrize(
    "peak, near", [(0.3, False), (500.0, False), (600.0, True), (851.0, True)]
)
def test_dynamics_names_the_resonance_only_near_the_fitted_one(peak, near):
    where = copy.deepcopy(WHERE["noise"])
    where["dominant_frequency_hz"] = peak
    model = PIEZO.with_dynamics(851.0, 0.3)
    text = jh.effects.Dynamics().evidence(where, model)
    assert_quotes_only(text, where, 851.0)
    assert ("near the fitted resonance" in text) is near
    assert (max(peak / 851, 851 / peak) <= NEAR_RESONANCE) is near
    if not near:
        assert "is not at the fitted resonance (851 Hz)" in text
        assert "the evidence is the held-out gain" in text


def test_asymmetry_branch_means_are_a_difference_only_when_far_apart():
    where = copy.deepcopy(WHERE["noise"])
    where["ascending"]["mean"], where["descending"]["mean"] = 0.152, 0.135
    where["overall_rms"] = 0.2
    text = jh.effects.Asymmetry().evidence(where, PIEZO)
    assert "branches do not differ on average" in text and NO_SUPPORT in text
    assert_quotes_only(text, where, 0.017 / 0.2)
    where["overall_rms"] = 0.05  # the same gap is now 0.34x the RMS
    text = jh.effects.Asymmetry().evidence(where, PIEZO)
    assert "branches differ on average" in text and NO_SUPPORT not in text
    assert_quotes_only(text, where, 0.017 / 0.05)


def test_asymmetry_without_a_branch_gap_rests_on_the_bend_at_the_extremes():
    text = jh.effects.Asymmetry().evidence(WHERE["extremes"], PIEZO)
    assert "branches do not differ" in text
    assert "concentrated at the extremes of the stroke" in text
    assert NO_SUPPORT not in text


def test_rate_dependence_does_not_cite_095x_at_fast_rates():
    where = copy.deepcopy(WHERE["noise"])
    where["fast_rate"]["relative"], where["slow_rate"]["relative"] = 0.95, 1.02
    text = jh.effects.RateDependence().evidence(where, PIEZO)
    assert "not concentrated at fast rates (0.95x" in text and NO_SUPPORT in text
    # A contrast between the terciles is support even when neither stands out.
    where["fast_rate"]["relative"], where["slow_rate"]["relative"] = 1.2, 0.7
    text = jh.effects.RateDependence().evidence(where, PIEZO)
    assert "at fast rates is 1.71x that at slow rates" in text
    assert NO_SUPPORT not in text
    assert_quotes_only(text, where, 1.2 / 0.7)


def test_creep_without_holds_names_no_relaxation():
    where = copy.deepcopy(WHERE["noise"])
    where["after_hold"]["relative"] = float("nan")
    text = jh.effects.Creep().evidence(where, PIEZO)
    assert "no holds" in text and "nan" not in text and NO_SUPPORT in text


def test_describe_names_only_what_stands_out():
    text = describe(WHERE["noise"])
    assert "spread evenly" in text
    text = describe(WHERE["reversals"])
    relative = WHERE["reversals"]["near_reversals"]["relative"]
    assert f"near reversals ({relative:.2f}x the overall RMS)" in text
    assert "spread evenly" not in text
    for where in WHERE.values():
        text = describe(where)
        for x in re.findall(r"\((\d+\.\d+)x the overall RMS\)", text):
            assert float(x) >= CONCENTRATED
        # 1: the moving average's window (s).
        assert_quotes_only(text, where, *_piezo_derived(where), 1.0)


# ------------------------------------------------------------- structural records


def _cyclic_test():
    """Three amplitude levels of two cycles, a softening force."""
    x = np.concatenate(
        [a * np.sin(np.linspace(0, 2 * np.pi, 400)) for a in (1, 1, 2, 2, 3, 3)]
    )
    force = 10 * np.tanh(x) + np.gradient(x) * 40
    return x, force


X, F = _cyclic_test()
CYCLE_NOISE = RNG.standard_normal(X.size)
N = X.size
LATE = np.arange(N) >= 2 * N // 3
STRUCTURAL_PATTERNS = {
    "noise": CYCLE_NOISE,
    "late": CYCLE_NOISE * np.where(LATE, 3.0, 0.5),
    "zero_force": 0.3 * CYCLE_NOISE
    + 3 * CYCLE_NOISE * (np.abs(F) < 0.15 * np.max(np.abs(F))),
    "even": 0.2 * CYCLE_NOISE + np.abs(X),
    "odd": 0.2 * CYCLE_NOISE + X,
    "weakening": 0.2 * CYCLE_NOISE - np.where(LATE, np.sign(F) * np.abs(X), 0.0),
}
CYCLES = {name: locate_cycles(X, F, r) for name, r in STRUCTURAL_PATTERNS.items()}
STRUCTURAL_MODEL = jh.StructuralBoucWen(
    1.0, 0.1, 1.0, 0.5, 0.5, 1.5, strength_degradation=0.05, pinch=0.4
)


def _degradation_figures(where, model):
    """The fitted losses the degradation evidence quotes, as it computes them."""
    energy = max(where["dissipated_energy"], 0.0)
    nu = max(1 + float(model.strength_degradation) * energy, 1e-2)
    eta = max(1 + float(model.stiffness_degradation) * energy, 1e-2)
    return 1 - nu ** (-1 / float(model.n)), 1 - 1 / eta


@pytest.mark.parametrize(
    "effect, supported_by, never",
    [
        ("degradation", {"late", "weakening"}, set()),
        ("pinching", {"zero_force"}, {"late"}),
        ("asymmetry", {"even"}, {"odd", "late"}),
        ("drift", {"even"}, set()),
    ],
)
def test_structural_evidence_claims_only_what_the_located_residual_shows(
    effect, supported_by, never
):
    for pattern, where in CYCLES.items():
        text = STRUCTURAL[effect].evidence(where, STRUCTURAL_MODEL)
        ratio = where["last_third"]["relative"] / where["first_third"]["relative"]
        excess = abs(where["late_peak_force_excess"]) / where["overall_rms"]
        shares = [
            where[k] / where["overall_rms"] for k in ("slow_trend_rms", "even_part_rms")
        ]
        assert_quotes_only(
            text,
            where,
            ratio,
            excess,
            *shares,
            *_degradation_figures(where, STRUCTURAL_MODEL),
            float(STRUCTURAL_MODEL.pinch),
            NEGLIGIBLE,
            min(abs(where["push"]["mean"]), abs(where["pull"]["mean"]))
            / where["overall_rms"],
        )
        if pattern == "noise" or pattern in never:
            assert not _claims(text), (pattern, text)
        if pattern in supported_by:
            assert _claims(text), (pattern, text)


def test_push_pull_means_of_opposite_sign_are_not_asymmetry():
    odd = CYCLES["odd"]
    assert odd["push"]["mean"] > 0 > odd["pull"]["mean"]
    text = jh.effects.PushPullAsymmetry().evidence(odd, STRUCTURAL_MODEL)
    assert "same sign" not in text and NO_SUPPORT in text
    text = jh.effects.PushPullAsymmetry().evidence(CYCLES["even"], STRUCTURAL_MODEL)
    assert "same sign in push" in text and "cannot produce" in text


def test_degradation_names_what_the_fitted_values_show():
    where = copy.deepcopy(CYCLES["noise"])
    where["dissipated_energy"] = 10.0
    none = STRUCTURAL_MODEL.replace(strength_degradation=0.0)
    assert "change by under 1%" in jh.effects.Degradation().evidence(where, none)
    text = jh.effects.Degradation().evidence(where, STRUCTURAL_MODEL)
    strength, _ = _degradation_figures(where, STRUCTURAL_MODEL)
    assert "mainly the strength changes" in text
    assert f"strength is down {strength:.0%}" in text
    # A rate at its floor reads as no change (not "up -0%").
    assert "its stiffness unchanged" in text and "-0%" not in text
    # The peak-driven rates count from zero (not from the yield displacement, 1
    # here) to the record's largest displacement (10).
    peak = eqx.tree_at(
        lambda m: m.displacement_scale,
        none.replace(peak_strength_degradation=0.05),
        jnp.asarray(10.0),
    )
    assert float(peak.saturation()) == pytest.approx(1.0)
    assert f"strength is down {1 - 1.5 ** (-1 / 1.5):.0%}" in (
        jh.effects.Degradation().evidence(where, peak)
    )
    both = STRUCTURAL_MODEL.replace(stiffness_degradation=0.05)
    assert "both strength and stiffness" in jh.effects.Degradation().evidence(
        where, both
    )
    where["late_peak_force_excess"] = 0.5 * where["overall_rms"]
    text = jh.effects.Degradation().evidence(where, STRUCTURAL_MODEL)
    assert "too small" in text and "does not produce" in text


def test_pinching_quotes_the_fitted_slip_lock_and_no_unsupported_place():
    text = jh.effects.Pinching().evidence(CYCLES["noise"], STRUCTURAL_MODEL)
    assert "up to 40% of the hysteretic stiffness" in text and NO_SUPPORT in text
    assert "series slip" not in text
    # The series slip alone: quoted, and no slip-lock claimed at 0 %.
    slip = STRUCTURAL_MODEL.replace(pinch=0.0, slip_length=0.25)
    text = jh.effects.Pinching().evidence(CYCLES["noise"], slip)
    assert "series slip moves 25% of the largest displacement beyond" in text
    assert "slip-lock" not in text and NO_SUPPORT in text
    reading = jh.effects.Pinching().reading(
        jh.effects.Pinching().values(slip),
        {},
        jh.effects.Pinching().units(time="s", input="mm", output="kN"),
    )
    assert "no slip-lock (pinch = 0)" in reading and "a series slip of 25" in reading


def test_describe_cycles_names_only_what_stands_out():
    assert "spread evenly" in describe_cycles(CYCLES["noise"])
    text = describe_cycles(CYCLES["late"])
    assert "in the last third of the test" in text and "spread evenly" not in text


# --------------------------------------------------------------- units, readings


@pytest.mark.parametrize("effect", ALL_EFFECTS, ids=lambda e: type(e).__name__)
@pytest.mark.parametrize(
    "given", [("s", "V", "µm"), ("", "", ""), ("sample", "mm", "kN")]
)
def test_every_parameter_has_a_unit(effect, given):
    time, input, output = given
    units = effect.units(time=time, input=input, output=output)
    assert set(units) == set(effect.parameters)
    for unit in units.values():
        assert isinstance(unit, str) and unit.strip()
        assert "()" not in unit and not unit.startswith("/") and not unit.endswith("/")


def test_units_follow_the_equations():
    units = {
        e.name: e.units(time="s", input="V", output="µm") for e in CATALOGUE.values()
    }
    assert units["input_bias"] == {"phi": "s", "input_lead": "1", "input_time": "s"}
    assert set(units["creep"].values()) == {"µm/V"}
    assert units["dynamics"] == {"natural_frequency": "Hz", "damping_ratio": "1"}
    assert set(units["drift"].values()) == {"µm"}
    assert units["rate_dependence"]["viscous"] == "µm"
    assert units["asymmetry"]["eps"] == "1/(V·s)"
    ms = jh.effects.Dynamics().units(time="ms", input="V", output="µm")
    assert ms["natural_frequency"] == "1/ms"
    blank = jh.effects.Creep().units(time="", input="", output="")
    assert set(blank.values()) == {"(output units)/(input units)"}
    assert jh.effects.PushPullAsymmetry().units(
        time="sample", input="mm", output="kN"
    ) == {
        "yield_skew": "1",
        "stiffness_skew": "1",
    }


def _on_values(effect):
    """Nonzero values for every parameter (gains on, shapes at plausible values)."""
    return {p: 0.1 * (i + 1) for i, p in enumerate(effect.parameters)}


@pytest.mark.parametrize("effect", ALL_EFFECTS, ids=lambda e: type(e).__name__)
def test_readings_quote_errors_or_say_not_determined(effect):
    units = effect.units(time="s", input="V", output="µm")
    values = _on_values(effect)
    text = effect.reading(values, {p: 0.01 for p in values}, units)
    assert "±" in text and not NAN.search(text) and "not determined" not in text
    for errors in ({p: float("nan") for p in values}, {}):
        text = effect.reading(values, errors, units)
        assert "not determined by this record" in text
        assert not NAN.search(text) and "±" not in text
    off = {p: (0.0 if p in effect.gains else v) for p, v in values.items()}
    assert effect.reading(off, {}, units)


def test_quantity_rounds_at_the_error():
    assert words.quantity(0.13312, 0.0041, "s") == "0.133 ± 0.004 s"
    assert words.quantity(2.93e-5, 1.2e-7, "m/V") == "(2.930 ± 0.012)e-5 m/V"
    assert words.quantity(1234.0, 40.0, "Hz") == "1230 ± 40 Hz"
    assert words.quantity(-0.0001, 0.02) == "0.00 ± 0.02"
    assert words.quantity(-0.0001, 0.012) == "0.000 ± 0.012"
    assert words.quantity(1.0, float("nan"), "1") == "1 (not determined by this record)"


def test_input_bias_reading_follows_the_models_sign():
    # The model: the hysteresis sees V = u(t + phi). With phi > 0 a drive that starts
    # moving at t = 1 s moves the output before then: the hysteresis sees it early.
    t = np.arange(0.0, 2.0, DT)
    u = np.where(t < 1.0, 0.0, 50 * (t - 1.0))
    path = jh.Recording(t, u, np.zeros_like(t)).input_path()
    model = jh.ExtendedPiezo.around(BASE, path).replace(phi=0.05)
    y = np.asarray(jh.simulate(model, path))
    moved = t[np.flatnonzero(np.abs(y - y[0]) > 1e-9)[0]]
    assert 0.94 < moved < 1.0
    units = jh.effects.InputBias().units(time="s", input="V", output="µm")
    values = {"phi": 0.133, "input_lead": 0.0, "input_time": 0.01}
    early = jh.effects.InputBias().reading(values, {"phi": 0.004}, units)
    assert "sees the drive 133 ± 4 ms early" in early
    late = jh.effects.InputBias().reading(
        {**values, "phi": -0.133}, {"phi": 0.004}, units
    )
    assert "sees the drive 133 ± 4 ms late" in late
    lag = jh.effects.InputBias().reading(
        {**values, "input_lead": -0.9, "input_time": 0.02},
        {"input_lead": 0.05, "input_time": 0.002},
        units,
    )
    assert "at 0.10 ± 0.05 of its size at once (a lag" in lag and "20 ± 2 ms" in lag


def test_input_bias_meaning_is_a_time_shift():
    assert "time shift of the drive" in jh.effects.InputBias().meaning
    assert "first-order network" in jh.effects.InputBias().meaning


def test_dynamics_reading_in_hertz_and_damping():
    effect = jh.effects.Dynamics()
    units = effect.units(time="s", input="V", output="µm")
    text = effect.reading(
        {"natural_frequency": 851.0, "damping_ratio": 0.3},
        {"natural_frequency": 12.0, "damping_ratio": 0.02},
        units,
    )
    assert "851 ± 12 Hz" in text and "0.30 ± 0.02" in text and "rings" in text
    text = effect.reading({"natural_frequency": 851.0, "damping_ratio": 1.5}, {}, units)
    assert "overdamped" in text
