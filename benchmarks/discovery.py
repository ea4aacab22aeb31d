"""How often discovery names what the model is missing (issue 43 item 4): seeded campaigns with an effect hidden
that the model discovery starts from lacks.

    python benchmarks/discovery.py [--seeds 0-5] [--calibrate 0-2] [--cells CELL,...] [--workers 2] [--angles]
                                   [--design short|paper] [--path-weights whitened|case] [--out DIR]
                                   [--markdown] [--table-only]

Every campaign (--design short): two no-failure and two joint-7 trials of 2 s, with the synthesizer's sensor noise
and start spread, made by this model or by reference.py (another model: kinematic joints, its own limits, the forces
written anew: reference.HiddenForces). Hidden, by both: nothing; a constant torque in the failed joint; a sideways
force at the head proportional to its rolling speed; the rear wheels (modules 11-14) with half the lateral viscous
friction; a tether dragging the tail (a Coulomb force at its end: the `study` effect, a shape the term library has);
a wheel toe (a library effect the model lacks: its force pattern must come back). reference.py also hides a floor
seam, a torque twisting the head as it crosses a fixed x: a shape no term has, so any term reported for it is wrong.

Discovery (diagnose/discover.py) runs from the paper's model with the truth's friction and its shipped gate: every
campaign's best sparse model is recorded with its held-out gain, and where it passes the gate, its terms refined and
checked by replaying each trial with terms fitted without it. The gate is chosen on the --calibrate seeds (MIN_FALL
kept; MIN_GAIN the smallest at or above the shipped one that gives no calibration null a term: only ever higher, so the
rows hold what any chosen gate reports) and the rates are reported on the other seeds, at the chosen and at the shipped
gate. Scored per campaign: whether a term is reported, and whether one is the right one (right place, right variable,
right sign: RIGHT), and how much of the held-out error the terms remove (by replay). Rows stream to
benchmarks/rows/NAME.jsonl (kept in the repository: a rerun resumes, from a fresh clone too); --markdown writes the
table into docs/diagnosis.md. --angles: discovery with the working joints' angles against the model's servos (`rc1
diagnose --discover --angles`), its rows apart (discovery-angles), its table printed (docs/diagnosis.md shows the
angles on the paper's design; give the page a block of that name to write it there). --design paper: the
paper's 21 trials of 10 s (the shipped campaign's design: no failure, joints 7, 13, 7 with a bias, 2), by default the
nulls and the tether only (PAPER_CELLS: about half an hour a campaign on 2 cores with the angles); its rows and table
its own too. --path-weights case: the path rows weighed by their case's scalar, as the diagnosis's fits, instead of
each trial's own input-noise covariance (discover.PATH_WEIGHTS): its rows apart (NAME-case), its table block its own."""

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np
from calibrate import seeds as parse_seeds  # benchmarks/ is on the path when this script runs
from doc_blocks import REPO_ROOT, append_row, check_block, load_rows, rows_file, write_block

from rc1_drake.config import Friction, Stop
from rc1_drake.diagnose import discover as discover_module
from rc1_drake.diagnose.discover import MIN_FALL, MIN_GAIN, best_gain, discover_campaign, passes_gate
from rc1_drake.measurements import load_campaign
from rc1_drake.synthesize import PAPER_DESIGN, Case, synthesize_campaign

PAGE = REPO_ROOT / "docs" / "diagnosis.md"
# A tether's force, averaged over the gait: a constant pull backward along the tail (right with a negative sign).
TETHER_MEAN = ("discrepancy_tail_push_long_N", -1)
# --design -> (the trials, their stop): short campaigns, or the paper's (the shipped campaign's 21 trials of 10 s)
DESIGNS = {
    "short": ([Case([], 2), Case([7], 2)], Stop(line_x_m=None, revolutions=None, time_limit_s=2.0)),
    "paper": (PAPER_DESIGN, None),
}
PAPER_CELLS = ("nothing", "tail tether 1 N", "nothing (reference.py)", "tail tether 1 N (reference.py)")
C_LAT = Friction().c_lat


@dataclasses.dataclass(frozen=True)
class Cell:
    label: str
    truth_model: str  # drake (this model) or reference
    hidden: dict  # effect parameter key -> value
    right: tuple | None  # (term key, sign) pairs a right answer names (any one); () nothing; None: no term is right


