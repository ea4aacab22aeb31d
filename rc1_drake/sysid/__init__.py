"""The identification core shared by identify and diagnose, in the stages of MuJoCo's sysid: parameters (one
Parameter type: friction, an effect's, or a nuisance), evaluate (replays of a campaign: one Replayer per trial and
process, the Evaluator over the executor, its Checkpoint), residual (a replay's standardized residuals), input_noise
(the replays' own error: resampled replays, the twin bootstrap), objective (a campaign's stacked residuals), stats
(channel variances, the sandwich uncertainty, Wald tests, intervals), optimize (the bounded least-squares step as a
Drake MathematicalProgram).
"""
