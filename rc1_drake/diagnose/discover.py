"""Discovery (stage 5, after the verdict): where the library's effects leave a campaign unexplained, fit the
discrepancy model (discrepancy.py) at the diagnosis's final model, sparse, its sparsity chosen on held-out trials;
then name the few terms that survive in physical words, check them by replaying each trial with terms fitted
without it, and say which library effect's shape each one matches.

The replay's columns are exact (the tangent model's sensitivities, one replay per trial for every term; the library
coordinates' likewise, taken only once a term survives, to compare its shape with). The sparse fit is orthogonal
matching pursuit (scikit-learn's) on normalized columns: with dozens of correlated columns, PySINDy's thresholded least
squares (STLSQ) kept large cancelling coefficients and lost the true term (docs/findings.md). How many terms is chosen
by leaving one trial out: the fewest whose held-out cost is within one standard error of the best, and none at all
unless it removes MIN_GAIN and MIN_FALL of the held-out cost without terms beyond the noise floor (linearly, then by
replaying each trial with the terms fitted without it; where that fails, the path's smaller models that pass the
gate are replayed in turn: _smaller, not_holding): what the rows cost at
the truth from the noise discovery measures (the replays' input noise, resampled; the angles' count). The camera's noise
is not in it (its stated sigma is a scale, not a measurement): the gate errs toward no term. A trial's path rows weigh
by its own input-noise covariance (a generalized least squares; PATH_WEIGHTS): a chaotic replay's misfit along its
noise's directions counts as that noise.

With `angles`, each trial also contributes its working joints' measured angles against the model's servos driven
by the trial's command (sysid.residual.angle_residual: a servo's tracking error is its load, which the kinematic
replay cannot see), and the servos' gains are fitted with the terms (nuisance coordinates, always in)."""

import dataclasses
import math
import os

import numpy as np
from scipy.linalg import block_diag

from ..config import Friction, Rc1Error, Servo
from ..effects import LIBRARY, candidate_names, coordinate_owner, parameter, parameter_owner, shifted
from ..engine.session import sensitivity_parameters
from ..executor import make_executor
from ..replay import Replayer
from ..sysid.evaluate import Evaluator
from ..sysid.input_noise import INPUT_NOISE_SAMPLES, bootstrap_twin, input_noise_covariance
from ..sysid.residual import (
    angle_residual,
    angle_rows,
    replay_residual,
    replay_residual_and_jacobian,
    residual_channels,
    trial_residual,
)
from ..sysid.stats import Z95, channel_variances, sandwich
from .linearize import trial_weights

SIZES = (1, 2, 3, 4)  # how many terms a sparse model may have: a missing effect is one or two mechanisms
# What a sparse model must remove of the held-out cost to say anything: a share of it, and the chi-square(1) 95%
# quantile in standardized units (what one free coefficient removes of white noise by chance). Chosen by hand on the
# round-trip tests, not yet on seeded campaigns (issue 43's rates).
MIN_FALL = 0.25
MIN_GAIN = 3.84
# How a trial's path rows weigh (_row_weights): "whitened", by its own input-noise covariance; "case", by its case's
# mean input-noise variance, as the diagnosis's fits (the paper design's tether: 62% of its error removed against 50%).
PATH_WEIGHTS = "whitened"
REFINEMENTS = 2  # Gauss-Newton steps on the surviving terms, by replay
HALVINGS = 4  # of a step whose runs fail or whose cost rises
MATCH_COSINE = 0.98  # a term "matches" a library coordinate whose column is this parallel to its prediction
# With the angles: the servos' gains, fitted as log multipliers of the model's (always in, as nuisance coordinates),
# their columns by forward differences of this step.
SERVO_GAINS = ("kp_Nm_per_rad", "kd_Nm_s_per_rad", "ki_Nm_per_rad_s")
GAIN_STEP = 0.02
WHERE = {
    "head": "the head's centre",
    "front": "the wheels of modules 2-5",
    "middle": "the wheels of modules 6-10",
    "rear": "the wheels of modules 11-14",
    "tail": "the tail's end",
    "failed_joint": "each failed joint",
}


