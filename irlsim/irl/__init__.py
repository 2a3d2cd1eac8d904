"""Path-integral maximum-entropy IRL: the training objective and the metrics
(docs/design/demonstrations.md)."""

from irlsim.irl.objectives import (
    attention_loss,
    attention_target,
    cycle_metrics,
    demo_distance,
    evaluate_thetas,
    expected_distance,
    expected_value_difference,
    history_indices,
    history_mean,
    nll,
    optimal_policy_distance,
    policy_log_probs,
    policy_values,
    summarize,
)

__all__ = [
    "attention_loss",
    "attention_target",
    "cycle_metrics",
    "demo_distance",
    "evaluate_thetas",
    "expected_distance",
    "expected_value_difference",
    "history_indices",
    "history_mean",
    "nll",
    "optimal_policy_distance",
    "policy_log_probs",
    "policy_values",
    "summarize",
]
