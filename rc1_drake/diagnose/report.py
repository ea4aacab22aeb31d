"""What a diagnosis returns: each candidate's result, the held-out scores of a model, the rounds, and the
Diagnosis with its tables, its text report (format) and its JSON."""

import dataclasses

import numpy as np

from ..config import Friction
from ..effects import coordinate_owner
from ..sysid.stats import estimate_text, p_text
from .coordinates import coordinate_bounds
from .verdict import Verdict, open_pairs, rate_text


@dataclasses.dataclass
class CandidateResult:
    name: str
    parameters: dict[str, float]  # the effect's parameters at the fit
    coordinates: dict[str, list[float]]  # coordinate -> [value, standard error]
    interval95: dict[str, list[float]]
    wald_p: float
    held_out_before: float  # RMS of the standardized held-out residuals, today's model (linear prediction)
    held_out_after: float
    held_out_reduction: float  # 1 - (after / before)^2: the fraction of the held-out sum of squares removed
    aic_delta: float
    score: float  # the held-out reduction: the ranking
    status: str  # accepted | not significant | no held-out gain | not detectable here | ...
    accepted: bool = False
    detectable_strength: dict[str, float] = dataclasses.field(default_factory=dict)  # 3 standard errors
    indistinguishable_from: list[str] = dataclasses.field(default_factory=list)
    visibility: dict[str, dict[str, float]] = dataclasses.field(default_factory=dict)  # case -> channel -> per unit
    simulated: dict | None = None  # the check by simulation, when it was made
    experiment: str | None = None  # the kind of trial that would see it / tell it apart
    apart: dict[str, str] = dataclasses.field(default_factory=dict)  # another candidate -> the trial telling them apart
    at_bound: list[str] = dataclasses.field(default_factory=list)  # its coordinates fitted at a bound of their range


@dataclasses.dataclass
class HeldOutScore:
    """Per-trial scores of a model (a replay per trial, each with the parameters fitted without it)."""

    label: str
    effects: dict[str, float]
    sum_of_squares: float
    eq6_pct: dict[str, float]  # trial -> Eq. 6 error
    yaw_fit_pct: dict[str, float]
    eq6_without_miss_pct: dict[str, float]  # trial -> Eq. 6 error with the replay's own miss taken off

    def by_case(self, trials) -> dict[str, dict]:
        ids = [t.trial_id for t in trials]
        return _cases(
            trials,
            [self.eq6_pct[i] for i in ids],
            [self.yaw_fit_pct[i] for i in ids],
            [self.eq6_without_miss_pct[i] for i in ids],
        )

    def mean_eq6(self) -> float:
        return float(np.mean(list(self.eq6_pct.values())))

    def mean_eq6_without_miss(self) -> float:
        return float(np.mean(list(self.eq6_without_miss_pct.values())))


@dataclasses.dataclass
class Round:
    friction: Friction
    effects: dict[str, float]
    baseline: HeldOutScore
    candidates: list[CandidateResult]  # ranked, best first
    accepted: str | None
    misfit_p: float  # today's model's final-position misfit against the noise
    scatter: float = 0.0  # the failed joint's scatter the misfit took as noise (tau, probe steps; scatter.py)
    refit: str = ""  # whether today's model's parameters were refitted this round, or kept (and why)
    ambiguous: list[str] = dataclasses.field(default_factory=list)  # candidates that explain it alike (none accepted)
    partial: str | None = None  # the best candidate, when it helped by less than half (not accepted)
    polished: str = ""  # how the accepted effect's estimate moved after acceptance (polish)

    def table(self) -> str:
        lines = [
            f"{'candidate':<32}{'fitted (95% interval)':<44}{'held-out rms':>14}{'gain':>6}{'Wald p':>9}"
            f"{'dAIC':>7}  status"
        ]
        for c in self.candidates:
            fitted = ", ".join(estimate_text(k, v, se, *coordinate_bounds(k)) for k, (v, se) in c.coordinates.items())
            lines.append(
                f"{c.name:<32}{fitted:<44}{c.held_out_before:>6.2f}->{c.held_out_after:<6.2f}"
                f"{100 * c.held_out_reduction:>5.0f}%{p_text(c.wald_p, bare=True):>9}{c.aic_delta:>7.0f}  {c.status}"
            )
        return "\n".join(lines)


