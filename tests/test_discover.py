"""Discovery (diagnose/discover.py): a noise-free round trip recovers a hidden discrepancy term, names it, and a
campaign without one gets no term."""

import dataclasses

import numpy as np
import pytest

from rc1_drake.config import Friction, Stop
from rc1_drake.diagnose.discover import discover, term_words
from rc1_drake.measurements import load_campaign
from rc1_drake.synthesize import Case, Noise, noise_free_twin, synthesize_campaign
from rc1_drake.sysid.residual import replay_residual

SILENT = dataclasses.replace(Noise().scaled(0.0), camera_dropout=0.0)


def _noise_free(folder, effects, seconds=2.0):
    """A noise-free campaign of this model with `effects` hidden, and the replay's own miss on each of its trials
    (a replay of its noise-free twin at the model without them): what discovery takes off."""
    synthesize_campaign(
        folder,
        design=[Case([], 1), Case([7], 2)],
        effects=effects,
        seed=5,
        noise=SILENT,
        stop=Stop(line_x_m=None, revolutions=None, time_limit_s=seconds),
    )
    trials = load_campaign(folder).trials
    # the twin from the trial's own start rates (none: the protocol's rest), as the replay's bootstrap makes it
    twins = [dataclasses.replace(noise_free_twin(t, friction=Friction()), initial_head_rates=t.initial_head_rates)
             for t in trials]  # fmt: skip
    return trials, [replay_residual(twin, Friction(), {}) for twin in twins]


def test_the_terms_in_words_read_their_sign():
    assert term_words("discrepancy_tail_dry_long", 0.4) == (
        "a dry (Coulomb) force against its longitudinal velocity at the tail's end, 0.4 N"
    )
    assert "less resistance than the model's" in term_words("discrepancy_middle_drag_lat", -0.5)
    assert "0.05 N at 0.1 m/s" in term_words("discrepancy_middle_drag_lat", -0.5)
    assert "to its right" in term_words("discrepancy_head_push_lat", -0.2)


# Measured (docs/findings.md): on this design (2 s, one no-failure and two joint-7 trials, the failed joint's angle
# unmeasured) a failed joint's bias of 0.2 N m comes back as its viscous drag at its bound (0.5, 89% of the held-out
# error removed): the head's path alone does not tell the failed joint's torque shapes apart.
@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="a look-alike term is chosen on this 3-trial design (docs/findings.md)")
def test_a_hidden_failed_joint_bias_is_recovered_to_five_percent_and_named(tmp_path):
    truth = 0.2
    trials, bias = _noise_free(tmp_path, {"discrepancy_failed_joint_bias_Nm": truth})
    found = discover(trials, Friction(), {}, bias=bias)
    assert found.fall > 0.5
    assert [t.key for t in found.terms] == ["discrepancy_failed_joint_bias_Nm"], found.format()
    assert found.terms[0].value == pytest.approx(truth, rel=0.05)


@pytest.mark.slow
def test_a_campaign_without_a_hidden_effect_gets_no_term(tmp_path):
    trials, bias = _noise_free(tmp_path, {})
    found = discover(trials, Friction(), {}, bias=bias)
    assert not found.terms, found.format()
    assert "no term earns its place" in found.format()
    assert np.isfinite(found.cost_without)
