"""The next experiment (issue 68): the lab's space, the open hypotheses, the T-optimal distance and the plan."""

import dataclasses
import json
import math

import numpy as np
import pytest
import yaml
from pydrake.common.yaml import yaml_load_typed

from rc1_drake.cli import main
from rc1_drake.config import JOINT_LIMIT_DEG, Friction, Rc1Error, Scenario
from rc1_drake.design import Hypothesis, Lab, TrialDesign, load_lab, open_hypotheses
from rc1_drake.design.lab import MAX_FREQUENCY_DEG_S, infeasible, joint_speed_deg_s, off_the_floor, sampled_designs
from rc1_drake.design.separation import distance, rival_linearization, synthesized_trial, told_apart
from rc1_drake.diagnose.decide import NOT_DETECTABLE
from rc1_drake.diagnose.fit import fit
from rc1_drake.measurements import load_campaign, merged_campaigns
from rc1_drake.synthesize import SERVO_SPEED_LIMIT_DEG_S
from rc1_drake.sysid.evaluate import Evaluator


def test_a_design_the_robot_or_the_lab_cannot_run_says_why_and_drawn_designs_can_all_run():
    lab = Lab()
    assert infeasible(TrialDesign(), lab) is None  # the paper's gait: 38 deg at 140 deg/s, 93 deg/s of joint speed
    assert "cannot power off [5]" in infeasible(TrialDesign((5,)), lab)
    assert "past the joints' limit" in infeasible(TrialDesign(bias_deg=4.0), lab)
    assert "servos reach 140" in infeasible(TrialDesign(frequency_deg_s=250.0), lab)
    assert "outside the lab's" in infeasible(TrialDesign(seconds=20.0), lab)
    for d in sampled_designs(lab, 40, np.random.default_rng(1)):
        assert d.amplitude_deg + abs(d.bias_deg) <= JOINT_LIMIT_DEG + 1e-9
        assert joint_speed_deg_s(d) <= SERVO_SPEED_LIMIT_DEG_S + 1e-9 and d.frequency_deg_s <= MAX_FREQUENCY_DEG_S
        assert list(d.failed_joints) in lab.failures and lab.min_seconds <= d.seconds <= lab.max_seconds


def test_a_path_off_the_floor_or_turning_tighter_than_the_robot_can_is_refused():
    lab, t = Lab(), np.linspace(0.0, 10.0, 101)
    straight = np.column_stack([0.3 * t, np.zeros_like(t)])
    assert off_the_floor(t, straight, np.zeros_like(t), lab) is None
    assert off_the_floor(t, straight * 2.0, np.zeros_like(t), lab) == "the head leaves the floor"  # 6 m > 4 m
    radius, rate = 0.4, 0.5  # rad/s: 0.2 m/s round a 0.4 m circle
    circle = radius * np.column_stack([np.sin(rate * t), 1.0 - np.cos(rate * t)])
    assert "0.40 m turning radius" in off_the_floor(t, circle, np.full_like(t, rate), lab)
    wide = 0.8 * np.column_stack([np.sin(0.2 * t), 1.0 - np.cos(0.2 * t)])  # 0.16 m/s, 0.2 rad/s: 0.8 m
    assert off_the_floor(t, wide, np.full_like(t, 0.2), lab) is None
    unseen = straight.copy()
    unseen[::7] = np.nan  # frames the camera missed: no verdict of their own
    assert off_the_floor(t, unseen, np.zeros_like(t), lab) is None
    unseen[-1] = [6.0, 0.0]
    assert off_the_floor(t, unseen, np.zeros_like(t), lab) == "the head leaves the floor"


@pytest.mark.parametrize(
    "text, named",
    [
        ("floor_x_m: [1.0, 2.0]\n", "floor_x_m must be [low, high] about the start"),
        ("failures: [[14]]\n", "joint numbers are 1..13"),
        ("min_seconds: 5.0\nmax_seconds: 4.0\n", "min_seconds <= max_seconds"),
        ("floor: 3\n", "floor"),
    ],
)
def test_a_lab_file_with_a_bad_field_is_refused_in_one_line_naming_it(tmp_path, text, named):
    path = tmp_path / "lab.yaml"
    path.write_text(text)
    with pytest.raises(Rc1Error) as error:
        load_lab(path)
    assert str(path) in str(error.value) and named in str(error.value) and "\n" not in str(error.value)