@dataclasses.dataclass
class Term:
    name: str  # the effect's (discrepancy_<group>_<kind>)
    key: str  # its parameter key, as a model file holds it
    value: float
    standard_error: float
    words: str  # what it is, in physical words
    matches: list[dict]  # library coordinates whose column its prediction parallels: name, cosine, value

    @property
    def interval95(self) -> list[float]:
        return [self.value - Z95 * self.standard_error, self.value + Z95 * self.standard_error]


@dataclasses.dataclass
class Discovery:
    terms: list[Term]  # none: no term earns its place
    path: list[dict]  # per number of terms: which and their held-out cost (leave one trial out, linear)
    cost_without: float  # held-out cost without terms (the sum of squared standardized residuals)
    heldout_before: float  # by replay: each trial at the final model
    heldout_after: float  # by replay: each trial with terms fitted on the other trials
    effects: dict[str, float]  # the final model's effects with the terms added
    simulations: int
    servo: Servo | None = None  # with the angles: the servos as their tracking shows them (fitted with the terms)
    noise: float = 0.0  # what the angle rows cost at the truth (their count: each standardized by its noise)
    angles_before: float = 0.0  # the angle rows' share of heldout_before and heldout_after
    angles_after: float = 0.0
    input_noise: float = 0.0  # the path rows' cost at the truth from the replays' input noise (weighted traces)
    tried: list[Term] = dataclasses.field(default_factory=list)  # through the linear gate, not holding up by replay

    @property
    def floor(self) -> float:
        """What the rows cost at the truth from the noise discovery measures: the angles' and the replays' input."""
        return self.noise + self.input_noise

    @property
    def fall(self) -> float:
        """The fraction of the held-out error beyond the noise floor that the terms remove (by replay)."""
        excess = self.heldout_before - self.floor
        return 1.0 - (self.heldout_after - self.floor) / excess if excess > 0 else 0.0

    @property
    def angle_fall(self) -> float:
        """The fraction of the angle rows' held-out error beyond their noise that the terms remove (by replay)."""
        excess = self.angles_before - self.noise
        return 1.0 - (self.angles_after - self.noise) / excess if excess > 0 else 0.0

    def format(self) -> str:
        lines = ["Discovery (the discrepancy model, sparse, its sparsity chosen on held-out trials):"]
        if self.servo is not None and self.terms:
            s = self.servo
            lines.append(
                f"  the servos as the measured angles show them: Kp {s.kp_Nm_per_rad:.3g} N m/rad, "
                f"Kd {s.kd_Nm_s_per_rad:.3g} N m s/rad, Ki {s.ki_Nm_per_rad_s:.3g} N m/(rad s)"
            )
        if self.tried:
            lines.append(
                f"  no term holds up when simulated: the best sparse model ({', '.join(t.key for t in self.tried)}) "
                f"passed the linear gate, but replayed on held-out trials it removes {100 * self.fall:.0f}% of the "
                f"held-out error beyond its noise floor ({self.heldout_before:.4g} -> {self.heldout_after:.4g}; "
                f"floor {self.floor:.4g}), under {100 * MIN_FALL:.0f}%: not reported"
            )
            return "\n".join(lines)
        if not self.terms:
            lines.append(
                f"  no term earns its place: the best sparse model removes less than {100 * MIN_FALL:.0f}% or "
                f"{MIN_GAIN:g} of the held-out cost without terms beyond its noise floor ({self.cost_without:.4g}"
                f" - {self.floor:.4g}: {_floor_words(self)})"
            )
            return "\n".join(lines)
        for t in self.terms:
            low, high = t.interval95
            lines.append(f"  {t.key} = {t.value:.3g} (95%: {low:.3g} .. {high:.3g}): {t.words}")
            for m in t.matches:
                lines.append(f"      its shape matches {m['name']} (cos {m['cosine']:.2f}) at {m['value']:.3g}")
        lines.append(
            f"  held-out error (each trial replayed with terms fitted without it): {self.heldout_before:.4g} -> "
            f"{self.heldout_after:.4g} ({100 * self.fall:.0f}% of what its noise floor, {self.floor:.4g}, leaves: "
            f"{_floor_words(self)})"
        )
        if self.noise:
            lines.append(
                f"    of it the angles': {self.angles_before:.4g} -> {self.angles_after:.4g} against their noise's "
                f"{self.noise:.4g} ({100 * self.angle_fall:.0f}% of the excess removed); the path's: "
                f"{self.heldout_before - self.angles_before:.4g} -> {self.heldout_after - self.angles_after:.4g}"
            )
        return "\n".join(lines)


