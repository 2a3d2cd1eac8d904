"""A tiny in-memory dataset with a known reward (no SUMO, no Parquet): what ``irlsim bench --scale``
trains on, and the tests' and smoke runs' quick dataset. Public: :func:`make_synthetic_dataset`
(a dataset with the reader's interface: ``manifest``, ``split_tensors(split)``), :func:`make_split`,
:func:`default_theta_true`.

Each cycle has N policies with random control points / actions; their 15 path-integral feature costs
are a fixed non-negative function of them plus noise; the demonstration is *sampled* from
p(pi | theta_true) = softmax(-theta_true^T f), and a policy's distance to the demonstration is the mean
Euclidean distance of its control points (lateral offset, progress) to the demonstration's [m], so
DEMO = 0 and a theta close to theta_true has a low OPD. As in the real data, ``stop_line`` is an event:
zero for most policies.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from irlsim import FEATURE_NAMES, N_FEATURES
from irlsim.data.schema import SCHEMA_VERSION

STOP_LINE = FEATURE_NAMES.index("stop_line")


@dataclass(frozen=True)
class SyntheticSplit:
    """Same fields and shapes as irlsim.data.reader.SplitTensors."""

    features: np.ndarray  # [C, N, 15] float32
    control_points: np.ndarray  # [C, N, K, 3] float32
    actions: np.ndarray  # [C, N, K, 2] float32
    distances: np.ndarray  # [C, N] float32
    demo_index: np.ndarray  # [C] int64
    demo_distance: np.ndarray  # [C] float32
    episode: np.ndarray  # [C] int32
    cycle: np.ndarray  # [C] int32
    executed_index: np.ndarray  # [C] int32
    labels: np.ndarray  # [C, N, 3] bool


def default_theta_true() -> np.ndarray:
    """A sparse-ish reward: four dominant features, the rest nearly ignored (so a uniform theta is wrong)."""
    theta = np.full(N_FEATURES, 0.05)
    theta[[1, 4, 9, 13]] = [3.0, 2.0, 4.0, 2.5]
    return theta


def make_split(
    n_cycles: int,
    n_policies: int,
    theta_true: np.ndarray,
    seed: int,
    k: int = 10,
    episode_len: int = 8,
    no_demo_every: int = 0,
) -> SyntheticSplit:
    rng = np.random.default_rng(seed)
    c, n = n_cycles, n_policies
    lat = rng.normal(0.0, 2.0, (c, n, 1)) * np.linspace(0.1, 1.0, k)[None, None, :]
    prog = rng.uniform(0.0, 30.0, (c, n, 1)) * np.linspace(0.1, 1.0, k)[None, None, :]
    yaw = 0.05 * lat
    cps = np.stack([lat, yaw, prog], axis=-1)
    order = np.argsort(cps[:, :, -1, 2], axis=1)  # sort policies by progress, ascending
    cps = np.take_along_axis(cps, order[:, :, None, None], axis=1)
    actions = np.stack([np.gradient(cps[..., 2], axis=-1), np.gradient(cps[..., 0], axis=-1)], axis=-1)
    # features: a fixed non-negative mixture of |control point| summaries plus noise
    summary = np.concatenate(
        [np.abs(cps).mean(2), np.abs(actions).mean(2), np.abs(cps[:, :, -1])], -1
    )  # [C,N,8]
    mix = np.random.default_rng(1).uniform(0.0, 1.0, (summary.shape[-1], N_FEATURES))
    feats = 0.2 * summary @ mix / summary.shape[-1] + rng.exponential(0.5, (c, n, N_FEATURES))
    # stop_line is an event (0 for a policy that crosses no active line): non-zero for about a fifth of
    # the policies, so the default stop_demos rule moves some demonstrations and keeps most cycles
    event = np.random.default_rng(seed + 7919).uniform(size=(c, n)) < 0.2
    feats[:, :, STOP_LINE] *= event
    logits = -(feats @ theta_true)
    p = np.exp(logits - logits.max(1, keepdims=True))
    p /= p.sum(1, keepdims=True)
    demo = np.array([rng.choice(n, p=pi) for pi in p], dtype=np.int64)
    rows = np.arange(c)
    d_cp = cps[:, :, :, [0, 2]] - cps[rows, demo][:, None, :, [0, 2]]
    distances = np.sqrt((d_cp**2).sum(-1)).mean(-1)
    if no_demo_every:
        demo[::no_demo_every] = -1
    return SyntheticSplit(
        features=feats.astype(np.float32),
        control_points=cps.astype(np.float32),
        actions=actions.astype(np.float32),
        distances=distances.astype(np.float32),
        demo_index=demo,
        demo_distance=np.where(demo >= 0, 0.0, np.nan).astype(np.float32),
        episode=(rows // episode_len).astype(np.int32),
        cycle=(rows % episode_len).astype(np.int32),
        executed_index=np.maximum(demo, 0).astype(np.int32),
        labels=np.zeros((c, n, 3), dtype=bool),
    )


@dataclass
class SyntheticDataset:
    """Anything with ``split_tensors(name)`` and ``manifest`` works as a dataset for the training loops."""

    splits: dict[str, Any]
    theta_true: np.ndarray
    manifest: dict[str, Any] = field(
        default_factory=lambda: {"schema_version": SCHEMA_VERSION, "feature_names": list(FEATURE_NAMES)}
    )

    def split_tensors(self, name: str) -> Any:
        return self.splits[name]


def make_synthetic_dataset(
    n_train: int = 96,
    n_eval: int = 48,
    n_policies: int = 32,
    k: int = 10,
    seed: int = 0,
    theta_true: np.ndarray | None = None,
) -> SyntheticDataset:
    """train / validation / test splits of a known reward (see module docstring)."""
    theta = default_theta_true() if theta_true is None else np.asarray(theta_true, dtype=np.float64)
    return SyntheticDataset(
        splits={
            "train": make_split(n_train, n_policies, theta, seed, k, no_demo_every=10),
            "validation": make_split(n_eval, n_policies, theta, seed + 1, k),
            "test": make_split(n_eval, n_policies, theta, seed + 2, k),
        },
        theta_true=theta,
        manifest={
            "schema_version": SCHEMA_VERSION,
            "feature_names": list(FEATURE_NAMES),
            # what identifies this dataset in a checkpoint (irlsim.train.checkpoint.dataset_identity)
            "synthetic": {
                "n_train": n_train,
                "n_eval": n_eval,
                "n_policies": n_policies,
                "k": k,
                "seed": seed,
            },
        },
    )
