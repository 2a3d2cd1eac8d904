"""Closed-loop driving with a learned reward in SUMO (``irlsim drive``): episodes, metrics, pictures."""

from irlsim.drive.closed_loop import DriveModel, PictureSpec, drive_episode, load_drive_model, model_names
from irlsim.drive.metrics import EPISODE_KEYS, episode_metrics, jerks, markdown_table, summarize

__all__ = [
    "DriveModel",
    "PictureSpec",
    "drive_episode",
    "load_drive_model",
    "model_names",
    "EPISODE_KEYS",
    "episode_metrics",
    "jerks",
    "markdown_table",
    "summarize",
]
