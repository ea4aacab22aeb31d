"""Shared runs: the Drake runs are seconds each, so a test session makes each one once."""

import dataclasses

import pytest

from rc1_drake.config import Failure, Scenario
from rc1_drake.protocol import Session


class RunCache:
    """simulate() with one Session per Diagram build key and one run per distinct scenario."""

    def __init__(self):
        self._sessions = {}
        self._runs = {}

    def __call__(self, scenario: Scenario):
        key = repr(scenario)
        if key not in self._runs:
            from rc1_drake.diagram import build_key

            bk = build_key(scenario)
            if bk not in self._sessions:
                self._sessions[bk] = Session(scenario)
            self._runs[key] = self._sessions[bk].simulate(scenario)
        return self._runs[key]


@pytest.fixture(scope="session")
def simulate_cached():
    return RunCache()


@pytest.fixture(scope="session")
def nominal_scenario():
    return Scenario()


@pytest.fixture(scope="session")
def joint7_scenario():
    return Scenario(failures=[Failure(joint=7)])


def with_stop(scenario, **kwargs):
    return dataclasses.replace(scenario, stop=dataclasses.replace(scenario.stop, **kwargs))


def trial_samples(trial, keep):
    """`trial` with only the samples `keep` (a mask or a slice) of its time series."""
    cut = {k: getattr(trial, k)[keep] for k in ("t", "q", "head_yaw_rate")}
    if trial.camera is not None:
        cut["camera"] = trial.camera[keep]
    return dataclasses.replace(trial, **cut)


def first_seconds(trial, seconds):
    """`trial`'s samples up to `seconds` from its start."""
    return trial_samples(trial, trial.t - trial.t[0] <= seconds)
