"""jaxhyst: Bouc-Wen hysteresis models in JAX — simulate, identify, diagnose.

The top level holds the everyday names: the models, `simulate` and its solvers,
the signals, `Recording`, `identify` and the polishes, `diagnose`, `compensate`, the
model files and the status codes. The rest lives in small public namespaces, each
imported here:

- `jaxhyst.effects`: the effects a diagnosis can add to a model.
- `jaxhyst.families`: the diagnosis families, their effect catalogues, the adoption
  policy and `locate`.
- `jaxhyst.diagnosis`: the records a `Diagnosis` is made of (steps, scores,
  validations, ...).
- `jaxhyst.identification`: the parts of `identify` (the swarm, search and refine,
  problems, identifiability, the corrected model's staged fit).
- `jaxhyst.periodic`: identification from periodic records.
- `jaxhyst.metrics`: the single error measures (`error_metrics` is top level).
- `jaxhyst.datasets`: loaders of the real data sets.
- `jaxhyst.report`: report writers, console summaries and `plot_*` figures
  (matplotlib is imported when a figure is drawn, not here).
- `jaxhyst.synthetic`: synthetic recordings with a known truth.

Every import is eager and in a fixed order, so `import jaxhyst` (or of any of its
modules, which imports the package first) always builds the same package.
"""

import importlib.metadata as _metadata

from . import (
    datasets as datasets,
    diagnosis as diagnosis,
    effects as effects,
    families as families,
    identification as identification,
    metrics as metrics,
    periodic as periodic,
    report as report,
    synthetic as synthetic,
)
from ._batch import (
    BatchResult as BatchResult,
    LocalWorkers as LocalWorkers,
    SchedulerAddress as SchedulerAddress,
    batch as batch,
)
from ._cache import enable_compilation_cache as enable_compilation_cache
from ._compensate import (
    AbstractCompensationMethod as AbstractCompensationMethod,
    Compensation as Compensation,
    DynamicInversion as DynamicInversion,
    OptimisedDrive as OptimisedDrive,
    PerSampleInversion as PerSampleInversion,
    compensate as compensate,
)
from ._diagnose._diagnose import diagnose as diagnose
from ._diagnose._results import Diagnosis as Diagnosis, Finding as Finding
from ._error_spectrum import (
    ErrorSpectrum as ErrorSpectrum,
    error_spectrum as error_spectrum,
)
from ._evaluate import default_solver as default_solver, predict as predict
from ._export_c import export_c as export_c
from ._identification._identify import Fit as Fit, identify as identify
from ._identification._polish import (
    AbstractOptimistixPolish as AbstractOptimistixPolish,
    AbstractPolish as AbstractPolish,
    AdamPolish as AdamPolish,
    BFGSPolish as BFGSPolish,
    LevenbergMarquardtPolish as LevenbergMarquardtPolish,
)
from ._inputs import (
    AbstractInterpolation as AbstractInterpolation,
    CubicInterpolation as CubicInterpolation,
    InputPath as InputPath,
    LinearInterpolation as LinearInterpolation,
)
from ._metrics import error_metrics as error_metrics
from ._model_files import (
    LoadedModel as LoadedModel,
    load_model as load_model,
    save_model as save_model,
)
from ._models.base import (
    AbstractGainHoldingModel as AbstractGainHoldingModel,
    AbstractHysteresisModel as AbstractHysteresisModel,
    BoucWenShape as BoucWenShape,
    DataScales as DataScales,
    Drive as Drive,
)
from ._models.bouc_wen import (
    BoucWen as BoucWen,
    CorrectedPiezoBoucWen as CorrectedPiezoBoucWen,
    PiezoBoucWen as PiezoBoucWen,
    PiezoStage as PiezoStage,
    ShiftedDrive as ShiftedDrive,
)
from ._models.damper import (
    BoucWenDamper as BoucWenDamper,
    DamperDrive as DamperDrive,
    SpencerDamper as SpencerDamper,
)
from ._models.damper_extended import ExtendedDamper as ExtendedDamper
from ._models.extended import ExtendedPiezo as ExtendedPiezo
from ._models.oscillator import HystereticOscillator as HystereticOscillator
from ._models.structural import StructuralBoucWen as StructuralBoucWen
from ._opensees import (
    OpenSeesMaterial as OpenSeesMaterial,
    opensees_force as opensees_force,
    opensees_material as opensees_material,
)
from ._params import ParameterSpace as ParameterSpace
from ._recording import Recording as Recording, RecordingError as RecordingError
from ._signals import (
    AbstractSignal as AbstractSignal,
    Chirp as Chirp,
    Concatenate as Concatenate,
    Constant as Constant,
    DecayingCosine as DecayingCosine,
    Multisine as Multisine,
    RaisedCosine as RaisedCosine,
    StepHold as StepHold,
    Triangle as Triangle,
    paper_u1 as paper_u1,
    paper_u2 as paper_u2,
    sample as sample,
    sample_times as sample_times,
)
from ._simulate import (
    RK4 as RK4,
    AbstractSimulationSolver as AbstractSimulationSolver,
    DiffraxSolver as DiffraxSolver,
    simulate as simulate,
)
from ._smoothing import (
    AbstractSmoothing as AbstractSmoothing,
    AlgebraicSign as AlgebraicSign,
    ExactSign as ExactSign,
    TanhSign as TanhSign,
)
from ._stability import (
    StabilityReport as StabilityReport,
    bibo_stability as bibo_stability,
    is_bibo_stable as is_bibo_stable,
)
from ._status import (
    RESULTS as RESULTS,
    status_message as status_message,
    status_name as status_name,
)
from ._swarm import MPSO as MPSO


try:
    __version__: str = _metadata.version("jaxhyst")
except _metadata.PackageNotFoundError:  # a source tree, not installed
    __version__ = "unknown"
