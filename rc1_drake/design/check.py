"""The plan's own check (issue 68 item 3): its trials replicated with noise under each hypothesis, each hypothesis
and its rival fitted to them, and the realized -2 log likelihood ratio set beside the distance the plan predicted.
On noisy data the rival's fit leaves the predicted distance plus the noise it cannot fit, the hypothesis's own
leaves the noise alone: their difference should scatter about the prediction."""

import numpy as np

from .hypotheses import pairs
from .separation import distance, rival_linearization, synthesized_trial


def realized_separation(designs, hypotheses, lab, free, evaluator, *, replicates: int, seed: int, scatter=0.0) -> tuple:
    """Per direction "a's trials, b fitted": the realized ratio (the rival's weighted sum of squares less a's own,
    both fitted with their starts, the free friction and their own effects, each model's replay bias on the noisy
    trials taken off as the diagnosis takes it; weighed by the failed joint's `scatter`)
    of each of `replicates` noisy copies of the planned trials (`designs`); and the same per trial, each fitted
    alone (which trial of a plan its prediction fails on). Returns (per direction, per direction and trial)."""
    out: dict[str, list[float]] = {}
    by_trial: dict[str, list[list[float]]] = {}
    every = list(range(len(designs)))
    for r in range(replicates):
        noisy = [
            evaluator.map(synthesized_trial, [(d, h, lab, True, seed + 1000 * (r + 1) + k, f"c{k}")
                                              for k, d in enumerate(designs)], f"the plan replicated under {h.name}")
            for h in hypotheses
        ]  # fmt: skip
        if any(isinstance(t, str) for trials in noisy for t in trials):
            continue  # a replicate whose run fails the loader's checks (separation.synthesized_trial) is not drawn
        own = [rival_linearization(noisy[x], noisy[x], h, free, evaluator, scatter, measured=True)
               for x, h in enumerate(hypotheses)]  # fmt: skip
        own_total = [distance(lin, every) for lin in own]
        own_each = [[distance(lin, [k]) for k in every] for lin in own]
        for a, b in pairs(hypotheses):
            for x, y in ((a, b), (b, a)):
                rival = rival_linearization(noisy[x], noisy[x], hypotheses[y], free, evaluator, scatter, measured=True)
                name = direction(hypotheses, x, y)
                out.setdefault(name, []).append(distance(rival, every) - own_total[x])
                per = by_trial.setdefault(name, [[] for _ in every])
                for k in every:
                    per[k].append(distance(rival, [k]) - own_each[x][k])
    return out, by_trial


def direction(hypotheses, x: int, y: int) -> str:
    return f"{hypotheses[x].name}'s trials, {hypotheses[y].name} fitted"


def predicted_separation(hypotheses, lins, indices) -> dict[str, float]:
    """Per direction, the distance the plan predicts over its trials `indices` (separation.distance)."""
    return {
        direction(hypotheses, x, y): distance(lins[x, y], indices)
        for a, b in pairs(hypotheses)
        for x, y in ((a, b), (b, a))
    }


def predicted_by_trial(hypotheses, lins, indices) -> dict[str, list[float]]:
    """Per direction, the distance the plan predicts on each of its trials `indices` fitted alone."""
    return {
        direction(hypotheses, x, y): [distance(lins[x, y], [k]) for k in indices]
        for a, b in pairs(hypotheses)
        for x, y in ((a, b), (b, a))
    }


def check_lines(predicted: dict, realized: dict, predicted_trials: dict, realized_trials: dict) -> list[str]:
    """One line per direction: predicted, realized (mean and each replicate); under it, one per trial fitted alone."""
    lines = []
    for name, values in realized.items():
        lines.append(
            f"  {name}: predicted {predicted[name]:.3g}, realized {np.mean(values):.3g} "
            f"({', '.join(f'{v:.3g}' for v in values)})"
        )
        for k, (guess, seen) in enumerate(zip(predicted_trials[name], realized_trials[name], strict=True), 1):
            lines.append(f"    trial {k} alone: predicted {guess:.3g}, realized {np.mean(seen):.3g} "
                         f"({', '.join(f'{v:.3g}' for v in seen)})")  # fmt: skip
    return lines
