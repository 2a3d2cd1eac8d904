"""Make examples/mydriver/recording.csv: a small recording of a driver, in the columnar format.

    python examples/mydriver/record.py [--out examples/mydriver/recording.csv]

SUMO (the eclipse-sumo wheel's binary) drives six cars of one cautious driver type (IDM, 2 s time
headway, at most 50 km/h) round the oval for 60 s behind each other, and records them (--fcd-output);
the rows become the columnar format without the optional lane column, so irlsim matches each car's route
from its positions. Your own recording replaces this file: one row per vehicle and time, the columns id,
t [s], x, y [m, the network's coordinates], v [m/s], heading [rad, counter-clockwise from east].
"""

from __future__ import annotations

import argparse
import csv
import math
import subprocess
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

from irlsim.road import load_road
from irlsim.road.network import sumo_binary

p = argparse.ArgumentParser(description="a small recording of one driver type on the oval, as CSV")
p.add_argument("--out", default="examples/mydriver/recording.csv", help="the CSV written")
args = p.parse_args()

road = load_road(scenario="oval")
cars = "".join(
    f'<vehicle id="car{i}" type="driver" route="loop" depart="0" departLane="{i % 3}" '
    f'departPos="{40 * i}" departSpeed="max"/>'
    for i in range(6)
)
routes = (
    '<routes><vType id="driver" carFollowModel="IDM" tau="2.0" accel="1.5" decel="3.0" sigma="0" '
    f'maxSpeed="13.9"/><route id="loop" edges="{" ".join(road.edges * 2)}"/>{cars}</routes>'
)
with tempfile.TemporaryDirectory() as tmp:
    (Path(tmp) / "cars.rou.xml").write_text(routes)
    fcd = Path(tmp) / "fcd.xml"
    cmd = [sumo_binary("sumo"), "-n", str(road.net_file), "-r", str(Path(tmp) / "cars.rou.xml")]
    cmd += ["--end", "60", "--step-length", "0.5", "--fcd-output", str(fcd), "--no-step-log", "true"]
    subprocess.run([*cmd, "--seed", "1"], check=True, capture_output=True)
    rows = [
        (v.get("id"), float(ts.get("time")), *(float(v.get(k)) for k in ("x", "y", "speed", "angle")))
        for ts in ET.parse(fcd).getroot().iter("timestep")
        for v in ts.iter("vehicle")
    ]
with open(args.out, "w", newline="") as f:
    w = csv.writer(f)
    w.writerow(["id", "t", "x", "y", "v", "heading"])
    for vid, t, x, y, v, angle in rows:  # SUMO's angle: degrees from north, clockwise
        heading = math.remainder(math.radians(90.0 - angle), 2 * math.pi)
        w.writerow([vid, f"{t:g}", f"{x:.2f}", f"{y:.2f}", f"{v:.2f}", f"{heading:.4f}"])
print(f"wrote {args.out}: {len(rows)} rows of {len({r[0] for r in rows})} vehicles")
