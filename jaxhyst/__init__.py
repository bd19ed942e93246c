"""jaxhyst: Bouc-Wen hysteresis models in JAX — simulate, identify, diagnose.

The names below are the public API. Each is imported when first used
(`_lazy.lazy_exports`): `import jaxhyst` is quick, and a command that only fits a
model does not import the diagnosis. The `if TYPE_CHECKING:` block is the list of
exports, read by type checkers as it is and by `lazy_exports` to find each name's
module; add a public name there.
"""

from typing import TYPE_CHECKING

from ._lazy import lazy_exports


if TYPE_CHECKING:
    from . import synthetic as synthetic
    from ._cache import enable_compilation_cache as enable_compilation_cache
    from ._compensate import (
        AbstractCompensationMethod as AbstractCompensationMethod,
        Compensation as Compensation,
        DynamicInversion as DynamicInversion,
        OptimisedDrive as OptimisedDrive,
        PerSampleInversion as PerSampleInversion,
        compensate as compensate,
    )
    from ._datasets import (
        MR_DAMPER_TESTS as MR_DAMPER_TESTS,
        STRUCTURAL_TESTS as STRUCTURAL_TESTS,
        BoucWenBenchmark as BoucWenBenchmark,
        default_data_dir as default_data_dir,
        load_bouc_wen_benchmark as load_bouc_wen_benchmark,
        load_mr_damper as load_mr_damper,
        load_mr_damper_sine as load_mr_damper_sine,
        load_piezo_actuator as load_piezo_actuator,
        load_structural_test as load_structural_test,
    )
    from ._diagnose._diagnose import diagnose as diagnose
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
    from ._diagnose._results import (
        Diagnosis as Diagnosis,
        DiagnosisStep as DiagnosisStep,
        Finding as Finding,
        NotShown as NotShown,
        RecordingErrors as RecordingErrors,
        Score as Score,
        Unexplained as Unexplained,
        Validation as Validation,
    )
    from ._error_spectrum import (
        ErrorSpectrum as ErrorSpectrum,
        error_spectrum as error_spectrum,
    )
    from ._evaluate import (
        default_solver as default_solver,
        predict as predict,
    )
    from ._export_c import export_c as export_c
    from ._identification._corrected import (
        CORRECTED_STAGES as CORRECTED_STAGES,
        identify_corrected as identify_corrected,
    )
    from ._identification._identifiability import (
        Identifiability as Identifiability,
        covariance as covariance,
        identifiability as identifiability,
        identifiability_of as identifiability_of,
        output_jacobian as output_jacobian,
    )
    from ._identification._identify import (
        Fit as Fit,
        PolishStage as PolishStage,
        RecordingMetrics as RecordingMetrics,
        identify as identify,
        joint_scales as joint_scales,
        refine as refine,
        search as search,
        starting_points as starting_points,
    )
    from ._identification._periodic import (
        PeriodicAverage as PeriodicAverage,
        PeriodicSimulation as PeriodicSimulation,
        SteadyOutput as SteadyOutput,
        average_periods as average_periods,
        bandlimited_upsample as bandlimited_upsample,
        fit_periodic as fit_periodic,
        oscillator_space as oscillator_space,
        periodic_identifiability as periodic_identifiability,
        periodic_problem as periodic_problem,
    )
    from ._identification._polish import (
        AbstractOptimistixPolish as AbstractOptimistixPolish,
        AbstractPolish as AbstractPolish,
        AdamPolish as AdamPolish,
        BFGSPolish as BFGSPolish,
        LevenbergMarquardtPolish as LevenbergMarquardtPolish,
        PolishResult as PolishResult,
    )
    from ._identification._problem import (
        Problem as Problem,
        RecordSimulation as RecordSimulation,
        stack_problems as stack_problems,
        swarm_samples_per_step as swarm_samples_per_step,
    )
    from ._inputs import (
        AbstractInterpolation as AbstractInterpolation,
        CubicInterpolation as CubicInterpolation,
        InputPath as InputPath,
        LinearInterpolation as LinearInterpolation,
    )
    from ._metrics import (
        error_metrics as error_metrics,
        mad as mad,
        mae as mae,
        mrd as mrd,
        nrmsd as nrmsd,
        rmse as rmse,
    )
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
        SearchBox as SearchBox,
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
    from ._plots import (
        plot_error_trend as plot_error_trend,
        plot_loop as plot_loop,
        plot_loop_opening as plot_loop_opening,
        plot_residual_scatter as plot_residual_scatter,
        plot_residual_time as plot_residual_time,
        plot_spectrum as plot_spectrum,
        plot_time_history as plot_time_history,
        require_matplotlib as require_matplotlib,
        save_figure as save_figure,
    )
    from ._recording import Recording as Recording, RecordingError as RecordingError
    from ._report import (
        COMPENSATION_FIGURES as COMPENSATION_FIGURES,
        DIAGNOSIS_FIGURES as DIAGNOSIS_FIGURES,
        FIT_FIGURES as FIT_FIGURES,
        diagnosis_html as diagnosis_html,
        diagnosis_markdown as diagnosis_markdown,
        diagnosis_summary as diagnosis_summary,
        fit_summary as fit_summary,
        write_compensation_report as write_compensation_report,
        write_diagnosis_figures as write_diagnosis_figures,
        write_diagnosis_html as write_diagnosis_html,
        write_diagnosis_report as write_diagnosis_report,
        write_fit_figures as write_fit_figures,
    )
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
        sum_squared_error as sum_squared_error,
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
    from ._swarm import (
        MPSO as MPSO,
        SwarmResult as SwarmResult,
        SwarmState as SwarmState,
        run_swarm as run_swarm,
    )


# Read from the installed package's metadata when first asked for.
__version__: str


def _version() -> str:
    import importlib.metadata

    try:
        return importlib.metadata.version("jaxhyst")
    except importlib.metadata.PackageNotFoundError:  # a source tree, not installed
        return "unknown"


__getattr__, __dir__, __all__ = lazy_exports(
    __name__, __file__, computed={"__version__": _version}
)