def _floor_words(found: Discovery) -> str:
    words = [f"the replays' input noise {found.input_noise:.4g}"]
    return ", ".join(words + ([f"the angles' {found.noise:.4g}"] if found.noise else []))


def term_words(name: str, value: float) -> str:
    """A fitted term in physical words, its sign read: what acts where, and how strongly."""
    effect = LIBRARY[name]
    where = WHERE.get(effect.group, effect.group)
    unit = effect.unit.replace("_per_", "/").replace("_s", " s").replace("_", " ")
    words = effect.words
    if effect.kind.startswith(("drag", "dry")) and value < 0:
        words = words.replace(" against ", " along ") + " (less resistance than the model's)"
    elif effect.kind.startswith("push") and value < 0:
        words = words.replace("toward the head", "toward the tail").replace("to its left", "to its right")
    elif effect.kind == "side_by_long" and value < 0:
        words = words.replace("to its left", "to its right")
    strength = f"{abs(value):.3g} {unit}"
    if effect.unit.endswith("_s_per_m"):
        strength += f" ({abs(value) * 0.1:.3g} N at 0.1 m/s)"
    return f"{words} at {where}, {strength}"


def discrepancy_keys(trials) -> list[str]:
    """The discrepancy's parameter keys these trials can see (the failed-joint terms only with a failed joint)."""
    failed = any(t.failed_joints for t in trials)
    names = candidate_names(["discrepancy"])
    return [LIBRARY[n].main.key for n in names if failed or not LIBRARY[n].failed_joints_only]


def library_coordinates() -> list[str]:
    """The default candidates' coordinates with exact columns, which a learned term's shape is compared with."""
    known = set(sensitivity_parameters())
    names = [p.key for n in candidate_names(None) for p in LIBRARY[n].coordinate_space()]
    return [n for n in names if n in known]


def discover(
    trials,
    friction: Friction,
    effects: dict,
    *,
    evaluator: Evaluator | None = None,
    sizes=SIZES,
    angles: bool = False,
) -> Discovery:
    """The discrepancy model fitted to `trials` at the model (`friction`, `effects`), on their residuals with the
    replay's own miss on the model's motion taken off (corrected_residual); with `angles`, also on the working
    joints' angles against the model's servos, whose gains are fitted with the terms (module docstring)."""
    evaluator = evaluator or Evaluator(None)
    start = evaluator.simulations
    keys, library = discrepancy_keys(trials), library_coordinates()
    view = _View(Servo(), angles)
    counts = [angle_rows(t) if angles else 0 for t in trials]  # each trial's angle rows, last in its residual
    blocks = evaluator.map(
        input_noise_covariance,
        [(t, friction, effects, INPUT_NOISE_SAMPLES, k) for k, t in enumerate(trials)],
        "the replays' input noise",
    )
    weights = _row_weights(trials, blocks)
    blocks = [w @ b @ w.T for w, b in zip(weights, blocks, strict=True)]  # the path rows' covariances, weighed
    parts = evaluator.map(
        corrected_and_jacobian,
        [(t, friction, effects, tuple(keys), view) for t in trials],
        "the discrepancy's columns (replays and twins)",
    )
    if any(len(p[0]) != len(w) + n for p, w, n in zip(parts, weights, counts, strict=True)):
        raise Rc1Error("discovery: a trial's residual rows are not its path rows and its angle rows")
    parts = _weighed(parts, weights)
    r = [p[0] for p in parts]
    columns = [p[1][:, : len(keys)] for p in parts]
    r, columns = _without_nuisance(r, columns, [p[1][:, len(keys) :] for p in parts])
    path, cost_without = _sparsity_path(r, columns, sizes)
    noise = float(sum(counts))
    input_noise = float(sum(np.trace(b) for b in blocks))
    chosen = _choose(path, cost_without, noise + input_noise)
    floors = {"noise": noise, "input_noise": input_noise}
    empty = Discovery([], path, float(cost_without.sum()), 0.0, 0.0, dict(effects), 0, **floors)
    if chosen is None:
        return dataclasses.replace(empty, simulations=evaluator.simulations - start)
    campaign = _Campaign(trials, friction, effects, evaluator, view, weights, blocks, r, counts, library)
    models = [chosen, *_smaller(path, chosen, cost_without, noise + input_noise)]
    found = _first_holding(
        campaign, [{keys[j]: v for j, v in zip(m["support"], m["values"], strict=True)} for m in models], empty
    )
    return dataclasses.replace(found, simulations=evaluator.simulations - start)


