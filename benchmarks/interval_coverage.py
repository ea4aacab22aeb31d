"""Do the 95% intervals hold the truth on data another model made (issue 67, item 5)?

    python benchmarks/interval_coverage.py [--seeds 10-17] [--methods program,avs,diagnose]
                                           [--hidden none,wheel_toe] [--form stop|lab|linkage|step|marker|scale]
                                           [--workers 2]
                                           [--out benchmarks/out/interval_coverage] [--markdown] [--table-only]

Every campaign has the paper's design (2 trials each of no failure, J7, J13 and J7 with synthesize.PAPER_DESIGN's
bias, to the 3.18 m line) and is made by reference.py, whose form is not this model's: its working joints follow
their command exactly, and its failed joint is the one the seed draws, a PD stop beyond +-38 deg of 20-500 N m/rad
(log-uniform; damping 0.2-2 N m s/rad) with a dry torque of 0-0.3 N m. The wheels' friction is drawn too: mu_lat
0.5-3, c_lat 1-10, c_joint 0.02-0.1 (log-uniform), mu_long 0.07-0.15, c_long 0.07-0.2; even seeds are recorded at
50 Hz, odd at 100 Hz, both with 0.2 deg of potentiometer noise and the starts spread as another lab's
(paper_rates.ROUGH). Each seed's truth makes two campaigns: nothing hidden, and a wheel toe at its reference
strength (benchmarks/diagnosis.py's REFERENCE, the one physical library effect reference.py expresses).
--form lab adds another lab's sensors (draw_lab: potentiometers behind a compliant linkage, a converter's step, a
camera marker ahead of the head's centre, a camera scale error); linkage, step, marker and scale add one of them.

Each campaign is identified as `rc1 identify --start-rates fit` does, by the program fit and by AVS (3 iterations),
and diagnosed as `rc1 diagnose` does by default. A row keeps every coefficient's estimate, its reported standard
error and the sandwich's (noise alone), whether the report called it identifiable, and the truth. Scored: of the
intervals a report gives (an identifiable coefficient, an accepted effect's coordinate, judged against 0 where the
effect is not hidden), how many hold the truth, beside the narrower ones of before (identify's sandwich alone, before
issue 67; the diagnosis's without the friction it holds unidentified); mu_lat within 25%; the toe found, its interval
holding. Seeds below 10 (CHOSE) are kept for choosing rules; the table reports the others. Rows stream to
benchmarks/rows/interval_coverage.jsonl (kept in the repository): a rerun resumes, from a fresh clone too.
--markdown writes the table into docs/identification.md.
"""

import argparse
import dataclasses
import itertools
import math
import time
from pathlib import Path

import diagnosis
import numpy as np
from calibrate import seeds as parse_seeds
from doc_blocks import REPO_ROOT, append_row, check_block, load_rows, rows_file, write_block

from rc1_drake.config import FRICTION_NAMES, Friction, Stop
from rc1_drake.diagnose import diagnose
from rc1_drake.diagnose.coordinates import coordinate_bounds
from rc1_drake.diagnose.thresholds import Thresholds
from rc1_drake.identify import identify
from rc1_drake.measurements import load_campaign
from rc1_drake.synthesize import PAPER_DESIGN, Case, Noise, Variation, synthesize_campaign
from rc1_drake.sysid.stats import HELD_LOG_SD, bound_side, reported_interval

