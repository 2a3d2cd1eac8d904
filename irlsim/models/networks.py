"""Reward networks: LIRL, 1DCNN, Bi1DCNN, PACNN(+S) (stage 1) and PTACNN(+S) (stage 2).

Stage-1 models map one planning cycle's policy set to linear reward weights theta (F features: the
paper's 15, or a larger feature set's, ``FeatureStats.n_features``):

    forward(features [B, N, F], control_points [B, N, K, 3], actions [B, N, K, 2]) -> dict
        theta     [B, F]  raw feature units, >= 0 (so path-integral features stay costs)
        context   [B, Cc]  (PACNN only) situation context vector, the input of PTACNN
        attention [B, N]   (PACNN only) policy attention, average-upsampled from the pooled groups
                           (each group's weight spread evenly over its policies: sums to 1 over N)

Theta is predicted in normalised units (features divided by their train std) and converted to raw
units by dividing by the per-feature std held in a buffer, so the normalisation travels with the
checkpoint. Positivity: theta_n = softplus(output). With ``ModelConfig.theta_bound`` = B > 1 the deep
models predict a bounded deviation from one learned situation-independent theta instead:
theta_n = softplus(b) * B^tanh(output), b [F] trainable (LIRL's weights, inside the deep model), so a
cycle's weight lies within a factor B of b's; an out-of-distribution state cannot switch a feature off.

The policy encoder treats the progress-sorted policy set as a 1-D sequence (length N, D = F + 5K
input channels) and convolves along the policy axis, then average-pools groups of ``pool`` neighbouring
policies (2500 -> 313; ceil, so no policy is dropped, the paper's figure says 312 with floor).
"""

from __future__ import annotations

import math

import torch
from torch import nn

from irlsim.models.normalization import FeatureStats


class RewardModel(nn.Module):
    """Base of the stage-1 models: input normalisation buffers and the theta output transform."""

    input_mean: torch.Tensor
    input_std: torch.Tensor
    theta_scale: torch.Tensor

    def __init__(self, stats: FeatureStats, n_policies: int) -> None:
        super().__init__()
        self.k = stats.k
        self.n_features = stats.n_features  # F: 15, or a larger feature set's
        self.n_policies = n_policies
        self.register_buffer("input_mean", torch.as_tensor(stats.mean, dtype=torch.float32))
        self.register_buffer("input_std", torch.as_tensor(stats.std, dtype=torch.float32))
        self.register_buffer(
            "theta_scale", torch.as_tensor(stats.std[: stats.n_features], dtype=torch.float32)
        )
        self.theta_bound = 0.0

    def bound_theta(self, bound: float) -> None:
        """Predict theta as a bounded deviation, within a factor ``bound`` (> 1), from a learned
        situation-independent theta (module docstring); 0 keeps the unbounded softplus."""
        if bound > 0:
            self.theta_bound = float(bound)
            self.theta_base = nn.Parameter(torch.zeros(self.n_features))

    @property
    def n_channels(self) -> int:
        return self.n_features + 5 * self.k

    def policy_inputs(
        self, features: torch.Tensor, control_points: torch.Tensor, actions: torch.Tensor
    ) -> torch.Tensor:
        """Normalised per-policy inputs [B, N, D] (shapes asserted)."""
        b, n = features.shape[:2]
        assert features.shape == (b, n, self.n_features), f"features {tuple(features.shape)}"
        assert control_points.shape == (b, n, self.k, 3), f"control_points {tuple(control_points.shape)}"
        assert actions.shape == (b, n, self.k, 2), f"actions {tuple(actions.shape)}"
        x = torch.cat([features, control_points.reshape(b, n, -1), actions.reshape(b, n, -1)], dim=-1)
        return (x - self.input_mean) / self.input_std

    def to_theta(self, out: torch.Tensor) -> torch.Tensor:
        """Network output [B, F] (normalised units, unconstrained) -> theta [B, F] raw units, >= 0."""
        if self.theta_bound > 0:
            base = nn.functional.softplus(self.theta_base)
            return base * torch.exp(math.log(self.theta_bound) * torch.tanh(out)) / self.theta_scale
        return nn.functional.softplus(out) / self.theta_scale


class LIRL(RewardModel):
    """Linear IRL: one theta for every situation (F trainable weights, one per feature)."""

    def __init__(self, stats: FeatureStats, n_policies: int) -> None:
        super().__init__(stats, n_policies)
        self.weights = nn.Parameter(torch.zeros(self.n_features))

    def forward(self, features, control_points, actions) -> dict[str, torch.Tensor]:  # type: ignore[override]
        self.policy_inputs(features, control_points, actions)  # shape checks only
        return {"theta": self.to_theta(self.weights.expand(features.shape[0], -1))}


