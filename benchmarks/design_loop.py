"""Does the next experiment close the loop (issue 68, item 5)? Rounds of diagnose -> choose trials -> run them on the
campaign's own truth -> diagnose the union, from the paper-design grid's campaigns.

    python benchmarks/design_loop.py [--seeds 102-105] [--cells CELL,...] [--ways designed,paper,probe,random]
                                     [--rounds 2] [--budget 4] [--designs 8] [--workers 2]
                                     [--out benchmarks/out/design_loop] [--markdown] [--table-only]

Round 0 is benchmarks/paper_rates.py's campaign of the cell and seed (the paper's design, 2 trials a case; its cells:
the nulls, each library effect at its reference strength, the mechanisms outside the candidates, by this model and by
reference.py), diagnosed as `rc1 diagnose --start-rates fit` does. While its verdict is neither `effect_found` nor
`no_missing_effect`, and for at most --rounds rounds, --budget trials are added, chosen one of four ways on the same
budget:

- designed: `rc1 design`'s plan from the last diagnosis's JSON (--designs drawn designs beside design.PAPER_KINDS);
- paper: one more of each of the paper's cases (no failure, J7, J13, J7 with its bias; to the 3.18 m line);
- probe: the kind the probe study names (diagnose.probe) for the open pair, or that best sees the first effect
  left undetectable, repeated to the budget as 10 s trials;
- random: feasible designs drawn over the lab (design.sampled_designs), redrawn where the truth's head path would
  leave the floor.

The added trials are synthesized from the cell's own truth (its model, friction, effects, sampling; new noise) and the
union is diagnosed again; every replay is checkpointed per campaign, so the trials already diagnosed keep theirs where
the model has not moved. Scored as the grid scores (paper_rates.classify): right, wrong (an effect accepted that is
not hidden), and the accepted effect's intervals holding the truth, after each round. Seeds 100-101 (paper_rates.CHOSE)
chose the grid's rules and are tabled apart. A loop's rounds stream to OUT as they end, and its row to
benchmarks/rows/design_loop.jsonl when it is done: a rerun resumes. --markdown writes the table into docs/design.md
and its summary line into the README.
"""

import argparse
import dataclasses
import json
import shutil
import time
from pathlib import Path

import numpy as np
import paper_rates as grid
from calibrate import seeds as parse_seeds
from doc_blocks import REPO_ROOT, append_row, check_block, load_rows, rows_file, write_block

from rc1_drake.cli.options import jsonable
from rc1_drake.config import Friction, Rc1Error, Stop
from rc1_drake.design import Lab, TrialDesign, design_trials, open_hypotheses
from rc1_drake.design.lab import off_the_floor, sampled_designs
from rc1_drake.diagnose import diagnose
from rc1_drake.diagnose.probe import PROBE_KINDS, probe_visibility, telling_apart
from rc1_drake.measurements import load_campaign, merged_campaigns
from rc1_drake.synthesize import Noise, synthesize_campaign

PAGE, BLOCK, WRITER = REPO_ROOT / "docs" / "design.md", "design-loop-table", "benchmarks/design_loop.py --markdown"
README, SUMMARY = REPO_ROOT / "README.md", "design-loop-summary"
ROWS = rows_file("design_loop")
WAYS = ("designed", "paper", "probe", "random")
# The planner's hypotheses as `designed` rows name them; rows without one were planned against the tied candidates
# alone (before design.hypotheses took every candidate that helped) and are tabled apart as EARLIER_DESIGNED.
PLANNER = "every candidate that helped"
EARLIER_DESIGNED = "designed, against the tied candidates only"
DECIDED = ("effect_found", "no_missing_effect")
TRIALS_PER_CASE = 2  # round 0: the grid's campaign
# The cells in the order a partial table is most worth having: another model's data first, then this model's.
DEFAULT_CELLS = [
    "none (reference rough 50 Hz)",
    "wheel_toe x1 (reference rough 50 Hz)",
    "none",
    *(f"{e} x1" for e in grid.PHYSICAL),
    "compliant_stop k 20 (outside)",
    "head_cantilever 1 (outside)",
]


