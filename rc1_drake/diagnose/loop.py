"""The diagnosis's loop (stage 4): linearize, fit today's model, rank and decide, accept and move the model, repeat
while what is left is not the noise; then the verdict."""

import dataclasses
import math
import os
import time

from ..compare import CampaignReport
from ..config import FRICTION_NAMES, START_MODES, Friction
from ..effects import LIBRARY, active, candidate_names, potentiometer_faults
from ..executor import make_executor
from ..identify.avs import avs
from ..residuals import where_it_fails
from ..sysid.evaluate import Checkpoint, Evaluator
from ..sysid.residual import trial_residual
from ..sysid.stats import HELD_LOG_SD, bound_side, interval95
from .coordinates import START, coordinate_bounds, physics_names
from .decide import NOT_DETECTABLE, decide, held_out_by_simulation, rank, screen_friction, unrefitted
from .fit import considered_variance, fit, polish, reported_standard_errors, starts_fitted
from .linearize import Linearization, linearize, moved, relinearize, with_replay_error
from .probe import suggest_experiments
from .replays import INPUT_NOISE_SAMPLES, evaluate, replay_and_score
from .report import Diagnosis, Round, waterfall_step
from .scatter import Scatter, failed_joint_scatter
from .significance import final_covariances, misfit
from .thresholds import THRESHOLDS, Thresholds
from .verdict import verdict

MAX_ROUNDS = 3
REPLAY_ERROR_MODES = ("paired", "full", "start")
FAR_LABEL = "today's model, friction searched (none identified at the start)"
REFINED_CANDIDATES = 3  # the best candidates by the linear ranking, refined by a secant step before the checks
CHECKED_CANDIDATES = 2  # of those, the best significant ones checked by simulation on held-out trials
# A powered-off servo's law, unknown on every real robot: with `failed_joint_law`, these effects' coordinates are
# nuisance in every fit of a campaign with failed joints (issue 67 item 3), not candidates.
FAILED_JOINT_LAW = ("joint_coulomb_friction", "compliant_stop")


def diagnose(
    campaign,
    *,
    friction: Friction | None = None,
    effects=None,
    candidates=None,
    trials=None,
    held=(),
    workers=None,
    scheduler=None,
    input_noise_samples=INPUT_NOISE_SAMPLES,
    max_rounds=MAX_ROUNDS,
    probe_study=True,
    progress=None,
    start_rates="rest",
    thresholds: Thresholds = THRESHOLDS,
    checkpoint=None,
    on_round=None,
    replay_error="paired",
    failed_joint_law=False,
) -> Diagnosis:
    """The loop (the package's docstring) on `campaign` (its `trials`, all by default), from the model (`friction`,
    `effects`); `candidates` are effect names or groups (effects.candidate_names; by default the physical effects,
    and the potentiometer faults of joints whose readings pass their limit); the friction coefficients named in
    `held` stay at their values. The head's rates at t = 0 of a trial that does not give them: `start_rates`
    "rest", the protocol's convention; "fit", three nuisance coordinates per trial fixed in every fit by its first
    START_FIT_S, for data whose start follows no known convention. `checkpoint`: a folder where every replay's result
    is kept as it arrives; a diagnosis interrupted and run again with it resumes where it stopped. `on_round(friction,
    effects, accepted)`: called with the model after each round that accepted an effect (so that a caller keeps it
    whatever follows). `replay_error`: the replay's own error is measured again at each accepted model, and at each
    polished one moved from the accepted model's by the paired difference of its first draws ("paired":
    linearize.PAIRED_DRAWS of six, docs/diagnosis.md); measured again in full there too ("full"); or the start's
    kept ("start"). The others are judged against the default campaign by campaign (benchmarks/paper_rates.py
    --variant). `failed_joint_law`: the failed joints' dry torque and compliant stop (FAILED_JOINT_LAW) fitted in
    every fit as nuisance, not offered as candidates, and a friction search judged on the trials with no failed joint
    (worse_without_failures)."""
    started = time.perf_counter()
    if start_rates not in START_MODES:
        raise ValueError(f"start_rates must be one of {START_MODES}, got {start_rates!r}")
    if replay_error not in REPLAY_ERROR_MODES:
        raise ValueError(f"replay_error must be one of {REPLAY_ERROR_MODES}, got {replay_error!r}")
    friction, effects, chosen = friction or Friction(), dict(effects or {}), campaign.chosen(trials)
    replayed, unseen = _candidates(chosen, effects, candidates)
    law = failed_joint_law_effects(chosen, effects) if failed_joint_law else []
    replayed = [n for n in replayed if n not in law]
    with make_executor(workers=workers or min(os.cpu_count() or 1, len(chosen)), scheduler=scheduler) as executor:
        evaluator = Evaluator(executor, progress, Checkpoint(checkpoint) if checkpoint else None)
        fit_starts = start_rates == "fit"
        lin = linearize(
            chosen,
            friction,
            effects,
            replayed + law,
            evaluator,
            input_noise_samples=input_noise_samples,
            held=held,
            starts=fit_starts,
        )
        search = _Search.begin(lin, evaluator, chosen, replayed, held, input_noise_samples, thresholds, law)
        search.replay_error = replay_error
        search.stop_reason = f"{max_rounds} rounds"
        for index in range(max_rounds):
            if not search.round(index):
                break
            if on_round:
                on_round(search.lin.friction, dict(search.lin.effects), list(search.accepted))
        result, left = search.finish(campaign, friction, effects, unseen)
    if probe_study:
        suggest_experiments(result.rounds, result.not_detectable, result.friction, result.effects, workers, progress)
    result.verdict, result.explanation = verdict(result.accepted, left, result.rounds)
    result.wall_s = time.perf_counter() - started
    return result