PAGE, BLOCK, WRITER = (
    REPO_ROOT / "docs" / "identification.md",
    "coverage-table",
    "benchmarks/interval_coverage.py --markdown",
)
ROWS = rows_file("interval_coverage")
CHOSE = range(0, 10)  # seeds kept for choosing rules; the table reports seeds from 10 on
METHODS = ("program", "avs", "diagnose")
# The rows of today's code, by method: identify's with the jackknife over failed joints (sysid.stats.uncertainty), the
# diagnosis's with the friction it holds unidentified carried in its intervals (sysid.stats.HELD_LOG_SD) and
# the jackknife over cases (diagnose.fit.reported_standard_errors, "2026-12-03b"); identify's with no interval where its
# fit stopped short of its least misfit (sysid.stats.stopped_short, "2026-12-04"); the program fit's screened at the
# noise, the coefficients it held carried in its intervals (sysid.stats.held_covariance, "2026-12-04b"); earlier rows
# stay in the rows file (method_of).
VERSIONS = {"program": "2026-12-04b", "avs": "2026-12-04", "diagnose": "2026-12-03b"}
LAW = "+failed-joint-law"  # a diagnosis with the failed joints' law fitted as nuisance (diagnose's failed_joint_law)
# a diagnosis whose candidates fitted at a bound of their range are set aside (Thresholds.set_aside_at_bound): a
# variant, not landed
AT_BOUND = "at-bound set aside"
LINKAGE = "+linkage"  # a diagnosis offered the servos' linkage (effects.physical.ServoLinkage) beside the physical ones
HIDDEN = ("none", "wheel_toe")
# The truth's form: "stop", the failed joint's (below); "lab", that and another lab's sensors besides (synthesize.
# LabForms: potentiometers on the servos' shafts behind a compliant linkage, a converter's step, a camera marker ahead
# of the head's centre, a camera scale error), drawn per seed from a stream of its own (the stop's draws stay).
# "linkage", "step", "marker", "scale": that and one of the lab's sensors alone (where a lab's result comes from).
ONE_FORM = {
    "linkage": "reference_linkage_rad_per_Nm",
    "step": "reference_potentiometer_step_deg",
    "marker": "reference_camera_marker_m",
    "scale": "reference_camera_scale_error",
}
FORMS = ("stop", "lab", *ONE_FORM)
J7_BIAS_DEG = next(c.bias_deg for c in PAPER_DESIGN if c.bias_deg)
DESIGN = [Case([], 2), Case([7], 2), Case([13], 2), Case([7], 2, bias_deg=J7_BIAS_DEG)]


@dataclasses.dataclass(frozen=True)
class Truth:
    friction: Friction
    stop_Nm_per_rad: float
    stop_Nm_s_per_rad: float
    dry_Nm: float
    sample_period_s: float
    lab: dict = dataclasses.field(default_factory=dict)  # synthesize.LabForms' effect keys ("lab" form)

    def effects(self, hidden: str) -> dict:
        out = {
            "reference_stop_Nm_per_rad": self.stop_Nm_per_rad,
            "reference_stop_Nm_s_per_rad": self.stop_Nm_s_per_rad,
            "discrepancy_failed_joint_dry_Nm": self.dry_Nm,
        }
        return out | self.lab | diagnosis.hidden_effects(None if hidden == "none" else hidden, 1.0)


def draw_lab(seed: int) -> dict:
    """Another lab's sensors: linkage compliance 0.002-0.02 rad/N m (log-uniform; 50-500 N m/rad), a converter's step
    of 0.1-0.35 deg, the camera's marker 0-5 cm ahead of the head's centre and its scale off by up to 1%."""
    rng = np.random.default_rng([67, seed, 1])
    return {
        "reference_linkage_rad_per_Nm": float(math.exp(rng.uniform(math.log(0.002), math.log(0.02)))),
        "reference_potentiometer_step_deg": float(rng.uniform(0.1, 0.35)),
        "reference_camera_marker_m": float(rng.uniform(0.0, 0.05)),
        "reference_camera_scale_error": float(rng.uniform(-0.01, 0.01)),
    }


def draw(seed: int, form: str = "stop") -> Truth:
    """The seed's truth: the failed joint's form and the wheels' friction, drawn over the ranges of the docstring,
    and for the "lab" form another lab's sensors (draw_lab)."""
    rng = np.random.default_rng([67, seed])

    def log_uniform(low, high):
        return float(math.exp(rng.uniform(math.log(low), math.log(high))))

    friction = Friction(
        c_joint=log_uniform(0.02, 0.1),
        mu_lat=log_uniform(0.5, 3.0),
        mu_long=float(rng.uniform(0.07, 0.15)),
        c_lat=log_uniform(1.0, 10.0),
        c_long=float(rng.uniform(0.07, 0.2)),
    )
    return Truth(
        friction=friction,
        stop_Nm_per_rad=log_uniform(20.0, 500.0),
        stop_Nm_s_per_rad=log_uniform(0.2, 2.0),
        dry_Nm=float(rng.uniform(0.0, 0.3)),
        sample_period_s=0.02 if seed % 2 == 0 else 0.01,
        lab={k: v for k, v in draw_lab(seed).items() if form == "lab" or k == ONE_FORM.get(form)},
    )


def campaign_of(seed: int, hidden: str, out: Path, form: str = "stop"):
    truth = draw(seed, form)
    folder = out / "campaigns" / f"{'' if form == 'stop' else form + '-'}{hidden}-{seed}"
    if not folder.is_dir():
        synthesize_campaign(
            folder,
            design=DESIGN,
            friction=truth.friction,
            effects=truth.effects(hidden),
            seed=seed,
            truth_model="reference",
            stop=Stop(),
            sample_period_s=truth.sample_period_s,
            noise=Noise(potentiometer_deg=0.2),
            variation=Variation(phase_deg=7.5, heading_deg=1.0),
        )
    return load_campaign(folder), truth