def lab_of(cell: grid.Cell) -> Lab:
    """The lab that recorded the cell's campaign: the paper's floor and failures, the campaign's sampling."""
    sampling = grid.SAMPLING[cell.sampling]
    noise = sampling.get("noise", Noise())
    return Lab(sample_period_s=sampling.get("sample_period_s", 0.01), potentiometer_deg=noise.potentiometer_deg)


def synthesize_trials(folder: Path, cell: grid.Cell, cases, seed: int, stop=None) -> None:
    """`cases` run on the cell's truth into `folder` (its sampling, new noise from `seed`)."""
    friction = Friction(**dict(cell.friction))
    synthesize_campaign(folder, design=cases, effects=cell.hidden, seed=seed, truth_model=cell.truth_model,
                        stop=stop, friction=friction, **grid.SAMPLING[cell.sampling])  # fmt: skip


def probe_designs(diagnosis: dict, budget: int, workers: int) -> list[TrialDesign]:
    """The probe study's kind for the diagnosis's open hypotheses (diagnose.probe), its trials repeated to `budget`."""
    names = list(dict.fromkeys(n for h in open_hypotheses(diagnosis) for n in h.owned))
    if not names:
        return []
    model = diagnosis["model"]
    study = probe_visibility(Friction(**model["friction"]), model["effects"], names, workers=workers)
    found = telling_apart(study, names[0], names[1]) if len(names) > 1 else None
    if found is not None:
        kind = found[0]
    else:
        kind = min(study, key=lambda k: min(study[k][names[0]]["detectable_strength"].values()))
    paper = TrialDesign.frequency_deg_s  # a kind without its own frequency runs the paper's gait
    trials = [TrialDesign(tuple(j), frequency_deg_s=f or paper, bias_deg=bias) for j, f, bias in PROBE_KINDS[kind]]
    return [trials[k % len(trials)] for k in range(budget)]


def random_designs(cell: grid.Cell, lab: Lab, budget: int, seed: int, folder: Path) -> list[TrialDesign]:
    """`budget` feasible drawn designs whose head path on the truth stays on the floor and whose run the loader takes (a
    lab would stop a trial that leaves it, and draw another)."""
    shutil.rmtree(folder, ignore_errors=True)
    rng, out = np.random.default_rng([68, seed]), []
    for k in range(50 * budget):
        if len(out) == budget:
            break
        draw = sampled_designs(lab, 1, rng)[0]
        synthesize_trials(folder / f"draw_{k}", cell, [draw.case()], seed)
        try:
            trial = load_campaign(folder / f"draw_{k}").trials[0]
        except Rc1Error:  # its run fails the loader's checks (a joint faster than a servo): the plan drops these too
            continue
        if off_the_floor(trial.t, trial.camera[:, :2], trial.head_yaw_rate, lab) is None:
            out.append(draw)
    return out


def next_trials(way: str, cell: grid.Cell, diagnosis: dict, args, seed: int, folder: Path) -> tuple:
    """(the cases to run next, the stop they run to, the plan's own numbers) for way `way`."""
    lab = lab_of(cell)
    if way == "paper":
        return grid.design(1), Stop(), {}
    if way == "probe":
        return [d.case() for d in probe_designs(diagnosis, args.budget, args.workers)], None, {}
    if way == "random":
        return [d.case() for d in random_designs(cell, lab, args.budget, seed, folder / "draws")], None, {}
    plan = design_trials(diagnosis=diagnosis, lab=lab, budget=args.budget, candidates=args.designs, seed=seed,
                         replicates=0, workers=args.workers)  # fmt: skip
    plan.write(folder / "plan")
    return [d.case() for d in plan.chosen], None, {"plan_s": plan.wall_s, "plan_simulations": plan.simulations}


def diagnosed(folders, cell: grid.Cell, args, checkpoint: Path, record: Path) -> dict:
    """The diagnosis of the union of `folders` (its JSON) and its round scored as the grid scores, kept in `record`."""
    if record.is_file():
        return json.loads(record.read_text())
    record.parent.mkdir(parents=True, exist_ok=True)  # before the long work: nothing measured is lost
    started = time.perf_counter()
    campaign = merged_campaigns(folders)
    result = diagnose(campaign, friction=Friction(), workers=args.workers, probe_study=False, start_rates="fit",
                      checkpoint=checkpoint)  # fmt: skip
    scored = {
        "verdict": str(result.verdict),
        "accepted": result.accepted,
        "outcome": grid.classify(str(result.verdict), result.accepted, cell.expected),
        "coverage": grid.coverage(result, cell),
        "trials": len(campaign.trials),
        "floor_s": float(sum(t.t[-1] - t.t[0] for t in campaign.trials)),
        "diagnose_s": time.perf_counter() - started,
        "simulations": result.simulations,
    }
    saved = {"diagnosis": json.loads(json.dumps(result.to_json(), default=jsonable)), "scored": scored}
    record.with_suffix(".partial").write_text(json.dumps(saved) + "\n")
    record.with_suffix(".partial").rename(record)
    return saved


