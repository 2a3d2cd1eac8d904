"""The pictures as pure functions of synthetic frames: files exist, are non-empty and have the set size."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from irlsim import N_FEATURES
from irlsim.viz.drive import CycleFrame, save_animation, save_frame_pictures
from irlsim.viz.radar import radar_radius


def synthetic_frame(
    cycle: int = 7, p: int = 60, t: int = 51, h: int | None = 10, attention: bool = True
) -> CycleFrame:
    rng = np.random.default_rng(cycle)
    tt = np.linspace(0.0, 5.0, t)
    v = rng.uniform(5.0, 20.0, (p, 1))
    lat = rng.uniform(-3.2, 3.2, (p, 1))
    x = (100.0 + v * tt).astype(np.float32)
    y = (50.0 + lat * np.clip(tt / 3.0, 0.0, 1.0)).astype(np.float32)
    value = v[:, 0] - np.abs(lat[:, 0])
    rank = (np.argsort(np.argsort(value)) / (p - 1)).astype(np.float32)
    att = rng.random(p).astype(np.float32)
    top = np.zeros(p, bool)
    top[np.argsort(att)[-5:]] = True
    road = tuple(
        ("edge" if abs(d) > 4 else "divider", np.stack([np.linspace(60, 220, 40), np.full(40, 50.0 + d)], 1))
        for d in (-4.8, -1.6, 1.6, 4.8)
    )
    w = None
    if h:
        w = rng.random(h)
        w /= w.sum()
    return CycleFrame(
        model="PTACNN+S",
        cycle=cycle,
        t=0.2 * cycle,
        x=x,
        y=y,
        value_rank=rank,
        top_attention=top,
        chosen=int(np.argmax(value)),
        theta=rng.uniform(0.01, 5.0, N_FEATURES),
        ego=(100.0, 50.0, 0.0, 12.0, 4.5, 1.8),
        vehicles=np.array([[130.0, 50.0, 0.0, 4.5, 1.8]]),
        attention=att if attention else None,
        temporal_weights=w,
        lines=road,
    )


def _size(path):
    assert path.is_file() and path.stat().st_size > 1000, path
    with Image.open(path) as im:
        return im.size


def test_stills_have_the_expected_sizes(tmp_path):
    paths = save_frame_pictures(tmp_path, synthetic_frame(7), reference=np.ones(N_FEATURES), dpi=100)
    assert [p.name for p in paths] == ["cycle_0007.png", "radar_0007.png", "temporal_0007.png"]
    assert _size(paths[0]) == (1000, 360)
    assert _size(paths[1]) == (500, 500)
    assert _size(paths[2]) == (500, 300)
    assert not list(tmp_path.glob(".*")), "temporary files left behind"


def test_stills_without_attention_or_history(tmp_path):
    # the expert and stage-1 models: no policy attention, no temporal weights; negative weights marked
    fr = synthetic_frame(3, attention=False, h=None)
    fr = CycleFrame(
        **{**fr.__dict__, "top_attention": np.zeros(len(fr.value_rank), bool), "theta": -fr.theta}
    )
    for p in save_frame_pictures(tmp_path, fr):
        assert p.stat().st_size > 1000


def test_animation_has_one_frame_per_cycle(tmp_path):
    frames = [synthetic_frame(c) for c in range(6)]
    path = save_animation(tmp_path / "episode.gif", frames, reference=np.ones(N_FEATURES), dpi=50)
    with Image.open(path) as im:
        assert im.format == "GIF" and im.n_frames == 6 and im.size == (500, 400)
    with pytest.raises(ValueError):
        save_animation(tmp_path / "empty.gif", [])


def test_radar_radius_is_log_relative_to_the_reference():
    ref = np.full(4, 2.0)
    r = radar_radius(np.array([2.0, 20.0, 0.002, 0.0]), ref, decades=(-3.0, 1.0))
    # the unit ring (same weight as the reference) sits at 3/4; x10 at the rim; x0.001 and 0 at the centre
    np.testing.assert_allclose(r, [0.75, 1.0, 0.0, 0.0])
    np.testing.assert_allclose(radar_radius(np.array([1e-2, 1e3]), None), [0.25, 1.0])
