"""A diagnosis threshold chosen on some seeds and reported on others: Thresholds.p_accept, the Wald test every
candidate must pass, over a family of candidates (the sensor faults add 28).

    python benchmarks/calibrate.py [--calibration-seeds 0-5] [--report-seeds 12-17] [--p-accept 2.7e-3,1e-4]
                                   [--cases none,wheel_toe,potentiometer_gain_j9x2] [--truth-models drake,reference]
                                   [--candidates physical,sensor] [--start-rates fit] [--workers 2]
                                   [--out benchmarks/out/calibrate] [--markdown]

Each campaign (3 s `none,J7x2`, friction held, as benchmarks/diagnosis.py makes them; a case is an effect of
diagnosis.REFERENCE, `xS` scaling its strength) is synthesized once and diagnosed once per threshold value through
one checkpoint, so another value replays only what it changes. A verdict is right when it is the whole answer
(no_missing_effect with nothing hidden; effect_found with the hidden effect alone). The value with the most right
verdicts on the calibration seeds is chosen (ties: the stricter); every value's rates are reported on the report
seeds, which chose nothing. Rows stream to benchmarks/rows/calibrate.jsonl: a rerun resumes. --markdown writes the
table into docs/diagnosis.md.
"""

import argparse
import sys
import time
from pathlib import Path

import diagnosis
from doc_blocks import REPO_ROOT, append_row, check_block, load_rows, rows_file, write_block

from rc1_drake.config import FRICTION_NAMES, Friction
from rc1_drake.diagnose import Thresholds, diagnose
from rc1_drake.measurements import load_campaign

PAGE, BLOCK, WRITER = REPO_ROOT / "docs" / "diagnosis.md", "calibration-table", "benchmarks/calibrate.py --markdown"
SECONDS = 3.0


def seeds(text: str) -> list:
    """'0-5' or '0,2,4' -> the seeds."""
    out = []
    for part in text.split(","):
        low, _, high = part.partition("-")
        out += list(range(int(low), int(high or low) + 1))
    return out


def case(text: str) -> tuple:
    """'none' -> (None, 0.0); 'wheel_toe' -> (effect, 1.0); 'potentiometer_gain_j9x2' -> (effect, 2.0)."""
    name, _, scale = text.rpartition("x") if text.rsplit("x", 1)[-1].replace(".", "").isdigit() else (text, "", "1")
    if name == "none":
        return None, 0.0
    if name not in diagnosis.REFERENCE:
        raise SystemExit(f"--cases: unknown effect {name!r} (known: none, {', '.join(diagnosis.REFERENCE)})")
    return name, float(scale)


def row(args, model: str, label: str, seed: int, p_accept: float) -> dict:
    """One campaign diagnosed at one threshold; its campaign and checkpoint are kept under --out."""
    effect, strength = case(label)
    folder = args.out / "campaigns" / f"{model}-{label}-{seed}"
    if not folder.is_dir():
        diagnosis.make_campaign(folder, effect, strength, seed, SECONDS, truth_model=model)
    effects = diagnosis.hidden_effects(effect, strength)
    started = time.perf_counter()
    result = diagnose(
        load_campaign(folder),
        friction=Friction(),
        held=FRICTION_NAMES,
        workers=args.workers,
        probe_study=False,
        candidates=args.candidates.split(","),
        start_rates=args.start_rates,
        thresholds=Thresholds(p_accept=p_accept),
        checkpoint=args.out / "checkpoints" / folder.name,
    )
    scored = diagnosis.score(result, effect, effects)
    return {
        "model": model,
        "case": label,
        "seed": seed,
        "p_accept": p_accept,
        "resumed": result.resumed,
        "wall_s": time.perf_counter() - started,
        **{k: scored[k] for k in ("verdict", "accepted", "right")},
    }


