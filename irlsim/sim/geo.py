"""Geographic positions (longitude, latitude) placed on a network by SUMO itself.

A network imported from OpenStreetMap (or built with a projection) keeps its projection in its
``<location projParameter=...>``: SUMO maps longitude and latitude onto the network's x, y with it
(``sumo --fcd-output.geo`` writes positions the other way). irlsim asks SUMO for the mapping (libsumo's
``simulation.convertGeo``, in a process of its own so that the command's own simulation is untouched)
rather than re-implementing map projections: the positions land where SUMO itself puts them.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from irlsim.errors import IrlsimError
from irlsim.sim.libsumo_process import run_libsumo

#: [s] at most this long for SUMO to load the network and map the points
CONVERT_TIMEOUT_S = 300.0

_CONVERT = """
import sys, numpy as np, libsumo
net, where = sys.argv[1], sys.argv[2]
libsumo.start(["sumo", "-n", net, "--begin", "0", "--end", "0", "--no-step-log", "true", "--no-warnings",
               "true", "--xml-validation", "never"])
lonlat = np.load(where + "/lonlat.npy")
convert = libsumo.simulation.convertGeo
xy = np.array([convert(lon, lat, True) for lon, lat in lonlat.tolist()], dtype=np.float64).reshape(-1, 2)
np.save(where + "/xy.npy", xy)
libsumo.close()
"""


def geo_to_network(net_file: str | Path, lon: np.ndarray, lat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The network's x, y [m] of the points ``lon``, ``lat`` [degrees], mapped by SUMO through the
    projection of ``net_file``'s location (SUMO's error as one line). Each distinct point is mapped once
    (a recording's standing cars repeat theirs); about a microsecond a point."""
    pts = np.stack([np.asarray(lon, dtype=np.float64), np.asarray(lat, dtype=np.float64)], axis=1)
    distinct, back = np.unique(pts, axis=0, return_inverse=True)
    with tempfile.TemporaryDirectory(prefix="irlsim-geo-") as tmp:
        np.save(Path(tmp) / "lonlat.npy", distinct)
        task = f"place {len(distinct)} geographic points on {net_file}"
        res, errors = run_libsumo(_CONVERT, [str(net_file), tmp], CONVERT_TIMEOUT_S, task)
        done = Path(tmp) / "xy.npy"
        if res.returncode != 0 or not done.is_file():
            why = errors[0] if errors else (res.stderr.strip().splitlines() or [f"exit {res.returncode}"])[-1]
            raise IrlsimError(f"SUMO could not place geographic points on {net_file}: {why}")
        xy = np.load(done)
    return xy[back.reshape(-1), 0], xy[back.reshape(-1), 1]
