"""Reference rows of Table I: what the learned models' figures should be read against.

- ``expert-theta``: the expert's hand-tuned weights (``expert_theta``), argmax V on every cycle (no
  model-based selection, no history): all five metrics.
- ``executed``: the policy the demonstrator actually executed (``executed_index``). A choice, not a
  distribution: OPD = ED = its distance to the odometry; no EVD or NLL.
- ``oracle``: per cycle, the linear theta over the 15 features that maximises that cycle's own max-ent
  log-likelihood of its demonstration (a small L2 penalty keeps it finite), fitted in torch batched over
  cycles. It sees the demonstration it is scored on, so it is an OPTIMISTIC BOUND on any linear reward,
  not a model.

Every function returns per-cycle metrics in the layout of :func:`irlsim.irl.objectives.evaluate_thetas`
({'nll', 'evd', 'ed', 'opd', 'demo'} float64 [C], 'valid' bool [C]).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from irlsim import feature_names_of
from irlsim.irl.objectives import evaluate_thetas
from irlsim.planner.expert import expert_theta

#: the oracle's optimiser: Adam steps, learning rate, L2 weight (in per-cycle standardised feature units)
ORACLE_STEPS = 200
ORACLE_LR = 0.3
ORACLE_L2 = 1e-3


def expert_theta_metrics(split: Any, theta: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Per-cycle metrics of one fixed theta [F] (default: the expert's, ``expert_theta``)."""
    nf = split.features.shape[-1]
    if theta is None:
        theta = expert_theta(feature_names_of(nf))
    theta = np.asarray(theta, dtype=np.float64).reshape(nf)
    return evaluate_thetas(np.tile(theta, (split.features.shape[0], 1)), split)


def chosen_metrics(split: Any, index: np.ndarray, chunk: int = 256) -> dict[str, np.ndarray]:
    """Per-cycle metrics of a chosen policy per cycle (``index`` [C]): OPD = ED = its distance."""
    index = np.asarray(index, dtype=np.int64)
    c = split.features.shape[0]
    assert index.shape == (c,), f"index {index.shape}, split has {c} cycles"
    opd = np.zeros(c)
    demo = np.full(c, np.nan)
    demo_index = np.asarray(split.demo_index)
    for start in range(0, c, chunk):
        sl = slice(start, min(start + chunk, c))
        d = np.asarray(split.distances[sl], dtype=np.float64)
        r = np.arange(len(d))
        opd[sl] = d[r, index[sl]]
        di = demo_index[sl]
        demo[sl] = np.where(di >= 0, d[r, np.maximum(di, 0)], np.nan)
    nan = np.full(c, np.nan)
    return {
        "nll": nan,
        "evd": nan.copy(),
        "ed": opd.copy(),
        "opd": opd,
        "demo": demo,
        "valid": demo_index >= 0,
    }


def executed_metrics(split: Any) -> dict[str, np.ndarray]:
    """Per-cycle metrics of the policy the demonstrator executed."""
    return chosen_metrics(split, np.asarray(split.executed_index))


def fit_oracle_thetas(
    split: Any,
    steps: int = ORACLE_STEPS,
    lr: float = ORACLE_LR,
    l2: float = ORACLE_L2,
    chunk: int = 256,
) -> np.ndarray:
    """Per-cycle linear thetas [C, 15] (raw feature units) maximising each cycle's max-ent
    log-likelihood of its demonstration: argmin_theta NLL_c(theta) + l2 |theta'|^2 with theta' the weights
    of the cycle's standardised features (f - mean) / std over its policies (the mean shift leaves the
    softmax unchanged). Convex per cycle; solved by Adam on all cycles of a chunk at once. Cycles without
    a demonstration get NaN. Deterministic (float32, start at 0)."""
    c, nf = split.features.shape[0], split.features.shape[-1]
    out = np.full((c, nf), np.nan)
    demo_index = np.asarray(split.demo_index)
    for start in range(0, c, chunk):
        sl = slice(start, min(start + chunk, c))
        di = torch.tensor(demo_index[sl], dtype=torch.int64)
        valid = di >= 0
        if not bool(valid.any()):
            continue
        f = torch.tensor(np.asarray(split.features[sl]), dtype=torch.float64)  # [B, N, 15]
        mean = f.mean(1, keepdim=True)
        std = f.std(1, keepdim=True).clamp_min(1e-9)
        z = ((f - mean) / std).float()
        idx = di.clamp_min(0)[:, None, None].expand(-1, 1, nf)
        z_demo = z.gather(1, idx).squeeze(1)  # [B, 15]
        w = torch.zeros(z.shape[0], nf, requires_grad=True)
        opt = torch.optim.Adam([w], lr=lr)
        vmask = valid.float()
        for _ in range(steps):  # optimiser iterations (not a loop over cycles or policies)
            opt.zero_grad()
            values = -torch.einsum("bnf,bf->bn", z, w)
            nll = torch.logsumexp(values, -1) + (z_demo * w).sum(-1)
            loss = ((nll + l2 * (w * w).sum(-1)) * vmask).sum()
            loss.backward()
            opt.step()
        theta = w.detach().double() / std.squeeze(1)
        out[sl] = torch.where(valid[:, None], theta, torch.full_like(theta, float("nan"))).numpy()
    return out


def oracle_metrics(split: Any, **kwargs: Any) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """(per-cycle metrics, thetas [C, 15]) of the per-cycle oracle (:func:`fit_oracle_thetas`)."""
    thetas = fit_oracle_thetas(split, **kwargs)
    return evaluate_thetas(thetas, split), thetas
