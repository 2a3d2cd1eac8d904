"""Path-integral maximum-entropy IRL objective and metrics (docs/design/demonstrations.md), batched over
cycles.

Notation, per planning cycle with N policies (sorted by progress) and 15 path-integral feature costs:

    p(pi | theta) = softmax_pi(-theta^T f^pi)          (the paper's Eq. 1)
    V(pi)         = -theta^T f^pi                      (policy value; higher is better)
    NLL           = theta^T f^D + logsumexp_pi(-theta^T f^pi)   gradient in theta: f^D - E_p[f]

The paper's Eq. 3, E_p[f] - f^D, is the gradient of the log-likelihood L = -NLL (which it ascends);
minimising the NLL is the same update (docs/design/demonstrations.md; the original brief had the sign
slipped).
    EVD           = |E_p[V] - V(pi^D)| / |V(pi^D)|
    ED            = E_p[d(zeta, pi)]        OPD = d(zeta, argmax_pi V)      DEMO = d(zeta, pi^D)

Distances ``d`` are the policies' distances to the demonstration odometry [m]. Cycles with
``demo_index == -1`` have no demonstration: their NLL / EVD / DEMO are NaN and they are skipped by
:func:`summarize` (ED and OPD only need the odometry, but they are skipped too so that every metric
averages over the same cycles).

All functions take ``theta`` in raw feature units (the units of ``features``).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from irlsim import N_FEATURES

#: |V(pi^D)| below this is treated as this value in the EVD denominator (avoids 0/0)
EVD_EPS = 1e-8


def _check(theta: torch.Tensor, features: torch.Tensor) -> None:
    assert features.dim() == 3 and features.shape[-1] >= N_FEATURES, f"features {tuple(features.shape)}"
    assert theta.shape == (features.shape[0], features.shape[-1]), f"theta {tuple(theta.shape)}"


def policy_values(theta: torch.Tensor, features: torch.Tensor) -> torch.Tensor:
    """V = -theta^T f. theta: [B, F], features: [B, N, F] -> [B, N]."""
    _check(theta, features)
    return -torch.einsum("bnf,bf->bn", features, theta)


def policy_log_probs(theta: torch.Tensor, features: torch.Tensor) -> torch.Tensor:
    """log p(pi | theta) = log_softmax(-theta^T f) over each cycle's policies -> [B, N]."""
    return torch.log_softmax(policy_values(theta, features), dim=-1)


