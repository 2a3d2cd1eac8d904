r"""A dataset's tracks, learned: a recording as public datasets give it, read, learned and driven.

SUMO alone (the wheel's binary) drives the motorway scenario at 25 Hz with its own drivers (cars, and
every fifth vehicle a truck of SUMO's class ``truck``), and its trajectories are written as a dataset of
tracks gives them: numeric ids, the centre of each vehicle's box, no heading, each vehicle's length,
width and type in columns, a tracker's position noise. irlsim reads it with ``position = "centre"`` and the
types' file (``vehicle_types``: the trucks are no egos and replay at their size), learns PACNN+S from the
first cars (20 training, 1 validation, 1 test egos), and drives the learned rewards and the expert where the
next 20 cars drove (the other vehicles driven by SUMO from their recorded states, ``--reactive``), with the
recording rows' rules of the style study; the table compares each driving with the held-out cars' own
recorded driving and the expert's (``studies/styles.py``'s distance and bounds). About 8 minutes:

    .venv/bin/python studies/recording_dataset.py --out runs/recording-dataset --sumo-seed 21 --workers 2

``--trips`` and ``--learned`` give a longer recording and more egos to learn from (``--drive-seed``: the
drives' first episode seed); ``--lc-duration`` has SUMO's lane changes
take that long; ``--choice expected`` drives the rewards with the decision their distribution expects
(the lane-change bias calibrated on the training data, as ``studies/style_choice.py``). Writes
``<out>/table[-choice].md`` and ``.json``.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv

sys.path.insert(0, str(Path(__file__).parent))
import styles  # noqa: E402  (studies/styles.py: collect, drive, the table)

from irlsim.data.recorded import egos, open_recording  # noqa: E402
from irlsim.data.recording_as import ReadAs  # noqa: E402
from irlsim.data.recording_read import read_rows  # noqa: E402
from irlsim.reward import load_reward  # noqa: E402
from irlsim.reward.choice import lane_change_bias  # noqa: E402
from irlsim.road import load_road  # noqa: E402
from irlsim.road.network import sumo_binary  # noqa: E402
from irlsim.rollout.style import pool_styles  # noqa: E402

ROAD = "motorway"
#: the recorded types: SUMO's drivers (Krauss, sigma 0.5), a car and a truck of class truck
TYPES = """<additional>
    <vType id="car" length="4.6" width="1.9" sigma="0.5"/>
    <vType id="truck" vClass="truck" length="12.0" width="2.5" sigma="0.5" maxSpeed="25"/>
</additional>
"""
TRIPS, EVERY_S, TRUCK_EVERY, HZ = 70, 2.5, 5, 25
LEARNED, DRIVEN = 22, 20  # egos learned from (20 train, 1 validation, 1 test), then the egos driven
V_MAX = 40.0  # [m/s] the planner's top speed: the drivers' 99th percentile was 36 m/s on a trial run
RULES = ["--full-stop", "--keep-distance", "0.3", "--in-lane"]  # the style study's recording rows' rules


def record(folder: Path, seed: int, noise: float, lc_duration: float = 0.0, n_trips: int = TRIPS) -> Path:
    """SUMO alone on the motorway at ``HZ`` (``lc_duration``: SUMO's ``--lanechange.duration``, 0 its
    default, a lane change within one step); its trajectories as a dataset's tracks (``tracks.csv``)."""
    folder.mkdir(parents=True, exist_ok=True)
    tracks = folder / "tracks.csv"
    if tracks.is_file():
        return tracks
    road = load_road(scenario=ROAD)
    (folder / "types.add.xml").write_text(TYPES)
    trips = "".join(
        f'<trip id="{i}" type="{"truck" if i % TRUCK_EVERY == TRUCK_EVERY - 1 else "car"}" '
        f'depart="{EVERY_S * i}" from="{road.edges[0]}" to="{road.edges[-1]}" departLane="random" '
        'departSpeed="max"/>'
        for i in range(n_trips)
    )
    (folder / "trips.rou.xml").write_text(f"<routes>{trips}</routes>\n")
    fcd = folder / "sumo.fcd.parquet"  # SUMO's own table format
    cmd = [sumo_binary("sumo"), "-n", str(road.net_file), "-a", str(folder / "types.add.xml")]
    cmd += ["-r", str(folder / "trips.rou.xml"), "--step-length", str(1.0 / HZ), "--seed", str(seed)]
    cmd += ["--end", str(n_trips * EVERY_S + 300), "--fcd-output", str(fcd), "--no-step-log", "true"]
    cmd += ["--lanechange.duration", str(lc_duration)] if lc_duration else []
    subprocess.run(cmd, check=True, capture_output=True)
    r = read_rows(fcd)
    assert r.vtype is not None
    length = np.where(r.vtype == "truck", 12.0, 4.6)
    rng = np.random.default_rng(0)
    x = r.x - 0.5 * length * np.cos(r.heading) + rng.normal(0.0, noise, len(r.x))
    y = r.y - 0.5 * length * np.sin(r.heading) + rng.normal(0.0, noise, len(r.x))
    cols = {"id": r.id.astype(str), "t": r.t, "x": x, "y": y, "v": r.v, "length": length}
    cols |= {"width": np.where(length > 10, 2.5, 1.9), "type": r.vtype.astype(str)}
    pacsv.write_csv(pa.table(cols), tracks)
    return tracks


