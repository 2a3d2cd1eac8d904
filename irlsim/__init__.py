"""irlsim: path-integral maximum-entropy deep IRL with policy and temporal attention on SUMO roads.

Implements Rosbach et al., "Planning on the fast lane", IROS 2020. Packages are split by noun:
``road`` (geometry), ``sim`` (SUMO), ``planner`` (sampling + features + expert), ``data`` (Parquet),
``irl`` (losses, metrics), ``models`` (networks), ``train``, ``reward`` (a trained model's reward:
``irlsim.reward.load_reward``), ``drive`` (closed loop), ``viz`` (pictures), ``workflows`` (each command's
work as a function with a typed request), ``bench``. The command line's argument parsing lives in
``pipelines``.
"""

__version__ = "0.1.0"

FEATURE_NAMES: tuple[str, ...] = (
    "acc_lon",
    "jerk_lon",
    "acc_lat",
    "jerk_lat",
    "velocity",
    "creep",
    "end_heading",
    "centerline",
    "road_edge",
    "mission_lane",
    "progress",
    "stop_line",
    "lc_delay",
    "lat_overshoot",
    "proximity",
)
N_FEATURES = len(FEATURE_NAMES)
#: the lane-preference pair (``planner.feature_set = "lanes"``): the lanes to the ego's right and to its
#: left, each a cost, so that positive weights can prefer either side (the paper's 15 price no lane)
LANE_FEATURE_NAMES: tuple[str, ...] = ("lane_right", "lane_left")
#: the feature sets a planner can compute, by name; "paper" (the 15) is the default everywhere
FEATURE_SETS: dict[str, tuple[str, ...]] = {
    "paper": FEATURE_NAMES,
    "lanes": FEATURE_NAMES + LANE_FEATURE_NAMES,
}


def feature_names_of(n: int, default: tuple[str, ...] | None = None) -> tuple[str, ...]:
    """The names of the feature set with ``n`` features (the sets differ in size); ``default`` if none,
    ValueError if none and no default."""
    for names in FEATURE_SETS.values():
        if len(names) == n:
            return names
    if default is not None:
        return default
    raise ValueError(f"no feature set has {n} features (irlsim.FEATURE_SETS)")


def feature_set_of(names: object) -> str | None:
    """The name of the feature set (``FEATURE_SETS``) whose features are ``names``, in that order; None
    if none (a list of other names, another order, or not a list at all, as a damaged manifest may hold)."""
    if not isinstance(names, (list, tuple)):
        return None
    return next((key for key, value in FEATURE_SETS.items() if list(value) == list(names)), None)


#: environment variables that size numpy's / torch's CPU thread pools; set to 1 for single-threaded
#: processes (``irlsim bench``, collection workers: see :mod:`irlsim.executor`). Read once, when
#: the libraries load, so they must be set before numpy / torch are imported.
THREAD_VARS: tuple[str, ...] = (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "NUMEXPR_NUM_THREADS",
)
