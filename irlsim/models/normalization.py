"""Per-channel input statistics that travel inside a model (as buffers) and its checkpoint.

A policy's input vector has D = F + 3K + 2K channels, in this order: the F path-integral features (15,
or a larger feature set's: ``n_features``),
the K control points flattened (lateral offset [m], yaw [rad], progress [m] per point), the K actions
flattened (two per point). Models normalise with ``(x - mean) / std``; the std of the F features also
converts a theta predicted for normalised features back to raw feature units (theta_raw = theta_n / std).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from irlsim import N_FEATURES

#: a channel with a smaller std than this is left unscaled (std := 1): it is (almost) constant
MIN_STD = 1e-6


@dataclass(frozen=True)
class FeatureStats:
    """mean, std: [D] float64, D = F + 5K; k: control points per policy; n_features: F (the feature
    set's size, irlsim.FEATURE_SETS)."""

    mean: np.ndarray
    std: np.ndarray
    k: int
    n_features: int = N_FEATURES

    def __post_init__(self) -> None:
        d = self.n_channels
        assert self.mean.shape == (d,) and self.std.shape == (d,), f"stats must be [{d}] for K={self.k}"

    @property
    def n_channels(self) -> int:
        return self.n_features + 5 * self.k

    @classmethod
    def identity(cls, k: int = 10, n_features: int = N_FEATURES) -> FeatureStats:
        d = n_features + 5 * k
        return cls(np.zeros(d), np.ones(d), k, n_features)

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"mean": self.mean.tolist(), "std": self.std.tolist(), "k": self.k}
        if self.n_features != N_FEATURES:  # the paper's set leaves it out (checkpoints as before)
            out["n_features"] = self.n_features
        return out

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> FeatureStats:
        return cls(
            np.asarray(d["mean"], dtype=np.float64),
            np.asarray(d["std"], dtype=np.float64),
            int(d["k"]),
            int(d.get("n_features", N_FEATURES)),
        )


def policy_inputs_np(
    features: np.ndarray, control_points: np.ndarray, actions: np.ndarray, dtype: Any = None
) -> np.ndarray:
    """Concatenate per-policy channels: [..., N, F], [..., N, K, 3], [..., N, K, 2] -> [..., N, D]
    (in ``dtype`` if given: one array, no copy in the inputs' dtype first)."""
    lead = features.shape[:-1]
    parts = [features, control_points.reshape(*lead, -1), actions.reshape(*lead, -1)]
    return np.concatenate(parts, axis=-1, dtype=dtype)


def compute_feature_stats(split: Any, max_cycles: int = 0, chunk: int = 256) -> FeatureStats:
    """Channel mean and std over all policies of the (first ``max_cycles``, 0 = all) cycles of ``split``.

    Chunked float64 sums, so it is memory-bounded on memory-mapped splits: one float64 chunk in memory at
    a time (256 cycles of the paper's 2,500 policies: 0.33 GB).
    """
    n = split.features.shape[0] if max_cycles <= 0 else min(max_cycles, split.features.shape[0])
    k, nf = split.control_points.shape[2], split.features.shape[-1]
    d = nf + 5 * k
    s1, s2, count = np.zeros(d), np.zeros(d), 0
    for start in range(0, n, chunk):
        sl = slice(start, min(start + chunk, n))
        x = policy_inputs_np(
            np.asarray(split.features[sl]),
            np.asarray(split.control_points[sl]),
            np.asarray(split.actions[sl]),
            dtype=np.float64,  # float32 -> float64 is exact: the values of a float32 copy cast after
        ).reshape(-1, d)
        s1 += x.sum(0)
        s2 += np.multiply(x, x, out=x).sum(0)  # squared in place: no second float64 copy of the chunk
        count += x.shape[0]
        del x  # freed before the next chunk is made, not after: one chunk in memory at a time
    if count == 0:
        return FeatureStats.identity(k, nf)
    mean = s1 / count
    std = np.sqrt(np.maximum(s2 / count - mean * mean, 0.0))
    std = np.where(std < MIN_STD, 1.0, std)
    return FeatureStats(mean, std, k, nf)
