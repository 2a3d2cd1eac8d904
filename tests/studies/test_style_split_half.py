"""studies/style_split_half.py on synthetic drivers: drivers apart are told apart as defined (the pooled
normaliser does no better), drivers alike are not (the count is not a foregone conclusion), and the same
seed gives the same counts."""

from __future__ import annotations

import numpy as np

from irlsim.rollout.style import style_summary
from tests.studies.test_styles import _study

study = _study("style_split_half")


def _episodes(speed: float, rng: np.random.Generator, n: int = 20) -> list[dict]:
    """``n`` 60 s episodes around ``speed`` in one of two lanes, behind a leader 25-35 m ahead."""
    out = []
    for _ in range(n):
        t = np.arange(601) * 0.1
        v = np.full(t.size, speed + rng.normal(0.0, 0.3))
        lane = np.full(t.size, int(rng.integers(0, 2)))
        gap = np.full(t.size, rng.uniform(25.0, 35.0))
        out.append(style_summary(t=t, s=np.cumsum(v) * 0.1, v=v, lane=lane, gap=gap))
    return out


def test_drivers_apart_are_told_apart_and_drivers_alike_are_not():
    rng = np.random.default_rng(3)
    apart = {"slow": _episodes(10.0, rng), "middle": _episodes(17.0, rng), "fast": _episodes(24.0, rng)}
    result = study.split_half(apart, splits=20, seed=0)
    defined, pooled = result["as defined"], result["pooled"]
    assert defined["rows"] == pooled["rows"] == 60
    assert defined["own_nearest"] >= 57 and defined["ratio_p90"] < 1.0
    # the pooled normaliser weighs the lanes, which the three drivers keep alike at random, as much as the
    # speed they differ on: it takes a driver for another in a third of the halves here
    assert pooled["own_nearest"] < defined["own_nearest"]
    assert pooled["ratio_median"] > defined["ratio_median"]
    alike = {name: _episodes(14.0, rng) for name in ("a", "b", "c")}
    again = study.split_half(alike, splits=20, seed=0)
    for kind in study.KINDS:
        assert 0 < again[kind]["own_nearest"] < 60  # about a third by chance
        assert again[kind]["ratio_median"] > 0.5
    assert study.split_half(alike, splits=20, seed=0) == again