def _candidates(trials, effects, candidates) -> tuple:
    """(the candidates a replay can see, not already in the model; those it cannot, with the experiment that can)."""
    names = candidate_names(candidates)
    if candidates is None:  # readings past a joint's limit point at its potentiometer (measurements.limit_warnings)
        names += potentiometer_faults(sorted({j for t in trials for j in t.beyond_limit}))
    unseen = [
        {
            "name": n,
            "reason": "replays follow the measured joint angles, which already contain it",
            "experiment": "runs driven by the gait command (rc1 run), compared with the measured joint angles: "
            "the servo channel",
        }
        for n in names
        if not LIBRARY[n].seen_in_replay
    ]
    in_model = [e.name for e in active(effects)]
    return [n for n in names if LIBRARY[n].seen_in_replay and n not in in_model], unseen


def failed_joint_law_effects(trials, effects) -> list[str]:
    """FAILED_JOINT_LAW's effects not already in the model, where some trial has a failed joint."""
    in_model = [e.name for e in active(effects)]
    return [n for n in FAILED_JOINT_LAW if n not in in_model] if any(t.failed_joints for t in trials) else []


def needs_friction_search(lin: Linearization, names: list[str], free: list[str], thresholds: Thresholds) -> bool:
    """Whether the screen's verdict (no coefficient of `names` identified) was judged far from the data: only where
    the start's replays miss by more than the noise (significance.misfit). At the data, a search walks the flat
    directions the screen saw down the noise (seen: a campaign at the paper's friction, mu_lat moved 1.5 -> 2.8).
    Never with the failed joint's scatter taken as noise: a far friction moves the failed joints' trials too, and the
    scatter took it (seen: mu_lat 0.6 in the data, tau 4.8, no search, a lateral asymmetry accepted)."""
    return bool(names) and not free and not misfit(lin, lin.r0, 0, thresholds).consistent