def _candidate(name, coordinates, status="not significant", detectable=None):
    return {"name": name, "coordinates": coordinates, "status": status, "detectable_strength": detectable or {}}


def _diagnosis(verdict, candidates, ambiguous=(), accepted=None, effects=None):
    model = {"friction": dataclasses.asdict(Friction()), "effects": effects or {}}
    rounds = [{"accepted": accepted, "ambiguous": list(ambiguous), "candidates": candidates}]
    return {"model": model, "verdict": verdict, "rounds": rounds, "accepted_effects": [accepted] if accepted else []}


def test_the_open_hypotheses_are_read_from_the_diagnosis_for_each_verdict():
    toe, drag = (
        _candidate("wheel_toe", {"wheel_toe_deg": [1.2, 0.4]}),
        _candidate("head_drag", {"head_drag_mu": [0.3, 0.1]}),
    )
    rivals = open_hypotheses(_diagnosis("ambiguous", [toe, drag], ambiguous=["wheel_toe", "head_drag"]))
    assert [(h.name, h.effects, h.owned) for h in rivals] == [
        ("wheel_toe", {"wheel_toe_deg": 1.2}, ("wheel_toe",)),
        ("head_drag", {"head_drag_mu": 0.3}, ("head_drag",)),
    ]
    found = _diagnosis("effect_found", [dict(toe, status="accepted"), drag], accepted="wheel_toe",
                       effects={"wheel_toe_deg": 1.2})  # fmt: skip
    accepted, runner = open_hypotheses(found)
    assert accepted.effects == {"wheel_toe_deg": 1.2} and runner.effects == {"head_drag_mu": 0.3}  # in its place
    unseen = _candidate("ground_slope", {"ground_slope_x_deg": [0.0, 1.0]}, NOT_DETECTABLE, {"ground_slope_x_deg": 2.5})
    nothing = open_hypotheses(_diagnosis("no_missing_effect", [unseen]))
    assert [h.name for h in nothing] == ["today's model", "ground_slope"]
    assert nothing[1].effects["ground_slope_deg"] == pytest.approx(2.5) and nothing[0].effects == {}
    with pytest.raises(Rc1Error, match="leaves one hypothesis"):
        open_hypotheses(_diagnosis("no_missing_effect", []))
    with pytest.raises(Rc1Error, match="no round accepted wheel_toe"):
        open_hypotheses(dict(found, rounds=[dict(found["rounds"][0], accepted=None)]))
    with pytest.raises(Rc1Error, match="not a diagnosis's JSON"):
        open_hypotheses({"verdict": "ambiguous"})


def _checked(candidate, reduction, after):
    return dict(candidate, simulated={"held_out_reduction": reduction, "held_out_sum_of_squares_after": after})


def test_a_candidate_that_helped_on_held_out_trials_stays_a_rival_best_first_and_one_that_did_not_is_dropped():
    toe, drag, payload, slope, tether = (
        _checked(_candidate("wheel_toe", {"wheel_toe_deg": [1.2, 0.4]}), 0.6, 100.0),
        _checked(_candidate("head_drag", {"head_drag_mu": [0.3, 0.1]}), 0.55, 120.0),
        _checked(_candidate("module_payload", {"payload_kg": [0.2, 0.1]}), 0.3, 300.0),
        _checked(_candidate("ground_slope", {"ground_slope_x_deg": [1.0, 0.5]}), 0.4, 250.0),
        _checked(_candidate("tail_tether", {"tail_tether_N": [0.1, 0.1]}), 0.02, 500.0),  # below decide's least gain
    )
    tied = _diagnosis("ambiguous", [toe, drag, payload, slope, tether], ambiguous=["wheel_toe", "head_drag"])
    assert [h.name for h in open_hypotheses(tied)] == ["wheel_toe", "head_drag", "ground_slope", "module_payload"]
    found = _diagnosis("effect_found", [dict(toe, status="accepted"), drag, payload, tether], accepted="wheel_toe",
                       effects={"wheel_toe_deg": 1.2})  # fmt: skip
    hypotheses = open_hypotheses(found)
    assert [h.name for h in hypotheses] == ["wheel_toe", "head_drag", "module_payload"]
    assert hypotheses[2].effects == {"payload_kg": 0.2}  # in the accepted effect's place


