"""The verdict of a diagnosis and its one-paragraph explanation."""

import enum

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
        experiments = sorted({c.experiment for c in rounds[-1].candidates if c.name in ambiguous and c.experiment})
        done = f"accepted {', '.join(accepted)}; then " if accepted else ""
        return Verdict.AMBIGUOUS, (
            f"{done}{' or '.join(ambiguous)} explain the held-out trials alike (simulated held-out "
            f"gains {', '.join(f'{100 * g:.0f}%' for g in gains.values())}): these trials cannot "
            f"tell them apart" + (f"; {'; '.join(experiments)}" if experiments else "")
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
