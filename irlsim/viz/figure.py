"""Figure plumbing shared by every picture: an Agg-canvas Figure (no pyplot, no display), atomic PNGs,
axes placed in inches. matplotlib is imported inside the functions: it costs about a second at start-up
and most commands draw nothing."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from irlsim.utils import atomic_path


def new_figure(size: tuple[float, float]) -> Any:
    """A matplotlib Figure on an Agg canvas (no pyplot, no display)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=size)
    FigureCanvasAgg(fig)
    return fig


def save_figure(fig: Any, path: str | Path, dpi: int = 100) -> Path:
    """Save ``fig`` as PNG atomically (temporary file beside ``path``, then rename)."""
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi, format="png")
        os.chmod(tmp, 0o644)  # mkstemp makes it private; pictures are for everyone
    return path


def axes_in(fig: Any, left: float, bottom: float, width: float, height: float, **kw: Any) -> Any:
    """Axes placed in inches from the figure's lower left corner (exact, unlike tight_layout with an
    equal-aspect axes)."""
    fw, fh = fig.get_size_inches()
    return fig.add_axes((left / fw, bottom / fh, width / fw, height / fh), **kw)
