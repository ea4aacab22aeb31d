"""The measurement format (data/README.md): a strict loader and a writer.

A campaign is a folder of trials; a trial is `<stem>.json` (what was done and the hand-measured end)
plus `<stem>.csv` (sampled signals). Every error is one line naming the file, the line or key, and
what is wrong; a campaign with any bad trial does not load at all.
"""

import csv
import dataclasses
import json
import math
import os
from pathlib import Path

import numpy as np

from .config import JOINT_LIMIT_DEG, NUM_JOINTS, Gait, Rc1Error

JOINT_COLUMNS = tuple(f"q{i}_rad" for i in range(1, NUM_JOINTS + 1))
REQUIRED_COLUMNS = ("t_s",) + JOINT_COLUMNS + ("head_yaw_rate_rad_s",)
CAMERA_COLUMNS = ("head_x_m", "head_y_m", "head_yaw_rad")
GAIT_KEYS = ("amplitude_deg", "frequency_deg_s", "phase_step_deg", "phase_offset_deg", "bias_deg")
STOP_TYPES = {"line": "line_x_m", "revolutions": "count", "time": "t_s"}
JSON_KEYS = {
    "trial_id",
    "failed_joints",
    "gait",
    "stop",
    "initial_head_pose",
    "final_head_xy_m",
    "notes",
    "initial_head_rates",
}
OPTIONAL_JSON_KEYS = ("notes", "initial_head_rates")
POSE_KEYS = ("x_m", "y_m", "yaw_rad")
RATE_KEYS = ("vx_m_s", "vy_m_s", "yaw_rate_rad_s")

# Tolerances of the checks (documented in data/README.md).
JOINT_TOLERANCE_DEG = 3.0  # measured joint angles may exceed +-38 deg by this much (noise, linkage play)
DEGREES_HINT_RAD = 1.5  # a joint angle above this (86 deg) in a _rad column is taken for degrees
# A joint's sample-to-sample change above JUMP_TOLERANCE_DEG + JUMP_SPEED_FACTOR x the servo's top speed
# (140 deg/s, paper Sec. 2) x the step is no motion of the joint: a glitch or a swapped column.
SERVO_SPEED_DEG_S = 140.0
JUMP_SPEED_FACTOR = 3.0
JUMP_TOLERANCE_DEG = 5.0
YAW_RATE_HINT_RAD_S = 30.0  # a head yaw rate above this in rad/s is taken for deg/s
SAMPLING_TOLERANCE = 0.01  # every time step within 1% of the median step


@dataclasses.dataclass(frozen=True)
class Stop:
    type: str  # line | revolutions | time
    value: float  # line_x_m, count or t_s

    def to_json(self) -> dict:
        return {"type": self.type, STOP_TYPES[self.type]: self.value}


@dataclasses.dataclass
class Trial:
    trial_id: str
    failed_joints: list[int]  # 1-based
    gait: Gait
    stop: Stop
    initial_head_pose: np.ndarray  # (3,) x_m, y_m, yaw_rad
    final_head_xy: np.ndarray  # (2,) measured by hand at the end
    t: np.ndarray  # (N,) s, evenly sampled
    q: np.ndarray  # (N, 13) rad; NaN in the columns of failed joints
    head_yaw_rate: np.ndarray  # (N,) rad/s
    camera: np.ndarray | None = None  # (N, 3) x_m, y_m, yaw_rad; NaN where the camera missed the head
    notes: str = ""
    source: Path | None = None  # the JSON file it came from
    # joint (1-based) -> its largest reading (deg, signed) where it passes the limit and the tolerance: a
    # measurement to explain (a potentiometer's offset or gain error), loaded with a warning
    beyond_limit: dict[int, float] = dataclasses.field(default_factory=dict)
    # (3,) the head's vx, vy (m/s) and yaw rate (rad/s) at t = 0, where the data give them (an optional key) or
    # a fit set them (diagnose.coordinates.start_coordinates); None: not known
    initial_head_rates: np.ndarray | None = None

    @property
    def case(self) -> str:
        """The paper's case label (Table 2 rows), from the trial's content: 'none', 'J7', 'J7+bias'."""
        label = "+".join(f"J{j}" for j in self.failed_joints) or "none"
        return label + ("+bias" if self.gait.bias_deg != 0.0 else "")

    @property
    def working_joints(self) -> list[int]:
        return [j for j in range(1, NUM_JOINTS + 1) if j not in self.failed_joints]