class PolicyEncoder(nn.Module):
    """1-D convs along the progress-sorted policy axis, then average pooling of ``pool`` policies.

    [B, N, D] -> [B, latent, G], G = ceil(N / pool).

    ``channels_last`` (default off; set by the training option ``encoder_layout``) computes the same
    function with the same weights on the policy-major [B, N, D] layout: each conv is one matrix product
    of the policy's stacked neighbours [B * N, kernel * D] with the reshaped kernel, the pooling a sum over
    reshaped groups. Equal to the conv path up to float rounding (the summation order differs). Measured
    slower than oneDNN's Conv1d on the 2-core AVX512 CPU of
    docs/results/throughput.md ("Training throughput": x0.85
    of the work per cycle); kept for ``irlsim bench --train-throughput`` on other hardware.
    """

    channels_last: bool = False

    def __init__(self, in_channels: int, hidden: int, latent: int, kernel: int, pool: int) -> None:
        super().__init__()
        pad = kernel // 2
        self.net = nn.Sequential(
            nn.Conv1d(in_channels, hidden, kernel, padding=pad),
            nn.ReLU(),
            nn.Conv1d(hidden, latent, kernel, padding=pad),
            nn.ReLU(),
            nn.AvgPool1d(pool, ceil_mode=True),
        )
        self.pool = pool

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if self.channels_last:
            return self._forward_channels_last(x)
        return self.net(x.transpose(1, 2))

    def _forward_channels_last(self, x: torch.Tensor) -> torch.Tensor:
        first, second = self.net[0], self.net[2]
        assert isinstance(first, nn.Conv1d) and isinstance(second, nn.Conv1d)
        h = torch.relu(conv_channels_last(torch.relu(conv_channels_last(x, first)), second))
        b, n, latent = h.shape
        g = pooled_length(n, self.pool)
        h = nn.functional.pad(h, (0, 0, 0, g * self.pool - n)).view(b, g, self.pool, latent).sum(2)
        sizes = torch.full((g, 1), float(self.pool), dtype=h.dtype, device=h.device)
        sizes[-1] = n - self.pool * (g - 1)  # ceil_mode: the last group averages the policies it has
        return (h / sizes).transpose(1, 2)


