"""The pictures as pure functions of synthetic frames (sizes, layers, the fitted window, same bytes every
time), and plot-cycle's drawing of a real planner cycle with the planner's own vehicle predictions."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from irlsim import N_FEATURES
from irlsim.viz.figure import new_figure
from irlsim.viz.frames import (
    FONT,
    PREDICTION_COLOR,
    TOP_COLOR,
    cycle_figure_size,
    draw_cycle,
    panels_figure_size,
    save_animation,
    save_cycle,
    save_frame_pictures,
)
from irlsim.viz.radar import radar_radius
from irlsim.viz.scene import CycleFrame, cycle_window


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
    fr = synthetic_frame(7)
    paths = save_frame_pictures(tmp_path, fr, reference=np.ones(N_FEATURES), dpi=100)
    assert [p.name for p in paths] == ["cycle_0007.png", "radar_0007.png", "temporal_0007.png"]
    w, h = cycle_figure_size(cycle_window(fr))
    assert _size(paths[0]) == (1000, round(100 * h))
    assert _size(paths[1]) == (500, 500)
    assert _size(paths[2]) == (600, 360)
    assert not list(tmp_path.glob(".*")), "temporary files left behind"


def test_the_window_fits_the_road_and_the_policies():
    """Road edges at +-4.8 m around the ego, policies within +-3.2 m reaching 5 s x 20 m/s = 100 m ahead:
    the window is [-(4.5 + 8) - 1, 100 + 4] x [-4.8 - 1.2, 4.8 + 1.2], and the figure keeps its aspect."""
    fr = synthetic_frame(7)
    px = fr.x - fr.ego[0]
    win = cycle_window(fr)
    assert np.isclose(win.x0, -13.5) and np.isclose(win.x1, float(px.max()) + 4.0)
    assert np.isclose(win.y0, -6.0) and np.isclose(win.y1, 6.0)
    w, h = cycle_figure_size(win)
    assert w == 10.0 and h < 3.0, "the figure is as tall as the road needs, not a fixed 3.6 in"
    # a far vehicle outside the window does not stretch it
    far = CycleFrame(**{**fr.__dict__, "vehicles": np.array([[400.0, 80.0, 0.0, 4.5, 1.8]])})
    assert cycle_window(far) == win


def test_cycle_layers_legend_and_colour_bar():
    """Top-attention policies above the value-coloured ones, thicker than the executed one, which is on
    top of them; the legend names them; a colour bar explains the value colours."""
    from matplotlib.collections import LineCollection

    fr = synthetic_frame(7)
    fig = new_figure((10.0, 3.0))
    ax = fig.add_subplot(111)
    draw_cycle(ax, fr)
    cols = [c for c in ax.collections if isinstance(c, LineCollection)]
    assert len(cols) == 2
    by_value, top = cols
    assert len(by_value.get_segments()) == len(fr.x)
    assert len(top.get_segments()) == int(fr.top_attention.sum())
    assert top.get_zorder() > by_value.get_zorder()
    assert np.allclose(top.get_colors()[0][:3], _rgb(TOP_COLOR))
    executed = [ln for ln in ax.lines if ln.get_color() == "black" and len(ln.get_xdata()) == fr.x.shape[1]]
    assert len(executed) == 1 and executed[0].get_zorder() > top.get_zorder()
    assert top.get_linewidths()[0] > executed[0].get_linewidth()
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels == ["top-5 attention", "executed", "vehicle", "ego"]
    assert all(t.get_fontsize() == FONT["legend"] for t in ax.get_legend().get_texts())
    (cax,) = ax.child_axes
    assert cax.get_ylabel() == "value" and [t.get_text() for t in cax.get_yticklabels()] == ["low", "high"]


def _rgb(color):
    from matplotlib.colors import to_rgb

    return np.array(to_rgb(color))


def test_cycle_picture_is_the_same_bytes_every_time(tmp_path):
    fr = synthetic_frame(5)
    a, b = save_cycle(tmp_path / "a.png", fr), save_cycle(tmp_path / "b.png", fr)
    assert a.read_bytes() == b.read_bytes()


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
    # one window for all frames: the union of theirs
    wins = [cycle_window(f) for f in frames]
    union = wins[0]
    for w in wins[1:]:
        union = union.union(w)
    assert union.x1 == max(w.x1 for w in wins) and union.y0 == min(w.y0 for w in wins)
    w, h = panels_figure_size(union)
    with Image.open(path) as im:
        assert im.format == "GIF" and im.n_frames == 6 and im.size == (round(50 * w), round(50 * h))
    with pytest.raises(ValueError):
        save_animation(tmp_path / "empty.gif", [])


def test_radar_radius_is_log_relative_to_the_reference():
    ref = np.full(4, 2.0)
    r = radar_radius(np.array([2.0, 20.0, 0.002, 0.0]), ref, decades=(-3.0, 1.0))
    # the unit ring (same weight as the reference) sits at 3/4; x10 at the rim; x0.001 and 0 at the centre
    np.testing.assert_allclose(r, [0.75, 1.0, 0.0, 0.0])
    np.testing.assert_allclose(radar_radius(np.array([1e-2, 1e3]), None), [0.25, 1.0])


def test_plot_cycle_draws_the_planners_predictions(road):
    """A vehicle 30 m before an active stop line at 15 m/s: the planner predicts it braking to stand
    0.3 m before the line within the 5 s horizon (b = v^2 / (2 * 29.7 m), standing after 3.96 s); one far
    from any line keeps its speed. plot-cycle draws exactly that (not a constant-speed extrapolation)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from irlsim.planner.expert import THETA_EXPERT
    from irlsim.planner.planner import Planner
    from irlsim.viz.cycle import draw_cycle as plot_cycle
    from irlsim.viz.cycle import predicted_vehicles
    from tests.planner.conftest import make_obs, make_vehicles

    line = road.stop_lines[1].s
    free_s = line + 300.0  # no stop line within 80 m ahead of it
    assert all((sl.s - free_s) % road.lap_length > 90.0 for sl in road.stop_lines)
    veh = make_vehicles(road, [(line - 30.0, 3.2, 15.0), (free_s, 0.0, 10.0)])
    obs = make_obs(road, line - 45.0, 0.0, 12.0, vehicles=veh, stop_s=line)
    ps = Planner(road).plan(obs)
    t = np.linspace(0.0, 5.0, ps.n_steps)
    pred = predicted_vehicles(road, obs.ego.s, veh, t)
    assert pred.shape == (2, ps.n_steps, 3)
    x_stop, y_stop = road.to_xy(np.array(line - 0.3), np.array(3.2))
    assert np.hypot(pred[0, -1, 0] - x_stop, pred[0, -1, 1] - y_stop) < 0.05
    x_free, y_free = road.to_xy(np.array(free_s + 10.0 * 5.0), np.array(0.0))
    assert np.hypot(pred[1, -1, 0] - x_free, pred[1, -1, 1] - y_free) < 0.05

    fig, ax = plt.subplots(figsize=(12, 6))
    try:
        value = ps.value(THETA_EXPERT)
        plot_cycle(ax, road, ps, value, chosen=int(np.argmax(value)), vehicles=veh, highlight=np.arange(3))
        dotted = [ln for ln in ax.lines if ln.get_color() == PREDICTION_COLOR and ln.get_linestyle() == ":"]
        ends = np.array([ln.get_xydata()[-1] for ln in dotted if len(ln.get_xdata())])
        # drawn in the view frame: ego front bumper at the origin, the road's heading to the right
        yaw = float(road.heading(np.array(obs.ego.s)))
        dx, dy = x_stop - obs.ego.x, y_stop - obs.ego.y
        want = np.array([np.cos(yaw) * dx + np.sin(yaw) * dy, -np.sin(yaw) * dx + np.cos(yaw) * dy])
        assert len(ends) == 2 and np.min(np.hypot(*(ends - want).T)) < 0.05
        labels = [tx.get_text() for tx in ax.get_legend().get_texts()]
        assert labels[:2] == ["top-3 attention", "executed"]
    finally:
        plt.close(fig)