@dataclasses.dataclass
class Campaign:
    path: Path
    trials: list[Trial]

    def cases(self) -> dict:
        """Trials grouped by case, in order of first appearance."""
        out: dict = {}
        for trial in self.trials:
            out.setdefault(trial.case, []).append(trial)
        return out

    def warnings(self) -> list[str]:
        """What the loader took in but the model cannot do, once per joint: readings past the joint limit."""
        return limit_warnings(self.trials)

    def chosen(self, trial_ids=None) -> list[Trial]:
        """The trials with these ids (all when None), in the campaign's order; Rc1Error for an id it lacks."""
        missing = sorted(set(trial_ids or []) - {t.trial_id for t in self.trials})
        if missing:
            raise Rc1Error(f"{self.path}: no trial '{missing[0]}' in the campaign")
        return [t for t in self.trials if trial_ids is None or t.trial_id in trial_ids]


def merged_campaigns(folders) -> Campaign:
    """Several campaign folders as one (a campaign and the trials a plan added to it, rc1 design): named after
    the first; a trial id taken twice is prefixed by its folder's name from its second folder on (and by the
    folder's place among them where folders share a name)."""
    if len({Path(f).resolve() for f in folders}) < len(folders):
        raise Rc1Error(f"{', '.join(map(str, folders))}: a campaign folder is given twice")
    campaigns = [load_campaign(f) for f in folders]
    if len(campaigns) == 1:
        return campaigns[0]
    trials, seen = [], set()
    for k, campaign in enumerate(campaigns, 1):
        for trial in campaign.trials:
            name, trial_id = Path(campaign.path).name, trial.trial_id
            if trial_id in seen:
                trial_id = f"{name}-{trial.trial_id}"
            if trial_id in seen:  # folders of one name: their place among them too
                trial_id = f"{name}{k}-{trial.trial_id}"
            if trial_id in seen:
                raise Rc1Error(f"{campaign.path}: trial {trial.trial_id} is in two of the folders given")
            seen.add(trial_id)
            trials.append(dataclasses.replace(trial, trial_id=trial_id))
    return Campaign(path=campaigns[0].path, trials=trials)


def limit_warnings(trials) -> list[str]:
    """One line per joint whose readings pass its limit (Trial.beyond_limit) in any of `trials`."""
    lines = []
    for joint in range(1, NUM_JOINTS + 1):
        seen = [(t.trial_id, t.beyond_limit[joint]) for t in trials if joint in t.beyond_limit]
        if seen:
            peak = max((v for _, v in seen), key=abs)
            lines.append(
                f"joint {joint}'s potentiometer reads up to {peak:+.1f} deg, past the +-{JOINT_LIMIT_DEG:g} deg "
                f"limit, in {len(seen)} trial(s) ({', '.join(i for i, _ in seen[:3])}"
                f"{', ...' if len(seen) > 3 else ''}): an offset or gain error? Loaded as measured"
            )
    return lines


def _fail(path, where, problem):
    raise Rc1Error(f"{path}: {where}: {problem}")


def _number(path, where, value, *, positive=False):
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        _fail(path, where, f"expected a number, got {json.dumps(value)}")
    if not math.isfinite(value):
        _fail(path, where, f"must be finite, got {value}")
    if positive and value <= 0:
        _fail(path, where, f"must be > 0, got {value}")
    return float(value)


def _mapping(path, where, value, keys, *, optional=()):
    if not isinstance(value, dict):
        _fail(path, where, f"expected an object with keys {', '.join(keys)}")
    missing = [k for k in keys if k not in value]
    if missing:
        _fail(path, f"{where}.{missing[0]}" if where else missing[0], "missing")
    unknown = sorted(set(value) - set(keys) - set(optional))
    if unknown:
        _fail(path, f"{where}.{unknown[0]}" if where else unknown[0], "unknown key")
    return value


