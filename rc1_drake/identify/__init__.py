"""Friction identification as stages (parameters -> data -> residual -> optimize -> report) on the core of
rc1_drake.sysid: the paper's AVS (avs.py), the program fit (program.py), the equation-error fit
(equation_error.py), and the held-out check (heldout.py).
"""

from ..config import Friction
from ..scenarios import load_model_file, model_to_yaml
from ..sysid.input_noise import INPUT_NOISE_SAMPLES
from .avs import AvsIteration, AvsResult, Eq6Objective, avs, avs_candidates, avs_figure, identify_avs
from .heldout import HeldOut, held_out_errors, split_trials
from .program import ProgramResult, fit_program, identify_equation_error, identify_program, screen, seeded_start
from .run import METHODS, Identification, identify

__all__ = [
    "INPUT_NOISE_SAMPLES",
    "METHODS",
    "AvsIteration",
    "AvsResult",
    "Eq6Objective",
    "HeldOut",
    "Identification",
    "ProgramResult",
    "avs",
    "avs_candidates",
    "avs_figure",
    "fit_program",
    "friction_to_yaml",
    "held_out_errors",
    "identify_avs",
    "identify",
    "identify_equation_error",
    "identify_program",
    "load_friction_file",
    "screen",
    "seeded_start",
    "split_trials",
]


def friction_to_yaml(friction: Friction, effects=None) -> str:
    return model_to_yaml(friction, effects, comment="Identified by rc1 identify")


def load_friction_file(path) -> Friction:
    """The friction of a model file (scenarios.load_model_file); Rc1Error names the problem."""
    return load_model_file(path).friction
