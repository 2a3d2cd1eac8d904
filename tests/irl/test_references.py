"""Reference rows of Table I on hand-made cycles."""

from __future__ import annotations

import numpy as np

from irlsim import N_FEATURES
from irlsim.data.reader import SplitTensors
from irlsim.irl.objectives import summarize
from irlsim.irl.references import executed_metrics, expert_theta_metrics, oracle_metrics


def _split(
    feats2: np.ndarray, distances: np.ndarray, demo_index: list[int], executed: list[int]
) -> SplitTensors:
    c, n, _ = feats2.shape
    f = np.zeros((c, n, N_FEATURES), np.float32)
    f[:, :, : feats2.shape[2]] = feats2
    k = 2
    return SplitTensors(
        features=f,
        control_points=np.zeros((c, n, k, 3), np.float32),
        actions=np.zeros((c, n, k, 2), np.float32),
        distances=distances.astype(np.float32),
        demo_index=np.array(demo_index, np.int64),
        demo_distance=distances[np.arange(c), np.maximum(demo_index, 0)].astype(np.float32),
        episode=np.zeros(c, np.int32),
        cycle=np.arange(c, dtype=np.int32),
        executed_index=np.array(executed, np.int32),
        labels=np.zeros((c, n, 3), bool),
    )


def test_oracle_reaches_a_demonstration_that_some_theta_makes_optimal() -> None:
    # policy 2 is optimal for theta = (1, 1): costs 1, 1, 0.6, 2; it is the demonstration
    feats = np.array([[[1.0, 0.0], [0.0, 1.0], [0.3, 0.3], [1.0, 1.0]]])
    dist = np.array([[2.0, 3.0, 0.1, 4.0]])
    split = _split(feats, dist, demo_index=[2], executed=[1])
    m, thetas = oracle_metrics(split)
    assert m["opd"][0] == np.float64(np.float32(0.1))  # the oracle picks the demonstration
    assert m["opd"][0] == m["demo"][0]
    assert np.argmin(feats[0] @ thetas[0, :2]) == 2
    assert m["nll"][0] < np.log(4) - 0.5  # far better than uniform


def test_oracle_cannot_reach_a_demonstration_no_theta_makes_optimal() -> None:
    # policy 2 = (0.6, 0.6) lies above the segment (1,0)-(0,1): never the strict minimum of theta . f
    feats = np.array([[[1.0, 0.0], [0.0, 1.0], [0.6, 0.6], [1.0, 1.0]]])
    dist = np.array([[2.0, 3.0, 0.1, 4.0]])
    m, _ = oracle_metrics(_split(feats, dist, demo_index=[2], executed=[2]))
    assert m["opd"][0] > m["demo"][0]


def test_executed_and_expert_theta_rows() -> None:
    rng = np.random.default_rng(0)
    feats = rng.uniform(0, 1, (3, 5, 2))
    dist = rng.uniform(0, 2, (3, 5))
    split = _split(feats, dist, demo_index=[0, -1, 4], executed=[3, 1, 2])
    ex = executed_metrics(split)
    np.testing.assert_allclose(ex["opd"], dist[[0, 1, 2], [3, 1, 2]].astype(np.float32))
    np.testing.assert_array_equal(ex["ed"], ex["opd"])
    assert np.isnan(ex["evd"]).all() and ex["valid"].tolist() == [True, False, True]
    s = summarize(ex)
    assert np.isclose(s["opd"], np.mean(dist[[0, 2], [3, 2]].astype(np.float32)))
    theta = np.zeros(N_FEATURES)
    theta[:2] = [1.0, 2.0]
    et = expert_theta_metrics(split, theta)
    best = np.argmin(feats @ theta[:2], axis=1)
    np.testing.assert_allclose(et["opd"], dist[np.arange(3), best].astype(np.float32))
