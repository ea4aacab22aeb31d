"""The failure sweep (paper section 4): no failure and each joint failed in turn, several trials each,
run through an executor, streamed to disk a row per run, resumable.

A row holds the run's summary (outcome, final head position, drift, revolutions, circle diameter,
time to the line) and its head path decimated to 0.1 s. A run that raises or diverges is recorded
with status "error" and its message; the sweep goes on.
"""

import dataclasses
import hashlib
import json
import math
import os
import sys
from concurrent.futures import as_completed
from pathlib import Path

import numpy as np

from .config import Failure, Friction, Gait, Numerics, Rc1Error, Scenario, Servo, Start, Stop
from .metrics import summarize
from .progress import Counter
from .scenarios import validate

PATH_PERIOD_S = 0.1


@dataclasses.dataclass(frozen=True)
class SweepJob:
    label: str  # the case: "none", "J7", "J7 locked", "J3+J9", ...
    trial: int
    scenario: Scenario

    @property
    def key(self) -> str:
        """Stable identity of the run, for resuming."""
        return hashlib.sha1(repr((self.label, self.trial, self.scenario)).encode()).hexdigest()[:16]


def case_label(failures: list[Failure]) -> str:
    if not failures:
        return "none"
    joints = "+".join(f"J{f.joint}" for f in failures)
    modes = {f.mode for f in failures}
    timing = {f.time_s for f in failures}
    suffix = "" if modes == {"free"} else " " + "/".join(sorted(modes))
    return joints + suffix + ("" if timing == {0.0} else f" @{max(timing):g}s")


def make_jobs(
    *,
    failure_sets,
    trials=5,
    seed=0,
    phase_jitter_deg=5.0,
    position_jitter_m=0.01,
    heading_jitter_deg=1.0,
    friction=None,
    friction_spread=0.0,
    bias_deg=0.0,
    stop=None,
    numerics=None,
    effects=None,
    servo=None,
) -> list[SweepJob]:
    """Jobs for each failure set (a list of Failures; [] for none) times `trials`, with the start
    phase and pose drawn around the protocol's, and optionally each friction coefficient drawn
    uniformly within +-friction_spread (a fraction) of its value."""
    rng = np.random.default_rng(seed)
    friction = friction or Friction()
    stop, numerics = stop or Stop(), numerics or Numerics()
    jobs = []
    for failures in failure_sets:
        for k in range(trials):
            drawn = friction
            if friction_spread:
                drawn = Friction(
                    **{
                        f.name: getattr(friction, f.name) * (1 + rng.uniform(-friction_spread, friction_spread))
                        for f in dataclasses.fields(Friction)
                    }
                )
            scenario = Scenario(
                gait=Gait(phase_offset_deg=float(rng.normal(0, phase_jitter_deg)), bias_deg=bias_deg),
                servo=servo or Servo(),
                friction=drawn,
                failures=list(failures),
                effects=dict(effects or {}),
                start=Start(
                    x_m=float(rng.normal(0, position_jitter_m)),
                    y_m=float(rng.normal(0, position_jitter_m)),
                    heading_deg=float(rng.normal(0, heading_jitter_deg)),
                ),
                stop=stop,
                numerics=numerics,
            )
            jobs.append(SweepJob(label=case_label(list(failures)), trial=k + 1, scenario=scenario))
    return jobs


_SESSIONS: dict = {}  # per worker process: one Session per Diagram build key


def simulate_job(job: SweepJob):
    """The job's Run, simulated in this process on a Session kept per Diagram; Rc1Error if it diverges."""
    from .diagram import build_key
    from .engine import default_engine, make_session

    scenario = validate(job.scenario, where=f"sweep job {job.label} trial {job.trial}")
    key = (default_engine(), build_key(scenario))
    if key not in _SESSIONS:
        _SESSIONS[key] = make_session(scenario)
    run = _SESSIONS[key].simulate(scenario)
    if not np.isfinite(run.state).all():
        raise Rc1Error("the run diverged (non-finite state)")
    return run