def _estimates_identify(result) -> dict:
    u = result.uncertainty
    rows = zip(u.names, u.values, u.standard_errors, u.noise_standard_errors, u.identifiable, u.step_to_least_misfit,
               strict=True)  # fmt: skip
    return {n: {"value": v, "se": se, "noise_se": nse, "interval": bool(ok), "step": d}
            for n, v, se, nse, ok, d in rows}  # fmt: skip


def _estimates_diagnose(result) -> dict:
    freed = _freed(result) - set(result.at_bound)
    return {
        name: {"value": value, "se": se, "noise_se": None, "interval": math.isfinite(se) and name in freed}
        for name, (value, se) in result.final_coordinates.items()
    }


def _freed(result) -> set:
    """The coordinates a diagnosis reports an interval for: its free friction and its accepted effects'."""
    return set(result.free) | {n for n in result.final_coordinates if n not in FRICTION_NAMES}


def measure(seed: int, hidden: str, method: str, args) -> dict:
    campaign, truth = campaign_of(seed, hidden, args.out, args.form)
    stem = f"{'' if args.form == 'stop' else args.form + '-'}{hidden}-{seed}-{method}"
    checkpoint = args.out / "checkpoints" / (stem + ("-linkage" if args.linkage else ""))
    law = (LAW if args.failed_joint_law else "") + (LINKAGE if args.linkage else "")
    candidates = ["physical", "servo_linkage"] if args.linkage else None
    started = time.perf_counter()
    if method == "diagnose":
        result = diagnose(campaign, workers=args.workers, probe_study=False, start_rates="fit", checkpoint=checkpoint,
                          failed_joint_law=args.failed_joint_law, candidates=candidates,
                          thresholds=Thresholds(set_aside_at_bound=args.set_aside_at_bound))  # fmt: skip
        estimates = _estimates_diagnose(result)
        extra = {"verdict": str(result.verdict), "accepted": result.accepted, "version": VERSIONS[method] + law,
                 "final_friction": dataclasses.asdict(result.friction),
                 "friction_search": result.friction_search, "considered": result.considered,
                 "considered_variance": result.considered_variance,
                 "fit_standard_errors": result.fit_standard_errors, "at_bound": result.at_bound}  # fmt: skip
        if args.set_aside_at_bound:
            extra["variant"] = AT_BOUND
    else:
        iterations = 3 if method == "avs" else 10
        result = identify(
            campaign, method=method, start_rates="fit", iterations=iterations, workers=args.workers,
            checkpoint=checkpoint,
        )  # fmt: skip
        estimates = _estimates_identify(result)
        extra = {"residual_rms": result.uncertainty.residual_rms, "held": getattr(result.result, "held", []),
                 "version": VERSIONS[method]}  # fmt: skip
    truths = dataclasses.asdict(truth.friction) | {
        k: v for k, v in diagnosis.hidden_effects(None if hidden == "none" else hidden, 1.0).items()
    }
    return {
        "seed": seed,
        "hidden": hidden,
        "method": method,
        "truth": truths,
        "failed_joint": {
            "stop_Nm_per_rad": truth.stop_Nm_per_rad,
            "stop_Nm_s_per_rad": truth.stop_Nm_s_per_rad,
            "dry_Nm": truth.dry_Nm,
        },  # fmt: skip
        "sample_period_s": truth.sample_period_s,
        "form": args.form,
        "lab": truth.lab,
        "estimates": estimates,
        **extra,
        "simulations": result.simulations,
        "wall_s": time.perf_counter() - started,
        # set by hand where known, never here: "shared_cpu" (timed beside other heavy work: its minutes left out)
    }


def holds(estimate: dict, truth: float, key: str = "se", name: str = "") -> bool | None:
    """Whether the estimate's 95% interval holds `truth`: two-sided, or one-sided where `name`'s coordinate sits
    at a bound of its range (as the report states it, sysid.stats.reported_interval)."""
    se = estimate.get(key)
    if se is None or not math.isfinite(se):
        return None
    low, high = reported_interval(estimate["value"], se, *(coordinate_bounds(name) if name else ()))
    return low <= truth <= high


def given(name: str, estimate: dict) -> bool:
    """Whether a report gives the estimate an interval: not a friction coefficient at a bound of its range (no
    measurement there: Diagnosis.at_bound, identify's identifiable, since 2026-12-03; scored so for earlier rows)."""
    at_bound = name in FRICTION_NAMES and bound_side(estimate["value"], *coordinate_bounds(name))
    return bool(estimate["interval"]) and not at_bound


