"""Shared test fixtures: the paper's input on a uniform grid, typical parameters, and
records for tests that stand in the diagnosis's refits."""

from collections.abc import Callable
from typing import Any

import jax
import numpy as np
import pytest

import jaxhyst as jh


def paper_u1_path(rate: float = 1000.0, periods: int = 1) -> jh.InputPath:
    t = np.arange(int(round(10.0 * periods * rate)) + 1) / rate
    return jh.InputPath.from_samples(t, 2 - 2 * np.cos(0.2 * np.pi * t))


def multisine_path(rate: float = 1000.0, duration: float = 4.0) -> jh.InputPath:
    t = np.arange(int(round(duration * rate)) + 1) / rate
    u = (
        1.0 * np.sin(2 * np.pi * 0.5 * t)
        + 0.5 * np.sin(2 * np.pi * 1.7 * t + 0.3)
        + 0.25 * np.sin(2 * np.pi * 4.1 * t + 1.1)
    )
    return jh.InputPath.from_samples(t, u)


def piezo_model(**overrides: Any) -> jh.PiezoBoucWen:
    values: dict[str, Any] = dict(k1=0.3, k2=1.0, A1=0.5, beta1=0.6, gamma1=0.2, n=1.5)
    values.update(overrides)
    return jh.PiezoBoucWen(**values)


def validation(
    heldout_before: float = 1.0, heldout_after: float = 0.5, *, accepted: bool = True
) -> jh.diagnosis.Validation:
    """A held-out validation record for stage tests that stand in the refits: the
    held-out RMSE before and after, whether the effect was accepted; the rest
    neutral."""
    return jh.diagnosis.Validation(
        heldout_rmse_before=heldout_before,
        heldout_rmse_after=heldout_after,
        fit_rmse_before=1.0,
        fit_rmse_after=1.0,
        heldout_margin_mse=0.0,
        heldout_resolution_mse=0.0,
        effective_samples_heldout=10.0,
        bic_change=0.0,
        score_statistic=1.0,
        score_dof=1,
        log10_p=-1.0,
        accepted=accepted,
    )


def lowered_while(call: Callable[[], Any]) -> tuple[Any, list[str]]:
    """`call()`'s result, and the names of the programs JAX lowered (compiled, or
    looked up in the compilation cache) meanwhile, eager operations included."""
    lowered: list[str] = []

    def listener(event, duration, **kwargs):
        if event == "/jax/core/compile/jaxpr_to_mlir_module_duration":
            lowered.append(kwargs.get("fun_name"))

    jax.monitoring.register_event_duration_secs_listener(listener)
    try:
        result = call()
    finally:
        jax.monitoring.unregister_event_duration_listener(listener)
    return result, lowered


def assert_the_chain_adds_up_and_findings_are_keyed(diagnosis: jh.Diagnosis) -> None:
    """The RMSE chain starts at the baseline, every finding's before and after are
    consecutive rows, and it ends at the final model; each finding's units, standard
    errors and final values are keyed like its parameters, and the report's final
    parameters hold those values."""
    chain = [step.rmse for step in diagnosis.steps]
    assert chain[0] == pytest.approx(diagnosis.baseline["rmse"])
    assert chain[-1] == pytest.approx(diagnosis.final_rmse)
    report = diagnosis.to_dict()
    for finding in diagnosis.findings:
        i = chain.index(pytest.approx(finding.before["rmse"]))
        assert chain[i + 1] == pytest.approx(finding.after["rmse"])
        names = set(finding.parameters)
        assert set(finding.units) == set(finding.standard_errors) == names
        assert set(finding.final_parameters) == names
        assert all(unit for unit in finding.units.values()) and finding.reading
        for name, value in finding.final_parameters.items():
            assert report["final"]["parameters"][name] == value
