"""The README's loop, measured on the shipped campaign: the figures of its five steps, written by this benchmark.

    python benchmarks/main_job.py [--out benchmarks/out/main_job] [--markdown]

1. compare: the paper's model (rc1_drake.config.Friction's defaults, no effect) replays every trial (Eq. 6);
2. where it fails: the worst trial, when its camera path passes 2 cm, the yaw-rate residual's whiteness;
3. diagnose: the README's main job itself (`rc1 diagnose data/paper_campaign`), its verdict and accepted effects
   beside the campaign's recorded truth (data/paper_campaign.truth.json, which the diagnosis never reads);
4. add it: the model file the diagnosis wrote;
5. compare again with that model file: the error falls.

--markdown writes the table into README.md (its loop-table markers) and the diagnosis's waterfall figure to
docs/waterfall.png.
"""

import argparse
import json
import shutil
import time
from pathlib import Path

from doc_blocks import REPO_ROOT, check_block, write_block

from rc1_drake.cli import main as rc1
from rc1_drake.compare import compare_campaign
from rc1_drake.config import Z95
from rc1_drake.measurements import load_campaign
from rc1_drake.residuals import where_it_fails
from rc1_drake.scenarios import load_model_file

CAMPAIGN = REPO_ROOT / "data" / "paper_campaign"
PAGE, BLOCK, WRITER = REPO_ROOT / "README.md", "loop-table", "benchmarks/main_job.py --markdown"


def table(before, where, diagnosis: dict, model, after, truth: dict, wall_s: float) -> str:
    worst = where.to_json()["trials"][0]
    final = diagnosis["final_coordinates"]  # the written model's values and standard errors
    found = (
        "; ".join(
            f"{k} = {final[k][0]:.2f} +- {Z95 * final[k][1]:.2f} (95%)"
            for k in diagnosis["model"]["effects"]
            if k in final
        )
        or "nothing"
    )
    hidden = ", ".join(f"{k} = {v:g}" for k, v in truth["effects"].items()) or "nothing"
    passes = worst["exceeds_2cm_at_s"]
    rows = [
        (
            "1. `rc1 compare data/paper_campaign`",
            f"the paper's model misses the final head positions by {before.mean_eq6_error_pct:.2f}% "
            f"of the distance travelled (mean Eq. 6 over {len(before.trials)} trials)",
        ),
        (
            "2. where it fails (printed by compare)",
            f"worst trial {worst['trial_id']} ({worst['case']}, {worst['eq6_error_pct']:.1f}%): "
            f"its camera path passes 2 cm "
            + (f"{passes:.2f} s after the start" if passes is not None else "never")
            + f"; yaw-rate residual lag-1 autocorrelation {worst['yaw_rate_lag1']:.2f} (white: 0)",
        ),
        (
            "3. `rc1 diagnose data/paper_campaign`",
            f"`{diagnosis['verdict']}`: accepted {', '.join(diagnosis['accepted_effects']) or 'nothing'}, "
            f"{found}; hidden in the truth: {hidden} "
            f"({diagnosis['simulations']} replays, {wall_s / 60:.1f} min)",
        ),
        (
            "4. add it: the model file",
            "effects "
            + (", ".join(f"{k} = {v:.3g}" for k, v in model.effects.items()) or "none")
            + "; friction refitted: "
            + ", ".join(f"{k} = {v:.3g}" for k, v in vars(model.friction).items()),
        ),
        (
            "5. `rc1 compare ... --model-file` it",
            f"mean Eq. 6 {before.mean_eq6_error_pct:.2f}% -> {after.mean_eq6_error_pct:.2f}%",
        ),
    ]
    lines = [
        f"Measured by `python {WRITER}` (last run {time.strftime('%Y-%m-%d')}):",
        "",
        "| step | on the shipped campaign |",
        "|---|---|",
    ]
    return "\n".join(lines + [f"| {step} | {text} |" for step, text in rows])


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=REPO_ROOT / "benchmarks" / "out" / "main_job")
    parser.add_argument("--markdown", action="store_true", help="write the table into README.md, the figure to docs/")
    args = parser.parse_args()
    if args.markdown:
        check_block(PAGE, BLOCK, WRITER)
    args.out.mkdir(parents=True, exist_ok=True)
    campaign = load_campaign(CAMPAIGN)
    before = compare_campaign(campaign)
    where = where_it_fails(before, campaign)
    # Timed from scratch: a checkpoint an interrupted run left would be resumed, and the time read short.
    checkpoint = args.out / "checkpoint"
    shutil.rmtree(checkpoint, ignore_errors=True)
    began = time.perf_counter()
    code = rc1(
        [
            "diagnose",
            str(CAMPAIGN),
            "--checkpoint",
            str(checkpoint),
            "--json",
            str(args.out / "diagnose.json"),
            "--plots",
            str(args.out / "plots"),
            "--out",
            str(args.out / "model.yaml"),
        ]
    )
    if code:
        raise SystemExit(f"rc1 diagnose ended with exit code {code}")
    wall = time.perf_counter() - began
    model = load_model_file(args.out / "model.yaml")
    after = compare_campaign(campaign, model.friction, effects=model.effects or None)
    truth = json.loads((REPO_ROOT / "data" / "paper_campaign.truth.json").read_text())
    text = table(before, where, json.loads((args.out / "diagnose.json").read_text()), model, after, truth, wall)
    print(text)
    if args.markdown:
        write_block(PAGE, BLOCK, WRITER, text)
        shutil.copyfile(args.out / "plots" / "waterfall.png", REPO_ROOT / "docs" / "waterfall.png")


if __name__ == "__main__":
    main()
