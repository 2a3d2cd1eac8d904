"""Reward stability on a sequential split: how much a model's reward and plan jump per cycle.

For consecutive cycles t, t+1 of the same episode:

- **theta change** = |theta_{t+1} - theta_t| / max(|theta_t|, eps) (Euclidean norms, raw feature units):
  the mean relative change of the reward weights. 0 for a constant theta.
- **plan change** [m] = the mean distance, over the common time span, between the policy chosen at
  t+1 (argmax V) and the one chosen at t. Each policy is known at its K control points
  (t + horizon k / K, k = 1..K) as route-frame offsets to the ego of its cycle; both are made absolute
  with the ego's stored (s, d), the plan of t is taken at its control points that lie after t+1, and the
  plan of t+1 is interpolated linearly at those times (from its own start, the ego at t+1, and its
  control points). Distance in the route frame: sqrt(ds^2 + dd^2).

Both are reported overall and "around situation switches": the pairs whose later cycle lies at most
``window`` cycles before or after a change of situation label (:func:`near_switch`; the labels are the
dataset's ``situation`` column, ``irlsim.data.situations``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

THETA_EPS = 1e-12


def situation_switches(situation: np.ndarray, episode: np.ndarray) -> np.ndarray:
    """[C] bool: the cycle's label differs from the previous cycle's in the same episode (the first
    cycle of an episode is no switch). Rows in (episode, cycle) order."""
    situation, episode = np.asarray(situation), np.asarray(episode)
    out = np.zeros(len(situation), dtype=bool)
    out[1:] = (situation[1:] != situation[:-1]) & (episode[1:] == episode[:-1])
    return out


def near_switch(situation: np.ndarray, episode: np.ndarray, window: int = 2) -> np.ndarray:
    """[C] bool: cycles at most ``window`` cycles before or after a situation switch, same episode
    (the switch cycle is the first cycle of the new label; the cycles just before it are the old one's)."""
    sw = situation_switches(situation, episode)
    c = len(sw)
    out = np.zeros(c, dtype=bool)
    idx = np.flatnonzero(sw)
    episode = np.asarray(episode)
    for k in range(-window, window):  # before: -window..-1, after: 0..window-1
        j = idx + k
        ok = (j >= 0) & (j < c)
        j = j[ok]
        out[j[episode[j] == episode[idx[ok]]]] = True
    return out


def consecutive_pairs(episode: np.ndarray) -> np.ndarray:
    """[C] bool: row i has a predecessor i-1 in the same episode (rows in (episode, cycle) order)."""
    episode = np.asarray(episode)
    out = np.zeros(len(episode), dtype=bool)
    out[1:] = episode[1:] == episode[:-1]
    return out


def theta_change(thetas: np.ndarray, episode: np.ndarray) -> np.ndarray:
    """[C] relative change |theta_i - theta_{i-1}| / |theta_{i-1}|; NaN where i has no predecessor."""
    thetas = np.asarray(thetas, dtype=np.float64)
    out = np.full(len(thetas), np.nan)
    pair = consecutive_pairs(episode)
    if len(thetas) > 1:
        num = np.linalg.norm(thetas[1:] - thetas[:-1], axis=1)
        den = np.maximum(np.linalg.norm(thetas[:-1], axis=1), THETA_EPS)
        out[1:] = np.where(pair[1:], num / den, np.nan)
    return out


def plan_change(
    chosen: np.ndarray,
    control_points: Any,
    ego_s: np.ndarray,
    ego_d: np.ndarray,
    t: np.ndarray,
    episode: np.ndarray,
    horizon: float,
    chunk: int = 1024,
) -> np.ndarray:
    """[C] plan change [m] between the policy chosen at row i and the one chosen at row i-1 (module
    docstring); NaN where i has no predecessor or the two plans share no time.

    chosen: [C] policy index per cycle; control_points: [C, N, K, 3] (lateral offset, yaw, progress to the
    ego; memory-mapped is fine); ego_s, ego_d [m], t [s], episode: [C]; horizon [s].
    """
    chosen = np.asarray(chosen, dtype=np.int64)
    c = len(chosen)
    k = control_points.shape[2]
    cp = np.empty((c, k, 2))
    for start in range(0, c, chunk):  # gather the chosen policies' points, a chunk of cycles at a time
        sl = slice(start, min(start + chunk, c))
        block = np.asarray(control_points[sl])
        sel = block[np.arange(len(block)), chosen[sl]]  # [B, K, 3]
        cp[sl, :, 0] = sel[:, :, 2]  # progress
        cp[sl, :, 1] = sel[:, :, 0]  # lateral offset
    s_abs = np.asarray(ego_s, np.float64)[:, None] + cp[:, :, 0]  # [C, K]
    d_abs = np.asarray(ego_d, np.float64)[:, None] + cp[:, :, 1]
    out = np.full(c, np.nan)
    if c < 2:
        return out
    step = horizon / k
    tau = np.arange(1, k + 1) * step  # [K] control-point times of a plan
    dt = np.asarray(t, np.float64)[1:] - np.asarray(t, np.float64)[:-1]  # [C-1] time between cycles
    # the earlier plan's points at times tau - dt on the later plan's clock (only those in (0, horizon])
    q = tau[None, :] - dt[:, None]  # [C-1, K]
    inside = (q > 0) & (q <= horizon + 1e-9)
    # the later plan with its start (the ego, offset 0) prepended: grid 0, step, ..., horizon
    s_new = np.concatenate([np.asarray(ego_s, np.float64)[1:, None], s_abs[1:]], axis=1)  # [C-1, K+1]
    d_new = np.concatenate([np.asarray(ego_d, np.float64)[1:, None], d_abs[1:]], axis=1)
    pos = np.clip(q / step, 0, k)
    i0 = np.minimum(np.floor(pos).astype(np.int64), k - 1)
    w = pos - i0
    rows = np.arange(c - 1)[:, None]
    s_i = s_new[rows, i0] * (1 - w) + s_new[rows, i0 + 1] * w
    d_i = d_new[rows, i0] * (1 - w) + d_new[rows, i0 + 1] * w
    dist = np.hypot(s_i - s_abs[:-1], d_i - d_abs[:-1])
    n = inside.sum(1)
    mean = np.where(n > 0, (dist * inside).sum(1) / np.maximum(n, 1), np.nan)
    out[1:] = np.where(consecutive_pairs(episode)[1:], mean, np.nan)
    return out


def stability_summary(
    theta_chg: np.ndarray | None,
    plan_chg: np.ndarray,
    situation: np.ndarray | None,
    episode: np.ndarray,
    window: int = 2,
) -> dict[str, float]:
    """Means: 'theta_change', 'plan_change' [m] over all pairs, and '..._switch' over the pairs near a
    situation switch (NaN without situations, without a theta, or without such pairs)."""

    def mean(v: np.ndarray | None, mask: np.ndarray | None = None) -> float:
        if v is None:
            return float("nan")
        ok = np.isfinite(v) if mask is None else np.isfinite(v) & mask
        return float(v[ok].mean()) if ok.any() else float("nan")

    near = None
    if situation is not None and (np.asarray(situation) >= 0).all():
        near = near_switch(situation, episode, window)
    return {
        "theta_change": mean(theta_chg),
        "plan_change": mean(plan_chg),
        "theta_change_switch": mean(theta_chg, near) if near is not None else float("nan"),
        "plan_change_switch": mean(plan_chg, near) if near is not None else float("nan"),
    }


def temporal_weight_summary(
    weights: np.ndarray, situation: np.ndarray | None, episode: np.ndarray, window: int = 2
) -> dict[str, float]:
    """Of PTACNN's temporal weights [C, H] (oldest first, newest last): 'newest_weight' (mean weight of
    the newest entry; 1 = the history is ignored), 'weight_shift' (mean L1 change of the weight vector
    between consecutive cycles), and both '..._switch' over the cycles near a situation switch."""
    weights = np.asarray(weights, dtype=np.float64)
    newest = weights[:, -1]
    shift = np.full(len(weights), np.nan)
    pair = consecutive_pairs(episode)
    if len(weights) > 1:
        shift[1:] = np.where(pair[1:], np.abs(weights[1:] - weights[:-1]).sum(1), np.nan)
    near = None
    if situation is not None and (np.asarray(situation) >= 0).all():
        near = near_switch(situation, episode, window)

    def mean(v: np.ndarray, mask: np.ndarray | None) -> float:
        ok = np.isfinite(v) if mask is None else np.isfinite(v) & mask
        return float(v[ok].mean()) if ok.any() else float("nan")

    return {
        "newest_weight": mean(newest, None),
        "weight_shift": mean(shift, None),
        "newest_weight_switch": mean(newest, near) if near is not None else float("nan"),
        "weight_shift_switch": mean(shift, near) if near is not None else float("nan"),
    }
