"""Two engines, one model: the Drake Diagram (diagram.py, the model of record) and its compiled twin
(this package: the same step as numba kernels, tests/test_engine.py holds them together).

`make_session(scenario, engine=...)` returns either's session; both take the same Scenario and return
the same protocol.Run. Batch work (replays, fits, sweeps, campaigns) uses `default_engine()`, which
`use_engine()` sets for this process and the worker processes it starts (through the environment).
"""

from __future__ import annotations

import contextlib
import os

ENGINES = ("drake", "compiled")
_VARIABLE = "RC1_ENGINE"


def default_engine() -> str:
    """The engine of batch work: $RC1_ENGINE if set (drake or compiled), else compiled."""
    engine = os.environ.get(_VARIABLE, "compiled")
    if engine not in ENGINES:
        raise ValueError(f"${_VARIABLE}: unknown engine '{engine}' (known: {', '.join(ENGINES)})")
    return engine


def use_engine(engine: str) -> None:
    """Make `engine` the default of batch work here and in worker processes started from now on."""
    if engine not in ENGINES:
        raise ValueError(f"unknown engine '{engine}' (known: {', '.join(ENGINES)})")
    os.environ[_VARIABLE] = engine


@contextlib.contextmanager
def engine_for(engine: str):
    """`engine` the default of batch work (use_engine) while the block runs, the previous default after: a command
    run in-process (a test, a benchmark) leaves the process's engine as it found it."""
    previous = os.environ.get(_VARIABLE)
    use_engine(engine)
    try:
        yield
    finally:
        if previous is None:
            os.environ.pop(_VARIABLE, None)
        else:
            os.environ[_VARIABLE] = previous


def make_session(scenario, *, engine: str | None = None, joint_reference=None):
    """A session (`.simulate(scenario, initial=None) -> Run`) on `engine` (default: default_engine()).
    `joint_reference` (replay.JointReference) makes the servos follow it instead of the gait."""
    engine = engine or default_engine()
    if engine == "drake":
        from ..protocol import Session

        return Session(scenario, joint_reference=joint_reference)
    if engine == "compiled":
        from .session import CompiledSession

        return CompiledSession(joint_reference=joint_reference)
    raise ValueError(f"unknown engine '{engine}' (known: {', '.join(ENGINES)})")
