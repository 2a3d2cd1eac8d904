"""Reward networks (PyTorch): LIRL, 1DCNN, Bi1DCNN, PACNN(+S), PTACNN(+S); see docs/design/models.md."""

from irlsim.models.networks import LIRL, PACNN, PTACNN, Bi1DCNN, Conv1DCNN, RewardModel
from irlsim.models.normalization import FeatureStats, compute_feature_stats
from irlsim.models.registry import (
    MODEL_NAMES,
    SEMI_SUPERVISED,
    STAGE1_MODELS,
    STAGE2_BASE,
    ModelConfig,
    build_model,
    count_parameters,
    format_parameters,
)

__all__ = [
    "LIRL",
    "PACNN",
    "PTACNN",
    "Bi1DCNN",
    "Conv1DCNN",
    "RewardModel",
    "FeatureStats",
    "compute_feature_stats",
    "MODEL_NAMES",
    "SEMI_SUPERVISED",
    "STAGE1_MODELS",
    "STAGE2_BASE",
    "ModelConfig",
    "build_model",
    "count_parameters",
    "format_parameters",
]
