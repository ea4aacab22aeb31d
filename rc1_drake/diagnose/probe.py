"""The probe study: which kind of trial would see a candidate these trials cannot, or tell apart two candidates
they explain alike (a noise-free trial of each kind, synthesized from the model and linearized)."""

import math
import os
import tempfile
from pathlib import Path

import numpy as np

from ..config import Friction, Gait, Stop
from ..effects import LIBRARY
from ..executor import make_executor
from ..measurements import load_campaign
from ..synthesize import Case, Noise, Variation, synthesize_campaign
from ..sysid.evaluate import Evaluator
from .linearize import FINAL_SIGMA_M, linearize
from .significance import subspace_cosine

PROBE_KINDS = {
    "no failure, 140 deg/s": ([], None),
    "no failure, 70 deg/s": ([], 70.0),
    "joint 7 failed": ([7], None),
    "joint 13 failed": ([13], None),
    "joint 2 failed": ([2], None),
}


PROBE_SECONDS = 3.0


def probe_visibility(
    friction: Friction,
    effects: dict[str, float],
    names: list[str],
    *,
    workers=None,
    seconds: float = PROBE_SECONDS,
    progress=None,
) -> dict[str, dict[str, dict]]:
    """Which kind of trial sees each candidate: a noise-free `seconds`-long trial of every PROBE_KINDS
    kind is synthesized from the model, replayed, and each candidate coordinate's probe step applied.
    Returns kind -> candidate -> {"final_cm_per_probe", "detectable_strength" (three standard errors of
    one trial with the campaign format's stated noise, no input noise), "columns"}."""
    design = [
        Case(list(failed), 1, gait=None if f is None else Gait(frequency_deg_s=f)) for failed, f in PROBE_KINDS.values()
    ]
    with tempfile.TemporaryDirectory() as tmp:
        synthesize_campaign(
            tmp,
            design=design,
            friction=friction,
            effects=effects,
            noise=Noise().scaled(0.0),
            variation=Variation(0.0, 0.0, 0.0),
            stop=Stop(line_x_m=None, revolutions=None, time_limit_s=seconds),
        )
        trials = load_campaign(Path(tmp)).trials
    with make_executor(workers=workers or min(os.cpu_count() or 1, len(trials))) as executor:
        lin = linearize(
            trials, friction, effects, names, Evaluator(executor, progress), noise=[np.zeros((1, 1))] * len(trials)
        )
    out: dict[str, dict[str, dict]] = {}
    for kind, (failed, frequency) in PROBE_KINDS.items():
        trial_index = next(
            k
            for k, t in enumerate(trials)
            if t.failed_joints == list(failed) and t.gait.frequency_deg_s == (frequency or Gait().frequency_deg_s)
        )
        for name in names:
            own = [c for c in lin.coordinates if c.owner == name]
            cols = np.column_stack([lin.columns[c.name][trial_index] for c in own])
            norms = np.linalg.norm(cols, axis=0)
            out.setdefault(kind, {})[name] = {
                "final_cm_per_probe": {
                    c.name: float(100 * FINAL_SIGMA_M * np.linalg.norm(cols[:2, i]) * c.step) for i, c in enumerate(own)
                },
                "detectable_strength": {
                    c.name: (float(3.0 / norms[i]) if norms[i] > 0 else math.inf) for i, c in enumerate(own)
                },
                "columns": cols,
            }
    return out


def suggest_experiments(rounds, not_detectable, friction, effects, workers, progress) -> None:
    """Fill in, from the probe study, the kind of trial that would see each effect not detectable here
    and that would tell apart candidates these data cannot."""
    if not rounds:
        return
    pairs = {tuple(sorted((c.name, other))) for c in rounds[0].candidates for other in c.indistinguishable_from}
    pairs = sorted(pairs | {tuple(sorted((a, b))) for r in rounds for a in r.ambiguous for b in r.ambiguous if a != b})
    hidden = [d["name"] for d in not_detectable if LIBRARY[d["name"]].seen_in_replay]
    names = list(dict.fromkeys(hidden + [n for pair in pairs for n in pair]))
    if not names:
        return
    study = probe_visibility(friction, effects, names, workers=workers, progress=progress)
    for d in not_detectable:
        if d["name"] not in hidden:
            continue
        best = min(study, key=lambda kind: min(study[kind][d["name"]]["detectable_strength"].values()))
        strength = study[best][d["name"]]["detectable_strength"]
        d["experiment"] = (
            f"a {best} trial: one {PROBE_SECONDS:g} s trial detects "
            + ", ".join(f"{k} of {v:.3g}" for k, v in strength.items())
            + " (sensor noise only)"
        )
    for a, b in pairs:
        cosines = {
            kind: subspace_cosine(study[kind][a]["columns"], study[kind][b]["columns"])
            for kind in study
            if np.linalg.norm(study[kind][a]["columns"]) > 0 and np.linalg.norm(study[kind][b]["columns"]) > 0
        }
        if cosines:
            kind = min(cosines, key=cosines.get)
            text = f"a {kind} trial tells {a} and {b} apart (cosine {cosines[kind]:.2f})"
            for c in [c for r in rounds for c in r.candidates if c.name in (a, b)]:
                c.experiment = text if c.experiment is None else c.experiment + "; " + text
