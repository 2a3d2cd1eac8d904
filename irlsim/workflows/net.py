"""Building the oval's SUMO network (``irlsim net``) and describing it."""

from __future__ import annotations

from pathlib import Path

from irlsim.road import load_road
from irlsim.road.network import build_net


def build_network(force: bool = False) -> Path:
    """Build ``sumo_net/oval.net.xml`` if stale (or ``force``), print its description; returns its path."""
    path = build_net(force=force)
    road = load_road(path)
    print(f"network: {path}")
    for key, value in road.describe().items():
        print(f"  {key}: {value}")
    return path
