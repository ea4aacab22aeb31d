"""Decide (stage 3): every candidate fitted beside today's model and scored on held-out trials (rank), the best
checked by simulation, and the decision between accepting one, calling candidates alike, or a partial one."""

import numpy as np

from ..config import FRICTION_NAMES
from ..effects import LIBRARY, effect_values
from ..sysid.evaluate import Evaluator
from ..sysid.stats import bound_side, interval95, wald_p
from .coordinates import model_at, starts_at
from .fit import Fit, fit
from .linearize import Linearization, visibility
from .replays import evaluate
from .report import CandidateResult, HeldOutScore
from .significance import orthogonal_to, subspace_cosine
from .thresholds import THRESHOLDS, Thresholds

NOT_DETECTABLE = "not detectable here"  # a candidate whose largest physical value would not be significant


def held_out_by_simulation(lin: Linearization, fitted: Fit, evaluator: Evaluator, label: str) -> HeldOutScore:
    """Every trial replayed with the parameters fitted without it."""
    coords = [lin.coordinate(n) for n in fitted.names]
    jobs = []
    for k in range(len(lin.trials)):
        values = [c.value + d for c, d in zip(coords, fitted.held_out_steps[k], strict=True)]
        jobs.append((starts_at(lin.trials, coords, values)[k], *model_at(lin.friction, lin.effects, coords, values)))
    out = evaluator.map(evaluate, jobs, f"held-out replays: {label}")
    _, effects = model_at(lin.friction, lin.effects, coords, fitted.values)
    return score(
        lin,
        label,
        effects,
        [lin.corrected(k, o[0]) for k, o in enumerate(out)],
        [o[1] for o in out],
        [o[2] for o in out],
    )


def screen_friction(lin: Linearization, names=FRICTION_NAMES, max_relative_error=0.3, nuisance=()) -> list[str]:
    """The friction coefficients these data identify (identify.screen's rule: standard error below 30%), fitted
    with the `nuisance` coordinates."""
    if not names:
        return []
    fitted = fit(lin, list(nuisance) + list(names))
    return [
        n
        for n, v, se in zip(fitted.names, fitted.values, fitted.standard_errors, strict=True)
        if n in names and se < max_relative_error * abs(v)
    ]


def rank(
    lin: Linearization,
    base: Fit,
    model_names: list[str],
    names: list[str],
    reference: Fit | None = None,
    thresholds: Thresholds = THRESHOLDS,
) -> list[CandidateResult]:
    """Every candidate fitted with today's model's free parameters, scored on held-out trials (linear)
    against `reference` (today's model without the candidates; `base` by default)."""
    reference = reference or base
    before = lin.weighted_rms(reference.held_out)
    x_model = lin.rows(model_names, range(len(lin.trials)), weighted=True)[0]
    projected = {}
    results = []
    for name in names:
        own = [c.name for c in lin.coordinates if c.owner == name]
        fitted = fit(lin, model_names + own)
        after = lin.weighted_rms(fitted.held_out)
        x_own = lin.rows(own, range(len(lin.trials)), weighted=True)[0]
        projected[name] = orthogonal_to(x_own, x_model)
        idx = [fitted.names.index(n) for n in own]
        coords = [lin.coordinate(n) for n in own]
        effect = LIBRARY[name]
        values = effect.coordinates(effect_values(lin.effects, effect))
        values.update({n: float(fitted.values[i]) for n, i in zip(own, idx, strict=True)})
        se = {n: float(fitted.standard_errors[i]) for n, i in zip(own, idx, strict=True)}
        seen_se = fitted.noise_standard_errors if thresholds.detectable_by_noise else fitted.standard_errors
        p = wald_p(fitted, own)
        reduction = 1.0 - (after / before) ** 2 if before > 0 else 0.0
        detectable = {n: 3.0 * float(seen_se[i]) for n, i in zip(own, idx, strict=True)}
        visible = (
            any(detectable[n] < max(abs(c.lower), abs(c.upper)) for n, c in zip(own, coords, strict=True))
            and np.linalg.norm(projected[name]) > 1e-9
        )
        if not visible:
            status = NOT_DETECTABLE
        elif p >= thresholds.p_accept:
            status = "not significant"
        elif reduction < thresholds.min_held_out_reduction:
            status = "no held-out gain"
        else:
            status = "candidate"
        results.append(
            CandidateResult(
                name=name,
                parameters=effect.from_coordinates(values),
                coordinates={n: [values[n], se[n]] for n in own},
                interval95={n: interval95(values[n], se[n]) for n in own},
                wald_p=p,
                held_out_before=before,
                held_out_after=after,
                held_out_reduction=reduction,
                aic_delta=fitted.aic - reference.aic,
                score=reduction,
                status=status,
                detectable_strength=detectable,
                visibility=visibility(lin, name),
                at_bound=[n for n, c in zip(own, coords, strict=True) if bound_side(values[n], c.lower, c.upper)],
            )
        )
    for c in results:
        for other in results:
            if other is c or np.linalg.norm(projected[c.name]) < 1e-9 or np.linalg.norm(projected[other.name]) < 1e-9:
                continue
            if subspace_cosine(projected[c.name], projected[other.name]) >= thresholds.indistinguishable_cos:
                c.indistinguishable_from.append(other.name)
    results.sort(key=lambda c: -c.score)
    return results


