"""The next experiment (issue 68): from a diagnosis's open hypotheses, the trials that tell them apart
(plan.design_trials), over what the robot and the lab can run (lab.Lab), judged by a T-optimal distance
(separation)."""

from .hypotheses import Hypothesis, open_hypotheses
from .lab import Lab, TrialDesign, load_lab
from .plan import Plan, design_trials, load_plan

__all__ = ["Hypothesis", "Lab", "Plan", "TrialDesign", "design_trials", "load_lab", "load_plan", "open_hypotheses"]
