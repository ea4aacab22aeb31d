"""Evaluating a model on a campaign: each worker process keeps one Replayer per trial (its Diagram,
Simulator and smoothed reference, built once); batches of jobs run in this process or on the executor
(executor.py), counted, and with a Checkpoint every result is kept on disk as it arrives, so that a long job
interrupted resumes where it stopped.
"""

import hashlib
import pickle
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ..config import Friction, Rc1Error
from ..engine import default_engine
from ..replay import Replayer
from .records import encode, read_records

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


# The diagnosis's modules that decide from results and compute none of a checkpointed job's (no job function imports
# them: tests/test_diagnose.py checks it): a rule changed there reuses the replays on disk (paper_rates.py --variant).
DECISION_ONLY = tuple(
    f"diagnose/{name}.py"
    for name in ("decide", "fit", "loop", "report", "scatter", "significance", "thresholds", "verdict")
)


def code_version() -> str:
    """A hash of the package's source files but DECISION_ONLY: results computed by other code are never taken from a
    checkpoint."""
    digest = hashlib.sha256()
    root = Path(__file__).resolve().parents[1]
    for path in sorted(root.rglob("*.py")):
        if path.relative_to(root).as_posix() not in DECISION_ONLY:
            digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


class Checkpoint:
    """Results of jobs on disk, by the job's content and this code's version: one file of records (sysid.records:
    arrays and JSON, which load without running code), appended and flushed as each result arrives. A record cut short
    by an interruption is dropped. A folder holding an older version's pickled checkpoint is refused."""

    def __init__(self, folder):
        folder = Path(folder)
        for old in sorted(folder.glob("results-*.pkl")) if folder.is_dir() else []:
            raise Rc1Error(
                f"{old}: a checkpoint of an older rc1 (pickled results, which could run code as they load): delete it "
                "and run again"
            )
        self.path = folder / f"results-{code_version()}.records"
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.results: dict = read_records(self.path) if self.path.exists() else {}
        self.loaded = set(self.results)  # what an earlier, interrupted run left
        self.resumed = 0  # results of an earlier run taken by this one (not this run's own, asked for again)

    @staticmethod
    def key(function, job) -> str:
        digest = hashlib.sha256(f"{function.__module__}.{function.__qualname__}".encode())
        digest.update(pickle.dumps(job, protocol=5))
        return digest.hexdigest()

    def put(self, key: str, value) -> None:
        self.results[key] = value
        with open(self.path, "ab") as f:
            f.write(encode(key, value))

    def take(self, key: str):
        self.resumed += key in self.loaded
        return self.results[key]

    @staticmethod
    def discard(folder) -> None:
        """Delete this code's checkpoint in `folder` (the job finished: its results are in its output), and the folder
        if nothing else is in it, and then its parent if that is an empty `checkpoints` (the commands' default)."""
        folder = Path(folder)
        (folder / f"results-{code_version()}.records").unlink(missing_ok=True)
        for empty in (folder, folder.parent) if folder.parent.name == "checkpoints" else (folder,):
            try:
                empty.rmdir()
            except OSError:
                return  # other files are there (another code version's checkpoint, the user's): left alone


class Evaluator:
    """Runs batches of jobs, function(*job), in this process or on an executor, counting them; with a
    `checkpoint`, a job whose result is on disk is not run again, and every new result goes there."""

    def __init__(self, executor, progress: Callable[[str], None] | None = None, checkpoint: Checkpoint | None = None):
        self.executor, self.progress, self.checkpoint, self.simulations = executor, progress, checkpoint, 0

    def map(self, function, jobs, what: str, *, keep: bool = True) -> list:
        """[function(*job) for job in jobs]; `keep`: through the checkpoint (not for results too large to keep)."""
        if self.progress:
            self.progress(f"{what}: {len(jobs)} replays")
        self.simulations += len(jobs)
        store = self.checkpoint if keep else None
        keys = [store.key(function, job) for job in jobs] if store else [None] * len(jobs)
        results = [store.take(k) if store and k in store.results else None for k in keys]
        todo = [i for i, k in enumerate(keys) if not (store and k in store.results)]
        if self.executor is None:
            done = ((i, function(*jobs[i])) for i in todo)
        else:
            futures = [(i, self.executor.submit(function, *jobs[i])) for i in todo]
            done = ((i, f.result()) for i, f in futures)
        for i, value in done:
            results[i] = value
            if store:
                store.put(keys[i], value)
        return results
