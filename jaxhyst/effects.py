"""The effects a diagnosis can add to a base model (`jaxhyst.diagnose`).

Each effect is one piece of missing physics, written as a small change to the base
model's equations that is switched off at its zero parameters: the piezo catalogue
(`Asymmetry`, `InputBias`, `RateDependence`, `Creep`, `Dynamics`, `Drift`), the
structural one (`Degradation`, `Pinching`, `PushPullAsymmetry`, `Drift`) and the MR
damper's (`FieldDependence`, `DriverLag`, `Rolloff`, `DamperOffset`,
`DamperAsymmetry`). A family (`jaxhyst.families`) lists the effects it scores;
`AbstractEffect` is the base class of a new one, and `RefitScales` the record's
scales that its bounds and starting points are expressed in.
"""

from ._diagnose._effects.asymmetry import Asymmetry as Asymmetry
from ._diagnose._effects.base import (
    AbstractEffect as AbstractEffect,
    RefitScales as RefitScales,
)
from ._diagnose._effects.creep import Creep as Creep
from ._diagnose._effects.damper_asymmetry import DamperAsymmetry as DamperAsymmetry
from ._diagnose._effects.damper_offset import DamperOffset as DamperOffset
from ._diagnose._effects.degradation import Degradation as Degradation
from ._diagnose._effects.drift import Drift as Drift
from ._diagnose._effects.driver_lag import DriverLag as DriverLag
from ._diagnose._effects.dynamics import Dynamics as Dynamics
from ._diagnose._effects.field_dependence import FieldDependence as FieldDependence
from ._diagnose._effects.input_bias import InputBias as InputBias
from ._diagnose._effects.pinching import Pinching as Pinching
from ._diagnose._effects.push_pull import PushPullAsymmetry as PushPullAsymmetry
from ._diagnose._effects.rate_dependence import RateDependence as RateDependence
from ._diagnose._effects.rolloff import Rolloff as Rolloff


__all__ = [
    "AbstractEffect",
    "Asymmetry",
    "Creep",
    "DamperAsymmetry",
    "DamperOffset",
    "Degradation",
    "Drift",
    "DriverLag",
    "Dynamics",
    "FieldDependence",
    "InputBias",
    "Pinching",
    "PushPullAsymmetry",
    "RateDependence",
    "RefitScales",
    "Rolloff",
]