def _load_json(path: Path) -> dict:
    try:
        data = json.loads(path.read_text())
    except json.JSONDecodeError as e:
        _fail(path, f"line {e.lineno}", f"not valid JSON: {e.msg}")
    except UnicodeDecodeError:
        _fail(path, "file", "not a text file")
    required = sorted(JSON_KEYS - set(OPTIONAL_JSON_KEYS))
    data = _mapping(path, "", data, required, optional=OPTIONAL_JSON_KEYS)
    trial_id = data["trial_id"]
    if not isinstance(trial_id, str) or not trial_id:
        _fail(path, "trial_id", "expected a non-empty string")
    failed = data["failed_joints"]
    if not isinstance(failed, list) or any(isinstance(j, bool) or not isinstance(j, int) for j in failed):
        _fail(path, "failed_joints", "expected a list of joint numbers, e.g. [] or [7]")
    for j in failed:
        if not 1 <= j <= NUM_JOINTS:
            _fail(path, "failed_joints", f"joint {j} does not exist (joints are 1..{NUM_JOINTS})")
    if len(set(failed)) != len(failed):
        _fail(path, "failed_joints", "a joint is listed twice")
    gait = _mapping(path, "gait", data["gait"], GAIT_KEYS)
    gait = Gait(**{k: _number(path, f"gait.{k}", gait[k]) for k in GAIT_KEYS})
    stop = data["stop"]
    if not isinstance(stop, dict) or "type" not in stop:
        _fail(path, "stop", 'expected {"type": ..., ...}')
    if stop["type"] not in STOP_TYPES:
        _fail(path, "stop.type", f"unknown stop type {json.dumps(stop['type'])} (known: {', '.join(STOP_TYPES)})")
    key = STOP_TYPES[stop["type"]]
    _mapping(path, "stop", stop, ("type", key))
    stop = Stop(stop["type"], _number(path, f"stop.{key}", stop[key], positive=stop["type"] != "line"))
    pose = _mapping(path, "initial_head_pose", data["initial_head_pose"], POSE_KEYS)
    pose = np.array([_number(path, f"initial_head_pose.{k}", pose[k]) for k in POSE_KEYS])
    final = data["final_head_xy_m"]
    if not isinstance(final, list) or len(final) != 2:
        _fail(path, "final_head_xy_m", "expected [x, y]")
    final = np.array([_number(path, f"final_head_xy_m[{i}]", v) for i, v in enumerate(final)])
    notes = data.get("notes", "")
    if not isinstance(notes, str):
        _fail(path, "notes", "expected a string")
    rates = None
    if "initial_head_rates" in data:
        given = _mapping(path, "initial_head_rates", data["initial_head_rates"], RATE_KEYS)
        rates = np.array([_number(path, f"initial_head_rates.{k}", given[k]) for k in RATE_KEYS])
    return dict(
        trial_id=trial_id,
        failed_joints=sorted(failed),
        gait=gait,
        stop=stop,
        initial_head_pose=pose,
        final_head_xy=final,
        notes=notes,
        initial_head_rates=rates,
    )


def _read_table(path: Path) -> tuple[list, np.ndarray]:
    """The CSV's header, checked against the columns a trial has, and its cells as numbers (NaN where empty)."""
    try:
        with open(path, newline="") as f:
            rows = list(csv.reader(f))
    except UnicodeDecodeError:
        _fail(path, "file", "not a text file")
    if not rows:
        _fail(path, "line 1", "empty file, expected a header row")
    header = [h.strip() for h in rows[0]]
    missing = [c for c in REQUIRED_COLUMNS if c not in header]
    if missing:
        _fail(path, "line 1", f"missing column {missing[0]}")
    unknown = [c for c in header if c not in REQUIRED_COLUMNS + CAMERA_COLUMNS]
    if unknown:
        _fail(path, "line 1", f"unknown column {unknown[0]!r}")
    if len(set(header)) != len(header):
        _fail(path, "line 1", "a column appears twice")
    camera = [c for c in CAMERA_COLUMNS if c in header]
    if camera and len(camera) != len(CAMERA_COLUMNS):
        _fail(path, "line 1", f"camera columns come together: {', '.join(CAMERA_COLUMNS)}")
    body = rows[1:]
    if len(body) < 2:
        _fail(path, "line 2", f"{len(body)} sample(s); at least 2 are needed")
    values = np.full((len(body), len(header)), np.nan)
    for r, row in enumerate(body):
        line = r + 2
        if len(row) != len(header):
            _fail(path, f"line {line}", f"{len(row)} cells, the header has {len(header)}")
        for c, cell in enumerate(row):
            cell = cell.strip()
            if cell == "":
                continue
            try:
                value = float(cell)
            except ValueError:
                _fail(path, f"line {line}, column {header[c]}", f"not a number: {cell!r}")
            if not math.isfinite(value):
                _fail(path, f"line {line}, column {header[c]}", f"{cell} is not a finite number")
            values[r, c] = value
    return header, values


