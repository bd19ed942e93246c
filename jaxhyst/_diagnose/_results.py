"""The typed records a diagnosis produces; `to_dict()` gives the JSON edge."""

from typing import Any

import equinox as eqx
import numpy as np

from .._models.base import AbstractHysteresisModel
from .._stability import stability_json
from ._loop_indicators import LoopAgreement, LoopIndicators, compare_loops
from ._remainder import Remainder


class Validation(eqx.Module):
    """How a refitted candidate did on the held-out and the fitted samples."""

    heldout_rmse_before: float
    heldout_rmse_after: float
    fit_rmse_before: float
    fit_rmse_after: float
    # The held-out MSE drop it needed (max of the minimum gain and the resolution).
    heldout_margin_mse: float
    # The smallest held-out MSE difference the record can tell from noise.
    heldout_resolution_mse: float
    effective_samples_heldout: float
    bic_change: float
    score_statistic: float
    score_dof: int
    log10_p: float
    accepted: bool
    # The effect this one replaced when greedy choices were revisited.
    replaced: str | None = None

    @property
    def heldout_gain(self) -> float:
        """Relative drop of the held-out RMSE."""
        return 1 - self.heldout_rmse_after / self.heldout_rmse_before

    def to_dict(self) -> dict[str, Any]:
        out = {
            "heldout_rmse_before": self.heldout_rmse_before,
            "heldout_rmse_after": self.heldout_rmse_after,
            "fit_rmse_before": self.fit_rmse_before,
            "fit_rmse_after": self.fit_rmse_after,
            "heldout_margin_mse": self.heldout_margin_mse,
            "heldout_resolution_mse": self.heldout_resolution_mse,
            "effective_samples_heldout": self.effective_samples_heldout,
            "bic_change": self.bic_change,
            "score_statistic": self.score_statistic,
            "score_dof": self.score_dof,
            "log10_p": self.log10_p,
            "accepted": self.accepted,
        }
        if self.replaced is not None:
            out["replaced"] = self.replaced
        return out


class Score(eqx.Module):
    """One effect scored in one round: the score test on the residual, and what
    became of it (its validation if refitted, else why not)."""

    effect: str
    statistic: float
    dof: int
    log10_p: float
    explained_mse: float
    significant: bool
    # The Gauss-Newton step along the usable directions, by parameter.
    step: dict[str, float] = eqx.field(repr=False)
    # The projected, usable directions (samples x dof).
    directions: np.ndarray = eqx.field(repr=False)
    start_mse: float | None = None
    validation: Validation | None = None
    rejection: str | None = None
    # Effects refitted and validated together with this one (its dependents, e.g.
    # driver_lag with field_dependence), when it failed validation alone.
    together: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "effect": self.effect,
            "statistic": self.statistic,
            "dof": self.dof,
            "log10_p": self.log10_p,
            "explained_mse": self.explained_mse,
            "significant": self.significant,
        }
        if self.start_mse is not None:
            out["start_mse"] = self.start_mse
        if self.validation is not None:
            out["validation"] = self.validation.to_dict()
        if self.rejection is not None:
            out["rejected"] = self.rejection
        if self.together:
            out["validated_with"] = list(self.together)
        return out


# A held-out MSE difference counts as resolved beyond this many standard errors
# (`NoiseModel.resolution` is this many standard errors).
RESOLVED_SIGMA = 3.0


class Rival(eqx.Module):
    """Another effect refitted in a finding's place, with the finding's other
    effects kept: its held-out RMSE, and how far it lost (`margin_sigma`: the
    held-out MSE difference in standard errors of that difference; below the
    resolution's 3 the record cannot tell the two apart, negative: the rival fits
    the held-out data better)."""

    effect: str
    heldout_rmse: float
    margin_sigma: float

    @property
    def resolved(self) -> bool:
        return self.margin_sigma > RESOLVED_SIGMA

    def to_dict(self) -> dict[str, Any]:
        return {
            "effect": self.effect,
            "heldout_rmse": self.heldout_rmse,
            "margin_sigma": self.margin_sigma,
        }


class Ambiguity(eqx.Module):
    """A statement about the choice of effects: `undecided` names the effects the
    record cannot decide on (empty for a statement of a decision, e.g. an effect
    dropped or replaced); `concerns` names the findings a statement is about
    without leaving them undecided (which of a finding's forms the record shows):
    it goes with them when they are dropped."""

    statement: str
    undecided: tuple[str, ...] = ()
    concerns: tuple[str, ...] = ()


