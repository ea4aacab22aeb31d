"""The method pages' figures, made from the shipped campaign (data/paper_campaign, synthetic: data/README.md) with the
project's own functions:

- docs/measurements.png (docs/measurements.md): one trial of each straight-running case replayed with the paper's
  model (`rc1 compare`'s default) against the head path the camera measured, and where the camera path's error first
  passes 2 cm (`rc1 compare`'s "where it fails", residuals.where_it_fails);
- docs/identification.png (docs/identification.md): mu_lat's profile, the others at the paper's values, with the
  paper's model and with the toe `rc1 diagnose` adds held fixed: the mean Eq. 6 error of the estimation and the
  held-out trials (what AVS minimizes and what judges it), and the program fit's standardized cost with what a 95%
  interval is on it. The numbers it prints are in docs/findings.md (32) and (33).

Regenerate (about 2 minutes on 2 cores, one process; numba's first compile adds 2-3 minutes where it has no cache):

    .venv/bin/python scripts/doc_figures.py --out docs/
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from scipy.interpolate import CubicSpline  # noqa: E402

from rc1_drake.compare import compare_campaign, simulator_error  # noqa: E402
from rc1_drake.config import Z95, Friction  # noqa: E402
from rc1_drake.measurements import load_campaign  # noqa: E402
from rc1_drake.plots import head_path_figure  # noqa: E402
from rc1_drake.residuals import ERROR_THRESHOLD_M, where_it_fails  # noqa: E402
from rc1_drake.sysid.evaluate import replay  # noqa: E402
from rc1_drake.sysid.residual import trial_residual  # noqa: E402

CAMPAIGN = Path(__file__).resolve().parents[1] / "data" / "paper_campaign"
# One trial of each straight-running case (no failure, joint 7, joint 13, joint 7 with its straightening bias).
PATH_TRIALS = ("nominal_1", "j7_1", "j13_1", "j7_bias_1")
# The profile's split, as `rc1 identify --trials ... --validation ...` takes it: the first three trials of each
# straight-running case fitted, the other two held out (the circling joint-2 trial left out, as the identification
# design leaves it: its replays are chaotic).
ESTIMATION = tuple(f"{case}_{k}" for case in ("nominal", "j7", "j13", "j7_bias") for k in (1, 2, 3))
HELD_OUT = tuple(f"{case}_{k}" for case in ("nominal", "j7", "j13", "j7_bias") for k in (4, 5))
# mu_lat from half to twice the paper's 1.5, the other four coefficients at the paper's values (config.Friction).
MU_LAT = (0.75, 0.9, 1.05, 1.2, 1.35, 1.5, 1.7, 1.9, 2.2, 2.6, 3.0)
# The effect `rc1 diagnose data/paper_campaign` adds (the README's loop table: 1.93 deg; the truth's is 2), held
# fixed as `rc1 identify --start MODEL.yaml` holds a model file's effects.
DIAGNOSED = (("wheel_toe_deg", 1.93),)


def measurements_figure(*, campaign, trial_ids=PATH_TRIALS):
    """The trials `trial_ids` of `campaign` replayed with the paper's model as `rc1 compare` does (one process): the
    replayed head paths (dashed, x at the replay's end) and the measured final positions (stars) by
    plots.head_path_figure, the camera's head path over them (solid), and where the camera path's error first passes
    2 cm (circles joined: measured and replayed head at that time), enlarged in an inset."""
    chosen = dataclasses.replace(campaign, trials=[campaign.chosen([i])[0] for i in trial_ids])
    report = compare_campaign(chosen, workers=1)
    where = {r.trial_id: r for r in where_it_fails(report, chosen).trials}
    results = {r.trial_id: r for r in report.trials}
    labels = [
        f"{t.trial_id} ({t.case}): Eq. 6 {results[t.trial_id].eq6_error_pct:.1f}%, camera path "
        + (
            "within 2 cm"
            if where[t.trial_id].exceeds_2cm_at_s is None
            else f"> 2 cm from {where[t.trial_id].exceeds_2cm_at_s:.1f} s"
        )
        for t in chosen.trials
    ]
    fig = head_path_figure(
        [report.runs[t.trial_id] for t in chosen.trials],
        labels=labels,
        measured_final=[t.final_head_xy for t in chosen.trials],
        title="The paper's model replayed (dashed) against the camera (solid): data/paper_campaign",
    )
    fig.set_size_inches(10, 5.8)
    ax = fig.axes[0]
    colours = {line.get_label(): line.get_color() for line in ax.get_lines()}
    for text in list(ax.texts):  # the line's label, moved from the top (where the paths end) to the bottom
        if text.get_text().startswith("x = "):
            line_x = text.xy[0]
            text.remove()
            ax.annotate(
                f"x = {line_x:g} m (the trials' line)",
                (line_x, 0.02),
                xycoords=("data", "axes fraction"),
                ha="right",
                va="bottom",
                rotation=90,
                fontsize=8,
            )
    for trial, label in zip(chosen.trials, labels, strict=True):
        colour = colours[label]
        t = trial.t - trial.t[0]
        seen = ~np.isnan(trial.camera[:, 0])
        ax.plot(trial.camera[seen, 0], trial.camera[seen, 1], "-", color=colour, lw=1, alpha=0.8)
        at = where[trial.trial_id].exceeds_2cm_at_s
        if at is None:
            continue
        k = int(np.argmin(np.abs(np.where(seen, t, np.inf) - at)))
        run = report.runs[trial.trial_id]
        replayed = [np.interp(at, run.t, run.head_xy[:, i]) for i in (0, 1)]
        ax.plot([trial.camera[k, 0], replayed[0]], [trial.camera[k, 1], replayed[1]], "o-", color=colour, mfc="white")
    ax.plot([], [], "k-", lw=1, label="measured head path (camera)")
    ax.plot([], [], "ko-", mfc="white", label=f"path error first > {100 * ERROR_THRESHOLD_M:g} cm: camera, replay")
    ax.legend(loc="upper left", fontsize=8)
    # The first half metre enlarged, where the replays leave the camera's path.
    inset = ax.inset_axes([0.03, 0.03, 0.4, 0.36])
    for line in ax.get_lines():
        inset.plot(
            line.get_xdata(),
            line.get_ydata(),
            linestyle=line.get_linestyle(),
            color=line.get_color(),
            marker=line.get_marker(),
            mfc=line.get_markerfacecolor(),
            lw=line.get_linewidth(),
            alpha=line.get_alpha(),
        )
    inset.set_xlim(-0.05, 0.55)
    inset.set_ylim(-0.3, 0.2)
    inset.set_aspect("equal", adjustable="box")
    inset.tick_params(labelsize=7)
    inset.set_title("the first 0.5 m: where the replays leave the camera's path", fontsize=8)
    inset.grid(True, alpha=0.3)
    ax.indicate_inset_zoom(inset, edgecolor="0.5")
    fig.tight_layout()
    return fig


def mu_lat_profile(
    *, campaign, effects=None, values=MU_LAT, estimation=ESTIMATION, held_out=HELD_OUT, progress=print
) -> dict:
    """Each trial of `estimation` and `held_out` replayed (this process) at each mu_lat of `values`, the other
    coefficients at the paper's and `effects` held fixed: per trial and value its Eq. 6 error (compare.simulator_error,
    %) and its standardized cost 0.5 |r|^2 (sysid.residual.trial_residual, the program fit's residuals), and the
    number of residuals of each trial."""
    trials = campaign.chosen(list(estimation) + list(held_out))
    eq6, cost, rows = {}, {}, {}
    for k, trial in enumerate(trials):
        eq6[trial.trial_id], cost[trial.trial_id] = [], []
        for value in values:
            run = replay(trial, dataclasses.replace(Friction(), mu_lat=value), effects)
            r = trial_residual(trial, run)
            eq6[trial.trial_id].append(
                simulator_error(run.final_head_xy, trial.final_head_xy, trial.initial_head_pose[:2])
            )
            cost[trial.trial_id].append(0.5 * float(r @ r))
            rows[trial.trial_id] = len(r)
        progress(f"  profile {effects or 'paper model'}: {k + 1}/{len(trials)} trials ({trial.trial_id})")
    return {
        "mu_lat": list(values),
        "effects": effects,
        "estimation": list(estimation),
        "held_out": list(held_out),
        "eq6_pct": eq6,
        "cost": cost,
        "rows": rows,
    }


def _minimum(*, x, y, fine):
    """(where a cubic spline through (x, y) is least on `fine`, the spline on `fine`)."""
    curve = CubicSpline(x, y)(fine)
    return float(fine[np.argmin(curve)]), curve


def profile_intervals(*, profile) -> dict:
    """mu_lat's estimate (the least standardized cost of the estimation trials, on a spline through the profile) and
    two 95% intervals on it: the residuals taken as independent with one variance (the cost's rise by
    0.5 Z95^2 s^2, s^2 its mean square at the least: the sandwich of output noise alone), and the trials'
    disagreement (each trial left out in turn, the least of the others; the jackknife's standard error)."""
    x = np.array(profile["mu_lat"])
    fine = np.linspace(x[0], x[-1], 4001)
    ids = profile["estimation"]
    per_trial = np.array([profile["cost"][i] for i in ids])
    best, curve = _minimum(x=x, y=per_trial.sum(axis=0), fine=fine)
    rows = sum(profile["rows"][i] for i in ids)
    variance = 2.0 * curve.min() / (rows - 1)
    rise = 0.5 * Z95**2 * variance
    inside = fine[curve <= curve.min() + rise]
    leave_out = np.array([_minimum(x=x, y=per_trial.sum(axis=0) - per_trial[g], fine=fine)[0] for g in range(len(ids))])
    n = len(ids)
    jackknife_se = float(np.sqrt((n - 1) / n * np.sum((leave_out - leave_out.mean()) ** 2)))
    return {
        "best": best,
        "fine": fine,
        "curve": curve,
        "rise": rise,
        "independent": (float(inside.min()), float(inside.max())),
        "jackknife": (best - Z95 * jackknife_se, best + Z95 * jackknife_se),
        "leave_out": leave_out,
    }


def _mean_eq6(*, profile, key) -> np.ndarray:
    return np.mean([profile["eq6_pct"][i] for i in profile[key]], axis=0)


def identification_figure(*, paper, with_toe):
    """Two panels of mu_lat's profile (mu_lat_profile): the mean Eq. 6 error of the estimation and the held-out
    trials, with the paper's model (`paper`) and with the diagnosis's toe held fixed (`with_toe`); and, with the toe,
    the estimation trials' standardized cost above its least, the two 95% intervals of profile_intervals and each
    leave-one-trial-out minimum."""
    x = np.array(with_toe["mu_lat"])
    fit = profile_intervals(profile=with_toe)
    fig, (left, right) = plt.subplots(1, 2, figsize=(11.5, 4.6))
    toe = with_toe["effects"]["wheel_toe_deg"]
    for profile, colour, model in ((paper, "0.45", "paper's model"), (with_toe, "tab:blue", f"with a {toe:g} deg toe")):
        for key, style, name in (("estimation", "o-", "estimation"), ("held_out", "s--", "held-out")):
            mean = _mean_eq6(profile=profile, key=key)
            left.plot(x, mean, style, color=colour, mfc="none", label=f"{model}: {name} ({len(profile[key])} trials)")
            k = int(np.argmin(mean))
            left.plot(x[k], mean[k], "o" if key == "estimation" else "s", color=colour, ms=8)
    for ax in (left, right):
        ax.axvline(1.5, color="0.4", lw=0.8, ls=":")
        ax.set_xlabel("mu_lat (lateral Coulomb coefficient, dimensionless)")
        ax.grid(True, alpha=0.3)
    left.set_ylim(0.0, 12.5)
    left.annotate("truth 1.5", (1.5, 12.3), ha="right", va="top", rotation=90, fontsize=8, color="0.4")
    left.set_ylabel("mean Eq. 6 error (%)")
    left.set_title("AVS's objective, and the held-out check (filled: least)", fontsize=10)
    left.legend(fontsize=7, loc="upper right")

    total = np.sum([with_toe["cost"][i] for i in with_toe["estimation"]], axis=0)
    least = fit["curve"].min()
    right.plot(x, total - least, "o", mfc="none", color="tab:blue", label=f"replays, {toe:g} deg toe held fixed")
    right.plot(fit["fine"], fit["curve"] - least, "-", color="tab:blue", lw=1)
    lo, hi = fit["jackknife"]
    right.axvspan(lo, hi, color="tab:orange", alpha=0.25, label=f"95%, the trials' disagreement: {lo:.2f}-{hi:.2f}")
    lo, hi = fit["independent"]
    right.axvspan(lo, hi, color="tab:green", alpha=0.7, label=f"95%, residuals as independent: {lo:.3f}-{hi:.3f}")
    right.axhline(
        fit["rise"],
        color="tab:green",
        lw=0.8,
        ls="--",
        label=f"cost rise 0.5 (1.96 s)^2 = {fit['rise']:.1f} (s: residual RMS at the least)",
    )
    right.plot(
        fit["leave_out"], np.zeros_like(fit["leave_out"]), "|", color="k", ms=14, label="least, one trial left out"
    )
    right.axvline(fit["best"], color="tab:blue", lw=1.2, label=f"least cost: mu_lat {fit['best']:.2f}")
    right.set_yscale("symlog", linthresh=max(fit["rise"], 1.0))
    right.set_ylim(-0.5, None)
    right.set_ylabel("standardized cost above its least (0.5 |r|^2)")
    right.set_title("the program fit's objective, and what 95% is on it", fontsize=10)
    right.legend(fontsize=7, loc="upper right")
    fig.suptitle(
        "mu_lat's profile on data/paper_campaign (a 2 deg toe hidden; other coefficients at the paper's values)",
        fontsize=10,
    )
    fig.tight_layout()
    return fig, fit


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=Path("docs"), help="folder for the PNGs (default docs/)")
    parser.add_argument("--campaign", type=Path, default=CAMPAIGN, help="the campaign (default data/paper_campaign)")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    campaign = load_campaign(args.campaign)

    fig = measurements_figure(campaign=campaign)
    fig.savefig(args.out / "measurements.png", dpi=110)
    plt.close(fig)
    print(f"wrote {args.out / 'measurements.png'}")

    paper = mu_lat_profile(campaign=campaign)
    with_toe = mu_lat_profile(campaign=campaign, effects=dict(DIAGNOSED))
    fig, fit = identification_figure(paper=paper, with_toe=with_toe)
    fig.savefig(args.out / "identification.png", dpi=110)
    plt.close(fig)
    print(
        f"wrote {args.out / 'identification.png'}: with the toe, least cost at mu_lat {fit['best']:.3f}; 95% residuals "
        f"independent {fit['independent'][0]:.3f}-{fit['independent'][1]:.3f}, trials' disagreement "
        f"{fit['jackknife'][0]:.3f}-{fit['jackknife'][1]:.3f}; leave-one-out least "
        + ", ".join(f"{v:.2f}" for v in fit["leave_out"])
    )
    for name, profile in (("paper's model", paper), ("with the toe", with_toe)):
        for key in ("estimation", "held_out"):
            print(
                f"  {name}, mean Eq. 6 error, {key}: "
                + ", ".join(
                    f"{v:g}: {e:.2f}%" for v, e in zip(MU_LAT, _mean_eq6(profile=profile, key=key), strict=True)
                )
            )
        cost = np.sum([profile["cost"][i] for i in profile["estimation"]], axis=0)
        print(f"  {name}, estimation cost: " + ", ".join(f"{v:g}: {c:.0f}" for v, c in zip(MU_LAT, cost, strict=True)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
