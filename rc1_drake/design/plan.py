"""The next experiment (issue 68): the budget's trials that best tell a diagnosis's open hypotheses apart, chosen
together from designs drawn over what the robot and the lab can run, and written as a plan a lab can run.

Every candidate design is synthesized under every hypothesis (separation.synthesized_trial), dropped where a
hypothesis's head path leaves the floor or turns tighter than RC1 can, and each hypothesis is linearized on every
other's trials (separation.rival_linearization), weighed by the failed joint's scatter where the diagnosis took it.
The trials are then chosen greedily, each step adding the design that most raises the worst pair's distance over the
trials chosen so far — the rival refits its starts, the free friction and its own effects over all of them together,
so that a design which only repeats what another already shows adds little (maximin T-optimality, evaluated again
at each step)."""

import dataclasses
import json
import os
import time
from pathlib import Path

import numpy as np

from ..config import Rc1Error
from ..diagnose.thresholds import THRESHOLDS
from ..executor import make_executor
from ..sysid.evaluate import Evaluator
from .check import check_lines, direction, predicted_by_trial, predicted_separation, realized_separation
from .hypotheses import Hypothesis, open_hypotheses, pairs
from .lab import Lab, TrialDesign, off_the_floor, sampled_designs
from .separation import rival_linearization, synthesized_trial, told_apart

AMBIGUOUS_RATIO = THRESHOLDS.ambiguous_ratio
# The paper's cases and the probe study's kinds among the candidates: a design has to beat them to be chosen.
PAPER_KINDS = [
    TrialDesign(()),
    TrialDesign((7,)),
    TrialDesign((13,)),
    TrialDesign((7,), bias_deg=-0.9, amplitude_deg=37.1),
    TrialDesign((2,), seconds=5.0),
    TrialDesign((), amplitude_deg=34.0, bias_deg=4.0),
    TrialDesign((), amplitude_deg=34.0, bias_deg=-4.0),
]


@dataclasses.dataclass
class Plan:
    lab: Lab
    hypotheses: list[Hypothesis]
    chosen: list[TrialDesign]
    # per step: "a | b" -> the pair's distance over the trials chosen up to it (the worse of the two directions)
    evidence: list[dict[str, float]]
    paths: list[dict[str, list]]  # per chosen trial: hypothesis -> its head path [[x, y], ...]
    considered: int
    dropped: dict[str, str]  # a design's label -> why it cannot be run
    simulations: int
    wall_s: float
    predicted: dict[str, float] = dataclasses.field(default_factory=dict)  # per direction (check.py)
    realized: dict[str, list[float]] = dataclasses.field(default_factory=dict)  # per direction, each replicate
    # per step: "a | b" -> the held-out ratio the diagnosis of the union is predicted to see (Standing.ratio)
    ratios: list[dict[str, float]] = dataclasses.field(default_factory=list)
    # per direction and chosen trial, fitted alone: the predicted distance, and the realized one of each replicate
    predicted_trials: dict[str, list[float]] = dataclasses.field(default_factory=dict)
    realized_trials: dict[str, list[list[float]]] = dataclasses.field(default_factory=dict)

    def to_json(self) -> dict:
        return {
            "lab": dataclasses.asdict(self.lab),
            "hypotheses": [
                {"name": h.name, "friction": dataclasses.asdict(h.friction), "effects": h.effects}
                for h in self.hypotheses
            ],  # fmt: skip
            "trials": [dataclasses.asdict(d) | {"label": d.label()} for d in self.chosen],
            "evidence": self.evidence,
            "told_apart": [{pair: told_apart(d) for pair, d in step.items()} for step in self.evidence],
            "held_out_ratio": self.ratios,
            "check": {
                n: {
                    "predicted": self.predicted[n],
                    "realized": v,
                    "by_trial": {"predicted": self.predicted_trials[n], "realized": self.realized_trials[n]},
                }
                for n, v in self.realized.items()
            },
            "considered": self.considered,
            "dropped": self.dropped,
            "simulations": self.simulations,
            "wall_s": self.wall_s,
        }

    def format(self) -> str:
        names = ", ".join(h.name for h in self.hypotheses)
        lines = [f"the next {len(self.chosen)} trials to tell apart {names} (of {self.considered} designs):"]
        for k, (d, step, ratio) in enumerate(zip(self.chosen, self.evidence, self.ratios, strict=True), 1):
            worst = min(ratio, key=ratio.get)
            lines.append(
                f"  {k}. {d.label()}: worst pair {worst} {step[worst]:.3g} apart, a held-out ratio of "
                f"{ratio[worst]:.2f} predicted (the diagnosis names one at {AMBIGUOUS_RATIO:g})"
            )
        if self.realized:
            count = len(next(iter(self.realized.values())))
            lines.append(f"the plan's own check ({count} noisy replicate(s) under each hypothesis; -2 log likelihood "
                         "ratio):")  # fmt: skip
            lines += check_lines(self.predicted, self.realized, self.predicted_trials, self.realized_trials)
        lines.append(f"{self.simulations} simulations, {self.wall_s:.0f} s")
        return "\n".join(lines)

    def write(self, folder) -> None:
        """PLAN/: plan.json, one scenario file per trial (what to set on the robot and how long; `rc1 run
        --scenarios-file PLAN/trial_k.yaml --scenario trial_k`), and a figure of the head paths each hypothesis
        predicts for each trial."""
        from pydrake.common.yaml import yaml_dump_typed

        from ..config import Scenario

        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        (folder / "plan.json").write_text(json.dumps(self.to_json(), indent=2) + "\n")
        for k, d in enumerate(self.chosen, 1):
            yaml_dump_typed(
                d.scenario(), schema=Scenario, filename=str(folder / f"trial_{k}.yaml"), child_name=f"trial_{k}"
            )
        _plot_paths(self, folder / "paths.png")