def loop(cell: grid.Cell, seed: int, way: str, args) -> dict:
    """One cell, seed and way: its rounds, each scored, resumed from OUT where an earlier run left them."""
    name = f"{cell.label.replace(' ', '_')}-{seed}"
    base, home = args.out / "campaigns" / name, args.out / "loops" / name
    folder_of_way = f"{way}-{PLANNER.replace(' ', '_')}" if way == "designed" else way
    if not base.is_dir():
        synthesize_trials(base, cell, grid.design(TRIALS_PER_CASE), seed, Stop())
    checkpoint = args.out / "checkpoints" / name  # shared by the ways and rounds: a replay's key is its job
    folders, rounds, extras, saved = [base], [], [], None
    for r in range(args.rounds + 1):
        if r:
            folder = home / folder_of_way / f"round_{r}"
            if not (folder / "trials").is_dir():  # made whole or made again
                cases, stop, extra = next_trials(way, cell, saved["diagnosis"], args, 1000 * seed + r, folder)
                if not cases:
                    raise SystemExit(f"design_loop: {cell.label} seed {seed}, round {r}: {way} chose no trial")
                shutil.rmtree(folder / "partial", ignore_errors=True)
                synthesize_trials(folder / "partial", cell, cases, 1000 * seed + r, stop)
                (folder / "chosen.json").write_text(
                    json.dumps({"cases": [dataclasses.asdict(c) for c in cases], **extra})
                )
                (folder / "partial").rename(folder / "trials")
            folders.append(folder / "trials")
            extras.append(json.loads((folder / "chosen.json").read_text()))
        saved = diagnosed(folders, cell, args, checkpoint, home / (folder_of_way if r else "") / f"round_{r}.json")
        rounds.append(saved["scored"])
        if saved["scored"]["verdict"] in DECIDED:
            break
    row = {"cell": cell.label, "seed": seed, "way": way, "budget": args.budget, "rounds": rounds, "chosen": extras}
    return row | ({"planner": PLANNER} if way == "designed" else {})


def way_of(row: dict) -> str:
    """The row's way, a designed row of an earlier planner as EARLIER_DESIGNED."""
    earlier = row["way"] == "designed" and row.get("planner") != PLANNER
    return EARLIER_DESIGNED if earlier else row["way"]


def _by_round(row: dict, k: int) -> dict:
    """The loop's state after round k (its last round, where it stopped before k)."""
    return row["rounds"][min(k, len(row["rounds"]) - 1)]


def table(rows: list, rounds: int) -> str:
    reported = [r for r in rows if r["seed"] not in grid.CHOSE]
    seeds = sorted({r["seed"] for r in reported})
    span = f"{seeds[0]}-{seeds[-1]}" if seeds else "-"
    head = " | ".join(f"right after {k}" for k in range(rounds + 1))
    lines = [
        f"Measured by `python {WRITER}` over reported seeds {span} (budget {rows[0]['budget'] if rows else '-'} trials"
        " a round). Per cell and way of choosing the trials: loops, how many were right after each round (as the"
        " grid scores: the hidden library effect found alone, nothing accepted for a null or an effect outside the"
        " candidates), an effect accepted that is not hidden, the accepted effects' intervals holding the truth,"
        " trials and floor seconds added, median minutes a loop:",
        "",
        f"| cell | way | loops | {head} | wrong | intervals hold | trials added | floor s added | min |",
        "|---|---|---|" + "---|" * (rounds + 1) + "---|---|---|---|---|",
    ]
    for cell in dict.fromkeys(r["cell"] for r in reported):
        for way in (*WAYS, EARLIER_DESIGNED):
            mine = [r for r in reported if r["cell"] == cell and way_of(r) == way]
            if not mine:
                continue
            right = " | ".join(str(sum(_by_round(r, k)["outcome"] == "right" for r in mine)) for k in range(rounds + 1))
            wrong = sum(r["rounds"][-1]["outcome"] == "wrong" for r in mine)
            held = [h for r in mine for h in r["rounds"][-1]["coverage"]]
            added = [r["rounds"][-1]["trials"] - r["rounds"][0]["trials"] for r in mine]
            floor = [r["rounds"][-1]["floor_s"] - r["rounds"][0]["floor_s"] for r in mine]
            minutes = [r["wall_s"] / 60 for r in mine]
            lines.append(
                f"| {cell} | {way} | {len(mine)} | {right} | {wrong} | {sum(held)} of {len(held)} | "
                f"{np.mean(added):.1f} | {np.mean(floor):.0f} | {np.median(minutes):.1f} |"
            )
    return "\n".join(lines)


