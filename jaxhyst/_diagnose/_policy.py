"""The adoption rules of the diagnosis, in one object."""

import equinox as eqx

from .._swarm import MPSO


class AdoptionPolicy(eqx.Module):
    """When an effect is adopted, and how hard the engine looks.

    - `significance`: the score test's p-value threshold for a candidate to be
      refitted (lower is stricter).
    - `min_heldout_gain`: the held-out MSE must drop by this fraction (and by more
      than its resolution); small gains are spurious effects soaking up what an
      adopted effect's form does not quite capture. Lower it on long, quiet records
      to report smaller effects.
    - `overlap`: canonical correlation of two signatures above which they count as
      the same mismatch ("cannot tell", "may also be present").
    - `max_effects`: rounds of forward selection.
    - `refits_per_round`: how many of the strongest significant candidates are
      refitted each round (each costs a short swarm plus a polish), plus any whose
      effect asks to be refitted always.
    - `refit_swarm`: the short swarm each candidate refit starts with (None: polish
      from the best starting point only).
    - `candidate_steps`, `converge_steps`, `final_steps`: Levenberg-Marquardt steps
      of a candidate's refit, of converging an adopted model, and of the final fit
      on every sample.
    - `refit_runners_up`: also refit, in later rounds, effects that passed held-out
      validation in an earlier round, even when the score test no longer flags
      them. On short records (a few thousand samples) the AR noise model read from
      the residual absorbs smooth structure and the score test loses power; the
      held-out data still decide.
    - `noise_bound`: bound the noise level of the held-out resolution by the better
      fit's held-out RMS (no model's residual is smaller than the noise). Where the
      base model misfits badly, the AR noise model's sd is mostly misfit and would
      demand far too large a gain.
    - `null_refit`: credit an accepted candidate only with its held-out gain over
      the model it extends refitted from the candidate's refitted values (the
      effect switched off): the candidate's swarm may have found a better basin for
      the parameters already in the model, and that gain is not the effect's.
    - `noise_across_strides`: read the noise model's effective sample count also
      at coarser strides and keep the largest (`NoiseModel.estimate`). For records
      whose sampling density is arbitrary (quasi-static tests in pseudo time): a
      record sampled ten times more densely then counts as many held-out samples,
      not fewer.
    - `refit_on_structure`: when the score test flags nothing but the model-free
      probes of `unexplained_structure` find structure on the held-out samples,
      refit the `refits_per_round` strongest candidates anyway (held-out
      validation decides). A misfit far above the noise inflates the AR noise
      model the score test reads, which then misses what is there: on a synthetic
      damper record left at 2.5 noise sigmas the field dependence scored 26.6 on
      2 degrees of freedom, under the 27.6 the default significance needs;
      refitted, it and the driver lag took the record to 1.2 sigmas.
    - `pair_refits`: when no candidate passes alone, refit the one with the best
      held-out error together with each other refitted candidate and adopt the
      first pair that passes (the backward check then tests each alone). Two
      effects present at once bias the model each is added to alone, so neither
      may clear the margin by itself.
    - `whole_catalogue_rivals`: test every finding against every other effect of
      the catalogue the record can show, each refitted in the finding's place (the
      other findings kept), not only against those that passed held-out validation
      or were significant but never refitted. A true effect can fail validation in
      an early round while another effect stands in for it, and would never be
      compared with what took its place. Such a rival never replaces the finding
      (it did not pass validation on its own); within the resolution, or better,
      it leaves the finding undecided, said as an ambiguity.
    - `forms_apart`: refit each finding whose effect has several forms on in each
      of them alone (the other forms' gains at zero, the other findings kept). A
      form alone that fits the held-out samples within the resolution of the
      forms together, or better, takes their place (the record does not need the
      other forms' terms); of several, the one with the lowest held-out error, and
      where others are within the resolution of it, the record cannot tell the
      forms apart, said as an ambiguity.
    - `form_correction`: an effect adopted after others stays a finding only if
      it fits the held-out samples better, by more than one standard error of the
      difference (`FORM_CORRECTION_SIGMA`), than the model
      without it plus a model-free correction of the loop (the family's
      `form_probes`: bin means of the residual over the input's level, direction
      and history, learnt on the fitted samples), which stands for the earlier
      findings' forms differing from the catalogue's. A later effect that only
      takes up such a form difference (a drift beside a pinching written in
      another law) is then not named: "X may be present, or the form of Y
      differs from the catalogue's".
    """

    significance: float = 1e-6
    min_heldout_gain: float = 0.05
    overlap: float = 0.9
    max_effects: int = 3
    refits_per_round: int = 3
    refit_swarm: MPSO | None = MPSO(num_particles=48, num_iterations=100)
    candidate_steps: int = 20
    converge_steps: int = 40
    final_steps: int = 30
    refit_runners_up: bool = False
    null_refit: bool = False
    noise_bound: bool = False
    noise_across_strides: bool = False
    pair_refits: bool = False
    refit_on_structure: bool = False
    whole_catalogue_rivals: bool = True
    forms_apart: bool = True
    form_correction: bool = True

    def __check_init__(self):
        if not 0 < self.significance < 1:
            raise ValueError(
                f"AdoptionPolicy(significance={self.significance}): must be in (0, 1), "
                "e.g. 1e-6."
            )
        if not 0 <= self.min_heldout_gain < 1:
            raise ValueError(
                f"AdoptionPolicy(min_heldout_gain={self.min_heldout_gain}): must be in "
                "[0, 1), e.g. 0.05 (5 % of the held-out MSE)."
            )
        if not 0 < self.overlap <= 1:
            raise ValueError(
                f"AdoptionPolicy(overlap={self.overlap}): must be in (0, 1], e.g. 0.9."
            )
        for name in (
            "max_effects",
            "refits_per_round",
            "candidate_steps",
            "converge_steps",
            "final_steps",
        ):
            value = getattr(self, name)
            if not isinstance(value, int) or isinstance(value, bool) or value < 1:
                raise ValueError(
                    f"AdoptionPolicy({name}={value!r}): must be an integer >= 1."
                )
