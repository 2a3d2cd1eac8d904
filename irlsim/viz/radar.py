"""Radar chart of a reward weight vector theta (15 named axes), as in the paper's supplementary video.

Scale (why logarithmic): the 15 weights multiply features of very different units and sizes, so a
predicted theta spans several decades; on a linear axis all but the two largest weights would sit at the
centre. Each axis therefore shows ``log10(|theta_i| / ref_i)``, clipped to ``decades`` = (low, high):

* with a ``reference`` theta (e.g. the expert's hand-tuned weights) the bold unit ring (0) is "same weight
  as the reference", the rings are x0.01, x0.1, x1, x10 of it;
* without one, ``ref_i = 1`` and the rings are the raw weights 1e-3 .. 1e1.

A weight of exactly 0 (or below ``10**low`` times the reference) sits at the centre. Negative weights
(a *reward* on a cost feature, possible for unconstrained networks) are plotted by magnitude and marked
with a red cross on their axis.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from irlsim import feature_names_of
from irlsim.viz.figure import new_figure, save_figure


def radar_radius(
    theta: np.ndarray, reference: np.ndarray | None = None, decades: tuple[float, float] = (-3.0, 1.0)
) -> np.ndarray:
    """Radius in [0, 1] of every axis: ``(clip(log10(|theta| / ref), low, high) - low) / (high - low)``.

    theta, reference: [F]; returns [F] float64.
    """
    theta = np.abs(np.asarray(theta, dtype=np.float64))
    ref = np.ones_like(theta) if reference is None else np.abs(np.asarray(reference, dtype=np.float64))
    assert theta.shape == ref.shape, f"theta {theta.shape} and reference {ref.shape} differ"
    low, high = decades
    ratio = theta / np.maximum(ref, 1e-300)
    logr = np.log10(np.maximum(ratio, 10.0 ** (low - 1)))
    return (np.clip(logr, low, high) - low) / (high - low)


def draw_radar(
    ax: Any,
    theta: np.ndarray,
    names: Sequence[str] | None = None,
    reference: np.ndarray | None = None,
    decades: tuple[float, float] = (-3.0, 1.0),
    title: str | None = None,
    color: str = "tab:blue",
    reference_label: str = "expert",
) -> None:
    """Draw theta [F] on a matplotlib *polar* axes ``ax`` (created with ``projection='polar'``)."""
    theta = np.asarray(theta, dtype=np.float64)
    names = feature_names_of(len(theta)) if names is None else names
    f = len(names)
    assert theta.shape == (f,), f"theta must be [{f}], got {theta.shape}"
    angles = np.linspace(0.0, 2 * np.pi, f, endpoint=False)
    r = radar_radius(theta, reference, decades)
    low, high = decades
    ax.set_theta_offset(np.pi / 2)
    ax.set_theta_direction(-1)
    ax.set_ylim(0.0, 1.0)
    ax.set_rlabel_position(180.0 / f)  # ring labels between the first two axes, clear of their names
    rings = np.arange(np.ceil(low), np.floor(high) + 1)
    ax.set_yticks((rings - low) / (high - low))
    if reference is None:
        ax.set_yticklabels([f"1e{int(k)}" for k in rings], fontsize=9)
    else:
        ax.set_yticklabels([f"x{10.0**k:g}" for k in rings], fontsize=9)
        ax.plot(
            np.append(angles, angles[0]),
            np.full(f + 1, (0.0 - low) / (high - low)),
            color="0.3",
            lw=1.2,
            ls="--",
            label=f"{reference_label} (x1)",
        )
    ax.set_xticks(angles)
    ax.set_xticklabels(list(names), fontsize=10)
    # names grow away from the circle (left-aligned on the right half, right-aligned on the left half),
    # so neighbours near the top and bottom do not run into each other
    side = np.sin(angles)  # clockwise from the top: > 0 on the right
    for label, sn in zip(ax.get_xticklabels(), side, strict=True):
        label.set_horizontalalignment("left" if sn > 0.05 else "right" if sn < -0.05 else "center")
    ax.plot(np.append(angles, angles[0]), np.append(r, r[0]), color=color, lw=1.5)
    ax.fill(np.append(angles, angles[0]), np.append(r, r[0]), color=color, alpha=0.25)
    neg = theta < 0
    if neg.any():
        ax.plot(angles[neg], r[neg], "x", color="tab:red", ms=6, label="negative weight")
    if title:
        ax.set_title(title, fontsize=12, pad=18)
    if reference is not None or neg.any():
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=2, fontsize=9, frameon=False)


def save_radar(
    path: str | Path,
    theta: np.ndarray,
    names: Sequence[str] | None = None,
    reference: np.ndarray | None = None,
    title: str | None = None,
    decades: tuple[float, float] = (-3.0, 1.0),
    dpi: int = 100,
) -> Path:
    """Write a radar chart PNG (5 x 5 in at ``dpi``) atomically; returns the path."""
    fig = new_figure((5.0, 5.0))
    ax = fig.add_subplot(111, projection="polar")
    draw_radar(ax, theta, names, reference, decades, title)
    fig.tight_layout()
    return save_figure(fig, path, dpi)
