"""Road geometry and topology of a route on a SUMO network (route frame, lanes, checkpoints, stop lines,
signals, yield points, exits), and the scenario files that name them."""

from irlsim.road.geometry import (
    HALF_ROAD,
    LANE_WIDTH,
    N_LANES,
    Checkpoint,
    Exit,
    LaneCentreline,
    Road,
    Signal,
    StopLine,
    YieldPoint,
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
    "Signal",
    "StopLine",
    "YieldPoint",
    "load_road",
    "wrap_angle",
    "yaw_to_sumo_angle",
]