def _first_holding(campaign: "_Campaign", models: list, empty: Discovery) -> Discovery:
    """The first of the sparse `models` (term key: linear fit) whose held-out replays remove MIN_FALL of the
    error beyond the floor, as `empty` with its fields; else the first replayed one, not holding (not_holding)."""
    first = None
    for values in models:
        found = _replayed(campaign, values)
        if found is None:  # every term refined to a zero bound: the model without them
            continue
        found = dataclasses.replace(empty, **found)
        if found.fall >= MIN_FALL:
            return found
        first = first or found
    return not_holding(first, campaign.effects) if first else empty


def _smaller(path, chosen, cost_without, noise: float) -> list:
    """The path's models with fewer terms than `chosen` that pass the gate on their own held-out gain, largest
    first: tried in turn where the chosen one's replays do not confirm it (its extra terms may fit the replay's
    linearization, not the data)."""
    total = float(np.sum(cost_without))
    smaller = [p for p in path if p["support"] and p["size"] < chosen["size"]]
    fits = [p for p in smaller if passes_gate(total - p["held"].sum(), cost_without, noise=noise)]
    return sorted(fits, key=lambda p: -p["size"])


@dataclasses.dataclass
class _Campaign:
    """What each sparse model discovery tries is refined on and replayed against: the trials at the model
    (`friction`, `effects`), their rows' weights and weighed input-noise covariances, their weighed residuals, their
    angle rows' counts, and the library coordinates (their columns taken once, when a first model needs them)."""

    trials: list
    friction: Friction
    effects: dict
    evaluator: Evaluator
    view: "_View"
    weights: list
    blocks: list
    r: list
    counts: list
    library: list
    library_columns: np.ndarray | None = None


def _replayed(c: _Campaign, values: dict) -> dict | None:
    """Discovery's fields for the sparse model `values` (a term key each: its linear fit): the terms refined by
    replay, their intervals and library matches, the held-out error by replay before and after; None where every
    term refines to its zero bound."""
    values, fitted, view = _refined(c.trials, c.friction, c.effects, values, c.evaluator, c.view, c.weights)
    values, fitted = _without_zeros(values, fitted, len(view.gains))
    if not values:
        return None
    model = {**c.effects, **values}
    errors = _standard_errors(fitted, c.blocks)
    if c.library_columns is None:
        base = _View(Servo(), c.view.angles)
        c.library_columns = _library_columns(c.trials, c.friction, c.effects, c.library, c.evaluator, c.weights, base)
    held = _held_out_by_replay(c.trials, c.friction, model, values, fitted, c.evaluator, view)
    held = [_weigh(w, x) for x, w in zip(held, c.weights, strict=True)]
    angles_before, angles_after = (
        sum(float(x[len(x) - n :] @ x[len(x) - n :]) for x, n in zip(rs, c.counts, strict=True)) for rs in (c.r, held)
    )
    terms = []
    for j, (key, value) in enumerate(values.items()):
        name = parameter_owner(key).name
        matches = _matches(fitted[0][:, j] * value, c.library_columns, c.library)
        terms.append(Term(name, key, value, float(errors[j]), term_words(name, value), matches))
    return {
        "terms": terms,
        "heldout_before": sum(float(x @ x) for x in c.r),
        "heldout_after": sum(float(x @ x) for x in held),
        "effects": model,
        "servo": view.servo if c.view.angles else None,
        "angles_before": angles_before,
        "angles_after": angles_after,
    }


