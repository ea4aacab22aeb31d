"""`rc1 effects`: the candidate effects and sensor faults."""

from __future__ import annotations


def add_effects(sub) -> None:
    sub.add_parser("effects", help="list the candidate physical effects and their parameters")


def cmd_effects(args) -> int:
    from ..discrepancy import GROUPS, JOINT_KINDS, SITE_KINDS
    from ..effects import LIBRARY

    for effect in (e for e in LIBRARY.values() if not e.discrepancy):
        notes = [] if effect.seen_in_replay else ["gait-driven runs only"]
        notes += [] if effect.default_candidate else ["study: a diagnosis candidate when asked for, --candidates study"]
        print(f"{effect.name}: {effect.summary}" + (f" ({'; '.join(notes)})" if notes else ""))
        for p in effect.parameters:
            print(
                f"    {p.key:<30} [{p.lower:g}, {p.upper:g}]"
                + ("" if p.fitted else f"  setting, default {p.default:g}")
            )
    sites, joints = ", ".join(k for k, _, _ in SITE_KINDS), ", ".join(k for k, _, _ in JOINT_KINDS)
    print(
        "discrepancy terms (rc1 diagnose --discover; keys discrepancy_<where>_<kind>_<unit>): at "
        f"{', '.join(GROUPS)}: {sites}; at failed_joint: {joints}"
    )
    return 0
