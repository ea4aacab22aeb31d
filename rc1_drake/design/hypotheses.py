"""The hypotheses a diagnosis leaves open (issue 68), read from its JSON (`rc1 diagnose --json`): each a model
(friction, effects) and the effects whose strength it fits itself. The next trials are chosen to tell them apart.

- `ambiguous`: today's model with each candidate of the last round that explained the held-out trials alike, at
  its fitted strength, and with each other candidate that helped there (a held-out gain when simulated), best first.
- `effect_found`: the accepted model against the same model with the runner-up of the round that accepted it in
  the accepted effect's place, and with each other candidate that helped in that round in its place.
- `no_missing_effect` or `unexplained`: today's model against it with each candidate these trials could not see,
  at the strength they would have needed to (its detectable strength), and with the best-ranked candidates.

A candidate that helped but lost is kept as a rival: the union of a campaign and its designed trials has named such a
one (a payload) tied with the effect the plan had set against the others. At most MAX_HYPOTHESES, each costing the
plan a simulation of every design (those a verdict names, all of them)."""

import dataclasses

from ..config import Friction, Rc1Error
from ..diagnose.decide import NOT_DETECTABLE
from ..diagnose.thresholds import THRESHOLDS
from ..effects import LIBRARY, effect_values

RIVALS_WHEN_NOTHING_FOUND = 2  # the best-ranked candidates set against today's model beside the undetectable ones
MAX_HYPOTHESES = 4


@dataclasses.dataclass(frozen=True)
class Hypothesis:
    name: str
    friction: Friction
    effects: dict = dataclasses.field(hash=False)
    owned: tuple[str, ...] = ()  # effects whose coordinates this hypothesis fits to any data (its own)


def _without(effects: dict, name: str) -> dict:
    keys = {p.key for p in LIBRARY[name].parameters}
    return {k: v for k, v in effects.items() if k not in keys}


def _at_strength(effects: dict, name: str, coordinates: dict[str, float]) -> dict:
    effect = LIBRARY[name]
    current = effect.coordinates(effect_values(effects, effect))
    current.update(coordinates)
    return {**effects, **effect.from_coordinates(current)}


def helped(candidates: list[dict], besides) -> list[dict]:
    """The candidates of a round not in `besides` whose simulated check gained on the held-out trials (decide's
    least gain), by their held-out sum of squares after, best first."""
    gained = [
        c for c in candidates if c["name"] not in besides and c.get("simulated")
        and c["simulated"]["held_out_reduction"] >= THRESHOLDS.min_held_out_reduction
    ]  # fmt: skip
    return sorted(gained, key=lambda c: c["simulated"]["held_out_sum_of_squares_after"])


def _fitted(candidate: dict) -> dict[str, float]:
    return {k: v[0] for k, v in candidate["coordinates"].items()}


def open_hypotheses(diagnosis: dict, where: str = "diagnosis") -> list[Hypothesis]:
    """The hypotheses to tell apart (module docstring), at least two, or Rc1Error naming what the JSON lacks."""
    try:
        friction = Friction(**diagnosis["model"]["friction"])
        effects, verdict, rounds = dict(diagnosis["model"]["effects"]), diagnosis["verdict"], diagnosis["rounds"]
    except (KeyError, TypeError) as error:
        raise Rc1Error(f"{where}: not a diagnosis's JSON (rc1 diagnose --json): no {error}") from None
    if not rounds:
        raise Rc1Error(f"{where}: the diagnosis has no round: nothing to tell apart")
    last = rounds[-1]
    if verdict == "ambiguous":
        by_name = {c["name"]: c for c in last["candidates"]}
        tied = [by_name[n] for n in last["ambiguous"]]
        out = [
            Hypothesis(c["name"], friction, _at_strength(effects, c["name"], _fitted(c)), (c["name"],))
            for c in (tied + helped(last["candidates"], last["ambiguous"]))[: max(MAX_HYPOTHESES, len(tied))]
        ]
    elif verdict == "effect_found":
        accepted = diagnosis["accepted_effects"][-1]
        round_of = next((r for r in rounds if r["accepted"] == accepted), None)
        if round_of is None:
            raise Rc1Error(f"{where}: no round accepted {accepted}, which the verdict names")
        runner = next((c for c in round_of["candidates"] if c["name"] != accepted and c["status"] != NOT_DETECTABLE
                       and c["name"] not in diagnosis["accepted_effects"]), None)  # fmt: skip
        out = [Hypothesis(accepted, friction, effects, (accepted,))]
        named = [accepted, *diagnosis["accepted_effects"]] + ([runner["name"]] if runner else [])
        rivals = ([runner] if runner else []) + helped(round_of["candidates"], named)
        for c in rivals[: MAX_HYPOTHESES - 1]:
            rival = _at_strength(_without(effects, accepted), c["name"], _fitted(c))
            out.append(Hypothesis(c["name"], friction, rival, (c["name"],)))
    else:
        out = [Hypothesis("today's model", friction, effects)]
        ranked = [c for c in last["candidates"] if c["name"] not in effects]
        unseen = [c for c in ranked if c["status"] == NOT_DETECTABLE and c["detectable_strength"]]
        best = [c for c in ranked if c not in unseen][:RIVALS_WHEN_NOTHING_FOUND]
        for c in unseen:
            out.append(Hypothesis(c["name"], friction, _at_strength(effects, c["name"], c["detectable_strength"]),
                                  (c["name"],)))  # fmt: skip
        for c in best:
            strength = {k: max(abs(v[0]), c["detectable_strength"].get(k, 0.0)) for k, v in c["coordinates"].items()}
            out.append(Hypothesis(c["name"], friction, _at_strength(effects, c["name"], strength), (c["name"],)))
    if len(out) < 2:
        raise Rc1Error(f"{where}: the diagnosis ({verdict}) leaves one hypothesis: nothing to tell apart")
    return out


def pairs(hypotheses: list[Hypothesis]) -> list[tuple[int, int]]:
    """Every pair of hypotheses, once."""
    return [(i, j) for i in range(len(hypotheses)) for j in range(i + 1, len(hypotheses))]