def not_holding(found: Discovery, effects: dict) -> Discovery:
    """`found` with its terms moved to `tried` and the model without them: terms through the linear gate whose
    held-out replays remove less than MIN_FALL of the error beyond the floor are not reported (a linear prediction
    the simulation does not confirm, as the diagnosis's candidates must be confirmed)."""
    return dataclasses.replace(found, terms=[], tried=found.terms, effects=dict(effects), servo=None)


def discover_campaign(
    trials, friction: Friction, effects: dict, *, workers=None, scheduler=None, progress=None, angles=False
):
    """discover() with its replays on an executor (all local cores by default; Dask's at `scheduler`)."""
    with make_executor(workers=workers or min(os.cpu_count() or 1, len(trials)), scheduler=scheduler) as executor:
        return discover(trials, friction, effects, evaluator=Evaluator(executor, progress), angles=angles)


@dataclasses.dataclass(frozen=True)
class _View:
    """What a trial's residual holds besides the path: with `angles`, the angle rows, made by servos `servo`."""

    servo: Servo
    angles: bool

    @property
    def gains(self) -> tuple:
        return SERVO_GAINS if self.angles else ()

    def moved(self, steps) -> "_View":
        """The servos with each gain multiplied by exp(step) (SERVO_GAINS' order)."""
        changes = {g: getattr(self.servo, g) * math.exp(float(h)) for g, h in zip(self.gains, steps, strict=True)}
        return dataclasses.replace(self, servo=dataclasses.replace(self.servo, **changes))


PATH_ONLY = _View(Servo(), False)


def _twin_parts(trial, friction: Friction, effects, view: _View) -> tuple:
    """The replay's own miss on this trial's motion as the model makes it — the trial's noise-free twin (the model
    driven by the gait from the trial's start, with its camera misses; sysid.input_noise.bootstrap_twin) replayed
    at the model: the diagnosis's bias, without its noise draws — and, with the angles, the twin's angles against
    the measured ones (sysid.residual.angle_residual; else empty)."""
    twin = bootstrap_twin(trial, friction, effects, view.servo)[0]
    path = trial_residual(twin, Replayer(twin).run(friction, effects))
    return path, angle_residual(trial, twin) if view.angles else np.zeros(0)


def corrected_residual(trial, friction: Friction, effects, view: "_View" = None) -> np.ndarray:
    """A trial's residuals less the replay's own miss on the model's motion: a term moves them both along the
    measured angles (the replay) and through the motion the servos make of the gait (the twin); on a wheeled
    body held to its path the second is most of it (docs/findings.md). With the angles, their rows follow."""
    view = view or PATH_ONLY
    path, angles = _twin_parts(trial, friction, effects, view)
    return np.concatenate([replay_residual(trial, friction, effects) - path, angles])


