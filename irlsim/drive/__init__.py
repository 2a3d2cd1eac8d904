"""Closed-loop driving with a learned reward in SUMO (``irlsim drive``): episodes, metrics, pictures.

The reward itself (loading a model, theta, values, the chosen policy) is :mod:`irlsim.reward`."""

from irlsim.drive.closed_loop import PictureSpec, drive_episode
from irlsim.drive.metrics import EPISODE_KEYS, episode_metrics, jerks, markdown_table, summarize

__all__ = [
    "PictureSpec",
    "drive_episode",
    "EPISODE_KEYS",
    "episode_metrics",
    "jerks",
    "markdown_table",
    "summarize",
]
