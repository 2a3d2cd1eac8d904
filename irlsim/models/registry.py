"""Model registry: ``build_model(name, config, n_policies, feature_stats)`` and sizes (ModelConfig)."""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn

from irlsim.config import require
from irlsim.errors import IrlsimError
from irlsim.models.networks import LIRL, PACNN, PTACNN, TAN_INPUTS, Bi1DCNN, Conv1DCNN, RewardModel
from irlsim.models.normalization import FeatureStats

#: stage-1 models (one cycle -> theta), in Table-I order
STAGE1_MODELS: tuple[str, ...] = ("LIRL", "1DCNN", "Bi1DCNN", "PACNN", "PACNN+S")
#: stage-2 models and the frozen stage-1 model each is built on
STAGE2_BASE: dict[str, str] = {"PTACNN": "PACNN", "PTACNN+S": "PACNN+S"}
MODEL_NAMES: tuple[str, ...] = STAGE1_MODELS + tuple(STAGE2_BASE)
#: models trained with the semi-supervised attention loss
SEMI_SUPERVISED: frozenset[str] = frozenset({"PACNN+S"})


@dataclass(frozen=True)
class ModelConfig:
    """Network sizes. Defaults are small so a CPU demo trains quickly; ``ModelConfig.paper()`` gives
    sizes close to the paper's Fig. 2 (latent 256, context 256)."""

    hidden_channels: int = 32
    """channels of the first policy-encoder conv layer"""
    latent: int = 32
    """latent features per pooled policy group = context vector size Cc"""
    kernel: int = 3
    """conv kernel width along the policy axis [policies]"""
    pool: int = 8
    """policies per average-pooling group (paper: 8, 2500 -> 312)"""
    attention_hidden: int = 16
    """channels of the PACNN attention-encoder conv"""
    head_hidden: int = 64
    """hidden units of the PACNN context -> theta FC head"""
    fc_hidden: int = 64
    """hidden units of the 1DCNN / Bi1DCNN fully connected head"""
    bi_cross_layers: int = 2
    """Bi1DCNN: strided convs across the pooled policies"""
    lstm_hidden: int = 32
    """PTACNN LSTM hidden size"""
    lstm_layers: int = 2
    """PTACNN LSTM layers (paper: 2)"""
    tan_fc_hidden: int = 32
    """PTACNN hidden units of the 4 FC layers"""
    history: int = 10
    """PTACNN history length H [cycles] (paper: 10)"""
    tan_inputs: str = "context+theta"
    """PTACNN per-step LSTM input (TAN_INPUTS): 'context+theta' (the paper: PACNN context vector and
    theta), 'context', 'theta', or 'context+theta+delta' (also theta_h - theta_{h-1}, normalised)"""
    theta_bound: float = 0.0
    """deep stage-1 models (1DCNN, Bi1DCNN, PACNN(+S)): 0 = the paper's theta_n = softplus(output), any
    weight per cycle; B > 1 = theta_n = softplus(b) * B^tanh(output) with a learned situation-independent
    b [15]: each cycle's weight within a factor B of b's (so that a state the data never showed cannot
    switch a feature such as proximity off; measured in closed loop and left off by default)"""
    drop_newest: float = 0.0
    """PTACNN training only: probability of dropping the newest history entry of a sample (the history
    is shifted one cycle back, the oldest entry repeated), so the net cannot rely on it alone"""

    def validate(self) -> None:
        for name in (
            "hidden_channels",
            "latent",
            "kernel",
            "pool",
            "attention_hidden",
            "head_hidden",
            "fc_hidden",
            "lstm_hidden",
            "lstm_layers",
            "tan_fc_hidden",
            "history",
        ):
            require(getattr(self, name) >= 1, f"model.{name} must be >= 1")
        require(self.kernel % 2 == 1, "model.kernel must be odd (same-length convs)")
        require(self.bi_cross_layers >= 0, "model.bi_cross_layers must be >= 0")
        require(
            self.tan_inputs in TAN_INPUTS,
            f"model.tan_inputs must be one of {', '.join(TAN_INPUTS)}, got '{self.tan_inputs}'",
        )
        require(
            self.theta_bound == 0.0 or self.theta_bound > 1.0,
            f"model.theta_bound must be 0 (unbounded) or > 1, got {self.theta_bound}",
        )
        require(0.0 <= self.drop_newest < 1.0, f"model.drop_newest must be in [0, 1), got {self.drop_newest}")

    @classmethod
    def paper(cls) -> ModelConfig:
        return cls(
            hidden_channels=128,
            latent=256,
            attention_hidden=128,
            head_hidden=256,
            fc_hidden=256,
            lstm_hidden=256,
            tan_fc_hidden=512,
        )


def _unknown(name: str) -> IrlsimError:
    return IrlsimError(f"unknown model '{name}': choose one of {', '.join(MODEL_NAMES)}")


def build_model(
    name: str, config: ModelConfig | None, n_policies: int, feature_stats: FeatureStats | None
) -> nn.Module:
    """Build model ``name`` (one of MODEL_NAMES) for cycles of ``n_policies`` policies.

    ``feature_stats`` (input mean/std, from the train split) becomes buffers of the model; None means
    identity normalisation with K = 10. For PTACNN(+S) ``n_policies`` is unused and the context size is
    ``config.latent`` (it must match the frozen PACNN).
    """
    if name not in MODEL_NAMES:
        raise _unknown(name)
    cfg = config or ModelConfig()
    stats = feature_stats or FeatureStats.identity()
    if n_policies < 1:
        raise IrlsimError(f"n_policies must be >= 1, got {n_policies}")
    if name == "LIRL":
        return LIRL(stats, n_policies)
    deep: RewardModel | None = None
    if name == "1DCNN":
        deep = Conv1DCNN(
            stats, n_policies, cfg.hidden_channels, cfg.latent, cfg.kernel, cfg.pool, cfg.fc_hidden
        )
    elif name == "Bi1DCNN":
        deep = Bi1DCNN(
            stats,
            n_policies,
            cfg.hidden_channels,
            cfg.latent,
            cfg.kernel,
            cfg.pool,
            cfg.fc_hidden,
            cfg.bi_cross_layers,
        )
    elif name in ("PACNN", "PACNN+S"):
        deep = PACNN(
            stats,
            n_policies,
            cfg.hidden_channels,
            cfg.latent,
            cfg.kernel,
            cfg.pool,
            cfg.attention_hidden,
            cfg.head_hidden,
        )
    if deep is not None:
        deep.bound_theta(cfg.theta_bound)
        return deep
    theta_scale = torch.as_tensor(stats.std[: stats.n_features], dtype=torch.float32)
    return PTACNN(
        cfg.latent,
        cfg.history,
        theta_scale,
        cfg.lstm_hidden,
        cfg.lstm_layers,
        cfg.tan_fc_hidden,
        inputs=cfg.tan_inputs,
        drop_newest=cfg.drop_newest,
    )


def count_parameters(model: nn.Module) -> int:
    """Number of trainable parameters (buffers such as the normalisation are not counted)."""
    return sum(p.numel() for p in model.parameters() if p.requires_grad)


def format_parameters(n: int) -> str:
    """15 -> '15', 31234 -> '31.2 k', 2940000 -> '2.94 M'."""
    if n >= 1_000_000:
        return f"{n / 1e6:.3g} M"
    if n >= 1_000:
        return f"{n / 1e3:.3g} k"
    return str(n)