def corrected_and_jacobian(trial, friction: Friction, effects, names, view: "_View" = None) -> tuple:
    """corrected_residual and its columns by `names`, then by the servos' gains (with the angles): the replay's
    exact (its sensitivities), the twin's by a forward difference over each coordinate's probe step (GAIN_STEP)."""
    view = view or PATH_ONLY
    r, jac = replay_residual_and_jacobian(trial, friction, effects, names)
    base_path, base_angles = _twin_parts(trial, friction, effects, view)
    n = len(r)
    out = np.zeros((n + len(base_angles), len(names) + len(view.gains)))
    out[:n, : len(names)] = jac
    moves = [(name, shifted(effects, name, _probe(name)), view, _probe(name)) for name in names]
    for k in range(len(view.gains)):
        steps = np.zeros(len(view.gains))
        steps[k] = GAIN_STEP
        moves.append((view.gains[k], effects, view.moved(steps), GAIN_STEP))
    for j, (_, moved_effects, moved_view, h) in enumerate(moves):
        path, angles = _twin_parts(trial, friction, moved_effects, moved_view)
        out[:n, j] -= (path - base_path) / h
        out[n:, j] = (angles - base_angles) / h
    return np.concatenate([r - base_path, base_angles]), out


def _probe(name: str) -> float:
    return next(p.probe_step for p in coordinate_owner(name).coordinate_space() if p.key == name)


def _without_nuisance(r, columns, nuisance) -> tuple:
    """The residuals and columns with the nuisance columns' span (the servos' gains) projected out, over all trials
    together: the sparse fit then chooses among the terms with the gains fitted alongside."""
    if not nuisance or nuisance[0].shape[1] == 0:
        return r, columns
    q = np.linalg.qr(np.vstack(nuisance))[0]
    ends = np.cumsum([0, *(len(x) for x in r)])
    r_all, x_all = np.concatenate(r), np.vstack(columns)
    r_all, x_all = r_all - q @ (q.T @ r_all), x_all - q @ (q.T @ x_all)
    return [r_all[a:b] for a, b in zip(ends[:-1], ends[1:], strict=True)], [
        x_all[a:b] for a, b in zip(ends[:-1], ends[1:], strict=True)
    ]


def _sparse_fit(x, y, size):
    """Orthogonal matching pursuit (scikit-learn's) to `size` terms on columns normalized to unit norm: greedy,
    so a term correlated with several others is not lost among large cancelling coefficients as thresholding
    loses it; the coefficients in the columns' own units."""
    from sklearn.linear_model import OrthogonalMatchingPursuit

    norms = np.linalg.norm(x, axis=0)
    norms[norms == 0] = 1.0
    fit = OrthogonalMatchingPursuit(n_nonzero_coefs=size, fit_intercept=False).fit(x / norms, y)
    return fit.coef_ / norms


def _sparsity_path(r, columns, sizes) -> tuple:
    """Per number of terms: its support on all trials and its held-out cost per trial (each trial predicted by
    the terms chosen and fitted on the others, linearly); and the per-trial cost without terms."""
    n = len(r)
    cost_without = np.array([float(x @ x) for x in r])
    x_all, y_all = np.vstack(columns), -np.concatenate(r)
    path = []
    for size in sizes:
        coef = _sparse_fit(x_all, y_all, size)
        support = np.flatnonzero(coef)
        held = np.empty(n)
        for k in range(n):
            others = [i for i in range(n) if i != k]
            c = _sparse_fit(np.vstack([columns[i] for i in others]), -np.concatenate([r[i] for i in others]), size)
            left = r[k] + columns[k] @ c
            held[k] = float(left @ left)
        path.append({"size": size, "support": support.tolist(), "values": coef[support].tolist(), "held": held})
    return path, cost_without


def best_gain(path, cost_without) -> float:
    """What the sparse model with the best held-out cost removes of the held-out cost without terms."""
    with_terms = [p for p in path if p["support"]]
    return max((float(np.sum(cost_without) - p["held"].sum()) for p in with_terms), default=0.0)


def passes_gate(gain: float, cost_without, min_fall=MIN_FALL, min_gain=MIN_GAIN, noise: float = 0.0) -> bool:
    """Whether a sparse model that removes `gain` of the held-out cost without terms (`cost_without`, per trial or
    summed) may be reported: at least `min_fall` of that cost beyond `noise` (what the rows cost at the truth:
    Discovery.floor) and at least `min_gain`."""
    return gain >= min_gain and gain >= min_fall * max(float(np.sum(cost_without)) - noise, 0.0)


