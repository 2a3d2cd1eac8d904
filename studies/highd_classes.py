r"""A recording's cars and trucks, learned apart: do rewards learned from its trucks drive like its trucks,
and those from its cars like its cars?

SUMO drives cars and trucks (its class defaults: a truck accelerates at 1.3 m/s^2, a car at 2.6) on a road
of highD's shape (``examples/highd/sample.py``), written as highD's recording and imported with ``irlsim
scenario from-highd``. On the lower carriageway, per class, the first egos in the order they entered are
learned from (PACNN+S, each ego at its recorded size) and the next ones driven (reactive, the recording
rows' rules of the style study), the learned rewards and the expert; the table compares each reward's
driving with the driven cars' and trucks' own recorded driving and the expert's. About 15 minutes:

    .venv/bin/python studies/highd_classes.py --out runs/highd-classes

``--cross`` also drives each class's rewards on the other class's egos (are the rows told apart by the
rewards, or by the egos they start from?). Writes ``<out>/table[-cross].md`` and ``.json``.
"""

from __future__ import annotations

import argparse
import json
import sys
import tomllib
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).parent))
import styles  # noqa: E402  (studies/styles.py: collect, drive, the table)
from ego_configs import drive, ego_configs  # noqa: E402  (a recording's egos: configs, drives)

from irlsim.rollout.style import pool_styles  # noqa: E402

SIDE = "lower"
CLASSES = {"cars": "", "trucks": "-trucks"}  # the import's config suffix per class


def record(out: Path, vehicles: int, every: float) -> Path:
    """The sample recording in highD's layout, imported; the import's folder."""
    hd = out / "hd"
    if not (hd / "highd.json").is_file():
        sample = out / "sample"
        cmd = [sys.executable, "examples/highd/sample.py", "--out", str(sample)]
        styles.run([*cmd, "--vehicles", str(vehicles), "--every", str(every)])
        styles.run([styles.irlsim(), "scenario", "from-highd", str(sample / "01"), "--out", str(hd)])
    return hd


def configs(hd: Path, cls: str, learned: int, driven: int) -> tuple[str, str, str]:
    """(collect, drive, reference) configs of class ``cls``: its first ``learned`` egos collected (two of
    them validation and test), the next ``driven`` driven; the import's scenario, planner speeds and
    recording, with 500 policies."""
    made = json.loads((hd / "highd.json").read_text())[SIDE]
    egos = made[f"collect_egos{CLASSES[cls]}"]
    if len(egos) < learned + driven:
        sys.exit(f"highd_classes: {len(egos)} {cls} to learn from and drive, {learned + driven} asked for")
    base = tomllib.loads(Path(made[f"collect{CLASSES[cls]}"]).read_text())
    planner = {"n_policies": 500, **base["planner"]}
    tables = {"scenario": base["scenario"], "planner": planner, "demonstrator": base["demonstrator"]}
    return ego_configs(tables, egos[:learned], egos[learned : learned + driven], hd.parent, f"{cls}-")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="runs/highd-classes")
    p.add_argument("--vehicles", type=int, default=180, help="vehicles per carriageway (every third a truck)")
    p.add_argument("--every", type=float, default=2.0, help="[s] one departs every")
    p.add_argument(
        "--learned", type=int, default=24, help="egos learned from per class (2: validation, test)"
    )
    p.add_argument("--driven", type=int, default=20, help="egos driven per class")
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2], help="training seeds")
    p.add_argument("--epochs", type=int, default=6)
    p.add_argument("--threads", type=int, default=2, help="torch threads of each training")
    p.add_argument("--workers", type=int, default=2, help="episodes collected or driven in parallel")
    p.add_argument("--cross", action="store_true", help="also drive each class's rewards on the other's egos")
    a = p.parse_args(argv)
    a.collect_sets = []
    out = Path(a.out)
    hd = record(out, a.vehicles, a.every)
    refs: dict[str, dict[str, Any]] = {}
    own: dict[str, dict[str, Any]] = {}
    expert_eps: list[dict[str, Any]] = []
    learned: dict[str, dict[str, Any]] = {}
    for cls in CLASSES:
        collect_toml, drive_toml, ref_toml = configs(hd, cls, a.learned, a.driven)
        data, ref = out / "data" / cls, out / "reference" / cls
        styles.collect(collect_toml, str(hd / f"{SIDE}.toml"), data, [], a)
        styles.collect(ref_toml, str(hd / f"{SIDE}.toml"), ref, [], a)
        refs[cls], own[cls] = pool_styles(styles.collected_episodes(ref)), styles.collected_bounds(ref)
        expert = drive(drive_toml, None, ["expert"], out / "drive" / cls / "expert", a)
        expert_eps += [e for e in json.loads(expert.read_text())["episodes"] if e["drive/model"] == "expert"]
        own[f"expert ({cls}' egos)"] = styles.safety(expert, "expert")
        for seed in a.seeds:
            runs = out / "runs" / f"{cls}-seed{seed}"
            styles.run(
                [styles.irlsim(), "train", "--stage", "1", "--config", "configs/train/stage1.toml"]
                + ["--data", str(data), "--out", str(runs), "--set", 'models=["PACNN+S"]']
                + ["--set", f"seed={seed}", "--set", f"threads={a.threads}", "--set", f"epochs={a.epochs}"]
            )
            dj = drive(drive_toml, runs, ["PACNN+S"], out / "drive" / cls / f"seed{seed}", a)
            row = {"model": "PACNN+S", "demonstrator": cls, "seed": seed}
            row["style"] = styles.driven_styles(dj)["PACNN+S"]
            learned[f"PACNN+S / {cls} / seed {seed}"] = {**row, "safety": styles.safety(dj, "PACNN+S")}
    refs["expert"] = pool_styles(expert_eps)
    crossed: dict[str, dict[str, Any]] = {}
    if a.cross:  # each class's rewards on the other class's egos: the egos' start states, not the rewards?
        for cls, other in (("cars", "trucks"), ("trucks", "cars")):
            drive_toml = configs(hd, other, a.learned, a.driven)[1]
            for seed in a.seeds:
                runs = out / "runs" / f"{cls}-seed{seed}"
                dj = drive(
                    drive_toml, runs, ["PACNN+S"], out / "drive-cross" / other / f"{cls}-seed{seed}", a
                )
                row = {"model": "PACNN+S", "demonstrator": cls, "seed": seed}
                row["style"] = styles.driven_styles(dj)["PACNN+S"]
                crossed[f"PACNN+S / {cls} / seed {seed}, on the {other}' egos"] = {
                    **row,
                    "safety": styles.safety(dj, "PACNN+S"),
                }
    title = (
        f"a road of highD's shape, SUMO's cars and trucks ({a.vehicles} vehicles a carriageway): each "
        "class's rewards on its driven egos"
    )
    tables = {title: {"rows": styles.table_rows(learned, refs), "demonstrators": own}}
    if crossed:
        tables["each class's rewards on the other class's driven egos"] = {
            "rows": styles.table_rows(crossed, refs),
            "demonstrators": own,
        }
    styles.write_tables(out, "table" + "-cross" * bool(crossed), tables)
    return 0


if __name__ == "__main__":
    sys.exit(main())