def _first_empty(data) -> int:
    """The file's line of a column's first empty cell."""
    return int(np.flatnonzero(np.isnan(data))[0]) + 2


def _check_time(path: Path, t) -> float:
    """The sample period, after checking the time column increases evenly."""
    steps = np.diff(t)
    if (steps <= 0).any():
        bad = int(np.flatnonzero(steps <= 0)[0]) + 3
        _fail(path, f"line {bad}, column t_s", "time does not increase")
    median = float(np.median(steps))
    uneven = np.abs(steps - median) > SAMPLING_TOLERANCE * median
    if uneven.any():
        bad = int(np.flatnonzero(uneven)[0]) + 3
        _fail(
            path, f"line {bad}, column t_s", f"not evenly sampled (step {steps[bad - 3]:.6g} s, usual {median:.6g} s)"
        )
    return median


def _joint_angles(path: Path, col: dict, failed_joints, period: float) -> tuple[np.ndarray, dict]:
    """The potentiometers' angles (NaN for failed joints), checked for units, gaps and jumps no servo makes, and the
    joints whose reading passes the limit (degrees)."""
    limit = math.radians(JOINT_LIMIT_DEG + JOINT_TOLERANCE_DEG)
    jump = math.radians(JUMP_TOLERANCE_DEG + JUMP_SPEED_FACTOR * SERVO_SPEED_DEG_S * period)
    q = np.full((len(col["t_s"]), NUM_JOINTS), np.nan)
    beyond = {}
    for j, name in enumerate(JOINT_COLUMNS, start=1):
        data = col[name]
        if j in failed_joints:
            if not np.isnan(data).all():
                line = int(np.flatnonzero(~np.isnan(data))[0]) + 2
                _fail(
                    path, f"line {line}, column {name}", f"joint {j} is listed as failed but its potentiometer has data"
                )
            continue
        if np.isnan(data).any():
            _fail(path, f"line {_first_empty(data)}, column {name}", f"empty cell for working joint {j}")
        peak = float(np.abs(data).max())
        line = int(np.argmax(np.abs(data))) + 2
        if peak > DEGREES_HINT_RAD:
            _fail(
                path, f"line {line}, column {name}", f"{data[line - 2]:g} looks like degrees, the column is in radians"
            )
        steps = np.abs(np.diff(data))
        if steps.max() > jump:
            at = int(np.argmax(steps)) + 3
            _fail(
                path,
                f"line {at}, column {name}",
                f"jumps by {math.degrees(steps[at - 3]):.1f} deg in one sample, more than a servo can move "
                f"({math.degrees(jump):.1f} deg at {SERVO_SPEED_DEG_S:g} deg/s)",
            )
        if peak > limit:
            beyond[j] = math.degrees(data[line - 2])
        q[:, j - 1] = data
    return q, beyond


