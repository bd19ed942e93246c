import gc
import os
import shutil
import subprocess
import sys
import tempfile

import pytest


def _compile_quickly() -> None:
    """Compile the tests' programs with XLA:CPU's elemental emitters, where this XLA
    knows the flag: the suite is mostly compilation of small programs, which they
    compile in about half the time (tests/test_identify.py: 130 s -> 57 s). Set in
    `XLA_FLAGS` before JAX starts its backend; a user's `XLA_FLAGS` that names the
    flag wins. XLA aborts on a flag it does not know, so a child process tries it
    first (about a second)."""
    flags = os.environ.get("XLA_FLAGS", "")
    if "xla_cpu_use_fusion_emitters" in flags:
        return
    wanted = f"{flags} --xla_cpu_use_fusion_emitters=false".strip()
    probe = subprocess.run(
        [sys.executable, "-c", "import jax; jax.devices()"],
        env={**os.environ, "XLA_FLAGS": wanted, "JAX_PLATFORMS": "cpu"},
        capture_output=True,
        timeout=120,
    )
    if probe.returncode == 0:
        os.environ["XLA_FLAGS"] = wanted


_compile_quickly()

import jax  # noqa: E402


jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_rank_promotion", "raise")

_RUN_CACHE = "JAXHYST_TEST_RUN_CACHE"


def pytest_configure(config):
    """One compilation cache for the whole run, shared by its processes. The
    controller makes a fresh folder (removed at the end; set JAXHYST_TEST_RUN_CACHE
    to a folder to keep one, or to an empty string to run without a cache); the
    xdist workers and the command lines the tests start inherit it through the
    environment. JAX's persistent cache lets a program compiled once in the run
    (the same fit in two test files, or after a module's `jax.clear_caches()`) load
    instead of compiling again; `JAXHYST_CACHE_DIR` points the CLI (its cache and its
    program store) at the same folder. Nothing is shared between runs and nothing is
    written to the user's cache folder. Programs that compile in under a tenth of a
    second (the eager operations of the tests, a thousand or more in a run) are not
    written: writing one costs about a tenth of compiling it. tests/test_cache.py
    and tests/test_program_store.py set their own folders."""
    if not hasattr(config, "workerinput") and _RUN_CACHE not in os.environ:
        folder = tempfile.mkdtemp(prefix="jaxhyst-test-cache-")
        os.environ[_RUN_CACHE] = folder
        config.add_cleanup(lambda: shutil.rmtree(folder, ignore_errors=True))
    folder = os.environ[_RUN_CACHE]
    os.environ.setdefault("JAXHYST_CACHE_DIR", folder)
    if folder:
        jax.config.update("jax_compilation_cache_dir", folder)
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.1)
        jax.config.update("jax_persistent_cache_min_entry_size_bytes", -1)


@pytest.fixture(autouse=True, scope="module")
def _release_compiled_programs():
    """Release the compiled programs after a test module once the process holds
    more than a third of the kernel's limit on memory maps (vm.max_map_count,
    65530 by default): every compiled CPU program holds about 80, and past the
    limit XLA's compiler crashes with a segmentation fault. Below it, the next
    module reuses what this one traced and compiled (measured on 8 fitting and CLI
    modules in one process: 287 s with a release after every module, 254 s)."""
    yield
    if _memory_maps() > _MAX_MAP_COUNT // 3:
        jax.clear_caches()
        gc.collect()


def _max_map_count() -> int:
    try:
        with open("/proc/sys/vm/max_map_count") as limit:
            return int(limit.read())
    except (OSError, ValueError):
        return 65530


_MAX_MAP_COUNT = _max_map_count()


def _memory_maps() -> int:
    """This process's memory maps (where /proc says; else as if at the limit)."""
    try:
        with open("/proc/self/maps") as maps:
            return sum(1 for _ in maps)
    except OSError:
        return _MAX_MAP_COUNT