def searched_friction(lin: Linearization, names: list[str], evaluator) -> Friction | None:
    """Where the screen at the start identifies no coefficient, it judged far from where the data are (seen: mu_lat
    0.6 in the data, 1.5 at the start, none identified, the start's values kept; the linear fit there goes to the
    bounds, mu_lat to 5). The paper's own search (AVS: one coefficient at a time over a few candidates, identify.avs)
    walks the friction down the diagnosis's weighted sum of squares, one pass over `names`: the friction it found,
    or None where it found nothing better."""

    def cost(friction: Friction) -> float:
        out = evaluator.map(evaluate, [(t, friction, lin.effects) for t in lin.trials], "searching the friction")
        return lin.weighted_sum_of_squares([lin.corrected(k, o[0]) for k, o in enumerate(out)])

    searched = avs(cost, start=lin.friction, iterations=len(names), parameters=[lin.coordinate(n) for n in names])
    better = searched.iterations and searched.iterations[-1].error < searched.start_error
    return searched.iterations[-1].friction if better else None


def best_candidate_at_start(lin: Linearization, nuisance: list[str], replayed: list[str], evaluator, thresholds):
    """(name, -2 log likelihood, coordinates) of the candidate that explains most of the start's miss: the
    best detectable ones of the linear ranking, each refined by a secant step (one replay a trial) as a round
    does; None where no candidate is detectable."""
    base = fit(lin, nuisance)
    ranked = [c for c in rank(lin, base, nuisance, replayed, thresholds=thresholds) if c.status != NOT_DETECTABLE]
    best = None
    for c in ranked[:REFINED_CANDIDATES]:
        at = secant_refined(lin, nuisance, c.name, evaluator, f"refining {c.name} at the start")
        cost = at.neg2_log_likelihood(at.r0)
        if best is None or cost < best[1]:
            best = (c.name, cost, len(owned(lin, c.name)))
    return best


def _scatter(lin: Linearization, evaluator, thresholds: Thresholds):
    """The failed joint's scatter columns at `lin` where a misfit takes that scatter as noise, else None."""
    return failed_joint_scatter(lin, evaluator) if thresholds.max_failed_joint_scatter > 0 else None


def owned(lin: Linearization, name: str) -> list[str]:
    """The coordinates of candidate `name`."""
    return [c.name for c in lin.coordinates if c.owner == name]


def secant_refined(lin: Linearization, names: list[str], candidate: str, evaluator, what: str) -> Linearization:
    """`lin` moved to its linear fit of `names` and `candidate`'s coordinates: one secant step, one replay a trial
    (a column taken at 0 misjudges an effect at a visible strength; docs/diagnosis.md)."""
    own = names + owned(lin, candidate)
    return moved(lin, own, fit(lin, own).values, evaluator, what=what)


def far_friction(
    lin, names, nuisance, replayed, evaluator, thresholds, samples, judged_without_failures=False
) -> tuple[Friction | None, str]:
    """(the searched friction where it explains the start's miss better than any one candidate does, else None; what
    was decided, in words). A miss beyond the noise is a far friction or a missing effect: the search alone lets the
    friction absorb an effect (seen: a hidden 1.5 deg toe taken up by mu_lat 1.5 -> 2.25, c_joint halved), so the two
    compete on their likelihood, each charged 2 per coordinate it moves (AIC). The friction is judged with the
    replay's own error measured again there (`samples` draws a trial): the search's cost keeps the start's, which at
    a far start misjudges it (seen: 6.6e5 with the start's, 6.4e3 measured there); its input noise moves the trials'
    weights (seen: the J7 trials' 0.55 -> 0.09 at mu_lat 0.75), which the likelihood's spread term prices. With
    `judged_without_failures` (the failed joints' law fitted as nuisance), a search that fits the trials with no
    failed joint worse is not kept (worse_without_failures)."""
    found = searched_friction(lin, names, evaluator)
    if found is None:
        return None, f"searched ({', '.join(names)}); nothing lowered the sum of squares"
    moved_names = [n for n in names if getattr(found, n) != getattr(lin.friction, n)]
    steps = ", ".join(f"{n} {getattr(lin.friction, n):.3g} -> {getattr(found, n):.3g}" for n in moved_names)
    there = relinearize(lin, found, lin.effects, evaluator, "residuals at the searched friction", samples=samples)
    cost = there.neg2_log_likelihood(there.r0)
    if judged_without_failures and (worse := worse_without_failures(lin, there, nuisance, len(moved_names))):
        return None, (
            f"searched ({steps}: -2 log likelihood {cost:.4g}), not kept: the trials with no failed joint fit it "
            f"worse ({worse[0]:.4g} -> {worse[1]:.4g}), so the failed joints' trials asked for it"
        )
    rival = best_candidate_at_start(lin, nuisance, replayed, evaluator, thresholds)
    if rival is not None and rival[1] + 2 * rival[2] < cost + 2 * len(moved_names):
        return None, (
            f"searched ({steps}: -2 log likelihood {cost:.4g}), not kept: {rival[0]} at the start explains "
            f"more ({rival[1]:.4g})"
        )
    against = f", against {rival[1]:.4g} for the best candidate ({rival[0]})" if rival else ""
    return found, f"searched and kept: {steps} (-2 log likelihood {cost:.4g}{against})"


