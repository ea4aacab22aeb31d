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

# Each kind: its trials as (failed joints, gait frequency deg/s or None: the paper's, bias deg: Eq. 7's B_i). Turning
# both ways parts what depends on the side the body turns to (a lateral friction asymmetry) from what does not (a
# payload): on the paper's design they are look-alikes (docs/diagnosis.md).
PROBE_KINDS = {
    "no failure, 140 deg/s": [([], None, 0.0)],
    "no failure, 70 deg/s": [([], 70.0, 0.0)],
    "turning both ways (bias +-4 deg)": [([], None, 4.0), ([], None, -4.0)],
    "joint 7 failed": [([7], None, 0.0)],
    "joint 13 failed": [([13], None, 0.0)],
    "joint 2 failed": [([2], None, 0.0)],
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
    """Which kind of trial sees each candidate: the noise-free `seconds`-long trials of every PROBE_KINDS
    kind are synthesized from the model, replayed, and each candidate coordinate's probe step applied.
    Returns kind -> candidate -> {"final_cm_per_probe" (the largest of the kind's trials), "detectable_strength"
    (three standard errors of the kind's trials with the campaign format's stated noise, no input noise),
    "columns" (the kind's trials' rows, stacked)}."""
    specs = [spec for trials in PROBE_KINDS.values() for spec in trials]
    design = [
        Case(list(failed), 1, bias_deg=bias, gait=None if f is None else Gait(frequency_deg_s=f))
        for failed, f, bias in specs
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
    for kind, kind_trials in PROBE_KINDS.items():
        indices = [_trial_of(trials, spec) for spec in kind_trials]
        for name in names:
            own = [c for c in lin.coordinates if c.owner == name]
            blocks = [np.column_stack([lin.columns[c.name][k] for c in own]) for k in indices]
            cols = np.vstack(blocks)
            norms = np.linalg.norm(cols, axis=0)
            out.setdefault(kind, {})[name] = {
                "final_cm_per_probe": {
                    c.name: float(100 * FINAL_SIGMA_M * c.step * max(np.linalg.norm(b[:2, i]) for b in blocks))
                    for i, c in enumerate(own)
                },
                "detectable_strength": {
                    c.name: (float(3.0 / norms[i]) if norms[i] > 0 else math.inf) for i, c in enumerate(own)
                },
                "columns": cols,
            }
    return out


def _trial_of(trials, spec) -> int:
    """The index of the probe trial of `spec` (failed joints, frequency or None, bias) among the loaded `trials`."""
    failed, frequency, bias = spec
    return next(
        k
        for k, t in enumerate(trials)
        if t.failed_joints == list(failed)
        and t.gait.frequency_deg_s == (frequency or Gait().frequency_deg_s)
        and t.gait.bias_deg == bias
    )


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
            f"{best}: {PROBE_SECONDS:g} s trials of that kind detect "
            + ", ".join(f"{k} of {v:.3g}" for k, v in strength.items())
            + " (sensor noise only)"
        )
    for a, b in pairs:
        found = telling_apart(study, a, b)
        if found is not None:
            kind, strengths = found
            cosine = subspace_cosine(study[kind][a]["columns"], study[kind][b]["columns"])
            text = (
                f"{kind} tells {a} and {b} apart (cosine {cosine:.2f}; what the other cannot mimic is detectable from "
                + ", ".join(f"{k} {v:.2g}" for k, v in strengths.items())
                + ")"
            )
            for c in [c for r in rounds for c in r.candidates if c.name in (a, b)]:
                c.experiment = text if c.experiment is None else c.experiment + "; " + text
                c.apart[b if c.name == a else a] = text


def apart_strengths(cols_a: np.ndarray, cols_b: np.ndarray) -> np.ndarray:
    """Per column of `cols_a`, the strength (in its probe units) at which its part that `cols_b`'s span cannot mimic
    reaches three standard errors; inf where none is left."""
    q, _ = np.linalg.qr(cols_b)
    rest = np.linalg.norm(cols_a - q @ (q.T @ cols_a), axis=0)
    return np.where(rest > 0, 3.0 / np.where(rest > 0, rest, 1.0), math.inf)


def telling_apart(study: dict, a: str, b: str):
    """(the probe kind that best tells candidates a and b apart, {coordinate: the strength from which what the other
    cannot mimic is detectable}), or None. Best: the smallest, over the kinds, of the larger of the two candidates'
    apart strengths, each relative to the strength at which its best kind detects it at all (units cancel; a kind
    that sees neither is never chosen for the angle between them alone)."""
    kinds = [k for k in study if min(np.linalg.norm(study[k][n]["columns"]) for n in (a, b)) > 0]
    if not kinds:
        return None
    best = {n: min(min(study[k][n]["detectable_strength"].values()) for k in kinds) for n in (a, b)}
    apart = {
        k: {n: apart_strengths(study[k][n]["columns"], study[k][m]["columns"]) for n, m in ((a, b), (b, a))}
        for k in kinds
    }
    kind = min(kinds, key=lambda k: max(float(apart[k][n].min()) / best[n] for n in (a, b)))
    names = {n: list(study[kind][n]["detectable_strength"]) for n in (a, b)}
    return kind, {c: float(v) for n in (a, b) for c, v in zip(names[n], apart[kind][n], strict=True)}
