"""Generated SUMO networks for sweeps (``irlsim scenario generate``): grids, spiders and random networks of
1-4 lanes, 30-130 km/h, traffic lights or priority junctions, with or without left-turn lanes, then
sidewalks and bike lanes guessed by netconvert.

Network ``i`` of seed ``S`` is drawn from ``numpy.random.default_rng([S, i])`` alone: the same ``(S, i)``
gives the same parameters and, as netgenerate and netconvert are deterministic for a given ``--seed``
and their time-stamped header is removed, the same bytes. Left-turn lanes come from netgenerate's
``--turn-lanes`` (netconvert has no option that guesses them on a network); sidewalks and bike lanes
from netconvert's ``--sidewalks.guess`` (roads up to 50 km/h by its default) and ``--bikelanes.guess``
(up to 80 km/h), pedestrian crossings from ``--crossings.guess``.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from irlsim.road.network import build_net, is_stale

KINDS = ("grid", "spider", "random")
KIND_FLAGS = {"grid": "--grid", "spider": "--spider", "random": "--rand"}
JUNCTIONS = ("traffic_light", "priority", "priority+tls.guess")
#: netconvert's pass over a generated network: sidewalks, bike lanes and crossings guessed
GUESS_OPTIONS = ("--sidewalks.guess", "--bikelanes.guess", "--crossings.guess", "--no-warnings")


@dataclass(frozen=True)
class NetworkParams:
    """What network ``index`` is: drawn by :func:`network_params`, recorded in the manifest."""

    index: int
    kind: str  # grid, spider or random
    lanes: int  # lanes per direction (at most, with random_lanes)
    random_lanes: bool  # netgenerate draws each edge's lane count from 1..lanes
    speed_kmh: int  # [km/h] every road's limit
    junctions: str  # one of JUNCTIONS
    turn_lanes: int  # left-turn lanes added before junctions (0 or 1)
    seed: int  # netgenerate's --seed
    shape: tuple[str, ...]  # the kind's own netgenerate options

    @property
    def file_name(self) -> str:
        return f"{self.index:04d}_{self.kind}.net.xml"

    def netgenerate_args(self) -> list[str]:
        junction, _, guess = self.junctions.partition("+")
        args = [
            KIND_FLAGS[self.kind],
            *self.shape,
            "-L",
            str(self.lanes),
            "-S",
            f"{self.speed_kmh / 3.6:.3f}",
        ]
        args += ["-j", junction, "--seed", str(self.seed), "--no-turnarounds", "true", "--no-warnings"]
        if guess:
            args.append("--tls.guess")
        if self.random_lanes:
            args.append("--random-lanenumber")
        if self.turn_lanes:
            args += ["--turn-lanes", str(self.turn_lanes), "--turn-lanes.length", "40"]
        return args


def network_params(seed: int, index: int) -> NetworkParams:
    """The parameters of network ``index`` of ``seed`` (the kinds take turns: grid, spider, random)."""
    rng = np.random.default_rng([seed, index])
    kind = KINDS[index % len(KINDS)]
    lanes = int(rng.integers(1, 5))
    random_lanes = bool(lanes > 1 and rng.random() < 0.3)
    speed = int(rng.integers(30, 131))
    junctions = JUNCTIONS[int(rng.integers(len(JUNCTIONS)))]
    turn_lanes = int(rng.integers(0, 2))
    shape: tuple[str, ...]
    if kind == "grid":
        shape = (
            f"--grid.x-number={int(rng.integers(2, 6))}",
            f"--grid.y-number={int(rng.integers(2, 6))}",
            f"--grid.length={int(rng.integers(15, 41)) * 10}",
            f"--grid.attach-length={int(rng.integers(0, 21)) * 10}",
        )
    elif kind == "spider":
        shape = (
            f"--spider.arm-number={int(rng.integers(3, 8))}",
            f"--spider.circle-number={int(rng.integers(2, 5))}",
            f"--spider.space-radius={int(rng.integers(12, 26)) * 10}",
        )
    else:
        shape = (
            f"--rand.iterations={int(rng.integers(20, 61))}",
            "--rand.min-distance=150",
            "--rand.max-distance=400",
        )
    return NetworkParams(
        index, kind, lanes, random_lanes, speed, junctions, turn_lanes, int(rng.integers(1, 2**31 - 1)), shape
    )


def build_network(params: NetworkParams, out_dir: Path) -> Path:
    """netgenerate, then netconvert's guesses, into ``out_dir / params.file_name`` unless it is there
    (drawn from the seed, it has no source it could be older than); one line when a tool fails."""
    target = out_dir / params.file_name
    if not is_stale(target, ()):
        return target
    subject = f"generated network {params.index} ({params.kind}, seed {params.seed})"
    fix = "report it with the command's --seed"
    with tempfile.TemporaryDirectory(dir=out_dir, prefix=".generate.") as tmp_dir:
        raw = Path(tmp_dir) / "raw.net.xml"
        build_net("netgenerate", params.netgenerate_args(), raw, subject=subject, fix=fix, force=True)
        guesses = ["-s", str(raw), *GUESS_OPTIONS]
        return build_net("netconvert", guesses, target, subject=subject, fix=fix, force=True)
