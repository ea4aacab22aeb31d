"""Finding the missing physics: detection rates and false alarms over seeds and strengths.

    python benchmarks/diagnosis.py [--seeds 3] [--time-limit-s 3] [--workers 2] [--effects NAME,...]
                                   [--strengths 0.5,1,1.5] [--hold-friction] [--design none,J7x2]
                                   [--truth-model drake|reference] [--record-after-s 0] [--candidates physical]
                                   [--out benchmarks/rows/diagnosis.jsonl]

For every effect the replays can see, campaigns of its design (the trials that make it visible: a
no-failure trial and two joint-7 failures by default, like tests/test_diagnose.py; two circling joint-2
failures for the head drag; two nominal and two turning trials, 4 deg bias each way, for the lateral
asymmetry; --design for all) are synthesized with the effect hidden at each strength
(a multiple of its reference strength below) and each seed, and diagnosed with the whole library;
campaigns with no hidden effect, on every design used, measure false alarms. A row per campaign streams
to --out (rerunning resumes); the table gives, per effect and strength, how often it was accepted,
ranked first, recovered inside its 95% interval, how often another effect was accepted instead, and
how often the best candidate explained only part of the held-out error (not accepted), and how often the
verdict was the whole right answer (effect_found with the hidden effect alone; no_missing_effect without one).
--hold-friction holds the friction at the truth, as the tests do (short trials identify no friction
coefficient). --truth-model reference makes the campaigns with the independent model (reference.py: kinematic
joints, the head at rest at its start, its own limit model; of the library it expresses the wheel toe and the
sensor faults),
--record-after-s starts their recording after the robot did: data this project's model did not make.
--candidates sensor (or physical,sensor) lets the diagnosis consider the sensor faults, which the reference model
also makes (potentiometer_offset_j9 hides one).
"""

import argparse
import re
import tempfile
import time
from pathlib import Path

from doc_blocks import append_row, load_rows, rows_file  # benchmarks/ is on the path when this runs

from rc1_drake.config import FRICTION_NAMES, START_MODES, TRUTH_MODELS, Z95, Friction, Gait, Stop
from rc1_drake.diagnose import diagnose
from rc1_drake.effects import LIBRARY, candidate_names, effect_values, parameter
from rc1_drake.measurements import load_campaign
from rc1_drake.synthesize import REFERENCE_EFFECTS, Case, synthesize_campaign

DESIGN = "none,J7x2"


def parse_design(text: str) -> list:
    """'none,none@70,noneb4,J7x2,J13': a case per item — the failed joint (J<n>) or none, an optional gait
    frequency in deg/s (@f), an optional bias on every joint in deg (b<B>, Eq. 7: a turning gait) and a
    trial count (x<k>)."""
    cases = []
    for item in text.split(","):
        m = re.fullmatch(r"(none|J(\d+))(?:@(\d+(?:\.\d+)?))?(?:b(-?\d+(?:\.\d+)?))?(?:x(\d+))?", item.strip())
        if m is None:
            raise SystemExit(
                f"--design: cannot read {item!r} (expected none or J<joint>, then @<deg/s>, b<bias deg>, x<trials>)"
            )
        cases.append(
            Case(
                [int(m[2])] if m[2] else [],
                int(m[5] or 1),
                bias_deg=float(m[4] or 0.0),
                gait=Gait(frequency_deg_s=float(m[3])) if m[3] else None,
            )
        )
    return cases


# On DESIGN a head drag looks like a longitudinal asymmetry, and a lateral friction asymmetry like a toe or a
# tilt; circling and turning trials tell them apart (docs/diagnosis.md).
DESIGNS = {"head_drag": "none,J2x2", "lateral_friction_asymmetry": "nonex2,noneb4,noneb-4"}
REFERENCE = {  # a clearly visible strength on DESIGN's 3 s trials (diagnose.probe_visibility)
    "wheel_toe": ("wheel_toe_deg", 1.5),
    # A failed joint's dry friction does almost nothing below ~0.4 N m on joint-7 trials and makes it stick
    # above (replays of a noise-free trial at 0 and 0.3 differ by 0.2 standard deviations), whatever the
    # linear probe's 0.26 says: 0.6 is a clearly visible strength.
    "joint_coulomb_friction": ("joint_coulomb_Nm", 0.6),
    "head_drag": ("head_drag_mu", 0.5),
    "lateral_friction_asymmetry": ("lateral_friction_asymmetry", 0.5),
    "longitudinal_friction_asymmetry": ("longitudinal_friction_asymmetry", 0.5),
    "module_payload": ("payload_kg", 0.8),
    "ground_slope": ("ground_slope_deg", 4.0),  # the diagnosis searches floors within 5 deg (effects.GroundSlope)
    "stribeck_friction": ("stribeck_ratio", 2.0),
    "potentiometer_offset_j9": ("potentiometer_offset_j9_deg", 2.0),  # a sensor fault: joint 9 reads 2 deg high
    "potentiometer_gain_j9": ("potentiometer_gain_j9_error", 0.04),  # a sensor fault: joint 9 reads 4% large
    "camera_delay": ("camera_delay_s", 0.1),  # a sensor fault: the camera's frames are stamped 0.1 s late
}