def _plot_paths(plan: Plan, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    count = max(len(plan.chosen), 1)
    fig, axes = plt.subplots(1, count, figsize=(4.5 * count, 4), squeeze=False)
    for ax, d, paths in zip(axes[0], plan.chosen, plan.paths, strict=False):
        for name, xy in paths.items():
            xy = np.asarray(xy)
            ax.plot(xy[:, 0], xy[:, 1], label=f"if {name}")
        ax.set_title(d.label(), fontsize=8, wrap=True)
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.set_aspect("equal", adjustable="datalim")
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def design_trials(*, diagnosis: dict, lab: Lab | None = None, budget: int = 4, candidates: int = 16, seed: int = 0,
                  replicates: int = 1, workers=None, progress=None, where: str = "diagnosis") -> Plan:  # fmt: skip
    """The plan of `budget` trials (module docstring) among `candidates` designs drawn from `lab` (default Lab())
    and PAPER_KINDS, for the hypotheses `diagnosis` (its JSON) leaves open; the friction it identified is free.
    `replicates`: noisy copies of the plan under each hypothesis for its own check (check.py; 0: none)."""
    started = time.perf_counter()
    lab = lab or Lab()
    if budget < 1:
        raise Rc1Error(f"design: the budget must be at least 1 trial, got {budget}")
    hypotheses = open_hypotheses(diagnosis, where)
    free = list(diagnosis.get("free_friction", []))
    scatter = float((diagnosis.get("scatter") or [0.0])[0])  # the failed joint's, as the diagnosis took it
    designs = [d for d in PAPER_KINDS if d.seconds <= lab.max_seconds and list(d.failed_joints) in lab.failures]
    designs += sampled_designs(lab, candidates, np.random.default_rng(seed))
    with make_executor(workers=workers or os.cpu_count()) as executor:
        evaluator = Evaluator(executor, progress)
        made = {noisy: [_synthesized(designs, h, lab, noisy, seed, evaluator) for h in hypotheses] for noisy in (0, 1)}
        dropped = _dropped(designs, made[0] + made[1], lab)
        keep = [k for k, d in enumerate(designs) if d.label() not in dropped]
        if not keep:
            raise Rc1Error("design: no candidate design stays on the lab's floor")
        lins = {
            (a, b): rival_linearization(
                [made[0][a][k] for k in keep], [made[1][a][k] for k in keep], hypotheses[b], free, evaluator, scatter
            )  # fmt: skip
            for a in range(len(hypotheses))
            for b in range(len(hypotheses))
            if a != b
        }
        chosen, evidence, ratios = _greedy(hypotheses, lins, min(budget, len(keep)), Standing.of(diagnosis, hypotheses))
        picked = [designs[keep[n]] for n in chosen]
        realized, realized_trials = realized_separation(picked, hypotheses, lab, free, evaluator,
                                                        replicates=replicates, seed=seed, scatter=scatter)  # fmt: skip
        simulations = evaluator.simulations
    paths = [{h.name: made[0][i][keep[n]].camera[:, :2].tolist() for i, h in enumerate(hypotheses)} for n in chosen]
    return Plan(lab, hypotheses, picked, evidence, paths, len(designs), dropped, simulations,
                time.perf_counter() - started, predicted_separation(hypotheses, lins, chosen), realized,
                ratios, predicted_by_trial(hypotheses, lins, chosen), realized_trials)  # fmt: skip


def _synthesized(designs, hypothesis, lab, noisy, seed, evaluator) -> list:
    jobs = [(d, hypothesis, lab, bool(noisy), seed + k, f"d{k}") for k, d in enumerate(designs)]
    return evaluator.map(synthesized_trial, jobs, f"the designs under {hypothesis.name}" + (" with noise" * noisy))


def _dropped(designs, made, lab) -> dict[str, str]:
    """A design's label -> why it cannot be run, where some hypothesis's trial of it (`made`: per hypothesis)
    leaves the floor or turns too tight."""
    out = {}
    for k, d in enumerate(designs):
        for trials in made:
            t = trials[k]
            if why := t if isinstance(t, str) else off_the_floor(t.t, t.camera[:, :2], t.head_yaw_rate, lab):
                out[d.label()] = why
    return out


@dataclasses.dataclass(frozen=True)
class Standing:
    """Where the diagnosis leaves the hypotheses: the best one's held-out weighted sum of squares (`leftover`) and,
    per pair, how far the other's already is above it. The diagnosis names an effect only where its rivals' held-out
    sum of squares is Thresholds.ambiguous_ratio times its own (decide.decide); on data a hypothesis explains, a
    trial adds about its row count to the true one's (its rows' noise, in the noise's units) and the pair's distance
    more to the rival's: the ratio the union's diagnosis is predicted to see."""

    leftover: float = 0.0
    apart: dict = dataclasses.field(default_factory=dict)  # "a | b" -> the rival's excess today

    @classmethod
    def of(cls, diagnosis: dict, hypotheses) -> "Standing":
        simulated = {c["name"]: c["simulated"]["held_out_sum_of_squares_after"]
                     for c in diagnosis["rounds"][-1].get("candidates", []) if c.get("simulated")}  # fmt: skip
        if not simulated:
            return cls()
        best = min(simulated.values())
        apart = {f"{hypotheses[a].name} | {hypotheses[b].name}": abs(simulated[hypotheses[a].name]
                 - simulated[hypotheses[b].name]) for a, b in pairs(hypotheses)
                 if hypotheses[a].name in simulated and hypotheses[b].name in simulated}  # fmt: skip
        return cls(best, apart)

    def ratio(self, pair: str, distance: float, rows: float) -> float:
        own = self.leftover + rows
        return (own + self.apart.get(pair, 0.0) + distance) / max(own, 1e-9)


def _greedy(hypotheses, lins, count: int, standing: Standing) -> tuple[list[int], list[dict], list[dict]]:
    """`count` trials, each step the one that most raises the worst pair's predicted held-out ratio (Standing) over
    those chosen so far."""
    chosen, evidence, ratios = [], [], []
    for _ in range(count):
        scored = []
        for n in range(len(lins[0, 1].trials)):
            if n in chosen:
                continue
            step = _pair_distances(hypotheses, lins, chosen + [n])
            rows = np.mean([sum(len(lin.r0[k]) for k in chosen + [n]) for lin in lins.values()])
            ratio = {pair: standing.ratio(pair, d, rows) for pair, d in step.items()}
            scored.append((min(ratio.values()), n, step, ratio))
        _, best, step, ratio = max(scored, key=lambda s: s[0])
        chosen.append(best)
        evidence.append(step)
        ratios.append(ratio)
    return chosen, evidence, ratios


def load_plan(folder) -> tuple[list[TrialDesign], Lab]:
    """The trials and the lab of a plan folder (rc1 design --out), or Rc1Error naming what is wrong."""
    path = Path(folder) / "plan.json"
    if not path.is_file():
        raise Rc1Error(f"{folder}: not a plan folder (no plan.json; rc1 design --out writes one)")
    fields = [f.name for f in dataclasses.fields(TrialDesign)]
    try:
        data = json.loads(path.read_text())
        designs = [
            TrialDesign(**{k: tuple(t[k]) if k == "failed_joints" else t[k] for k in fields}) for t in data["trials"]
        ]
        lab = Lab(**data["lab"])
    except (json.JSONDecodeError, KeyError, TypeError) as error:
        raise Rc1Error(f"{path}: not a plan rc1 design wrote ({type(error).__name__}: {error})") from None
    lab.check(str(path))
    return designs, lab


def _pair_distances(hypotheses, lins, indices) -> dict[str, float]:
    """Per pair "a | b": the smaller of a's trials' distance from b's fit and b's trials' from a's."""
    both = predicted_separation(hypotheses, lins, indices)
    return {
        f"{hypotheses[a].name} | {hypotheses[b].name}": min(
            both[direction(hypotheses, a, b)], both[direction(hypotheses, b, a)]
        )
        for a, b in pairs(hypotheses)
    }