@dataclasses.dataclass
class Diagnosis:
    campaign: str
    start_friction: Friction
    start_effects: dict[str, float]
    free: list[str]  # friction coefficients these data identify (the others stay at their start values)
    rounds: list[Round]
    waterfall: list[dict]
    friction: Friction  # the final model
    effects: dict[str, float]
    accepted: list[str]
    verdict: Verdict
    explanation: str
    misfit_p: float  # the final model's, without the unexplained trials
    not_detectable: list[dict]
    where_it_fails: dict | None
    simulations: int
    wall_s: float
    final_coordinates: dict[str, list[float]] = dataclasses.field(default_factory=dict)  # name -> [value, se]
    starts: dict[str, list[float]] = dataclasses.field(default_factory=dict)  # "<trial>:<rate>" -> [value, se]
    # the friction coefficients no trial identified, held (sysid.stats.HELD_LOG_SD), and per final coordinate the
    # variance they add to its interval at a factor e (fit.considered_variance), already in final_coordinates' se
    considered: list[str] = dataclasses.field(default_factory=list)
    considered_variance: dict[str, float] = dataclasses.field(default_factory=dict)
    # the free friction that ended at a bound of its range: no measurement of it (the model's form cannot follow the
    # data there), given no interval
    at_bound: list[str] = dataclasses.field(default_factory=list)
    # per final coordinate, the fit's own standard error (what the decisions use): before the case jackknife and the
    # held friction widened it (fit.reported_standard_errors, fit.considered_variance)
    fit_standard_errors: dict[str, float] = dataclasses.field(default_factory=dict)
    stop_reason: str = ""
    friction_search: str = ""  # at the start, where no coefficient was identified (loop.far_friction)
    resumed: int = 0  # of the simulations, results taken from a checkpoint of an interrupted run
    unexplained_trials: dict[str, dict] = dataclasses.field(default_factory=dict)  # trial -> misfit (see Misfit)
    scatter: list | None = None  # [tau taken, tau unbounded] where the misfit took the failed joint's scatter
    trials: list = dataclasses.field(default_factory=list, repr=False)  # the trials, with their fitted starts
    report: object = dataclasses.field(default=None, repr=False)  # compare.CampaignReport of the final model (plots)

    @property
    def candidates(self) -> list[CandidateResult]:
        return self.rounds[0].candidates if self.rounds else []

    def to_json(self) -> dict:
        return {
            "campaign": self.campaign,
            "verdict": self.verdict,
            "explanation": self.explanation,
            "start_model": {"friction": dataclasses.asdict(self.start_friction), "effects": self.start_effects},
            "free_friction": self.free,
            "baseline_error": {
                "held_out_mean_eq6_pct": self.rounds[0].baseline.mean_eq6(),
                "cases": self.rounds[0].baseline.by_case(self.trials),
            }
            if self.rounds
            else None,
            "candidates": [dataclasses.asdict(c) for c in self.candidates],
            "rounds": [
                {
                    "effects": r.effects,
                    "accepted": r.accepted,
                    "misfit_p": r.misfit_p,
                    "scatter": r.scatter,
                    "refit": r.refit,
                    "polished": r.polished,
                    "ambiguous": r.ambiguous,
                    "partial": r.partial,
                    "candidates": [dataclasses.asdict(c) for c in r.candidates],
                }
                for r in self.rounds
            ],
            "accepted_effects": self.accepted,
            "model": {"friction": dataclasses.asdict(self.friction), "effects": self.effects},
            "error_after": self.waterfall[-1] if self.waterfall else None,
            "final_coordinates": self.final_coordinates,
            "starts": self.starts,
            "considered": self.considered,
            "considered_variance": self.considered_variance,
            "at_bound": self.at_bound,
            "fit_standard_errors": self.fit_standard_errors,
            "stop_reason": self.stop_reason,
            "friction_search": self.friction_search,
            "waterfall": self.waterfall,
            "misfit_p": self.misfit_p,
            "scatter": self.scatter,
            "unexplained_trials": self.unexplained_trials,
            "not_detectable": self.not_detectable,
            "where_it_fails": self.where_it_fails,
            "simulations": self.simulations,
            "resumed": self.resumed,
            "wall_s": self.wall_s,
        }

    def summary(self) -> list[str]:
        """The answer first: the verdict, the effects added with their intervals, the held-out error before and
        after, and the trials left unexplained."""
        added = [
            estimate_text(n, v, se, *coordinate_bounds(n))
            for n, (v, se) in self.final_coordinates.items()
            if (owner := coordinate_owner(n)) is not None and owner.name in self.accepted
        ]
        carried = f", with {', '.join(self.considered)} held unidentified" if self.considered else ""
        lines = [
            f"verdict: {self.verdict}: {self.explanation}",
            *(f"  {a} or {b}: {text}" for a, b, text in open_pairs(self.rounds)),
            rate_text(self.verdict, trials=self.trials),
            f"added: {', '.join(added) + ' (95%' + carried + ')' if added else 'nothing'}",
        ]
        if self.at_bound:
            lines.append(
                "friction at a bound of its range, no interval (no measurement: the model's form cannot follow the "
                f"data there): {', '.join(f'{n}={getattr(self.friction, n):.3g}' for n in self.at_bound)}"
            )
        risen = []
        if self.waterfall:
            line, risen = headline(self.waterfall)
            lines.append(line)
        left = ", ".join(f"{k} ({o['off_cm']:.0f} cm off)" for k, o in self.unexplained_trials.items())
        lines.append(f"trials still unexplained: {left or 'none'}")
        if self.scatter:
            lines.append(
                f"the failed joint's trial-by-trial scatter taken as noise: {self.scatter[0]:.2g} probe steps of its "
                f"terms (maximum likelihood {self.scatter[1]:.2g}; diagnose/scatter.py)"
            )
        return lines + risen

    def format(self) -> str:
        """The report `rc1 diagnose` prints: the answer first (summary), then each round's ranking, the candidates'
        visibility per case, the error waterfall, what these trials cannot see, and the verdict again."""
        lines = [
            *self.summary(),
            "",
            f"Diagnosis of {self.campaign} ({len(self.trials)} trials; friction these data identify: "
            f"{', '.join(self.free) or 'none'}, the others held; the friction's search: {self.friction_search}):",
        ]
        for k, r in enumerate(self.rounds):
            lines += [
                "",
                f"round {k + 1}: candidates against {r.baseline.label} (held-out: leave one trial out; "
                f"final-position misfit {p_text(r.misfit_p)}"
                + (f" with the failed joint's scatter {r.scatter:.2g} taken as noise" if r.scatter else "")
                + f"; today's model's parameters: {r.refit})",
                r.table(),
            ]
            if r.polished:
                lines.append(f"{r.accepted} accepted, then estimated further: {r.polished}")
        lines += [
            "",
            "Visibility: the final head position's change (cm) per probe step of each candidate, per case:",
            self.visibility_table(),
            "",
            "Error waterfall (Eq. 6 error, the same with the replay's own miss on each trial's motion taken off,"
            " and yaw-rate fit, per case; held-out after the start):",
            self.waterfall_table(),
        ]
        for d in self.not_detectable:
            lines.append(
                f"not detectable here: {d['name']}: {d['reason']}"
                + (f"; would be seen by {d['experiment']}" if d.get("experiment") else "")
            )
        for c in self.candidates:
            if c.accepted and c.indistinguishable_from:
                lines.append(
                    f"note: {c.name} cannot be told apart from {', '.join(c.indistinguishable_from)} by these "
                    "trials" + (f"; {c.experiment}" if c.experiment else "")
                )
        lines += ["", f"verdict: {self.verdict}: {self.explanation}"]
        return "\n".join(lines)

    def visibility_table(self) -> str:
        """Per candidate coordinate and case: the final position's change (cm) per probe step."""
        cases = list(dict.fromkeys(t.case for t in self.trials))
        lines = [f"{'coordinate (probe step)':<44}" + "".join(f"{c:>10}" for c in cases)]
        for c in self.candidates:
            keys = [k for k in next(iter(c.visibility.values()), {}) if "final position" in k]
            for k in keys:
                name = k.split(":")[0] + f" ({k.rsplit(' per ', 1)[1]})"
                lines.append(f"{name:<44}" + "".join(f"{c.visibility[case][k]:>10.2f}" for case in cases))
        return "\n".join(lines)

    def waterfall_table(self) -> str:
        """Per case and step: Eq. 6 error, the same with the replay's own miss taken off, yaw-rate fit."""
        cases = list(self.waterfall[0]["cases"]) if self.waterfall else []
        lines = [
            f"{'':<38}" + "".join(f"{'Eq.6 (miss off) fit':>26}" for _ in cases) + f"{'Eq.6 (miss off)':>20}",
            f"{'model':<38}" + "".join(f"{c:>26}" for c in cases) + f"{'all trials':>20}",
        ]
        for step in self.waterfall:
            cells = "".join(
                f"{v['mean_eq6_error_pct']:>9.2f}% ({v['mean_eq6_without_replay_miss_pct']:>6.2f}%)"
                f"{v['mean_yaw_rate_fit_pct']:>5.0f}%"
                for v in (step["cases"][c] for c in cases)
            )
            lines.append(
                f"{step['model']:<38}{cells}{step['mean_eq6_error_pct']:>9.2f}% "
                f"({step['mean_eq6_without_replay_miss_pct']:>6.2f}%)"
            )
        return "\n".join(lines)