def test_two_hypotheses_are_as_far_apart_as_the_rival_cannot_fit_away():
    """A 3 s trial with no failure: the model is 0 apart from its own trial; a 2 deg wheel toe is farther from
    the paper's model than a 1 deg one; a rival that fits the toe's strength itself (its own effect) fits a
    toe of another strength away; the distance over two trials is at least either's."""
    lab, evaluator = Lab(min_seconds=1.0), Evaluator(None)
    design = TrialDesign(seconds=3.0)
    paper = Hypothesis("paper", Friction(), {})
    made = {}
    for name, toe in (("paper", 0.0), ("toe 1", 1.0), ("toe 2", 2.0)):
        h = Hypothesis(name, Friction(), {"wheel_toe_deg": toe} if toe else {})
        made[name] = [synthesized_trial(design, h, lab, noisy, 3, "d0") for noisy in (False, True)]
    near = {name: distance(rival_linearization([m[0]], [m[1]], paper, [], evaluator), [0]) for name, m in made.items()}
    assert near["paper"] < 0.05 * near["toe 1"] and near["toe 1"] < near["toe 2"], near
    fits_toe = Hypothesis("toe fitted", Friction(), {"wheel_toe_deg": 1.0}, ("wheel_toe",))
    lin = rival_linearization([made["toe 2"][0]], [made["toe 2"][1]], fits_toe, [], evaluator)
    assert distance(lin, [0]) < 0.1 * near["toe 2"], (distance(lin, [0]), near["toe 2"])
    names = [c.name for c in lin.coordinates]
    assert distance(lin, [0]) == pytest.approx(lin.weighted_sum_of_squares(fit(lin, names).residual))
    assert told_apart(0.0) == pytest.approx(0.5) and told_apart(16.0) == pytest.approx(0.97725, abs=1e-4)


@pytest.mark.slow
def test_rc1_design_writes_a_plan_a_lab_can_run(tmp_path, capsys):
    """From a diagnosis's JSON, one trial among the paper's kinds and two drawn designs of at most 3 s: a scenario
    file Scenario loads, plan.json with the pair's distance, a figure; a bad lab file is one line."""
    campaign = tmp_path / "campaign"
    assert main(["synthesize", str(campaign), "--design", "identification", "--time-limit-s", "1"]) == 0
    toe, drag = (
        _candidate("wheel_toe", {"wheel_toe_deg": [1.5, 0.4]}),
        _candidate("head_drag", {"head_drag_mu": [0.4, 0.1]}),
    )
    diagnosis = tmp_path / "diagnosis.json"
    diagnosis.write_text(json.dumps(_diagnosis("ambiguous", [toe, drag], ambiguous=["wheel_toe", "head_drag"])))
    lab = tmp_path / "lab.yaml"
    lab.write_text(yaml.safe_dump({"failures": [[], [7]], "min_seconds": 2.0, "max_seconds": 3.0}))
    plan = tmp_path / "plan"
    argv = ["design", str(campaign), "--diagnosis", str(diagnosis), "--lab", str(lab), "--budget", "1",
            "--designs", "2", "--workers", "2", "--out", str(plan)]  # fmt: skip
    assert main(argv) == 0
    written = json.loads((plan / "plan.json").read_text())
    assert len(written["trials"]) == 1 and list(written["evidence"][0]) == ["wheel_toe | head_drag"]
    assert written["evidence"][0]["wheel_toe | head_drag"] > 0
    check = written["check"]["wheel_toe's trials, head_drag fitted"]  # one noisy replicate: its ratio beside the plan's
    assert len(check["realized"]) == 1 and check["predicted"] >= written["evidence"][0]["wheel_toe | head_drag"]
    # one trial: fitted alone it is the whole plan, in prediction and in the replicate
    assert check["by_trial"]["predicted"] == pytest.approx([check["predicted"]], rel=1e-9)
    assert check["by_trial"]["realized"] == [pytest.approx(check["realized"], rel=1e-9)]
    scenario = yaml_load_typed(schema=Scenario, filename=str(plan / "trial_1.yaml"), child_name="trial_1")
    assert math.isclose(scenario.stop.time_limit_s, written["trials"][0]["seconds"])
    run = tmp_path / "run.json"
    assert (
        main(["run", "--scenarios-file", str(plan / "trial_1.yaml"), "--scenario", "trial_1", "--json", str(run)]) == 0
    )
    assert json.loads(run.read_text())["failed_joints"] == written["trials"][0]["failed_joints"]
    assert (plan / "paths.png").stat().st_size > 10_000
    printed = capsys.readouterr().out
    assert "the next 1 trials to tell apart wheel_toe, head_drag" in printed and "the plan's own check" in printed
    added = tmp_path / "added"
    assert main(["synthesize", str(added), "--plan", str(plan), "--seed", "4"]) == 0
    (trial,) = load_campaign(added).trials
    assert trial.t[-1] == pytest.approx(written["trials"][0]["seconds"], abs=0.02)
    both = merged_campaigns([campaign, added])
    assert len(both.trials) == len(load_campaign(campaign).trials) + 1
    assert len({t.trial_id for t in both.trials}) == len(both.trials)  # an id taken twice is prefixed
    with pytest.raises(Rc1Error, match="given twice"):
        merged_campaigns([campaign, campaign])
    lab.write_text("failures: [[14]]\n")
    assert main(argv) == 2
    assert "joint numbers are 1..13" in capsys.readouterr().err
    assert main(["synthesize", str(tmp_path / "x"), "--plan", str(tmp_path)]) == 2
    assert "not a plan folder" in capsys.readouterr().err
    lab.write_text("failures: [[]]\n")
    diagnosis.write_text("{")
    assert main(argv) == 2
    assert f"{diagnosis}: not a diagnosis's JSON" in capsys.readouterr().err


