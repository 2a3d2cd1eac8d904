"""The temporal attention as a strip over time: :func:`irlsim.viz.frames.draw_temporal`'s bars of
one cycle, stacked for consecutive cycles of a sequential split, with the situation labels on top.

Rows of the strip are the history lags (now at the top, oldest at the bottom), columns the cycles, the
colour the weight; a second panel shows the newest entry's weight and the uniform 1/H (the H-mean the
stage-1 models use), the top band each cycle's situation label.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from irlsim.data.situations import LANE_CHANGE, SITUATION_NAMES, STOP_APPROACH
from irlsim.viz.figure import new_figure, save_figure
from irlsim.viz.frames import FONT

#: colours of the situation codes 0..5 in the top band
SITUATION_COLOURS = ("#dddddd", "#b00000", "#ff8c00", "#1f77b4", "#2ca02c", "#9467bd")


def onset_window(
    situation: np.ndarray, episode: np.ndarray, code: int, before: int = 30, after: int = 50, nth: int = 0
) -> slice | None:
    """Rows around the ``nth`` onset (a switch into ``code``) in the split, clipped to its episode;
    None when there is no such onset."""
    situation, episode = np.asarray(situation), np.asarray(episode)
    on = (
        np.flatnonzero((situation[1:] == code) & (situation[:-1] != code) & (episode[1:] == episode[:-1])) + 1
    )
    if len(on) <= nth:
        return None
    i = int(on[nth])
    rows = np.flatnonzero(episode == episode[i])
    return slice(max(rows[0], i - before), min(rows[-1] + 1, i + after))


def save_temporal_strip(
    path: str | Path,
    weights: np.ndarray,
    situation: np.ndarray,
    t: np.ndarray,
    title: str = "",
    dpi: int = 110,
) -> Path:
    """The strip of ``weights`` [T, H] (oldest first) over ``T`` cycles at times ``t`` [s], with their
    ``situation`` codes [T]. Written atomically; returns the path."""
    w = np.asarray(weights, dtype=np.float64)
    n, h = w.shape
    t = np.asarray(t, dtype=np.float64)
    fig = new_figure((10.0, 4.6))
    band, strip, line = (
        fig.add_axes((0.08, y, 0.80, hh)) for y, hh in ((0.86, 0.05), (0.40, 0.44), (0.10, 0.26))
    )
    sit = np.asarray(situation)
    colours = np.array([SITUATION_COLOURS[s] if 0 <= s < len(SITUATION_COLOURS) else "#ffffff" for s in sit])
    band.bar(t, np.ones(n), width=(t[1] - t[0]) if n > 1 else 0.2, color=colours, align="center")
    band.set_xlim(t[0], t[-1])
    band.set_yticks([])
    band.set_xticks([])
    present = sorted({int(s) for s in sit if 0 <= s < len(SITUATION_NAMES)})
    for s in present:
        band.bar([np.nan], [0], color=SITUATION_COLOURS[s], label=SITUATION_NAMES[s])
    band.legend(
        loc="lower left", bbox_to_anchor=(0.0, 1.0), ncol=len(present), fontsize=FONT["legend"], frameon=False
    )
    band.set_title(title or "temporal attention over time", fontsize=FONT["title"], pad=18)
    im = strip.imshow(
        w[:, ::-1].T,  # row 0 = now
        aspect="auto",
        origin="upper",
        extent=(t[0], t[-1], h - 0.5, -0.5),
        cmap="Purples",
        vmin=0.0,
        vmax=1.0,
        interpolation="nearest",
    )
    strip.set_yticks(range(h))
    strip.set_yticklabels(["now" if k == 0 else f"-{k}" for k in range(h)], fontsize=FONT["tick"])
    strip.set_ylabel("history entry", fontsize=FONT["label"])
    strip.set_xticks([])
    cax = fig.add_axes((0.90, 0.40, 0.015, 0.44))
    fig.colorbar(im, cax=cax).set_label("weight", fontsize=FONT["label"])
    line.plot(t, w[:, -1], color="tab:purple", label="weight of the newest entry")
    line.axhline(1.0 / h, color="0.4", lw=1.0, ls="--", label=f"uniform 1/H (H = {h})")
    line.set_xlim(t[0], t[-1])
    line.set_ylim(0.0, 1.05)
    line.set_xlabel("time [s]", fontsize=FONT["label"])
    line.set_ylabel("weight", fontsize=FONT["label"])
    line.legend(loc="lower right", fontsize=FONT["legend"], frameon=False)
    line.tick_params(labelsize=FONT["tick"])
    return save_figure(fig, path, dpi)


def save_situation_strips(
    out_dir: str | Path,
    name: str,
    weights: np.ndarray,
    situation: np.ndarray,
    t: np.ndarray,
    episode: np.ndarray,
) -> dict[str, str]:
    """``temporal_<model>_<situation>.png`` strips of a temporal model over the split's first stop-line
    approach and first lane change; returns {'strip_<situation>': file name} of those drawn."""
    out = {}
    for code, label in ((STOP_APPROACH, "stop_approach"), (LANE_CHANGE, "lane_change")):
        win = onset_window(situation, episode, code)
        if win is None:
            continue
        path = Path(out_dir) / f"temporal_{name.replace('+', 'p')}_{label}.png"
        title = f"{name}: temporal attention, {label.replace('_', ' ')}"
        save_temporal_strip(path, weights[win], situation[win], t[win], title=title)
        out[f"strip_{label}"] = path.name
    return out
