"""The records a diagnosis is made of.

`jaxhyst.diagnose` returns a `jaxhyst.Diagnosis` whose findings are
`jaxhyst.Finding`s; the pieces inside them are here: each adopted model in turn
(`DiagnosisStep`), each effect scored in a round (`Score`) and the held-out test a
refit passed or failed (`Validation`), the effects the recording cannot show
(`NotShown`), what is left unexplained (`Unexplained`) and, for a diagnosis over
several recordings, each one's errors before and after (`RecordingErrors`). They are
plain records, built by the diagnosis and read by the reports; `to_dict()` gives
each one's JSON.
"""

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
    "NotShown",
    "RecordingErrors",
    "Score",
    "Unexplained",
    "Validation",
]
