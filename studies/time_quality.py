r"""Time to a reward against quality: every DAgger schedule of the faster recipe tried, a table and a picture.

For every training seed's run of the faster recipe (``<out>/new-seed<s>/`` of ``studies/recipe.py``: its
stage 1, its own DAgger rounds of 6 and 20 learner episodes, and the schedules ``studies/rounds.py`` ran
beside them in ``rounds-<schedule>/``), each schedule whose last round drove the first development sample
(20 episodes of 2 laps from seed 2000) gives one point per model:

- time to a reward: stage 1 plus the schedule's DAgger rounds, with PTACNN+S trained in the last round
  only (``stage2_every_round = false``: the same last-round models; the earlier rounds' stage 2 is
  left out of a schedule that ran it), as recorded by the runs;
- quality: the share of the checkpoints in lane, the safety events (collisions, exits, missed stops)
  and the closed-loop score (mean over the episodes).

``--acceptance <out>/recipe.json`` adds the rows of a ``studies/recipe.py`` run (its own seeds, each
recipe's time as it ran); ``--development`` the rows of development variants' runs on the first
development sample (their ``recipe-s2000.json``, copied aside). ``--points`` adds points kept in a CSV
(the published ones: ``docs/results/recipe-time-quality.csv``, whose runs need not be on this machine),
and ``--save-points`` writes every point to one, so the picture grows with each study. The table goes
to ``<out>/time-quality.md`` and ``.json``, the picture to ``--picture``:

    .venv/bin/python studies/time_quality.py --out runs/recipe --seeds 10 11 \
        --picture docs/img/recipe_time_quality.png
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).parent))
import recipe  # noqa: E402  (studies/recipe.py: the bar and its cells)
import rounds  # noqa: E402  (studies/rounds.py: a schedule's DAgger time)

from irlsim.drive.metrics import summarize  # noqa: E402

#: the picture's name of each recipe of studies/recipe.py: its name and DAgger schedule
RECIPE_LABELS = {
    "old": "old (6,20, retrained)",
    "new": "new (6,20)",
    "new3": "new3 (6,20,10)",
    "new3p": "new3p (6,10,10, plain NLL)",
    "new2p": "new2p (6,10, plain NLL)",
}
#: the faster recipe's own two rounds, beside the schedules tried on its stage 1
OWN = RECIPE_LABELS["new"]


def schedule_folders(run: Path) -> list[tuple[str, Path, Path]]:
    """(label, DAgger folder, development drive folder) of every schedule of the run in ``run`` that drove
    the first development sample: the recipe's own rounds first."""
    found = [(OWN, run / "dagger", run / "accept-round2-s2000-e20")]
    for here in sorted(run.glob("rounds-*")):
        label = here.name.removeprefix("rounds-").removesuffix("-s2last").replace("-", ",")
        found.append((label, here, here / "dev20"))
    return [f for f in found if (f[2] / "drive.json").is_file()]


def points(run: Path) -> list[dict[str, Any]]:
    """One row per (schedule, model) of the run in ``run`` (``<out>/new-seed<s>``)."""
    stage1 = float(json.loads((run / "times.json").read_text())["stage 1"])
    rows = []
    for label, here, dev in schedule_folders(run):
        eps = json.loads((dev / "drive.json").read_text())["episodes"]
        minutes = (stage1 + rounds.dagger_seconds(here, stage2_last=True)) / 60
        for m in recipe.MODELS:
            s = summarize([e for e in eps if e["drive/model"] == m])
            rows.append(row(label, int(run.name.rsplit("seed", 1)[1]), m, minutes, "development", s))
    return rows


#: a point's figures: the CSV's column (``--points``, ``--save-points``) and the drive summary's key, which
#: the point keeps so that studies/recipe.py's cells and share in lane read it as they read a summary
FIGURES = {
    "collisions": "drive/collisions", "exits": "drive/exits",
    "stops_compliant": "drive/stop_lines_compliant", "stops_passed": "drive/stop_lines_passed",
    "checkpoints_in_lane": "drive/checkpoints_in_lane", "checkpoints_passed": "drive/checkpoints_passed",
    "score": "score/score",
}  # fmt: skip
#: the columns of a point, as kept in a CSV
FIELDS = ["schedule", "seeds", "seed", "model", "minutes", *FIGURES]