def hidden_effects(effect, strength) -> dict:
    """The truth's effects of a row: `effect` at REFERENCE's strength times `strength` (none for None)."""
    return {} if effect is None else {REFERENCE[effect][0]: REFERENCE[effect][1] * strength}


def make_campaign(folder, effect, strength, seed, seconds, design=DESIGN, truth_model="drake", record_after_s=0.0):
    """Synthesize the campaign of one row into `folder`, with hidden_effects(effect, strength)."""
    effects = hidden_effects(effect, strength)
    synthesize_campaign(
        folder,
        design=parse_design(design),
        effects=effects,
        seed=seed,
        truth_model=truth_model,
        record_after_s=record_after_s,
        stop=Stop(line_x_m=None, revolutions=None, time_limit_s=seconds),
    )
    return effects


def is_right(verdict, accepted, effect) -> bool:
    """The whole right answer: no_missing_effect with nothing hidden, effect_found with the hidden effect alone."""
    return verdict == ("effect_found" if effect else "no_missing_effect") and set(accepted) == (
        {effect} if effect else set()
    )


def final_estimate(result, effect: str, effects: dict) -> tuple:
    """(the final model's estimate of `effect`, hidden at `effects`, in its fitted coordinates: name -> [value, se],
    or None if it has none; whether every coordinate's 95% interval holds the truth, or None)."""
    truth = LIBRARY[effect].coordinates(effect_values(effects, LIBRARY[effect]))
    estimate = {k: result.final_coordinates[k] for k in truth if k in result.final_coordinates} or None
    inside = all(abs(v - truth[k]) <= Z95 * se for k, (v, se) in estimate.items()) if estimate else None
    return estimate, inside


def score(result, effect, effects) -> dict:
    """What a row records of a diagnosis with `effect` hidden (at `effects`)."""
    first = result.candidates[0] if result.candidates else None
    # The final model's estimate (after every round's refit), in the fitted coordinates.
    estimate, inside = final_estimate(result, effect, effects) if effect is not None else (None, None)
    return {
        "verdict": str(result.verdict),
        "accepted": result.accepted,
        "right": is_right(result.verdict, result.accepted, effect),
        "first": first.name if first else None,
        "inside_interval": inside,
        "estimate": estimate,
        "first_round": [
            [c.name, c.status, c.coordinates, (c.simulated or {}).get("held_out_reduction")] for c in result.candidates
        ],
        "partial": [r.partial for r in result.rounds if r.partial],
        "final_effects": result.effects,
        "simulations": result.simulations,
    }


