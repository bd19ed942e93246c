"""Synthetic recordings that conceal missing physics, with a known truth.

The diagnosis has to be proven on records where an effect is *concealed* (it changes
the output by only a few noise sigmas) and on clean records, where nothing may be
named. These generators make such records for every family, with truth forms that
differ from the diagnosis catalogue's own equations, and effect names taken from the
catalogue (`jh.families.EFFECT_NAMES`, `jh.families.STRUCTURAL_EFFECT_NAMES`,
`jh.families.DAMPER_EFFECT_NAMES`):

- piezo: `concealed_recording` (under `rich_excitation`), `practical_recording`
  (under a plain drive: `SineExcitation`, `SwitchOnSine`) and `demo_recording`, each
  a `ConcealedCase` made by a `ConcealedTruth` around `base_truth`;
- structural: `structural_recording` under a `loading_protocol`, a `StructuralCase`
  made by a `StructuralTruth` around `structural_base_truth`;
- MR damper: `damper_recording` (a white-noise test: random displacement, random
  piecewise-constant command), a `DamperCase` made by a `DamperTruth`
  (`jh.families.DAMPER_EFFECT_NAMES`, forms in `DAMPER_FORMS`).
"""

from ._cases import (
    ConcealedCase as ConcealedCase,
    concealed_recording as concealed_recording,
    practical_recording as practical_recording,
)
from ._damper import (
    DAMPER_FORMS as DAMPER_FORMS,
    DamperCase as DamperCase,
    DamperTruth as DamperTruth,
    damper_recording as damper_recording,
)
from ._demo import demo_recording as demo_recording
from ._excitation import (
    AbstractExcitation as AbstractExcitation,
    SineExcitation as SineExcitation,
    SwitchOnSine as SwitchOnSine,
    rich_excitation as rich_excitation,
)
from ._protocols import loading_protocol as loading_protocol
from ._structural_cases import (
    StructuralCase as StructuralCase,
    structural_recording as structural_recording,
)
from ._structural_truth import (
    STRUCTURAL_FORMS as STRUCTURAL_FORMS,
    StructuralTruth as StructuralTruth,
    structural_base_truth as structural_base_truth,
)
from ._truth import ConcealedTruth as ConcealedTruth, base_truth as base_truth
