"""The public surface: a small top level, a few namespaces, eager imports.

`import jaxhyst` imports every module in one fixed order (plain imports, as in
equinox, diffrax and optimistix), so whichever module a program imports first, the
package it gets is the same, to the last bit of every default. The top level holds
the everyday names; the rest lives in the public namespaces below, each a module
with an `__all__` (`jaxhyst.synthetic` is a subpackage without one: its public names
are those without a leading underscore).

Counted as top-level names: `dir(jaxhyst)` without the names that start with an
underscore and without the namespace modules, which are counted apart.
"""

import concurrent.futures
import json
import subprocess
import sys
import textwrap
import types

import pytest

import jaxhyst as jh


NAMESPACES = (
    "datasets",
    "diagnosis",
    "effects",
    "families",
    "identification",
    "metrics",
    "periodic",
    "report",
    "synthetic",
)
MAX_TOP_LEVEL_NAMES = 110

# The package's exports before the namespaces (issue 49): each must still be
# reachable, from the top level or from one namespace.
EXPORTS_BEFORE_NAMESPACES = """
AbstractCompensationMethod AbstractEffect AbstractFamily AbstractGainHoldingModel
AbstractHysteresisModel AbstractInterpolation AbstractOptimistixPolish AbstractPolish
AbstractSignal AbstractSimulationSolver AbstractSmoothing AdamPolish AdoptionPolicy
AlgebraicSign Asymmetry BFGSPolish BoucWen BoucWenBenchmark BoucWenDamper BoucWenShape
CATALOGUE COMPENSATION_FIGURES CORRECTED_STAGES Chirp Compensation Concatenate
Constant CorrectedPiezoBoucWen Creep CubicInterpolation DAMPER_EFFECT_NAMES
DIAGNOSIS_FIGURES DamperAsymmetry DamperDrive DamperFamily DamperOffset DataScales
DecayingCosine Degradation Diagnosis DiagnosisStep DiffraxSolver Drift Drive
DriverLag DynamicInversion Dynamics EFFECT_NAMES ErrorSpectrum ExactSign
ExtendedDamper ExtendedPiezo FIT_FIGURES FieldDependence Finding Fit
HystereticOscillator Identifiability InputBias InputPath LevenbergMarquardtPolish
LinearInterpolation LoadedModel MPSO MR_DAMPER_TESTS Multisine NotShown
OpenSeesMaterial OptimisedDrive ParameterSpace PerSampleInversion PeriodicAverage
PeriodicSimulation PiezoBoucWen PiezoFamily PiezoStage Pinching PolishResult
PolishStage Problem PushPullAsymmetry RESULTS RK4 RaisedCosine RateDependence
RecordSimulation Recording RecordingError RecordingErrors RecordingMetrics
RefitScales Rolloff STRUCTURAL_EFFECT_NAMES STRUCTURAL_TESTS Score SearchBox
ShiftedDrive SpencerDamper StabilityReport SteadyOutput StepHold StructuralBoucWen
StructuralFamily SwarmResult SwarmState TanhSign Triangle Unexplained Validation
average_periods bandlimited_upsample bibo_stability compensate covariance
default_data_dir default_solver diagnose diagnosis_html diagnosis_markdown
diagnosis_summary enable_compilation_cache error_metrics error_spectrum export_c
fit_periodic fit_summary identifiability identifiability_of identify
identify_corrected is_bibo_stable joint_scales load_bouc_wen_benchmark load_model
load_mr_damper load_mr_damper_sine load_piezo_actuator load_structural_test locate
locate_cycles mad mae mrd nrmsd opensees_force opensees_material oscillator_space
output_jacobian paper_u1 paper_u2 periodic_identifiability periodic_problem
plot_error_trend plot_loop plot_loop_opening plot_residual_scatter plot_residual_time
plot_spectrum plot_time_history predict refine require_matplotlib rmse run_swarm
sample sample_times save_figure save_model search simulate stack_problems
starting_points status_message status_name sum_squared_error swarm_samples_per_step
synthetic write_compensation_report write_diagnosis_figures write_diagnosis_html
write_diagnosis_report write_fit_figures
""".split()


def _public(module: types.ModuleType) -> list[str]:
    """`module.__all__`, or (a package without one) its names without a leading
    underscore that are not modules."""
    if hasattr(module, "__all__"):
        return list(module.__all__)
    return [
        name
        for name in dir(module)
        if not name.startswith("_")
        and not isinstance(getattr(module, name), types.ModuleType)
    ]


def _top_level() -> list[str]:
    return [
        name for name in dir(jh) if not name.startswith("_") and name not in NAMESPACES
    ]


def test_the_top_level_is_small_and_holds_no_other_module():
    names = _top_level()
    assert len(names) <= MAX_TOP_LEVEL_NAMES, len(names)
    modules = [n for n in names if isinstance(getattr(jh, n), types.ModuleType)]
    assert modules == [], "a public module that is not a listed namespace"
    for namespace in NAMESPACES:
        assert isinstance(getattr(jh, namespace), types.ModuleType), namespace