def one(
    effect,
    strength,
    seed,
    seconds,
    workers,
    held=(),
    design=DESIGN,
    truth_model="drake",
    record_after_s=0.0,
    candidates="physical",
    start_rates="rest",
) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        effects = make_campaign(tmp, effect, strength, seed, seconds, design, truth_model, record_after_s)
        campaign = load_campaign(tmp)
        start = time.perf_counter()
        result = diagnose(
            campaign,
            friction=Friction(),
            workers=workers,
            probe_study=False,
            held=held,
            candidates=candidates.split(","),
            start_rates=start_rates,
        )
    return {
        "effect": effect,
        "strength": strength,
        "seed": seed,
        "design": design,
        "truth_model": truth_model,
        "record_after_s": record_after_s,
        "candidates": candidates,
        "start_rates": start_rates,
        **score(result, effect, effects),
        "wall_s": time.perf_counter() - start,
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--time-limit-s", type=float, default=3.0)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--effects", default=",".join(REFERENCE))
    parser.add_argument("--strengths", default="0.5,1,1.5")
    parser.add_argument("--hold-friction", action="store_true", help="hold the friction at the truth (as the tests)")
    parser.add_argument(
        "--design",
        help="the trials of every campaign, e.g. none,none@70,noneb4,J7x2,J13 (default: "
        f"{DESIGN}, or the effect's own: {DESIGNS})",
    )
    parser.add_argument(
        "--truth-model",
        choices=TRUTH_MODELS,
        default="drake",
        help="what makes the campaigns (default: drake, this project's model)",
    )
    parser.add_argument("--record-after-s", type=float, default=0.0, help="the recording starts this late")
    parser.add_argument(
        "--candidates",
        default="physical",
        help="what the diagnosis considers: physical (default), sensor, or effect names (comma list)",
    )
    parser.add_argument(
        "--start-rates",
        choices=START_MODES,
        default="rest",
        help="the trials' head rates at t = 0: rest (the protocol's convention) or fit (nuisance "
        "coordinates of every fit)",
    )
    parser.add_argument("--out", type=Path, default=rows_file("diagnosis"), help="the rows (a rerun resumes)")
    args = parser.parse_args()
    made = (args.truth_model, args.record_after_s, args.candidates, args.start_rates)
    done = {}
    for row in load_rows(args.out):
        if (
            row.get("truth_model", "drake"),
            row.get("record_after_s", 0.0),
            row.get("candidates", "physical"),
            row.get("start_rates", "rest"),
        ) == made:  # a study per truth, candidate set and start
            done[(row["effect"], row["strength"], row["seed"], row.get("design", DESIGN))] = row
    effects = args.effects.split(",")
    unknown = [e for e in effects if e not in REFERENCE]
    if unknown:
        raise SystemExit(f"--effects: unknown effect {unknown[0]!r} (known: {', '.join(REFERENCE)})")
    if args.truth_model == "reference":
        inexpressible = [e for e in effects if REFERENCE[e][0] not in REFERENCE_EFFECTS]
        if inexpressible:
            raise SystemExit(
                f"--effects: the reference model cannot make {inexpressible[0]!r} (it makes: "
                f"{', '.join(e for e in REFERENCE if REFERENCE[e][0] in REFERENCE_EFFECTS)})"
            )
    try:
        strengths = [float(k) for k in args.strengths.split(",")]
    except ValueError:
        raise SystemExit(f"--strengths: cannot read {args.strengths!r} (expected numbers such as 0.5,1,2)") from None
    for e in effects:  # an effect beyond its physical domain stops here, not in the middle of the study
        key, reference = REFERENCE[e]
        domain = parameter(key)
        for k in strengths:
            if not domain.lower <= reference * k <= domain.upper:
                raise SystemExit(
                    f"--strengths: {args.strengths!r} puts {key} at {reference * k:g}, outside "
                    f"[{domain.lower:g}, {domain.upper:g}] (its reference strength is {reference:g})"
                )
    try:
        candidate_names(args.candidates.split(","))
    except ValueError as error:
        raise SystemExit(f"--candidates: {error}") from None
    jobs = [
        (e, k, s, args.design or DESIGNS.get(e, DESIGN)) for e in effects for k in strengths for s in range(args.seeds)
    ]
    designs = list(dict.fromkeys(j[3] for j in jobs))
    for design in designs:
        parse_design(design)  # a bad design stops here, with its one-line error, before any campaign runs
    jobs = [(None, 0.0, s, d) for d in designs for s in range(args.seeds)] + jobs
    for n, job in enumerate(jobs):
        if job in done:
            continue
        effect, strength, seed, design = job
        row = one(
            effect,
            strength,
            seed,
            args.time_limit_s,
            args.workers,
            FRICTION_NAMES if args.hold_friction else (),
            design,
            *made,
        )
        done[job] = row
        append_row(args.out, row)
        print(
            f"[{n + 1}/{len(jobs)}] {effect or 'no effect'} x{strength:g} seed {seed} ({design}): "
            f"{row['verdict']}, accepted {row['accepted']}, first {row['first']}, {row['wall_s']:.0f} s",
            flush=True,
        )
    print(
        f"\ncampaigns made by {args.truth_model}"
        + (f", recorded {args.record_after_s:g} s late" if args.record_after_s else "")
        + f"; candidates: {args.candidates}"
    )
    print(
        f"{'hidden effect':<34}{'design':>11}{'strength':>9}{'accepted':>10}{'first':>7}{'in CI':>7}{'wrong':>7}"
        f"{'partial':>9}{'right':>7}{'mean s':>8}"
    )
    groups = {}
    for (effect, strength, _, design), row in done.items():
        groups.setdefault((effect, strength, design), []).append(row)
    for (effect, strength, design), rows in sorted(groups.items(), key=lambda kv: (kv[0][0] or "", *kv[0][1:])):
        n = len(rows)
        hit = sum(effect in r["accepted"] for r in rows) if effect else 0
        first = sum(r["first"] == effect for r in rows) if effect else 0
        inside = sum(bool(r["inside_interval"]) for r in rows) if effect else 0
        wrong = sum(any(a != effect for a in r["accepted"]) for r in rows)
        partial = sum(bool(r.get("partial")) for r in rows)
        right = sum(is_right(r["verdict"], r["accepted"], effect) for r in rows)  # the whole answer
        print(
            f"{effect or 'none (false alarms)':<34}{design:>11}{strength:>9g}{hit:>7}/{n}{first:>5}/{n}"
            f"{inside:>5}/{n}{wrong:>5}/{n}{partial:>7}/{n}{right:>5}/{n}{sum(r['wall_s'] for r in rows) / n:>8.0f}"
        )


if __name__ == "__main__":
    main()
