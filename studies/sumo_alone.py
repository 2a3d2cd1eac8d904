"""SUMO alone drives a study's recording: the trips, SUMO's own run and its FCD output (studies/styles.py's
recording, studies/style_rate.py's two step lengths)."""

from __future__ import annotations

import subprocess
from pathlib import Path
from typing import Any

from irlsim.road.network import sumo_binary


def sumo_alone(
    fcd: Path,
    road: Any,
    cars: int,
    seconds: float,
    seed: int,
    step: float | None = None,
    vtype: dict[str, str] | None = None,
) -> None:
    """SUMO alone drives ``cars`` trips of one lap of ``road`` (one every 4 s, SUMO's routing and default
    driver type, SUMO's ``seed``; ``step``: its step length, SUMO's default 1 s if None; ``vtype``: the
    cars' vType attributes instead of SUMO's default type) until ``seconds`` after the last departure, its
    FCD output written to ``fcd`` (whole or not at all), the trips beside it."""
    fcd.parent.mkdir(parents=True, exist_ok=True)
    first, last = road.edges[0], road.edges[-1]
    typed = ' type="driver"' if vtype else ""
    trips = "".join(
        f'<trip id="car{i}" depart="{4 * i}" from="{first}" to="{last}" departLane="best" departSpeed="max"'
        f"{typed}/>"
        for i in range(cars)
    )
    attrs = "".join(f' {k}="{v}"' for k, v in (vtype or {}).items())
    types = f'<vType id="driver"{attrs}/>' if vtype else ""
    routes = fcd.with_name(fcd.stem + ".rou.xml") if vtype else fcd.parent / "cars.rou.xml"
    routes.write_text(f"<routes>{types}{trips}</routes>\n")
    cmd = [sumo_binary("sumo"), "-n", str(road.net_file), "-r", str(routes)]
    cmd += ["--fcd-output", str(fcd.with_suffix(".tmp")), "--no-step-log", "true"]
    cmd += ["--seed", str(seed), "--end", str(4 * cars + seconds)]
    cmd += [] if step is None else ["--step-length", f"{step:g}"]
    print("$", " ".join(cmd), flush=True)
    subprocess.run(cmd, check=True)
    fcd.with_suffix(".tmp").rename(fcd)