def _choose(path, cost_without, noise: float = 0.0):
    """The fewest terms within a standard error of the best held-out cost, if the best passes the gate
    (passes_gate); else None."""
    with_terms = [p for p in path if p["support"]]
    if not with_terms or not passes_gate(best_gain(path, cost_without), cost_without, noise=noise):
        return None
    best = min(with_terms, key=lambda p: p["held"].sum())
    gain_per_trial = cost_without - best["held"]
    limit = best["held"].sum() + math.sqrt(len(gain_per_trial)) * gain_per_trial.std(ddof=1)
    return min((p for p in with_terms if p["held"].sum() <= limit), key=lambda p: p["size"])


def _refined(trials, friction, effects, values, evaluator, view: _View, weights) -> tuple:
    """Gauss-Newton steps on the surviving terms (their bounds kept) and the servos' gains (with the angles), each
    halved while a replay fails or the cost rises: (values, (their Jacobian, the residual, each trial's row count)
    there, the view with the servos there); each trial's rows weighed by `weights` (_row_weights)."""
    keys = list(values)

    def at(v, vw):
        try:
            parts = evaluator.map(
                corrected_and_jacobian,
                [(t, friction, {**effects, **v}, tuple(keys), vw) for t in trials],
                "the discovered terms refined",
            )
        except Rc1Error:  # a run blew up at these values
            return None
        parts = _weighed(parts, weights)
        return np.concatenate([p[0] for p in parts]), np.vstack([p[1] for p in parts]), [len(p[0]) for p in parts]

    values = _clipped(values)
    here = at(values, view)
    for _ in range(HALVINGS):  # the linear fit's values may be too far for the runs: toward the model
        if here is not None:
            break
        values = {k: 0.5 * x for k, x in values.items()}
        here = at(values, view)
    if here is None:
        raise Rc1Error(f"discovery: every run with {', '.join(keys)} failed, even at 1/{2**HALVINGS} of the fit")
    for _ in range(REFINEMENTS):
        move = np.linalg.lstsq(here[1], -here[0], rcond=None)[0]
        for _ in range(HALVINGS):
            proposal = _clipped({k: values[k] + m for k, m in zip(keys, move[: len(keys)], strict=True)})
            moved = view.moved(move[len(keys) :])
            there = at(proposal, moved)
            if there is not None and there[0] @ there[0] < here[0] @ here[0]:
                values, view, here = proposal, moved, there
                break
            move = 0.5 * move
        else:
            break
    return values, (here[1], here[0], here[2]), view


def _without_zeros(values: dict, fitted: tuple, gains: int) -> tuple:
    """(values, fitted) without the terms at exactly 0 (a term clipped to its zero bound, a drag that may not turn
    into a push: the model without it, not a finding), their Jacobian columns with them (the servos' `gains`
    columns, last, kept)."""
    keys = list(values)
    keep = [j for j, k in enumerate(keys) if values[k] != 0.0]
    jacobian, residual, rows = fitted
    columns = keep + list(range(len(keys), len(keys) + gains))
    return {keys[j]: values[keys[j]] for j in keep}, (jacobian[:, columns], residual, rows)


def _row_weights(trials, blocks) -> list:
    """Each trial's path rows' weight matrix W (its angle rows after them weigh 1: their noise is the
    potentiometers', white, and each is standardized by it), by PATH_WEIGHTS: "case", the diagnosis's
    (linearize.trial_weights, a scalar feasible generalized least squares by its case's input-noise variance: a
    joint-2 failure's chaotic replay weighs less); "whitened", (1 + C)^-1/2 with C the trial's own input-noise
    covariance (`blocks`), a generalized least squares in which a replay's misfit along its noise's directions
    weighs as that noise and the rest as the sensors' (standardized to 1)."""
    if PATH_WEIGHTS == "case":
        return [w * np.eye(len(b)) for w, b in zip(trial_weights(trials, blocks), blocks, strict=True)]
    whiteners = []
    for b in blocks:
        lam, u = np.linalg.eigh(b) if len(b) else (np.zeros(0), np.zeros((0, 0)))
        whiteners.append((u / np.sqrt(1.0 + np.clip(lam, 0.0, None))) @ u.T)
    return whiteners


