"""Figures in the paper's styles; functions take results and return matplotlib Figures."""

from __future__ import annotations

import os
import sys
import textwrap

import matplotlib

if "MPLBACKEND" not in os.environ and "matplotlib.pyplot" not in sys.modules:
    matplotlib.use("Agg")  # files only, unless a notebook (or the user) chose a backend
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .kinematics import module_positions, module_yaws  # noqa: E402
from .metrics import circling_fit  # noqa: E402


def head_path_figure(runs, *, labels=None, title=None, measured_final=None):
    """Head paths in the style of paper Figs. 8 and 10-13.

    Small circles: the modules at t = 0; dashed line: the head path; a cross at the end; the
    finish line x = line_x_m when the scenario has one; for a circling run, its fitted mean circle.
    With `measured_final` (one [x, y] per run), a star at each measured final head position joined
    to the run's predicted one.
    """
    fig, ax = plt.subplots(figsize=(7, 5))
    runs = list(runs)
    labels = labels or [None] * len(runs)
    first = runs[0]
    x0 = first.state[0]
    phi0 = module_yaws(x0[2], x0[3:16])
    p0 = module_positions(complex(x0[0], x0[1]), phi0, first.geometry)
    ax.plot(p0.real, p0.imag, "o", mfc="none", color="k", ms=6, label="start configuration")
    for k, (run, label) in enumerate(zip(runs, labels, strict=True)):
        run = run.until_event()  # a replay runs on past its stop event: drawn up to it
        (line,) = ax.plot(run.head_xy[:, 0], run.head_xy[:, 1], "--", label=label or "simulated head path")
        ax.plot(*run.head_xy[-1], "x", color=line.get_color(), ms=9, mew=2)
        if measured_final is not None:
            m = measured_final[k]
            ax.plot(*m, "*", color=line.get_color(), ms=12)
            ax.plot([m[0], run.head_xy[-1, 0]], [m[1], run.head_xy[-1, 1]], "-", color=line.get_color(), lw=1)
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
    if measured_final is not None:
        ax.plot([], [], "k*", ms=10, label="measured final head position")
    ax.legend(loc="best", fontsize=8)
    if title:
        ax.set_title(title)
    fig.tight_layout()
    return fig


def joints_figure(runs, *, labels=None, joints=(1, 2, 7, 13)):
    """Joint angles (deg) and servo torques (N m) against time, one column per joint, one line per run."""
    runs = list(runs)
    labels = labels or [None] * len(runs)
    fig, axes = plt.subplots(2, len(joints), figsize=(3.2 * len(joints), 5), sharex=True, squeeze=False)
    for col, j in enumerate(joints):
        for run, label in zip(runs, labels, strict=True):
            axes[0, col].plot(run.t, np.degrees(run.q[:, j - 1]), lw=1, label=label)
            axes[1, col].plot(run.t, run.servo_torque[:, j - 1], lw=1, label=label)
        axes[0, col].set_title(f"joint {j}")
        axes[1, col].set_xlabel("t (s)")
        for ax in axes[:, col]:
            ax.grid(True, alpha=0.3)
    axes[0, 0].set_ylabel("angle q (deg)")
    axes[1, 0].set_ylabel("servo torque (N m)")
    if any(labels):
        axes[0, -1].legend(fontsize=8)
    fig.tight_layout()
    return fig


