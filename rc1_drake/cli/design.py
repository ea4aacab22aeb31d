"""`rc1 design`: the next trials that tell a diagnosis's open hypotheses apart (issue 68), as a plan a lab runs."""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

from ..config import Rc1Error
from .options import add_start_rates, jsonable, loaded_campaign, positive_int, whole_number


def add_design(sub) -> None:
    d = sub.add_parser("design", help="design the next trials: those that best tell the diagnosis's open "
                       "hypotheses apart, written as scenario files and a plan")  # fmt: skip
    d.add_argument("campaign", type=Path, help="the campaign (diagnosed first unless --diagnosis is given)")
    d.add_argument("--diagnosis", type=Path, metavar="JSON", help="its diagnosis (rc1 diagnose --json)")
    d.add_argument("--budget", type=positive_int, default=4, metavar="N", help="trials to plan (default 4)")
    d.add_argument("--designs", type=lambda t: whole_number(t, 2), default=16, metavar="N",
                   help="designs drawn over the lab's space, beside the paper's kinds (default 16)")  # fmt: skip
    d.add_argument("--lab", type=Path, metavar="LAB.yaml", help="the lab's floor, failures and sensors "
                   "(default: the paper's experiment at the campaign's sample period; docs/design.md)")  # fmt: skip
    d.add_argument("--check", type=lambda t: whole_number(t, 0), default=1, metavar="K",
                   help="noisy replicates of the plan under each hypothesis, its prediction checked against them "
                   "(default 1; 0: none)")  # fmt: skip
    d.add_argument("--seed", type=int, default=0)
    d.add_argument("--out", type=Path, required=True, metavar="PLAN", help="the plan's folder")
    d.add_argument("--workers", type=positive_int, metavar="N", help="local processes (default: every core)")
    add_start_rates(d, default="fit", fit="for the diagnosis run first: three nuisance coordinates per trial")


def cmd_design(args) -> int:
    from ..design import Lab, design_trials, load_lab

    campaign = loaded_campaign(args.campaign)
    period = float(campaign.trials[0].t[1] - campaign.trials[0].t[0])
    lab = load_lab(args.lab) if args.lab else Lab(sample_period_s=round(period, 6))
    started = time.perf_counter()

    def progress(text):
        print(f"  [{time.perf_counter() - started:5.0f} s] {text}", file=sys.stderr, flush=True)

    if args.diagnosis:
        try:
            diagnosis = json.loads(args.diagnosis.read_text())
        except (OSError, json.JSONDecodeError) as error:
            raise Rc1Error(f"{args.diagnosis}: not a diagnosis's JSON ({error})") from None
        where = str(args.diagnosis)
    else:
        from ..diagnose import diagnose

        result = diagnose(campaign, workers=args.workers, progress=progress,
                          start_rates=args.start_rates, probe_study=False)  # fmt: skip
        diagnosis, where = jsonable(result.to_json()), f"the diagnosis of {args.campaign}"
        print(f"diagnosis: {result.verdict}: {result.explanation.splitlines()[0] if result.explanation else ''}")
    plan = design_trials(diagnosis=diagnosis, lab=lab, budget=args.budget, candidates=args.designs, seed=args.seed,
                         replicates=args.check, workers=args.workers, progress=progress, where=where)  # fmt: skip
    plan.write(args.out)
    print(plan.format())
    print(f"plan written to {args.out}/ (plan.json, trial_*.yaml, paths.png)")
    return 0