def _cases(trials, eq6, fit_pct, without_miss) -> dict[str, dict]:
    out: dict[str, list] = {}
    for t, e, f, m in zip(trials, eq6, fit_pct, without_miss, strict=True):
        out.setdefault(t.case, []).append((e, f, m))
    return {
        c: {
            "mean_eq6_error_pct": float(np.mean([v[0] for v in vs])),
            "mean_yaw_rate_fit_pct": float(np.mean([v[1] for v in vs])),
            "mean_eq6_without_replay_miss_pct": float(np.mean([v[2] for v in vs])),
        }
        for c, vs in out.items()
    }


RAW, MISS_OFF = "mean_eq6_error_pct", "mean_eq6_without_replay_miss_pct"


def headline(waterfall: list[dict]) -> tuple[str, list[str]]:
    """The error a user watches, before -> after (held out): raw, and with the replay's own miss on each trial's
    motion taken off (the twin bootstrap: what no model change removes); and a line for each case whose raw error
    rose while it fell with that miss taken off, saying why."""
    first, last = waterfall[0], waterfall[-1]
    if len(waterfall) == 1:
        return (
            f"mean Eq. 6 error: {first[RAW]:.2f}% ({first['model']}), where the model stayed; with the replay's own "
            f"miss taken off {first[MISS_OFF]:.2f}%"
        ), []
    line = (
        f"mean Eq. 6 error: {first[RAW]:.2f}% ({first['model']}) -> {last[RAW]:.2f}% ({last['model']}); with the "
        f"replay's own miss taken off {first[MISS_OFF]:.2f}% -> {last[MISS_OFF]:.2f}%"
    )
    risen = []
    for case, before in first["cases"].items():
        after = last["cases"].get(case)
        if after is None or after[RAW] <= before[RAW] or after[MISS_OFF] >= before[MISS_OFF]:
            continue
        risen.append(
            f"{case}: its error rose {before[RAW]:.2f}% -> {after[RAW]:.2f}% while it fell {before[MISS_OFF]:.2f}% -> "
            f"{after[MISS_OFF]:.2f}% with the replay's own miss taken off: that miss (the replay's error on this "
            "case's motion even at the truth, the twin bootstrap) had offset part of the model's; once the model's "
            "is gone it is what is left, and no change of the model removes it"
        )
    return line, risen


def waterfall_step(label, score: HeldOutScore, trials) -> dict:
    return {
        "model": label,
        "effects": score.effects,
        "mean_eq6_error_pct": score.mean_eq6(),
        "mean_eq6_without_replay_miss_pct": score.mean_eq6_without_miss(),
        "held_out_sum_of_squares": score.sum_of_squares,
        "cases": score.by_case(trials),
    }
