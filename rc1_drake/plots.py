"""Figures in the paper's styles; functions take results and return matplotlib Figures."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")  # files only; notebooks set their own backend before importing pyplot
import matplotlib.pyplot as plt  # noqa: E402

from .kinematics import module_positions, module_yaws  # noqa: E402
from .metrics import circling_fit  # noqa: E402


def head_path_figure(runs, *, labels=None, title=None):
    """Head paths in the style of paper Figs. 8 and 10.

    Small circles: the modules at t = 0; dashed line: the head path; a cross at the end; the
    finish line x = line_x_m when the scenario has one; for a circling run, its fitted mean circle.
    """
    fig, ax = plt.subplots(figsize=(7, 5))
    runs = list(runs)
    labels = labels or [None] * len(runs)
    first = runs[0]
    x0 = first.state[0]
    phi0 = module_yaws(x0[2], x0[3:16])
    p0 = module_positions(complex(x0[0], x0[1]), phi0, first.geometry)
    ax.plot(p0.real, p0.imag, "o", mfc="none", color="k", ms=6, label="start configuration")
    for run, label in zip(runs, labels, strict=True):
        (line,) = ax.plot(run.head_xy[:, 0], run.head_xy[:, 1], "--", label=label or "simulated head path")
        ax.plot(*run.head_xy[-1], "x", color=line.get_color(), ms=9, mew=2)
        fit = circling_fit(run.head_xy, run.head_yaw) if run.stop_reason == "circling" else None
        if fit is not None:
            centre, radius = fit
            ax.add_patch(plt.Circle(centre, radius, fill=False, color=line.get_color(), lw=1.5))
            ax.annotate(f"mean diameter {2 * radius:.2f} m", centre, ha="center", color=line.get_color())
    line_x = first.scenario.stop.line_x_m
    if line_x is not None:
        ax.axvline(line_x, color="k", lw=1)
        ax.annotate(f"x = {line_x:g} m", (line_x, ax.get_ylim()[1]), ha="right", va="top", rotation=90)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    if title:
        ax.set_title(title)
    fig.tight_layout()
    return fig
