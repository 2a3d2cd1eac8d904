"""Road geometry and topology of the oval course (route frame, lanes, checkpoints, stop lines, exits)."""

from irlsim.road.geometry import (
    HALF_ROAD,
    LANE_WIDTH,
    N_LANES,
    Checkpoint,
    Exit,
    LaneCentreline,
    Road,
    StopLine,
    load_road,
    wrap_angle,
    yaw_to_sumo_angle,
)

__all__ = [
    "HALF_ROAD",
    "LANE_WIDTH",
    "N_LANES",
    "Checkpoint",
    "Exit",
    "LaneCentreline",
    "Road",
    "StopLine",
    "load_road",
    "wrap_angle",
    "yaw_to_sumo_angle",
]
