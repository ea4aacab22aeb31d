"""Statistics of a least-squares fit of standardized residuals."""

import numpy as np

from .residual import FINAL_CHANNEL

def channel_variances(r, channels, num_parameters: int) -> np.ndarray:
    """Per residual, its channel's variance in standardized units. The residuals are scaled by stated
    uncertainties (config.RESIDUAL_SIGMAS) that are not all equally tight: the camera path's 1 cm scale is
    twice its noise, the final position's 1 cm is all hand-measurement noise. So each channel's variance
    is estimated from its own residuals (degrees of freedom shared in proportion), and the final
    position's may exceed 1 (a misfit larger than the noise) but not fall below it: two numbers a trial
    cannot show that the hand measured better than stated."""
    m = len(r)
    channels = np.zeros(m, dtype=int) if channels is None or len(channels) != m else channels
    variance = np.empty(m)
    for c in np.unique(channels):
        mine = channels == c
        dof = max(mine.sum() * (m - num_parameters) / m, 1.0)
        estimate = float(r[mine] @ r[mine]) / dof
        variance[mine] = max(estimate, 1.0) if c == FINAL_CHANNEL else estimate
    return variance