def _weigh(w, a):
    """`a` (a trial's residual, or its Jacobian) with its first len(w) rows, the path's, times W; the rest kept."""
    out = np.array(a, dtype=float)
    out[: len(w)] = w @ out[: len(w)]
    return out


def _weighed(parts, weights) -> list:
    """Each trial's (residual, Jacobian) with its rows weighed (_row_weights)."""
    return [(_weigh(w, r), _weigh(w, jac)) for (r, jac), w in zip(parts, weights, strict=True)]


def _standard_errors(fitted, blocks) -> np.ndarray:
    """The terms' standard errors by the sandwich (sysid.stats.sandwich; inf where the data do not constrain a
    term), S each channel's variance (sysid.stats.channel_variances) plus the covariance the angle noise in the
    replays' input causes (`blocks`: each trial's path rows', weighed, at the model without the terms, which move it
    little): as white residuals, the interval of a failed joint's bias on a noisy campaign missed the truth
    (docs/findings.md). Channels by row position: whitened path rows mix a trial's channels, each standardized alike."""
    jac, residual, sizes = fitted
    # The angle rows (after a trial's path rows) follow no replay: their noise is the potentiometers', white.
    channels = np.concatenate([residual_channels(np.zeros(n), n - len(b)) for b, n in zip(blocks, sizes, strict=True)])
    blocks = [np.pad(b, (0, n - len(b))) for b, n in zip(blocks, sizes, strict=True)]
    spread = np.diag(channel_variances(residual, channels, jac.shape[1]))
    cov, null = sandwich(jac, spread + block_diag(*blocks))
    return np.where(null, np.inf, np.sqrt(np.clip(np.diag(cov), 0.0, None)))


def _clipped(values: dict) -> dict:
    """Term values within their bounds."""
    return {key: float(np.clip(value, parameter(key).lower, parameter(key).upper)) for key, value in values.items()}


def _held_out_by_replay(trials, friction, model, values, fitted, evaluator, view: _View) -> list:
    """Each trial's residuals replayed with the terms (and the servos' gains) refitted (linearly, from the final fit)
    on the other trials."""
    jac, residual, sizes = fitted
    ends = np.cumsum([0, *sizes])
    jobs = []
    for k, t in enumerate(trials):
        rows = np.r_[0 : ends[k], ends[k + 1] : ends[-1]]
        move = np.linalg.lstsq(jac[rows], -residual[rows], rcond=None)[0]
        moved = {key: values[key] + m for key, m in zip(values, move[: len(values)], strict=True)}
        jobs.append((t, friction, {**model, **_clipped(moved)}, view.moved(move[len(values) :])))
    return evaluator.map(corrected_residual, jobs, "each trial held out")


def _library_columns(trials, friction, effects, names, evaluator, weights, view: _View) -> np.ndarray:
    """The library coordinates' columns at the model discovery started from, weighed as the terms' were: what a
    reported term's shape is compared with (_matches), taken only when there is one."""
    parts = evaluator.map(
        corrected_and_jacobian,
        [(t, friction, effects, tuple(names), view) for t in trials],
        "the library's columns, for the terms' shapes",
    )
    return np.vstack([jac[:, : len(names)] for _, jac in _weighed(parts, weights)])


def _matches(prediction, library_columns, names) -> list[dict]:
    """The library coordinates whose column parallels a term's predicted change of the residuals."""
    out = []
    size = np.linalg.norm(prediction)
    for j, name in enumerate(names):
        column = library_columns[:, j]
        norm = np.linalg.norm(column)
        if not size or not norm:
            continue
        cosine = abs(float(column @ prediction)) / (norm * size)
        if cosine >= MATCH_COSINE:
            out.append({"name": name, "cosine": cosine, "value": float(column @ prediction) / norm**2})
    return sorted(out, key=lambda m: -m["cosine"])
