r"""A SUMO scenario's traffic, learned: does a reward learned from SUMO's own drivers on a scenario of SUMO's
(a signalised crossing by default) drive like them, or like the expert?

SUMO runs the scenario's configuration on its own and it is imported with ``irlsim scenario from-sumo``;
the first cars in the order they entered are learned from (PACNN+S, each at its type's size), the next
held-out cars driven (reactive: SUMO drives the others from their recorded states; the recording rows'
rules of the style study), the learned rewards and the expert; the table compares each reward's driving
with the driven cars' own recorded driving and the expert's on the same cars. About 15 minutes:

    .venv/bin/python studies/sumo_scenario.py --out runs/sumo-cross

``--config grid`` is a SUMO user's scenario instead, made here as one is made: a 3 x 3 grid of 200 m
streets, two lanes each way, signals SUMO places and times (netgenerate ``--tls.guess``), and random
trips (SUMO's ``randomTrips.py``, one every 2 s, seeded by ``--sumo-seed``). Writes ``<out>/table.md``
and ``.json``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tomllib
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).parent))
import styles  # noqa: E402  (studies/styles.py: collect, drive, the table)
from ego_configs import drive, ego_configs  # noqa: E402  (a recording's egos: configs, drives)

from irlsim.road.network import sumo_binary, sumo_home  # noqa: E402
from irlsim.rollout.style import pool_styles  # noqa: E402


def grid_config(out: Path, seed: int, duration: float) -> str:
    """A signalised grid with random trips, as a SUMO user makes one; its configuration's path."""
    folder = out / "grid"
    cfg = folder / "grid.sumocfg"
    if not cfg.is_file():
        folder.mkdir(parents=True, exist_ok=True)
        net, trips = folder / "grid.net.xml", folder / "grid.rou.xml"
        subprocess.run(
            [sumo_binary("netgenerate"), "--grid", "--grid.number", "3", "--grid.length", "200"]
            + ["--default.lanenumber", "2", "--tls.guess", "--no-turnarounds", "-o", str(net)],
            check=True, capture_output=True,
        )  # fmt: skip
        subprocess.run(
            [sys.executable, f"{sumo_home()}/tools/randomTrips.py", "-n", str(net), "-e", f"{duration:g}"]
            + ["-p", "2", "--seed", str(seed), "--fringe-factor", "10", "--min-distance", "300"]
            + ["--validate", "-r", str(trips), "-o", str(folder / "grid.trips.xml")],
            check=True, capture_output=True,
        )  # fmt: skip
        cfg.write_text(
            '<configuration><input><net-file value="grid.net.xml"/><route-files value="grid.rou.xml"/>'
            "</input></configuration>\n"
        )
    return str(cfg)


def imported(out: Path, a: Any) -> Path:
    """The scenario's traffic recorded by SUMO alone and imported; the import's folder."""
    folder = out / "import"
    if not (folder / "from-sumo.json").is_file():
        styles.run(
            [styles.irlsim(), "scenario", "from-sumo", a.config, "--out", str(folder)]
            + ["--duration", f"{a.duration:g}", "--seed", str(a.sumo_seed)]
        )
    return folder


def configs(folder: Path, learned: int, driven: int) -> tuple[str, str, str]:
    """(collect, drive, reference) configs: the import's first ``learned`` collected cars (two of them to
    validation and test), and the first ``driven`` of its held-out cars, driven and, as recorded, the
    reference."""
    made = json.loads((folder / "from-sumo.json").read_text())
    tables = tomllib.loads((folder / "drive.toml").read_text())
    tables.pop("seed", None)
    learn, drive = made["collect_egos"][:learned], made["drive_egos"][:driven]
    if len(learn) < learned or len(drive) < driven:
        raise SystemExit(
            f"the import has {len(made['collect_egos'])} collected and {len(made['drive_egos'])} held-out "
            "cars: record longer (--duration) or ask for fewer"
        )
    return ego_configs(tables, learn, drive, folder.parent)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="runs/sumo-cross")
    p.add_argument("--config", default="sumo_tools/game/cross.sumocfg", help="the SUMO configuration")
    p.add_argument("--duration", type=float, default=900.0, help="[s] SUMO's run")
    p.add_argument("--sumo-seed", type=int, default=0, help="SUMO's seed")
    p.add_argument("--learned", type=int, default=40, help="cars learned from (2: validation, test)")
    p.add_argument("--driven", type=int, default=20, help="held-out cars driven")
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2], help="training seeds")
    p.add_argument("--epochs", type=int, default=6)
    p.add_argument("--threads", type=int, default=2, help="torch threads of each training")
    p.add_argument("--workers", type=int, default=2, help="episodes collected or driven in parallel")
    a = p.parse_args(argv)
    a.collect_sets = []
    out = Path(a.out)
    if a.config == "grid":
        a.config = grid_config(out, a.sumo_seed, a.duration)
    folder = imported(out, a)
    collect_toml, drive_toml, ref_toml = configs(folder, a.learned, a.driven)
    scenario = str(folder / "scenario.toml")
    data, ref = out / "data", out / "reference"
    styles.collect(collect_toml, scenario, data, [], a)
    styles.collect(ref_toml, scenario, ref, [], a)
    refs = {"recording": pool_styles(styles.collected_episodes(ref))}
    own = {"recording": styles.collected_bounds(ref)}
    expert = drive(drive_toml, None, ["expert"], out / "drive" / "expert", a)
    refs["expert"] = styles.driven_styles(expert)["expert"]
    own["expert"] = styles.safety(expert, "expert")
    learned: dict[str, dict[str, Any]] = {}
    for seed in a.seeds:
        runs = out / "runs" / f"seed{seed}"
        if not (runs / "stage1" / "PACNN+S" / "checkpoint.pt").is_file():
            styles.run(
                [styles.irlsim(), "train", "--stage", "1", "--config", "configs/train/stage1.toml"]
                + ["--data", str(data), "--out", str(runs), "--set", 'models=["PACNN+S"]']
                + ["--set", f"seed={seed}", "--set", f"threads={a.threads}", "--set", f"epochs={a.epochs}"]
            )
        dj = drive(drive_toml, runs, ["PACNN+S"], out / "drive" / f"seed{seed}", a)
        row = {"model": "PACNN+S", "demonstrator": "recording", "seed": seed}
        row["style"] = styles.driven_styles(dj)["PACNN+S"]
        learned[f"PACNN+S / seed {seed}"] = {**row, "safety": styles.safety(dj, "PACNN+S")}
    title = f"{Path(a.config).name} ({a.duration:g} s of SUMO, seed {a.sumo_seed}): rewards on held-out cars"
    tables = {title: {"rows": styles.table_rows(learned, refs), "demonstrators": own}}
    styles.write_tables(out, "table", tables)
    return 0


if __name__ == "__main__":
    sys.exit(main())
