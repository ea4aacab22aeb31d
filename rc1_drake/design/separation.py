"""The criterion of the next experiment (issue 68): how far apart two hypotheses' predictions of a set of trials
are, in the noise's units, once the rival has refitted what it is free to — a T-optimal distance (Atkinson & Fedorov
1975), linearized as the diagnosis linearizes (diagnose.linearize).

For hypotheses a and b and a trial design, a's trial is synthesized without sensor noise (this model driven by the
gait through its servos); b replays it (the measured angles, its friction and effects) with its nuisances free —
each trial's start, the friction coefficients the campaign identifies, b's own effects' strengths — and the
distance is the weighted sum of squares b cannot fit away (diagnose.fit: bounded, each start profiled on its
first 0.5 s). The weights hold the replay's own error on that motion (the twin bootstrap on a copy with the lab's
potentiometer noise). On noisy data the expected -2 log likelihood ratio for a against b is that distance, so a
pair is told apart with probability about Phi(sqrt(d) / 2)."""

import dataclasses
import math
import tempfile
from pathlib import Path

from ..config import Rc1Error
from ..diagnose.fit import fit
from ..diagnose.linearize import Linearization, linearize, replay_errors, trial_weights
from ..diagnose.scatter import failed_joint_scatter
from ..measurements import load_campaign
from ..synthesize import Noise, Variation, synthesize_campaign
from .hypotheses import Hypothesis
from .lab import Lab, TrialDesign

BOOTSTRAP_DRAWS = 3  # the replay's own error per designed trial: fewer than the diagnosis's 6, one design of many


def synthesized_trial(design: TrialDesign, hypothesis: Hypothesis, lab: Lab, noisy: bool, seed: int, label: str):
    """`design` run by `hypothesis` (this model, through its servos, from the origin heading +x), measured at the
    lab's sample period with no sensor noise (`noisy`: with the lab's potentiometer noise, the other sensors' at
    their defaults), its camera always seeing the head; the trial named `label`. Where the run's measurements fail
    the loader's checks (a joint that jumps faster than a servo moves: the servos cannot follow that gait), why, in
    place of the trial."""
    noise = Noise(potentiometer_deg=lab.potentiometer_deg) if noisy else Noise().scaled(0.0)
    with tempfile.TemporaryDirectory() as tmp:
        synthesize_campaign(
            tmp,
            design=[design.case()],
            friction=hypothesis.friction,
            effects=hypothesis.effects,
            noise=dataclasses.replace(noise, camera_dropout=0.0),
            variation=Variation(0.0, 0.0, 0.0),
            stop=design.stop(),
            sample_period_s=lab.sample_period_s,
            seed=seed,
        )
        try:
            (trial,) = load_campaign(Path(tmp)).trials
        except Rc1Error as error:
            return "its run fails the measurement checks: " + str(error).split(": ", 1)[-1]
    return dataclasses.replace(trial, trial_id=label)


def rival_linearization(
    data, noisy, rival: Hypothesis, free: list[str], evaluator, scatter: float = 0.0, measured: bool = False
):
    """`rival` linearized on the trials `data` (one hypothesis's, noise-free), its columns for each trial's start,
    the `free` friction coefficients and its own effects, each trial weighed by the replay's own error measured on
    its `noisy` copy at the rival's model (BOOTSTRAP_DRAWS draws) and, with `scatter` (tau, the diagnosis's), by the
    failed joint's scatter as the diagnosis weighs its trials (diagnose.scatter): a failed-joint trial tells what
    the scatter leaves of it, not what the sensors alone would. `measured`: `data` are noisy (the plan's check): the
    replay's own error is measured on them, at the starts the residuals are taken at, and its bias taken off, as the
    diagnosis does (linearize; noise-free data have none to take off)."""
    held = [n for n in dataclasses.asdict(rival.friction) if n not in free]
    common = dict(held=held, starts=True)
    if measured:
        lin = linearize(data, rival.friction, rival.effects, list(rival.owned), evaluator,
                        input_noise_samples=BOOTSTRAP_DRAWS, **common)  # fmt: skip
    else:
        _, noise, _, _ = replay_errors(noisy, rival.friction, rival.effects, evaluator, BOOTSTRAP_DRAWS)
        lin = linearize(data, rival.friction, rival.effects, list(rival.owned), evaluator, noise=noise, **common)
    if scatter > 0.0 and any(t.failed_joints for t in data):
        lin = failed_joint_scatter(lin, evaluator).weighing(lin, scatter)
    return lin


def subset(lin: Linearization, indices: list[int]) -> Linearization:
    """`lin` over the trials `indices` only (their starts renumbered, the others' dropped)."""
    where = {k: n for n, k in enumerate(indices)}
    coords = [
        dataclasses.replace(c, start_of=(where[c.start_of[0]], c.start_of[1])) if c.start_of else c
        for c in lin.coordinates
        if c.start_of is None or c.start_of[0] in where
    ]
    pick = lambda values: None if values is None else [values[k] for k in indices]  # noqa: E731
    names = {c.name for c in coords}
    return dataclasses.replace(
        lin,
        trials=pick(lin.trials),
        coordinates=coords,
        r0=pick(lin.r0),
        eq6=pick(lin.eq6),
        yaw_fit=pick(lin.yaw_fit),
        columns={n: pick(v) for n, v in lin.columns.items() if n in names},
        noise=pick(lin.noise),
        weights=trial_weights(pick(lin.trials), pick(lin.noise), pick(lin.scatter)),
        bias=pick(lin.bias),
        w0=pick(lin.w0),
        wcolumns={n: pick(v) for n, v in lin.wcolumns.items() if n in names},
        start_bias=pick(lin.start_bias),
        draws=pick(lin.draws),
        scatter=pick(lin.scatter),
    )


def distance(lin: Linearization, indices: list[int]) -> float:
    """What the rival of `lin` cannot fit away on the trials `indices`: the weighted sum of squares at its fit of
    every coordinate it has (starts, free friction, its own effects)."""
    if not indices:
        return 0.0
    part = subset(lin, indices)
    names = [c.name for c in part.coordinates]
    return part.weighted_sum_of_squares(fit(part, names).residual) if names else part.weighted_sum_of_squares(part.r0)


def told_apart(d: float) -> float:
    """The probability that a likelihood-ratio choice between two simple hypotheses d apart (squared, in the
    noise's units) picks the true one: Phi(sqrt(d) / 2)."""
    return 0.5 * (1.0 + math.erf(math.sqrt(max(d, 0.0)) / (2.0 * math.sqrt(2.0))))