def row(label: str, seed: int, model: str, minutes: float, seeds: str, s: dict[str, Any]) -> dict[str, Any]:
    """One point: a schedule's model, its time to a reward and the figures of its drives' summary ``s``."""
    point = {"schedule": label, "seeds": seeds, "seed": seed, "model": model, "minutes": round(minutes, 2)}
    return point | {k: s[k] for k in FIGURES.values()}


in_lane = recipe.in_lane


def events(r: dict[str, Any]) -> int:
    """A point's safety events: collisions, exits and stops not made."""
    missed = r["drive/stop_lines_passed"] - r["drive/stop_lines_compliant"]
    return r["drive/collisions"] + r["drive/exits"] + missed


def read_points(path: Path) -> list[dict[str, Any]]:
    """The points kept in the CSV ``path``; a missing score (not recorded) reads as None."""
    with path.open(newline="") as f:
        found = list(csv.DictReader(f))
    if not found or set(found[0]) != set(FIELDS):
        raise SystemExit(f"{path}: not a points file: its header must be {','.join(FIELDS)}")
    rows = []
    for r in found:
        try:
            figures = {FIGURES[k]: int(r[k]) for k in FIGURES if k != "score"}
            score = float(r["score"]) if r["score"] else None
            point = {k: r[k] for k in ("schedule", "seeds", "model")} | {"seed": int(r["seed"])}
            rows.append(point | {"minutes": float(r["minutes"])} | figures | {"score/score": score})
        except (TypeError, ValueError) as e:  # a short row reads None, a word where a number belongs
            raise SystemExit(f"{path}: a row that is not a point ({e}): {r}") from None
    return rows


def merge(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One point per (schedule, drive seeds, training seed, model): a later row replaces an earlier one in
    its place, so adding a run's points to a file that holds them already changes nothing."""
    kept: dict[tuple[Any, ...], dict[str, Any]] = {}
    for r in rows:
        kept[(r["schedule"], r["seeds"], r["seed"], r["model"])] = r
    return list(kept.values())


def write_points(rows: list[dict[str, Any]], path: Path) -> None:
    with path.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=FIELDS, lineterminator="\n")
        w.writeheader()
        for r in rows:
            kept = {k: r[FIGURES.get(k, k)] for k in FIELDS}
            w.writerow({k: "" if v is None else v for k, v in kept.items()})


def acceptance_rows(path: Path, seeds: str = "evaluation") -> list[dict[str, Any]]:
    """The rows of a studies/recipe.py run (its ``recipe.json``, or ``recipe-s<seed>.json`` on
    ``seeds="development"``): each recipe as it ran."""
    rows = []
    for r in json.loads(path.read_text()):
        minutes = (r["times"].get("stage 1", 0.0) + r["dagger_s"]) / 60
        label = RECIPE_LABELS.get(r["recipe"], r["recipe"])
        rows += [row(label, r["seed"], m, minutes, seeds, r["drive"][m]) for m in recipe.MODELS]
    return rows


def table(rows: list[dict[str, Any]]) -> str:
    head = "schedule | drive seeds | seed | model | to a reward [min] | collisions | exits | stops"
    head += " | checkpoints in lane | in lane [%] | score"
    lines = [f"| {head} |", "|" + "---|" * (head.count("|") + 1)]
    for r in rows:
        score = r["score/score"]
        cells = [r["schedule"], r["seeds"], r["seed"], r["model"], f"{r['minutes']:.1f}"]
        cells += [*recipe.closed_loop_cells(r), f"{100 * in_lane(r):.1f}"]
        cells += ["-" if score is None else f"{score:.1f}"]
        lines.append("| " + " | ".join(map(str, cells)) + " |")
    return "\n".join(lines) + "\n"