def _load_csv(path: Path, failed_joints) -> dict:
    header, values = _read_table(path)
    col = {name: values[:, header.index(name)] for name in header}
    for name in ("t_s", "head_yaw_rate_rad_s"):
        if np.isnan(col[name]).any():
            _fail(path, f"line {_first_empty(col[name])}, column {name}", "empty cell")
    period = _check_time(path, col["t_s"])
    q, beyond = _joint_angles(path, col, failed_joints, period)
    rate = col["head_yaw_rate_rad_s"]
    if np.abs(rate).max() > YAW_RATE_HINT_RAD_S:
        line = int(np.argmax(np.abs(rate))) + 2
        _fail(
            path,
            f"line {line}, column head_yaw_rate_rad_s",
            f"{rate[line - 2]:g} looks like deg/s, the column is in rad/s",
        )
    cam = None
    if CAMERA_COLUMNS[0] in col:
        cam = np.column_stack([col[c] for c in CAMERA_COLUMNS])
        partial = np.isnan(cam).any(axis=1) & ~np.isnan(cam).all(axis=1)
        if partial.any():
            _fail(path, f"line {int(np.flatnonzero(partial)[0]) + 2}", "camera cells are empty together or not at all")
    return dict(t=col["t_s"], q=q, head_yaw_rate=rate, camera=cam, beyond_limit=beyond)


def load_trial(json_path) -> Trial:
    json_path = Path(json_path)
    csv_path = json_path.with_suffix(".csv")
    if not csv_path.is_file():
        _fail(json_path, "file", f"its CSV {csv_path.name} is missing")
    meta = _load_json(json_path)
    signals = _load_csv(csv_path, meta["failed_joints"])
    return Trial(**meta, **signals, source=json_path)


def load_campaign(folder) -> Campaign:
    """All trials of a campaign folder, or Rc1Error for the first problem found (nothing half-loaded)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise Rc1Error(f"{folder}: not a campaign folder")
    jsons = sorted(p for p in folder.glob("*.json") if not p.name.startswith("."))
    csvs = sorted(p for p in folder.glob("*.csv") if not p.name.startswith("."))
    for c in csvs:
        if not c.with_suffix(".json").is_file():
            _fail(c, "file", f"its JSON {c.with_suffix('.json').name} is missing")
    if not jsons:
        raise Rc1Error(f"{folder}: no trials (<trial>.json + <trial>.csv pairs)")
    trials = [load_trial(p) for p in jsons]
    ids = [t.trial_id for t in trials]
    for trial in trials:
        if ids.count(trial.trial_id) > 1:
            _fail(trial.source, "trial_id", f"{trial.trial_id!r} is used by another trial of the campaign")
    return Campaign(path=folder, trials=trials)


def _fmt(v):
    return "" if not math.isfinite(v) else f"{float(v):.9g}"


def write_trial(folder, stem: str, trial: Trial) -> Path:
    """Write `trial` as <stem>.json + <stem>.csv (each written to a temporary name, then renamed)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    meta = {
        "trial_id": trial.trial_id,
        "failed_joints": list(trial.failed_joints),
        "gait": {k: getattr(trial.gait, k) for k in GAIT_KEYS},
        "stop": trial.stop.to_json(),
        "initial_head_pose": dict(zip(POSE_KEYS, map(float, trial.initial_head_pose), strict=True)),
        "final_head_xy_m": [float(v) for v in trial.final_head_xy],
    }
    if trial.notes:
        meta["notes"] = trial.notes
    if trial.initial_head_rates is not None:
        meta["initial_head_rates"] = dict(zip(RATE_KEYS, map(float, trial.initial_head_rates), strict=True))
    header = list(REQUIRED_COLUMNS) + (list(CAMERA_COLUMNS) if trial.camera is not None else [])
    rows = []
    for k in range(len(trial.t)):
        row = [_fmt(trial.t[k])] + [_fmt(v) for v in trial.q[k]] + [_fmt(trial.head_yaw_rate[k])]
        if trial.camera is not None:
            row += [_fmt(v) for v in trial.camera[k]]
        rows.append(row)
    csv_path = folder / f"{stem}.csv"
    tmp = folder / f".{stem}.csv.tmp"
    with open(tmp, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(header)
        writer.writerows(rows)
    os.replace(tmp, csv_path)
    json_path = folder / f"{stem}.json"
    tmp = folder / f".{stem}.json.tmp"
    tmp.write_text(json.dumps(meta, indent=2) + "\n")
    os.replace(tmp, json_path)
    return json_path
