"""The value share of studies/style_weights.py against closed forms."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

_spec = importlib.util.spec_from_file_location(
    "style_weights", Path(__file__).parents[2] / "studies" / "style_weights.py"
)
study = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(study)  # type: ignore[union-attr]


def test_value_shares_closed_form():
    rng = np.random.default_rng(0)
    f = rng.normal(size=(7, 40, 15))
    theta = np.zeros((7, 15))
    theta[:, 3] = 2.0
    np.testing.assert_allclose(study.value_shares(theta, f), np.eye(15)[3])  # one weight: all of it
    # two features with the same spread in every cycle, weights 1 and 3: shares 1/4 and 3/4
    g = np.zeros((5, 4, 15))
    g[:, :, 0] = g[:, :, 1] = [0.0, 1.0, 2.0, 3.0]
    th = np.zeros((5, 15))
    th[:, 0], th[:, 1] = 1.0, -3.0
    shares = study.value_shares(th, g, chunk=2)  # chunks add up as one pass
    np.testing.assert_allclose(shares[:2], [0.25, 0.75])
    assert np.isclose(shares.sum(), 1.0)
    # a constant feature moves no value whatever its weight
    g[:, :, 2] = 5.0
    th[:, 2] = 100.0
    np.testing.assert_allclose(study.value_shares(th, g)[:2], [0.25, 0.75])
