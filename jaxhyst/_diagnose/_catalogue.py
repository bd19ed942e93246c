"""The catalogue of physics a quasi-static piezo model can leave out.

Each entry names a set of `ExtendedPiezo` parameters; with them at zero the extended
model is the base model exactly. Names are stable identifiers (they appear in the
`jaxhyst diagnose` JSON).
"""

import equinox as eqx


class Effect(eqx.Module):
    """One catalogue entry: a stable name, the parameters that switch it on, and how
    a stage engineer would recognise it."""

    name: str
    parameters: tuple[str, ...]
    meaning: str


CATALOGUE: dict[str, Effect] = {
    effect.name: effect
    for effect in (
        Effect(
            "asymmetry",
            ("eps", "quad", "cubic", "skew"),
            "the ascending and descending branches are not mirror images (the loop is "
            "wider, saturates sooner or is bent differently at one end of the stroke)",
        ),
        Effect(
            "input_bias",
            ("phi", "input_lead", "input_time"),
            "the hysteresis responds to the input slightly early or late (a time "
            "shift of the drive as the operator sees it)",
        ),
        Effect(
            "rate_dependence",
            ("rate_gain", "viscous", "rate_amplitude", "viscous_time"),
            "the loop changes with how fast the input moves (it widens, opens or "
            "rotates at higher rates)",
        ),
        Effect(
            "creep",
            ("creep_faster", "creep_fast", "creep_slow", "creep_slower"),
            "the output keeps drifting for seconds after the input changes or "
            "holds (slow relaxation driven by the input)",
        ),
        Effect(
            "dynamics",
            ("natural_frequency", "damping_ratio"),
            "the stage's mass and damping matter: the output lags and rings after "
            "fast changes (a mechanical resonance)",
        ),
        Effect(
            "drift",
            ("offset", "trend", "curvature", "wander"),
            "the output has an offset or slow wander that does not follow the input "
            "(sensor offset, thermal drift)",
        ),
    )
}

EFFECT_NAMES: tuple[str, ...] = tuple(CATALOGUE)