def truths(row: dict) -> dict:
    """The row's true values: the friction, the hidden effect, the failed joint's law in the model's form (its
    compliant stop and dry torque are reference.py's, effects.CompliantStop and JointCoulombFriction) and the lab's
    linkage (reference.py's readings lead their joints by c tau, as effects.ServoLinkage's)."""
    law = row["failed_joint"]
    return row["truth"] | {
        "joint_coulomb_Nm": law["dry_Nm"],
        "stop_compliance_rad_per_Nm": 1.0 / law["stop_Nm_per_rad"],
        "stop_d_Nm_s_per_rad": law["stop_Nm_s_per_rad"],
        "linkage_compliance_rad_per_Nm": row.get("lab", {}).get("reference_linkage_rad_per_Nm", 0.0),
    }


def intervals(rows: list) -> tuple:
    """(reported intervals, of which hold the truth; the narrower intervals of before, and of which hold it: for
    identify, those the sandwich alone would have reported before issue 67 (a coefficient fitted whose sandwich
    standard error is under 30% of it); for a diagnosis, its fit's own (the decisions'), before the jackknife over
    cases and the friction it held unidentified widened them (rows before 2026-12-03b: without the held friction).
    An effect accepted where none is hidden is judged against its nested value, 0."""
    reported = held = before = before_held = 0
    for row in rows:
        # an effect the truth does not have is there at its nested value, 0 (a toe accepted on a null is scored)
        truth = {n: 0.0 for n in row["estimates"] if n not in FRICTION_NAMES} | truths(row)
        for name, estimate in row["estimates"].items():
            if name not in truth:
                continue
            if given(name, estimate):
                reported += 1
                held += bool(holds(estimate, truth[name], name=name))
            if "considered_variance" in row and given(name, estimate):  # the fit's own, or without the held friction
                carried = HELD_LOG_SD**2 * row["considered_variance"].get(name, 0.0)
                own = row.get("fit_standard_errors", {}).get(name, math.sqrt(max(estimate["se"] ** 2 - carried, 0.0)))
                narrower = {"value": estimate["value"], "se": own}
                before += 1
                before_held += bool(holds(narrower, truth[name], name=name))
            noise = estimate.get("noise_se")
            if noise is not None and name not in row.get("held", []) and noise < 0.3 * abs(estimate["value"]):
                before += 1
                before_held += bool(holds(estimate, truth[name], "noise_se"))
    return reported, held, before, before_held


def mu_lat_kept(row: dict) -> float | None:
    """The mu_lat a run ended with: fitted or held (identify), the final model's (diagnose; rows before 2026-12-02
    kept only its free coordinates)."""
    if "final_friction" in row:
        return row["final_friction"]["mu_lat"]
    return row["estimates"].get("mu_lat", {}).get("value")


def method_of(row: dict) -> str:
    """The row's method, with its variant where it has one: ", before" for rows made before VERSIONS (identify's
    before the jackknife over failed joints, not tabled; the diagnosis's without the held friction's uncertainty,
    which decides as today), ", failed-joint law" for a diagnosis with the failed joints' law fitted, a row's own
    "variant" (rows of a rule that did not land, kept as measured: docs/findings.md (34), (35); not tabled)."""
    if row.get("variant"):
        return f"{row['method']}, {row['variant']}"
    version = row.get("version")
    if version == VERSIONS[row["method"]] + LAW:
        return row["method"] + ", failed-joint law"
    if version == VERSIONS[row["method"]] + LINKAGE:
        return row["method"] + ", linkage offered"
    return row["method"] if version == VERSIONS[row["method"]] else row["method"] + ", before"


TABLED = [*METHODS, "diagnose, failed-joint law", "diagnose, linkage offered"]


def form_of(row: dict) -> str:
    return row.get("form", "stop")  # rows before the lab form had the failed joint's alone


