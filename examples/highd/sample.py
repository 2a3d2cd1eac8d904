"""Make a recording in highD's layout without the dataset: SUMO's own run on a road of highD's shape,
written as highD's recording 01, to try ``irlsim scenario from-highd`` on.

    python examples/highd/sample.py --out data/highd-sample

The road is built here from the lane markings (two carriageways of three 3.8 m lanes, 420 m, netconvert);
SUMO (the eclipse-sumo wheel's binary) drives 12 vehicles on each, every third a 12 m truck (entering in
the right lane, the cars in every lane), at 25 Hz, and its FCD output is written in highD's conventions:
the upper left corner of each vehicle's box in the image's frame (x to the right, y down), the box's
extent along x as ``width`` and along y as ``height``, ``xVelocity`` and ``yVelocity``, frames from 1,
``class`` Car or Truck, ``drivingDirection`` 1 (upper, to the left) or 2 (lower, to the right), and the
markings' image y in ``01_recordingMeta.csv``.
"""

from __future__ import annotations

import argparse
import subprocess
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv

from irlsim.data.recording_read import read_rows
from irlsim.road.network import sumo_binary

UPPER, LOWER = (8.0, 11.8, 15.6, 19.4), (21.6, 25.4, 29.2, 33.0)  # image y of the lane markings [m]
SIZE = {"car": (4.6, 1.9), "truck": (12.0, 2.5)}  # length, width [m]
HZ = 25


def sumo_run(tmp: Path, vehicles: int = 12, every: float = 2.0) -> tuple[Path, Path]:
    """A network of highD's layout, built here from the markings (not by the importer), and SUMO's FCD of
    ``vehicles`` cars and trucks on each carriageway, one every ``every`` seconds, at 25 Hz."""
    mid = {"lower": -(LOWER[0] + LOWER[-1]) / 2, "upper": -(UPPER[0] + UPPER[-1]) / 2}
    (tmp / "n.nod.xml").write_text(
        f'<nodes><node id="l0" x="0" y="{mid["lower"]}"/><node id="l1" x="420" y="{mid["lower"]}"/>'
        f'<node id="u0" x="420" y="{mid["upper"]}"/><node id="u1" x="0" y="{mid["upper"]}"/></nodes>'
    )
    edge = 'numLanes="3" width="3.8" spreadType="center" speed="36"'
    (tmp / "n.edg.xml").write_text(
        f'<edges><edge id="lower" from="l0" to="l1" {edge}/>'
        f'<edge id="upper" from="u0" to="u1" {edge}/></edges>'
    )
    net = tmp / "road.net.xml"
    cmd = [sumo_binary("netconvert"), "-n", str(tmp / "n.nod.xml"), "-e", str(tmp / "n.edg.xml")]
    subprocess.run([*cmd, "-o", str(net), "--offset.disable-normalization"], check=True, capture_output=True)
    types = "".join(f'<vType id="{k}" vClass="{"passenger" if k == "car" else "truck"}" length="{le}" '
                    f'width="{w}" sigma="0" lcSpeedGain="5"/>' for k, (le, w) in SIZE.items())  # fmt: skip
    trips = "".join(
        f'<vehicle id="{side}{i}" type="{"truck" if i % 3 == 2 else "car"}" depart="{every * i}" '
        f'departLane="{0 if i % 3 == 2 else (i + i // 3) % 3}" departSpeed="{18 + 2 * (i % 5)}">'
        f'<route edges="{side}"/></vehicle>'
        for i in range(vehicles)
        for side in ("lower", "upper")
    )
    (tmp / "r.rou.xml").write_text(f"<routes>{types}{trips}</routes>")
    fcd = tmp / "fcd.xml"
    cmd = [sumo_binary("sumo"), "-n", str(net), "-r", str(tmp / "r.rou.xml"), "--step-length", str(1 / HZ)]
    cmd += [
        "--end",
        str(every * vehicles + 40),
        "--fcd-output",
        str(fcd),
        "--no-step-log",
        "true",
        "--precision",
        "6",
    ]
    subprocess.run(cmd, check=True, capture_output=True)
    return net, fcd


def as_highd(fcd: Path, folder: Path) -> dict[str, int]:
    """SUMO's FCD written as highD's recording 01: its boxes' upper left corners in the image's frame,
    velocities, classes, driving directions and the lane markings. Returns SUMO id -> highD id."""
    r = read_rows(fcd)
    ids = {v: i + 1 for i, v in enumerate(dict.fromkeys(r.id.tolist()))}
    kind = np.array([kind_of(v) for v in r.id])
    length = np.array([SIZE[k][0] for k in kind])
    width = np.array([SIZE[k][1] for k in kind])
    cx, cy = r.x - length / 2 * np.cos(r.heading), r.y - length / 2 * np.sin(r.heading)
    track = {"frame": np.rint(r.t * HZ).astype(int) + 1, "id": [ids[v] for v in r.id]}
    track |= {"x": cx - length / 2, "y": -cy - width / 2, "width": length, "height": width}
    track |= {"xVelocity": r.v * np.cos(r.heading), "yVelocity": -r.v * np.sin(r.heading)}
    track["laneId"] = np.zeros(len(r.id), dtype=int)  # highD's own lane numbering: not read
    pacsv.write_csv(pa.table(track), folder / "01_tracks.csv")
    first = {v: i for i, v in reversed(list(enumerate(r.id)))}
    meta = {"id": list(ids.values()), "width": [SIZE[kind[first[v]]][0] for v in ids]}
    meta |= {"class": [kind[first[v]].title() for v in ids]}
    meta["drivingDirection"] = [1 if v.startswith("upper") else 2 for v in ids]
    pacsv.write_csv(pa.table(meta), folder / "01_tracksMeta.csv")
    rec = {"id": [1], "frameRate": [HZ], "locationId": [1], "speedLimit": [-1.0]}
    rec |= {
        "upperLaneMarkings": [";".join(map(str, UPPER))],
        "lowerLaneMarkings": [";".join(map(str, LOWER))],
    }
    pacsv.write_csv(pa.table(rec), folder / "01_recordingMeta.csv")
    return ids


def kind_of(sumo_id: str) -> str:
    """A vehicle's highD class (lower case) by its SUMO id: every third of a carriageway is a truck."""
    return "truck" if int(sumo_id.lstrip("lowerup")) % 3 == 2 else "car"


if __name__ == "__main__":
    p = argparse.ArgumentParser(description="SUMO's run on a road of highD's shape, as highD's recording 01")
    p.add_argument("--out", type=Path, default=Path("data/highd-sample"), help="the folder written")
    p.add_argument("--vehicles", type=int, default=12, help="vehicles per carriageway (default: 12)")
    p.add_argument("--every", type=float, default=2.0, help="[s] one departs every (default: 2)")
    args = p.parse_args()
    (args.out / "sumo").mkdir(parents=True, exist_ok=True)
    as_highd(
        sumo_run(args.out / "sumo", args.vehicles, args.every)[1], args.out
    )  # SUMO's network and FCD in <out>/sumo
    print(f"wrote {args.out}/01_tracks.csv, 01_tracksMeta.csv, 01_recordingMeta.csv")