def table(rows: list, args) -> str:
    def right(p, chosen_seeds, model=None, label=None):
        rs = [
            r
            for r in rows
            if r["p_accept"] == p
            and r["seed"] in chosen_seeds
            and (model is None or r["model"] == model)
            and (label is None or r["case"] == label)
        ]
        return sum(r["right"] for r in rs), len(rs)

    calibration = {p: right(p, args.calibration_seeds)[0] for p in args.p_accept}
    chosen = max(args.p_accept, key=lambda p: (calibration[p], -p))
    lines = [
        f"Measured by `python {WRITER}` (last run {time.strftime('%Y-%m-%d')}; 3 s `none,J7x2`, friction held, "
        f"candidates {args.candidates}, start rates {args.start_rates}). Right verdicts (the whole answer) for each "
        f"Wald threshold p_accept: chosen on seeds {args.calibration_seeds[0]}-{args.calibration_seeds[-1]} "
        f"(most right, ties to the stricter: **{chosen:g}**), reported on seeds "
        f"{args.report_seeds[0]}-{args.report_seeds[-1]}, which chose nothing.",
        "",
        "| p_accept | calibration: right | "
        + " | ".join(f"report, {label}, {model}" for label in args.cases for model in args.truth_models)
        + " | report: right |",
        "|---|---|" + "---|" * (len(args.cases) * len(args.truth_models) + 1),
    ]
    for p in args.p_accept:
        n_cal = right(p, args.calibration_seeds)[1]
        cells = ["{}/{}".format(*right(p, args.report_seeds, m, c)) for c in args.cases for m in args.truth_models]
        mark = " (chosen)" if p == chosen else " (default)" if p == Thresholds().p_accept else ""
        lines.append(
            f"| {p:g}{mark} | {calibration[p]}/{n_cal} | "
            + " | ".join(cells)
            + " | {}/{} |".format(*right(p, args.report_seeds))
        )
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calibration-seeds", type=seeds, default=seeds("0-5"))
    parser.add_argument("--report-seeds", type=seeds, default=seeds("12-17"))
    parser.add_argument("--p-accept", type=lambda t: [float(v) for v in t.split(",")], default=[2.7e-3, 1e-4])
    parser.add_argument(
        "--cases", type=lambda t: t.split(","), default=["none", "wheel_toe", "potentiometer_gain_j9x2"]
    )
    parser.add_argument("--truth-models", type=lambda t: t.split(","), default=["drake", "reference"])
    parser.add_argument("--candidates", default="physical,sensor")
    parser.add_argument("--start-rates", default="fit")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path, default=REPO_ROOT / "benchmarks" / "out" / "calibrate")
    parser.add_argument("--markdown", action="store_true", help="write the table into docs/diagnosis.md")
    args = parser.parse_args()
    if set(args.calibration_seeds) & set(args.report_seeds):
        parser.error("--calibration-seeds and --report-seeds must not share a seed")
    for label in args.cases:
        case(label)
    if args.markdown:
        check_block(PAGE, BLOCK, WRITER)
    args.out.mkdir(parents=True, exist_ok=True)
    path = rows_file("calibrate")
    done = {(r["model"], r["case"], r["seed"], r["p_accept"]): r for r in load_rows(path)}
    jobs = [
        (m, c, s, p)
        for s in args.calibration_seeds + args.report_seeds
        for m in args.truth_models
        for c in args.cases
        for p in args.p_accept
    ]
    for n, job in enumerate(jobs):
        if job not in done:
            done[job] = row(args, *job)
            append_row(path, done[job])
        r = done[job]
        print(
            f"[{n + 1}/{len(jobs)}] {' '.join(map(str, job))}: {r['verdict']} {r['accepted']} "
            f"({r['wall_s']:.0f} s, {r['resumed']} replays resumed)",
            file=sys.stderr,
            flush=True,
        )
    text = table([done[j] for j in jobs], args)
    print(text)
    if args.markdown:
        write_block(PAGE, BLOCK, WRITER, text)


if __name__ == "__main__":
    main()