def test_the_design_loop_table_counts_a_loop_that_decided_early_as_it_ended(monkeypatch):
    """A loop stops at the round whose verdict decides: after the rounds it did not need, it stands where it ended
    (right after rounds 1 and 2 here); wrong, the intervals and what was added are read from its last round."""
    import importlib
    from pathlib import Path

    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[1] / "benchmarks"))
    design_loop = importlib.import_module("design_loop")

    def scored(outcome, trials, coverage=()):
        return {"outcome": outcome, "trials": trials, "floor_s": 10.0 * trials, "coverage": list(coverage)}

    rows = [
        {"cell": "wheel_toe x1", "seed": 102, "way": "designed", "budget": 4, "wall_s": 600.0,
         "rounds": [scored("ambiguous", 8), scored("right", 12, [True])]},
        {"cell": "wheel_toe x1", "seed": 103, "way": "designed", "budget": 4, "wall_s": 300.0,
         "rounds": [scored("ambiguous", 8), scored("ambiguous", 12), scored("wrong", 16)]},
        {"cell": "wheel_toe x1", "seed": 100, "way": "designed", "budget": 4, "wall_s": 1.0,  # chose: not reported
         "rounds": [scored("right", 8)]},
    ]  # fmt: skip
    rows = [r | {"planner": design_loop.PLANNER} for r in rows]
    earlier = dict(rows[0], rounds=[scored("ambiguous", 8), scored("ambiguous", 12)], planner=None)  # tabled apart
    lines = design_loop.table([*rows, earlier], 2).splitlines()
    assert lines[-2] == "| wheel_toe x1 | designed | 2 | 0 | 1 | 1 | 1 | 1 of 1 | 6.0 | 60 | 7.5 |"
    earlier_line = f"| wheel_toe x1 | {design_loop.EARLIER_DESIGNED} | 1 | 0 | 0 | 0 | 0 | 0 of 0 | 4.0 | 40 | 10.0 |"
    assert lines[-1] == earlier_line


def test_the_design_loop_benchmark_names_a_bad_cell_in_one_line_before_any_campaign(tmp_path):
    import subprocess
    import sys
    from pathlib import Path

    script = Path(__file__).resolve().parents[1] / "benchmarks" / "design_loop.py"
    proc = subprocess.run([sys.executable, str(script), "--cells", "none,gravity", "--out", str(tmp_path / "out")],
                          capture_output=True, text=True, timeout=120)  # fmt: skip
    assert proc.returncode != 0 and not (tmp_path / "out").exists()
    assert proc.stderr.strip().splitlines() == ["design_loop: unknown cell or way gravity (cells: paper_rates.CELLS)"]