def summary(rows: list, rounds: int) -> str:
    """The README's line: per way, the loops right after the last round against those right at round 0."""
    reported = [r for r in rows if r["seed"] not in grid.CHOSE]
    seeds = sorted({r["seed"] for r in reported})
    if not seeds:
        return "The loop with designed trials (`benchmarks/design_loop.py`): not yet measured on reported seeds."
    parts = []
    for way in WAYS:
        mine = [r for r in reported if way_of(r) == way]
        if mine:
            right = sum(_by_round(r, rounds)["outcome"] == "right" for r in mine)
            parts.append(f"{way} {right} of {len(mine)}")
    first = way_of(reported[0])  # round 0 is every way's: counted on one
    start = sum(r["rounds"][0]["outcome"] == "right" for r in reported if way_of(r) == first)
    cells = len({r["cell"] for r in reported})
    return (
        f"Closing the loop (`benchmarks/design_loop.py`, {cells} cells, seeds {seeds[0]}-{seeds[-1]}, up to {rounds}"
        f" rounds of {reported[0]['budget']} trials): right after them, {', '.join(parts)} (right before them:"
        f" {start} of {sum(way_of(r) == first for r in reported)}); docs/design.md."
    )


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", default="102-105")
    parser.add_argument("--cells", default=",".join(DEFAULT_CELLS))
    parser.add_argument("--ways", default=",".join(WAYS))
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--budget", type=int, default=4)
    parser.add_argument("--designs", type=int, default=8, help="designs drawn beside design.PAPER_KINDS")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path, default=REPO_ROOT / "benchmarks" / "out" / "design_loop")
    parser.add_argument("--markdown", action="store_true")
    parser.add_argument("--table-only", action="store_true")
    args = parser.parse_args()
    cells = {c.label: c for c in grid.CELLS}
    chosen, ways = args.cells.split(","), args.ways.split(",")
    if unknown := [c for c in chosen if c not in cells] + [w for w in ways if w not in WAYS]:
        raise SystemExit(f"design_loop: unknown cell or way {', '.join(unknown)} (cells: paper_rates.CELLS)")
    if args.markdown:
        check_block(PAGE, BLOCK, WRITER)
        check_block(README, SUMMARY, WRITER)
    args.out.mkdir(parents=True, exist_ok=True)
    done = {(r["cell"], r["seed"], way_of(r)) for r in load_rows(ROWS) if r["budget"] == args.budget}
    jobs = [(c, s, w) for s in parse_seeds(args.seeds) for c in chosen for w in ways if (c, s, w) not in done]
    for k, (cell, seed, way) in enumerate([] if args.table_only else jobs, 1):
        started = time.perf_counter()
        row = loop(cells[cell], seed, way, args) | {"rounds_asked": args.rounds}
        row["wall_s"] = time.perf_counter() - started  # a resumed loop's: this run's part alone
        append_row(ROWS, row)
        ends = " -> ".join(r["outcome"] for r in row["rounds"])
        print(f"[{k}/{len(jobs)}] {cell} seed {seed} {way}: {ends}, {row['wall_s'] / 60:.1f} min", flush=True)
    text = table(load_rows(ROWS), args.rounds)
    print(text)
    if args.markdown:
        write_block(PAGE, BLOCK, WRITER, text)
        write_block(README, SUMMARY, WRITER, summary(load_rows(ROWS), args.rounds))


if __name__ == "__main__":
    main()
