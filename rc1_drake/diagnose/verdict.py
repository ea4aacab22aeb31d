"""The verdict of a diagnosis and its one-paragraph explanation."""

import enum
import json
from pathlib import Path

from ..sysid.stats import p_text


class Verdict(enum.StrEnum):
    EFFECT_FOUND = "effect_found"  # effects accepted, and what is left is consistent with the noise
    NO_MISSING_EFFECT = "no_missing_effect"  # nothing accepted, and the misfit is consistent with the noise
    AMBIGUOUS = "ambiguous"  # two candidates explain the held-out trials alike
    UNEXPLAINED = "unexplained"  # a misfit that no candidate explains, or one explains only in part


def verdict(accepted, left, rounds) -> tuple:
    """(the Verdict, its explanation) from the accepted effects, the final model's Misfit and the rounds."""
    ambiguous = rounds[-1].ambiguous if rounds else []
    if ambiguous:
        gains = {c.name: c.simulated["held_out_reduction"] for c in rounds[-1].candidates if c.name in ambiguous}
        done = f"accepted {', '.join(accepted)}; then " if accepted else ""
        return Verdict.AMBIGUOUS, (
            f"{done}{' or '.join(ambiguous)} explain the held-out trials alike (simulated held-out "
            f"gains {', '.join(f'{100 * g:.0f}%' for g in gains.values())}): these trials cannot tell them apart"
            + ("; the trials that would are below" if open_pairs(rounds) else "")
        )
    outliers = ""
    if left.outliers:
        outliers = "; not explained: " + ", ".join(
            f"{k} (final position off by {o['off_cm']:.0f} cm, noise {o['noise_cm']:.1f} cm)"
            for k, o in left.outliers.items()
        )
    if left.consistent and accepted:
        return Verdict.EFFECT_FOUND, (
            f"accepted {', '.join(accepted)}; what is left is consistent with the noise "
            f"(final positions {p_text(left.p)}){outliers}"
        )
    partial = rounds[-1].partial if rounds else None
    if left.consistent and not partial:
        # "Nothing found" says as much as the trials could see: name the strengths they would miss.
        unseen = [
            f"{k} {v:.2g}" for c in (rounds[-1].candidates if rounds else []) for k, v in c.detectable_strength.items()
        ]
        limits = f"; these trials would miss an effect below (3 standard errors): {', '.join(unseen)}" if unseen else ""
        return Verdict.NO_MISSING_EFFECT, (
            f"no candidate is significant on held-out trials, and the misfit is consistent "
            f"with the noise (final positions {p_text(left.p)}){outliers}{limits}"
        )
    part = ""
    if partial:
        best = next(c for c in rounds[-1].candidates if c.name == partial)
        part = (
            f"; {partial} is significant and removes {100 * best.simulated['held_out_reduction']:.0f}% of the "
            f"held-out error, too little to name it: these trials cannot identify what is missing"
        )
    helped = f"; {', '.join(accepted)} helped but did not explain it (partial)" if accepted else ""
    return Verdict.UNEXPLAINED, (
        f"the residual is not explained by any candidate (final positions {p_text(left.p)}){helped}{part}{outliers}"
    )


def open_pairs(rounds) -> list[tuple[str, str, str]]:
    """(a, b, the trial that tells them apart) for each pair of the last round's tied candidates that the probe study
    could part, each pair once (a candidate carries every pair it is in: CandidateResult.apart)."""
    ambiguous = rounds[-1].ambiguous if rounds else []
    out: dict[tuple, str] = {}
    for c in (c for c in rounds[-1].candidates if c.name in ambiguous) if ambiguous else ():
        for other, text in c.apart.items():
            if other in ambiguous:
                out.setdefault(tuple(sorted((c.name, other))), text)
    return [(a, b, text) for (a, b), text in out.items()]


# How often each verdict was right on the paper's design, as benchmarks/paper_rates.py measured it (written there).
RATES_FILE = Path(__file__).with_name("paper_rates.json")
# What each verdict claims, and so which campaigns bear it out: the hidden effects found exactly, nothing hidden,
# something hidden (that the diagnosis could not name, or not tell apart).
VERDICT_HOLDS = {
    Verdict.EFFECT_FOUND: ("the hidden effects exactly", lambda row: row["outcome"] == "right"),
    Verdict.NO_MISSING_EFFECT: ("nothing hidden", lambda row: row["hidden"] == "nothing"),
    Verdict.AMBIGUOUS: ("something hidden", lambda row: row["hidden"] != "nothing"),
    Verdict.UNEXPLAINED: ("something hidden", lambda row: row["hidden"] != "nothing"),
}


def verdict_rates(rows: list[dict]) -> dict:
    """Per verdict, over benchmark rows (each with `verdict`, `outcome` and `hidden`: "nothing", "library" or
    "outside"): how many campaigns got it and in how many it held (VERDICT_HOLDS)."""
    out = {}
    for v, (meaning, holds) in VERDICT_HOLDS.items():
        mine = [r for r in rows if r["verdict"] == v]
        out[str(v)] = {"campaigns": len(mine), "held": sum(bool(holds(r)) for r in mine), "meaning": meaning}
    return out


def rate_text(verdict: Verdict, rates: dict | None = None, trials=None) -> str:
    """One line: how often this verdict held on the paper's design (RATES_FILE), or that it is not measured; with
    the campaign's `trials`, whether their design is the one the rate was measured on."""
    if rates is None:
        rates = json.loads(RATES_FILE.read_text()) if RATES_FILE.is_file() else {}
    row = rates.get("verdicts", {}).get(str(verdict))
    if not row or not row["campaigns"]:
        return f"measured rate of {verdict} on the paper's design: none yet (benchmarks/paper_rates.py)"
    text = (
        f"measured on the paper's design ({rates['design']}; {rates['measured']}): {verdict} held ({row['meaning']}) "
        f"on {row['held']} of {row['campaigns']} campaigns"
    )
    mine = design_text(trials) if trials else None
    if mine and not rates["design"].startswith(mine):
        text += f"; this campaign's design is another ({mine}): a guide, not its own rate"
    return text


def design_text(trials) -> str:
    """A campaign's design as the rates name one: 'N trials each of none, J7, ...', or 'N none, M J7, ...'."""
    counts: dict[str, int] = {}
    for t in trials:
        counts[t.case] = counts.get(t.case, 0) + 1
    if len(set(counts.values())) == 1:
        return f"{next(iter(counts.values()))} trials each of {', '.join(counts)}"
    return ", ".join(f"{n} {case}" for case, n in counts.items())
