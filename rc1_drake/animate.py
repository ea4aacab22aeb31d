"""Watch a run: its logged states played back through Meshcat, live or as a standalone HTML file.

The simulation itself runs without a visualizer (publishing geometry every step would cost more than
the physics); a finished Run's states are replayed afterwards through a small Diagram of the same
plant (models/rc1.sdf) with a MeshcatVisualizer, recorded as a Meshcat animation. `record` shows it on
a Meshcat server (the notebooks' live view, on localhost); `write_animation` exports the recording
as static HTML that any browser plays offline. The floor's finish line and the head's path are drawn
beside the robot.
"""

from __future__ import annotations

import base64
import re
from pathlib import Path

import numpy as np
from pydrake.geometry import Box, Meshcat, MeshcatVisualizer, MeshcatVisualizerParams, Rgba, Role
from pydrake.math import RigidTransform
from pydrake.systems.framework import DiagramBuilder

from .model import add_rc1_plant
from .protocol import Run

FRAMES_PER_SECOND = 30.0
PATH_PREFIX = "/drake/visualizer/rc1"  # where MeshcatVisualizer puts the robot's bodies


def record(run: Run, meshcat, *, fps: float = FRAMES_PER_SECOND) -> int:
    """Play `run` into `meshcat` as an animation (fps frames per simulated second); returns the frames."""
    builder = DiagramBuilder()
    rc1 = add_rc1_plant(builder, time_step=run.scenario.numerics.time_step_s)
    params = MeshcatVisualizerParams()
    params.role = Role.kIllustration
    params.publish_period = 1.0 / fps
    visualizer = MeshcatVisualizer.AddToBuilder(builder, rc1.scene_graph, meshcat, params)
    visualizer.set_name("meshcat_visualizer")
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    plant_context = rc1.plant.GetMyMutableContextFromRoot(context)
    times = np.arange(0.0, run.t[-1] + 0.5 / fps, 1.0 / fps)
    positions = np.column_stack([np.interp(times, run.t, run.state[:, i]) for i in range(rc1.plant.num_positions())])
    _draw_scene(run, meshcat)
    visualizer.StartRecording(set_transforms_while_recording=False)
    for k, q in enumerate(positions):
        context.SetTime((k + 0.5) / fps)  # inside frame k (Meshcat floors time * fps); it shows t = k / fps
        rc1.plant.SetPositions(plant_context, q)
        diagram.ForcedPublish(context)
    visualizer.StopRecording()
    visualizer.PublishRecording()
    return len(times)


def write_animation(run: Run, path, *, fps: float = FRAMES_PER_SECOND) -> Path:
    """A standalone HTML animation of `run` (a Meshcat recording on localhost, exported as static HTML)."""
    meshcat = Meshcat()
    try:
        record(run, meshcat, fps=fps)
        html = meshcat.StaticHtml()
    finally:
        del meshcat  # closes the server's port
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(html)
    tmp.replace(path)
    return path


def frame_camera(run: Run, meshcat) -> tuple:
    """Point Meshcat's camera at the run from above, three-quarters behind the start: the head's path and the
    finish line fill the view (Meshcat's default camera sits low at the origin, the robot small and far).
    Returns (camera position, target) in world coordinates (m)."""
    xy = run.head_xy
    if run.scenario.stop.line_x_m is not None:
        xy = np.vstack([xy, [run.scenario.stop.line_x_m, xy[0, 1]]])
    low, high = xy.min(axis=0), xy.max(axis=0)
    target = np.array([*(low + high) / 2, 0.0])
    span = max(float(np.max(high - low)), 1.75)  # at least the robot's length
    # 47 deg down, from behind the start's left, at 0.6 span: Meshcat's 75 deg vertical fov (107 deg across at
    # 16:9) then holds the span across about 80% of the view.
    camera = target + span * 0.6 * np.array([-0.35, -0.6, 0.75]) / np.linalg.norm([-0.35, -0.6, 0.75])
    meshcat.SetCameraPose(camera, target)
    return camera, target


def _draw_scene(run: Run, meshcat) -> None:
    frame_camera(run, meshcat)
    stop = run.scenario.stop
    if stop.line_x_m is not None:
        meshcat.SetObject("/scene/finish_line", Box(0.02, 1.5, 0.002), Rgba(0.1, 0.6, 0.1, 1.0))
        meshcat.SetTransform("/scene/finish_line", RigidTransform([stop.line_x_m, run.state[0, 1], 0.001]))
    path = np.vstack([run.head_xy.T, np.full(len(run.t), 0.002)])
    meshcat.SetLine("/scene/head_path", path, 2.0, Rgba(0.9, 0.2, 0.1, 1.0))


def recorded_frames(html: str) -> dict:
    """The animation inside an exported HTML file: body path -> (frame times s, positions (N, 3) m).
    Decodes Meshcat's embedded commands (msgpack), so that a test can check what would be played."""
    import msgpack

    commands = [
        msgpack.unpackb(base64.b64decode(b), strict_map_key=False)
        for b in re.findall(r'data:application/octet-binary;base64,([A-Za-z0-9+/=]+)"', html)
    ]
    frames = {}
    for command in [c for c in commands if c.get("type") == "set_animation"]:
        for animation in command["animations"]:
            clip = animation["clip"]
            for track in clip["tracks"]:
                if track["name"] == ".position":
                    keys = track["keys"]
                    frames[animation["path"]] = (
                        np.array([k["time"] for k in keys]) / clip["fps"],
                        np.array([k["value"] for k in keys], dtype=float),
                    )
    return frames