def picture(rows: list[dict[str, Any]], path: Path) -> None:
    """Checkpoints in lane against time to a reward, one point per (schedule, seed, model); a ring marks
    a point with a safety event; a hollow point is on evaluation seeds."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9.5, 4.8), dpi=110)
    labels = list(dict.fromkeys(r["schedule"] for r in rows))
    colours = {k: plt.get_cmap("tab10")(i % 10) for i, k in enumerate(labels)}
    for r in rows:
        marker = "o" if r["model"] == "PACNN+S" else "^"
        face = "none" if r["seeds"] == "evaluation" else colours[r["schedule"]]
        ax.scatter(r["minutes"], 100 * in_lane(r), marker=marker, s=46, c=[face],
                   edgecolors=[colours[r["schedule"]]], linewidths=1.3)  # fmt: skip
        if events(r):
            ax.scatter(r["minutes"], 100 * in_lane(r), marker="o", s=190, facecolors="none", edgecolors="red")
    for k in labels:
        ax.scatter([], [], marker="s", c=[colours[k]], label=k)
    ax.scatter([], [], marker="o", c="grey", label="PACNN+S")
    ax.scatter([], [], marker="^", c="grey", label="PTACNN+S")
    ax.scatter([], [], marker="o", s=190, facecolors="none", edgecolors="red", label="a safety event")
    if any(r["seeds"] == "evaluation" for r in rows):
        ax.scatter([], [], marker="o", facecolors="none", edgecolors="grey", label="hollow: evaluation seeds")
    ax.axhline(100 * recipe.MISSION_BAR, color="k", lw=0.8, ls="--")
    ax.axvline(20, color="k", lw=0.8, ls=":")
    if max(r["minutes"] for r in rows) > 40:  # the old recipe beside: a log axis keeps the fast ones apart
        ax.set_xscale("log")
        ticks = [t for t in (10, 15, 20, 30, 40, 60, 80) if t <= 1.2 * max(r["minutes"] for r in rows)]
        ax.set_xticks(ticks, [str(t) for t in ticks])
        ax.minorticks_off()
    ax.set_xlabel("time to a reward on 2 CPU cores [min] (stage 1 + DAgger)")
    ax.set_ylabel("checkpoints in lane [%]")
    ax.set_title("Recipes and DAgger schedules: time to a reward against the mission")
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))  # beside: no point hidden
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="runs/recipe", help="the recipe study's folder (studies/recipe.py)")
    p.add_argument("--seeds", type=int, nargs="*", default=[], help="training seeds of the runs")
    p.add_argument("--acceptance", help="a studies/recipe.py run's recipe.json to add (evaluation seeds)")
    p.add_argument(
        "--development", nargs="+", default=[],
        help="studies/recipe.py runs of development variants on the first development sample to add "
        "(their recipe-s2000.json, kept under another name: every run writes that name)",
    )  # fmt: skip
    p.add_argument("--points", help="a CSV of points to add first (docs/results/recipe-time-quality.csv)")
    p.add_argument("--save-points", help="write every point to this CSV (it may be the --points file)")
    p.add_argument("--picture", help="where to draw the picture (default <out>/time-quality.png)")
    a = p.parse_args()
    out = Path(a.out)
    runs = [out / f"new-seed{s}" for s in a.seeds]
    for run in runs:
        if not (run / "times.json").is_file():
            raise SystemExit(f"{run} has no recorded stage 1: run studies/recipe.py --recipes new first")
    given = [("--acceptance", a.acceptance), ("--points", a.points)]
    for option, path in given + [("--development", d) for d in a.development]:
        if path and not Path(path).is_file():
            what = "a points CSV" if option == "--points" else "a studies/recipe.py run's json"
            raise SystemExit(f"{option}: {path} is not a file: give {what}")
    rows = read_points(Path(a.points)) if a.points else []
    rows += [r for run in runs for r in points(run)]
    rows += [r for path in a.development for r in acceptance_rows(Path(path), "development")]
    rows += acceptance_rows(Path(a.acceptance)) if a.acceptance else []
    if not rows:
        raise SystemExit("no points: give --seeds, --acceptance, --development or --points")
    rows = merge(rows)
    out.mkdir(parents=True, exist_ok=True)
    pic = Path(a.picture) if a.picture else out / "time-quality.png"
    (out / "time-quality.json").write_text(json.dumps(rows, indent=1) + "\n")
    (out / "time-quality.md").write_text(table(rows))
    if a.save_points:
        write_points(rows, Path(a.save_points))
    picture(rows, pic)
    kept = f", {a.save_points}" if a.save_points else ""
    print(table(rows) + f"wrote {out / 'time-quality.md'}, {out / 'time-quality.json'}{kept} and {pic}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