CELLS = [
    Cell("nothing", "drake", {}, ()),
    Cell("failed joint's constant torque 0.2 N m", "drake", {"discrepancy_failed_joint_bias_Nm": 0.2},
         (("discrepancy_failed_joint_bias_Nm", 1),)),
    Cell("head: sideways force 3 N s/m x rolling speed", "drake", {"discrepancy_head_side_by_long_N_s_per_m": 3.0},
         (("discrepancy_head_side_by_long_N_s_per_m", 1),)),
    Cell("rear wheels: half the lateral viscous friction", "drake",
         {"discrepancy_rear_drag_lat_N_s_per_m": -0.5 * C_LAT},
         (("discrepancy_rear_drag_lat_N_s_per_m", -1), ("discrepancy_rear_dry_lat_N", -1))),
    Cell("tail tether 1 N", "drake", {"tail_tether_N": 1.0},
         tuple((f"discrepancy_tail_{k}", 1) for k in ("dry_long_N", "dry_lat_N", "drag_long_N_s_per_m",
                                                         "drag_lat_N_s_per_m")) + (TETHER_MEAN,)),
    Cell("wheel toe 1.5 deg", "drake", {"wheel_toe_deg": 1.5},
         tuple((f"discrepancy_{g}_side_by_long_N_s_per_m", 1) for g in ("front", "middle", "rear"))),
    Cell("nothing (reference.py)", "reference", {}, ()),
    Cell("failed joint's constant torque 0.2 N m (reference.py)", "reference",
         {"discrepancy_failed_joint_bias_Nm": 0.2}, (("discrepancy_failed_joint_bias_Nm", 1),)),
    Cell("head: sideways force 3 N s/m x rolling speed (reference.py)", "reference",
         {"discrepancy_head_side_by_long_N_s_per_m": 3.0}, (("discrepancy_head_side_by_long_N_s_per_m", 1),)),
    Cell("rear wheels: half the lateral viscous friction (reference.py)", "reference",
         {"discrepancy_rear_drag_lat_N_s_per_m": -0.5 * C_LAT},
         (("discrepancy_rear_drag_lat_N_s_per_m", -1), ("discrepancy_rear_dry_lat_N", -1))),
    Cell("tail tether 1 N (reference.py)", "reference", {"tail_tether_N": 1.0},
         tuple((f"discrepancy_tail_{k}", 1) for k in ("dry_long_N", "dry_lat_N", "drag_long_N_s_per_m",
                                                         "drag_lat_N_s_per_m")) + (TETHER_MEAN,)),
    Cell("floor seam 2 N m at x = 0.3 m (reference.py)", "reference", {"floor_seam_Nm": 2.0, "floor_seam_x_m": 0.3},
         None),
    Cell("wheel toe 1.5 deg (reference.py)", "reference", {"wheel_toe_deg": 1.5},
         tuple((f"discrepancy_{g}_side_by_long_N_s_per_m", 1) for g in ("front", "middle", "rear"))),
]  # fmt: skip


def one(cell: Cell, seed: int, args) -> dict:
    folder = args.out / "campaigns" / f"{cell.label.replace(' ', '_').replace('/', '_')}-{seed}"
    if not folder.is_dir():
        design, stop = DESIGNS[args.design]
        synthesize_campaign(folder, design=design, effects=cell.hidden, seed=seed, truth_model=cell.truth_model,
                            stop=stop)  # fmt: skip
    started = time.perf_counter()
    found = discover_campaign(load_campaign(folder).trials, Friction(), {}, workers=args.workers, angles=args.angles)
    return {
        "cell": cell.label,
        "seed": seed,
        "gain": best_gain(found.path, found.cost_without),
        "cost_without": found.cost_without,
        "noise": found.noise,
        "input_noise": found.input_noise,
        "terms": [{"key": t.key, "value": t.value, "se": t.standard_error, "words": t.words} for t in found.terms],
        "tried": [{"key": t.key, "value": t.value, "se": t.standard_error} for t in found.tried],
        "fall": found.fall,
        "angle_fall": found.angle_fall,
        "simulations": found.simulations,
        "wall_s": time.perf_counter() - started,
    }


def reported(row: dict, min_fall: float, min_gain: float) -> bool:
    """Whether the gate (discover.passes_gate) lets the campaign's best sparse model through, a term of it stays
    off zero when refined, and its held-out replays remove MIN_FALL of the excess (discover reports nothing
    otherwise; rows made before either check kept their terms, and read the same here)."""
    gate = passes_gate(row["gain"], row["cost_without"], min_fall, min_gain, noise=row["noise"] + row["input_noise"])
    return gate and any(t["value"] for t in row["terms"]) and row["fall"] >= MIN_FALL


def is_right(row: dict, cell: Cell) -> bool:
    return any(t["key"] == key and t["value"] * sign > 0 for t in row["terms"] for key, sign in cell.right or ())


def chosen_gain(rows: list, calibration: set) -> float:
    """The smallest MIN_GAIN at or above the shipped one that gives no null campaign among the calibration seeds a
    term (MIN_FALL kept)."""
    nulls = [r for r in rows if r["seed"] in calibration and _cell(r).right == () and reported(r, MIN_FALL, 0.0)]
    return max([MIN_GAIN] + [1.0001 * r["gain"] for r in nulls])


def _cell(row: dict) -> Cell:
    return next(c for c in CELLS if c.label == row["cell"])


