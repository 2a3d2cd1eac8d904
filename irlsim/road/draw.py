"""Random car routes on any SUMO network, for the sweep over many networks (``irlsim scenario sweep``).

Route ``k`` of a network is drawn from ``numpy.random.default_rng([seed, k])`` alone, so it is the same
whatever the other routes drew: a pair of different edges that admit passenger cars, joined by SUMO's
shortest path for a passenger car (``sumolib``'s Dijkstra), kept when that path is at least
``min_length`` long and turns round nowhere (no edge followed by its reverse: a U-turn is no route a
driver would be given); up to :data:`DRAW_TRIES` pairs are tried. What the route then says on the network
(lanes, widths, junctions) is the road layer's to judge when the scenario is loaded.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from irlsim.errors import IrlsimError
from irlsim.road.geometry import MIN_OPEN_LENGTH

#: [m] a drawn route is at least as long as the shortest route the road accepts (room for a start): a
#: longer minimum left the small networks (SUMO's Ingolstadt extract, its 'hiking' crossing of 173 m at
#: most) without routes in 100 draws
MIN_ROUTE_LENGTH = MIN_OPEN_LENGTH
#: pairs of edges tried per route before it is given up as 'no-path'
DRAW_TRIES = 100


@dataclass(frozen=True)
class DrawnRoute:
    """Route ``index`` of a network: its edges and length, or why none was found (a one-line refusal)."""

    index: int
    edges: tuple[str, ...]
    length: float  # [m] sum of the edges' lengths (0 when refused)
    refusal: str = ""


def read_network(net_file: Path) -> Any:
    """The sumolib network without its junction lanes (enough for edges and paths); one line when it
    cannot be read."""
    import sumolib  # lazy: sumolib parses XML with its own machinery, only needed here

    try:
        return sumolib.net.readNet(str(net_file))
    except Exception as e:  # sumolib raises bare SAX / attribute errors on malformed XML
        raise IrlsimError(
            f"network {net_file} is malformed ({type(e).__name__}): choose a SUMO network"
        ) from None


def car_edges(net: Any) -> list[Any]:
    """The network's edges (no junction lanes) with a lane that admits passenger cars, by id."""
    edges = [e for e in net.getEdges(withInternal=False) if e.allows("passenger")]
    return sorted(edges, key=lambda e: e.getID())


def draw_routes(net: Any, n: int, seed: int, min_length: float = MIN_ROUTE_LENGTH) -> list[DrawnRoute]:
    """``n`` routes on ``net`` (see the module docstring); a route no pair yields is a refusal."""
    edges = car_edges(net)
    out = []
    for k in range(n):
        if len(edges) < 2:
            out.append(
                DrawnRoute(k, (), 0.0, "network: it has fewer than two edges that admit passenger cars")
            )
            continue
        out.append(_draw_one(net, edges, k, seed, min_length))
    return out


def _draw_one(net: Any, edges: list[Any], k: int, seed: int, min_length: float) -> DrawnRoute:
    rng = np.random.default_rng([seed, k])
    longest = 0.0  # [m] of the paths found, when none was long enough
    for _ in range(DRAW_TRIES):
        i, j = rng.choice(len(edges), size=2, replace=False)
        path, _cost = net.getShortestPath(edges[i], edges[j], vClass="passenger")
        if path is None or _turns_round(path):
            continue
        length = float(sum(e.getLength() for e in path))
        if length >= min_length:
            return DrawnRoute(k, tuple(e.getID() for e in path), round(length, 1))
        longest = max(longest, length)
    if longest > 0:  # pairs connect, but every route is short: a network too small to drive
        why = (
            f"route: every car route of {DRAW_TRIES} draws is shorter than the {min_length:.0f} m an "
            f"episode needs (the longest {longest:.0f} m): a network too small to drive"
        )
    else:
        why = (
            f"route: no pair of car edges joined by a path of at least {min_length:.0f} m in "
            f"{DRAW_TRIES} draws"
        )
    return DrawnRoute(k, (), 0.0, why)


def _turns_round(path: list[Any]) -> bool:
    """True when an edge of ``path`` is followed by its reverse (a U-turn)."""
    return any(
        b.getFromNode() is a.getToNode() and b.getToNode() is a.getFromNode()
        for a, b in zip(path, path[1:], strict=False)
    )
