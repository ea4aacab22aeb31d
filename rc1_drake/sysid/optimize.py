"""The bounded step of a least-squares fit, as a Drake MathematicalProgram."""

import math

import numpy as np
from pydrake.solvers import MathematicalProgram, SnoptSolver

from ..config import Rc1Error


def bounded_step(jac, r, damping, lower, upper):
    """The Levenberg-Marquardt step as a Drake MathematicalProgram solved by SNOPT:
    min |r + J d|^2 + damping |d|^2 subject to lower <= d <= upper."""
    n = jac.shape[1]
    prog = MathematicalProgram()
    d = prog.NewContinuousVariables(n, "step")
    prog.Add2NormSquaredCost(np.vstack([jac, math.sqrt(damping) * np.eye(n)]), np.concatenate([-r, np.zeros(n)]), d)
    prog.AddBoundingBoxConstraint(lower, upper, d)
    result = SnoptSolver().Solve(prog, np.zeros(n))
    if not result.is_success():
        raise Rc1Error(f"identify: SNOPT failed on a step ({result.get_solution_result()})")
    return result.GetSolution(d)
