"""The hypotheses a diagnosis leaves open (issue 68), read from its JSON (`rc1 diagnose --json`): each a model
(friction, effects) and the effects whose strength it fits itself. The next trials are chosen to tell them apart.

- `ambiguous`: today's model with each candidate of the last round that explained the held-out trials alike, at
  its fitted strength.
- `effect_found`: the accepted model against the same model with the runner-up of the round that accepted it in
  the accepted effect's place.
- `no_missing_effect` or `unexplained`: today's model against it with each candidate these trials could not see,
  at the strength they would have needed to (its detectable strength), and with the best-ranked candidates."""

import dataclasses

from ..config import Friction, Rc1Error
from ..diagnose.decide import NOT_DETECTABLE
from ..effects import LIBRARY, effect_values

RIVALS_WHEN_NOTHING_FOUND = 2  # the best-ranked candidates set against today's model beside the undetectable ones


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
        out = [
            Hypothesis(
                n, friction, _at_strength(effects, n, {k: v[0] for k, v in by_name[n]["coordinates"].items()}), (n,)
            )  # fmt: skip
            for n in last["ambiguous"]
        ]
    elif verdict == "effect_found":
        accepted = diagnosis["accepted_effects"][-1]
        round_of = next((r for r in rounds if r["accepted"] == accepted), None)
        if round_of is None:
            raise Rc1Error(f"{where}: no round accepted {accepted}, which the verdict names")
        runner = next((c for c in round_of["candidates"] if c["name"] != accepted and c["status"] != NOT_DETECTABLE
                       and c["name"] not in diagnosis["accepted_effects"]), None)  # fmt: skip
        out = [Hypothesis(accepted, friction, effects, (accepted,))]
        if runner is not None:
            rival = _at_strength(_without(effects, accepted), runner["name"],
                                 {k: v[0] for k, v in runner["coordinates"].items()})  # fmt: skip
            out.append(Hypothesis(runner["name"], friction, rival, (runner["name"],)))
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