def configs(folder: Path, tracks: Path, n_learned: int = LEARNED) -> tuple[str, str, str]:
    """(collect, drive, reference) configs: the first ``n_learned`` egos learned, the next ``DRIVEN``."""
    read = ReadAs("centre", (str(folder / "types.add.xml"),))
    road = load_road(scenario=ROAD)
    eligible = egos(open_recording(tracks, road, 0.1, read), road, (), 20.0)
    learned, driven = eligible[:n_learned], eligible[n_learned : n_learned + DRIVEN]
    if len(driven) < DRIVEN:
        sys.exit(
            f"recording_dataset: {len(eligible)} egos, {n_learned} learned: too few left to drive {DRIVEN}"
        )
    common = f'seed = 0\n\n[scenario]\nname = "{ROAD}"\n\n[planner]\nn_policies = 500\nv_max = {V_MAX}\n'
    rec = (
        f'\n[demonstrator]\nkind = "recording"\nfile = "{tracks}"\nposition = "centre"\n'
        f'vehicle_types = ["{folder / "types.add.xml"}"]\nmin_duration = 20.0\n'
    )
    out = []
    for name, ids, splits in (
        (
            "collect",
            learned,
            f"train_episodes = {n_learned - 2}\nvalidation_episodes = 1\ntest_episodes = 1\n",
        ),
        ("drive", driven, ""),
        ("reference", driven, f"train_episodes = {DRIVEN}\nvalidation_episodes = 0\ntest_episodes = 0\n"),
    ):
        path = folder / f"{name}.toml"
        path.write_text(f'{splits}max_cycles = 800\n{common}{rec}ego = "{",".join(ids)}"\n')
        out.append(str(path))
    return out[0], out[1], out[2]


