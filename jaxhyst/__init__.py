"""jaxhyst: Bouc-Wen hysteresis models in JAX — simulate, identify, diagnose."""

import importlib.metadata

from ._inputs import (
    AbstractInterpolation as AbstractInterpolation,
    CubicInterpolation as CubicInterpolation,
    InputPath as InputPath,
    LinearInterpolation as LinearInterpolation,
)
from ._smoothing import (
    AbstractSmoothing as AbstractSmoothing,
    AlgebraicSign as AlgebraicSign,
    ExactSign as ExactSign,
    TanhSign as TanhSign,
)

from ._datasets import (
    BoucWenBenchmark as BoucWenBenchmark,
    default_data_dir as default_data_dir,
    load_bouc_wen_benchmark as load_bouc_wen_benchmark,
    load_piezo_actuator as load_piezo_actuator,
)
from ._metrics import (
    error_metrics as error_metrics,
    mad as mad,
    mae as mae,
    mrd as mrd,
    nrmsd as nrmsd,
    rmse as rmse,
)
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

# [swarm-exports]
from ._models.base import (
    AbstractHysteresisModel as AbstractHysteresisModel,
    Drive as Drive,
)
from ._models.bouc_wen import (
    BoucWen as BoucWen,
    CorrectedPiezoBoucWen as CorrectedPiezoBoucWen,
    PiezoBoucWen as PiezoBoucWen,
    PiezoStage as PiezoStage,
    ShiftedDrive as ShiftedDrive,
)
from ._models.oscillator import HystereticOscillator as HystereticOscillator
from ._simulate import (
    AbstractSimulationSolver as AbstractSimulationSolver,
    DiffraxSolver as DiffraxSolver,
    RK4 as RK4,
    simulate as simulate,
)
from ._stability import (
    bibo_stability as bibo_stability,
    is_bibo_stable as is_bibo_stable,
    StabilityReport as StabilityReport,
)
# [core-exports]


__version__ = importlib.metadata.version("jaxhyst")
