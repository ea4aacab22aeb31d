"""Evaluating a model on a campaign: each worker process keeps one Replayer per trial (its Diagram,
Simulator and smoothed reference, built once), and maps a function over the trials in this process or on
the executor (executor.py).
"""

import numpy as np

from ..config import Friction
from ..engine import default_engine
from ..replay import Replayer

_REPLAYERS: dict = {}  # per worker process: trial source -> Replayer (its Diagram and reference)


def replayer(trial):
    """This process's Replayer of `trial` (built once: its Diagram, Simulator and reference)."""
    key = (default_engine(), str(trial.source or trial.trial_id))
    if key not in _REPLAYERS:
        _REPLAYERS[key] = Replayer(trial)
    replayer = _REPLAYERS[key]
    if not _same(replayer.trial.initial_head_rates, trial.initial_head_rates):  # a fit moves a trial's start
        replayer.use_start(trial.initial_head_rates)
    return replayer


def _same(a, b) -> bool:
    return (a is None and b is None) or (a is not None and b is not None and np.array_equal(a, b))


def replay(trial, friction: Friction, effects=None):
    """Replay `trial`, reusing this process's Replayer for it."""
    return replayer(trial).run(friction, effects)


def map_trials(function, trials, friction, effects, executor) -> list:
    """function(trial, friction, effects) for every trial, in this process or on the executor."""
    if executor is None:
        return [function(t, friction, effects) for t in trials]
    return [f.result() for f in [executor.submit(function, t, friction, effects) for t in trials]]
