"""The HTML animation of a run: its recorded frames are the run's motion, so an empty or frozen
animation cannot pass; opened in a browser (headless Chromium), it shows the robot large, from above."""

import numpy as np
from conftest import screenshot, with_stop

from rc1_drake.animate import FRAMES_PER_SECOND, recorded_frames, write_animation
from rc1_drake.cli import main
from rc1_drake.kinematics import module_positions, module_yaws


def test_the_html_animation_replays_the_runs_motion(tmp_path, simulate_cached, joint7_scenario):
    run = simulate_cached(with_stop(joint7_scenario, time_limit_s=2.0))
    html = write_animation(run, tmp_path / "j7.html").read_text()
    assert "<html" in html.lower() and "MeshCat" in html  # the viewer is inside: it plays offline
    frames = recorded_frames(html)
    assert len(frames) == 14  # every module moves
    t, head = frames["/drake/visualizer/rc1/module_1"]
    assert len(t) == round(run.t[-1] * FRAMES_PER_SECOND) + 1 and t[-1] == np.float64(run.t[-1])
    expected = np.column_stack([np.interp(t, run.t, run.head_xy[:, i]) for i in range(2)])
    assert np.abs(head[:, :2] - expected).max() < 1e-9  # the head's track is the run's head position
    assert np.linalg.norm(head[-1, :2] - head[0, :2]) > 0.3  # and it travels
    # Every module where the chain's kinematics (kinematics.py, independent of Drake) puts it.
    state = np.column_stack([np.interp(t, run.t, run.state[:, i]) for i in range(16)])
    centres = module_positions(state[:, 0] + 1j * state[:, 1], module_yaws(state[:, 2], state[:, 3:]), run.geometry)
    for k in range(1, 15):
        xy = frames[f"/drake/visualizer/rc1/module_{k}"][1][:, :2]
        assert np.abs(xy[:, 0] + 1j * xy[:, 1] - centres[:, k - 1]).max() < 1e-9


def test_rc1_run_animate_writes_the_file(tmp_path, capsys):
    out = tmp_path / "run.html"
    assert main(["run", "--time-limit-s", "0.5", "--animate", str(out)]) == 0
    assert len(recorded_frames(out.read_text())["/drake/visualizer/rc1/module_1"][0]) == 16


def test_the_animation_opens_on_the_robot_seen_from_above_with_the_line_in_view(
    tmp_path, simulate_cached, joint7_scenario
):
    # Meshcat's default camera showed the robot low and far: 0.2% of the view, 16% of its width (measured).
    run = simulate_cached(joint7_scenario)
    image = screenshot(write_animation(run, tmp_path / "j7.html"), tmp_path / "j7.png")
    red, green, blue = image[..., 0], image[..., 1], image[..., 2]
    robot = (blue > red + 0.25) & (blue > green + 0.1)  # the modules' blue
    line = (green > red + 0.2) & (green > blue + 0.2)  # the finish line's green
    columns = np.nonzero(robot.any(axis=0))[0]
    assert robot.mean() > 0.005, robot.mean()  # the robot is large in the view
    assert (columns.max() - columns.min()) / image.shape[1] > 0.25  # and spans a quarter of its width
    assert line.sum() > 100  # the finish line, 3.18 m ahead, is in view too