def run_job(job: SweepJob) -> dict:
    """Simulate one job in this process (reusing its Diagrams); never raises: errors become rows."""
    row = {
        "key": job.key,
        "label": job.label,
        "trial": job.trial,
        "failed_joints": [f.joint for f in job.scenario.failures],
        "modes": [f.mode for f in job.scenario.failures],
        "bias_deg": job.scenario.gait.bias_deg,
        "friction": dataclasses.asdict(job.scenario.friction),
    }
    try:
        run = simulate_job(job)
    except Exception as e:  # noqa: BLE001 - a failed run is data: record it and go on
        return {**row, "status": "error", "error": f"{type(e).__name__}: {' '.join(str(e).split())}"}
    summary = summarize(run).to_json()
    start = run.head_xy[0]
    progress_x = float(run.head_xy[-1, 0] - start[0])
    step = max(1, int(round(PATH_PERIOD_S / max(run.scenario.numerics.log_period_s, 1e-9))))
    path = np.vstack([run.head_xy[::step], run.head_xy[-1:]])
    return {
        **row,
        "status": "ok",
        **summary,
        "progress_x_m": progress_x,
        "drift_per_m": summary["lateral_drift_m"] / summary["distance_travelled_m"]
        if summary["distance_travelled_m"] > 0.05
        else None,
        "time_to_line_s": summary["t_final_s"] if summary["outcome"] == "crossed" else None,
        "path": np.round(path, 4).tolist(),
    }


def read_rows(path) -> list[dict]:
    path = Path(path)
    if not path.is_file():
        return []
    rows = []
    with open(path) as f:
        for number, line in enumerate(f, start=1):
            if not line.strip():
                continue
            try:
                rows.append(json.loads(line))
            except json.JSONDecodeError:
                raise Rc1Error(f"{path}: line {number}: not a JSON row (delete the line to redo its run)") from None
    return rows


def run_sweep(jobs: list[SweepJob], results_path, *, executor, progress: bool = True) -> list[dict]:
    """Run the jobs not yet in `results_path` (JSON lines), appending a row as each finishes.
    Returns the rows of all `jobs` (earlier and new), in job order."""
    results_path = Path(results_path)
    results_path.parent.mkdir(parents=True, exist_ok=True)
    done = {row["key"]: row for row in read_rows(results_path)}
    todo = [job for job in jobs if job.key not in done]
    bar = count = None
    finished = len(jobs) - len(todo)
    if progress and sys.stderr.isatty():
        from tqdm import tqdm

        bar = tqdm(total=len(jobs), initial=len(jobs) - len(todo), unit="run", desc="sweep", dynamic_ncols=True)
    elif progress:  # a log: a line every few seconds
        count = Counter("sweep: runs")
    with open(results_path, "a") as out:
        futures = {executor.submit(run_job, job): job for job in todo}
        for future in as_completed(futures):
            job = futures[future]
            try:
                row = future.result()
            except Exception as e:  # noqa: BLE001 - the worker itself died
                row = {
                    "key": job.key,
                    "label": job.label,
                    "trial": job.trial,
                    "status": "error",
                    "error": f"{type(e).__name__}: {' '.join(str(e).split())}",
                }
            out.write(json.dumps(row) + "\n")
            out.flush()
            os.fsync(out.fileno())
            done[job.key] = row
            if bar:
                bar.update(1)
            elif count:
                finished += 1
                count(finished, len(jobs), job.label)
    if bar:
        bar.close()
    return [done[job.key] for job in jobs]