@pytest.mark.parametrize("namespace", NAMESPACES)
def test_each_namespace_resolves_every_name_it_lists(namespace):
    module = getattr(jh, namespace)
    assert module.__name__ == f"jaxhyst.{namespace}"
    assert module.__doc__ and module.__doc__.strip()
    names = _public(module)
    assert names and len(names) == len(set(names)), namespace
    if hasattr(module, "__all__"):
        public = {n for n in dir(module) if not n.startswith("_")}
        assert public == set(names), "__all__ lists every public name"
    for name in names:
        assert getattr(module, name) is not None, f"{namespace}.{name}"
        assert name not in _top_level(), f"{name}: at the top level and in {namespace}"


def test_every_name_exported_before_the_namespaces_is_still_reachable():
    homes = {name: "jaxhyst" for name in _top_level()}
    for namespace in NAMESPACES:
        for name in _public(getattr(jh, namespace)):
            if namespace == "synthetic":
                continue  # the synthetic subpackage was not flattened before either
            assert name not in homes, f"{name}: in {homes[name]} and {namespace}"
            homes[name] = f"jaxhyst.{namespace}"
    homes["synthetic"] = "jaxhyst"
    missing = [name for name in EXPORTS_BEFORE_NAMESPACES if name not in homes]
    assert missing == []


def test_the_version_is_a_string():
    assert isinstance(jh.__version__, str) and jh.__version__


def _run(code: str) -> str:
    """The last line `code` prints in a fresh interpreter."""
    result = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stderr
    return result.stdout.strip().splitlines()[-1]


# Run after one of the `FIRST_IMPORTS`: whether matplotlib is imported, the defaults
# built when the modules are imported and a small deterministic simulation, every
# array as its dtype and bytes.
_FINGERPRINT = """
import inspect, json, sys
matplotlib = "matplotlib" in sys.modules
import jax.numpy as jnp
import numpy as np
import jaxhyst as jh

def bits(x):
    x = np.asarray(x)
    return f"{x.dtype}:{x.tobytes().hex()}"

def swarm(s):
    fields = ("c1", "c2", "w_max", "w_min", "velocity_limit")
    return [bits(getattr(s, f)) for f in fields]

model = jh.PiezoBoucWen.paper_table4(case=3)
path = jh.sample(jh.paper_u1(), 20.0)
u = np.asarray(path.values)
print(json.dumps({
    "matplotlib": matplotlib,
    "MPSO()": swarm(jh.MPSO()),
    "AdoptionPolicy()": swarm(jh.families.AdoptionPolicy().refit_swarm),
    "identify": swarm(inspect.signature(jh.identify).parameters["swarm"].default),
    "simulate": bits(jh.simulate(model, path)),
    "error_metrics": repr(jh.error_metrics(u, 1.01 * u)),
}))
"""

X64 = "import jax\njax.config.update('jax_enable_x64', True)\n"
FIRST_IMPORTS = (
    "import jaxhyst",
    "import jaxhyst.synthetic",
    "import jaxhyst._swarm",
    "from jaxhyst import effects",
    "from jaxhyst._cli._main import build_parser",
)


def _fingerprints(firsts) -> list[dict]:
    """The `_FINGERPRINT` of a fresh interpreter for each of `firsts` (code run
    before it), two interpreters at a time."""
    with concurrent.futures.ThreadPoolExecutor(max_workers=2) as pool:
        outputs = pool.map(lambda first: _run(f"{first}\n{_FINGERPRINT}"), firsts)
        return [json.loads(output) for output in outputs]


def test_the_package_is_the_same_whichever_module_is_imported_first():
    reference, *others = _fingerprints([X64 + first for first in FIRST_IMPORTS])
    assert reference["matplotlib"] is False
    assert reference["MPSO()"][0].startswith("float64:")
    assert reference["simulate"].startswith("float64:")
    for first, fingerprint in zip(FIRST_IMPORTS[1:], others, strict=True):
        assert fingerprint == reference, first


_DEFAULT_SWARMS = """
import inspect
import jax.numpy as jnp
import numpy as np
swarms = [
    inspect.signature(jh.identify).parameters["swarm"].default,
    jh.families.AdoptionPolicy().refit_swarm,
    inspect.signature(jh.identification.identify_corrected).parameters["swarm"].default,
    inspect.signature(jh.periodic.fit_periodic).parameters["swarm"].default,
]
best = [
    jh.identification.run_swarm(
        lambda x, args: jnp.sum((x - 0.3) ** 2) + jnp.sin(7 * x[0]),
        np.zeros(3), np.ones(3), s, jax.random.key(0)
    ).best_fitness
    for s in swarms
]
print([np.asarray(b).dtype.str + np.asarray(b).tobytes().hex() for b in best])
"""


def test_the_defaults_do_not_depend_on_when_64_bit_floats_are_enabled():
    # The command line imports jaxhyst, then turns 64-bit floats on: the default
    # swarms, built at import, must search exactly as if it had been on before.
    enable = 'jax.config.update("jax_enable_x64", True)\n'
    orders = (
        "import jax\n" + enable + "import jaxhyst as jh\n",
        "import jax\nimport jaxhyst as jh\n" + enable,
    )
    with concurrent.futures.ThreadPoolExecutor(2) as pool:
        before, after = pool.map(lambda order: _run(order + _DEFAULT_SWARMS), orders)
    assert "<f8" in before
    assert after == before