def _demo(demo_index: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """(valid mask [B], index clamped to >= 0 [B, 1]) for gathering the demonstration policy."""
    demo_index = torch.as_tensor(demo_index).long()
    valid = demo_index >= 0
    return valid, demo_index.clamp_min(0).unsqueeze(-1)


def nll(theta: torch.Tensor, features: torch.Tensor, demo_index: torch.Tensor) -> torch.Tensor:
    """Negative log-likelihood of the demonstration per cycle -> [B] (NaN where demo_index == -1).

    theta^T f^D + logsumexp(-theta^T f) = -log p(pi^D | theta); computed with logsumexp, so it is stable
    for any scale of theta. d NLL / d theta = f^D - E_p[f] (= minus the paper's Eq. 3).
    Train on ``nll(...)[demo_index >= 0].mean()``.
    """
    values = policy_values(theta, features)
    valid, idx = _demo(demo_index)
    out = torch.logsumexp(values, dim=-1) - values.gather(-1, idx.to(values.device)).squeeze(-1)
    return torch.where(valid.to(out.device), out, torch.full_like(out, float("nan")))


def sampled_nll(
    theta: torch.Tensor,
    features: torch.Tensor,
    demo_index: torch.Tensor,
    n_sample: int,
    generator: torch.Generator | None = None,
) -> torch.Tensor:
    """:func:`nll` with the max-ent normaliser Z = sum_pi exp(V(pi)) estimated on a sample of each
    cycle's policies -> [B] (NaN where demo_index == -1).

    The sample holds the demonstration always and m = min(n_sample, N) - 1 of the other N - 1 policies,
    drawn uniformly without replacement, each importance-weighted by (N - 1) / m:
    Z_hat = exp(V(pi^D)) + (N - 1) / m * sum_{j in sample} exp(V(j)), so E[Z_hat] = Z (unbiased);
    log Z_hat, and so the NLL, is biased low by Jensen's inequality (measured in
    docs/results/throughput.md). With
    n_sample >= N the sample is the whole set, every weight is 1 and the value is exactly :func:`nll`'s
    (up to float summation order). Only the sampled policies' values are computed.
    """
    _check(theta, features)
    b, n, nf = features.shape
    m = max(min(n_sample, n) - 1, 0)
    valid, idx = _demo(demo_index)
    idx = idx.to(features.device)
    v_demo = -(features.gather(1, idx[..., None].expand(-1, -1, nf)).squeeze(1) * theta).sum(-1)
    if m == 0:  # the demonstration alone: log Z_hat = V(pi^D)
        out = torch.zeros_like(v_demo)
    else:
        keys = torch.rand(b, n, generator=generator).to(features.device).scatter(1, idx, 2.0)
        others = keys.argsort(dim=1)[:, :m]  # m uniform policies other than the demonstration
        v = -torch.einsum("bmf,bf->bm", features.gather(1, others[..., None].expand(-1, -1, nf)), theta)
        log_w = torch.log(torch.tensor((n - 1) / m, dtype=v.dtype, device=v.device))
        out = torch.logsumexp(torch.cat([v_demo[:, None], v + log_w], dim=1), dim=1) - v_demo
    return torch.where(valid.to(out.device), out, torch.full_like(out, float("nan")))


def expected_value_difference(
    theta: torch.Tensor, features: torch.Tensor, demo_index: torch.Tensor
) -> torch.Tensor:
    """EVD = |E_p[V] - V(pi^D)| / |V(pi^D)| per cycle -> [B] (NaN without a demonstration)."""
    values = policy_values(theta, features)
    p = torch.softmax(values, dim=-1)
    valid, idx = _demo(demo_index)
    v_demo = values.gather(-1, idx.to(values.device)).squeeze(-1)
    out = ((p * values).sum(-1) - v_demo).abs() / v_demo.abs().clamp_min(EVD_EPS)
    return torch.where(valid.to(out.device), out, torch.full_like(out, float("nan")))


def expected_distance(theta: torch.Tensor, features: torch.Tensor, distances: torch.Tensor) -> torch.Tensor:
    """ED = E_p[d] per cycle [m]. distances: [B, N] -> [B]."""
    p = torch.softmax(policy_values(theta, features), dim=-1)
    return (p * distances).sum(-1)


def optimal_policy_distance(
    theta: torch.Tensor, features: torch.Tensor, distances: torch.Tensor
) -> torch.Tensor:
    """OPD = d(argmax_pi V) per cycle [m] -> [B] (ties: the lowest index, i.e. least progress)."""
    best = policy_values(theta, features).argmax(dim=-1, keepdim=True)
    return distances.gather(-1, best).squeeze(-1)


def demo_distance(distances: torch.Tensor, demo_index: torch.Tensor) -> torch.Tensor:
    """DEMO = d(pi^D) per cycle [m], the lower bound of OPD -> [B] (NaN without a demonstration)."""
    valid, idx = _demo(demo_index)
    out = distances.gather(-1, idx.to(distances.device)).squeeze(-1)
    return torch.where(valid.to(out.device), out, torch.full_like(out, float("nan")))


def cycle_metrics(
    theta: torch.Tensor,
    features: torch.Tensor,
    distances: torch.Tensor,
    demo_index: torch.Tensor,
    log_weights: torch.Tensor | None = None,
) -> dict[str, torch.Tensor]:
    """All per-cycle metrics at once: {'nll', 'evd', 'ed', 'opd', 'demo'} each [B].

    ``log_weights`` [B, N]: the policies are a sample of a larger set (:func:`sample_policies`), each
    standing for exp(log_weight) policies; the max-ent normaliser and the expectations (NLL, EVD, ED) are
    the importance-weighted estimates over the sample (exact for the sample itself when every weight is
    0); OPD is the sample's best policy."""
    values = policy_values(theta, features)
    logp = torch.log_softmax(values if log_weights is None else values + log_weights, dim=-1)
    p = logp.exp()
    valid, idx = _demo(demo_index)
    nan = torch.full(values.shape[:1], float("nan"), dtype=values.dtype, device=values.device)
    v_demo = values.gather(-1, idx).squeeze(-1)
    evd = ((p * values).sum(-1) - v_demo).abs() / v_demo.abs().clamp_min(EVD_EPS)
    return {
        "nll": torch.where(valid, -logp.gather(-1, idx).squeeze(-1), nan),
        "evd": torch.where(valid, evd, nan),
        "ed": (p * distances).sum(-1),
        "opd": distances.gather(-1, values.argmax(-1, keepdim=True)).squeeze(-1),
        "demo": torch.where(valid, distances.gather(-1, idx).squeeze(-1), nan),
    }


def sample_policies(
    n: int, m: int, demo_index: np.ndarray, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per cycle, the demonstration and m - 1 of the other n - 1 policies drawn uniformly without
    replacement, in their original (progress) order: the sampled max-ent normaliser of training
    (``policy_sample``).

    demo_index [B] (every entry >= 0) -> (policies [B, m] ascending indices into the n policies,
    the demonstration's position in them [B], log_weights [B, m]: 0 for the demonstration,
    log((n - 1) / (m - 1)) for the others, so that sum exp(V + log_weight) is an unbiased estimate of the
    normaliser sum_pi exp(V(pi)) (the log of it, and so the NLL, is biased low: Jensen). ``m >= n`` gives
    every policy with weight 1 (the exact normaliser)."""
    demo_index = np.asarray(demo_index, dtype=np.int64)
    b = len(demo_index)
    if not (demo_index >= 0).all():
        raise ValueError("sample_policies needs a demonstration in every cycle")
    if m >= n:
        return np.broadcast_to(np.arange(n), (b, n)).copy(), demo_index.copy(), np.zeros((b, n), np.float32)
    if m < 2:
        raise ValueError(f"a policy sample needs m >= 2 (the demonstration and one other), got {m}")
    keys = rng.random((b, n))
    keys[np.arange(b), demo_index] = -1.0  # the demonstration always drawn
    policies = np.sort(np.argpartition(keys, m - 1, axis=1)[:, :m], axis=1)
    is_demo = policies == demo_index[:, None]
    log_w = np.where(is_demo, 0.0, np.log((n - 1) / (m - 1))).astype(np.float32)
    return policies, is_demo.argmax(axis=1), log_w


def attention_target(distances: torch.Tensor, pool: int, tau: float) -> torch.Tensor:
    """Target of the semi-supervised attention loss (PACNN+S): softmax(-d / tau) over the N policies,
    summed in the same groups of ``pool`` consecutive (progress-sorted) policies as the encoder's pooling.

    distances: [B, N] [m]; tau [m] -> [B, ceil(N / pool)], each row sums to 1.
    """
    b, n = distances.shape
    target = torch.softmax(-distances / tau, dim=-1)
    groups = -(-n // pool)
    target = torch.nn.functional.pad(target, (0, groups * pool - n))
    return target.view(b, groups, pool).sum(-1)


def attention_loss(attention: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Semi-supervised attention loss per cycle -> [B]: the L1 distance sum_g |a_g - t_g| in [0, 2].

    The paper calls it the mean absolute distance; we sum over the pooled positions (instead of averaging)
    so its size does not shrink with the number of policies, which keeps ``attention_loss_weight``
    meaningful across N. The batch mean is taken by the caller.
    """
    assert attention.shape == target.shape, f"{tuple(attention.shape)} vs {tuple(target.shape)}"
    return (attention - target).abs().sum(-1)


# --------------------------------------------------------------------------------------------- numpy side


def evaluate_thetas(thetas: np.ndarray, split: Any, chunk: int = 256) -> dict[str, np.ndarray]:
    """Per-cycle metrics of predicted ``thetas`` [C, F] (raw units) on ``split`` (a SplitTensors).

    Works in chunks of ``chunk`` cycles so memory stays bounded for memory-mapped splits.
    Returns {'nll', 'evd', 'ed', 'opd', 'demo'} -> float64 [C] each, and 'valid' [C] bool (has a demo).
    """
    thetas = np.asarray(thetas)
    n_cycles = split.features.shape[0]
    assert thetas.shape == (n_cycles, split.features.shape[-1]), (
        f"thetas {thetas.shape}, split has {n_cycles} cycles"
    )
    out: dict[str, list[np.ndarray]] = {k: [] for k in ("nll", "evd", "ed", "opd", "demo")}
    with torch.no_grad():
        for start in range(0, n_cycles, chunk):
            sl = slice(start, min(start + chunk, n_cycles))
            m = cycle_metrics(
                torch.as_tensor(thetas[sl], dtype=torch.float64),
                torch.tensor(np.asarray(split.features[sl]), dtype=torch.float64),
                torch.tensor(np.asarray(split.distances[sl]), dtype=torch.float64),
                torch.tensor(np.asarray(split.demo_index[sl]), dtype=torch.int64),
            )
            for k, v in m.items():
                out[k].append(v.numpy())
    res = {k: (np.concatenate(v) if v else np.zeros(0)) for k, v in out.items()}
    res["valid"] = np.asarray(split.demo_index) >= 0
    return res


def summarize(metrics: dict[str, np.ndarray]) -> dict[str, float]:
    """Means of per-cycle metrics over cycles with a demonstration (NaN if there are none)."""
    valid = metrics["valid"]
    return {
        k: (float(np.mean(v[valid])) if valid.any() else float("nan"))
        for k, v in metrics.items()
        if k != "valid"
    }


def episode_starts(episode: np.ndarray) -> np.ndarray:
    """Index of the first row of each row's episode run -> [C] int64 (rows in (episode, cycle) order)."""
    episode = np.asarray(episode)
    n = episode.shape[0]
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    new = np.ones(n, dtype=bool)
    new[1:] = episode[1:] != episode[:-1]
    return np.maximum.accumulate(np.where(new, np.arange(n), 0)).astype(np.int64)


def history_mean(thetas: np.ndarray, episode: np.ndarray, H: int = 10) -> np.ndarray:
    """Mean of the last ``H`` predicted thetas within the same episode, the current one included.

    thetas: [C, D] in sequential (episode, cycle) order, episode: [C] -> [C, D]. The first cycles of an
    episode average over the fewer thetas available. Vectorised with a cumulative sum (float64).
    """
    thetas = np.asarray(thetas)
    assert thetas.ndim == 2 and thetas.shape[0] == len(episode), f"{thetas.shape} vs {len(episode)}"
    assert H >= 1, "history H must be >= 1"
    c = thetas.shape[0]
    cs = np.zeros((c + 1, thetas.shape[1]), dtype=np.float64)
    np.cumsum(thetas, axis=0, dtype=np.float64, out=cs[1:])
    i = np.arange(c)
    start = np.maximum(i - H + 1, episode_starts(episode))
    return ((cs[i + 1] - cs[start]) / (i + 1 - start)[:, None]).astype(thetas.dtype)


def history_indices(episode: np.ndarray, H: int = 10) -> np.ndarray:
    """Row indices of the H-cycle history ending at each row (oldest first, the row itself last).

    episode: [C] -> [C, H] int64. Histories never cross an episode boundary: the first cycles of an
    episode are padded by repeating the episode's first row.
    """
    c = len(episode)
    i = np.arange(c)[:, None]
    idx = i - np.arange(H - 1, -1, -1)[None, :]
    return np.maximum(idx, episode_starts(episode)[:, None]).astype(np.int64)