def summarize_sweep(rows: list[dict]) -> list[dict]:
    """One line per case: outcomes, mean final position, drift per metre, circling figures."""
    cases: dict = {}
    for row in rows:
        cases.setdefault(row["label"], []).append(row)
    table = []
    for label, rs in cases.items():
        ok = [r for r in rs if r["status"] == "ok"]
        outcomes = {}
        for r in ok:
            outcomes[r["outcome"]] = outcomes.get(r["outcome"], 0) + 1

        def mean(key, of=ok):
            values = [r[key] for r in of if r.get(key) is not None]
            return float(np.mean(values)) if values else None

        circling = [r for r in ok if r["outcome"] == "circling"]
        table.append(
            {
                "label": label,
                "failed_joints": rs[0].get("failed_joints", []),
                "runs": len(rs),
                "errors": len(rs) - len(ok),
                "outcomes": outcomes,
                "final_x_m": float(np.mean([r["final_head_xy_m"][0] for r in ok])) if ok else None,
                "final_y_m": float(np.mean([r["final_head_xy_m"][1] for r in ok])) if ok else None,
                "drift_per_m": mean("drift_per_m"),
                "drift_per_m_sd": float(np.std([r["drift_per_m"] for r in ok if r["drift_per_m"] is not None]))
                if any(r["drift_per_m"] is not None for r in ok)
                else None,
                "time_to_line_s": mean("time_to_line_s"),
                "revolutions": mean("revolutions", circling),
                "circle_diameter_m": mean("circle_diameter_m", circling),
            }
        )
    return table


def half_summary(table: list[dict]) -> dict:
    """The paper's conclusion in numbers: single free failures in the front half (joints 1-6) against
    the rear half (8-13): share of runs that reached the line, mean |drift per metre|."""
    out = {}
    for name, joints in (("front (J1-J6)", range(1, 7)), ("rear (J8-J13)", range(8, 14))):
        rows = [
            t
            for t in table
            if len(t["failed_joints"]) == 1 and t["failed_joints"][0] in joints and " " not in t["label"]
        ]
        runs = sum(t["runs"] - t["errors"] for t in rows)
        crossed = sum(t["outcomes"].get("crossed", 0) for t in rows)
        drifts = [abs(t["drift_per_m"]) for t in rows if t["drift_per_m"] is not None]
        out[name] = {
            "runs": runs,
            "crossed_fraction": crossed / runs if runs else None,
            "mean_abs_drift_per_m": float(np.mean(drifts)) if drifts else None,
        }
    return out


def format_table(table: list[dict]) -> str:
    def f(v, fmt):
        width = int(fmt.split(".")[0])
        return f"{'-':>{width}}" if v is None or (isinstance(v, float) and not math.isfinite(v)) else format(v, fmt)

    lines = [
        f"{'case':<16}{'runs':>5}{'outcomes':>26}{'final x':>9}{'final y':>9}{'drift/m':>9}"
        f"{'to line s':>10}{'revs':>6}{'diam m':>8}"
    ]
    for t in table:
        outcomes = ", ".join(f"{n} {k}" for k, n in sorted(t["outcomes"].items())) + (
            f", {t['errors']} error" if t["errors"] else ""
        )
        lines.append(
            f"{t['label']:<16}{t['runs']:>5}{outcomes:>26}{f(t['final_x_m'], '9.2f')}{f(t['final_y_m'], '9.2f')}"
            f"{f(t['drift_per_m'], '9.3f')}{f(t['time_to_line_s'], '10.1f')}{f(t['revolutions'], '6.2f')}"
            f"{f(t['circle_diameter_m'], '8.2f')}"
        )
    return "\n".join(lines)


def single_failure_sets(joints=range(1, 14), *, mode="free", time_s=0.0, include_none=True) -> list:
    sets = [[]] if include_none else []
    return sets + [[Failure(joint=j, mode=mode, time_s=time_s)] for j in joints]


def double_failure_sets(joints=range(1, 14), *, mode="free") -> list:
    return [
        [Failure(joint=a, mode=mode), Failure(joint=b, mode=mode)]
        for i, a in enumerate(joints)
        for b in list(joints)[i + 1 :]
    ]