def test_campaign_folders_of_one_name_merge_with_every_trial_id_their_own(tmp_path):
    """A campaign and two rounds of added trials, each in a folder named `trials`: one trial id in all three."""
    import shutil

    from rc1_drake.config import Stop
    from rc1_drake.synthesize import Case, synthesize_campaign

    synthesize_campaign(tmp_path / "made", design=[Case([], 1)], stop=Stop(time_limit_s=0.5))
    folders = [tmp_path / name / "trials" for name in ("a", "b", "c")]
    for folder in folders:
        shutil.copytree(tmp_path / "made", folder)
    merged = merged_campaigns(folders)
    assert [t.trial_id for t in merged.trials] == ["nominal_1", "trials-nominal_1", "trials3-nominal_1"]


def test_the_failed_joints_scatter_the_diagnosis_took_discounts_only_failed_joint_trials():
    """A 2 deg toe against the paper's model on 3 s trials: with the diagnosis's scatter (tau 1 probe step), a
    joint-7 trial's distance falls (its failed joint's swing is part noise), a trial with no failure keeps its own."""
    lab, evaluator = Lab(min_seconds=1.0), Evaluator(None)
    toe, paper = Hypothesis("toe", Friction(), {"wheel_toe_deg": 2.0}), Hypothesis("paper", Friction(), {})
    for failed, falls in (((7,), True), ((), False)):
        made = [synthesized_trial(TrialDesign(failed, seconds=3.0), toe, lab, noisy, 3, "d0") for noisy in (0, 1)]
        plain, weighed = (
            distance(rival_linearization([made[0]], [made[1]], paper, [], evaluator, tau), [0]) for tau in (0.0, 1.0)
        )
        assert (weighed < 0.95 * plain) if falls else weighed == plain, (failed, plain, weighed)  # 233 -> 210


def test_the_checks_noisy_replicate_has_the_replays_bias_taken_off_as_the_diagnosis_takes_it():
    """A 3 s J7 trial with the lab's potentiometer noise, replayed by the model that made it: measured, its residuals
    are those with the bias the twin bootstrap measured taken off (findings (41): left on, a 9 s replicate's own
    hypothesis fitted worse than its rival on every replicate); the prediction's noise-free trials keep theirs."""
    lab, evaluator = Lab(min_seconds=1.0), Evaluator(None)
    toe = Hypothesis("toe", Friction(), {"wheel_toe_deg": 2.0})
    noisy = [synthesized_trial(TrialDesign((7,), seconds=3.0), toe, lab, True, 5, "d0")]
    left_on = rival_linearization(noisy, noisy, toe, [], evaluator)
    taken_off = rival_linearization(noisy, noisy, toe, [], evaluator, measured=True)
    assert left_on.bias is None and np.abs(taken_off.bias[0]).max() > 0
    assert taken_off.r0[0] == pytest.approx(left_on.r0[0] - taken_off.bias[0], abs=1e-9)


def test_the_plan_predicts_the_held_out_ratio_the_diagnosis_decides_by():
    """Today's best leaves 400 (held out), its rival 460: 4 trials of 50 rows add 200 to the true one's and the
    pair's distance to the rival's, so a distance of 240 brings the ratio to (600 + 60 + 240) / 600 = 1.5."""
    from rc1_drake.design.plan import Standing

    hypotheses = [Hypothesis(n, Friction(), {}) for n in ("head_drag", "module_payload")]
    simulated = lambda ss: {"held_out_sum_of_squares_after": ss}  # noqa: E731
    diagnosis = {"rounds": [{"candidates": [{"name": "head_drag", "simulated": simulated(400.0)},
                                            {"name": "module_payload", "simulated": simulated(460.0)},
                                            {"name": "wheel_toe", "simulated": None}]}]}  # fmt: skip
    standing = Standing.of(diagnosis, hypotheses)
    assert standing.leftover == 400.0 and standing.apart == {"head_drag | module_payload": 60.0}
    assert standing.ratio("head_drag | module_payload", 240.0, 200.0) == pytest.approx(1.5)
    assert Standing.of({"rounds": [{"candidates": []}]}, hypotheses).ratio("x | y", 50.0, 100.0) == pytest.approx(1.5)