def table(rows: list) -> str:
    reported = [r for r in rows if r["seed"] not in CHOSE]
    seeds = sorted({r["seed"] for r in reported})
    lines = [
        f"Measured by `python {WRITER}` over reported seeds {seeds[0] if seeds else '-'}-{seeds[-1] if seeds else '-'}"
        f" ({len(seeds)} truths, each with nothing and a {diagnosis.REFERENCE['wheel_toe'][1]:g} deg wheel toe hidden)."
        " The 95% intervals a report gives (its identifiable coefficients; a diagnosis's free friction and accepted"
        " effects) and how many hold the truth (an effect accepted where none is hidden, against 0); before them, the"
        " narrower intervals of before: identify's sandwich alone (every residual independent, identifiable under 30%:"
        " before issue 67), the diagnosis's fit's own (what its decisions use; its reported intervals take the"
        " jackknife over cases where wider and carry the friction it holds unidentified, known to a factor 2);"
        " mu_lat within 25% of the truth; the toe found, and its interval holding:",
        "",
        "| form | method | hidden | campaigns | narrower: given, hold | reported: given, hold | mu_lat within 25% "
        "| toe found, holds | median min |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for form, method, hidden in itertools.product(FORMS, TABLED, HIDDEN):
        mine = [r for r in reported if method_of(r) == method and r["hidden"] == hidden and form_of(r) == form]
        if not mine:
            continue
        given, held, before, before_held = intervals(mine)
        kept = [(mu_lat_kept(r), r["truth"]["mu_lat"]) for r in mine]
        kept = [(v, t) for v, t in kept if v is not None]
        close = f"{sum(abs(v / t - 1) <= 0.25 for v, t in kept)} of {len(kept)}" if kept else "-"
        toe = [r["estimates"].get("wheel_toe_deg") for r in mine] if hidden == "wheel_toe" else []
        found = [e for e in toe if e is not None and e["interval"]]
        inside = sum(bool(holds(e, diagnosis.REFERENCE["wheel_toe"][1], name="wheel_toe_deg")) for e in found)
        toe_text = (
            "-" if hidden == "none" or not method.startswith("diagnose") else f"{len(found)} of {len(mine)}, {inside}"
        )
        before_text = f"{before}, {before_held}" if before else "-"
        timed = [r["wall_s"] for r in mine if not r.get("shared_cpu")]  # alone on the machine
        minutes = f"{float(np.median(timed)) / 60:.1f}" if timed else "- (shared CPU)"
        lines.append(
            f"| {form} | {method} | {hidden} | {len(mine)} | {before_text} | {given}, {held} | {close} | "
            f"{toe_text} | {minutes} |"
        )
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", default="10-17")
    parser.add_argument("--methods", default=",".join(METHODS))
    parser.add_argument("--hidden", default=",".join(HIDDEN))
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path, default=REPO_ROOT / "benchmarks" / "out" / "interval_coverage")
    parser.add_argument("--markdown", action="store_true")
    parser.add_argument("--table-only", action="store_true")
    parser.add_argument("--form", choices=FORMS, default="stop", help="the truth's form (FORMS)")
    parser.add_argument("--failed-joint-law", action="store_true", help="diagnose with the failed joints' law fitted")
    parser.add_argument("--linkage", action="store_true", help="diagnose with the servos' linkage among the candidates")
    parser.add_argument(
        "--set-aside-at-bound", action="store_true", help="diagnose with candidates at a bound set aside (a variant)"
    )
    args = parser.parse_args()
    methods, hidden = args.methods.split(","), args.hidden.split(",")
    if unknown := sorted(set(methods) - set(METHODS)) + sorted(set(hidden) - set(HIDDEN)):
        raise SystemExit(f"coverage: unknown method or hidden effect {', '.join(unknown)}")
    if args.markdown:
        check_block(PAGE, BLOCK, WRITER)
    args.out.mkdir(parents=True, exist_ok=True)
    done = {(r["seed"], r["hidden"], method_of(r), form_of(r)) for r in load_rows(ROWS)}
    label = {"diagnose": "diagnose, failed-joint law"} if args.failed_joint_law else {}  # identify ignores both
    label = {"diagnose": "diagnose, linkage offered"} if args.linkage else label
    label = {"diagnose": f"diagnose, {AT_BOUND}"} if args.set_aside_at_bound else label
    jobs = [(s, h, m) for s in parse_seeds(args.seeds) for h in hidden for m in methods
            if (s, h, label.get(m, m), args.form) not in done]  # fmt: skip
    for k, (seed, what, method) in enumerate([] if args.table_only else jobs, 1):
        row = measure(seed, what, method, args)
        append_row(ROWS, row)
        given, held, _, _ = intervals([row])
        print(f"[{k}/{len(jobs)}] seed {seed} {what} {method}: {held} of {given} intervals hold, "
              f"{row['wall_s'] / 60:.1f} min", flush=True)  # fmt: skip
    text = table(load_rows(ROWS))
    print(text)
    if args.markdown:
        write_block(PAGE, BLOCK, WRITER, text)


if __name__ == "__main__":
    main()