def table(rows: list, calibration: set, cells: list, writer: str) -> tuple:
    """(the markdown table on the reported seeds at the chosen and the shipped thresholds, its head)."""
    gain = chosen_gain(rows, calibration)
    shown = [r for r in rows if r["seed"] not in calibration]
    lines = [
        "| hidden | campaigns | a term reported (chosen / shipped gate) | the right term among them (chosen / "
        "shipped) | held-out error removed, median (where reported) | gain of the best sparse model, median |",
        "|---|---|---|---|---|---|",
    ]
    for cell in cells:
        mine = [r for r in shown if r["cell"] == cell.label]
        if not mine:
            continue
        cols = []
        for g in (gain, MIN_GAIN):
            on = [r for r in mine if reported(r, MIN_FALL, g)]
            cols.append((len(on), sum(is_right(r, cell) for r in on)))
        falls = [r["fall"] for r in mine if reported(r, MIN_FALL, gain)]  # of the excess over the noise floor
        lines.append(
            f"| {cell.label} | {len(mine)} | {cols[0][0]} / {cols[1][0]} | "
            + (f"{cols[0][1]} / {cols[1][1]}" if cell.right else "-")
            + f" | {f'{100 * np.median(falls):.0f}%' if falls else '-'} | {np.median([r['gain'] for r in mine]):.3g} |"
        )
    seeds = sorted({r["seed"] for r in shown})
    head = (
        f"Measured by `python {writer}` (last run {time.strftime('%Y-%m-%d')}): "
        f"{len(shown)} campaigns on seeds {', '.join(map(str, seeds)) or '-'}; the gate's MIN_GAIN chosen on seeds "
        f"{', '.join(map(str, sorted(calibration)))} ({gain:.3g}; shipped {MIN_GAIN:g}), MIN_FALL {MIN_FALL:g}:"
    )
    return "\n".join(lines), head


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="0-5")
    parser.add_argument("--calibrate", default="0-2", help="the seeds that choose the gate (reported: the others)")
    parser.add_argument("--cells", help="comma-separated cell labels (default: all)")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--angles", action="store_true", help="discovery with the angles (module docstring)")
    parser.add_argument("--design", choices=DESIGNS, default="short", help="the campaigns' trials (DESIGNS)")
    parser.add_argument(
        "--path-weights",
        choices=("whitened", "case"),
        default=discover_module.PATH_WEIGHTS,
        help="how a trial's path rows weigh (discover.PATH_WEIGHTS); not the default's: rows apart",
    )
    parser.add_argument("--out", type=Path, help="campaigns (default benchmarks/out/<block>; rows: benchmarks/rows)")
    parser.add_argument("--markdown", action="store_true", help="write the table into docs/diagnosis.md")
    parser.add_argument("--table-only", action="store_true", help="print (and write) the table of the rows so far")
    args = parser.parse_args()
    known = {c.label: c for c in CELLS}
    labels = args.cells.split(",") if args.cells else list(PAPER_CELLS if args.design == "paper" else known)
    if unknown := [c for c in labels if c not in known]:
        raise SystemExit(f"--cells: unknown cell {unknown[0]!r} (known: {', '.join(known)})")
    try:
        seed_list, calibration = parse_seeds(args.seeds), set(parse_seeds(args.calibrate))
    except ValueError:
        raise SystemExit(f"--seeds/--calibrate: cannot read {args.seeds!r} / {args.calibrate!r} (e.g. 0-5)") from None
    variant = args.path_weights != discover_module.PATH_WEIGHTS  # not the default's: rows and table apart
    discover_module.PATH_WEIGHTS = args.path_weights
    name = "discovery" + ("-angles" if args.angles else "") + ("-paper" if args.design == "paper" else "")
    name += f"-{args.path_weights}" if variant else ""
    flags = ("--angles " if args.angles else "") + ("--design paper " if args.design == "paper" else "")
    flags += f"--path-weights {args.path_weights} " if variant else ""
    block, writer = f"{name}-rates-table", f"benchmarks/discovery.py {flags}--markdown"
    if args.markdown:
        check_block(PAGE, block, writer)
    args.out = args.out or REPO_ROOT / "benchmarks" / "out" / name
    args.out.mkdir(parents=True, exist_ok=True)
    # Rows without the gate's noise floor were made before it: run again.
    rows = [r for r in load_rows(rows_file(name)) if "input_noise" in r]
    done = {(r["cell"], r["seed"]) for r in rows}
    jobs = [(known[c], s) for s in seed_list for c in labels if (c, s) not in done]
    for n, (cell, seed) in enumerate([] if args.table_only else jobs):
        row = one(cell, seed, args)
        rows.append(row)
        append_row(rows_file(name), row)
        terms = ", ".join(f"{t['key']}={t['value']:.3g}" for t in row["terms"]) or "none"
        cost = f"{row['wall_s'] / 60:.1f} min, {row['simulations']} jobs of ~100 runs"
        print(f"[{n + 1}/{len(jobs)}] {cell.label} seed {seed}: gain {row['gain']:.3g}, terms {terms}, fall "
              f"{100 * row['fall']:.0f}% ({cost})", flush=True)  # fmt: skip
    body, head = table(rows, calibration, [known[c] for c in labels], writer)
    print(head, body, sep="\n")
    if args.markdown and not any(r["seed"] not in calibration for r in rows):
        raise SystemExit(f"{rows_file(name)}: no rows on the reported seeds: the table in {PAGE} is left as it is")
    if args.markdown:
        write_block(PAGE, block, writer, head + "\n\n" + body)


if __name__ == "__main__":
    main()