class Advice(eqx.Module):
    """A test that would separate effects this record cannot tell apart: the
    rival fitted models simulated under `input` differ by `difference_sigma`
    noise sigmas (RMS of the difference over the noise's standard deviation)."""

    separates: tuple[str, ...]
    input: str
    difference_sigma: float
    # The same difference on the recording analysed, for comparison.
    difference_sigma_here: float

    def to_dict(self) -> dict[str, Any]:
        return {
            "separates": list(self.separates),
            "input": self.input,
            "difference_sigma": self.difference_sigma,
            "difference_sigma_on_this_record": self.difference_sigma_here,
        }


class DiagnosisStep(eqx.Module):
    """One model the diagnosis moved to, in order: the RMSE chain of a report.

    `model` is that model, so that each step can be checked on a recording it
    was not fitted to (`jh.predict(step.model, other_recording)`).
    """

    label: str
    rmse: float
    heldout_rmse: float
    model: AbstractHysteresisModel | None = eqx.field(default=None, repr=False)

    def to_dict(self) -> dict[str, Any]:
        return {
            "step": self.label,
            "rmse": self.rmse,
            "heldout_rmse": self.heldout_rmse,
        }


class Finding(eqx.Module):
    """One adopted effect, with the evidence for it and what it bought.

    `parameters` are the values when it was adopted; `final_parameters`,
    `standard_errors` and `units` describe the final model (filled in once the
    diagnosis is complete), `form` names the effect's forms on in it that the
    record determines (`AbstractEffect.form`, joined by "+"), `reading` says what they mean
    physically and `moved` flags a large move between the two."""

    effect: str
    evidence: str
    where: str
    score: float
    parameters: dict[str, float]
    before: dict[str, float]
    after: dict[str, float]
    validation: Validation
    rivals: tuple[Rival, ...] = ()
    final_parameters: dict[str, float] = eqx.field(default_factory=dict)
    standard_errors: dict[str, float] = eqx.field(default_factory=dict)
    units: dict[str, str] = eqx.field(default_factory=dict)
    form: str = ""
    meaning: str = ""
    reading: str = ""
    moved: str | None = None

    @property
    def decided(self) -> bool:
        """True when every rival lost by more than the record's resolution."""
        return all(r.resolved for r in self.rivals)

    def to_dict(self) -> dict[str, Any]:
        out = {
            "effect": self.effect,
            "form": self.form,
            "evidence": self.evidence,
            "where": self.where,
            "score": self.score,
            "parameters": self.parameters,
            "final_parameters": self.final_parameters,
            "units": self.units,
            "standard_errors": self.standard_errors,
            "meaning": self.meaning,
            "reading": self.reading,
            "before": self.before,
            "after": self.after,
            "validation": self.validation.to_dict(),
            "rivals": [r.to_dict() for r in self.rivals],
            "decided": self.decided,
        }
        if self.moved is not None:
            out["moved"] = self.moved
        return out


class Unexplained(eqx.Module):
    """A structured mismatch that remains on held-out data and that no effect of
    the catalogue removed: where it lives, how large, what it resembles."""

    description: str
    where: str
    rms: float
    heldout_gain: float
    resembles: str

    def to_dict(self) -> dict[str, Any]:
        return {
            "description": self.description,
            "where": self.where,
            "rms": self.rms,
            "heldout_gain": self.heldout_gain,
            "resembles": self.resembles,
        }


class NotShown(eqx.Module):
    """A catalogue effect the recording cannot show (so it was not scored), and why."""

    effect: str
    reason: str

    def to_dict(self) -> dict[str, Any]:
        return {"effect": self.effect, "reason": self.reason}


class RecordingErrors(eqx.Module):
    """One recording's errors before and after a diagnosis over several."""

    recording: str
    samples: int
    baseline: dict[str, float]
    final: dict[str, float]

    def to_dict(self) -> dict[str, Any]:
        return {
            "recording": self.recording,
            "samples": self.samples,
            "baseline": self.baseline,
            "final": self.final,
        }


