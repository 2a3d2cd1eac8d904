"""Building the default scenario's SUMO network (``irlsim net``: the oval's) and describing it."""

from __future__ import annotations

from pathlib import Path

from irlsim.road import load_road
from irlsim.road.scenario import load_scenario


def build_network(force: bool = False) -> Path:
    """Build the default scenario's network (``sumo_net/oval/oval.net.xml``) if stale (or ``force``),
    print its description; returns its path."""
    scn = load_scenario(force=force)
    path = scn.net_file
    road = load_road(scenario=scn, build=False)  # its network just built; the file not read again
    print(f"network: {path}")
    for key, value in road.describe().items():
        print(f"  {key}: {value}")
    return path