def decide(results: list[CandidateResult], thresholds: Thresholds = THRESHOLDS) -> tuple:
    """From the candidates checked by simulation (`simulated` set): (the accepted one's name or None, the
    names that explain the held-out trials alike, the name of one that explains only part of it); sets
    every checked candidate's status and the accepted one's flag. Only a significant candidate is accepted; a
    look-alike checked though not significant (its parameters loose: a slope's two) is a rival that can tie it."""
    helping = [
        c for c in results if c.simulated and c.simulated["held_out_reduction"] >= thresholds.min_held_out_reduction
    ]
    helping.sort(key=lambda c: c.simulated["held_out_sum_of_squares_after"])
    for c in results:
        if c.simulated and c not in helping:
            c.status = "no held-out gain when simulated"
    if thresholds.set_aside_at_bound:
        for c in (c for c in helping if c.at_bound):
            c.status = f"fitted at a bound of its range ({', '.join(c.at_bound)}): the model's form, not this effect"
        helping = [c for c in helping if not c.at_bound]
    significant = [c for c in helping if c.wald_p < thresholds.p_accept]
    if not significant:
        return None, [], None
    best = significant[0]
    others = [c for c in helping if c is not best]
    for c in others:
        if c in significant:  # a look-alike keeps its "not significant"
            c.status = "held-out gain, clearly less than the best one's"
    best_after = best.simulated["held_out_sum_of_squares_after"]
    rivals = [
        c for c in others if c.simulated["held_out_sum_of_squares_after"] < thresholds.ambiguous_ratio * best_after
    ]
    if rivals:
        # Two effects that explain the held-out trials alike: these trials cannot tell which it is.
        ambiguous = [best.name] + [c.name for c in rivals]
        for c in [best, *rivals]:
            c.status = "explains it, as well as " + ", ".join(n for n in ambiguous if n != c.name)
        return None, ambiguous, None
    if best.simulated["held_out_reduction"] < thresholds.accept_held_out_reduction:
        # Significant and confirmed, but too weak a gain to name the effect: wrong effects accepted in a true
        # one's place gained 17-49% (Thresholds.accept_held_out_reduction).
        best.status = (
            f"explains part of it ({100 * best.simulated['held_out_reduction']:.0f}% of the held-out "
            f"error; accepting needs half): not accepted"
        )
        return None, [], best.name
    best.status, best.accepted = "accepted", True
    return best.name, [], None


def score(lin: Linearization, label: str, effects, corrected, eq6, yaw_fit) -> HeldOutScore:
    """Per-trial scores of one replay per trial of `lin`: its bias-corrected residuals, Eq. 6, yaw-rate fit."""
    ids = [t.trial_id for t in lin.trials]
    return HeldOutScore(
        label=label,
        effects=effects,
        sum_of_squares=lin.weighted_sum_of_squares(corrected),
        eq6_pct=dict(zip(ids, eq6, strict=True)),
        yaw_fit_pct=dict(zip(ids, yaw_fit, strict=True)),
        eq6_without_miss_pct={
            i: lin.eq6_without_miss(k, r) for k, (i, r) in enumerate(zip(ids, corrected, strict=True))
        },
    )


def unrefitted(lin: Linearization, label: str) -> HeldOutScore:
    """The model of `lin` scored as it stands (its replays there, nothing refitted or held out)."""
    return score(lin, label, dict(lin.effects), lin.r0, lin.eq6, lin.yaw_fit)
