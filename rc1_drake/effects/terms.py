"""The discrepancy model's terms (discrepancy.py) as effects, so that a model file, compare and a fit take them."""

from ..config import Friction
from .base import Effect, EffectParameter


class DiscrepancyTerm(Effect):
    """One term of the discrepancy model (discrepancy.py): a coefficient times a fixed shape, at the sites of one
    group or in the failed joints. Not a mechanism: what discovery (diagnose/discover.py) fits when the library's
    effects leave the data unexplained, named afterwards by its body, variable and sign."""

    discrepancy = True
    default_candidate = False
    # |v| v's bound: about the viscous bound's force at the gait's 0.3 m/s
    BOUNDS = {"N_s_per_m": 5.0, "N_s2_per_m2": 15.0, "N": 5.0, "Nm": 1.0, "Nm_per_rad": 5.0, "Nm_s_per_rad": 0.5}

    def __init__(self, index: int, group: str, kind: str, unit: str, words: str):
        self.index, self.group, self.kind, self.unit, self.words = index, group, kind, unit, words
        self.name = f"discrepancy_{group}_{kind}"
        where = "each failed joint" if group == "failed_joint" else f"the {group}'s sites"
        self.summary = f"discrepancy term: {words} at {where}"
        self.failed_joints_only = group == "failed_joint"
        bound = self.BOUNDS[unit]
        self.parameters = (EffectParameter(f"{self.name}_{unit}", self._lower(bound), bound, probe=0.1 * bound),)

    def _lower(self, bound: float) -> float:
        """A term that resists motion may take away at most the paper's own friction where it acts: none at the
        wheelless head, the tail's end or in a failed joint's dry friction, c_lat / c_long at a wheel (its Coulomb
        part, which needs the wheel's load, is bounded as the other terms), c_joint in a failed joint."""
        if not self.kind.startswith(("drag", "dry", "quad")):
            return -bound
        paper = Friction()
        if self.group == "failed_joint":
            return -paper.c_joint if self.kind == "drag" else 0.0
        if self.group in ("head", "tail"):
            return 0.0
        return {"drag_lat": -paper.c_lat, "drag_long": -paper.c_long}.get(self.kind, -bound)

    def configure(self, setup, values):
        setup.discrepancy[self.index] = values[self.main.key]