def yaw_rate_figure(trial, run, *, title=None):
    """Head angular velocity against time, measured and simulated (paper Fig. 9)."""
    fig, ax = plt.subplots(figsize=(8, 3.5))
    ax.plot(trial.t - trial.t[0], trial.head_yaw_rate, color="0.5", lw=1, label="measured (head IMU)")
    ax.plot(run.t, run.head_yaw_rate, "--", lw=1.2, label="simulated")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("head yaw rate (rad/s)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(title or f"{trial.trial_id}: head angular velocity")
    fig.tight_layout()
    return fig


def compare_figures(report, campaign) -> dict:
    """Where a model fails, per case of `campaign` that `report` (compare.CampaignReport) replayed: case -> {file
    name: Figure} of its head paths against the measured ends, its first trial's yaw rate, and its residuals."""
    results = {r.trial_id: r for r in report.trials}
    out = {}
    for case, trials in campaign.cases().items():
        trials = [t for t in trials if t.trial_id in report.runs]  # the trials the report replayed
        if not trials:
            continue
        name = case.replace("+", "_")
        runs = [report.runs[t.trial_id] for t in trials]
        out[case] = {
            f"paths_{name}.png": head_path_figure(
                runs,
                labels=[t.trial_id for t in trials],
                measured_final=[t.final_head_xy for t in trials],
                title=f"case {case}: simulated paths, measured (*) vs predicted (x) ends",
            ),
            f"yaw_rate_{name}.png": yaw_rate_figure(trials[0], runs[0]),
            f"residuals_{name}.png": residuals_figure([results[t.trial_id] for t in trials], title=f"case {case}"),
        }
    return out


def residuals_figure(results, *, title=None):
    """Residuals over time for the trials of one case: head yaw rate, and head position where a
    camera saw it (measured - simulated)."""
    camera = any(r.position_residual is not None for r in results)
    fig, axes = plt.subplots(2 if camera else 1, 1, figsize=(8, 5 if camera else 3), sharex=True, squeeze=False)
    for r in results:
        axes[0, 0].plot(r.t, r.yaw_rate_residual, lw=0.8, label=r.trial_id)
        if camera and r.position_residual is not None:
            axes[1, 0].plot(r.t, np.linalg.norm(r.position_residual, axis=1), lw=0.8, label=r.trial_id)
    axes[0, 0].set_ylabel("yaw rate residual (rad/s)")
    if camera:
        axes[1, 0].set_ylabel("|head position residual| (m)")
    axes[-1, 0].set_xlabel("t (s)")
    for ax in axes[:, 0]:
        ax.grid(True, alpha=0.3)
    axes[0, 0].legend(fontsize=7, ncol=3)
    if title:
        axes[0, 0].set_title(title)
    fig.tight_layout()
    return fig


def sweep_figure(table):
    """Outcome and lateral drift per metre travelled against the failed joint (single failures)."""
    singles = sorted((t for t in table if len(t["failed_joints"]) == 1), key=lambda t: t["failed_joints"][0])
    nominal = next((t for t in table if t["label"] == "none"), None)
    joints = [t["failed_joints"][0] for t in singles]
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    bottom = np.zeros(len(singles))
    for outcome, color in (("crossed", "tab:green"), ("circling", "tab:red"), ("timed_out", "tab:gray")):
        share = np.array([t["outcomes"].get(outcome, 0) / max(t["runs"] - t["errors"], 1) for t in singles])
        ax1.bar(joints, share, bottom=bottom, color=color, label=outcome)
        bottom += share
    ax1.set_ylabel("share of runs")
    ax1.legend(fontsize=8, ncol=3)
    drift = [np.nan if t["drift_per_m"] is None else t["drift_per_m"] for t in singles]
    sd = [0.0 if t["drift_per_m_sd"] is None else t["drift_per_m_sd"] for t in singles]
    ax2.errorbar(joints, drift, yerr=sd, fmt="o-", capsize=3, label="failed joint")
    if nominal and nominal["drift_per_m"] is not None:
        ax2.axhline(nominal["drift_per_m"], color="k", ls="--", lw=1, label="no failure")
    ax2.axhline(0.0, color="k", lw=0.5)
    ax2.set_ylabel("lateral drift per metre")
    ax2.set_xlabel("failed joint (1 = next to the head)")
    ax2.set_xticks(range(1, 14))
    ax2.legend(fontsize=8)
    ax2.grid(True, alpha=0.3)
    fig.tight_layout()
    return fig


def paths_grid_figure(rows, *, line_x_m=3.18):
    """Small multiples: the head paths of every run, one panel per case."""
    cases: dict = {}
    for r in rows:
        if r.get("status") == "ok":
            cases.setdefault(r["label"], []).append(r)
    n = len(cases)
    cols = min(5, n)
    nrows = -(-n // cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(3 * cols, 2.6 * nrows), sharex=True, sharey=True, squeeze=False)
    for ax, (label, rs) in zip(axes.flat, cases.items(), strict=False):
        for r in rs:
            path = np.asarray(r["path"])
            ax.plot(path[:, 0], path[:, 1], lw=0.8)
        ax.axvline(line_x_m, color="k", lw=0.5)
        ax.set_title(label, fontsize=9)
        ax.set_aspect("equal", adjustable="box")
        ax.grid(True, alpha=0.3)
    return _plan_grid_done(fig, axes, n)


def _plan_grid_done(fig, axes, n: int):
    """A grid of x-y panels finished: the unused panels off, the plane's axes labelled once."""
    for ax in axes.flat[n:]:
        ax.axis("off")
    fig.supxlabel("x (m)")
    fig.supylabel("y (m)")
    fig.tight_layout()
    return fig


def waterfall_figure(waterfall):
    """The error waterfall: mean held-out Eq. 6 error per case after each step of the diagnosis (bars), and
    the same with the replay's own miss taken off (black ticks)."""
    cases = list(waterfall[0]["cases"])
    fig, ax = plt.subplots(figsize=(max(6, 1.6 * len(cases) + 2), 4))
    width = 0.8 / len(waterfall)
    for k, step in enumerate(waterfall):
        x = np.arange(len(cases)) + (k - (len(waterfall) - 1) / 2) * width
        ax.bar(x, [step["cases"][c]["mean_eq6_error_pct"] for c in cases], width, label=step["model"])
        # The same with the replay's own miss on each trial's motion taken off (diagnose.replay_error).
        ax.plot(
            x,
            [step["cases"][c]["mean_eq6_without_replay_miss_pct"] for c in cases],
            "_",
            ms=14,
            mew=2,
            color="k",
            label="replay's own miss taken off" if k == 0 else None,
        )
    ax.set_xticks(np.arange(len(cases)), cases)
    ax.set_ylabel("mean Eq. 6 error (%)")
    ax.set_title("error waterfall (held-out trials after the start)")
    ax.grid(True, axis="y", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def candidates_figure(candidates):
    """Each candidate's held-out error reduction, coloured by its status."""
    colours = {"accepted": "tab:green", "not significant": "tab:gray", "not detectable here": "lightgray"}
    fig, ax = plt.subplots(figsize=(7, 0.4 * len(candidates) + 1.2))
    y = np.arange(len(candidates))[::-1]
    ax.barh(
        y,
        [100 * c.held_out_reduction for c in candidates],
        color=[colours.get(c.status, "tab:orange") for c in candidates],
    )
    labels = [textwrap.fill(f"{c.name} ({c.status})", 44) for c in candidates]  # a long status wraps, never cut
    ax.set_yticks(y, labels, fontsize=7)
    ax.axvline(0, color="k", lw=0.5)
    ax.set_xlabel("held-out error reduction (%), linear leave-one-trial-out")
    ax.grid(True, axis="x", alpha=0.3)
    fig.tight_layout()
    return fig


def findings_figure(panels, *, line_x_m=3.18):
    """The paper's cases side by side in the style of its Figs. 8 and 10-13: per panel (a dict: title, traces,
    paper_circle (centre, diameter) or None, paper_band_m (claim, (y_lo, y_hi)) or None) the modules at t = 0 (small
    circles), each trial's head path (dashed, x at its end, its fitted circle when it circled), the line, and in
    black the paper's: its mean circle, and the band of its final head y drawn on the line."""
    n = len(panels)
    cols = min(3 if n <= 6 else 4, n)
    nrows = -(-n // cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(4.2 * cols, 3.6 * nrows), squeeze=False)
    for ax, panel in zip(axes.flat, panels, strict=False):
        traces = panel["traces"]
        if traces and traces[0].start_modules_xy is not None:
            ax.plot(*traces[0].start_modules_xy.T, "o", mfc="none", color="k", ms=4, label="start configuration")
        for k, trace in enumerate(traces):
            (line,) = ax.plot(*trace.head_xy.T, "--", lw=1, label="model head paths" if k == 0 else None)
            ax.plot(*trace.head_xy[-1], "x", color=line.get_color(), ms=7, mew=1.5)
            fit = circling_fit(trace.head_xy, trace.head_yaw) if trace.stop_reason == "circling" else None
            if fit is not None:
                ax.add_patch(plt.Circle(fit[0], fit[1], fill=False, color=line.get_color(), lw=0.8))
        if panel.get("paper_circle") is not None:
            centre, diameter = panel["paper_circle"]
            ax.add_patch(plt.Circle(centre, diameter / 2, fill=False, color="k", lw=2.0))
            ax.plot([], [], "k-", lw=2.0, label=f"paper: mean circle, {diameter:g} m")
        if panel.get("paper_band_m") is not None:
            claim, (lo, hi) = panel["paper_band_m"]
            ax.plot([line_x_m, line_x_m], [lo, hi], "k-", lw=5, solid_capstyle="butt", label=f"paper: {claim}")
        ax.axvline(line_x_m, color="k", lw=0.6)
        ax.set_title(panel["title"], fontsize=9)
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best", fontsize=6)
    return _plan_grid_done(fig, axes, n)
