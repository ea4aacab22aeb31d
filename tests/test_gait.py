"""The serpenoid (Eqs. 3, 7): the kernel by hand, and Drake's gait source against the kernel."""

import math

import numpy as np
import pytest
from pydrake.systems.framework import DiagramBuilder

from rc1_drake.config import Gait, JointGait
from rc1_drake.gait import add_gait_source, serpenoid


def test_paper_gait_by_hand():
    # Joint 3 at t = 1 s: 38 sin(140 * 1 - 80) deg = 38 sin(60 deg) = 32.909 deg; rate 38 cos(60) * 140 deg/s.
    q, qd = serpenoid(1.0, Gait())
    assert math.degrees(q[2]) == pytest.approx(38 * math.sin(math.radians(60)))
    assert qd[2] == pytest.approx(math.radians(38) * math.radians(140) * 0.5)
    assert math.degrees(serpenoid(0.0, Gait())[0][0]) == pytest.approx(0.0, abs=1e-12)


def test_bias_offset_and_joint_overrides():
    gait = Gait(bias_deg=2.0, phase_offset_deg=30.0, joints=[JointGait(joint=5, amplitude_deg=10.0, bias_deg=-1.0)])
    q, _ = serpenoid(0.0, gait)
    assert math.degrees(q[0]) == pytest.approx(38 * math.sin(math.radians(30)) + 2)  # offset advances the wave
    assert math.degrees(q[4]) == pytest.approx(10 * math.sin(math.radians(30 - 160)) - 1)


def test_drake_gait_source_matches_kernel():
    gait = Gait(bias_deg=1.5, phase_step_deg=55.0, joints=[JointGait(joint=13, frequency_deg_s=90.0)])
    builder = DiagramBuilder()
    port, _ = add_gait_source(builder, gait)
    builder.ExportOutput(port, "desired")
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    for t in (0.0, 0.37, 2.9):
        context.SetTime(t)
        out = diagram.GetOutputPort("desired").Eval(context)
        q, qd = serpenoid(t, gait)
        assert np.allclose(out[:13], q) and np.allclose(out[13:], qd)