def worse_without_failures(lin: Linearization, there: Linearization, nuisance: list[str], moved: int):
    """(-2 log likelihood of the trials with no failed joint at `lin`, at `there`), their starts profiled out, where
    `there` fits them worse by more than 2 per coordinate moved (AIC); else None, and None where every trial or none
    has a failed joint. A friction search that makes them worse bends the wheels to absorb what the model gets wrong
    in a failed joint, whose law on a real robot is the least known (seen: mu_lat 1.5 -> 0.75 on a reference.py
    campaign at 1.5 with a soft stop; the no-failure trials' Eq. 6 error 0.67% -> 2.0%)."""
    clean = [k for k, t in enumerate(lin.trials) if not t.failed_joints]
    if not clean or len(clean) == len(lin.trials):
        return None
    before = lin.neg2_log_likelihood(fit(lin, nuisance).residual, clean)
    after = there.neg2_log_likelihood(fit(there, nuisance).residual, clean)
    return (before, after) if after > before + 2 * moved else None


@dataclasses.dataclass
class _Search:
    """One diagnosis between rounds: today's linearized model, what every fit includes, what was accepted."""

    lin: Linearization
    evaluator: Evaluator
    trials: list  # the campaign's chosen trials
    replayed: list[str]  # the candidates
    nuisance: list[str]  # the trials' start coordinates
    free: list[str]  # the friction coefficients these data identify
    model_names: list[str]  # in every fit: the starts, the free friction, then the accepted effects' coordinates
    samples: int  # bootstrap replays per trial for the replay's own error
    thresholds: Thresholds
    waterfall: list[dict]
    accepted: list[str] = dataclasses.field(default_factory=list)
    rounds: list[Round] = dataclasses.field(default_factory=list)
    stop_reason: str = ""
    replay_error: str = "paired"  # at each accepted and polished model: one of REPLAY_ERROR_MODES
    friction_search: str = ""  # whether the friction was searched at the start, and what was decided (far_friction)
    scatter: Scatter | None = None  # the failed joint's scatter columns, where a misfit takes it as noise
    screened: list[str] = dataclasses.field(default_factory=list)  # the friction coefficients not held by the user

    @classmethod
    def begin(cls, lin, evaluator, trials, replayed, held, samples, thresholds, law=()) -> "_Search":
        """The search at the start: the friction these data identify (where none is at the start and its replays
        miss by more than the noise, judged again where a search of the friction goes, if the friction explains that
        miss better than a candidate does: needs_friction_search, far_friction), the trials' starts fitted with it.
        `law`: effects whose coordinates are polished here, before the friction is judged, and in every fit after
        (FAILED_JOINT_LAW)."""
        nuisance = [c.name for c in lin.coordinates if c.owner == START]
        names = [n for n in FRICTION_NAMES if n not in held]
        free = screen_friction(lin, names, nuisance=nuisance)
        lin = starts_fitted(lin, nuisance, free, evaluator)
        law_names = [c.name for c in lin.coordinates if c.owner in law]
        if law_names:  # fitted before the friction is judged: else the wheels take up what the failed joints miss
            lin = polish(lin, nuisance + list(free) + law_names, tuple(law), evaluator, samples, paired=True)[0]
        start = unrefitted(lin, "start (no refit)")
        waterfall = [
            {
                "model": start.label,
                "effects": start.effects,
                "mean_eq6_error_pct": start.mean_eq6(),
                "mean_eq6_without_replay_miss_pct": start.mean_eq6_without_miss(),
                "cases": start.by_case(trials),
            }
        ]
        found, note = None, "not needed: " + (
            "every coefficient held" if not names else f"the start identifies {', '.join(free)}" if free else
            "the start's replays are within the noise"
        )  # fmt: skip
        if needs_friction_search(lin, names, free, thresholds):
            found, note = far_friction(lin, names, nuisance, replayed, evaluator, thresholds, samples, bool(law))
        if found is not None:  # linearized again where the search went, and judged there
            lin = linearize(lin.trials, found, lin.effects, replayed + list(law), evaluator,
                            input_noise_samples=samples, held=held, starts=bool(nuisance))  # fmt: skip
            free = screen_friction(lin, names, nuisance=nuisance)
            lin = starts_fitted(lin, nuisance, free, evaluator)
            waterfall.append(waterfall_step(FAR_LABEL, unrefitted(lin, FAR_LABEL), trials))
        model_names = nuisance + list(free) + law_names
        search = cls(lin, evaluator, trials, replayed, nuisance, free, model_names, samples, thresholds, waterfall)
        search.friction_search = note
        search.screened = names
        search.scatter = _scatter(lin, evaluator, thresholds)  # at the model the rounds start from
        return search

    def label(self) -> str:
        return "today's model" if not self.accepted else "+ " + " + ".join(self.accepted)

    def round(self, index: int) -> bool:
        """One round: rank the candidates against today's model, accept one if it holds. Whether to go on."""
        if (
            index
            and misfit(
                self.lin, self.lin.r0, len(physics_names(self.lin, self.model_names)), self.thresholds, self.scatter
            ).consistent
        ):
            # What the accepted effects leave is noise: searching it only finds false alarms (docs/diagnosis.md).
            self.stop_reason = "what the accepted effects leave is consistent with the noise"
            return False
        self._weigh_scatter()
        names, baseline, refit_note = self._baseline(first=index == 0)
        results, checked, left = self._candidates_checked(names, baseline)
        chosen, ambiguous, partial = decide(results, self.thresholds)
        for c in results:
            if c.status == "candidate":
                c.status = "significant, not checked (a better candidate was)"
        # The ranking: what simulation showed first (by its held-out gain), then the linear scores.
        results.sort(key=lambda c: (c.simulated is None, -(c.simulated or {}).get("held_out_reduction", c.score)))
        self.rounds.append(
            Round(
                friction=self.lin.friction,
                effects=dict(self.lin.effects),
                baseline=baseline,
                candidates=results,
                accepted=chosen,
                misfit_p=left.p,
                scatter=left.scatter,
                refit=refit_note,
                ambiguous=ambiguous,
                partial=partial,
            )
        )
        if chosen is None:
            self.stop_reason = (
                "candidates these trials cannot tell apart"
                if ambiguous
                else f"{partial} explains only part of it"
                if partial
                else "no candidate accepted"
            )
            return False
        self._accept(*checked[chosen])
        return True

    def _weigh_scatter(self) -> None:
        """Today's trials weighed by the failed joint's scatter (scatter.py), its tau estimated at today's model's
        fit: one model of the noise for the misfit and the fits."""
        if self.scatter is not None:
            residual = fit(self.lin, self.model_names).residual
            tau = final_covariances(self.lin, residual, self.scatter, self.thresholds.max_failed_joint_scatter)[1]
            self.lin = self.scatter.weighing(self.lin, tau)

    def _baseline(self, first: bool) -> tuple:
        """(the round's fitted names, today's model's held-out score, what happened to its parameters): refitted
        and moved where simulation confirms it, else kept."""
        lin, label = self.lin, self.label()
        current = unrefitted(lin, label + " (no refit)")
        if not physics_names(lin, self.model_names):
            return self.model_names, current, "nothing to refit"
        base_fit = fit(lin, self.model_names)
        refit = held_out_by_simulation(lin, base_fit, self.evaluator, label + ", refitted")
        if refit.sum_of_squares >= current.sum_of_squares:
            # The linear step of a nonlinear (Coulomb) model can overshoot: keep what simulation rejects out.
            return (
                self.nuisance,
                current,
                (
                    f"kept: refitting {', '.join(physics_names(lin, self.model_names))} raised the held-out sum "
                    f"of squares from {current.sum_of_squares:.4g} to {refit.sum_of_squares:.4g}"
                ),
            )
        there = moved(lin, self.model_names, base_fit.values, self.evaluator)  # the refit on all trials
        if lin.weighted_sum_of_squares(there.r0) < current.sum_of_squares:
            self.lin = there
            if first:  # a step of the waterfall only where the model moved there
                self.waterfall.append(waterfall_step("today's model, friction refitted", refit, self.trials))
            return self.model_names, refit, "refitted"
        return (
            self.model_names,
            refit,
            "refitted for the held-out check; kept where it was (the all-trial refit did worse)",
        )

    def _candidates_checked(self, names: list[str], baseline) -> tuple:
        """(every candidate ranked, the best checked by simulation: name -> (result, score, fit, linearization),
        today's model's misfit)."""
        lin, evaluator, thresholds = self.lin, self.evaluator, self.thresholds
        base_fit = fit(lin, names)
        left = misfit(lin, base_fit.residual, len(physics_names(lin, names)), thresholds, self.scatter)
        results = rank(
            lin, base_fit, names, [n for n in self.replayed if n not in self.accepted], thresholds=thresholds
        )
        refined = {}
        for c in [c for c in results if c.status != NOT_DETECTABLE][:REFINED_CANDIDATES]:
            at = secant_refined(lin, names, c.name, evaluator, f"refining {c.name}")
            again = rank(at, fit(at, names), names, [c.name], reference=base_fit, thresholds=thresholds)[0]
            again.visibility, again.indistinguishable_from = c.visibility, c.indistinguishable_from
            refined[c.name] = (again, at)
        results = sorted([refined[c.name][0] if c.name in refined else c for c in results], key=lambda c: -c.score)
        to_check = [c for c in results if c.status == "candidate" and c.name in refined][:CHECKED_CANDIDATES]
        if to_check:  # and the refined ones that help but are not significant: look-alikes, rivals only (decide)
            to_check += [
                c
                for c in results
                if c.name in refined and c.status == "not significant" and c.score >= thresholds.min_held_out_reduction
            ]
        checked = {}
        for c in to_check:
            at = refined[c.name][1]
            cand_fit = fit(at, names + owned(at, c.name))
            check = held_out_by_simulation(at, cand_fit, evaluator, f"{self.label()} + {c.name}")
            c.simulated = {
                "held_out_sum_of_squares_before": baseline.sum_of_squares,
                "held_out_sum_of_squares_after": check.sum_of_squares,
                "held_out_reduction": 1.0 - check.sum_of_squares / baseline.sum_of_squares,
                "held_out_mean_eq6_pct_before": baseline.mean_eq6(),
                "held_out_mean_eq6_pct_after": check.mean_eq6(),
            }
            checked[c.name] = (c, check, cand_fit, at)
        return results, checked, left

    def _accept(self, c, check, cand_fit, at) -> None:
        """Add candidate `c` to the model: its refined fit, where simulation puts it, estimated further there."""
        self.accepted.append(c.name)
        self.waterfall.append(waterfall_step("+ " + " + ".join(self.accepted) + " (held out)", check, self.trials))
        self.model_names = list(dict.fromkeys(self.model_names + cand_fit.names))
        # The accepted model: the refined fit, where its residuals are simulated (at the refinement's point plus
        # the refit's step; that step is small, and the next round refits from there).
        lin = moved(at, cand_fit.names, cand_fit.values, self.evaluator)
        # The replay's own error depends on the model: measured again at the accepted one (docs/diagnosis.md).
        remeasure, paired = self.replay_error != "start", self.replay_error == "paired"
        if remeasure:  # in full: the input noise's covariance moves with the model too (paired keeps it)
            lin = with_replay_error(lin, self.evaluator, self.samples)
        accepted_at = {n: lin.coordinate(n).value for n in c.coordinates}
        samples = self.samples if remeasure else 0
        lin, steps = polish(lin, self.model_names, c.name, self.evaluator, samples, paired=paired)
        here = fit(lin, self.model_names)  # the accepted effect's interval, the replay's error measured there
        self.rounds[-1].polished = (
            f"{steps} Gauss-Newton step(s) from " + ", ".join(f"{n}={v:.3g}" for n, v in accepted_at.items())
            if steps
            else "no step: the accepted fit stands"
        )
        for n, se in zip(here.names, here.standard_errors, strict=True):
            if n in c.coordinates:
                value = lin.coordinate(n).value
                c.coordinates[n] = [value, float(se)]
                c.interval95[n] = interval95(value, float(se))
        self.lin = lin

    def finish(self, campaign, friction, effects, unseen: list[dict]) -> tuple:
        """(the Diagnosis, its verdict and wall time to be set; the final model's Misfit from its replays, not the
        linear guess). The model is the last one checked by simulation. `unseen`: the candidates no replay sees."""
        lin = self.lin
        final_fit = fit(lin, self.model_names)
        out = self.evaluator.map(
            replay_and_score, [(t, lin.friction, lin.effects) for t in lin.trials], "where the model fails", keep=False
        )  # whole runs: too large to keep
        report = CampaignReport(
            campaign=str(campaign.path),
            friction=lin.friction,
            trials=[o[0] for o in out],
            runs={t.trial_id: o[1] for t, o in zip(lin.trials, out, strict=True)},
        )
        simulated = [lin.corrected(k, trial_residual(t, report.runs[t.trial_id])) for k, t in enumerate(lin.trials)]
        left = misfit(lin, simulated, len(physics_names(lin, self.model_names)), self.thresholds, self.scatter)
        considered = [n for n in self.screened if n not in self.free]
        carried = considered_variance(lin, final_fit.names, considered)
        final = {
            n: [float(lin.coordinate(n).value), math.sqrt(float(se) ** 2 + HELD_LOG_SD**2 * c)]
            for n, se, c in zip(final_fit.names, reported_standard_errors(lin, final_fit), carried, strict=True)
        }
        not_detectable = list(unseen)
        for c in (c for r in self.rounds for c in r.candidates if c.status == NOT_DETECTABLE):
            if c.name not in [d["name"] for d in not_detectable]:
                not_detectable.append(
                    {
                        "name": c.name,
                        "experiment": c.experiment,
                        "reason": "its largest physical value would not be significant on these trials",
                    }
                )
        checkpoint = self.evaluator.checkpoint
        result = Diagnosis(
            campaign=str(campaign.path),
            start_friction=friction,
            start_effects=effects,
            free=self.free,
            rounds=self.rounds,
            waterfall=self.waterfall,
            friction=lin.friction,
            effects=lin.effects,
            accepted=self.accepted,
            verdict=None,
            explanation="",
            misfit_p=left.p,
            scatter=[left.scatter, left.scatter_unbounded] if self.scatter else None,
            unexplained_trials=left.outliers,
            not_detectable=not_detectable,
            where_it_fails=where_it_fails(report, campaign).to_json(),
            simulations=self.evaluator.simulations,
            wall_s=0.0,
            resumed=checkpoint.resumed if checkpoint else 0,
            trials=lin.trials,
            report=report,
            stop_reason=self.stop_reason,
            friction_search=self.friction_search,
            final_coordinates={n: v for n, v in final.items() if n not in self.nuisance},
            starts={n: v for n, v in final.items() if n in self.nuisance},
            considered=considered,
            at_bound=[n for n in self.free if bound_side(lin.coordinate(n).value, *coordinate_bounds(n))],
            fit_standard_errors={
                n: float(se)
                for n, se in zip(final_fit.names, final_fit.standard_errors, strict=True)
                if n not in self.nuisance
            },  # fmt: skip
            considered_variance={
                n: float(c) for n, c in zip(final_fit.names, carried, strict=True) if n not in self.nuisance
            },
        )
        return result, left
