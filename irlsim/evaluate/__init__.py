"""Evaluating trained models offline: Table I of the paper (model, trainable parameters, EVD, ED, OPD, DEMO)
with reference rows, per-situation and stability breakdowns, and the convergence and OPD plots
(:mod:`irlsim.evaluate.table`: :func:`evaluate_models`). Above training (it reads checkpoints through
its loading and batching), beside :mod:`irlsim.reward`; ``irlsim evaluate`` is
:func:`irlsim.workflows.evaluate.evaluate_runs`.
"""

from irlsim.evaluate.table import METRIC_KEYS, REFERENCE_ROWS, evaluate_models

__all__ = ["METRIC_KEYS", "REFERENCE_ROWS", "evaluate_models"]
