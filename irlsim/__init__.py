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

#: environment variables that size numpy's / torch's CPU thread pools; set to 1 for single-threaded
#: processes (``irlsim bench``, collection workers: see :mod:`irlsim.executor`). Read once, when
#: the libraries load, so they must be set before numpy / torch are imported.
THREAD_VARS: tuple[str, ...] = (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "NUMEXPR_NUM_THREADS",
)
