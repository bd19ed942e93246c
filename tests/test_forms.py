"""Every effect names its functional forms; a finding names the forms on."""

import re

import jax.numpy as jnp
import numpy as np
import pytest

import jaxhyst as jh


FAMILIES = (
    jh.families.PiezoFamily(),
    jh.families.StructuralFamily(),
    jh.families.DamperFamily(),
)


@pytest.mark.parametrize("family", FAMILIES, ids=lambda f: f.name)
def test_every_parameter_of_an_effect_is_in_one_named_form(family):
    for effect in family.catalogue:
        owned = [p for params in effect.forms.values() for p in params]
        assert sorted(owned) == sorted(effect.parameters), effect.name
        for form in effect.forms:
            assert re.fullmatch(r"[a-z][a-z_]*", form), (effect.name, form)


def test_a_finding_names_the_forms_on():
    family = jh.families.StructuralFamily()
    pinching = family.effect("pinching")
    degradation = family.effect("degradation")
    model = jh.StructuralBoucWen(10.0, 0.05, 1.0, 0.3, 0.2, 1.5)
    assert pinching.form(model) == "" and pinching.forms_on(model) == ()
    # A shape parameter set while its gain is zero does not switch its form on.
    slip = model.replace(slip_length=0.3, pinch_width=0.5)
    assert pinching.form(slip) == "series_slip"
    both = slip.replace(pinch=0.4)
    assert pinching.form(both) == "slip_lock+series_slip"
    assert pinching.fitted_dof(both) == len(pinching.parameters)
    assert pinching.fitted_dof(slip) == 2
    both_drivers = model.replace(
        strength_degradation=0.1, peak_stiffness_degradation=0.2
    )
    assert degradation.form(both_drivers) == "energy+peak_excursion"
    # With standard errors, a form whose gains the record does not determine is
    # not named, unless none is.
    errors = dict.fromkeys(degradation.parameters, 0.01)
    assert degradation.form(both_drivers, errors) == "energy+peak_excursion"
    errors["peak_stiffness_degradation"] = 1.0
    assert degradation.form(both_drivers, errors) == "energy"
    errors["strength_degradation"] = 1.0
    assert degradation.form(both_drivers, errors) == "energy+peak_excursion"


def test_a_resonance_is_on_by_structure():
    dynamics = jh.families.PiezoFamily().effect("dynamics")
    base = jh.PiezoBoucWen(1.0, 0.3, -1.0, 0.002, -0.001, 1.5)
    path = jh.sample(jh.paper_u1(), 100.0)
    extended = jh.ExtendedPiezo.around(base, path)
    assert dynamics.form(extended) == ""
    assert dynamics.form(extended.with_dynamics(800.0, 0.3)) == "second_order"


def test_a_viscous_element_and_a_creep_mode_share_no_term():
    # A Kelvin-Voigt element (rate_dependence) and one relaxation mode of creep are
    # the same equation, a first-order lag of the drive added to the output: at
    # creep's fastest time they give the same output to rounding. The catalogue
    # draws the line there: fits keep viscous_time at or below it, where creep's
    # modes begin, even when a polish steps past the box.
    drive = jh.Multisine(
        (0.5, 3.0), (20.0, 10.0), (0.0, 1.0), duration=4.0, offset=40.0
    )
    u = jh.sample(drive, 1000.0)
    base = jh.PiezoBoucWen(0.2, 0.0, 0.02, 0.01, 0.005, 1.5)
    model = jh.ExtendedPiezo.around(base, u)
    fastest = min(model.creep_times)
    viscous = model.replace(viscous=0.4, viscous_time=fastest)
    creep = model.replace(creep_faster=-0.4 / (fastest * float(model.rate_scale)))
    np.testing.assert_allclose(
        jh.simulate(viscous, u), jh.simulate(creep, u), rtol=1e-9, atol=1e-12
    )
    family = jh.families.PiezoFamily()
    space = jh.ParameterSpace(
        viscous,
        {"viscous": (0.0, 1.0), "viscous_time": (1e-3, fastest)},
        log_scale=["viscous_time"],
    )
    far = space.to_model(jnp.array([0.5, 3.0]))  # far past the box's upper bound
    assert float(far.viscous_time) == fastest
    rate = family.effect("rate_dependence")
    for sample_rate in (1000.0, 100.0):
        lower, upper = rate.bounds(
            "viscous_time", 0.01, jh.effects.RefitScales(sample_rate, 10.0, {})
        )
        assert lower < upper == fastest