def conv_channels_last(x: torch.Tensor, conv: nn.Conv1d) -> torch.Tensor:
    """``conv`` (stride 1, odd kernel, 'same' zero padding) applied along dim 1 of x [B, N, C_in] ->
    [B, N, C_out]: one matrix product of the stacked neighbours with the kernel reshaped to
    [kernel * C_in, C_out] (im2col), no transposed copy of the input."""
    k = conv.kernel_size[0]
    b, n, c = x.shape
    if k == 1:
        cols = x.reshape(b * n, c)
    else:
        padded = nn.functional.pad(x, (0, 0, k // 2, k // 2))
        cols = torch.cat([padded[:, j : j + n] for j in range(k)], dim=-1).reshape(b * n, k * c)
    weight = conv.weight.permute(2, 1, 0).reshape(k * c, conv.out_channels)
    out = cols @ weight if conv.bias is None else torch.addmm(conv.bias, cols, weight)
    return out.view(b, n, conv.out_channels)


def set_encoder_layout(model: nn.Module, layout: str) -> None:
    """Every PolicyEncoder of ``model`` computes on the 'channels_first' ([B, D, N], torch's Conv1d,
    the default) or 'channels_last' ([B, N, D], matrix products) layout; same weights, same function."""
    assert layout in ENCODER_LAYOUTS, layout
    for m in model.modules():
        if isinstance(m, PolicyEncoder):
            m.channels_last = layout == "channels_last"


#: memory layouts of the policy encoder's computation (training option ``encoder_layout``)
ENCODER_LAYOUTS: tuple[str, ...] = ("channels_first", "channels_last")


def pooled_length(n: int, pool: int) -> int:
    return -(-n // pool)


class Conv1DCNN(RewardModel):
    """1DCNN (Rosbach et al. 2019): encoder, then fully connected layers over all pooled latents.

    The first FC layer has latent * ceil(N / pool) inputs, so the parameter count grows with N.
    """

    def __init__(
        self,
        stats: FeatureStats,
        n_policies: int,
        hidden: int,
        latent: int,
        kernel: int,
        pool: int,
        fc_hidden: int,
    ) -> None:
        super().__init__(stats, n_policies)
        self.encoder = PolicyEncoder(self.n_channels, hidden, latent, kernel, pool)
        g = pooled_length(n_policies, pool)
        self.head = nn.Sequential(
            nn.Flatten(), nn.Linear(latent * g, fc_hidden), nn.ReLU(), nn.Linear(fc_hidden, self.n_features)
        )

    def forward(self, features, control_points, actions) -> dict[str, torch.Tensor]:  # type: ignore[override]
        assert features.shape[1] == self.n_policies, f"1DCNN was built for N={self.n_policies} policies"
        h = self.encoder(self.policy_inputs(features, control_points, actions))
        return {"theta": self.to_theta(self.head(h))}


class Bi1DCNN(RewardModel):
    """Bi1DCNN: encoder, then strided 1-D convs across the pooled policies' latent features (each halves
    the policy axis), then a fully connected layer over what is left (fewer weights than 1DCNN)."""

    def __init__(
        self,
        stats: FeatureStats,
        n_policies: int,
        hidden: int,
        latent: int,
        kernel: int,
        pool: int,
        fc_hidden: int,
        cross_layers: int = 2,
    ) -> None:
        super().__init__(stats, n_policies)
        self.encoder = PolicyEncoder(self.n_channels, hidden, latent, kernel, pool)
        layers: list[nn.Module] = []
        g = pooled_length(n_policies, pool)
        for _ in range(cross_layers):
            layers += [nn.Conv1d(latent, latent, kernel, stride=2, padding=kernel // 2), nn.ReLU()]
            g = (g + 2 * (kernel // 2) - kernel) // 2 + 1
        self.cross = nn.Sequential(*layers)
        self.head = nn.Sequential(
            nn.Flatten(), nn.Linear(latent * g, fc_hidden), nn.ReLU(), nn.Linear(fc_hidden, self.n_features)
        )

    def forward(self, features, control_points, actions) -> dict[str, torch.Tensor]:  # type: ignore[override]
        assert features.shape[1] == self.n_policies, f"Bi1DCNN was built for N={self.n_policies} policies"
        h = self.cross(self.encoder(self.policy_inputs(features, control_points, actions)))
        return {"theta": self.to_theta(self.head(h))}


class PACNN(RewardModel):
    """Policy attention CNN.

    encoder h [B, L, G] -> attention encoder (1-D conv, ReLU, per-position FC) -> softmax over the G
    pooled positions -> alpha [B, G]; attended a = sum_g alpha_g h_g. context [B, L] -> FC -> ReLU -> FC
    -> theta.

    Deviation from the paper: the paper's context is the attended vector scaled by a learned scalar,
    gamma * a. Here, following SAGAN (Zhang et al. 2018, the paper's [zhang2018self], where the learned
    scalar comes from), the context is residual: context = mean_g h_g + gamma * a, gamma initialised
    to 0. Why: with gamma * a alone and gamma = 0 at the start the context is the zero vector, theta is
    the same for every cycle and no gradient reaches the encoder until gamma moves; initialising gamma
    away from 0 instead lets an untrained, nearly uniform softmax decide the first epochs. The residual
    form starts as plain average pooling (a working per-cycle model from the first step) and lets
    training move weight onto the attended, non-local evidence as far as it helps. The attention
    weights, the attention loss of PACNN+S and the context size are as in the paper.
    Works for any N (no N-dependent weights). PACNN+S is the same network trained with the extra
    semi-supervised attention loss (see irlsim.irl.objectives.attention_loss).
    """

    def __init__(
        self,
        stats: FeatureStats,
        n_policies: int,
        hidden: int,
        latent: int,
        kernel: int,
        pool: int,
        attention_hidden: int,
        head_hidden: int,
    ) -> None:
        super().__init__(stats, n_policies)
        self.pool = pool
        self.latent = latent
        self.encoder = PolicyEncoder(self.n_channels, hidden, latent, kernel, pool)
        self.attention_encoder = nn.Sequential(
            nn.Conv1d(latent, attention_hidden, kernel, padding=kernel // 2),
            nn.ReLU(),
            nn.Conv1d(attention_hidden, 1, 1),  # a fully connected layer applied at each pooled position
        )
        self.gamma = nn.Parameter(torch.zeros(()))
        self.head = nn.Sequential(
            nn.Linear(latent, head_hidden), nn.ReLU(), nn.Linear(head_hidden, self.n_features)
        )

    def forward(self, features, control_points, actions) -> dict[str, torch.Tensor]:  # type: ignore[override]
        n = features.shape[1]
        h = self.encoder(self.policy_inputs(features, control_points, actions))  # [B, L, G]
        alpha = torch.softmax(self.attention_encoder(h).squeeze(1), dim=-1)  # [B, G]
        attended = torch.einsum("blg,bg->bl", h, alpha)
        context = h.mean(-1) + self.gamma * attended
        theta = self.to_theta(self.head(context))
        return {
            "theta": theta,
            "context": context,
            "attention_pooled": alpha,
            "attention": upsample_attention(alpha, n, self.pool),
        }


def upsample_attention(alpha: torch.Tensor, n: int, pool: int) -> torch.Tensor:
    """[B, G] pooled attention -> [B, N]: each group's weight spread evenly over its (<= pool) policies."""
    g = alpha.shape[-1]
    sizes = torch.full((g,), pool, dtype=alpha.dtype, device=alpha.device)
    sizes[-1] = n - pool * (g - 1)
    return (alpha / sizes).repeat_interleave(pool, dim=-1)[..., :n]


#: PTACNN per-step inputs: the paper's (context, theta) and the alternatives of the temporal-attention study
TAN_INPUTS: tuple[str, ...] = ("context+theta", "context", "theta", "context+theta+delta")


class PTACNN(nn.Module):
    """Temporal attention network (stage 2, on a frozen PACNN).

    contexts [B, H, Cc], thetas [B, H, F] (oldest first, raw units) -> per step input
    [context, theta * theta_scale] (theta in normalised units; ``inputs`` picks another set, TAN_INPUTS)
    -> 2-layer LSTM -> last hidden state -> 4 FC layers -> softmax weights w [B, H];
    theta_next = sum_h w_h theta_h, a convex combination of the history's thetas (so it stays >= 0 and in
    raw units). In training mode, with probability ``drop_newest`` per sample the newest entry is dropped
    (history shifted back one cycle, the oldest entry repeated).
    """

    theta_scale: torch.Tensor

    def __init__(
        self,
        context_dim: int,
        history: int,
        theta_scale: torch.Tensor,
        lstm_hidden: int,
        lstm_layers: int,
        fc_hidden: int,
        inputs: str = "context+theta",
        drop_newest: float = 0.0,
    ) -> None:
        super().__init__()
        assert inputs in TAN_INPUTS, inputs
        self.context_dim = context_dim
        self.history = history
        self.inputs = inputs
        self.drop_newest = float(drop_newest)
        self.register_buffer("theta_scale", torch.as_tensor(theta_scale, dtype=torch.float32).clone())
        nf = self.n_features = int(self.theta_scale.numel())  # F, the feature set's size
        n_in = {"context+theta": context_dim + nf, "context": context_dim, "theta": nf}.get(
            inputs, context_dim + 2 * nf
        )
        self.lstm = nn.LSTM(n_in, lstm_hidden, num_layers=lstm_layers, batch_first=True)
        self.fc = nn.Sequential(
            nn.Linear(lstm_hidden, fc_hidden),
            nn.ReLU(),
            nn.Linear(fc_hidden, fc_hidden),
            nn.ReLU(),
            nn.Linear(fc_hidden, fc_hidden),
            nn.ReLU(),
            nn.Linear(fc_hidden, history),
        )

    def forward(self, contexts: torch.Tensor, thetas: torch.Tensor) -> dict[str, torch.Tensor]:
        b = contexts.shape[0]
        assert contexts.shape == (b, self.history, self.context_dim), f"contexts {tuple(contexts.shape)}"
        assert thetas.shape == (b, self.history, self.n_features), f"thetas {tuple(thetas.shape)}"
        if self.training and self.drop_newest > 0 and self.history > 1:
            # drawn on the CPU whatever the device: the same draws (and so the same training) on any device
            drop = (torch.rand(b) < self.drop_newest)[:, None, None].to(contexts.device)
            contexts = torch.where(drop, torch.cat([contexts[:, :1], contexts[:, :-1]], 1), contexts)
            thetas = torch.where(drop, torch.cat([thetas[:, :1], thetas[:, :-1]], 1), thetas)
        scaled = thetas * self.theta_scale
        parts = {
            "context+theta": [contexts, scaled],
            "context": [contexts],
            "theta": [scaled],
            "context+theta+delta": [contexts, scaled, scaled - torch.cat([scaled[:, :1], scaled[:, :-1]], 1)],
        }[self.inputs]
        out, _ = self.lstm(torch.cat(parts, dim=-1))
        weights = torch.softmax(self.fc(out[:, -1]), dim=-1)
        return {"theta": torch.einsum("bh,bhf->bf", weights, thetas), "weights": weights}
