"""The diagnosis families and their catalogues of effects.

A family is what `jaxhyst.diagnose(recording, family=...)` is told about the
record: its base model, the effects it scores and how a record is split and read.
`PiezoFamily` (the default) is for piezo stages and actuators, `StructuralFamily`
for quasi-static cyclic tests and `DamperFamily` for MR dampers (two inputs);
`AbstractFamily` is the base class of a new one. `EFFECT_NAMES`,
`STRUCTURAL_EFFECT_NAMES` and `DAMPER_EFFECT_NAMES` name each catalogue's effects
(the classes are in `jaxhyst.effects`) and `CATALOGUE` is the piezo family's
effects by name. `AdoptionPolicy` sets when an effect is adopted and how hard the
diagnosis looks; `locate` (a drive record) and `locate_cycles` (a cyclic test) say
where in a record a residual lives.
"""

from ._diagnose._families import (
    CATALOGUE as CATALOGUE,
    DAMPER_EFFECT_NAMES as DAMPER_EFFECT_NAMES,
    EFFECT_NAMES as EFFECT_NAMES,
    STRUCTURAL_EFFECT_NAMES as STRUCTURAL_EFFECT_NAMES,
    AbstractFamily as AbstractFamily,
    DamperFamily as DamperFamily,
    PiezoFamily as PiezoFamily,
    StructuralFamily as StructuralFamily,
)
from ._diagnose._locate import locate as locate, locate_cycles as locate_cycles
from ._diagnose._policy import AdoptionPolicy as AdoptionPolicy


__all__ = [
    "CATALOGUE",
    "DAMPER_EFFECT_NAMES",
    "EFFECT_NAMES",
    "STRUCTURAL_EFFECT_NAMES",
    "AbstractFamily",
    "AdoptionPolicy",
    "DamperFamily",
    "PiezoFamily",
    "StructuralFamily",
    "locate",
    "locate_cycles",
]
