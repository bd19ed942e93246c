"""The records a diagnosis is made of.

`jaxhyst.diagnose` returns a `jaxhyst.Diagnosis` whose findings are
`jaxhyst.Finding`s; the pieces inside them are here: each adopted model in turn
(`DiagnosisStep`), each effect scored in a round (`Score`) and the held-out test a
refit passed or failed (`Validation`), the effects the recording cannot show
(`NotShown`), what is left unexplained (`Unexplained`) and, for a diagnosis over
several recordings, each one's errors before and after (`RecordingErrors`). They are
plain records, built by the diagnosis and read by the reports; `to_dict()` gives
each one's JSON.

Beside a structural diagnosis, `loop_indicators(recording)` reads a cyclic test's
loops without a model (`LoopIndicators`: strength and stiffness at equal
displacement over the repeated cycles, the force at zero displacement and the energy
per cycle, by amplitude level in `LoopLevel`s, per cycle in `LoopCycle`s) and says
whether they degrade and pinch (`LoopVerdict`s); `compare_loops` sets that beside
the effects a diagnosis named (`LoopAgreement`s; `Diagnosis.loop_agreement`).
"""

from ._diagnose._loop_indicators import (
    LoopAgreement as LoopAgreement,
    LoopCycle as LoopCycle,
    LoopIndicators as LoopIndicators,
    LoopLevel as LoopLevel,
    LoopVerdict as LoopVerdict,
    compare_loops as compare_loops,
    loop_indicators as loop_indicators,
)
from ._diagnose._results import (
    DiagnosisStep as DiagnosisStep,
    NotShown as NotShown,
    RecordingErrors as RecordingErrors,
    Score as Score,
    Unexplained as Unexplained,
    Validation as Validation,
)


__all__ = [
    "DiagnosisStep",
    "LoopAgreement",
    "LoopCycle",
    "LoopIndicators",
    "LoopLevel",
    "LoopVerdict",
    "NotShown",
    "RecordingErrors",
    "Score",
    "Unexplained",
    "Validation",
    "compare_loops",
    "loop_indicators",
]