class Diagnosis(eqx.Module):
    """The result of `diagnose`; `to_dict()` is the `jaxhyst diagnose` JSON."""

    recording: str
    samples: int
    family: str
    base_name: str
    base_model: AbstractHysteresisModel
    final_model: AbstractHysteresisModel
    baseline: dict[str, float]
    final: dict[str, float]
    findings: list[Finding]
    unexplained: list[Unexplained]
    rounds: list[list[Score]]
    ambiguities: list[Ambiguity]
    advice: list[Advice]
    steps: list[DiagnosisStep]
    noise_sigma: float
    noise: dict[str, float]
    location: dict[str, Any]
    base_predicted: np.ndarray
    final_predicted: np.ndarray
    # True on the held-out samples, and how the family chose them.
    heldout: np.ndarray
    holdout_description: str
    holdout_fraction: float
    final_parameters: dict[str, float]
    # Family-specific keys of the JSON (the structural family: `opensees`).
    exports: dict[str, Any]
    seconds: float
    # Where the final model still misses most, and whether the rest is noise.
    remainder: Remainder
    # Each recording's errors, when several were diagnosed together (else empty).
    per_recording: tuple[RecordingErrors, ...] = ()
    # Catalogue effects the recording cannot show (not scored), with the reason.
    cannot_show: tuple[NotShown, ...] = ()
    # What the loops show without a model (`AbstractFamily.loop_indicators`: the
    # structural family's; None for the others and for several recordings).
    loops: LoopIndicators | None = None

    @property
    def effects(self) -> tuple[str, ...]:
        return tuple(f.effect for f in self.findings)

    @property
    def undecided(self) -> frozenset[str]:
        """The effects this record cannot decide on (named in an ambiguity)."""
        return frozenset(e for a in self.ambiguities for e in a.undecided)

    @property
    def final_rmse(self) -> float:
        return self.final["rmse"]

    @property
    def loop_agreement(self) -> tuple[LoopAgreement, ...]:
        """Whether the named effects agree with `loops` (`compare_loops`: degradation
        and pinching), and why not where they differ; () without loops."""
        if self.loops is None:
            return ()
        return compare_loops(
            self.effects,
            self.loops,
            undecided=self.undecided,
            not_named=self._why_not_named(),
        )

    def _why_not_named(self) -> dict[str, str]:
        """Why each effect that is not a finding was not named, in words."""
        why = {
            n.effect: f"the record cannot show it ({n.reason})"
            for n in self.cannot_show
        }
        for round_ in reversed(self.rounds):  # the last round says it best
            for score in round_:
                if score.effect in self.effects or score.effect in why:
                    continue
                if score.validation is not None and score.validation.accepted:
                    text = (
                        "it fitted the held-out cycles but was not kept (another "
                        "effect explained the same; see the candidates)"
                    )
                elif score.validation is not None:
                    text = (
                        "refitted, it did not lower the held-out error enough: the "
                        "held-out cycles did not support it"
                    )
                elif not score.significant:
                    text = "the score test found no sign of it in the residual"
                else:
                    text = "it was not refitted"
                if score.significant and score.rejection:
                    text += f" ({score.rejection})"
                why[score.effect] = text
        return why

    @property
    def candidates(self) -> list[list[dict[str, Any]]]:
        """Every round's scored candidates, as in the JSON."""
        return [[score.to_dict() for score in round_] for round_ in self.rounds]

    def to_dict(self) -> dict[str, Any]:
        return {
            "recording": self.recording,
            "samples": self.samples,
            "model": self.base_name,
            "noise": self.noise,
            "baseline": self.baseline,
            "findings": [f.to_dict() for f in self.findings],
            "unexplained": [u.to_dict() for u in self.unexplained],
            "cannot_show": [n.to_dict() for n in self.cannot_show],
            "loops": None
            if self.loops is None
            else {
                **self.loops.to_dict(),
                "agreement": [a.to_dict() for a in self.loop_agreement],
            },
            "final": {
                "model": "+".join((self.base_name, *self.effects)),
                "rmse": self.final["rmse"],
                "metrics": self.final,
                "parameters": self.final_parameters,
                "stability": stability_json(self.final_model),
            },
            "ambiguities": [a.statement for a in self.ambiguities],
            "undecided": sorted(self.undecided),
            "advice": [a.to_dict() for a in self.advice],
            "steps": [s.to_dict() for s in self.steps],
            "location": self.location,
            "candidates": self.candidates,
            "holdout_fraction": self.holdout_fraction,
            **self.exports,
            "timing": {"total_s": self.seconds},
            "remainder": self.remainder.to_dict(),
            **(
                {"per_recording": [r.to_dict() for r in self.per_recording]}
                if self.per_recording
                else {}
            ),
        }
