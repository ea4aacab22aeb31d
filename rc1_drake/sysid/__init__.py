"""The identification core shared by identify.py and diagnose.py, in stages: parameters (what is fitted),
evaluate (replays of a campaign, one Replayer per trial and process), residual (standardized replay
residuals), stats (their variances), optimize (the bounded least-squares step).
"""