def drive(config: str, runs: Path | None, models: list[str], out: Path, a: Any) -> Path:
    """``irlsim drive --reactive`` on the driven egos (the learned rewards with ``RULES``, and with
    ``--choice expected`` the decision their distribution expects, the lane-change bias calibrated on the
    training data as ``studies/style_choice.py`` does)."""
    if not set(models) <= styles.driven_models(out / "drive.json"):
        choice = []
        if runs and a.choice == "expected":
            bias = lane_change_bias(load_reward(models[0], runs=str(runs)), [a.data])
            print(f"{runs.name}: {models[0]}'s lane-change bias {bias:.3f}", flush=True)
            choice = ["--choice", "expected", "--lane-change-bias", repr(bias)]
        styles.run(
            [styles.irlsim(), "drive", *(["--runs", str(runs)] if runs else []), "--model", ",".join(models)]
            + ["--reactive", *(RULES + choice if runs else []), "--episodes", str(DRIVEN), "--config", config]
            + ["--seed", str(a.drive_seed)]
            + ["--max-cycles", "800", "--frames", "0", "--workers", str(a.workers), "--out", str(out)]
        )
    return out / "drive.json"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="runs/recording-dataset")
    p.add_argument("--sumo-seed", type=int, default=21, help="SUMO's seed of the recording")
    p.add_argument("--noise", type=float, default=0.1, help="[m] the tracks' position noise (sigma)")
    p.add_argument("--lc-duration", type=float, default=0.0, help="[s] SUMO's lane changes take this long")
    p.add_argument("--trips", type=int, default=TRIPS, help="vehicles SUMO drives (one every 2.5 s)")
    p.add_argument(
        "--drive-seed", type=int, default=100, help="the drives' first episode seed (irlsim's 100)"
    )
    p.add_argument(
        "--learned", type=int, default=LEARNED, help="egos learned from (2 of them validation, test)"
    )
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2], help="training seeds")
    p.add_argument("--epochs", type=int, default=6)
    p.add_argument("--threads", type=int, default=2, help="torch threads of each training")
    p.add_argument("--workers", type=int, default=1, help="episodes collected or driven in parallel")
    p.add_argument("--choice", choices=["argmax", "expected"], default="argmax", help="the rewards' choice")
    a = p.parse_args(argv)
    out = Path(a.out)
    folder = out / f"recording-s{a.sumo_seed}"
    tracks = record(folder, a.sumo_seed, a.noise, a.lc_duration, a.trips)
    collect_toml, drive_toml, ref_toml = configs(folder, tracks, a.learned)
    a.collect_sets, data = [], out / "data"
    a.data = data
    styles.collect(collect_toml, ROAD, data, [], a)
    ref = out / "reference"
    styles.collect(ref_toml, ROAD, ref, [], a)
    expert = drive(drive_toml, None, ["expert"], out / "drive" / "expert", a)
    refs = {
        "recording": pool_styles(styles.collected_episodes(ref)),
        "expert": styles.driven_styles(expert)["expert"],
    }
    own = {"recording": styles.collected_bounds(ref), "expert": styles.safety(expert, "expert")}
    learned: dict[str, dict[str, Any]] = {}
    for seed in a.seeds:
        runs = out / "runs" / f"seed{seed}"
        styles.run(
            [
                styles.irlsim(),
                "train",
                "--stage",
                "1",
                "--config",
                "configs/train/stage1.toml",
                "--data",
                str(data),
            ]
            + ["--out", str(runs), "--set", 'models=["PACNN+S"]', "--set", f"seed={seed}"]
            + ["--set", f"threads={a.threads}", "--set", f"epochs={a.epochs}"]
        )
        dj = drive(
            drive_toml,
            runs,
            ["PACNN+S"],
            out / f"drive{'-choice' * (a.choice == 'expected')}" / f"seed{seed}",
            a,
        )
        style = styles.driven_styles(dj)["PACNN+S"]
        row = {"model": "PACNN+S", "demonstrator": "recording", "seed": seed, "style": style}
        learned[f"PACNN+S / recording / seed {seed}"] = {**row, "safety": styles.safety(dj, "PACNN+S")}
    lc = f", {a.lc_duration:g} s lane changes" if a.lc_duration else ""
    lc += ", the expected choice" if a.choice == "expected" else ""
    title = (
        f"{ROAD}, a dataset's tracks (SUMO seed {a.sumo_seed}, {a.noise:g} m noise{lc}): the held-out cars"
    )
    tables = {title: {"rows": styles.table_rows(learned, refs), "demonstrators": own}}
    name = "table" + "-choice" * (a.choice == "expected")
    styles.write_tables(out, name, tables)
    return 0


if __name__ == "__main__":
    sys.exit(main())