# Long end-to-end variants run with `-m slow` only: each behaviour they check is
# covered in the fast suite by a shorter test (named after the reason) or by a
# sibling variant. Seconds: the 2-core machine, loaded, session 36.
SLOW = {
    "test_structural_diagnose.py::test_a_clean_structural_test_names_nothing": (
        "15 s after the pinching test; a clean structural record stays silent in "
        "test_an_effect_the_score_cannot_screen_is_refitted_and_judged_held_out"
    ),
    "test_identify.py::test_two_stage_corrected_fit_finds_asymmetry": (
        "16 s; the two stages run in test_cli's corrected fit, and an asymmetry is "
        "found by test_diagnose's quick positive"
    ),
    "test_diagnose.py::test_clean_recording_flags_nothing": (
        "14 s; clean records stay silent in the structural and damper quick tests "
        "and in the CLI's diagnosis contract test"
    ),
    "test_mixed_rates.py::test_joint_fit_at_two_rates_recovers_the_truth_as_at_one_rate": (
        "19 s; two rates are fitted together by the CLI's fit-and-evaluate test, and "
        "the stacked simulation equals each record alone exactly"
    ),
    "test_compensate.py::test_lagging_models_get_a_drive_ahead_of_time[time_shift]": (
        "21 s; the three stage variants check the same drive ahead of time"
    ),
    "test_diagnose_several.py::test_command_line_diagnoses_several_files": (
        "276 s; several recordings are diagnosed together in Python by "
        "test_diagnose_several's other tests, and the CLI's diagnose by test_cli"
    ),
    "test_damper_diagnose.py::test_every_effect_off_is_the_fixed_field_damper": (
        "96 s; the same identity for the piezo and structural families stays fast"
    ),
    "test_damper_diagnose.py::test_the_base_swarm_is_restarted_out_of_a_wrong_basin": (
        "67 s; a rare-path restart of the damper base fit"
    ),
    "test_damper_diagnose.py::test_synthetic_damper_cases": (
        "41 s; the damper generator's cases, also run by benchmarks/damper_suite.py"
    ),
    "test_refit.py::test_gains_held_at_zero_leave_the_output_and_the_other_slopes_unchanged[structural]": (
        "56 s; the piezo variant checks the same mechanism"
    ),
    "test_refit.py::test_gains_held_at_zero_leave_the_output_and_the_other_slopes_unchanged[damper]": (
        "54 s; the piezo variant checks the same mechanism"
    ),
    "test_compensate.py::test_a_time_shifted_hysteresis_is_inverted_without_shifting_the_linear_term[0.02]": (
        "the -0.02 variant checks the same inversion"
    ),
    "test_compensate.py::test_lagging_models_get_a_drive_ahead_of_time[stage]": (
        "38 s; the time_shift variant checks a drive ahead of time"
    ),
    "test_compensate.py::test_lagging_models_get_a_drive_ahead_of_time[stage_with_drift]": (
        "31 s; the time_shift variant checks a drive ahead of time"
    ),
    "test_compensate.py::test_lagging_models_get_a_drive_ahead_of_time[stage_optimised]": (
        "29 s; the optimised drive is checked on the corrected model too"
    ),
    "test_compensate.py::test_inverse_recovers_the_drive_that_made_the_reference[corrected]": (
        "35 s; the piezo variant checks the same inversion"
    ),
    "test_compensate.py::test_inverse_recovers_the_drive_that_made_the_reference[extended]": (
        "38 s; the piezo variant checks the same inversion"
    ),
    "test_simulate.py::test_gradients_match_finite_differences[smoothing1]": (
        "51 s; the same finite-difference check with the other sign smoothing"
    ),
    "test_simulate.py::test_input_bias_gradient_matches_sample_scale_differences": (
        "47 s; gradients are checked against finite differences in the fast suite"
    ),
    "test_simulate.py::test_simulate_runs_without_jit": (
        "39 s; op-by-op execution of the whole scan"
    ),
    "test_swarm.py::test_two_devices_match_single_device": (
        "40 s; a subprocess with two host devices"
    ),
    "test_placement.py::test_identify_on_an_explicit_polish_device_gives_the_same_fit": (
        "28 s; a second full fit; placement itself is checked by the other tests"
    ),
    "test_cli.py::test_fit_window_cuts_the_record": (
        "39 s; Recording.segment is tested directly in test_recording"
    ),
    "test_cli.py::test_fit_corrected_runs_the_two_stages": (
        "26 s; the two-stage fit is tested in Python in test_identify"
    ),
    "test_damper.py::test_recommended_substeps_at_published_conditions[0.0]": (
        "25 s; the 2.25 V variant checks the same rule"
    ),
    "test_compensate.py::test_a_time_shifted_hysteresis_is_inverted_without_shifting_the_linear_term[-0.02]": (
        "38 s; test_lagging_models_get_a_drive_ahead_of_time[time_shift] inverts a "
        "time-shifted hysteresis too"
    ),
    "test_refit.py::test_declared_additive_terms_add_a_fixed_function_of_time[damper]": (
        "25 s; the piezo variant checks the same mechanism"
    ),
    # Session 41, the 2-core AMD machine, loaded; .ci/run runs these two after the
    # README's command.
    "test_damper_diagnose.py::test_a_large_concealed_field_dependence_is_named": (
        "85 s; the damper family's positive check, run by .ci/run; in the fast "
        "suite the quick damper diagnosis runs in "
        "test_a_record_at_one_command_says_what_it_cannot_show and "
        "test_a_clean_record_names_nothing, and the piezo and structural positives "
        "name their effects"
    ),
    # Session 42: .ci/run runs this one too.
    "test_diagnose.py::test_a_large_concealed_effect_is_named_on_a_short_record": (
        "102 s (70 s alone: a cold diagnosis compiles the programs of every effect "
        "set it refits); the piezo family's positive check under the default "
        "policy, run by .ci/run; in the fast suite the structural positive names "
        "its effect and checks the same RMSE chain, units, standard errors and "
        "final values, the CLI runs the piezo diagnosis end to end "
        "(test_cli's contract test), and the rival and forms stages' decisions "
        "are tested with stand-ins (test_rival_swaps, test_forms_apart)"
    ),
    "test_batch.py::test_an_existing_cluster_runs_the_same_records": (
        "15 s; run by .ci/run; the batch's tasks run on a LocalCluster in the other "
        "batch tests, and only the client's address differs"
    ),
}


def pytest_collection_modifyitems(config, items):
    for item in items:
        name = item.nodeid.split("tests/", 1)[-1]
        if name in SLOW:
            item.add_marker(pytest.mark.slow)
