"""Long work on data far from the model: identify and diagnose end with their reports where a parameter moves the
replays' crossings, keep what they computed when a later stage fails, and say so in one line."""

import importlib
import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import overflowing, screenshot

from rc1_drake.cli import main
from rc1_drake.config import Friction, Stop
from rc1_drake.measurements import load_campaign
from rc1_drake.replay import Replayer
from rc1_drake.synthesize import Case, synthesize_campaign
from rc1_drake.sysid.residual import RESIDUAL_PERIOD_S

FAR = Friction(mu_lat=0.75, c_lat=1.875)  # the paper's lateral coefficients halved: slipping, slower snakes
QUICK = ["--input-noise-samples", "2", "--workers", "1"]


@pytest.fixture(scope="module")
def far_campaign(tmp_path_factory):
    """Two short trials made by the independent model (reference.py) with friction far from the paper's, stopped
    at a line 0.8 m ahead: the replays' crossings move with the friction."""
    folder = tmp_path_factory.mktemp("far") / "campaign"
    synthesize_campaign(
        folder,
        design=[Case([], 1), Case([7], 1)],
        truth_model="reference",
        friction=FAR,
        seed=1,
        stop=Stop(line_x_m=0.8, revolutions=None, time_limit_s=6.0),
    )
    return folder


def test_the_far_campaigns_crossings_move_with_the_friction(far_campaign):
    """The setting of issue 40: a fit that starts at the paper's friction meets replays that cross the line a
    residual period or more apart, or not at all within the data."""
    j7 = next(t for t in load_campaign(far_campaign).trials if t.failed_joints)
    at_paper, at_truth = (Replayer(j7).run(f) for f in (Friction(), FAR))
    assert at_paper.event_t is not None and at_truth.event_t is not None
    assert abs(at_truth.event_t - at_paper.event_t) > RESIDUAL_PERIOD_S


@pytest.mark.parametrize("method", ["avs", "program", "equation-error"])
def test_identify_ends_with_its_report_far_from_the_data(far_campaign, tmp_path, capsys, monkeypatch, method):
    out, report = tmp_path / "model.yaml", tmp_path / "report.json"
    monkeypatch.chdir(tmp_path)  # its checkpoint at the default, out/checkpoints/...
    argv = ["identify", str(far_campaign), "--method", method, "--iterations", "2", *QUICK]
    argv += ["--out", str(out), "--json", str(report)]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "held-out" in printed.lower()
    record = json.loads(report.read_text())
    if method != "equation-error":
        assert "Uncertainty at the result" in printed and record["uncertainty"]["standard_errors"]
    assert yaml.safe_load(out.read_text())["friction"]
    assert not (tmp_path / "out" / "checkpoints").exists()  # done: its checkpoint (and the fit kept for a failure)


def test_diagnose_ends_with_its_report_far_from_the_data_and_its_page_shows_it(far_campaign, tmp_path, capsys):
    """The report leads with the verdict; --report writes one page that a browser shows: the verdict's banner on
    top, and the figures (matplotlib's first colour, the waterfall's bars) rendered from the embedded PNGs."""
    from rc1_drake.diagnose.page import VERDICT_COLOURS

    out, page = tmp_path / "model.yaml", tmp_path / "page"
    argv = ["diagnose", str(far_campaign), "--rounds", "1", "--no-probe-study", *QUICK]
    argv += ["--checkpoint", str(tmp_path / "ck"), "--out", str(out), "--report", str(page)]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert printed.startswith("verdict: ") and out.exists()
    verdict = printed.split(":")[1].strip()
    text = (page / "index.html").read_text()
    assert f"verdict: {verdict}" in text and out.read_text().splitlines()[2] in text and "rc1 diagnose" in text
    image = screenshot(page / "index.html", tmp_path / "page.png", size=(1200, 2400))
    banner = np.array([int(VERDICT_COLOURS[verdict][i : i + 2], 16) for i in (1, 3, 5)]) / 255
    assert (np.abs(image[:300] - banner).max(axis=-1) < 0.02).sum() > 20_000  # the verdict, on top
    tab_blue = np.array([31, 119, 180]) / 255
    assert (np.abs(image - tab_blue).max(axis=-1) < 0.02).sum() > 2_000  # the figures, drawn
    assert overflowing(page / "index.html", 1400) == []  # labels, tables and figures fit the page's width
    assert f"<title>rc1 diagnose {far_campaign.name}: " in text  # the campaign's name, not its path


def test_a_failure_after_the_fit_keeps_the_fit_says_where_and_resumes(far_campaign, tmp_path, capsys, monkeypatch):
    """The uncertainty stage fails: the fitted model and the AVS history are already written, the error is one line
    naming them and a log with the traceback, exit code 1; the same command then resumes from the fit."""
    avs_module = importlib.import_module("rc1_drake.identify.avs")  # the package's `avs` is the function

    monkeypatch.chdir(tmp_path)  # the log goes to out/logs here
    argv = ["identify", str(far_campaign), "--iterations", "2", *QUICK, "--checkpoint", "ck"]

    def broken(*args, **kwargs):
        raise ValueError("operands could not be broadcast together")

    with monkeypatch.context() as patch:
        patch.setattr(avs_module, "uncertainty", broken)
        assert main(argv) == 1
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err.startswith("rc1 identify: internal error: ValueError: operands could not be broadcast")
    assert "kept: the fitted model in ck/fit.model.yaml, the fit in ck/fit.json" in err and "resume" in err
    log = tmp_path / err.rsplit("full log: ", 1)[1]
    assert "Traceback" in log.read_text() and "broken" in log.read_text()
    history = json.loads((tmp_path / "ck" / "fit.json").read_text())
    assert history["method"] == "avs" and len(history["iterations"]) == 2
    kept = yaml.safe_load((tmp_path / "ck" / "fit.model.yaml").read_text())["friction"]
    assert kept == pytest.approx(history["friction"], rel=1e-5)

    assert main(argv) == 0  # resumed: the fit's replays come from the checkpoint
    assert "from an interrupted run's checkpoint" in capsys.readouterr().out
    assert not (tmp_path / "ck").exists()


def test_a_failure_in_a_later_round_keeps_the_model_of_the_rounds_before(tmp_path, capsys, monkeypatch):
    """A diagnosis that accepted an effect writes that model at once; a failure after it names the file."""
    monkeypatch.chdir(tmp_path)
    written = []

    def diagnose_that_fails_after_a_round(campaign, *, on_round, **kwargs):
        on_round(Friction(), {"wheel_toe_deg": 1.9}, ["wheel_toe"])
        written.append((tmp_path / "m.yaml").read_text())
        raise RuntimeError("the second round broke")

    monkeypatch.setattr("rc1_drake.diagnose.diagnose", diagnose_that_fails_after_a_round)
    campaign = str(Path(__file__).parents[1] / "data" / "paper_campaign")
    assert main(["diagnose", campaign, "--out", "m.yaml", "--checkpoint", "ck"]) == 1
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "internal error: RuntimeError: the second round broke" in err
    assert "kept: the model after accepting wheel_toe in m.yaml" in err
    assert yaml.safe_load(written[0])["effects"] == {"wheel_toe_deg": 1.9}


def test_an_interruption_is_one_line_with_what_was_kept(tmp_path, capsys, monkeypatch):
    from rc1_drake import cli

    def interrupted(args):
        args.kept.append("nothing yet")
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "cmd_effects", interrupted)
    assert main(["effects"]) == 130
    assert capsys.readouterr().err == "rc1 effects: interrupted; kept: nothing yet\n"
